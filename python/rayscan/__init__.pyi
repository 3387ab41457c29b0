# Type stubs of the rayscan package (python/rayscan/__init__.py documents each call: shapes,
# dtypes, units, errors). Arrays: "(N, 3)" means any array-like of real numbers of that shape;
# float64 C-contiguous arrays are used without a copy. Coordinates and distances are in the
# cloud's world units (its CRS's).
import os
from typing import Any, Literal, Mapping, Sequence, TypedDict, Union

import numpy as np
import numpy.typing as npt

from ._rayscan import PointCloud as PointCloud
from ._results import BoxResult as BoxResult
from ._results import NeighborResult as NeighborResult
from ._results import RayQueryResult as RayQueryResult

__version__: str
__all__: list[str]

_Path = Union[str, os.PathLike[str]]
_Points = npt.ArrayLike                       # (N, 3) or one (3,) row, real numbers
_Cloud = Union[_Path, PointCloud, npt.ArrayLike]  # a file, a PointCloud or (N, 3) positions
_Order = Literal["ray", "time", "sphere_hit"]


def read(path: _Path, attributes: str | Sequence[str] | None = None) -> PointCloud: ...
def write(path: _Path, cloud: PointCloud | npt.ArrayLike, **fields: npt.ArrayLike) -> None: ...
def open(path: _Path, cache: str = ...) -> Site: ...


class _QueriesMixin:
    def ray_query(self, origins: _Points, directions: _Points, k: int | None = None, radius: float = ...,
                  t_min: float = ..., t_max: float = ..., order: _Order = "ray", any_hit: bool = False,
                  threads: int = 0, allow_all: bool = False) -> RayQueryResult: ...
    def knn(self, points: _Points, k: int, radius: float = ..., threads: int = 0) -> NeighborResult: ...
    def radius(self, points: _Points, r: float, threads: int = 0) -> NeighborResult: ...
    def box(self, lo: _Points, hi: _Points, threads: int = 0) -> BoxResult: ...


class Octree(_QueriesMixin):
    def __init__(self, xyz: _Points | PointCloud, layout: Literal["adaptive", "layered", "fixed"] = "adaptive",
                 capacity: int | None = None, depth: int | None = None, max_depth: int | None = None,
                 insertion: bool = False) -> None: ...
    def __len__(self) -> int: ...
    @property
    def layout(self) -> str: ...
    @property
    def capacity(self) -> int | None: ...  # None for layout "fixed"
    @property
    def node_count(self) -> int: ...
    @property
    def depth(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def type(self) -> str: ...


class KdTree(_QueriesMixin):
    def __init__(self, xyz: _Points | PointCloud, capacity: int | None = None) -> None: ...
    def __len__(self) -> int: ...
    @property
    def capacity(self) -> int: ...
    @property
    def node_count(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def type(self) -> str: ...


class BruteForce(_QueriesMixin):
    def __init__(self, xyz: _Points | PointCloud) -> None: ...
    def __len__(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def type(self) -> str: ...


class Site(_QueriesMixin):
    def __init__(self, path: _Path, cache: str = ...) -> None: ...
    def __len__(self) -> int: ...
    @property
    def storage(self) -> Literal["index_file", "copc", "memory"]: ...
    @property
    def path(self) -> str: ...
    @property
    def has_ids(self) -> bool: ...  # False: results are index slots (an .rsi built without ids)
    @property
    def closed(self) -> bool: ...
    def close(self) -> None: ...
    def __enter__(self) -> Site: ...
    def __exit__(self, *exc: object) -> Literal[False]: ...


# Jobs (present when the module is built with the library's job API). Each returns a dict of
# NumPy arrays and numbers; see the docstrings for the keys.
def render(scene: _Path | dict[str, Any] | PointCloud | npt.ArrayLike, cloud: _Cloud | None = None,
           width: int | None = None, height: int | None = None, spp: int | None = None,
           seed: int | None = None, aovs: Sequence[str] = (), camera: _Path | None = None,
           threads: int = 0) -> dict[str, Any]: ...
class _OrthoMap(TypedDict):
    image: np.ndarray        # (rows, cols, 3) float32 linear RGB, row 0 the north edge
    coverage: np.ndarray     # (rows, cols) float32 in [0, 1]: the orthophoto GeoTIFF's alpha
    dsm: np.ndarray          # (rows, cols) float32 elevation, NaN = no surface
    geotransform: tuple[float, float, float, float, float, float]  # GDAL's, north-up
    crs: str | None          # WKT
    radius: float
def ortho_map(cloud: _Cloud, res: float, spp: int | None = None, seed: int | None = None,
              threads: int = 0, colour: Literal["albedo", "shaded"] = "albedo") -> _OrthoMap: ...
def visibility(cloud: _Cloud, observers: _Path | npt.ArrayLike | None = None, radius: float | None = None,
               height: float | None = None, max_distance: float | None = None, tolerance: float | None = None,
               target_height: float | None = None, sky_rays: int = 0, camera: _Path | None = None,
               distance: bool = False, threads: int = 0, cache: str = "2G",
               ground_radius: float | None = None) -> dict[str, Any]: ...
SOLAR_PERIOD_FIELDS: tuple[str, ...]
SOLAR_INSTANT_FIELDS: tuple[str, ...]
def solar(cloud: _Cloud, start: str | None = None, end: str | None = None, step: str = "1h",
          at: str | None = None, latitude: float | None = None, longitude: float | None = None,
          linke: float | Sequence[float] = 3.0, albedo: float = 0.2, weather: _Path | None = None,
          sector: float = 1.0, sky_rays: int = 64, primitive: Literal["sphere", "surfel"] = "sphere",
          radius: float | None = None, threads: int = 0, cache: str = "2G") -> dict[str, Any]: ...
def compare(reference: _Path | npt.ArrayLike, image: _Path | npt.ArrayLike, channels: Sequence[str] = (),
            mask: bool = False, alpha: bool = False, resize: bool = False, fail: float | None = None,
            fail_percent: float | None = None, fail_psnr: float | None = None, fail_ssim: float | None = None,
            warn: float | None = None) -> dict[str, Any]: ...
