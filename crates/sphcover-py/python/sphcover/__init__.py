"""sphcover: processing of scanned geometry with spherically supported functions.

Covers of space by balls, each carrying a small local function, blended by partition of unity
(after Y. Nagai, "Processing of Scanned Geometry Using Spherically Supported Functions",
2010): surface reconstruction from scanned points, skeletal sheets from CT volumes, discrete
differential operators, regular triangulations. NumPy arrays in and out.

Long calls (``reconstruct``, ``skeleton``, ``skeleton_from_samples``, ``cover``,
``operators``, ``regular_triangulation``, ``dual_complex``) run with the GIL released, and Ctrl-C ends them
within a twentieth of a second. Errors are :class:`BadInputError` (a ``ValueError``: what the
command line exits with 2 for) and :class:`SphcoverError` (a ``RuntimeError``), with the
command line's messages.

See ``docs/python.md`` in the repository for a guide.
"""

from __future__ import annotations

import os
import sys
from typing import Any, Callable, NamedTuple, Optional, Union

import numpy as np

from . import _sphcover
from ._sphcover import BadInputError, Cover, DualComplex, SphcoverError, keep_freed_memory
from ._types import Mesh, PointCloud, Spheres, Volume

__all__ = [
    "BadInputError",
    "Cover",
    "DualComplex",
    "Mesh",
    "Operators",
    "PointCloud",
    "SphcoverError",
    "Spheres",
    "Volume",
    "cover",
    "dual_complex",
    "keep_freed_memory",
    "operators",
    "read",
    "reconstruct",
    "reconstruct_file",
    "regular_triangulation",
    "skeleton",
    "skeleton_from_samples",
    "tile_function",
    "streamed_tile_function",
    "dask_map_tiles",
    "write",
]

Progress = Union[None, bool, Callable[[str, int, int], Any]]


def _points(a, name: str = "points") -> np.ndarray:
    """An ``(n, 3)`` C-contiguous float64 array (no copy when ``a`` already is one)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise BadInputError(f"{name} must have shape (n, 3), not {a.shape}")
    return a


def _vector(a, name: str) -> Optional[np.ndarray]:
    return None if a is None else np.ascontiguousarray(a, dtype=np.float64).reshape(-1)


def _colors(a) -> Optional[np.ndarray]:
    """An ``(n, 3)`` C-contiguous uint8 array of colours; floats in [0, 1] (Open3D's
    convention) are scaled to 0–255."""
    if a is None:
        return None
    a = np.asarray(a)
    if a.ndim != 2 or a.shape[1] != 3:
        raise BadInputError(f"colors must have shape (n, 3), not {a.shape}")
    if np.issubdtype(a.dtype, np.floating):
        a = np.round(np.clip(a, 0.0, 1.0) * 255.0)
    elif a.size and (a.min() < 0 or a.max() > 255):
        raise BadInputError("colors must be 0–255 integers or floats in [0, 1]")
    return np.ascontiguousarray(a, dtype=np.uint8)


def _progress(progress: Progress):
    """The callback for ``progress``: None or False (quiet), a callable ``(stage, index,
    count)``, or True (a tqdm bar when tqdm is installed, else one line per stage on
    stderr)."""
    if progress is None or progress is False:
        return None, None
    if callable(progress):
        return progress, None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        def lines(name, index, count):
            print(f"[{index + 1}/{count}] {name}", file=sys.stderr, flush=True)

        return lines, None
    bar = tqdm(total=None, unit="stage")

    def advance(name, index, count):
        bar.total = count
        bar.n = index
        bar.set_description(name)
        bar.refresh()

    return advance, bar


def _with_progress(progress: Progress, call):
    callback, bar = _progress(progress)
    try:
        return call(callback)
    finally:
        if bar is not None:
            bar.close()


def read(path, *, drop_non_finite: bool = False, max_memory: Union[None, int, str] = None):
    """Reads any file the command line reads, the format from the extension.

    Returns a :class:`Mesh` (a file with faces: PLY, OBJ, OFF, STL), a :class:`PointCloud`
    (points: PLY, OBJ, OFF, XYZ/PWN, LAS), :class:`Spheres` (a sphere set: ``.sph``,
    ``.spheres``, 4-column ``.txt``, PLY with ``radius``), a :class:`Cover` (a cover file) or
    a :class:`Volume` (NIfTI-1/2 ``.nii``/``.nii.gz``, INRIMAGE ``.inr``/``.inr.gz``).

    ``drop_non_finite`` drops vertices with NaN or infinite coordinates instead of refusing
    the file, and sets non-finite voxels of a volume to its lowest finite value (the command
    line's ``--drop-non-finite``). ``max_memory`` (bytes, or a size such as ``"4G"``) bounds
    what the file may declare; by default 60% of the memory this process may use (the least
    of the machine's, its cgroup's and ``ulimit -v``), so that a decompression bomb or a lying
    header raises :class:`BadInputError` naming the file instead of exhausting memory.
    """
    d = _sphcover.read(str(path), drop_non_finite, max_memory)
    kind = d["kind"]
    if kind == "volume":
        return Volume(values=d["values"], affine=d["affine"], format=d["format"])
    if kind == "cover":
        return d["cover"]
    if "radii" in d:
        return Spheres(centres=d["points"], radii=d["radii"])
    if len(d["triangles"]):
        return Mesh(
            vertices=d["points"],
            faces=d["triangles"],
            normals=d.get("normals"),
            values=d.get("values"),
            colors=d.get("colors"),
        )
    return PointCloud(
        points=d["points"],
        normals=d.get("normals"),
        confidence=d.get("confidence"),
        values=d.get("values"),
        colors=d.get("colors"),
    )


def write(path, data, *, ascii: bool = False, single: bool = False) -> None:
    """Writes ``data`` to ``path`` in the format its extension names, as the command line
    writes it: PLY binary little-endian with float64 numbers (``ascii``, ``single`` for ascii
    and float32), OBJ, OFF, STL, XYZ/PWN, sphere sets, cover files, and for a
    :class:`DualComplex` ``.vtk`` or ``.txt``/``.tets``.

    ``data`` is a :class:`Mesh`, :class:`PointCloud`, :class:`Spheres`, :class:`Cover` or
    :class:`DualComplex`. The file appears whole or not at all.

    A mesh keeps its per-vertex values and colours in PLY and VTK XML only; as ``sphcover
    recon`` does, other formats get the mesh without them (and STL, which has no per-vertex
    normals, without normals). A point cloud's attributes that the format cannot hold are
    refused.
    """
    path = str(path)
    if isinstance(data, (Cover, DualComplex)):
        if isinstance(data, Cover):
            data.write(path, ascii=ascii)
        else:
            data.write(path)
        return
    if isinstance(data, Mesh):
        _sphcover.write_geometry(
            path,
            _points(data.vertices, "vertices"),
            triangles=np.ascontiguousarray(data.faces, dtype=np.uint32),
            normals=None if data.normals is None else _points(data.normals, "normals"),
            values=_vector(data.values, "values"),
            colors=_colors(data.colors),
            ascii=ascii,
            single=single,
        )
        return
    if isinstance(data, PointCloud):
        _sphcover.write_geometry(
            path,
            _points(data.points),
            normals=None if data.normals is None else _points(data.normals, "normals"),
            confidence=_vector(data.confidence, "confidence"),
            values=_vector(data.values, "values"),
            colors=_colors(data.colors),
            ascii=ascii,
            single=single,
        )
        return
    if isinstance(data, Spheres):
        _sphcover.write_geometry(
            path, _points(data.centres, "centres"), radii=_vector(data.radii, "radii"),
            ascii=ascii, single=single,
        )
        return
    raise TypeError(
        f"cannot write a {type(data).__name__}: give a Mesh, PointCloud, Spheres, Cover or DualComplex"
    )


def reconstruct(
    points,
    normals=None,
    *,
    confidence=None,
    colors=None,
    method: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    trim: Union[None, bool, float] = None,
    depth: Optional[int] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    normal_neighbours: int = 12,
    estimate_normals: bool = False,
    refine: bool = True,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: Progress = None,
    max_memory: Union[None, int, str] = None,
    noise: Union[None, str, float] = None,
    tiles: Union[None, int, tuple] = None,
    halo: Optional[float] = None,
    client: Any = None,
    map_tiles: Optional[Callable[[list], list]] = None,
    scratch: Union[None, str, "os.PathLike[str]"] = None,
) -> Mesh:
    """Reconstructs a surface mesh from scanned points, as ``sphcover recon`` does.

    ``points`` is an ``(n, 3)`` array (or a :class:`PointCloud`, whose normals, confidence
    and colours are then used); ``normals`` an ``(n, 3)`` array of outward normals, estimated
    when absent; ``colors`` ``(n, 3)`` red, green, blue (uint8, or floats in [0, 1]), carried
    to the vertices (the colour of the nearest inlier sample).
    Keywords are the command line's options: ``method`` (``"integrated"``, ``"graphcut"``,
    ``"diffusion"``, ``"pu"``), ``eps`` (cover tolerance relative to the longest bounding-box
    edge, used as given), ``noise`` (``"auto"``: ε at least 4× the measured noise, the default
    without ``eps``; ``"off"``: ε as given, the default with ``eps``; a number: the noise σ to
    keep to), ``k`` (graph-cut ratio), ``trim`` (True: drop surface farther than 3 sample
    spacings from every sample; a number: that distance relative to the longest edge),
    ``depth``, ``normal_fit``, ``position_fit``, ``normal_neighbours``, ``estimate_normals``,
    ``refine`` (False is ``--no-refine``), ``seed``; ``threads`` the worker threads (the
    result does not depend on it); ``progress`` a callable ``(stage, index, count)`` or True
    for a progress bar; ``max_memory`` (bytes, or a size such as ``"4G"``) the budget of the
    run's predicted peak memory: over it, a coarser default depth that fits is used (with a
    ``UserWarning``), and a given ``depth`` that does not fit, or no depth at all, raises
    :class:`BadInputError` before any work (``stats["memory"]`` records the decision); the
    budget is checked again once the cover's graph is built, and a cover that does not fit
    raises :class:`BadInputError` with its size and the remedies.

    ``tiles`` (``N`` for N×N×N, or ``(nx, ny, nz)``) builds the cover and its function tile
    by tile, each from the samples of its box and a ``halo`` (relative to the longest
    bounding-box edge; default a fifth of a tile's width, at most 0.1), as ``sphcover recon --tiles`` does. The tiles run one after the other
    in this process; with ``client`` (a ``dask.distributed.Client``) they run as tasks of
    that cluster (see :func:`dask_map_tiles`), and a task whose worker dies runs again
    elsewhere. ``map_tiles`` runs them on any other engine: it takes the list of tile inputs
    (bytes) and returns the list of :func:`tile_function` results, in order. With
    ``scratch`` (a directory the workers can read, such as a shared file system) the inputs
    are written there one at a time and the engine gets their paths, so this process never
    holds them all; they are removed after the run. The surface is the same, byte for byte,
    whichever ran the tiles.

    Returns a :class:`Mesh` with per-vertex normals, the per-vertex confidence of the surface
    as ``values`` (``confidence``), the statistics, and ``point_confidence``, ``outliers``,
    ``cover`` of the input points. Written with :func:`write` to PLY it is the command line's
    file byte for byte.
    """
    if isinstance(points, PointCloud):
        cloud = points
        points = cloud.points
        normals = cloud.normals if normals is None else normals
        confidence = cloud.confidence if confidence is None else confidence
        colors = cloud.colors if colors is None else colors
    if isinstance(tiles, int):
        tiles = (tiles, tiles, tiles)
    options = dict(
        method_name=method,
        eps=eps,
        k=k,
        normal_fit=normal_fit,
        position_fit=position_fit,
        seed=seed,
        noise=noise,
    )
    run_tiles = _tile_runner(client, map_tiles, tile_function, options)
    d = _with_progress(
        progress,
        lambda callback: _sphcover.reconstruct(
            _points(points),
            None if normals is None else _points(normals, "normals"),
            _vector(confidence, "confidence"),
            _colors(colors),
            method_name=method,
            eps=eps,
            k=k,
            trim_value=trim,
            depth=depth,
            normal_fit=normal_fit,
            position_fit=position_fit,
            normal_neighbours=normal_neighbours,
            estimate_normals=estimate_normals,
            refine=refine,
            seed=seed,
            threads=threads,
            progress=callback,
            max_memory=max_memory,
            noise=noise,
            tiles=None if tiles is None else tuple(int(t) for t in tiles),
            halo=halo,
            map_tiles=run_tiles,
            scratch=None if scratch is None else os.fspath(scratch),
        ),
    )
    return Mesh(
        vertices=d["vertices"],
        faces=d["faces"],
        normals=d.get("normals"),
        values=d.get("confidence"),
        colors=d.get("colors"),
        stats=d["stats"],
        point_confidence=d["point_confidence"],
        outliers=d["outliers"],
        cover=d["cover"],
    )


def reconstruct_file(
    path,
    *,
    tiles: Union[int, tuple],
    halo: Optional[float] = None,
    scratch: Union[None, str, "os.PathLike[str]"] = None,
    method: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    trim: Union[None, bool, float] = None,
    depth: Optional[int] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    refine: bool = True,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: Progress = None,
    noise: Union[None, str, float] = None,
    client: Any = None,
    map_tiles: Optional[Callable[[list, dict], list]] = None,
) -> Mesh:
    """Reconstructs the surface of a scan file larger than memory, as ``sphcover recon
    --tiles N --stream`` does: the file (binary PLY, LAS or LAZ) is read a block
    at a time into tile files in ``scratch`` (default: the system's temporary directory;
    about 48 bytes per sample and tile that reads it), and every pass over the samples reads
    one tile file, so this process holds one tile's samples, the tiles' functions and the
    surface, never the whole scan. ``tiles`` is ``N`` (N×N×N) or ``(nx, ny, nz)``; the other
    keywords are those of :func:`reconstruct`.

    With ``client`` (a ``dask.distributed.Client``) the tiles' functions, the longest part of
    the run, are tasks of that cluster (:func:`streamed_tile_function`); ``scratch`` must then
    be a directory every worker sees under the same path. ``map_tiles`` runs them on any
    other engine: ``(tasks, options) -> products`` over lists of bytes, in order.

    Returns a :class:`Mesh` with per-vertex normals, the confidence of the surface as
    ``values`` and the statistics (no per-point labels or cover: those would take memory in
    proportion to the scan). Normals the file lacks are estimated tile by tile.
    """
    if isinstance(tiles, int):
        tiles = (tiles, tiles, tiles)
    options = dict(
        method_name=method,
        eps=eps,
        k=k,
        normal_fit=normal_fit,
        position_fit=position_fit,
        seed=seed,
        noise=noise,
    )
    run_tiles = _tile_runner(client, map_tiles, streamed_tile_function, options)
    d = _with_progress(
        progress,
        lambda callback: _sphcover.reconstruct_file(
            os.fspath(path),
            tiles=tuple(int(t) for t in tiles),
            halo=halo,
            scratch=None if scratch is None else os.fspath(scratch),
            method_name=method,
            eps=eps,
            k=k,
            trim_value=trim,
            depth=depth,
            normal_fit=normal_fit,
            position_fit=position_fit,
            refine=refine,
            seed=seed,
            threads=threads,
            progress=callback,
            noise=noise,
            map_tiles=run_tiles,
        ),
    )
    return Mesh(
        vertices=d["vertices"],
        faces=d["faces"],
        normals=d.get("normals"),
        values=d.get("confidence"),
        stats=d["stats"],
    )


def _tile_runner(client, map_tiles, function, options: dict):
    """What the native run hands its tiles to: ``map_tiles`` (or, with ``client``, a Dask map
    of ``function``) with the tiles' ``options`` bound; None to run them in this process."""
    if client is not None and map_tiles is None:
        map_tiles = dask_map_tiles(client, function=function)
    if map_tiles is None:
        return None
    return lambda tiles: map_tiles(tiles, options)


def tile_function(tile, options: dict) -> Optional[bytes]:
    """One tile's function from its input (bytes, or the path of a file holding them, as
    ``map_tiles`` receives them) and the reconstruction's options: bytes, or None for a tile
    with too few samples for a cover. It depends on nothing else, so any worker of any engine
    gives the same bytes."""
    if isinstance(tile, (str, os.PathLike)):
        with open(tile, "rb") as f:
            tile = f.read()
    return _sphcover.tile_function_bytes(tile, **options)


def streamed_tile_function(task: bytes, options: dict) -> bytes:
    """One tile of :func:`reconstruct_file` from its task (bytes, as ``map_tiles`` receives
    them) and the reconstruction's options: its product, bytes. It reads the tile's file and
    stores its samples' labels beside it, in the run's scratch directory, so the worker must
    see that directory (a shared file system). It depends on nothing else, so any worker
    gives the same bytes, also when it runs again after another worker died."""
    return _sphcover.streamed_tile_bytes(task, **options)


def dask_map_tiles(client, retries: int = 2, function: Callable = tile_function):
    """A ``map_tiles`` for :func:`reconstruct` that runs the tiles as tasks of a Dask
    cluster: ``client.map`` of ``function`` (:func:`tile_function`, or
    :func:`streamed_tile_function` for :func:`reconstruct_file`) over the inputs, then
    ``client.gather``. A task whose worker dies is rescheduled by Dask's scheduler; one that
    raises is tried ``retries`` more times."""

    def map_tiles(inputs, options):
        futures = client.map(function, inputs, options=options, pure=False, retries=retries)
        return client.gather(futures)

    return map_tiles


def skeleton(
    volume,
    affine=None,
    *,
    threshold: Optional[float] = None,
    material: str = "auto",
    sigma: Optional[float] = None,
    eps: Optional[float] = None,
    method: str = "ridge",
    seed: int = 0,
    threads: Optional[int] = None,
    progress: Progress = None,
):
    """The skeletal sheet (mid-surface) of a thin part in a CT volume, as ``sphcover
    skeleton`` extracts it.

    ``volume`` is a :class:`Volume` or an ``(nx, ny, nz)`` array indexed ``[i, j, k]`` with
    ``affine`` the 4×4 voxel-to-world matrix (identity when omitted): what nibabel's
    ``img.get_fdata()`` and ``img.affine`` give. The object is brighter than the background.
    Keywords are the command line's: ``threshold`` (default: from the histogram),
    ``material`` (on a CT in Hounsfield units: ``"auto"``, ``"bone"``, ``"tissue"`` or
    ``"off"``; ``stats["material"]`` says what was chosen and why), ``sigma``, ``eps``,
    ``method`` (``"ridge"``, or ``"nms"`` for the baseline's ridge points), ``seed``.
    As the command line does, the grid is checked first: voxels more than 8:1 anisotropic or
    axes oblique to the world's raise :class:`BadInputError` (resample first), several frames
    too; voxels more than 1.75:1 apart are resampled along the coarse axes (Catmull–Rom, same
    world frame) and give a ``UserWarning`` saying how, as do voxels processed though not
    cubic.

    Returns a :class:`Mesh` in world coordinates (per-vertex values: the ridge strength), or
    for ``method="nms"`` a :class:`PointCloud`.
    """
    if isinstance(volume, Volume):
        volume, affine = volume.values, volume.affine if affine is None else affine
    values = np.asarray(volume, dtype=np.float64)
    if values.ndim == 4 and values.shape[3] > 1:
        raise BadInputError(
            f"a 4D volume with {values.shape[3]} frames; extract the frame to process first "
            "(volume[..., 0])"
        )
    if values.ndim == 4:
        values = values[..., 0]
    if values.ndim != 3:
        raise BadInputError(f"volume must be a 3-D array, not {values.ndim}-D")
    affine = np.eye(4) if affine is None else np.ascontiguousarray(affine, dtype=np.float64)
    d = _with_progress(
        progress,
        lambda callback: _sphcover.skeleton_volume(
            values, affine, threshold=threshold, material=material, sigma=sigma, eps=eps,
            method=method, seed=seed, threads=threads, progress=callback,
        ),
    )
    if method == "nms":
        return PointCloud(points=d["points"], stats=d["stats"])
    return _sheet(d)


def skeleton_from_samples(
    points,
    values,
    *,
    threshold: Optional[float] = None,
    sigma: Optional[float] = None,
    eps: Optional[float] = None,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: Progress = None,
) -> Mesh:
    """The skeletal sheet of scattered samples with values (``(n, 3)`` points off any grid,
    ``(n,)`` values), as ``sphcover skeleton --value-property`` extracts it; lengths in voxels
    become multiples of the median distance between nearest samples."""
    d = _with_progress(
        progress,
        lambda callback: _sphcover.skeleton_samples(
            _points(points), _vector(values, "values"), threshold=threshold, sigma=sigma,
            eps=eps, seed=seed, threads=threads, progress=callback,
        ),
    )
    return _sheet(d)


def _sheet(d) -> Mesh:
    return Mesh(
        vertices=d["vertices"],
        faces=d["faces"],
        normals=d.get("normals"),
        values=d.get("values"),
        stats=d["stats"],
    )


def cover(
    points,
    normals=None,
    *,
    eps: Optional[float] = None,
    seed: int = 0,
    values=None,
    affine=None,
    threshold: Optional[float] = None,
    linear: bool = False,
    centre_order: str = "random",
    elimination: str = "corners",
) -> Cover:
    """A spherical cover, as ``sphcover cover`` builds it, of one of three inputs:

    * oriented points (thesis §3.4.1): ``points`` ``(n, 3)`` and outward ``normals`` (or a
      :class:`PointCloud` with normals); balls whose local functions fit the points to ``eps``
      (relative to the longest bounding-box edge, default 2.5e-3);
    * a voxel volume (thesis §3.4.2): ``points`` a :class:`Volume` or an ``(nx, ny, nz)``
      array with ``affine`` (identity when omitted), in world coordinates;
    * scattered samples with values: ``points`` ``(n, 3)`` and ``values`` ``(n,)``
      (``sphcover cover --value-property``).

    The volume covers take the command line's ``threshold`` (in the values' units; default
    from the histogram), ``eps`` (RMS tolerance as a fraction of the value range, default
    0.05), ``linear`` (the thesis' linear functions over the bounding box), ``centre_order``
    (``"random"``, ``"deepest"``, ``"greedy"``) and ``elimination`` (``"off"``,
    ``"centres"``, ``"corners"``).

    ``Cover.evaluate(x)`` gives the implicit function ``f`` (positive inside) and its
    gradient at the rows of ``x``.
    """
    volume_options = dict(
        threshold=threshold, eps=eps, linear=linear, centre_order=centre_order,
        elimination=elimination, seed=seed,
    )
    if isinstance(points, Volume):
        points, affine = points.values, points.affine if affine is None else affine
    if isinstance(points, np.ndarray) and points.ndim == 3:
        affine = np.eye(4) if affine is None else np.ascontiguousarray(affine, dtype=np.float64)
        return _sphcover.volume_cover(
            np.asarray(points, dtype=np.float64), affine, **volume_options
        )
    if values is not None:
        return _sphcover.scattered_cover(
            _points(points), _vector(values, "values"), **volume_options
        )
    if threshold is not None or linear or centre_order != "random" or elimination != "corners":
        raise BadInputError(
            "threshold, linear, centre_order and elimination apply to volumes and to "
            "scattered samples (values=...) only"
        )
    if isinstance(points, PointCloud):
        points, normals = points.points, points.normals if normals is None else normals
    if normals is None:
        raise BadInputError(
            "the points have no normals: the surface cover needs outward normals "
            "(estimating them from unoriented points is part of reconstruct)"
        )
    return _sphcover.surface_cover(_points(points), _points(normals, "normals"), eps=eps, seed=seed)


class Operators(NamedTuple):
    """``Grad`` (``3n × n``), ``Div`` (``n × 3n``) and ``Lap`` (``n × n``) as
    ``scipy.sparse.csr_matrix``; vector fields are ``(n, 3)`` arrays flattened row by row
    (``v.reshape(-1)``), so ``(grad @ u).reshape(-1, 3)`` is the gradient at each centre."""

    grad: Any
    div: Any
    lap: Any


def operators(
    centres,
    radii=None,
    *,
    variant: str = "thesis",
    mass: str = "thesis",
    flux: str = "neighbour",
    shrink: float = 1.0,
) -> Operators:
    """The discrete differential operators of a set of balls (thesis §4) as SciPy sparse
    matrices, at the balls' centres.

    ``centres`` is an ``(n, 3)`` array with ``radii`` ``(n,)``, or a :class:`Cover` (its
    supports in input coordinates) or :class:`Spheres`. ``variant="thesis"`` is the thesis'
    form (``mass`` ``"thesis"`` or ``"moment"``, ``flux`` ``"neighbour"`` or ``"central"``);
    ``variant="consistent"`` the second-order least-squares family, exact on quadratics.
    Neighbours are the balls that intersect after scaling the radii by ``shrink``.

    Needs SciPy.
    """
    import scipy.sparse

    if isinstance(centres, Cover):
        centres, radii = centres.centres, centres.radii
    elif isinstance(centres, Spheres):
        centres, radii = centres.centres, centres.radii
    if radii is None:
        raise BadInputError("radii are needed with an array of centres")
    d = _sphcover.operator_matrices(
        _points(centres, "centres"), _vector(radii, "radii"),
        variant=variant, mass=mass, flux=flux, shrink=shrink,
    )

    def csr(parts):
        data, indices, indptr, shape = parts
        return scipy.sparse.csr_matrix((data, indices, indptr), shape=shape)

    return Operators(grad=csr(d["grad"]), div=csr(d["div"]), lap=csr(d["lap"]))


def regular_triangulation(centres, radii, *, seed: Optional[int] = None) -> np.ndarray:
    """The finite tetrahedra, ``(m, 4)`` uint32 indices, of the regular (weighted Delaunay)
    triangulation of the balls with weights ``radii²``. Exact predicates; the result does
    not depend on ``seed``."""
    d = _sphcover.regular_triangulation(
        _points(centres, "centres"), _vector(radii, "radii"), seed=seed
    )
    return d["tets"]


def dual_complex(centres, radii=None, *, shrink: float = 0.75, seed: int = 0) -> DualComplex:
    """The dual complex of a union of balls (thesis §3.5), as ``sphcover tetra`` builds it:
    the tetrahedral mesh of a cover. ``centres`` may be a :class:`Cover` or
    :class:`Spheres`; ``shrink`` scales the radii before triangulating (default 0.75)."""
    if isinstance(centres, (Cover, Spheres)):
        centres, radii = centres.centres, centres.radii
    if radii is None:
        raise BadInputError("radii are needed with an array of centres")
    return _sphcover.dual_complex(
        _points(centres, "centres"), _vector(radii, "radii"), shrink=shrink, seed=seed
    )
