"""Batch queries of rayscan.Octree / KdTree / BruteForce against NumPy brute force (the C++
formulas in the same operation order, so equality is exact) and against the C++ `rayscan query`."""

import csv
import subprocess

import numpy as np
import pytest

import rayscan
from conftest import brute_ray_query, sigint_once_entered

INDEXES = [
    lambda x: rayscan.Octree(x),
    lambda x: rayscan.Octree(x, layout="layered", capacity=8),
    lambda x: rayscan.Octree(x, layout="fixed", depth=4),
    lambda x: rayscan.Octree(x, capacity=4, insertion=True),
    lambda x: rayscan.KdTree(x, capacity=5),
    lambda x: rayscan.BruteForce(x),
]
QUERIES = [
    dict(k=8, order="ray"),
    dict(radius=0.05, order="ray"),
    dict(k=3, radius=0.04, order="time", t_min=0.0),
    dict(k=1, radius=0.02, order="sphere_hit", t_min=0.0),
    dict(radius=0.03, order="sphere_hit", t_min=1.0, t_max=2.5),
]


def check_against_brute(res, xyz, o, d, q):
    assert res.offsets.dtype == np.int64 and res.indices.dtype == np.int64
    assert res.offsets.shape == (len(o) + 1,) and res.offsets[0] == 0
    assert res.offsets[-1] == len(res.indices) == len(res.t) == len(res.distance)
    total = 0
    for i in range(len(o)):
        idx, t, dist = brute_ray_query(xyz, o[i], d[i], **q)
        s = slice(res.offsets[i], res.offsets[i + 1])
        np.testing.assert_array_equal(res.indices[s], idx)
        np.testing.assert_array_equal(res.t[s], t)
        np.testing.assert_array_equal(res.distance[s], dist)
        total += len(idx)
    return total


@pytest.mark.parametrize("make", INDEXES)
@pytest.mark.parametrize("q", QUERIES)
def test_ray_query_equals_brute_force(make, q, uniform_cloud, random_rays):
    o, d = random_rays
    res = make(uniform_cloud).ray_query(o, d, **q)
    total = check_against_brute(res, uniform_cloud, o, d, q)
    assert total > 0  # the workload really returns hits


def test_ray_query_equals_cli(cli, tmp_path, uniform_cloud, random_rays):
    """Same points, same rays: the Python batch equals `rayscan query` row for row (17 digits)."""
    o, d = random_rays
    cloud = tmp_path / "cloud.f64"
    rays = tmp_path / "rays.f64"
    uniform_cloud.astype("<f8").tofile(cloud)
    np.hstack([o, d]).astype("<f8").tofile(rays)
    for q, args in [(dict(k=4, radius=0.05, order="sphere_hit"), ["--k", "4", "--radius", "0.05", "--order", "sphere_hit"]),
                    (dict(k=6, order="ray", t_min=0.5), ["--k", "6", "--t-min", "0.5"]),
                    (dict(radius=0.03, order="time"), ["--radius", "0.03", "--order", "time"])]:
        out = tmp_path / "hits.csv"
        subprocess.run([cli, "query", "--cloud", str(cloud), "--rays", str(rays), "--out", str(out)] + args,
                       check=True)
        with open(out) as f:
            rows = list(csv.DictReader(f))
        res = rayscan.Octree(uniform_cloud).ray_query(o, d, **q)
        assert len(rows) == len(res.indices) > 0
        ray = np.array([int(r["ray"]) for r in rows])
        np.testing.assert_array_equal(np.bincount(ray, minlength=len(o)), res.counts)
        np.testing.assert_array_equal([int(r["index"]) for r in rows], res.indices)
        np.testing.assert_array_equal([float(r["t"]) for r in rows], res.t)
        np.testing.assert_array_equal([float(r["distance"]) for r in rows], res.distance)


def test_broadcast_origin_and_first(uniform_cloud):
    """One origin (3,) against M directions; first() gives the best hit per ray, -1/NaN for misses."""
    tree = rayscan.Octree(uniform_cloud)
    o = np.array([0.5, 0.5, 0.5])
    d = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=np.float32)
    res = tree.ray_query(o, d, k=1, radius=0.01, order="sphere_hit", t_min=0.0, t_max=0.2)
    assert len(res) == 4
    for i in range(4):
        idx, t, _ = brute_ray_query(uniform_cloud, o, d[i].astype(np.float64), k=1, radius=0.01,
                                    order="sphere_hit", t_min=0.0, t_max=0.2)
        assert res.first()[i] == (idx[0] if len(idx) else -1)
        if len(idx):
            assert res.first("t")[i] == t[0]
            np.testing.assert_array_equal(res[i], idx)
        else:
            assert np.isnan(res.first("t")[i])
    # "index" (the CLI's column name) is "indices"; an unknown field names the valid ones.
    np.testing.assert_array_equal(res.first("index"), res.first("indices"))
    with pytest.raises(ValueError, match="not one of indices, t, distance"):
        res.first("depth")


def test_knn_and_radius_equal_brute_force(uniform_cloud):
    rng = np.random.default_rng(3)
    qs = rng.random((50, 3))
    qs[0] = uniform_cloud[0]  # a query on a duplicated point: ties at distance 0
    for make in INDEXES:
        tree = make(uniform_cloud)
        knn = tree.knn(qs, k=12)
        rad = tree.radius(qs, 0.08)
        both = tree.knn(qs, k=5, radius=0.05)
        for i, q in enumerate(qs):
            v = uniform_cloud - q
            d2 = v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2]
            order = np.lexsort((np.arange(len(d2)), d2))
            np.testing.assert_array_equal(knn[i], order[:12])
            np.testing.assert_array_equal(knn.distance[knn.offsets[i]:knn.offsets[i + 1]], np.sqrt(d2[order[:12]]))
            within = order[d2[order] <= 0.08 * 0.08]
            np.testing.assert_array_equal(rad[i], within)
            np.testing.assert_array_equal(both[i], order[d2[order] <= 0.05 * 0.05][:5])
        assert rad.counts.sum() > 0


def test_k_past_the_point_count_and_infinite_radius_return_every_point(cli, tmp_path):
    """k larger than N (up to any size: 10**30 is past every C++ integer) means no k limit, and an
    infinite radius no distance limit: each query gets all N points ranked by (distance, index),
    as NumPy ranks them, on every index and on a Site (an .rsi index with ids, a file indexed in
    memory). The result is CSR, so nothing is sized by k."""
    rng = np.random.default_rng(11)
    xyz = rng.random((300, 3))
    xyz[200:203] = xyz[7]  # ties broken by index
    qs = np.vstack([xyz[7], rng.random((4, 3)) * 3 - 1])
    ply = tmp_path / "small.ply"
    rayscan.write(str(ply), xyz)
    rsi = tmp_path / "small.rsi"
    subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", str(rsi), str(ply)], check=True)
    indexes = [make(xyz) for make in INDEXES] + [rayscan.open(str(rsi)), rayscan.open(str(ply))]
    assert [s.storage for s in indexes[-2:]] == ["index_file", "memory"]
    for index in indexes:
        answers = [index.knn(qs, k) for k in (len(xyz), len(xyz) + 1, 2**32, 2**64, 10**30)]
        answers += [index.radius(qs, np.inf), index.radius(qs, float("inf")), index.knn(qs, 10**30, radius=np.inf)]
        for res in answers:
            assert res.offsets.tolist() == [len(xyz) * i for i in range(len(qs) + 1)]
            for i, q in enumerate(qs):
                v = xyz - q
                d2 = v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2]
                order = np.lexsort((np.arange(len(d2)), d2))
                np.testing.assert_array_equal(res[i], order)
                np.testing.assert_array_equal(res.distance[res.offsets[i]:res.offsets[i + 1]], np.sqrt(d2[order]))
        # A finite k below N still limits, a huge k with a finite radius keeps the radius.
        assert index.knn(qs, 299).counts.tolist() == [299] * len(qs)
        near = index.knn(qs[:1], 10**30, radius=0.2)
        v = xyz - qs[0]
        assert len(near.indices) == np.count_nonzero(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2] <= 0.2 * 0.2)


def test_box_equals_numpy_mask(uniform_cloud):
    rng = np.random.default_rng(4)
    lo = rng.random((20, 3)) * 0.7
    hi = lo + rng.random((20, 3)) * 0.4
    for make in INDEXES:
        res = make(uniform_cloud).box(lo, hi)
        for i in range(20):
            mask = np.all((uniform_cloud >= lo[i]) & (uniform_cloud <= hi[i]), axis=1)
            np.testing.assert_array_equal(np.sort(res[i]), np.nonzero(mask)[0])
        assert res.counts.sum() > 0
    empty = rayscan.Octree(uniform_cloud).box([0.6, 0, 0], [0.4, 1, 1])  # lo > hi: empty box
    assert empty.counts.tolist() == [0]


def test_non_contiguous_and_other_dtypes_equal_contiguous(uniform_cloud, random_rays):
    o, d = random_rays
    big = np.zeros((len(uniform_cloud), 6))
    big[:, ::2] = uniform_cloud  # strided columns
    ref = rayscan.Octree(uniform_cloud).ray_query(o, d, k=5, radius=0.05)
    for xyz in (big[:, ::2], np.asfortranarray(uniform_cloud), uniform_cloud.tolist()):
        res = rayscan.Octree(xyz).ray_query(np.asfortranarray(o), d[:, [0, 1, 2]], k=5, radius=0.05)
        np.testing.assert_array_equal(res.indices, ref.indices)
        np.testing.assert_array_equal(res.t, ref.t)
    ints = np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]], dtype=np.int32)
    assert rayscan.KdTree(ints).knn([1.1, 1, 1], k=1).indices.tolist() == [1]


def test_empty_inputs():
    tree = rayscan.Octree(np.zeros((0, 3)))
    assert len(tree) == 0
    res = tree.ray_query([0, 0, 0], [1, 0, 0], k=1)
    assert res.offsets.tolist() == [0, 0] and len(res.indices) == 0
    tree = rayscan.Octree(np.random.default_rng(1).random((10, 3)))
    res = tree.ray_query(np.zeros((0, 3)), np.zeros((0, 3)), allow_all=True)
    assert res.offsets.tolist() == [0]
    assert tree.knn(np.zeros((0, 3)), k=2).offsets.tolist() == [0]


def test_bad_arguments_raise_value_error(uniform_cloud):
    tree = rayscan.Octree(uniform_cloud)
    o = np.zeros((4, 3))
    d = np.ones((4, 3))
    cases = [
        (lambda: rayscan.Octree(np.zeros((5, 2))), "xyz: expected shape (N, 3), got (5, 2)"),
        (lambda: rayscan.Octree(np.zeros((2, 3, 1))), "xyz: expected shape (N, 3)"),
        (lambda: rayscan.Octree(np.array([[0, 0, 0], [1, np.nan, 0.0]])), "point 1"),
        (lambda: rayscan.KdTree(np.array([[0, np.inf, 0.0]])), "point 0"),
        (lambda: rayscan.Octree(uniform_cloud, layout="sparse"), "octree layout 'sparse'"),
        (lambda: rayscan.Octree(uniform_cloud, capacity=0), "capacity must be"),
        (lambda: rayscan.Octree(uniform_cloud, capacity=-5), "capacity must be"),
        (lambda: rayscan.Octree(uniform_cloud, layout="fixed", depth=22), "depth must be None or an integer in [0, 21], got 22"),
        (lambda: tree.ray_query(o, np.zeros((4, 3))), "ray 0: Ray: direction must be non-zero"),
        (lambda: tree.ray_query(np.array([[0, 0, 0], [np.nan, 0, 0]]), d[:2]), "ray 1: Ray: origin must be finite"),
        (lambda: tree.ray_query(o, np.ones((3, 3))), "origins has 4 rows but directions has 3"),
        (lambda: tree.ray_query(o, d, order="closest"), "order 'closest'"),
        (lambda: tree.ray_query(o, d, order="sphere_hit"), "sphere_hit requires a finite radius"),
        (lambda: tree.ray_query(o, d, radius=-1.0), "radius must be >= 0"),
        (lambda: tree.ray_query(o, d, radius=float("nan")), "must not be NaN"),
        (lambda: tree.ray_query(o, d, t_min=2.0, t_max=1.0), "t_min"),
        (lambda: tree.ray_query(o, d, k=-1), "k must be None or an integer >= 0"),
        (lambda: tree.ray_query(o, [[1, 2], [3, 4]]), "directions: expected shape"),
        (lambda: tree.ray_query(o, [[1, 2, 3], [1, 2]]), ""),  # ragged: NumPy's own ValueError
        (lambda: tree.knn([[0, 0, np.nan]], k=1), "query point 0 is not finite"),
        (lambda: tree.radius(o, -0.5), "radius must be >= 0"),
        (lambda: tree.box([0, 0, np.nan], [1, 1, 1]), "box 0: lo and hi must not be NaN"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError) as e:
            call()
        assert message in str(e.value), (message, str(e.value))
    # numpy integer types are valid k values
    assert tree.ray_query(o, d, k=np.int64(2), radius=0.1).counts.max() <= 2


def test_thread_count_does_not_change_results(uniform_cloud, random_rays):
    o, d = random_rays
    tree = rayscan.Octree(uniform_cloud)
    for threads in (1, 2, 3):
        a = tree.ray_query(o, d, k=4, radius=0.05, threads=threads)
        b = tree.ray_query(o, d, k=4, radius=0.05)
        np.testing.assert_array_equal(a.indices, b.indices)
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(tree.knn(o, 3, threads=threads).indices, tree.knn(o, 3).indices)
    with pytest.raises(ValueError, match="threads must be"):
        tree.box([0, 0, 0], [1, 1, 1], threads=-1)


def test_first_batch_of_a_fresh_process_equals_brute_force(tmp_path):
    # The first query on each fresh worker thread is the one that touches its thread_local scratch
    # for the first time (with TLS descriptors on glibc 2.36 that first ray lost its hit, see
    # python/CMakeLists.txt): a new interpreter, one batch, checked against BruteForce ray by ray.
    import os
    import pathlib
    import sys
    script = tmp_path / "first_batch.py"
    script.write_text(
        "import numpy as np, rayscan\n"
        "rng = np.random.default_rng(7)\n"
        "xyz = rng.random((20000, 3))\n"
        "v = rng.normal(size=(2000, 3))\n"
        "o = 0.5 + 2.0 * v / np.linalg.norm(v, axis=1, keepdims=True)\n"
        "d = xyz[rng.integers(0, len(xyz), 2000)] - o\n"
        "a = rayscan.Octree(xyz).ray_query(o, d, k=1, radius=0.004, t_min=0.0, order='sphere_hit', threads=2)\n"
        "b = rayscan.BruteForce(xyz).ray_query(o, d, k=1, radius=0.004, t_min=0.0, order='sphere_hit')\n"
        "assert np.array_equal(a.offsets, b.offsets), np.nonzero(np.asarray(a.counts) != np.asarray(b.counts))[0][:5]\n"
        "assert np.array_equal(a.indices, b.indices) and np.array_equal(a.t, b.t)\n"
        "print(len(b.indices))\n")
    env = dict(os.environ, PYTHONPATH=str(pathlib.Path(rayscan.__file__).resolve().parent.parent))
    out = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) >= 1900  # every ray aims at a data point


def test_default_capacities_follow_the_layout(uniform_cloud):
    # capacity=None takes each index type's default (octree_rules.hpp default_capacity, as documented in
    # the docstrings): adaptive 64, layered 32, kd-tree 32; the property reports the built one.
    adaptive = rayscan.Octree(uniform_cloud)
    assert adaptive.capacity == 64
    assert adaptive.node_count == rayscan.Octree(uniform_cloud, capacity=64).node_count
    assert adaptive.node_count != rayscan.Octree(uniform_cloud, capacity=32).node_count
    assert rayscan.Octree(uniform_cloud, layout="layered").capacity == 32
    assert rayscan.KdTree(uniform_cloud).capacity == 32
    assert rayscan.Octree(uniform_cloud, capacity=7).capacity == 7


def test_brute_force_refuses_a_non_finite_point_like_the_trees():
    """Every index refuses NaN and infinite coordinates with the same message (a brute force scan
    that kept them would return them as hits)."""
    for make, name in ((rayscan.Octree, "octree"), (rayscan.KdTree, "kdtree"), (rayscan.BruteForce, "brute")):
        for bad in (np.nan, np.inf, -np.inf):
            with pytest.raises(ValueError) as e:
                make([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, bad, 0.5]])
            assert str(e.value) == f"{name}: point 2 has a non-finite coordinate"


def test_result_indexing_follows_python_sequences(uniform_cloud):
    """r[i] for i in [-M, M) is query i's hits (negative from the end, as in a list) against a
    NumPy oracle; outside that range IndexError naming the index and the query count."""
    qs = uniform_cloud[:3]
    for make in INDEXES:
        r = make(uniform_cloud).knn(qs, k=2)
        oracle = []
        for q in qs:
            v = uniform_cloud - q
            d2 = v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2]
            oracle.append(np.lexsort((np.arange(len(d2)), d2))[:2].tolist())
        for i in range(-3, 3):
            assert r[i].tolist() == oracle[i], i
        assert [hits.tolist() for hits in r] == oracle  # iteration stops at the end
        for i in (3, -4, 2**70):
            with pytest.raises(IndexError) as e:
                r[i]
            assert str(e.value) == f"query index {i} is out of range for 3 queries"
        assert r[np.int64(-1)].tolist() == oracle[2]
        with pytest.raises(TypeError, match="query index must be an integer, got float"):
            r[1.0]


def test_box_with_infinite_bounds_is_half_open(uniform_cloud):
    """Infinite corners bound nothing on their side (NumPy's comparisons are the oracle); NaN
    is still refused."""
    inf = np.inf
    lo = np.array([[-inf, -inf, 0.5], [-inf, -inf, -inf], [0.2, -inf, 0.3], [inf, 0, 0]])
    hi = np.array([[inf, inf, inf], [inf, inf, inf], [0.6, 0.4, inf], [inf, 1, 1]])
    for make in INDEXES:
        res = make(uniform_cloud).box(lo, hi)
        for i in range(len(lo)):
            mask = np.all((uniform_cloud >= lo[i]) & (uniform_cloud <= hi[i]), axis=1)
            np.testing.assert_array_equal(np.sort(res[i]), np.nonzero(mask)[0])
        assert res.counts[1] == len(uniform_cloud) and res.counts[3] == 0 and 0 < res.counts[0] < len(uniform_cloud)
    with pytest.raises(ValueError, match="box 0: lo and hi must not be NaN"):
        rayscan.Octree(uniform_cloud).box([-inf, np.nan, 0], [inf, inf, inf])


def test_empty_batch_broadcasts_against_one_row(uniform_cloud):
    """(0, 3) against a (3,) row is zero queries, as NumPy broadcasts (0, 3) with (3,)."""
    tree = rayscan.Octree(uniform_cloud)
    none = np.zeros((0, 3))
    assert np.broadcast_shapes(none.shape, (3,)) == (0, 3)
    for res in (tree.ray_query(none, [0, 0, 1], k=1, radius=0.1),
                tree.ray_query([0, 0, 0], none, k=1, radius=0.1),
                tree.box(none, [1, 1, 1]), tree.box([0, 0, 0], none)):
        assert len(res) == 0 and res.offsets.tolist() == [0] and len(res.indices) == 0
    with pytest.raises(ValueError, match="origins has 0 rows but directions has 2"):
        tree.ray_query(none, np.ones((2, 3)), k=1)
    with pytest.raises(ValueError, match="lo has 2 rows but hi has 0"):
        tree.box(np.zeros((2, 3)), none)


def test_ctrl_c_stops_a_long_batch(monkeypatch):
    # A batch of 2^19 rays against 20,000 points by brute force, interrupted as Ctrl-C would once
    # the call has begun (sigint_once_entered). KeyboardInterrupt comes after the running chunk,
    # not at the end of the batch: its note says how many queries ran, short of the batch. The
    # index then answers the next call.
    import re
    rng = np.random.default_rng(3)
    b = rayscan.BruteForce(rng.random((20000, 3)))
    n = 1 << 19
    o, d = rng.random((n, 3)), rng.normal(size=(n, 3))
    interrupted = sigint_once_entered(monkeypatch, b, "_ray_query",
                                      lambda: b.ray_query(o, d, k=1, radius=0.01, threads=1))
    notes = getattr(interrupted, "__notes__", [])
    m = re.fullmatch(r"interrupted after (\d+) of (\d+) queries", notes[0] if notes else "")
    assert m, "KeyboardInterrupt without the batch's note (raised outside the batch?): {}".format(notes)
    done, total = int(m[1]), int(m[2])
    assert total == n and 0 < done < n, (done, total)
    r = b.ray_query(o[:3], d[:3], k=1, radius=0.01)
    assert len(r) == 3


@pytest.mark.parametrize("threads", [0, 1])
def test_ctrl_c_stops_slow_queries_after_a_few_of_them(monkeypatch, threads):
    # 100,000 radius queries against 200,000 points by brute force: each scans every point (about
    # 0.3 ms), half a minute of work or more on one thread, in a batch smaller than any fixed chunk
    # that would make a check for a signal cheap for fast queries (kNN of k=1 take microseconds).
    # Chunks sized by time answer Ctrl-C, sent once the call has begun, after a small share of the
    # batch: the note counts the queries that ran (the test's measure, whatever the machine's
    # speed or load), and the wait is far below the batch's time. The answers of the queries are
    # those of a batch run whole.
    import re
    import time
    rng = np.random.default_rng(11)
    xyz = rng.random((200_000, 3))
    b = rayscan.BruteForce(xyz)
    q = rng.random((100_000, 3))
    start = time.monotonic()
    interrupted = sigint_once_entered(monkeypatch, b, "_knn", lambda: b.radius(q, 0.01, threads=threads))
    waited = time.monotonic() - start
    notes = getattr(interrupted, "__notes__", [])
    m = re.fullmatch(r"interrupted after (\d+) of (\d+) queries", notes[0] if notes else "")
    assert m, "KeyboardInterrupt without the batch's note (raised after the batch?): {}".format(notes)
    done, total = int(m[1]), int(m[2])
    assert total == len(q) and 0 < done <= total // 20, (done, total)
    assert waited < 5.0, waited
    # A batch of several chunks keeps each query's answer in its row: NumPy's, sorted by
    # (distance, index).
    part = b.radius(q[:300], 0.01, threads=threads)
    for i in range(300):
        dist = np.sqrt(((xyz - q[i]) ** 2).sum(axis=1))
        idx = np.nonzero(dist <= 0.01)[0]
        idx = idx[np.lexsort((idx, dist[idx]))]
        np.testing.assert_array_equal(part[i], idx)
