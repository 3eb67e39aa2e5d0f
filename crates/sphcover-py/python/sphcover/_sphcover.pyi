"""Type stubs of the native module ``sphcover._sphcover`` (the Rust half of the package).

The public functions are those of ``sphcover`` itself, which wrap these with result classes.
"""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
U32 = npt.NDArray[np.uint32]
U8 = npt.NDArray[np.uint8]
ProgressCallback = Optional[Callable[[str, int, int], Any]]
Path = Union[str, "PathLike[str]"]

class BadInputError(ValueError):
    """The input or an option is unusable (the command line exits with 2)."""

class SphcoverError(RuntimeError):
    """A run failed for a reason other than its input (the command line exits with 1)."""

class Cover:
    """A spherical cover: balls with local functions blended by partition of unity."""

    def __len__(self) -> int: ...
    @property
    def centres(self) -> F64:
        """The support centres, ``(n, 3)``, in input coordinates."""
    @property
    def radii(self) -> F64:
        """The support radii, ``(n,)``, in input units."""
    @property
    def unit_centre(self) -> Tuple[float, float, float]:
        """The centre of the unit frame in input coordinates."""
    @property
    def unit_scale(self) -> float:
        """The length in input units of one unit of the unit frame."""
    @property
    def expansion(self) -> float:
        """The default expansion factor σ ≥ 1 of the supports when evaluating."""
    def evaluate(self, x: F64, sigma: Optional[float] = None) -> Tuple[F64, F64]:
        """``f`` (unit-frame units) and its gradient (with respect to input coordinates) at
        the rows of ``x``; NaN where no support reaches."""
    def write(self, path: Path, ascii: bool = False, notes: Sequence[str] = ()) -> None:
        """Writes the cover file (PLY)."""

class DualComplex:
    """The dual complex of a union of balls: the tetrahedral mesh of a cover."""

    @property
    def tets(self) -> U32:
        """The tetrahedra, ``(m, 4)`` ball indices, positively oriented."""
    @property
    def edges(self) -> U32:
        """The edges, ``(e, 2)`` ball indices."""
    @property
    def hidden(self) -> npt.NDArray[np.bool_]:
        """Per ball: True when it is no vertex of the complex."""
    @property
    def euler_characteristic(self) -> int: ...
    def write(self, path: Path) -> None:
        """Writes ``.vtk`` (VTK legacy unstructured grid) or ``.txt``/``.tets``."""

def read(
    path: Path, drop_non_finite: bool = False, max_memory: Union[None, int, str] = None
) -> Dict[str, Any]: ...
def write_geometry(
    path: Path,
    points: F64,
    triangles: Optional[U32] = None,
    normals: Optional[F64] = None,
    confidence: Optional[F64] = None,
    values: Optional[F64] = None,
    radii: Optional[F64] = None,
    colors: Optional[U8] = None,
    ascii: bool = False,
    single: bool = False,
) -> None: ...
def reconstruct(
    points: F64,
    normals: Optional[F64] = None,
    confidence: Optional[F64] = None,
    colors: Optional[U8] = None,
    *,
    method_name: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    trim_value: Union[None, bool, float] = None,
    depth: Optional[int] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    normal_neighbours: int = 12,
    estimate_normals: bool = False,
    refine: bool = True,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: ProgressCallback = None,
    max_memory: Union[None, int, str] = None,
    noise: Union[None, str, float] = None,
    tiles: Optional[Tuple[int, int, int]] = None,
    halo: Optional[float] = None,
    map_tiles: Optional[Callable[[List[bytes]], List[Optional[bytes]]]] = None,
    scratch: Optional[str] = None,
) -> Dict[str, Any]: ...
def reconstruct_file(
    path: str,
    *,
    tiles: Tuple[int, int, int],
    halo: Optional[float] = None,
    scratch: Optional[str] = None,
    method_name: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    trim_value: Union[None, bool, float] = None,
    depth: Optional[int] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    refine: bool = True,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: ProgressCallback = None,
    noise: Union[None, str, float] = None,
    map_tiles: Optional[Callable[[List[bytes]], List[bytes]]] = None,
) -> Dict[str, Any]: ...
def streamed_tile_bytes(
    task: bytes,
    *,
    method_name: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    seed: int = 0,
    noise: Union[None, str, float] = None,
    threads: Optional[int] = None,
) -> bytes: ...
def tile_function_bytes(
    tile: bytes,
    *,
    method_name: str = "integrated",
    eps: Optional[float] = None,
    k: Optional[float] = None,
    normal_fit: Optional[float] = None,
    position_fit: Optional[float] = None,
    seed: int = 0,
    noise: Union[None, str, float] = None,
    threads: Optional[int] = None,
) -> Optional[bytes]: ...
def skeleton_volume(
    values: npt.NDArray[np.float64],
    affine: F64,
    *,
    threshold: Optional[float] = None,
    material: str = "auto",
    sigma: Optional[float] = None,
    eps: Optional[float] = None,
    method: str = "ridge",
    seed: int = 0,
    threads: Optional[int] = None,
    progress: ProgressCallback = None,
) -> Dict[str, Any]: ...
def skeleton_samples(
    points: F64,
    values: F64,
    *,
    threshold: Optional[float] = None,
    sigma: Optional[float] = None,
    eps: Optional[float] = None,
    seed: int = 0,
    threads: Optional[int] = None,
    progress: ProgressCallback = None,
) -> Dict[str, Any]: ...
def surface_cover(
    points: F64, normals: F64, eps: Optional[float] = None, seed: int = 0
) -> Cover: ...
def volume_cover(
    values: npt.NDArray[np.float64],
    affine: F64,
    *,
    threshold: Optional[float] = None,
    eps: Optional[float] = None,
    linear: bool = False,
    centre_order: str = "random",
    elimination: str = "corners",
    seed: int = 0,
) -> Cover: ...
def scattered_cover(
    points: F64,
    values: F64,
    *,
    threshold: Optional[float] = None,
    eps: Optional[float] = None,
    linear: bool = False,
    centre_order: str = "random",
    elimination: str = "corners",
    seed: int = 0,
) -> Cover: ...
def operator_matrices(
    centres: F64,
    radii: F64,
    *,
    variant: str = "thesis",
    mass: str = "thesis",
    flux: str = "neighbour",
    shrink: float = 1.0,
) -> Dict[str, Tuple[F64, npt.NDArray[np.int64], npt.NDArray[np.int64], Tuple[int, int]]]: ...
def regular_triangulation(
    centres: F64, radii: F64, *, seed: Optional[int] = None
) -> Dict[str, Any]: ...
def dual_complex(
    centres: F64, radii: F64, *, shrink: float = 0.75, seed: int = 0
) -> DualComplex: ...
def keep_freed_memory() -> None:
    """Keeps freed memory in the process for reuse, as ``sphcover recon`` does (glibc's mmap
    threshold 32 MiB, trim threshold 1 GiB): faster reconstructions, a slightly higher peak
    resident set, for the whole process. A no-op where the C library is not glibc."""
