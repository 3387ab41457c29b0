# Type stubs of the C++ extension rayscan._rayscan (python/src/*.cpp). The public names are
# re-exported and documented by rayscan/__init__.pyi; the underscore names are the package's own.
import os
from typing import Any, Mapping, Sequence, Union, overload

import numpy as np
import numpy.typing as npt

_Path = Union[str, os.PathLike[str]]
_Points = npt.ArrayLike  # (N, 3) real numbers

__version__: str


class PointCloud:
    """A point cloud read from a file or built from arrays; arrays as documented per property."""

    def __init__(
        self,
        xyz: _Points,
        rgb: npt.ArrayLike | None = None,
        intensity: npt.ArrayLike | None = None,
        classification: npt.ArrayLike | None = None,
        gps_time: npt.ArrayLike | None = None,
        normals: npt.ArrayLike | None = None,
        scalars: Mapping[str, npt.ArrayLike] | None = None,
        crs: str | None = None,
    ) -> None: ...
    @staticmethod
    def from_structured(array: np.ndarray, crs: str | None = None) -> PointCloud: ...
    def __len__(self) -> int: ...
    @overload
    def __getitem__(self, key: str) -> np.ndarray: ...
    @overload
    def __getitem__(self, key: slice | npt.ArrayLike) -> PointCloud: ...
    def take(self, indices: npt.ArrayLike) -> PointCloud: ...
    def __contains__(self, name: str) -> bool: ...
    @property
    def xyz(self) -> npt.NDArray[np.float64]: ...  # (N, 3) world units
    @property
    def rgb(self) -> npt.NDArray[np.uint16] | None: ...  # (N, 3) 0..65535
    @property
    def intensity(self) -> npt.NDArray[np.uint16] | None: ...  # (N,)
    @property
    def classification(self) -> npt.NDArray[np.uint8] | None: ...  # (N,)
    @property
    def gps_time(self) -> npt.NDArray[np.float64] | None: ...  # (N,) seconds
    @property
    def normals(self) -> npt.NDArray[np.float32] | None: ...  # (N, 3) unit vectors
    @property
    def scalars(self) -> Mapping[str, npt.NDArray[np.float64]]: ...  # name -> (N,), read-only
    @property
    def attributes(self) -> list[str]: ...
    @property
    def crs(self) -> str | None: ...  # WKT
    @property
    def epsg(self) -> int | None: ...
    @property
    def format(self) -> str | None: ...
    @property
    def point_format(self) -> int | None: ...
    @property
    def path(self) -> str | None: ...
    @property
    def bounds(self) -> npt.NDArray[np.float64]: ...  # (2, 3) [lo, hi]


class _Index:
    def __len__(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def type(self) -> str: ...
    def _ray_query(self, origins: _Points, directions: _Points, k: int | None = None, radius: float = ...,
                   t_min: float = ..., t_max: float = ..., order: str = "ray", any_hit: bool = False,
                   allow_all: bool = False, threads: int = 0) -> dict[str, np.ndarray]: ...
    def _knn(self, points: _Points, k: int | None = None, radius: float = ...,
             threads: int = 0) -> dict[str, np.ndarray]: ...
    def _box(self, lo: _Points, hi: _Points, threads: int = 0) -> dict[str, np.ndarray]: ...


class _Octree(_Index):
    def __init__(self, xyz: _Points, layout: str = "adaptive", capacity: int | None = None,
                 depth: int | None = None, max_depth: int | None = None, insertion: bool = False) -> None: ...
    @property
    def layout(self) -> str: ...
    @property
    def capacity(self) -> int | None: ...
    @property
    def node_count(self) -> int: ...
    @property
    def depth(self) -> int: ...


class _KdTree(_Index):
    def __init__(self, xyz: _Points, capacity: int | None = None) -> None: ...
    @property
    def capacity(self) -> int: ...
    @property
    def node_count(self) -> int: ...


class _BruteForce(_Index):
    def __init__(self, xyz: _Points) -> None: ...


class _Site:
    def __init__(self, path: _Path, cache: str = ...) -> None: ...
    def __len__(self) -> int: ...
    @property
    def storage(self) -> str: ...
    @property
    def path(self) -> str: ...
    @property
    def has_ids(self) -> bool: ...
    @property
    def closed(self) -> bool: ...
    def close(self) -> None: ...
    def _ray_query(self, origins: _Points, directions: _Points, k: int | None = None, radius: float = ...,
                   t_min: float = ..., t_max: float = ..., order: str = "ray", any_hit: bool = False,
                   allow_all: bool = False, threads: int = 0) -> dict[str, np.ndarray]: ...
    def _knn(self, points: _Points, k: int | None = None, radius: float = ...,
             threads: int = 0) -> dict[str, np.ndarray]: ...
    def _box(self, lo: _Points, hi: _Points, threads: int = 0) -> dict[str, np.ndarray]: ...


def _read(path: _Path, attributes: str | Sequence[str] | None = None) -> PointCloud: ...
def _write(path: _Path, cloud: PointCloud | _Points, fields: Mapping[str, npt.ArrayLike] = ...) -> None: ...
def _render(scene: Any, scene_json: str = "", cloud: Any = None, width: int | None = None,
            height: int | None = None, spp: int | None = None, seed: int | None = None,
            aovs: Sequence[str] = (), camera: _Path | None = None, threads: int = 0) -> dict[str, Any]: ...
def _ortho_map(cloud: Any, res: float, spp: int | None = None, seed: int | None = None,
               threads: int = 0, colour: str = "albedo") -> dict[str, Any]: ...
def _visibility(cloud: Any, observers: Any = None, radius: float | None = None, height: float | None = None,
                max_distance: float | None = None, tolerance: float | None = None,
                target_height: float | None = None, sky_rays: int = 0, camera: _Path | None = None,
                distance: bool = False, threads: int = 0, cache: str = "2G",
                ground_radius: float | None = None) -> dict[str, Any]: ...
SOLAR_PERIOD_FIELDS: tuple[str, ...]
SOLAR_INSTANT_FIELDS: tuple[str, ...]
def _opens_in_place(path: _Path) -> bool: ...
def _check_cache(cache: str) -> None: ...
def _check_visibility(observers: Any = None, radius: float | None = None, height: float | None = None,
                      max_distance: float | None = None, tolerance: float | None = None,
                      target_height: float | None = None, sky_rays: int = 0, camera: _Path | None = None,
                      distance: bool = False, threads: int = 0, cache: str = "2G",
                      ground_radius: float | None = None) -> None: ...
def _check_solar(start: str | None = None, end: str | None = None, step: str = "1h", at: str | None = None,
                 latitude: float | None = None, longitude: float | None = None,
                 linke: float | Sequence[float] = 3.0, albedo: float = 0.2, weather: _Path | None = None,
                 sector: float = 1.0, sky_rays: int = 64, primitive: str = "sphere", radius: float | None = None,
                 threads: int = 0, cache: str = "2G") -> None: ...
def _solar(cloud: Any, start: str | None = None, end: str | None = None, step: str = "1h", at: str | None = None,
           latitude: float | None = None, longitude: float | None = None, linke: float | Sequence[float] = 3.0,
           albedo: float = 0.2, weather: _Path | None = None, sector: float = 1.0, sky_rays: int = 64,
           primitive: str = "sphere", radius: float | None = None, threads: int = 0,
           cache: str = "2G") -> dict[str, Any]: ...
def _compare(reference: Any, image: Any, channels: Sequence[str] = (), mask: bool = False, alpha: bool = False,
             resize: bool = False, fail: float | None = None, fail_percent: float | None = None,
             fail_psnr: float | None = None, fail_ssim: float | None = None,
             warn: float | None = None) -> dict[str, Any]: ...
