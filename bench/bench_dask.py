"""rayscan.dask against one process: per-point visibility for many observers and a batch of first
hits over the same index file, on a Dask LocalCluster of W worker processes (one thread each)
and in this process (rayscan.visibility / Site.ray_query with `threads` = W), rounds interleaved.
Answers are compared bit for bit in every round; the figures are wall seconds (the cluster's
start-up is timed apart, once).

    /usr/bin/python3 bench/bench_dask.py BUILD [--workers 2] [--observers 16] [--rays 200000] [--rounds 3]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--observers", type=int, default=16)
    ap.add_argument("--rays", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cloud", default="tests/data/las/autzen_trim.las")
    a = ap.parse_args()
    sys.path.insert(0, os.path.join(a.build, "python"))
    import rayscan
    import rayscan.dask as rd
    import dask
    from distributed import Client, LocalCluster

    with tempfile.TemporaryDirectory() as tmp:
        rsi = os.path.join(tmp, "site.rsi")
        subprocess.run([os.path.join(a.build, "tools", "rayscan"), "index", "-q", "--attributes", "id",
                        "-o", rsi, a.cloud], check=True)
        pc = rayscan.read(a.cloud)
        rng = np.random.default_rng(1)
        observers = pc.xyz[rng.choice(len(pc), a.observers, replace=False), :2]
        lo, hi = pc.xyz.min(axis=0), pc.xyz.max(axis=0)
        origins = np.column_stack([rng.uniform(lo[0], hi[0], a.rays), rng.uniform(lo[1], hi[1], a.rays),
                                   np.full(a.rays, hi[2] + 50.0)])
        dirs = rng.normal(size=(a.rays, 3))
        dirs[:, 2] = -np.abs(dirs[:, 2]) - 1.0
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        site = rayscan.open(rsi)
        print(f"cloud {a.cloud}: {len(pc):,} points; {a.observers} observers; {a.rays:,} rays; "
              f"{a.workers} workers x 1 thread vs one process with {a.workers} threads")
        t0 = time.perf_counter()
        with LocalCluster(n_workers=a.workers, threads_per_worker=1, dashboard_address=None) as cluster, \
                Client(cluster):
            print(f"cluster start-up: {time.perf_counter() - t0:.2f} s")
            for r in range(a.rounds):
                t = time.perf_counter()
                one = rayscan.visibility(rsi, observers, height=6.0, threads=a.workers)["visible_count"]
                t_one = time.perf_counter() - t
                t = time.perf_counter()
                dk = rd.visibility(rsi, observers, chunks=max(1, a.observers // a.workers),
                                   height=6.0)["visible_count"].compute()
                t_dask = time.perf_counter() - t
                assert np.array_equal(one, dk), "visibility: Dask and one process differ"
                t = time.perf_counter()
                h1 = site.ray_query(origins, dirs, k=1, radius=1.0, t_min=0.0, order="sphere_hit",
                                    threads=a.workers)
                t_q1 = time.perf_counter() - t
                t = time.perf_counter()
                hd = rd.first_hits(rsi, origins, dirs, radius=1.0, chunks=a.rays // (2 * a.workers))
                hd_i, _ = dask.compute(hd["indices"], hd["t"])  # one pass over the chunks
                t_qd = time.perf_counter() - t
                assert np.array_equal(h1.first("indices"), hd_i), "first hits: Dask and one process differ"
                print(f"round {r + 1}: visibility one process {t_one:.2f} s, Dask {t_dask:.2f} s "
                      f"({t_one / t_dask:.2f}x); first hits one process {t_q1:.2f} s, Dask {t_qd:.2f} s "
                      f"({t_q1 / t_qd:.2f}x); answers equal")


if __name__ == "__main__":
    main()
