# Type stubs of rayscan.dask (python/rayscan/dask.py documents each call: shapes, dtypes, units).
# Arrays are (M, 3) / (K, 3) / (K, 2) NumPy or Dask arrays; results are Dask arrays, or NumPy
# arrays (a RayQueryResult for ray_query) with compute=True.
import os
from typing import Any, Literal, Sequence, Union

import numpy.typing as npt

from ._results import RayQueryResult

_Path = Union[str, os.PathLike[str]]
_Rays = Any  # (M, 3) NumPy or Dask array, or one (3,) row
_Order = Literal["ray", "time", "sphere_hit"]

__all__: list[str]


def ray_query(path: _Path, origins: _Rays, directions: _Rays, k: int | None = 1, radius: float = ...,
              t_min: float = ..., t_max: float = ..., order: _Order = "ray", any_hit: bool = False,
              threads: int = 1, allow_all: bool = False, cache: str = "2G", chunks: int = 100_000,
              compute: bool = False) -> dict[str, Any] | RayQueryResult: ...
def first_hits(path: _Path, origins: _Rays, directions: _Rays, radius: float, t_min: float = 0.0,
               t_max: float = ..., threads: int = 1, cache: str = "2G", chunks: int = 100_000,
               compute: bool = False) -> dict[str, Any] | RayQueryResult: ...
def visibility(path: _Path, observers: npt.ArrayLike, chunks: int = 8, radius: float | None = None,
               height: float | None = None, max_distance: float | None = None, tolerance: float | None = None,
               target_height: float | None = None, sky_rays: int = 0, distance: bool = False, threads: int = 1,
               cache: str = "2G", ground_radius: float | None = None, compute: bool = False) -> dict[str, Any]: ...
def solar(path: _Path, at: str | Sequence[str] | None = None,
          periods: tuple[str, str] | Sequence[tuple[str, str]] | None = None, step: str = "1h",
          latitude: float | None = None, longitude: float | None = None, linke: float | Sequence[float] = 3.0,
          albedo: float = 0.2, weather: _Path | None = None, sector: float = 1.0, sky_rays: int = 64,
          primitive: Literal["sphere", "surfel"] = "sphere", radius: float | None = None, threads: int = 1,
          cache: str = "2G", compute: bool = False) -> dict[str, Any]: ...
