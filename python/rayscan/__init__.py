"""rayscan on NumPy: ray queries on raw point clouds (Teuscher et al., "Ray Queries On Raw Point
Clouds", Algorithm 1), point queries, the point cloud readers and writers and the jobs (render,
visibility, solar, compare) of the rayscan C++ library.

From the source tree (autzen_trim.las: 110,000 points, coordinates in international feet):

    >>> import os, tempfile
    >>> import numpy as np, rayscan
    >>> pc = rayscan.read("tests/data/las/autzen_trim.las")
    >>> len(pc), pc.xyz.dtype, pc.rgb.dtype
    (110000, dtype('float64'), dtype('uint16'))
    >>> tree = rayscan.Octree(pc.xyz, layout="adaptive", capacity=64)
    >>> lo, hi = pc.bounds                                        # corners of the cloud
    >>> eye = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 100.0])
    >>> down_and_up = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    >>> hits = tree.ray_query(eye, down_and_up, k=1, radius=2.0, t_min=0.0, order="sphere_hit")
    >>> hits.first()                                              # point hit by each ray, -1 = miss
    array([46903,    -1])
    >>> hits.first("t").round(2)                                  # depth along each ray, NaN = miss
    array([191.52,    nan])
    >>> seen = rayscan.visibility(pc, observers=[eye[:2]], height=6.0)   # an eye 6 ft above ground
    >>> int(np.count_nonzero(seen["visible_count"]))              # points it sees
    2351
    >>> out = os.path.join(tempfile.mkdtemp(), "seen.laz")
    >>> rayscan.write(out, pc, visible_count=seen["visible_count"])
    >>> float(rayscan.read(out).scalars["visible_count"].sum())
    2351.0
    >>> low = rayscan.PointCloud(pc.xyz[pc.xyz[:, 2] < 420.0])  # a cloud from arrays
    >>> len(rayscan.BruteForce(low).box(lo, hi)[0]) == len(low)
    True

Conventions (the C++ library's, docs/library.md "Conventions"; the Python guide is
docs/python.md):
  * Arrays of points, origins and directions are (N, 3) array-likes of real numbers; float64
    C-contiguous arrays are used without a copy, anything else is converted once. A (3,) array
    is one row and broadcasts against the other argument.
  * Coordinates are double precision in the cloud's own world frame (its CRS's units); `t` and
    distances are in the same units (ray directions are normalised).
  * Batch queries run on all cores (TBB) with the GIL released; every result equals the
    single-query C++ call bit for bit (and the brute force).
  * Bad arguments raise ValueError (a value out of range: capacity=2**70, seed=-1, height=nan, a
    file name with a NUL byte) or TypeError (a value of the wrong type: None, a float or str where
    an integer is expected, a str where a number is, a list of numbers for attribute names). A
    file that cannot be opened (missing, unreadable, a directory) raises the OSError subclass
    open() raises for its errno (FileNotFoundError, PermissionError, IsADirectoryError; errno
    and filename set), a malformed point cloud, index, image or weather file OSError; a
    malformed scene, camera or observer file (JSON or CSV content) raises ValueError, like a bad
    option. Each carries the C++ library's one-line message naming the argument (or file, byte
    offset, row, JSON pointer) and what was expected.
"""

from . import _rayscan
from ._results import NeighborResult, RayQueryResult, BoxResult

__all__ = ["read", "write", "open", "PointCloud", "Octree", "KdTree", "BruteForce", "Site",
           "RayQueryResult", "NeighborResult", "BoxResult"]

#: The project version (CMakeLists.txt project(VERSION)), compiled into the extension.
__version__ = _rayscan.__version__

PointCloud = _rayscan.PointCloud
_INF = float("inf")


def read(path, attributes=None):
    """Read a point cloud file: LAS 1.0-1.4 (PDRF 0-10), PLY, PCD, XYZ/CSV/TXT or .f64
    (docs/formats.md); the format comes from the extension.

    attributes: None (everything the file has) or a list of names to keep, from "xyz", "rgb",
    "intensity", "classification", "gps_time", "normals" and the file's scalar fields (see
    PointCloud.attributes). Asking for an attribute the file lacks raises ValueError. Leaving
    the scalar fields out saves 8 bytes per point and field. A PLY, PCD or text field named
    intensity, classification or gps_time fills that attribute when its values fit it (integers
    in 0..65535 for intensity, 0..255 for classification), else it stays a float64 scalar field
    of that name (docs/formats.md), with or without `attributes`: a PLY float intensity of 0..1
    gives .intensity None and .scalars["intensity"]; pc["intensity"] gives either.

    Returns a PointCloud whose arrays (.xyz (N, 3) float64, .rgb (N, 3) uint16, .intensity,
    .classification, .gps_time, .normals, .scalars, .crs) are views of the reader's memory.
    Raises FileNotFoundError for a missing file (errno ENOENT, filename set, as open() raises
    it; IsADirectoryError, PermissionError, NotADirectoryError likewise, the library's one-line
    message as the note), OSError for a malformed file (the reader's one-line message).
    """
    return _rayscan._read(path, attributes)


def write(path, cloud, **fields):
    """Write a point cloud file in the format its extension names, like `rayscan translate`
    (io::write_point_cloud): .las / .laz (ASPRS LAS 1.4, point format 6, 7 with rgb; .laz
    compressed), .ply (binary), .pcd (binary), .xyz / .txt / .csv (text). A .copc.laz name is
    refused: COPC is built from a file (`rayscan translate IN OUT.copc.laz`).

    cloud: a PointCloud or an (N, 3) array of positions. fields: name=(N,) array of real numbers,
    added as scalar fields (replacing one of the same name), e.g. the "visible_count" of a
    visibility result; in LAS they are float64 extra bytes, in PLY/PCD properties, in text columns.
    Scalar fields named like the LAS reader's (return_number, scan_angle in degrees, user_data,
    point_source_id, ...) go to the standard LAS fields. LAS and PLY read every field back under
    its own name; for PLY, PCD and text a name their readers take for a dedicated field (Intensity,
    gpstime: another spelling of an attribute; ReturnNumber: PDAL's name of return_number) raises
    ValueError, and so does, for PCD and text, a name their readers take for a position, normal,
    colour or padding (PCD: x, nx, normal_y, red, B, _; text: x, nx, NormalY, red, B, i), which
    PLY and LAS keep.

    LAS coordinates are scaled integers: a cloud read from LAS/LAZ (or a subset of one) keeps the
    file's scale and offset (bit-exact round trip); otherwise each axis gets the coarsest of 1,
    0.1, 0.01, 0.001 that stores every coordinate exactly, else 0.001, coarsened to 0.01, 0.1,
    ... while the axis spans more than 2e9 steps (32-bit integers): an axis spanning more than
    2,000,000 units is stored at 0.01 or coarser, not to the nearest 0.001. In a geographic CRS
    longitude and latitude are degrees: the same down to 1e-7 degrees (about 1 cm), not 0.001
    (about 100 m); the height keeps 0.001. Written to a temporary
    file renamed into place, with the GIL released; with `fields`, a PointCloud's arrays are
    copied once (the file gets them, `cloud` keeps its own), also without the GIL. Raises ValueError for an unsupported extension, a field of the
    wrong shape or named like a PointCloud attribute, TypeError for another `cloud`, OSError
    when the file cannot be written.
    """
    _rayscan._write(path, cloud, fields)


def open(path, cache="2G"):  # noqa: A001 - rayscan.open, like gzip.open
    """Open a point file for queries, without reading it whole where the storage allows:
    an index file (.rsi, `rayscan index`) is memory-mapped and queried in place, a COPC file
    (.copc.laz) through its own octree (nodes decoded as queries reach them, kept within
    `cache`: "2G", "512M", as the CLI's --cache); any other point file is read and indexed in
    memory. Returns a Site with the index classes' queries (ray_query, knn, radius, box)
    answering with the points' original indices, except for an index file built without ids
    (`rayscan index` without `--attributes id`), which answers with index slots (depth-first node
    order): Site.has_ids says which. Its queries may run from several threads. Like gzip.open's
    file, the Site has close() and is a context manager (`with rayscan.open(path) as site:`).
    Raises FileNotFoundError for a missing file (the OSError subclass open() raises for the
    errno: IsADirectoryError, PermissionError, ...), OSError for a malformed file, ValueError for
    a bad cache size, TypeError for a path or cache of another type.
    """
    return Site(path, cache)


def _xyz(points):
    return points.xyz if isinstance(points, PointCloud) else points


class _QueriesMixin:
    """The query methods shared by every index class."""

    def ray_query(self, origins, directions, k=None, radius=_INF, t_min=-_INF, t_max=_INF,
                  order="ray", any_hit=False, threads=0, allow_all=False):
        """Ray query (paper Algorithm 1) for M rays o + t d.

        origins, directions: (M, 3) (or (3,), broadcast); directions need not be unit length.
        k: keep the k best results per ray (None: all). radius: keep points whose orthogonal
        distance to the ray line is <= radius (world units). t_min, t_max: keep results with t in
        [t_min, t_max]. order: 'ray' (distance to the ray line, eq. 1), 'time' (t along the ray,
        eq. 2) or 'sphere_hit' (entry into the sphere of `radius` around the point: the first
        surface hit; needs a finite radius). any_hit: stop at the first candidate (occlusion).
        threads: worker threads (0 = all cores); the result does not depend on it.
        allow_all: with neither k nor a finite radius (nor any_hit) every ray returns every
        point (N x M hits); that raises ValueError unless allow_all=True. any_hit and allow_all
        are True or False (a NumPy bool too).

        Returns a RayQueryResult (CSR): ray i's hits are indices[offsets[i]:offsets[i+1]],
        ranked best first, with t (projection parameter, or sphere entry for 'sphere_hit') and
        distance (orthogonal distance to the ray line, not squared).
        Raises ValueError for bad shapes, non-finite rays (naming the ray), t_min > t_max,
        a negative radius or k, 'sphere_hit' without a radius, or no bound without allow_all;
        TypeError for an argument of the wrong type (a float or str k, a str radius or array, an
        array of str, any_hit='no'), naming it. Same as `rayscan query`.
        """
        return RayQueryResult(**self._ray_query(origins, directions, k, radius, t_min, t_max,
                                                order, any_hit, allow_all, threads))

    def knn(self, points, k, radius=_INF, threads=0):
        """The k nearest points (within `radius` when given) of each of the Q query points
        ((Q, 3) or (3,)). Returns a NeighborResult (CSR: offsets (Q+1,), indices, distance),
        each query's neighbours sorted by (distance, index). threads: as in ray_query.
        k: an integer >= 0 of any size; a k at or above the point count N returns every point
        (within `radius`): N per query, as nothing is sized by k. Raises ValueError for k < 0
        and for a negative or NaN radius, TypeError for a k that is None or not an integer
        (3.0, '3') and for points that are not an array of real numbers."""
        if k is None:
            raise TypeError("knn: k must be an integer >= 0 (use radius() for all points within r)")
        return NeighborResult(**self._knn(points, k, radius, threads))

    def radius(self, points, r, threads=0):
        """Every point within distance r (inclusive, world units) of each query point;
        NeighborResult sorted by (distance, index) per query. r=inf returns all N points for
        each of the Q queries (Q x N results: mind the memory). Raises ValueError for a negative
        or NaN r."""
        return NeighborResult(**self._knn(points, None, r, threads))

    def box(self, lo, hi, threads=0):
        """Points p with lo <= p <= hi (closed box) for each of the B boxes (lo, hi: (B, 3) or
        (3,)). Returns a BoxResult (CSR: offsets (B+1,), indices in the index's storage order;
        sort a slice for ascending indices). An empty box (lo > hi on an axis) matches nothing."""
        return BoxResult(**self._box(lo, hi, threads))


class Octree(_QueriesMixin, _rayscan._Octree):
    """Octree after Warren & Salmon (paper section 4.1) over the (N, 3) points `xyz` (or a
    PointCloud). layout: 'adaptive' (split a leaf above `capacity` points, up to max_depth),
    'layered' (every node keeps up to `capacity` points: a level-of-detail subsample) or 'fixed'
    (all points in leaves at `depth`). insertion=True builds by point insertion as the paper
    measures (same tree as the default Morton bulk load). capacity=None takes the layout's default
    (64 for adaptive, 32 for layered). depth: 0..21, layout 'fixed' only (None: 6); max_depth:
    1..21, layouts 'adaptive' and 'layered' only (None: 21), as `rayscan index --max-depth` (0
    would leave one leaf holding every point). An argument the layout does not use (capacity or
    max_depth with 'fixed', depth with another) raises ValueError, as `rayscan query` and
    `rayscan index` refuse it, rather than being ignored. Raises ValueError for a non-finite point
    (naming it), a bad layout, capacity < 1 or a depth out of its range; TypeError for an
    argument of the wrong type (a file name for xyz: use rayscan.read or rayscan.open)."""

    def __init__(self, xyz, layout="adaptive", capacity=None, depth=None, max_depth=None, insertion=False):
        super().__init__(_xyz(xyz), layout, capacity, depth, max_depth, insertion)

    def __repr__(self):
        capacity = "" if self.capacity is None else f"capacity={self.capacity}, "
        return (f"<rayscan.Octree {len(self)} points, layout={self.layout}, "
                f"{capacity}{self.node_count} nodes, depth {self.depth}>")


class KdTree(_QueriesMixin, _rayscan._KdTree):
    """kd-tree (median split on the widest axis) over the (N, 3) points `xyz`, at most
    `capacity` points per leaf (None: 32). Same queries and results as Octree."""

    def __init__(self, xyz, capacity=None):
        super().__init__(_xyz(xyz), capacity)

    def __repr__(self):
        return f"<rayscan.KdTree {len(self)} points, capacity={self.capacity}, {self.node_count} nodes>"


class BruteForce(_QueriesMixin, _rayscan._BruteForce):
    """Exhaustive scan (the C++ test oracle): same queries and results as the trees."""

    def __init__(self, xyz):
        super().__init__(_xyz(xyz))

    def __repr__(self):
        return f"<rayscan.BruteForce {len(self)} points>"


class Site(_QueriesMixin, _rayscan._Site):
    """A point file opened for queries (see rayscan.open): .storage is "index_file" (an .rsi
    index mapped, queried in place), "copc" (a COPC file's own octree, nodes decoded as queries
    reach them, within `cache`, "2G" by default) or "memory" (another point file, read and
    indexed as an adaptive octree). Same queries and results as Octree over the same points;
    indices are the points' original order (the sources' order), except on an index file built
    without ids (`rayscan index` without `--attributes id`): there they are index slots
    (depth-first node order). .has_ids is True when they are the original order. Queries may run
    from several Python threads at once (each releases the GIL).

    close() releases the file's mapping, a COPC file's decoded nodes or the points read (once the
    queries running in other threads have ended); a query, len() or .storage after it raises
    ValueError("I/O operation on closed site"), as a closed file does; .closed says which. A
    Site is a context manager, closed on leaving the `with` block:

        with rayscan.open("site.rsi") as site:
            hits = site.ray_query(origins, directions, k=1, radius=0.5)
    """

    def __init__(self, path, cache="2G"):
        super().__init__(path, cache)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        if self.closed:
            return f"<rayscan.Site {self.path}: closed>"
        return f"<rayscan.Site {self.path}: {len(self)} points, storage={self.storage}>"


# ---- Jobs: render, visibility, compare (the library's job calls, docs/library.md) ------------

def _json_default(value):
    """File names in a scene dict may be os.PathLike (pathlib.Path)."""
    import os
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"scene dict: a {type(value).__name__} is not a JSON value")


def render(scene, cloud=None, width=None, height=None, spp=None, seed=None, aovs=(), camera=None,
           threads=0):
    """Path-trace a scene (paper section 5.3; schema in scenes/README.md) like `rayscan render`,
    without writing files: jobs::run_render.

    scene: one of
      * a scene file (.json);
      * a point cloud file (LAS, LAZ, COPC, PLY, PCD, text, .rsi), a PointCloud or an (N, 3) array:
        the quick look of `rayscan render CLOUD` (radius auto, surfels, colour from rgb if present
        else elevation, the default sky gradient and no sun, the overview camera framing the whole cloud, 600 x 400
        unless width/height say otherwise);
      * a dict: the same JSON as a scene file, relative file names from the working directory;
        errors name it "scene dict".
    A scene without "camera" gets the overview camera, as in the CLI.
    cloud: the points instead of the scene's "cloud" (a file name, a PointCloud or an (N, 3)
    array; the scene then needs no "cloud"). width/height (pixels, 1..65536 as `--width`; the
    other follows the camera's aspect), spp (1..1048576), seed, camera (a camera file) override
    the scene.
    aovs: names from "depth", "normal", "position", "index", "albedo", "cost".

    Returns a dict of arrays, row 0 at the top: "beauty" (H, W, 3) float32 linear radiance, and
    per requested AOV "depth" (H, W) float32 (t of the first hit, world units; inf = miss),
    "normal" and "albedo" (H, W, 3) float32, "position" (H, W, 3) float32 relative to
    "position_origin" (3,) float64, "index" (H, W) int64 (point index, -1 = miss), "cost" (H, W)
    float32 (nodes visited per sample); plus "radius" (the sphere radius used, world units),
    "points" and "stats" (dict).
    Raises ValueError for a bad scene or option (file or "scene dict" and JSON pointer named;
    also for a camera file named inside the scene that cannot be opened; an option named as the
    keyword) or a PointCloud with a non-finite coordinate (naming its row), TypeError for a `scene`
    or `cloud` of another type (None included), OSError for a scene, camera= or cloud file that
    cannot be opened and for a malformed cloud file.
    """
    scene_json = ""
    if isinstance(scene, dict):
        import json
        try:
            scene_json = json.dumps(scene, default=_json_default, allow_nan=False)
        except ValueError as e:  # NaN or infinity: not JSON
            raise ValueError(f"scene dict: {e}") from None
        scene = None
    return _rayscan._render(scene, scene_json, cloud, width, height, spp, seed, aovs, camera,
                            threads)


def ortho_map(cloud, res, spp=None, seed=None, threads=0, colour="albedo"):
    """A true orthophoto and digital surface model of the cloud, like `rayscan render CLOUD
    --ortho-map RES --dsm dsm.tif --ortho-colour COLOUR` without writing GeoTIFFs: the quick look's
    scene (radius auto, surfels, colour from rgb else elevation) seen by a top-down orthographic
    camera, vertical rays through the cells of a north-up grid over the cloud's XY extent
    (analysis::ortho_map).

    cloud: a point cloud file, a PointCloud or an (N, 3) array. res: cell edge, world units per
    pixel (> 0). colour: "albedo" (default: the unshaded colour of the points seen from above,
    the point's rgb, else the elevation ramp, as the cell's mean: that of the points first hit by
    spp stratified rays through the cell, over the rays that hit, averaged sRGB-encoded as the
    colours are stored; spp=1: the point under the cell centre, its colour as stored) or "shaded"
    (the path-traced render: sky light and shading). spp, seed: rays per cell (default 16) and
    random seed (as in render).

    Returns a dict: "image" (rows, cols, 3) float32 linear RGB, row 0 the north edge (albedo: the
    cell's mean colour converted from sRGB, 0 where no ray hit; shaded: radiance); "coverage"
    (rows, cols) float32 in [0, 1], the orthophoto GeoTIFF's alpha band (255 x coverage, rounded,
    in the file): the share of the cell's rays that hit (shaded: 1 where the cell-centre ray hit,
    else 0); "dsm" (rows,
    cols) float32 elevation of the first surface per cell (world units, NaN where the ray
    missed); "geotransform" (x0, res, 0, y_top, 0, -res) as GDAL's (x0, y_top: the grid's west
    and north edges, snapped to multiples of res); "crs" (WKT or None); "radius".
    Raises ValueError for a res that is not > 0 or gives more than 65536 cells per side (or more
    cells in all than the raster limit the message names), a colour other than "albedo" or
    "shaded", or a PointCloud with a non-finite coordinate (naming its row).
    """
    return _rayscan._ortho_map(cloud, res, spp, seed, threads, colour)


def visibility(cloud, observers=None, radius=None, height=None, max_distance=None, tolerance=None,
               target_height=None, sky_rays=0, camera=None, distance=False, threads=0, cache="2G",
               ground_radius=None):
    """Per-point visibility like `rayscan visibility` (jobs::run_visibility; rule in
    analysis/README.md), without writing files.

    Line of sight runs on surfels, the CLI's default `--primitive surfel`: each point an oriented
    disc (PCA normal, radius from its neighbours' spacing), solid below.

    cloud: a file path, a PointCloud or an (N, 3) array of positions (world units).
    observers: a .json/.csv observer file, an (K, 3) array of eye positions, or (K, 2)
    positions whose eyes stand `height` above the local ground. radius: sphere radius (world
    units; None = auto from the point spacing) of the sky view and camera marks, which use
    spheres; for line of sight it scales the default ground search radius (5 x radius).
    sky_rays > 0 adds the sky view factor; camera (a camera file) adds the pixels whose first hit
    is each point. A COPC file is queried on its own octree in place (its points still read for
    the fields; the same answers as read whole), decoded nodes kept within `cache` ("2G",
    "512M", as `--cache`).

    Returns a dict: "visible_count" (N,) (observers that see each point), "visible_distance" (N,)
    (with distance=True; -1 = unseen), "sky_view" (N,), "camera_hits" (N,) when asked, as float64;
    "radius", "tolerance", "target_height" used, "observers" (K, 3) placed eyes and "per_observer"
    (K,) uint64 points each observer sees.

    height: eye height above the local ground (world units) of observers given without z (the
    (K, 2) rows, file rows without z); a finite number. ground_radius: that local ground is the
    lowest point (of class 2, ground, when classified) within this horizontal distance of the
    eye (world units, > 0, as `--ground-radius`; None = 5 x radius, searched first within the
    median surfel radius, right under the eye). max_distance: viewing range (world units; None =
    unlimited). tolerance: a point counts as seen when the first surface the ray meets lies at
    most this far before it (None = 0). target_height: rays aim this far above each point (None
    = 0: at the point, as GIS viewsheds). threads: worker threads (0 = all cores).
    Raises ValueError for a bad option (named as the keyword: "height: expected an eye height
    above the local ground, a finite number ...", "observers[2]: no point within the ground
    radius ...; move it or raise ground_radius", rows numbered from 0), a malformed observer
    file or a PointCloud with a non-finite coordinate, TypeError for an argument of the wrong
    type, OSError for a cloud, observer or camera file that cannot be opened and for a malformed
    cloud file.
    """
    return _rayscan._visibility(cloud, observers, radius, height, max_distance, tolerance,
                                target_height, sky_rays, camera, distance, threads, cache,
                                ground_radius)


def solar(cloud, start=None, end=None, step="1h", at=None, latitude=None, longitude=None,
          linke=3.0, albedo=0.2, weather=None, sector=1.0, sky_rays=64, primitive="sphere",
          radius=None, threads=0, cache="2G"):
    """Sun and shadow on every point like `rayscan solar` (jobs::run_solar; docs/solar.md),
    without writing files.

    cloud: a file path, a PointCloud or an (N, 3) array of positions (metres). A period (start,
    end: ISO 8601 text, no offset = UTC, a date alone = local mean solar midnight, end
    inclusive; step: a duration such as "15min", "30min" or "1h", at most "1h", that divides the
    period) or one instant (at). latitude/longitude: degrees (default: from the cloud's CRS).
    linke: one Linke turbidity or 12 monthly values; albedo; weather: an EPW file instead of the
    clear sky; sector: sun-map sector in degrees (0 = one shadow ray per step); sky_rays: sky-map
    directions; primitive: "sphere" or "surfel". A COPC file is queried in place as by
    visibility(), within `cache`.

    Returns a dict of (N,) float64 arrays: for a period SOLAR_PERIOD_FIELDS, "solar_global",
    "solar_beam", "solar_diffuse", "solar_reflected" (kWh/m²), "sun_hours" (h), "sky_view"; for an
    instant SOLAR_INSTANT_FIELDS, "in_shadow" (1/0), "irradiance_global", "irradiance_beam",
    "irradiance_diffuse" (W/m²), with "sun_azimuth" and "sun_elevation" (degrees); and
    "latitude", "longitude", "steps", "sectors", "radius". radius: sphere radius (world units;
    None = auto from the point spacing). threads:
    worker threads (0 = all cores). Raises ValueError for a bad option (named as the keyword),
    TypeError for an argument of the wrong type (at=datetime: pass at.isoformat()), OSError for
    a cloud or weather file that cannot be opened or is malformed.
    """
    return _rayscan._solar(cloud, start, end, step, at, latitude, longitude, linke, albedo, weather,
                           sector, sky_rays, primitive, radius, threads, cache)


def compare(reference, image, channels=(), mask=False, alpha=False, resize=False, fail=None,
            fail_percent=None, fail_psnr=None, fail_ssim=None, warn=None):
    """Compare `image` against `reference` like `rayscan compare` (jobs::run_compare;
    definitions in analysis/README.md). Each is an image file (anything OpenImageIO reads) or an
    (H, W) / (H, W, C) array (channels Y / R,G,B / R,G,B,A; values as given, e.g. linear floats).

    Returns a dict of metrics: "mae", "rmse", "psnr" (dB, as idiff), "max_error", "max_pixel"
    (x, y, c), "ssim", "flip" (mean LDR-FLIP; NaN unless R,G,B or Y), "percent_over_fail" and
    "percent_over_warn" with their "fail_threshold" and "warn_threshold" (None for a level
    without a pixel test, as the CLI's "off"), "pixels_compared", "per_channel" {name: {...}},
    "verdict" ("pass", "warn", "fail") and "reasons".
    Raises ValueError for an array of another shape or a bad option, TypeError for a `reference`
    or `image` that is neither a file name nor an array (None), OSError for an image file that
    cannot be opened or decoded. compare takes no `threads`.
    """
    return _rayscan._compare(reference, image, channels, mask, alpha, resize, fail,
                             fail_percent, fail_psnr, fail_ssim, warn)


if not hasattr(_rayscan, "_render"):  # built without the library's job API
    del render, ortho_map, visibility, solar, compare
else:
    __all__ += ["render", "ortho_map", "visibility", "solar", "compare"]
    #: The names of solar()'s arrays for a period and for an instant, in the library's order (the
    #: library's own lists, jobs::kSolarPeriodFields and kSolarInstantFields).
    SOLAR_PERIOD_FIELDS = _rayscan.SOLAR_PERIOD_FIELDS
    SOLAR_INSTANT_FIELDS = _rayscan.SOLAR_INSTANT_FIELDS
