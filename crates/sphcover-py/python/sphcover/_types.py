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


def _open3d_colors(o3d, colors):
    """Open3D's colours: float64 in [0, 1]."""
    return o3d.utility.Vector3dVector(np.asarray(colors, dtype=np.float64) / 255.0)


def _from_open3d_colors(colors) -> Optional[np.ndarray]:
    c = np.asarray(colors, dtype=np.float64)
    return np.round(np.clip(c, 0.0, 1.0) * 255.0).astype(np.uint8) if len(c) else None


def _from_trimesh_colors(geometry) -> Optional[np.ndarray]:
    """The per-vertex colours of a trimesh geometry, when it has its own (trimesh makes up a
    default colour for geometry without)."""
    if hasattr(geometry, "colors"):  # a trimesh.PointCloud: an empty array when uncoloured
        colors = np.asarray(geometry.colors)
        return colors[:, :3].astype(np.uint8) if colors.ndim == 2 and len(colors) else None
    visual = getattr(geometry, "visual", None)
    if visual is None or getattr(visual, "kind", None) != "vertex":
        return None
    return np.asarray(visual.vertex_colors[:, :3], dtype=np.uint8)


@dataclass
class Mesh:
    """A triangle mesh.

    Attributes:
        vertices: ``(n, 3)`` float64 positions.
        faces: ``(m, 3)`` uint32 vertex indices, counter-clockwise seen from outside.
        normals: ``(n, 3)`` per-vertex normals, or None.
        values: ``(n,)`` per-vertex values, or None: the confidence of the surface for a
            reconstruction (``confidence`` names them too), the ridge strength for a sheet.
        colors: ``(n, 3)`` uint8 red, green, blue per vertex, or None: for a reconstruction
            of coloured points, the colour of the nearest inlier sample.
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
    colors: Optional[np.ndarray] = None
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
        """An ``open3d.geometry.TriangleMesh``: the colours as vertex colours, or without
        colours the values as grey levels."""
        o3d = _require("open3d")
        m = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.asarray(self.vertices, dtype=np.float64)),
            o3d.utility.Vector3iVector(np.asarray(self.faces, dtype=np.int32)),
        )
        if self.normals is not None:
            m.vertex_normals = o3d.utility.Vector3dVector(self.normals)
        if self.colors is not None:
            m.vertex_colors = _open3d_colors(o3d, self.colors)
        elif self.values is not None and len(self.values):
            v = np.asarray(self.values, dtype=np.float64)
            lo, hi = float(v.min()), float(v.max())
            grey = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
            m.vertex_colors = o3d.utility.Vector3dVector(np.repeat(grey[:, None], 3, axis=1))
        return m

    @classmethod
    def from_open3d(cls, mesh) -> "Mesh":
        """The mesh of an ``open3d.geometry.TriangleMesh`` (positions, triangles, normals,
        colours)."""
        normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
        return cls(
            vertices=np.asarray(mesh.vertices, dtype=np.float64),
            faces=np.asarray(mesh.triangles, dtype=np.uint32),
            normals=normals if len(normals) else None,
            colors=_from_open3d_colors(mesh.vertex_colors),
        )

    def to_trimesh(self):
        """A ``trimesh.Trimesh`` (not processed: vertices and faces stay as they are);
        values go to ``vertex_attributes['values']``, colours to the vertex colours."""
        trimesh = _require("trimesh")
        attributes = {} if self.values is None else {"values": np.asarray(self.values)}
        return trimesh.Trimesh(
            vertices=np.asarray(self.vertices),
            faces=np.asarray(self.faces, dtype=np.int64),
            vertex_normals=None if self.normals is None else np.asarray(self.normals),
            vertex_colors=None if self.colors is None else np.asarray(self.colors, dtype=np.uint8),
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
            colors=_from_trimesh_colors(mesh),
        )


@dataclass
class PointCloud:
    """Points with optional per-point normals, confidence, scalar values and colours
    (``(n, 3)`` uint8 red, green, blue)."""

    points: np.ndarray
    normals: Optional[np.ndarray] = None
    confidence: Optional[np.ndarray] = None
    values: Optional[np.ndarray] = None
    colors: Optional[np.ndarray] = None
    stats: Dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        extra = [
            n for n in ("normals", "confidence", "values", "colors") if getattr(self, n) is not None
        ]
        return f"PointCloud({len(self.points)} points{''.join(', ' + e for e in extra)})"

    def to_open3d(self):
        """An ``open3d.geometry.PointCloud`` (positions, normals, colours)."""
        o3d = _require("open3d")
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))
        if self.normals is not None:
            pcd.normals = o3d.utility.Vector3dVector(self.normals)
        if self.colors is not None:
            pcd.colors = _open3d_colors(o3d, self.colors)
        return pcd

    @classmethod
    def from_open3d(cls, pcd) -> "PointCloud":
        """The points (and normals and colours, when it has them) of an
        ``open3d.geometry.PointCloud``."""
        normals = np.asarray(pcd.normals, dtype=np.float64)
        return cls(
            points=np.asarray(pcd.points, dtype=np.float64),
            normals=normals if len(normals) else None,
            colors=_from_open3d_colors(pcd.colors),
        )

    def to_trimesh(self):
        """A ``trimesh.PointCloud`` (with the colours)."""
        trimesh = _require("trimesh")
        colors = None if self.colors is None else np.asarray(self.colors, dtype=np.uint8)
        return trimesh.PointCloud(np.asarray(self.points), colors=colors)

    @classmethod
    def from_trimesh(cls, cloud) -> "PointCloud":
        """The points (and colours) of a ``trimesh.PointCloud`` (or the vertices of a
        ``Trimesh``)."""
        return cls(
            points=np.asarray(cloud.vertices, dtype=np.float64),
            colors=_from_trimesh_colors(cloud),
        )


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
