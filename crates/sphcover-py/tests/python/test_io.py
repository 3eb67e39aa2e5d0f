"""Arrays through every reader and writer: what is written reads back as it was."""

import gzip
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import sphcover
from conftest import fibonacci_sphere


def tetrahedron_mesh():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64) * 0.3
    vertices += [0.1, 0.2, 0.3]
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.uint32)
    return sphcover.Mesh(vertices=vertices, faces=faces)


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_mesh_round_trip_keeps_every_attribute_exactly(tmp_path, ascii):
    mesh = tetrahedron_mesh()
    mesh.normals = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1)[:, None]
    mesh.values = np.array([0.25, 1 / 3, np.pi, -2.0])
    path = tmp_path / "mesh.ply"
    sphcover.write(path, mesh, ascii=ascii)
    back = sphcover.read(path)
    assert isinstance(back, sphcover.Mesh)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(back.normals, mesh.normals)
    np.testing.assert_array_equal(back.values, mesh.values)


def test_single_precision_rounds_to_float32(tmp_path):
    mesh = tetrahedron_mesh()
    path = tmp_path / "single.ply"
    sphcover.write(path, mesh, single=True)
    back = sphcover.read(path)
    np.testing.assert_array_equal(back.vertices, mesh.vertices.astype(np.float32))


@pytest.mark.parametrize("extension", ["obj", "off"])
def test_text_mesh_formats_round_trip(tmp_path, extension):
    mesh = tetrahedron_mesh()
    path = tmp_path / f"mesh.{extension}"
    sphcover.write(path, mesh)
    back = sphcover.read(path)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)


def test_mesh_values_and_colours_stay_in_ply_only(tmp_path):
    mesh = tetrahedron_mesh()
    mesh.values = np.arange(4.0)
    mesh.colors = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [7, 8, 9]], dtype=np.uint8)
    sphcover.write(tmp_path / "mesh.obj", mesh)
    back = sphcover.read(tmp_path / "mesh.obj")
    assert back.values is None and back.colors is None
    sphcover.write(tmp_path / "mesh.ply", mesh)
    np.testing.assert_array_equal(sphcover.read(tmp_path / "mesh.ply").colors, mesh.colors)


@pytest.mark.parametrize("ascii", [False, True])
def test_colours_round_trip_through_ply_as_uchar_red_green_blue(tmp_path, ascii):
    points, normals = fibonacci_sphere(40)
    colors = np.stack([np.arange(40) * 6, 255 - np.arange(40), np.full(40, 17)], axis=1)
    cloud = sphcover.PointCloud(points=points, normals=normals, colors=colors.astype(np.uint8))
    path = tmp_path / "coloured.ply"
    sphcover.write(path, cloud, ascii=ascii)
    header = path.read_bytes().split(b"end_header")[0].decode()
    assert "property uchar red\nproperty uchar green\nproperty uchar blue" in header
    back = sphcover.read(path)
    assert back.colors.dtype == np.uint8
    np.testing.assert_array_equal(back.colors, cloud.colors)
    # Open3D's float colours in [0, 1] are taken too.
    cloud.colors = colors / 255.0
    sphcover.write(path, cloud)
    np.testing.assert_array_equal(sphcover.read(path).colors, colors)
    with pytest.raises(sphcover.BadInputError, match="colours"):
        sphcover.write(tmp_path / "coloured.xyz", cloud)
    with pytest.raises(sphcover.BadInputError, match="shape"):
        sphcover.write(path, sphcover.PointCloud(points=points, colors=colors[:, :2]))


def test_stl_round_trip_in_float32(tmp_path):
    mesh = tetrahedron_mesh()
    path = tmp_path / "mesh.stl"
    sphcover.write(path, mesh)
    back = sphcover.read(path)
    assert len(back.faces) == 4
    # STL stores float32 triangles; identical corners are merged back into vertices.
    got = back.vertices[back.faces].reshape(-1, 3)
    want = mesh.vertices.astype(np.float32).astype(np.float64)[mesh.faces].reshape(-1, 3)
    np.testing.assert_array_equal(np.sort(got, axis=0), np.sort(want, axis=0))


@pytest.mark.parametrize("extension", ["ply", "xyz", "pwn", "txt"])
def test_point_clouds_with_normals_round_trip(tmp_path, extension):
    points, normals = fibonacci_sphere(50)
    cloud = sphcover.PointCloud(points=points, normals=normals)
    path = tmp_path / f"points.{extension}"
    sphcover.write(path, cloud)
    back = sphcover.read(path)
    assert isinstance(back, sphcover.PointCloud)
    np.testing.assert_array_equal(back.points, points)
    np.testing.assert_array_equal(back.normals, normals)


def test_ply_point_attributes_round_trip(tmp_path):
    points, _ = fibonacci_sphere(20)
    cloud = sphcover.PointCloud(
        points=points, confidence=np.linspace(0, 1, 20), values=np.arange(20.0)
    )
    sphcover.write(tmp_path / "p.ply", cloud)
    back = sphcover.read(tmp_path / "p.ply")
    np.testing.assert_array_equal(back.confidence, cloud.confidence)
    np.testing.assert_array_equal(back.values, cloud.values)


@pytest.mark.parametrize("extension", ["ply", "sph", "spheres", "txt"])
def test_sphere_sets_round_trip(tmp_path, extension):
    centres, _ = fibonacci_sphere(30)
    spheres = sphcover.Spheres(centres=centres, radii=np.linspace(0.01, 0.1, 30))
    path = tmp_path / f"balls.{extension}"
    sphcover.write(path, spheres)
    back = sphcover.read(path)
    assert isinstance(back, sphcover.Spheres)
    np.testing.assert_array_equal(back.centres, spheres.centres)
    np.testing.assert_array_equal(back.radii, spheres.radii)


def test_cover_file_round_trip_evaluates_the_same(tmp_path):
    points, normals = fibonacci_sphere(800)
    cover = sphcover.cover(points, normals, eps=1e-2)
    path = tmp_path / "sphere.cover.ply"
    sphcover.write(path, cover)
    back = sphcover.read(path)
    assert isinstance(back, sphcover.Cover)
    assert len(back) == len(cover)
    np.testing.assert_array_equal(back.centres, cover.centres)
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.4], [0.1, 0.2, -0.3]])
    for a, b in zip(back.evaluate(x), cover.evaluate(x)):
        np.testing.assert_array_equal(a, b)


def test_writers_refuse_what_a_format_cannot_hold(tmp_path):
    mesh = tetrahedron_mesh()
    with pytest.raises(sphcover.BadInputError, match="faces"):
        sphcover._sphcover.write_geometry(
            str(tmp_path / "m.xyz"), mesh.vertices, triangles=mesh.faces
        )


def test_malformed_files_raise_the_command_line_message(fixtures, run_cli, tmp_path):
    bad = fixtures / "malformed" / "ply_bad_token.ply"
    with pytest.raises(sphcover.BadInputError) as raised:
        sphcover.read(bad)
    result = run_cli("info", bad, expect_ok=False)
    assert result.returncode == 2
    assert str(raised.value) in result.stderr


def test_bundled_scans_read_with_their_attributes(fixtures):
    kitten = sphcover.read(fixtures / "real" / "kitten.ply")
    assert isinstance(kitten, sphcover.PointCloud)
    assert kitten.points.shape == (5210, 3) and kitten.normals.shape == (5210, 3)
    bunny = sphcover.read(fixtures / "real" / "bunny_npm.off")
    assert isinstance(bunny, sphcover.Mesh) and len(bunny.faces) > 0
    torus = sphcover.read(fixtures / "torus_3k.xyz")
    assert len(torus) == 3000


def test_nifti_volume_reads_with_its_affine(fixtures):
    volume = sphcover.read(fixtures / "phantoms" / "t_junction_ct_n000.nii.gz")
    assert isinstance(volume, sphcover.Volume)
    assert volume.values.ndim == 3 and volume.affine.shape == (4, 4)
    np.testing.assert_array_equal(volume.affine[3], [0, 0, 0, 1])
    assert np.ptp(volume.values) > 0


def write_inrimage(path, values, voxel):
    """A minimal INRIMAGE-4 file of float32 voxels, x fastest."""
    nx, ny, nz = values.shape
    header = (
        f"#INRIMAGE-4#{{\nXDIM={nx}\nYDIM={ny}\nZDIM={nz}\nVDIM=1\nTYPE=float\nPIXSIZE=32 bits\n"
        f"VX={voxel}\nVY={voxel}\nVZ={voxel}\nCPU=decm\n"
    )
    header += "\n" * (252 - len(header)) + "##}\n"
    path.write_bytes(header.encode() + values.astype("<f4").tobytes(order="F"))


def test_inrimage_volume_reads_voxels_in_index_order(tmp_path):
    values = np.arange(4 * 3 * 2, dtype=np.float64).reshape(4, 3, 2)
    write_inrimage(tmp_path / "v.inr", values, 0.5)
    volume = sphcover.read(tmp_path / "v.inr")
    np.testing.assert_array_equal(volume.values, values)
    np.testing.assert_allclose(np.diag(volume.affine)[:3], [0.5, 0.5, 0.5])


def write_las(path, xyz, intensity, scale=0.001, rgb=None):
    """A minimal LAS 1.2 file, point format 0, or 2 with 16-bit colours `rgb`."""
    n = len(xyz)
    point_format, length = (0, 20) if rgb is None else (2, 26)
    offset = xyz.min(axis=0)
    header = bytearray(227)
    header[0:4] = b"LASF"
    struct.pack_into("<BB", header, 24, 1, 2)
    struct.pack_into("<HIIBHI", header, 94, 227, 227, 0, point_format, length, n)
    struct.pack_into("<3d", header, 131, scale, scale, scale)
    struct.pack_into("<3d", header, 155, *offset)
    struct.pack_into(
        "<6d", header, 179,
        xyz[:, 0].max(), xyz[:, 0].min(), xyz[:, 1].max(), xyz[:, 1].min(),
        xyz[:, 2].max(), xyz[:, 2].min(),
    )
    records = bytearray()
    for k, (p, i) in enumerate(zip(xyz, intensity)):
        q = np.round((p - offset) / scale).astype(np.int64)
        records += struct.pack("<3iHBBbBH", *q, int(i), 0, 0, 0, 0, 0)
        if rgb is not None:
            records += struct.pack("<3H", *(int(c) for c in rgb[k]))
    path.write_bytes(bytes(header) + bytes(records))


def test_las_points_read_with_intensity_as_values(tmp_path):
    xyz = np.array([[10.0, 20.0, 1.5], [10.5, 20.25, 2.0], [11.0, 21.0, 0.125]])
    write_las(tmp_path / "tile.las", xyz, [100, 200, 300])
    cloud = sphcover.read(tmp_path / "tile.las")
    np.testing.assert_allclose(cloud.points, xyz, atol=1e-9)
    np.testing.assert_array_equal(cloud.values, [100, 200, 300])


def test_las_colours_read_as_bytes(tmp_path):
    xyz = np.array([[10.0, 20.0, 1.5], [10.5, 20.25, 2.0], [11.0, 21.0, 0.125]])
    rgb8 = np.array([[255, 0, 10], [128, 64, 32], [0, 0, 1]])
    write_las(tmp_path / "rgb.las", xyz, [1, 2, 3], rgb=rgb8 * 257)
    cloud = sphcover.read(tmp_path / "rgb.las")
    np.testing.assert_array_equal(cloud.colors, rgb8)
    write_las(tmp_path / "plain.las", xyz, [1, 2, 3])
    assert sphcover.read(tmp_path / "plain.las").colors is None


def write_nifti_bomb(path, dims):
    """A gzip NIfTI-1 file of float32 voxels, all zero: a decompression bomb, about a
    thousandth of what it declares."""
    header = bytearray(348)
    struct.pack_into("<i", header, 0, 348)
    struct.pack_into("<8h", header, 40, 3, *dims, 1, 1, 1, 1)
    struct.pack_into("<hh", header, 70, 16, 32)
    struct.pack_into("<8f", header, 76, 1, 1, 1, 1, 1, 1, 1, 1)
    struct.pack_into("<f", header, 108, 352.0)
    header[344:348] = b"n+1\0"
    with gzip.open(path, "wb", compresslevel=9) as out:
        out.write(bytes(header) + bytes(4))
        zeros = bytes(1 << 24)
        for _ in range(4 * dims[0] * dims[1] * dims[2] // len(zeros)):
            out.write(zeros)


BOMB_UNDER_ULIMIT = textwrap.dedent(
    """
    import resource, sys
    limit = 3 << 29  # 1.5 GiB of address space: the default read limit is 60% of it
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    import sphcover
    try:
        sphcover.read(sys.argv[1])
    except sphcover.BadInputError as e:
        print(e)
    """
)


def test_a_file_declaring_more_than_memory_is_refused_from_its_header(tmp_path, run_cli):
    bomb = tmp_path / "bomb.nii.gz"
    write_nifti_bomb(bomb, (1024, 1024, 256))  # 1 GiB of float32
    child = subprocess.run(
        [sys.executable, "-c", BOMB_UNDER_ULIMIT, str(bomb)], capture_output=True, text=True
    )
    message = child.stdout.strip()
    assert child.returncode == 0, child.stderr
    assert "bomb.nii.gz" in message, message
    assert "(60% of the 1.5 GiB address-space limit (ulimit -v); max_memory sets it)" in message
    # The command line with the same limit: the same refusal, but for where it came from.
    cli = run_cli("info", bomb, "--max-memory", str((3 << 29) // 100 * 60), expect_ok=False)
    assert cli.returncode == 2
    assert message.split(" (60%")[0] in cli.stderr, (message, cli.stderr)


def test_max_memory_bounds_what_read_may_allocate(fixtures):
    kitten = fixtures / "real" / "kitten.ply"
    for limit in ["100K", 100_000]:
        with pytest.raises(sphcover.BadInputError, match=r"kitten\.ply.*\(max_memory\)"):
            sphcover.read(kitten, max_memory=limit)
    assert len(sphcover.read(kitten, max_memory="1G")) == 5210
    for bad in ["lots", -1, 1.5j]:
        with pytest.raises(sphcover.BadInputError, match="max_memory"):
            sphcover.read(kitten, max_memory=bad)
