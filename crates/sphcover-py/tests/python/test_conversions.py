"""Conversions to and from Open3D and trimesh, when those packages are installed."""

import numpy as np
import pytest

import sphcover
from conftest import fibonacci_sphere


@pytest.fixture(scope="module")
def mesh():
    points, normals = fibonacci_sphere(1500)
    colors = np.round((points / 0.8 + 0.5) * 255).astype(np.uint8)
    return sphcover.reconstruct(points, normals, colors=colors)


def test_trimesh_round_trip(mesh):
    trimesh = pytest.importorskip("trimesh", reason="trimesh is not installed")
    tm = mesh.to_trimesh()
    assert isinstance(tm, trimesh.Trimesh) and tm.is_watertight
    back = sphcover.Mesh.from_trimesh(tm)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(back.values, mesh.values)
    np.testing.assert_array_equal(back.colors, mesh.colors)
    points, _ = fibonacci_sphere(50)
    cloud = sphcover.PointCloud(points=points, colors=np.full((50, 3), 9, dtype=np.uint8))
    again = sphcover.PointCloud.from_trimesh(cloud.to_trimesh())
    np.testing.assert_array_equal(again.points, points)
    np.testing.assert_array_equal(again.colors, cloud.colors)
    assert sphcover.PointCloud.from_trimesh(
        sphcover.PointCloud(points=points).to_trimesh()
    ).colors is None


def test_open3d_round_trip(mesh):
    o3d = pytest.importorskip("open3d", reason="open3d is not installed")
    m = mesh.to_open3d()
    assert isinstance(m, o3d.geometry.TriangleMesh)
    back = sphcover.Mesh.from_open3d(m)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(back.colors, mesh.colors)
    points, normals = fibonacci_sphere(100)
    colors = np.arange(300).reshape(100, 3).astype(np.uint8)
    pcd = sphcover.PointCloud(points=points, normals=normals, colors=colors).to_open3d()
    cloud = sphcover.PointCloud.from_open3d(pcd)
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.normals, normals)
    np.testing.assert_array_equal(cloud.colors, colors)


def test_a_missing_package_is_named():
    try:
        import open3d  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="open3d"):
            sphcover.PointCloud(points=np.zeros((1, 3))).to_open3d()
    else:
        pytest.skip("open3d is installed: nothing to name")
