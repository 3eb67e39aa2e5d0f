"""`skeleton` of NumPy phantoms, and against `sphcover skeleton` on the bundled CT."""

import numpy as np
import pytest

import sphcover


def plate_phantom(n=32, half_thickness=2.0, half_width=10.0):
    """A CT-like square plate at z = centre (between voxel centres), brighter than the
    background, with soft faces and rims."""
    centre = n / 2 - 0.7
    i, j, k = np.meshgrid(*[np.arange(n, dtype=np.float64)] * 3, indexing="ij")
    inside = np.minimum(
        half_thickness - np.abs(k - centre),
        np.minimum(half_width - np.abs(i - n / 2), half_width - np.abs(j - n / 2)),
    )
    return 1000.0 * (1.0 + np.tanh(inside / 0.8)), centre


def test_the_sheet_of_a_plate_is_its_mid_plane():
    values, centre = plate_phantom()
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = [1.0, 2.0, 3.0]
    sheet = sphcover.skeleton(values, affine)
    assert sheet.stats["components"] == 1 and len(sheet.faces) > 500
    # A solid plate has no perforation to cut open.
    assert sheet.stats["perforations_cut"] == 0
    # Cubic voxels: no slices to centre the sheet on.
    assert sheet.stats["slice_centred_vertices"] == 0
    assert sheet.stats["hessian_slice_stretch"] is None
    assert sheet.stats["rim_slice_stretch"] is None
    # World z of the mid-plane: 3 + 0.5·centre, within a tenth of a voxel on average.
    assert np.mean(np.abs(sheet.vertices[:, 2] - (3.0 + 0.5 * centre))) < 0.05
    # The sheet spans the plate: x from about 1 + 0.5·6 to 1 + 0.5·26.
    assert sheet.vertices[:, 0].min() < 5.0 and sheet.vertices[:, 0].max() > 13.0


def test_the_sheet_of_scattered_samples_is_its_mid_plane():
    rng = np.random.default_rng(1)
    grid = np.stack(np.meshgrid(*[np.arange(16.0)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    points = grid + rng.uniform(-0.3, 0.3, grid.shape)
    values = 500.0 * (1.0 + np.tanh((2.0 - np.abs(points[:, 2] - 8.0)) / 0.8))
    sheet = sphcover.skeleton_from_samples(points, values)
    assert sheet.stats["components"] == 1
    assert np.mean(np.abs(sheet.vertices[:, 2] - 8.0)) < 0.1


def test_bundled_ct_matches_the_command_line_byte_for_byte(fixtures, run_cli, tmp_path):
    ct = fixtures / "phantoms" / "t_junction_ct_n000.nii.gz"
    run_cli("skeleton", ct, "-o", tmp_path / "cli.ply")
    sheet = sphcover.skeleton(sphcover.read(ct))
    sphcover.write(tmp_path / "python.ply", sheet)
    assert (tmp_path / "python.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()


def test_the_baseline_gives_ridge_points():
    values, centre = plate_phantom()
    points = sphcover.skeleton(values, method="nms")
    assert isinstance(points, sphcover.PointCloud) and len(points) > 100
    # The baseline's ridge points lie inside the plate (the sheet's accuracy is the ridge
    # method's business).
    assert np.all(np.abs(points.points[:, 2] - centre) < 2.0)


def test_a_constant_volume_is_bad_input():
    try:
        sphcover.skeleton(np.full((8, 8, 8), 3.0))
    except sphcover.BadInputError as e:
        assert str(e) == "the volume is constant (every voxel is 3)"
    else:
        raise AssertionError("a constant volume was accepted")


def test_grids_the_pipeline_cannot_treat_are_refused_as_the_command_line_refuses_them():
    values, _ = plate_phantom(16)
    needle = np.diag([0.5, 0.5, 4.5, 1.0])
    with pytest.raises(sphcover.BadInputError, match=r"too anisotropic \(more than 8:1\)"):
        sphcover.skeleton(values, needle)
    turned = np.eye(4)
    c, s = np.cos(0.1), np.sin(0.1)
    turned[:2, :2] = [[c, -s], [s, c]]
    with pytest.raises(sphcover.BadInputError, match="oblique to the world axes"):
        sphcover.skeleton(values, turned)
    with pytest.raises(sphcover.BadInputError, match="a 4D volume with 2 frames"):
        sphcover.skeleton(np.stack([values, values], axis=3))
    with pytest.warns(UserWarning, match="not cubic"):
        sheet = sphcover.skeleton(values, np.diag([0.5, 0.5, 0.6, 1.0]))
    assert len(sheet.faces) > 0


def test_thick_slices_are_resampled_and_the_sheet_stays_in_world_coordinates():
    # Pixels of 0.5, slices of 1.5: a plate 3 thick tilted 25 degrees off the slices, its
    # faces blurred over 0.8 pixel in-plane and 0.8 slice across.
    tilt = np.radians(25.0)
    normal, offset = np.array([0.0, -np.sin(tilt), np.cos(tilt)]), 2.4
    i, j, k = np.meshgrid(np.arange(48.0), np.arange(48.0), np.arange(12.0), indexing="ij")
    u = normal[1] * 0.5 * j + normal[2] * 1.5 * k - offset
    width = np.hypot(0.4 * normal[1], 1.2 * normal[2])
    values = -1000.0 + 1500.0 * (np.tanh((1.5 - u) / width) + np.tanh((1.5 + u) / width))
    with pytest.warns(UserWarning, match=r"resampled by 2 along voxel axis k"):
        sheet = sphcover.skeleton(values, np.diag([0.5, 0.5, 1.5, 1.0]))
    resampled = sheet.stats["resampled"]
    assert resampled["factors"] == [1, 1, 2]
    assert resampled["input_dims"] == [48, 48, 12] and resampled["dims"] == [48, 48, 23]
    assert sheet.stats["slice_centred_vertices"] > 0
    assert sheet.stats["hessian_slice_stretch"] > 1.0
    assert 1.0 < sheet.stats["rim_slice_stretch"] < sheet.stats["hessian_slice_stretch"]
    assert sheet.stats["components"] == 1
    assert np.max(np.abs(sheet.vertices @ normal - offset)) < 0.3


def head_phantom(n=40):
    """A CT in HU of 1 mm voxels: a ball of soft tissue (+40, radius 16) in air holding a bone
    shell (+1200, radii 11-13), as the command line's test builds it."""
    i, j, k = np.meshgrid(*[np.arange(n, dtype=np.float64)] * 3, indexing="ij")
    r = np.sqrt((i - 19.5) ** 2 + (j - 19.5) ** 2 + (k - 19.5) ** 2)
    return np.where((r >= 11.0) & (r <= 13.0), 1200.0, np.where(r <= 16.0, 40.0, -1000.0))


def test_a_ct_takes_its_thin_material_and_says_why():
    sheet = sphcover.skeleton(head_phantom())
    material = sheet.stats["material"]
    assert material["name"] == "bone" and material["automatic"]
    assert material["air_hu"] == pytest.approx(-1000.0, abs=5.0)
    assert material["soft_tissue_hu"] == pytest.approx(40.0, abs=5.0)
    assert material["window"] == pytest.approx([40.0, 420.0], abs=5.0)
    radii = np.linalg.norm(sheet.vertices - 19.5, axis=1)
    assert np.all(np.abs(radii - 12.0) < 1.0)
    # Without materials the air/body split is taken, and the report says no material.
    whole = sphcover.skeleton(head_phantom(), material="off")
    assert whole.stats["material"] is None and whole.stats["threshold"] < -100.0
    with pytest.raises(sphcover.BadInputError, match="not one of"):
        sphcover.skeleton(head_phantom(), material="metal")
