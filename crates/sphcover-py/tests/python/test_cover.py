"""`cover` of points, volumes and scattered samples against `sphcover cover`."""

import numpy as np
import pytest

import sphcover
from conftest import fibonacci_sphere


def same_cover(a, b):
    assert len(a) == len(b)
    np.testing.assert_array_equal(a.centres, b.centres)
    np.testing.assert_array_equal(a.radii, b.radii)
    x = a.centres[:: max(1, len(a) // 50)]
    for fa, fb in zip(a.evaluate(x), b.evaluate(x)):
        np.testing.assert_array_equal(fa, fb)


def test_volume_cover_matches_the_command_line(fixtures, run_cli, tmp_path):
    ct = fixtures / "phantoms" / "t_junction_ct_n000.nii.gz"
    run_cli("cover", ct, "-o", tmp_path / "cli.ply", "--centre-order", "deepest")
    volume = sphcover.read(ct)
    cover = sphcover.cover(volume, centre_order="deepest")
    same_cover(cover, sphcover.read(tmp_path / "cli.ply"))
    # f is positive in the object: at the brightest voxel's centre.
    i = np.unravel_index(np.argmax(volume.values), volume.values.shape)
    bright = (volume.affine @ np.array([*i, 1.0]))[:3]
    assert cover.evaluate(bright[None, :])[0][0] > 0


def test_scattered_cover_matches_the_command_line(run_cli, tmp_path):
    # A thick spherical shell's samples, brighter inside, off any grid.
    rng = np.random.default_rng(5)
    points = rng.uniform(-1.0, 1.0, size=(6000, 3))
    r = np.linalg.norm(points, axis=1)
    values = 1000.0 * (1.0 + np.tanh((0.15 - np.abs(r - 0.6)) / 0.05))
    samples = tmp_path / "samples.ply"
    sphcover.write(samples, sphcover.PointCloud(points=points, values=values))
    run_cli("cover", samples, "-o", tmp_path / "cli.ply", "--value-property", "quality")
    same_cover(sphcover.cover(points, values=values), sphcover.read(tmp_path / "cli.ply"))


def test_volume_options_are_checked():
    points, normals = fibonacci_sphere(500)
    with pytest.raises(sphcover.BadInputError, match="apply to volumes"):
        sphcover.cover(points, normals, threshold=3.0)
    with pytest.raises(sphcover.BadInputError, match="centre_order"):
        sphcover.cover(np.zeros((4, 4, 4)), centre_order="first")
    with pytest.raises(sphcover.BadInputError, match="eps"):
        sphcover.cover(points, values=np.ones(500), eps=-1.0)
