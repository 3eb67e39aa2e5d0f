"""The result classes of sphcover, and their conversions to Open3D and trimesh.

Open3D and trimesh are optional: they are imported only when a conversion is asked for, and a
missing package raises ImportError naming it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Optional

import numpy as np

__all__ = ["Mesh", "PointCloud", "Spheres", "Volume"]


def _require(module: str):
    try:
        return __import__(module)
    except ImportError as e:  # pragma: no cover - the message is the point
        raise ImportError(
            f"this conversion needs the optional package {module!r} (pip install {module})"
        ) from e


@dataclass
class Mesh:
    """A triangle mesh.

    Attributes:
        vertices: ``(n, 3)`` float64 positions.
        faces: ``(m, 3)`` uint32 vertex indices, counter-clockwise seen from outside.
        normals: ``(n, 3)`` per-vertex normals, or None.
        values: ``(n,)`` per-vertex values, or None: the confidence of the surface for a
            reconstruction (``confidence`` names them too), the ridge strength for a sheet.
        stats: counts and per-stage timings of the run that made the mesh (the keys of the
            command line's ``--report`` JSON).
        point_confidence: for a reconstruction, the confidence of every input point.
        outliers: for a reconstruction, the outlier label of every input point.
        cover: for a reconstruction, the final :class:`Cover`.
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: Optional[np.ndarray] = None
    values: Optional[np.ndarray] = None
    stats: Dict[str, Any] = field(default_factory=dict)
    point_confidence: Optional[np.ndarray] = None
    outliers: Optional[np.ndarray] = None
    cover: Any = None

    @property
    def confidence(self) -> Optional[np.ndarray]:
        """The per-vertex values (for a reconstruction: the confidence of the surface)."""
        return self.values

    def __repr__(self) -> str:
        return f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces)"

    def to_open3d(self):
        """An ``open3d.geometry.TriangleMesh`` (values become grey vertex colours)."""
        o3d = _require("open3d")
        m = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.asarray(self.vertices, dtype=np.float64)),
            o3d.utility.Vector3iVector(np.asarray(self.faces, dtype=np.int32)),
        )
        if self.normals is not None:
            m.vertex_normals = o3d.utility.Vector3dVector(self.normals)
        if self.values is not None and len(self.values):
            v = np.asarray(self.values, dtype=np.float64)
            lo, hi = float(v.min()), float(v.max())
            grey = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
            m.vertex_colors = o3d.utility.Vector3dVector(np.repeat(grey[:, None], 3, axis=1))
        return m

    @classmethod
    def from_open3d(cls, mesh) -> "Mesh":
        """The mesh of an ``open3d.geometry.TriangleMesh`` (positions, triangles, normals)."""
        normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
        return cls(
            vertices=np.asarray(mesh.vertices, dtype=np.float64),
            faces=np.asarray(mesh.triangles, dtype=np.uint32),
            normals=normals if len(normals) else None,
        )

    def to_trimesh(self):
        """A ``trimesh.Trimesh`` (not processed: vertices and faces stay as they are);
        values go to ``vertex_attributes['values']``."""
        trimesh = _require("trimesh")
        attributes = {} if self.values is None else {"values": np.asarray(self.values)}
        return trimesh.Trimesh(
            vertices=np.asarray(self.vertices),
            faces=np.asarray(self.faces, dtype=np.int64),
            vertex_normals=None if self.normals is None else np.asarray(self.normals),
            vertex_attributes=attributes,
            process=False,
        )

    @classmethod
    def from_trimesh(cls, mesh) -> "Mesh":
        """The mesh of a ``trimesh.Trimesh``."""
        values = mesh.vertex_attributes.get("values") if mesh.vertex_attributes else None
        return cls(
            vertices=np.asarray(mesh.vertices, dtype=np.float64),
            faces=np.asarray(mesh.faces, dtype=np.uint32),
            values=None if values is None else np.asarray(values, dtype=np.float64),
        )


@dataclass
class PointCloud:
    """Points with optional per-point normals, confidence and scalar values."""

    points: np.ndarray
    normals: Optional[np.ndarray] = None
    confidence: Optional[np.ndarray] = None
    values: Optional[np.ndarray] = None
    stats: Dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        extra = [n for n in ("normals", "confidence", "values") if getattr(self, n) is not None]
        return f"PointCloud({len(self.points)} points{''.join(', ' + e for e in extra)})"

    def to_open3d(self):
        """An ``open3d.geometry.PointCloud`` (positions and normals)."""
        o3d = _require("open3d")
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))
        if self.normals is not None:
            pcd.normals = o3d.utility.Vector3dVector(self.normals)
        return pcd

    @classmethod
    def from_open3d(cls, pcd) -> "PointCloud":
        """The points (and normals, when it has them) of an ``open3d.geometry.PointCloud``."""
        normals = np.asarray(pcd.normals, dtype=np.float64)
        return cls(
            points=np.asarray(pcd.points, dtype=np.float64),
            normals=normals if len(normals) else None,
        )

    def to_trimesh(self):
        """A ``trimesh.PointCloud``."""
        trimesh = _require("trimesh")
        return trimesh.PointCloud(np.asarray(self.points))

    @classmethod
    def from_trimesh(cls, cloud) -> "PointCloud":
        """The points of a ``trimesh.PointCloud`` (or the vertices of a ``Trimesh``)."""
        return cls(points=np.asarray(cloud.vertices, dtype=np.float64))


@dataclass
class Spheres:
    """A set of balls: ``(n, 3)`` centres and ``(n,)`` radii."""

    centres: np.ndarray
    radii: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass
class Volume:
    """A voxel volume: ``values[i, j, k]`` is the voxel whose centre is at
    ``affine @ (i, j, k, 1)`` (the convention of nibabel's ``get_fdata()`` and ``affine``)."""

    values: np.ndarray
    affine: np.ndarray
    format: str = ""
