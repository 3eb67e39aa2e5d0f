"""The regular triangulation and the dual complex, against `sphcover tetra`."""

import numpy as np
import pytest

import sphcover


def tet_volumes(points, tets):
    a, b, c, d = (points[tets[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def test_regular_triangulation_tiles_the_convex_hull():
    spatial = pytest.importorskip("scipy.spatial", reason="the hull volume comes from SciPy")
    rng = np.random.default_rng(4)
    centres = rng.uniform(-1, 1, (200, 3))
    radii = rng.uniform(0.0, 0.05, 200)
    tets = sphcover.regular_triangulation(centres, radii)
    volumes = tet_volumes(centres, tets.astype(np.int64))
    assert np.all(volumes > 0)
    assert np.isclose(volumes.sum(), spatial.ConvexHull(centres).volume, rtol=1e-12)


def test_dual_complex_matches_the_command_line(fixtures, run_cli, tmp_path):
    spheres = sphcover.read(fixtures / "grid_spheres.sph")
    complex_ = sphcover.dual_complex(spheres)
    assert len(complex_.tets) > 0 and complex_.euler_characteristic == 1
    for extension in ["txt", "vtk"]:
        run_cli("tetra", fixtures / "grid_spheres.sph", "-o", tmp_path / f"cli.{extension}")
        sphcover.write(tmp_path / f"python.{extension}", complex_)
        assert (tmp_path / f"python.{extension}").read_bytes() == (
            tmp_path / f"cli.{extension}"
        ).read_bytes()
