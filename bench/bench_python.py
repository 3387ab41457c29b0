#!/usr/bin/env python3
"""bench_python: the `rayscan` Python module against the C++ batch, NumPy and Open3D.

1. Python batch ray query vs the C++ batch (python_batch_peer: rayscan::ray_query_batch) on the
   same points and rays, same index: throughput ratio Python / C++ (goal >= 0.95).
2. rayscan vs a NumPy brute force (vectorised over the points, one ray at a time) on 1e5 points.
3. kNN (k = 8) next to Open3D: KDTreeFlann.search_knn_vector_3d (one call per query, the API
   Python users reach for) and open3d.core.nns.NearestNeighborSearch.knn_search (batch).
Every contender runs once per round, rounds interleave them, medians are reported; answers are
cross-checked before timing (exit 3 on a mismatch). Each call is timed by the wall clock and by
the process CPU time (all threads, time.process_time / std::clock): on a loaded shared machine the
CPU-time ratios are the figures to read (waiting for a core is excluded, cache interference is not).

Usage: /usr/bin/python3 bench/bench_python.py BUILD_DIR [--quick] [--rounds R] [--scratch DIR]
"""

import argparse
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np


def cube_rays(rng, m):
    """Origins on a sphere of radius 2 around the unit cube's centre, aimed at uniform points in it
    (the random rays of bench_rays)."""
    v = rng.normal(size=(m, 3))
    o = 0.5 + 2.0 * v / np.linalg.norm(v, axis=1, keepdims=True)
    return o, rng.random((m, 3)) - o


def timed(f):
    """(wall ms, process CPU ms, f())."""
    c0, t0 = time.process_time(), time.perf_counter()
    r = f()
    t1, c1 = time.perf_counter(), time.process_time()
    return (t1 - t0) * 1e3, (c1 - c0) * 1e3, r


def fail(msg):
    print("bench_python: MISMATCH: " + msg)
    sys.exit(3)


def brute_first_hit(xyz, o, d, r):
    """NumPy brute force of the first sphere hit (order sphere_hit, k = 1, t >= 0) of one ray."""
    d = d / np.linalg.norm(d)
    v = xyz - o
    tp = v @ d
    w = v - tp[:, None] * d
    d2 = np.einsum("ij,ij->i", w, w)
    t = tp - np.sqrt(np.maximum(0.0, r * r - d2))
    t[(d2 > r * r) | (t < 0)] = np.inf
    i = int(np.argmin(t))
    return (i, t[i]) if np.isfinite(t[i]) else (-1, np.inf)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("--quick", action="store_true", help="smaller sizes, 3 rounds")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--scratch", type=pathlib.Path, default=None,
                    help="folder for the generated .f64 files (deleted afterwards)")
    a = ap.parse_args()
    sys.path.insert(0, str(a.build / "python"))
    import rayscan

    peer = a.build / "bench" / "python_batch_peer"
    rounds = 3 if a.quick else a.rounds
    n_points = 200_000 if a.quick else 1_000_000
    n_rays = 20_000 if a.quick else 100_000
    rng = np.random.default_rng(20240601)
    print(f"# bench_python: rayscan {pathlib.Path(rayscan.__file__).parent}, NumPy {np.__version__}, "
          f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}, {rounds} interleaved rounds, medians")

    # 1. Python batch vs C++ batch -------------------------------------------------------------
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="bench_python.", dir=a.scratch))
    try:
        xyz = rng.random((n_points, 3))
        o, d = cube_rays(rng, n_rays)
        xyz.astype("<f8").tofile(scratch / "cloud.f64")
        np.hstack([o, d]).astype("<f8").tofile(scratch / "rays.f64")
        tree = rayscan.Octree(xyz, capacity=32)
        print(f"\n## 1. ray query batch, {n_points} uniform points, {n_rays} rays, octree adaptive 32, "
              "t_min = 0; Python call (arrays in, CSR arrays out) vs rayscan::ray_query_batch")
        print("| query | C++ batch ms wall / CPU | Python batch ms wall / CPU | Python k rays per CPU-s | "
              "ratio Python / C++ throughput, wall / CPU |")
        print("|---|---:|---:|---:|---:|")
        for name, k, radius, order in [("sphere (k=1, r=0.002, sphere_hit)", 1, 0.002, "sphere_hit"),
                                       ("knn8 (k=8, order ray)", 8, float("inf"), "ray")]:
            py = lambda: tree.ray_query(o, d, k=k, radius=radius, t_min=0.0, order=order)
            res = py()  # warm-up and answer for the cross-check
            cpp_ms, py_ms, cpp_cpu, py_cpu = [], [], [], []
            for rnd in range(rounds):
                def cpp():
                    out = subprocess.run([str(peer), str(scratch / "cloud.f64"), str(scratch / "rays.f64"),
                                          str(k), str(radius), order, "32", "1"],
                                         check=True, capture_output=True, text=True).stdout.split("\n")
                    return out
                contenders = [("cpp", cpp), ("py", py)]
                if rnd % 2:
                    contenders.reverse()
                for who, f in contenders:
                    if who == "cpp":
                        out = f()
                        cpp_ms.append(float(out[0].split()[1]))
                        cpp_cpu.append(float(out[0].split()[2]))
                        chk = out[1].split()
                        if (int(chk[1]) != len(res.indices) or float(chk[2]) != float(res.indices.sum())
                                or not np.isclose(float(chk[3]), res.t.sum(), rtol=1e-12)):
                            fail(f"{name}: C++ {chk[1:]} vs Python {len(res.indices)} {res.indices.sum()} {res.t.sum()}")
                    else:
                        w, c, _ = timed(f)
                        py_ms.append(w)
                        py_cpu.append(c)
            c, p = statistics.median(cpp_ms), statistics.median(py_ms)
            cc, pc = statistics.median(cpp_cpu), statistics.median(py_cpu)
            print(f"| {name} | {c:.1f} / {cc:.1f} | {p:.1f} / {pc:.1f} | {n_rays / pc:.1f} | "
                  f"{c / p:.3f}x / {cc / pc:.3f}x |")
    finally:
        shutil.rmtree(scratch)

    # 2. vs NumPy brute force ------------------------------------------------------------------
    n = 100_000
    pts = rng.random((n, 3))
    o, d = cube_rays(rng, 10_000)
    r = 0.005
    nb = 50 if a.quick else 200
    small = rayscan.Octree(pts)
    res = small.ray_query(o, d, k=1, radius=r, t_min=0.0, order="sphere_hit")
    first, first_t = res.first(), res.first("t")
    for i in range(20):
        bi, bt = brute_first_hit(pts, o[i], d[i], r)
        if bi != first[i] or (bi >= 0 and not np.isclose(bt, first_t[i], rtol=1e-12)):
            fail(f"brute force ray {i}: {bi} {bt} vs {first[i]} {first_t[i]}")
    ours, ours1, brute = [], [], []
    for _ in range(rounds):
        ours.append(timed(lambda: small.ray_query(o, d, k=1, radius=r, t_min=0.0, order="sphere_hit"))[1]
                    / len(o))
        ours1.append(timed(lambda: small.ray_query(o, d, k=1, radius=r, t_min=0.0, order="sphere_hit",
                                                   threads=1))[1] / len(o))
        brute.append(timed(lambda: [brute_first_hit(pts, o[i], d[i], r) for i in range(nb)])[1] / nb)
    us, us1, bf = statistics.median(ours), statistics.median(ours1), statistics.median(brute)
    print(f"\n## 2. first hit (k=1, sphere_hit, r={r}) on {n} uniform points: rayscan batch "
          f"({len(o)} rays) vs NumPy brute force ({nb} rays, one vectorised pass over the points per ray)")
    print("| contender | CPU us per ray | rays per CPU-s | factor |")
    print("|---|---:|---:|---:|")
    print(f"| rayscan Octree.ray_query (threads=1) | {us1 * 1e3:.2f} | {1e3 / us1:,.0f} | {bf / us1:,.0f}x |")
    print(f"| rayscan Octree.ray_query (all {os.cpu_count()} threads) | {us * 1e3:.2f} | {1e3 / us:,.0f} | {bf / us:,.0f}x |")
    print(f"| NumPy brute force (1 thread) | {bf * 1e3:.1f} | {1e3 / bf:,.0f} | 1x |")

    # 3. kNN next to Open3D ----------------------------------------------------------------------
    try:
        import open3d as o3d
    except ImportError:
        print("\n## 3. Open3D not installed (python3-open3d): skipped")
        return
    nq = 20_000
    queries = rng.random((nq, 3))
    k = 8
    kd_tree = rayscan.KdTree(pts)
    ours = small.knn(queries, k)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    flann = o3d.geometry.KDTreeFlann(pcd)
    nns = o3d.core.nns.NearestNeighborSearch(o3d.core.Tensor(pts))
    nns.knn_index()
    t_queries = o3d.core.Tensor(queries)
    nq_flann = 2_000 if a.quick else nq
    idx_o3d, d2_o3d = nns.knn_search(t_queries, k)
    d_ours = ours.distance.reshape(nq, k)
    if not np.allclose(np.sqrt(d2_o3d.numpy()), d_ours, rtol=1e-9, atol=1e-12):
        fail("kNN distances differ from open3d.core.nns")
    for i in range(100):
        _, fi, fd2 = flann.search_knn_vector_3d(queries[i], k)
        if not np.allclose(np.sqrt(np.asarray(fd2)), d_ours[i], rtol=1e-9, atol=1e-12):
            fail(f"kNN query {i}: distances differ from KDTreeFlann")
    t = {"octree": [], "kdtree": [], "nns": [], "flann": []}
    w = {key: [] for key in t}
    for _ in range(rounds):
        for key, f, scale in [("octree", lambda: small.knn(queries, k), 1),
                              ("kdtree", lambda: kd_tree.knn(queries, k), 1),
                              ("nns", lambda: nns.knn_search(t_queries, k), 1),
                              ("flann", lambda: [flann.search_knn_vector_3d(q, k) for q in queries[:nq_flann]],
                               nq / nq_flann)]:
            wall, cpu, _ = timed(f)
            w[key].append(wall * scale)
            t[key].append(cpu * scale)
    med = {key: statistics.median(v) for key, v in t.items()}
    medw = {key: statistics.median(v) for key, v in w.items()}
    print(f"\n## 3. kNN, k = {k}, {nq} random queries on the same {n} points (answers checked equal)")
    print("| contender | ms wall | ms CPU (all threads) | CPU us per query | ratio of CPU time, rayscan octree / contender |")
    print("|---|---:|---:|---:|---:|")
    labels = {"octree": "rayscan Octree.knn (batch, TBB)", "kdtree": "rayscan KdTree.knn (batch, TBB)",
              "nns": "Open3D core.nns.NearestNeighborSearch.knn_search (batch)",
              "flann": f"Open3D KDTreeFlann.search_knn_vector_3d (Python loop{', scaled from ' + str(nq_flann) if nq_flann != nq else ''})"}
    for key in ["octree", "kdtree", "nns", "flann"]:
        print(f"| {labels[key]} | {medw[key]:.1f} | {med[key]:.1f} | {med[key] * 1e3 / nq:.2f} | "
              f"{med['octree'] / med[key]:.2f}x |")


if __name__ == "__main__":
    main()
