"""rayscan.dask on a real two-process LocalCluster against the single-process calls, bit for bit:
ray queries and first hits over Dask arrays of rays, visibility counts for observers split over
tasks, solar instants. Skipped without Dask (Debian: python3-dask, python3-distributed)."""

import os
import shutil
import subprocess

import numpy as np
import pytest

import rayscan

pytest.importorskip("dask")
pytest.importorskip("distributed")
import dask  # noqa: E402
import dask.array as da  # noqa: E402
import distributed  # noqa: E402

import rayscan.dask as rd  # noqa: E402


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                       dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def site_file(tmp_path_factory, data_dir, cli):
    """Every 4th point of autzen_trim.las (27,500 points, international feet) as an .rsi index with
    the original ids: small enough for a few seconds of visibility."""
    d = tmp_path_factory.mktemp("dask")
    pc = rayscan.read(data_dir / "las" / "autzen_trim.las")
    las = d / "autzen_quarter.las"
    rayscan.write(las, pc[::4])
    rsi = d / "autzen_quarter.rsi"
    subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", str(rsi), str(las)], check=True)
    return rsi


@pytest.fixture(scope="module")
def rays(site_file):
    """5,000 rays from 1,000 ft above the scan towards random points of its extent."""
    lo, hi = rayscan.read(str(site_file).replace(".rsi", ".las")).bounds
    rng = np.random.default_rng(48)
    target = lo + rng.random((5000, 3)) * (hi - lo)
    origins = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 1000.0]) + rng.normal(0, 50, (5000, 3))
    return origins, target - origins


def test_import_needs_no_dask():
    # `import rayscan` alone must not pull Dask in (it is an optional dependency).
    code = "import sys, rayscan; assert 'dask' not in sys.modules and 'rayscan.dask' not in sys.modules"
    subprocess.run([__import__("sys").executable, "-c", code], check=True)


def test_ray_query_and_first_hits(client, site_file, rays):
    o, d = rays
    site = rayscan.open(site_file)
    one = site.ray_query(o, d, k=3, radius=6.0, order="time")
    lazy = rd.ray_query(site_file, da.from_array(o, chunks=(1200, 3)), da.from_array(d, chunks=(700, 3)),
                        k=3, radius=6.0, order="time")
    assert lazy["indices"].chunks[0] == (1200, 1200, 1200, 1200, 200)
    idx, t, dist = dask.compute(lazy["indices"], lazy["t"], lazy["distance"])
    assert idx.shape == (5000, 3) and idx.dtype == np.int64 and t.dtype == np.float64
    counts = one.counts
    for r in range(3):  # rank r of each ray with at least r + 1 hits, -1 / NaN past its last hit
        has = counts > r
        pos = one.offsets[:-1][has] + r
        assert np.array_equal(idx[has, r], one.indices[pos])
        assert np.array_equal(t[has, r], one.t[pos]) and np.array_equal(dist[has, r], one.distance[pos])
        assert (idx[~has, r] == -1).all() and np.isnan(t[~has, r]).all()

    merged = rd.ray_query(site_file, o, d, k=None, radius=6.0, chunks=900, compute=True)
    full = site.ray_query(o, d, radius=6.0)
    for f in ("offsets", "indices", "t", "distance"):
        assert np.array_equal(getattr(merged, f), getattr(full, f)), f

    first = site.ray_query(o, d, k=1, radius=3.0, t_min=0.0, order="sphere_hit")
    hits = rd.first_hits(site_file, da.from_array(o, chunks=(1000, 3)), d, radius=3.0)
    hi, ht = dask.compute(hits["indices"], hits["t"])
    assert hi.shape == (5000,) and (hi >= 0).mean() > 0.5
    assert np.array_equal(hi, first.first("indices"))
    assert np.array_equal(ht, first.first("t"), equal_nan=True)

    # NumPy origins follow the chunks of Dask directions.
    mixed = rd.first_hits(site_file, o, da.from_array(d, chunks=(1500, 3)), radius=3.0)
    assert mixed["indices"].chunks == ((1500, 1500, 1500, 500),)
    assert np.array_equal(mixed["indices"].compute(), first.first("indices"))

    # One origin (3,) broadcast against chunks of directions.
    eye = o[0]
    bcast = rd.first_hits(site_file, eye, da.from_array(d, chunks=(2000, 3)), radius=3.0)
    assert np.array_equal(bcast["indices"].compute(),
                          site.ray_query(eye, d, k=1, radius=3.0, t_min=0.0, order="sphere_hit").first())


def test_visibility_counts(client, site_file):
    xyz = rayscan.read(str(site_file).replace(".rsi", ".las")).xyz
    xy = xyz[np.random.default_rng(3).choice(len(xyz), 6, replace=False), :2]  # on the ground
    one = rayscan.visibility(site_file, xy, height=6.0, distance=True)
    lazy = rd.visibility(site_file, xy, chunks=2, height=6.0, distance=True)
    count, dist, per = dask.compute(lazy["visible_count"], lazy["visible_distance"], lazy["per_observer"])
    assert count.shape == (27500,) and one["visible_count"].max() > 1  # some points seen by several
    assert np.array_equal(count, one["visible_count"])
    assert np.array_equal(dist, one["visible_distance"])
    assert np.array_equal(per, one["per_observer"])
    merged = rd.visibility(site_file, xy, chunks=4, height=6.0, compute=True)
    assert np.array_equal(merged["visible_count"], one["visible_count"])
    assert np.array_equal(merged["observers"], one["observers"]) and merged["radius"] == one["radius"]


def test_solar_instants(client, site_file):
    at = ["2024-06-21T18:00", "2024-12-21T20:00"]
    opts = dict(latitude=44.05, longitude=-123.07, sky_rays=16)
    out = rd.solar(site_file, at=at, **opts)
    shadow, elev = dask.compute(out["in_shadow"], out["sun_elevation"])
    assert shadow.shape == (2, 27500)
    for i, when in enumerate(at):
        one = rayscan.solar(site_file, at=when, **opts)
        assert np.array_equal(shadow[i], one["in_shadow"]) and elev[i] == one["sun_elevation"]


def test_solar_instants_of_a_file_read_whole(client, site_file, tmp_path):
    """The lazy (T, N) arrays of a file that is read whole, whose N is unknown until the tasks
    run (NaN), row i equal to rayscan.solar at instant i."""
    las = tmp_path / "tenth.las"
    rayscan.write(las, rayscan.read(str(site_file).replace(".rsi", ".las"))[::10])
    at = ["2024-06-21T18:00", "2024-12-21T20:00"]
    opts = dict(latitude=44.05, longitude=-123.07, sky_rays=4)
    out = rd.solar(las, at=at, **opts)
    assert np.isnan(out["in_shadow"].shape[1]) and out["in_shadow"].chunks[0] == (1, 1)
    shadow, = dask.compute(out["in_shadow"])
    assert shadow.shape == (2, 2750)
    for i, when in enumerate(at):
        assert np.array_equal(shadow[i], rayscan.solar(las, at=when, **opts)["in_shadow"])


def test_missing_arguments_raise(site_file):
    with pytest.raises(ValueError, match="compute=True"):
        rd.ray_query(site_file, np.zeros((2, 3)), np.ones((2, 3)), k=None, radius=1.0)
    with pytest.raises(TypeError, match="observer file"):
        rd.visibility(site_file, "observers.csv")
    with pytest.raises(ValueError, match="at="):
        rd.solar(site_file)



def test_lazy_k_above_the_point_count_is_refused(client, tmp_path, cli):
    """The lazy result has k columns per ray: a k above the point count would only size columns
    that can hold no hit (k=10**9 would ask for gigabytes per chunk), so it raises ValueError, at
    the call for an .rsi file (its count is in the header) and in the task for another file. k
    equal to the count is kept."""
    xyz = np.array([[0.0, 0, 0], [0, 0, 1], [0, 0, 2]])
    ply = tmp_path / "three.ply"
    rayscan.write(ply, xyz)
    rsi = tmp_path / "three.rsi"
    subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", str(rsi), str(ply)], check=True)
    o, d = np.array([[0.0, 0, -1]]), np.array([[0.0, 0, 1]])
    for k in (4, 10**30):
        with pytest.raises(ValueError, match=rf"k={k} is more than the 3 points of .*three\.rsi"):
            rd.ray_query(rsi, o, d, k=k, radius=0.5)
        lazy = rd.ray_query(ply, o, d, k=k, radius=0.5)  # the count of a PLY needs a full read
        with pytest.raises(ValueError, match=rf"k={k} is more than the 3 points of .*three\.ply"):
            dask.compute(lazy["indices"])
    for path in (rsi, ply):
        idx, = dask.compute(rd.ray_query(path, o, d, k=3, radius=0.5)["indices"])
        assert idx.tolist() == [[0, 1, 2]]


def _rays_down(las, m=2000, seed=0):
    """m vertical rays from 100 units above the cloud at `las` onto random points of its extent."""
    lo, hi = rayscan.read(las).bounds
    target = lo + np.random.default_rng(seed).random((m, 3)) * (hi - lo)
    origins = target.copy()
    origins[:, 2] = hi[2] + 100.0
    return origins, target - origins


def test_site_reopened_when_the_file_changes(client, tmp_path, cli, data_dir, site_file):
    """A worker keeps the Site of a path only while the file under it is the same one: after
    `rayscan index -o` over it and after a copy onto it, the answers are the new file's, as a
    fresh single-process Site gives them, from the same worker processes (a Site kept over a
    file copied onto it would read past its end and kill the worker)."""
    clouds = {"hay": str(data_dir / "las" / "Haystack_Rock.las"), "quarter": str(site_file).replace(".rsi", ".las")}
    path = tmp_path / "swap.rsi"

    def index(name, out=path):
        subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", str(out), clouds[name]], check=True)

    def same_as_one_process(name):
        o, d = _rays_down(clouds[name])
        hits = rd.first_hits(path, o, d, radius=2.0, chunks=250)["indices"].compute()
        one = rayscan.open(path).ray_query(o, d, k=1, radius=2.0, t_min=0.0, order="sphere_hit").first("indices")
        assert (one >= 0).sum() > 100  # not two empty answers
        assert np.array_equal(hits, one), name

    pids = client.run(os.getpid)
    index("hay")
    same_as_one_process("hay")
    kept = client.run(lambda: [p for p, _ in __import__("rayscan.dask").dask._sites])
    assert all(str(path) in paths for paths in kept.values())  # both workers hold its Site
    index("quarter")  # another file under the path
    same_as_one_process("quarter")
    index("hay", tmp_path / "hay.rsi")
    inode = os.stat(path).st_ino
    shutil.copyfile(tmp_path / "hay.rsi", path)  # the same file rewritten
    assert os.stat(path).st_ino == inode
    same_as_one_process("hay")
    assert client.run(os.getpid) == pids  # no worker died and was replaced


def _message(call):
    with pytest.raises(Exception) as e:
        call()
    return type(e.value), str(e.value)


def test_errors_name_the_callers_row(client, site_file, rays):
    """A bad ray or observer is named by its row in the caller's array, from 0 over all chunks,
    in the words of the single-process call (the oracle): ray 1234 of chunks of 500 rays is not
    'ray 234', observer 5 of chunks of 4 is not 'observers[1]'."""
    o, d = rays
    d = d.copy()
    d[1234] = 0.0
    one = _message(lambda: rayscan.open(site_file).ray_query(o, d, k=1, radius=2.0))
    assert one[0] is ValueError and one[1].startswith("ray 1234: ")
    assert _message(lambda: rd.ray_query(site_file, o, d, k=1, radius=2.0, chunks=500)["indices"].compute()) == one
    assert _message(lambda: rd.ray_query(site_file, o, d, k=None, radius=2.0, chunks=500, compute=True)) == one
    o = o.copy()
    o[4321, 0] = np.inf  # a ray of the last Dask chunk of directions, NumPy origins following it
    one = _message(lambda: rayscan.open(site_file).ray_query(o, d[0], k=1, radius=2.0))
    assert one[1].startswith("ray 4321: ")
    assert _message(lambda: rd.first_hits(site_file, da.from_array(o, chunks=(1000, 3)), d[0],
                                          radius=2.0)["indices"].compute())[1] == \
        _message(lambda: rayscan.open(site_file).ray_query(o, d[0], k=1, radius=2.0, t_min=0.0,
                                                           order="sphere_hit"))[1]

    xyz = rayscan.read(str(site_file).replace(".rsi", ".las")).xyz
    xy = xyz[np.random.default_rng(3).choice(len(xyz), 6, replace=False), :2]
    for bad in ([0.0, 0.0], [np.nan, 1.0]):  # no ground under the eye; not a number
        obs = xy.copy()
        obs[5] = bad
        one = _message(lambda: rayscan.visibility(site_file, obs, height=6.0, max_distance=50.0))
        assert one[0] is ValueError and one[1].startswith("observers[5]: ")
        assert _message(lambda: rd.visibility(site_file, obs, chunks=4, height=6.0, max_distance=50.0,
                                              compute=True)) == one


# Keywords of the single-process calls that the Dask calls do not take, and why (docs/python.md,
# "What is not there").
_NOT_TAKEN = {
    "ray_query": {},
    "first_hits": {"k": "1", "order": "'sphere_hit'", "any_hit": "any hit is not the first",
                   "allow_all": "k=1 bounds every ray"},
    "visibility": {"cloud": "path, the file each worker opens", "camera": "one camera's pixels do not depend "
                   "on the observers: nothing to split; rayscan.visibility(path, camera=...)"},
    "solar": {"cloud": "path, the file each worker opens", "start": "periods=[(start, end), ...]",
              "end": "periods=[(start, end), ...]"},
}
# Keywords taken with another default, and why.
_OWN_DEFAULT = {
    "ray_query": {"k": "1: the lazy result's columns", "threads": "1: the workers are the parallelism"},
    "first_hits": {"radius": "required: the spheres hit", "t_min": "0: in front of the origin", "threads": "1"},
    "visibility": {"observers": "required: what the tasks split", "threads": "1"},
    "solar": {"threads": "1"},
}


@pytest.mark.parametrize("name", sorted(_NOT_TAKEN))
def test_keywords_as_the_single_process_call(name):
    """Every keyword of the single-process call (Site.ray_query and rayscan.open's cache for the
    ray queries) is a keyword of the Dask call with the same default, or listed above."""
    import inspect
    single = {}
    if name in ("ray_query", "first_hits"):
        single.update(inspect.signature(rayscan.Site.ray_query).parameters)
        single.update(inspect.signature(rayscan.open).parameters)
        del single["self"], single["path"]
    else:
        single.update(inspect.signature(getattr(rayscan, name)).parameters)
    ours = inspect.signature(getattr(rd, name)).parameters
    for kw, p in single.items():
        if kw in _NOT_TAKEN[name]:
            assert kw not in ours, kw
        else:
            assert kw in ours, f"rayscan.dask.{name} lacks {kw}"
            if kw not in _OWN_DEFAULT[name]:
                assert ours[kw].default == p.default, kw
            else:
                assert ours[kw].default != p.default, kw


def test_keywords_reach_the_tasks(client, site_file, tmp_path):
    """allow_all, ground_radius and cache do in the tasks what they do in the single-process call."""
    ply = tmp_path / "three.ply"
    rayscan.write(ply, np.array([[0.0, 0, 0], [0, 0, 1], [0, 0, 2]]))
    o, d = np.array([[0.0, 0, -1], [5.0, 0, -1]]), np.array([0.0, 0, 1])
    one = rayscan.open(ply).ray_query(o, d, allow_all=True)
    every = rd.ray_query(ply, o, d, k=None, allow_all=True, chunks=1, compute=True)
    assert every.counts.tolist() == [3, 3] and np.array_equal(every.indices, one.indices)
    assert _message(lambda: rd.ray_query(ply, o, d, k=None, chunks=1, compute=True)) == \
        _message(lambda: rayscan.open(ply).ray_query(o, d))

    xyz = rayscan.read(str(site_file).replace(".rsi", ".las")).xyz
    xy = xyz[np.random.default_rng(3).choice(len(xyz), 4, replace=False), :2]
    opts = dict(height=6.0, max_distance=50.0)
    near = rayscan.visibility(site_file, xy, **opts)["observers"]
    wide = rayscan.visibility(site_file, xy, ground_radius=60.0, **opts)
    assert not np.array_equal(wide["observers"], near)  # a lower ground further out
    ours = rd.visibility(site_file, xy, chunks=2, ground_radius=60.0, compute=True, **opts)
    assert np.array_equal(ours["observers"], wide["observers"])
    assert np.array_equal(ours["visible_count"], wide["visible_count"])

    bad_cache = _message(lambda: rayscan.open(site_file, cache="lots"))
    assert bad_cache[0] is ValueError and "cache" in bad_cache[1]
    assert _message(lambda: rd.ray_query(site_file, o, d, cache="lots")) == bad_cache
    assert _message(lambda: rd.visibility(site_file, xy, chunks=2, cache="lots", compute=True, **opts)) == \
        _message(lambda: rayscan.visibility(site_file, xy, cache="lots", **opts))


def test_solar_one_instant_or_one_period(client, site_file):
    """One text for `at` is one instant and one (start, end) pair one period, T = 1, as
    rayscan.solar takes them; what rayscan.solar refuses (a datetime) is refused at the call."""
    import datetime
    opts = dict(latitude=44.05, longitude=-123.07, sky_rays=16)
    at = "2024-06-21T18:00"
    out = rd.solar(site_file, at=at, compute=True, **opts)
    one = rayscan.solar(site_file, at=at, **opts)
    assert out["in_shadow"].shape == (1, 27500) and out["sun_elevation"].tolist() == [one["sun_elevation"]]
    assert np.array_equal(out["irradiance_global"][0], one["irradiance_global"])
    start, end = "2024-06-21T17:00", "2024-06-21T19:00"
    out = rd.solar(site_file, periods=(start, end), compute=True, **opts)
    one = rayscan.solar(site_file, start=start, end=end, **opts)
    assert out["sun_hours"].shape == (1, 27500) and one["sun_hours"].max() > 0
    assert np.array_equal(out["solar_global"][0], one["solar_global"])
    assert np.array_equal(out["sun_hours"][0], one["sun_hours"])

    when = datetime.datetime(2024, 6, 21, 18)
    with pytest.raises(TypeError, match="isoformat"):
        rayscan.solar(site_file, at=when, **opts)
    for bad, named in (({"at": when}, "at must"), ({"at": [at, when]}, r"at\[1\] must"),
                       ({"periods": [(start, end), (start,)]}, r"periods\[1\] must .* of length 1"),
                       ({"periods": [start, end, end]}, r"periods\[0\] must .* got str"),
                       ({"periods": 2024}, "periods must")):
        with pytest.raises(TypeError, match=named):
            rd.solar(site_file, **bad)


@pytest.mark.parametrize("value", [3, np.int64(3), np.uint8(3), True, 3.0, np.float64(3.0), "3"],
                         ids=lambda v: f"{type(v).__name__}({v!r})")
def test_integer_arguments_as_the_rest_of_the_api(site_file, value):
    """k and chunks take what Site.ray_query's k takes (any integer, a NumPy one too) and refuse
    what it refuses (a bool, a float, a str) with TypeError; below 1 is a ValueError."""
    o, d = np.zeros((7, 3)), np.array([0.0, 0, 1])
    try:
        rayscan.open(site_file).ray_query(o, d, k=value, radius=1.0)
        refused = None
    except TypeError:
        refused = TypeError
    if refused:
        with pytest.raises(TypeError, match="k must be an integer >= 1"):
            rd.ray_query(site_file, o, d, k=value, radius=1.0)
        with pytest.raises(TypeError, match=r"chunks must be an integer >= 1 \(rays per task\)"):
            rd.ray_query(site_file, o, d, radius=1.0, chunks=value)
        with pytest.raises(TypeError, match=r"chunks must be an integer >= 1 \(observers per task\)"):
            rd.visibility(site_file, o, chunks=value)
    else:
        assert rd.ray_query(site_file, o, d, k=value, radius=1.0)["indices"].shape == (7, 3)
        assert rd.ray_query(site_file, o, d, radius=1.0, chunks=value)["indices"].chunks == ((3, 3, 1),)
        graph = dict(rd.visibility(site_file, o, chunks=value)["per_observer"].__dask_graph__())
        assert sum(str(key).startswith("_visibility_block") for key in graph) == 3  # observers 3 + 3 + 1
    for name, call in (("k", lambda v: rd.ray_query(site_file, o, d, k=v)),
                       ("chunks", lambda v: rd.ray_query(site_file, o, d, chunks=v)),
                       ("chunks", lambda v: rd.visibility(site_file, o, chunks=v))):
        with pytest.raises(ValueError, match=rf"{name} must be an integer >= 1 .*got 0"):
            call(np.int64(0))
    with pytest.raises(TypeError, match="got bool_"):  # NumPy deprecates a bool as an index
        rd.ray_query(site_file, o, d, k=np.True_)


# Arguments Site.ray_query refuses whatever the rays (the oracle: its own exception, type and words).
_BAD_RAY_OPTIONS = [dict(order="first"), dict(order=None), dict(radius="2"), dict(radius=-1.0),
                    dict(t_min=2.0, t_max=1.0), dict(order="sphere_hit", radius=np.inf), dict(threads=-1),
                    dict(threads=1.5), dict(any_hit="no"), dict(allow_all="yes"), dict(k=-1),
                    dict(k=None, radius=np.inf)]


@pytest.mark.parametrize("bad", _BAD_RAY_OPTIONS, ids=lambda b: ",".join(f"{k}={v!r}" for k, v in b.items()))
def test_ray_options_are_checked_at_the_call(client, site_file, rays, tmp_path, bad):
    """An option Site.ray_query refuses raises its exception, in its words, at the rayscan.dask
    call, lazy or compute=True, before any task runs: the path names no file, so a task that ran
    would raise the file's OSError instead."""
    o, d = rays
    opts = dict(dict(k=1, radius=2.0, threads=1), **bad)
    one = _message(lambda: rayscan.open(site_file).ray_query(o, d, **opts))
    assert one[0] in (ValueError, TypeError) and one[1]
    missing = tmp_path / "missing.ply"
    for compute in (False, True):
        if opts["k"] is None and not compute:
            continue  # the lazy result needs a k (its own message, test_missing_arguments_raise)
        if opts["k"] == -1 and not compute:
            assert _message(lambda: rd.ray_query(missing, o, d, compute=compute, **opts)) == \
                (ValueError, "k must be an integer >= 1 (columns of the lazy result; k=None needs compute=True), got -1")
            continue
        assert _message(lambda: rd.ray_query(missing, o, d, compute=compute, **opts)) == one, compute


def test_first_hits_options_are_checked_at_the_call(client, site_file, rays, tmp_path):
    o, d = rays
    missing = tmp_path / "missing.ply"
    lazy = rd.first_hits(missing, o, d, radius=2.0)  # good options: nothing raised until the tasks run
    with pytest.raises(OSError, match="missing.ply"):
        lazy["indices"].compute()
    for radius in (-1.0, "2", np.inf):
        one = _message(lambda: rayscan.open(site_file).ray_query(o, d, k=1, radius=radius, t_min=0.0,
                                                                 order="sphere_hit"))
        assert one[0] in (ValueError, TypeError)
        assert _message(lambda: rd.first_hits(missing, o, d, radius=radius)) == one
    assert _message(lambda: rd.first_hits(missing, o, d, radius=2.0, t_min=3.0, t_max=1.0)) == \
        _message(lambda: rayscan.open(site_file).ray_query(o, d, k=1, radius=2.0, t_min=3.0, t_max=1.0,
                                                           order="sphere_hit"))


# Options rayscan.visibility and rayscan.solar refuse whatever the points (the oracle: their own
# exception, type and words), each with the good options of the test below.
_BAD_VISIBILITY_OPTIONS = [dict(cache="lots"), dict(cache=2), dict(ground_radius=-1.0), dict(ground_radius=np.nan),
                           dict(ground_radius="5"), dict(radius="auto"), dict(height=[6.0]), dict(sky_rays=-1),
                           dict(sky_rays=1.5), dict(threads=-1), dict(tolerance="0"), dict(radius=-1.0),
                           dict(radius=np.inf), dict(tolerance=-1.0), dict(target_height=np.nan),
                           dict(max_distance=-1.0)]
_BAD_SOLAR_OPTIONS = [dict(cache="lots"), dict(cache=None), dict(albedo=2.0), dict(albedo="0.2"), dict(linke=0.5),
                      dict(linke=[3.0] * 5), dict(sector=45.0), dict(latitude=100.0, longitude=0.0),
                      dict(latitude=44.05, longitude=None), dict(primitive="cube"), dict(sky_rays=5000),
                      dict(weather="weather.epw"), dict(at=["2024-06-21T18:00", "2024-13-45T00:00"]),
                      dict(at=None, periods=[("2024-06-21T17:00", "June")]),
                      dict(at=None, periods=[("2024-06-21T17:00", "2024-06-21T19:00")], step="2h"),
                      dict(step="15min"), dict(radius=0.0)]


def _ids(options):
    return ",".join(f"{k}={v!r}" for k, v in options.items())


@pytest.mark.parametrize("bad", _BAD_VISIBILITY_OPTIONS, ids=_ids)
def test_visibility_options_are_checked_at_the_call(client, site_file, tmp_path, bad):
    """An option rayscan.visibility refuses raises its exception, in its words, at the
    rayscan.dask call, lazy or compute=True, before any task runs: the path names no file, so a
    task that ran would raise the file's OSError instead (and the lazy call none at all)."""
    xy = rayscan.read(str(site_file).replace(".rsi", ".las")).xyz[:5, :2]
    opts = dict(dict(height=6.0, sky_rays=4), **bad)
    one = _message(lambda: rayscan.visibility(site_file, xy, **opts))
    assert one[0] in (ValueError, TypeError) and one[1]
    missing = tmp_path / "missing.ply"
    for compute in (False, True):
        assert _message(lambda: rd.visibility(missing, xy, chunks=2, compute=compute, **opts)) == one, compute
    if "cache" in bad:  # the ray queries take rayscan.open's cache, refused at the call too
        o, d = np.zeros((3, 3)), np.array([0.0, 0, 1])
        one = _message(lambda: rayscan.open(site_file, cache=bad["cache"]))
        for compute in (False, True):
            assert _message(lambda: rd.ray_query(missing, o, d, radius=1.0, compute=compute, **bad)) == one
    # Good options build the graph: what needs the points (the eyes' ground) is the tasks'.
    rd.visibility(missing, xy, chunks=2, height=6.0, sky_rays=4)
    rd.visibility(missing, xy, chunks=2)  # no height for (K, 2) eyes: found against the points


@pytest.mark.parametrize("bad", _BAD_SOLAR_OPTIONS, ids=_ids)
def test_solar_options_are_checked_at_the_call(client, site_file, tmp_path, bad):
    """As for visibility: what rayscan.solar refuses for the options of one of the instants or
    periods raises its exception, in its words, at the rayscan.dask call, lazy or compute=True."""
    opts = dict(dict(at=["2024-06-21T18:00", "2024-12-21T20:00"], latitude=44.05, longitude=-123.07, sky_rays=4),
                **bad)
    if "weather" in bad:  # a file that opens (rayscan.solar refuses a missing one first)
        opts["weather"] = tmp_path / bad["weather"]
        opts["weather"].write_text("")
    whens = [dict(at=w) for w in opts["at"]] if opts["at"] else [dict(start=s, end=e) for s, e in opts["periods"]]
    single = {k: v for k, v in opts.items() if k not in ("at", "periods")}
    one = None
    for when in whens:  # the first instant or period refused
        try:
            rayscan.solar(site_file, **when, **single)
        except Exception as e:
            one = type(e), str(e)
            break
    assert one is not None and one[0] in (ValueError, TypeError) and one[1]
    missing = tmp_path / "missing.ply"
    for compute in (False, True):
        assert _message(lambda: rd.solar(missing, compute=compute, **opts)) == one, compute
    # Good options build the graph, also without latitude and longitude: a file's CRS is the tasks'.
    rd.solar(missing, at=["2024-06-21T18:00", "2024-12-21T20:00"])
    rd.solar(missing, periods=("2024-06-21T17:00", "2024-06-21T19:00"), step="15min")
    rd.solar(missing, periods=("2024-06-21", "2024-06-30"), weather=tmp_path / "missing.epw")  # a file: the tasks'


@pytest.mark.parametrize("value", ["yes", 1, None])
def test_flags_are_true_or_false(site_file, value):
    """compute (and visibility's distance) take what the module's other flags take (any_hit:
    True or False, a NumPy bool too) and refuse the rest with TypeError naming them: a text "no"
    would otherwise be true."""
    o, d = np.zeros((2, 3)), np.array([0.0, 0, 1])
    expected = f"got {type(value).__name__}"
    assert _message(lambda: rayscan.open(site_file).ray_query(o, d, k=1, radius=1.0, any_hit=value)) == \
        (TypeError, f"any_hit must be True or False, {expected}")
    for call in (lambda: rd.ray_query(site_file, o, d, radius=1.0, compute=value),
                 lambda: rd.first_hits(site_file, o, d, radius=1.0, compute=value),
                 lambda: rd.visibility(site_file, o, compute=value),
                 lambda: rd.solar(site_file, at="2024-06-21T18:00", compute=value)):
        assert _message(call) == (TypeError, f"compute must be True or False, {expected}")
    assert _message(lambda: rd.visibility(site_file, o, distance=value)) == \
        (TypeError, f"distance must be True or False, {expected}")
    lazy = rd.ray_query(site_file, o, d, radius=1.0, compute=np.False_)
    assert lazy["indices"].shape == (2,)
