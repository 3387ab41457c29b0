"""rayscan.dask on a real two-process LocalCluster against the single-process calls, bit for bit:
ray queries and first hits over Dask arrays of rays, visibility counts for observers split over
tasks, solar instants. Skipped without Dask (Debian: python3-dask, python3-distributed)."""

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
