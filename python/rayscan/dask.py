"""rayscan over Dask collections: ray queries, first hits, visibility for many observers and solar
instants mapped over the workers of a Dask cluster (local processes or a distributed one).

    >>> from distributed import Client, LocalCluster
    >>> import dask.array as da, rayscan.dask as rd
    >>> client = Client(LocalCluster(n_workers=2, threads_per_worker=1))     # doctest: +SKIP
    >>> o = da.from_array(origins, chunks=(100_000, 3))                        # doctest: +SKIP
    >>> hit = rd.first_hits("site.rsi", o, directions, radius=0.5)           # doctest: +SKIP
    >>> index, t = dask.compute(hit["indices"], hit["t"])                     # doctest: +SKIP
    >>> seen = rd.visibility("site.rsi", observers, chunks=16, compute=True)  # doctest: +SKIP

Every task opens the point file by its path (rayscan.open: an .rsi index file is memory-mapped,
a COPC file read in place), so nothing is pickled but the path, the options and the query arrays
of the task; the file must be readable under the same path on every worker (a shared or local
file system). Each worker process opens a file once and keeps the Site for its later tasks
while the file stays the same: a task that finds another file under the path (another device,
inode, size or modification time, as after `rayscan index -o` over it or a copy onto it) opens
it anew. A file rewritten in place while a task reads it is not safe, as for one process: write
a new file and rename it over the old one (as `rayscan index` and `translate` do).
The C++ calls release the GIL, so a worker with several threads runs several chunks at once.
`threads` is the number of TBB threads of each task (default 1: Dask's workers are the
parallelism; 0 = all cores of the worker's machine).

Every answer equals the single-process call (rayscan.open(path).ray_query, rayscan.visibility,
rayscan.solar) bit for bit: each ray, observer or instant is computed alone there too, and the
merges only concatenate or add integer counts.

Needs Dask (Debian 12: apt-get install python3-dask python3-distributed); `import rayscan` does not.
"""

try:
    import dask
    import dask.array as da
except ImportError as e:  # rayscan itself never needs Dask; this module does
    raise ImportError(
        "rayscan.dask needs Dask: install the Debian packages python3-dask and python3-distributed "
        "(apt-get install python3-dask python3-distributed) or `pip install dask distributed`") from e

import contextlib
import operator
import os
import re
import threading

import numpy as np

import rayscan
from rayscan import _INF  # the module's one infinity default
from ._results import RayQueryResult

__all__ = ["ray_query", "first_hits", "visibility", "solar"]


def _integer(value, name, expected, least):
    """`value` as an int by the rule of the module's other calls (python/src/arrays.cpp): any
    integer (int, NumPy integers: operator.index) but a bool, else TypeError naming `name`;
    ValueError below `least`."""
    try:
        if isinstance(value, (bool, np.bool_)):
            raise TypeError
        i = operator.index(value)
    except TypeError:
        raise TypeError(f"{name} must be {expected}, got {type(value).__name__}") from None
    if i < least:
        raise ValueError(f"{name} must be {expected}, got {i!r}")
    return i


def _boolean(value, name):
    """`value` as a bool by the rule of the module's other calls (python/src/arrays.cpp): True or
    False, a NumPy bool too, else TypeError naming `name` (a text "no" would be true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {type(value).__name__}")
    return bool(value)


_NO_ROWS = np.empty((0, 3))


def _check_ray_query(kw):
    """Raises at the call what Site.ray_query raises in a task for the options `kw` (every argument
    but the rays, which Dask holds until the chunks run, and the file): a bad order, a radius,
    t_min or t_max of the wrong type or range, t_min > t_max, 'sphere_hit' without a finite
    radius, neither k nor a finite radius without allow_all, a bad threads or k. The same binding
    asked the same query for no rays over no points makes these checks, in its own words."""
    rayscan.BruteForce(_NO_ROWS)._ray_query(_NO_ROWS, _NO_ROWS, **kw)


# ---- worker side: one Site per file and process ------------------------------------------------

_sites = {}
_sites_lock = threading.Lock()


def _site(path, cache):
    """The Site of `path` in this process, opened on first use and again whenever the file
    under the path is another one: a Site maps or reads the file it opened, so one kept after
    `rayscan index -o` replaced the file (a new inode) would answer from the old points, and one
    kept after a copy onto the file (same inode, another size) would read past its end. The file
    is told by (device, inode, size, modification time in ns), taken before opening, so that a
    change between the two reopens once more rather than keeping the new points under the old
    key. A COPC Site trims its node cache after each query, which must not overlap another query
    on the same Site: its queries take a lock (an .rsi or in-memory Site answers concurrent
    queries from several threads). Raises what rayscan.open raises (OSError for a missing file)."""
    try:
        st = os.stat(path)
    except OSError:
        rayscan.open(path, cache)  # the reader's own message for a missing or unreadable file
        raise
    version = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    with _sites_lock:
        entry = _sites.get((path, cache))
        if entry is None or entry[0] != version:
            site = rayscan.open(path, cache)
            lock = threading.Lock() if site.storage == "copc" else None
            entry = _sites[(path, cache)] = (version, site, lock)
    return entry[1], entry[2]


# A task's rows are numbered within its chunk in the messages of the calls it makes: the
# bindings start a message about one row with "ray i: " (Site.ray_query) or "observers[i]: "
# (rayscan.visibility). The number there, and only there, is read back.
_RAY_ROW = re.compile(r"(ray )(\d+)(: )")
_OBSERVER_ROW = re.compile(r"(observers\[)(\d+)(\]: )")


@contextlib.contextmanager
def _rows_from(first, pattern):
    """Re-raise a ValueError that names a row of the task's chunk as the caller's row, `first`
    plus it, the number the single-process call gives (docs/python.md: rows from 0)."""
    try:
        yield
    except ValueError as e:
        message = e.args[0] if len(e.args) == 1 and isinstance(e.args[0], str) else ""
        m = pattern.match(message)
        if m:
            e.args = (f"{m[1]}{first + int(m[2])}{m[3]}{message[m.end():]}",)
        raise


def _ray_block(path, cache, origins, directions, kw, first):
    """One chunk of rays on a worker, its first ray the caller's row `first`: the CSR arrays of
    Site.ray_query (dict of NumPy arrays)."""
    site, lock = _site(path, cache)
    with _rows_from(first, _RAY_ROW), (lock or contextlib.nullcontext()):
        return site._ray_query(origins, directions, **kw)


def _dense(res, m, k):
    """CSR hits of m rays as (m, k) arrays, missing ranks filled with -1 (indices) or NaN."""
    counts = np.diff(res["offsets"])
    rank = np.arange(len(res["indices"])) - np.repeat(res["offsets"][:-1], counts)
    rows = np.repeat(np.arange(m), counts)
    out = {}
    for name, fill in (("indices", -1), ("t", np.nan), ("distance", np.nan)):
        a = np.full((m, k), fill, dtype=res[name].dtype)
        a[rows, rank] = res[name]
        out[name] = a[:, 0] if k == 1 else a
    return out


def _k_past_points(k, n, path):
    return ValueError(f"ray_query: k={k} is more than the {n} points of {path}: the lazy result has k columns "
                      f"per ray, those past {n} always empty; give k <= {n}, or compute=True for the CSR result")


def _ray_dense_block(path, cache, origins, directions, kw, first, m, k):
    # Before the (m, k) arrays: a k past the point count would only size empty columns (k=10**9
    # asks for gigabytes per chunk).
    site, _ = _site(path, cache)
    if k > 1 and k > len(site):  # (k=1 is one column, (m,), also over an empty cloud)
        raise _k_past_points(k, len(site), path)
    return _dense(_ray_block(path, cache, origins, directions, kw, first), m, k)


def _merge_csr(parts):
    """Concatenate the CSR results of consecutive ray chunks into one RayQueryResult."""
    offsets = [np.zeros(1, dtype=np.int64)]
    base = 0
    for p in parts:
        offsets.append(p["offsets"][1:] + base)
        base += int(p["offsets"][-1])
    return RayQueryResult(offsets=np.concatenate(offsets),
                          **{f: np.concatenate([p[f] for p in parts]) for f in ("indices", "t", "distance")})


# ---- client side -------------------------------------------------------------------------------

def _path(path):
    """The absolute path, so that workers with another working directory open the same file."""
    return os.path.abspath(os.fspath(path))


def _row_blocks(origins, directions, chunks):
    """The ray chunks as (delayed origins, delayed directions, first row, rows) tuples. A 2-D
    argument (M, 3) is split into row chunks (its own Dask chunks, those of the other argument,
    else `chunks` rows); a (3,) argument is one row shared by every chunk."""
    blocks, first = [], 0
    for o, d, rows in _row_chunks(origins, directions, chunks):
        blocks.append((o, d, first, rows))
        first += rows
    return blocks


def _row_chunks(origins, directions, chunks):
    def as_rows(a):
        if isinstance(a, da.Array):
            return a
        a = np.asarray(a, dtype=np.float64)
        return a if a.ndim == 1 else da.from_array(a, chunks=(chunks, 3))

    o, d = as_rows(origins), as_rows(directions)
    for name, a in (("origins", o), ("directions", d)):
        if not (a.ndim == 1 and a.shape == (3,)) and not (a.ndim == 2 and a.shape[1] == 3):
            raise ValueError(f"{name}: expected an (M, 3) array or one (3,) row, got shape {a.shape}")
    if o.ndim == 1 and d.ndim == 1:  # one ray
        o, d = (da.asarray(a).reshape(1, 3) for a in (o, d))
    if o.ndim == 2 and d.ndim == 2:
        if o.shape[0] != d.shape[0]:
            raise ValueError(f"origins has {o.shape[0]} rows, directions {d.shape[0]}")
        if isinstance(directions, da.Array) and not isinstance(origins, da.Array):
            d = d.rechunk({1: 3})  # the Dask argument's chunks lead
            o = o.rechunk((d.chunks[0], 3))
        else:
            o = o.rechunk({1: 3})
            d = d.rechunk((o.chunks[0], 3))
        rows = o.chunks[0]
        return list(zip(o.to_delayed().ravel(), d.to_delayed().ravel(), rows))
    if o.ndim == 2:
        o = o.rechunk({1: 3})
        return [(b, d, r) for b, r in zip(o.to_delayed().ravel(), o.chunks[0])]
    d = d.rechunk({1: 3})
    return [(o, b, r) for b, r in zip(d.to_delayed().ravel(), d.chunks[0])]


def ray_query(path, origins, directions, k=1, radius=_INF, t_min=-_INF, t_max=_INF, order="ray",
              any_hit=False, threads=1, allow_all=False, cache="2G", chunks=100_000, compute=False):
    """Site.ray_query of the file at `path` (an .rsi index, a COPC file, or any point file, which
    each worker then reads and indexes in memory) over chunks of rays, one task per chunk.

    origins, directions: (M, 3) Dask arrays (their row chunks are the tasks; the other argument
    follows them) or NumPy arrays (split into `chunks` rows, an integer >= 1), or one (3,) row
    for all rays. k, radius, t_min, t_max, order, any_hit, allow_all: as Site.ray_query (world
    units; t along the unit direction); k defaults to 1, the lazy result's columns. cache: as
    rayscan.open (a COPC file's decoded nodes per worker). threads: TBB threads per task (0 =
    all cores).

    Returns, with compute=False, a dict of Dask arrays chunked like the rays: "indices" int64
    (original point index, -1 = no hit), "t" and "distance" float64 (NaN = no hit), of shape (M,)
    for k=1, else (M, k) with the hits of each ray best first (k=None needs compute=True; a k
    above the point count raises ValueError, as its last columns could hold no hit: here for an
    .rsi or COPC file, else when the chunks are computed).
    Compute them in one call (dask.compute(out["indices"], out["t"])) so that each chunk is
    queried once. With compute=True: the RayQueryResult (CSR) of the single-process call,
    bit for bit. Raises ValueError and TypeError as Site.ray_query does, naming the argument: at
    the call for every argument but the rays' values and the file (order, radius, t_min, t_max,
    k, threads, any_hit, allow_all, and the shapes of origins and directions); on the workers for
    the rays' values, naming the caller's row ("ray 1234: ..." from 0 over all chunks), and for
    the file (at the call for the lazy result of an .rsi or COPC file, whose point count is read
    there); cache at the call, as rayscan.open. TypeError for a k or chunks that is not an integer
    (a bool, 3.0), ValueError below 1; TypeError for a compute that is not True or False.
    """
    compute = _boolean(compute, "compute")
    if k is None and not compute:
        raise ValueError("ray_query: k=None (every hit of each ray) needs compute=True; "
                         "the lazy result holds k hits per ray")
    chunks = _integer(chunks, "chunks", "an integer >= 1 (rays per task)", 1)
    if not compute:
        k = _integer(k, "k", "an integer >= 1 (columns of the lazy result; k=None needs compute=True)", 1)
    kw = dict(k=k, radius=radius, t_min=t_min, t_max=t_max, order=order, any_hit=any_hit,
              allow_all=allow_all, threads=threads)
    _check_ray_query(kw)
    rayscan._rayscan._check_cache(cache)
    path = _path(path)
    blocks = _row_blocks(origins, directions, chunks)
    if compute:
        parts = dask.compute(*[dask.delayed(_ray_block)(path, cache, o, d, kw, first)
                               for o, d, first, _ in blocks])
        return _merge_csr(parts)
    n = _point_count(path, cache)  # NaN (not known without reading the file): checked by each task
    if k > 1 and k > n:
        raise _k_past_points(k, n, path)
    out = {"indices": [], "t": [], "distance": []}
    for o, d, first, m in blocks:
        res = dask.delayed(_ray_dense_block)(path, cache, o, d, kw, first, m, k)
        shape = (m,) if k == 1 else (m, k)
        for name, dtype in (("indices", np.int64), ("t", np.float64), ("distance", np.float64)):
            out[name].append(da.from_delayed(res[name], shape, dtype=dtype))
    return {name: da.concatenate(parts) for name, parts in out.items()}


def first_hits(path, origins, directions, radius, t_min=0.0, t_max=_INF, threads=1, cache="2G",
               chunks=100_000, compute=False):
    """The first surface each ray hits: ray_query(k=1, order="sphere_hit") with spheres of
    `radius` (world units) around the points, from t_min (0: in front of the origin) to t_max.
    Returns "indices" (-1 = miss) and "t" (depth along the unit direction, NaN = miss) as Dask
    arrays of shape (M,) (or, with compute=True, the RayQueryResult). See ray_query."""
    return ray_query(path, origins, directions, k=1, radius=radius, t_min=t_min, t_max=t_max,
                     order="sphere_hit", threads=threads, cache=cache, chunks=chunks, compute=compute)


# ---- visibility: observers split over tasks ----------------------------------------------------

def _visibility_block(path, observers, kw, first=0):
    with _rows_from(first, _OBSERVER_ROW):
        r = rayscan.visibility(path, observers, **kw)
    return {name: r[name] for name in ("visible_count", "visible_distance", "sky_view", "per_observer",
                                       "observers", "radius", "tolerance", "target_height") if name in r}


def _merge_visibility(a, b):
    """Two observer groups' answers as one: counts add (integers, exact in float64), the nearest
    seeing observer is the nearer of the two (-1 = none), per-observer arrays concatenate."""
    out = dict(a)
    out["visible_count"] = a["visible_count"] + b["visible_count"]
    if "visible_distance" in a:
        da_, db_ = a["visible_distance"], b["visible_distance"]
        out["visible_distance"] = np.where(da_ < 0, db_, np.where(db_ < 0, da_, np.minimum(da_, db_)))
    out["per_observer"] = np.concatenate([a["per_observer"], b["per_observer"]])
    out["observers"] = np.concatenate([a["observers"], b["observers"]])
    return out


def visibility(path, observers, chunks=8, radius=None, height=None, max_distance=None,
               tolerance=None, target_height=None, sky_rays=0, distance=False, threads=1,
               cache="2G", ground_radius=None, compute=False):
    """rayscan.visibility of the cloud at `path` for many observers, `chunks` observers per task.

    The observers are split, not the points: every observer's line of sight needs the whole
    cloud as occluders (the job takes one cloud as both targets and occluders), and each
    (observer, point) pair is decided alone, so a task answers for its observers on all points
    and the visible counts of the tasks add up exactly (integers in float64). Each task opens the
    file and resolves the same automatic radius; pass `radius` to skip that estimate per task.

    observers: (K, 3) eye positions or (K, 2) positions placed `height` above the ground (world
    units), a NumPy or Dask array; observer files are not split (read them first). chunks: an
    integer >= 1. sky_rays > 0 adds "sky_view", computed once in its own task. Other options
    (ground_radius, cache, ...) as rayscan.visibility; camera= is not taken (its pixels do not
    depend on the observers, so there is nothing to split: call rayscan.visibility(path,
    camera=...)).

    Returns a dict: "visible_count" (N,) float64 (observers that see each point), with
    distance=True "visible_distance" (N,) float64 (nearest seeing observer, -1 = unseen),
    "sky_view" (N,) when asked, "per_observer" (K,) uint64, "observers" (K, 3) float64 placed
    eyes; Dask arrays (N is known for an .rsi or COPC file, else NaN until computed) or, with
    compute=True, NumPy arrays plus "radius", "tolerance", "target_height", equal to
    rayscan.visibility(path, observers, ...) bit for bit. Raises as rayscan.visibility does,
    naming an observer by the caller's row ("observers[13]: ..." from 0 over all chunks): at the
    call for the options and the observers' values (radius, tolerance, target_height and
    max_distance included: what rayscan.visibility checks before it reads the file), when the
    tasks run for the file and what needs the points (an eye's ground and height, the automatic
    radius); TypeError for a chunks that is
    not an integer, ValueError below 1, and for a compute or distance that is not True or False.
    """
    compute = _boolean(compute, "compute")
    distance = _boolean(distance, "distance")
    if isinstance(observers, (str, os.PathLike)):
        raise TypeError("observers: an (K, 3) or (K, 2) array (an observer file is not split "
                        "over tasks; pass rayscan.visibility the file instead)")
    obs = observers.compute() if isinstance(observers, da.Array) else np.asarray(observers, dtype=np.float64)
    if obs.ndim != 2 or obs.shape[1] not in (2, 3) or len(obs) == 0:
        raise ValueError(f"observers: expected a non-empty (K, 3) or (K, 2) array, got shape {obs.shape}")
    chunks = _integer(chunks, "chunks", "an integer >= 1 (observers per task)", 1)
    path = _path(path)
    kw = dict(radius=radius, height=height, max_distance=max_distance, tolerance=tolerance,
              target_height=target_height, distance=distance, threads=threads, cache=cache,
              ground_radius=ground_radius)
    # What rayscan.visibility refuses before it reads the file, refused here in its words: the
    # job's own check of the options (jobs::check_options, python/src/bind_jobs.cpp).
    rayscan._rayscan._check_visibility(obs, sky_rays=sky_rays, **kw)
    parts = [dask.delayed(_visibility_block)(path, obs[i:i + chunks], kw, i)
             for i in range(0, len(obs), chunks)]
    while len(parts) > 1:  # a tree of pairwise merges: each holds two (N,) arrays at a time
        parts = [dask.delayed(_merge_visibility)(parts[i], parts[i + 1]) if i + 1 < len(parts) else parts[i]
                 for i in range(0, len(parts), 2)]
    merged = parts[0]
    sky = None
    if sky_rays:
        sky_kw = dict(radius=radius, max_distance=max_distance, sky_rays=sky_rays, threads=threads, cache=cache)
        sky = dask.delayed(_visibility_block)(path, None, sky_kw)
    if compute:
        merged, sky = dask.compute(merged, sky)
        if sky is not None:
            merged["sky_view"] = sky["sky_view"]
        return merged
    n = _point_count(path, cache)
    out = {"visible_count": da.from_delayed(merged["visible_count"], (n,), dtype=np.float64)}
    if distance:
        out["visible_distance"] = da.from_delayed(merged["visible_distance"], (n,), dtype=np.float64)
    if sky is not None:
        out["sky_view"] = da.from_delayed(sky["sky_view"], (n,), dtype=np.float64)
    out["per_observer"] = da.from_delayed(merged["per_observer"], (len(obs),), dtype=np.uint64)
    out["observers"] = da.from_delayed(merged["observers"], (len(obs), 3), dtype=np.float64)
    return out


def _point_count(path, cache):
    """N of a file that rayscan.open queries in place (an index file or a COPC file, told apart
    as rayscan.open does, by the COPC header's bytes whatever the name): from its header, mapped,
    cheap. NaN (unknown) for other files, which rayscan.open would read whole."""
    if rayscan._rayscan._opens_in_place(path):
        return len(rayscan.open(path, cache))
    return np.nan


# ---- solar: instants (or periods) split over tasks ---------------------------------------------

def _solar_block(path, when, kw):
    if isinstance(when, str):
        return rayscan.solar(path, at=when, **kw)
    return rayscan.solar(path, start=when[0], end=when[1], **kw)


def _instants(at):
    """`at` as a list of ISO 8601 texts: one text is one instant, as rayscan.solar's `at`."""
    if isinstance(at, str):
        return [at]
    if isinstance(at, bytes) or not hasattr(at, "__iter__"):
        raise TypeError("at must be ISO 8601 text or a list of it (a datetime's isoformat()), "
                        f"got {type(at).__name__}")
    whens = list(at)
    for i, w in enumerate(whens):
        if not isinstance(w, str):
            raise TypeError(f"at[{i}] must be ISO 8601 text (a datetime's isoformat()), got {type(w).__name__}")
    return whens


def _periods(periods):
    """`periods` as a list of (start, end) texts: one pair of texts is one period, as
    rayscan.solar's start and end."""
    def pair(p):
        return isinstance(p, (tuple, list)) and len(p) == 2 and all(isinstance(t, str) for t in p)

    if pair(periods):
        return [tuple(periods)]
    expected = "a (start, end) pair of ISO 8601 texts"
    if isinstance(periods, (str, bytes)) or not hasattr(periods, "__iter__"):
        raise TypeError(f"periods must be {expected} or a list of them, got {type(periods).__name__}")
    whens = list(periods)
    for i, p in enumerate(whens):
        if not pair(p):
            raise TypeError(f"periods[{i}] must be {expected}, got {type(p).__name__}"
                            + (f" of length {len(p)}" if isinstance(p, (tuple, list)) else ""))
    return [tuple(p) for p in whens]


def solar(path, at=None, periods=None, step="1h", latitude=None, longitude=None, linke=3.0,
          albedo=0.2, weather=None, sector=1.0, sky_rays=64, primitive="sphere", radius=None,
          threads=1, cache="2G", compute=False):
    """rayscan.solar of the cloud at `path` for T instants or T periods, one task each.

    at: a list of T instants (ISO 8601 text, as rayscan.solar's `at`; one text is one instant,
    T = 1); or periods: a list of T (start, end) pairs (as rayscan.solar's start and end, e.g.
    one per month; one pair of texts is one period, T = 1). step, latitude, longitude, linke,
    albedo, weather, sector, sky_rays, primitive, radius, cache: as rayscan.solar, with its
    defaults; give latitude/longitude when the cloud has no CRS. threads: TBB threads per task
    (0 = all cores).

    Returns a dict of (T, N) float64 arrays, row i for at[i] / periods[i]: for instants
    "in_shadow" (1/0), "irradiance_global", "irradiance_beam", "irradiance_diffuse" (W/m²) and
    (T,) "sun_azimuth", "sun_elevation" (degrees); for periods "solar_global", "solar_beam",
    "solar_diffuse", "solar_reflected" (kWh/m²), "sun_hours" (h), "sky_view" (with sky_rays > 0).
    Dask arrays chunked one row per task, or NumPy with compute=True; row i equals
    rayscan.solar(path, at=at[i], ...) bit for bit. Raises ValueError without exactly one of at
    and periods or with an empty list, TypeError for an instant that is not text (a datetime:
    pass its isoformat(), as rayscan.solar) or a period that is not a pair of texts; as
    rayscan.solar does for the options and each instant or period at the call (what
    rayscan.solar checks before it reads a file: a step for instants too), and when the tasks
    run for the files (the cloud, the weather file) and what needs the points (the CRS, the
    automatic radius). TypeError for a
    compute that is not True or False.
    """
    compute = _boolean(compute, "compute")
    if (at is None) == (periods is None):
        raise ValueError("solar: give either at= (a list of instants) or periods= (a list of (start, end))")
    whens = _instants(at) if at is not None else _periods(periods)
    if not whens:
        raise ValueError("solar: no instant or period given")
    options = dict(step=step, latitude=latitude, longitude=longitude, linke=linke, albedo=albedo,
                   weather=weather, sector=sector, sky_rays=sky_rays, primitive=primitive,
                   radius=radius, cache=cache)
    for w in whens:  # as for visibility: what rayscan.solar refuses before it reads the points
        when = dict(at=w) if isinstance(w, str) else dict(start=w[0], end=w[1])
        rayscan._rayscan._check_solar(**when, **options, threads=threads)
    path = _path(path)
    kw = dict(options, threads=threads)
    tasks = [dask.delayed(_solar_block)(path, w, kw) for w in whens]
    fields = rayscan.SOLAR_INSTANT_FIELDS if at is not None else rayscan.SOLAR_PERIOD_FIELDS
    if at is None and sky_rays == 0:
        fields = tuple(f for f in fields if f != "sky_view")  # no sky view without sky rays
    if compute:
        res = dask.compute(*tasks)
        out = {f: np.stack([r[f] for r in res]) for f in fields if f in res[0]}
        if at is not None:
            out["sun_azimuth"] = np.array([r["sun_azimuth"] for r in res])
            out["sun_elevation"] = np.array([r["sun_elevation"] for r in res])
        return out
    n = _point_count(path, cache)
    # One (1, N) row per task, concatenated: da.stack refuses rows of unknown N (NaN != NaN).
    out = {f: da.concatenate([da.from_delayed(dask.delayed(np.atleast_2d)(t[f]), (1, n), dtype=np.float64)
                              for t in tasks], allow_unknown_chunksizes=True) for f in fields}
    if at is not None:
        for f in ("sun_azimuth", "sun_elevation"):
            out[f] = da.concatenate([da.from_delayed(dask.delayed(np.atleast_1d)(t[f]), (1,), dtype=np.float64)
                                     for t in tasks])
    return out
