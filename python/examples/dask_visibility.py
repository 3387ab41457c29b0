"""Visibility for many observers on a Dask cluster: index a LAS file once, then let the workers
split the observers, each opening the memory-mapped index by its path; the counts equal one
process's rayscan.visibility. Needs Dask (Debian: python3-dask python3-distributed).

    PYTHONPATH=build/python /usr/bin/python3 python/examples/dask_visibility.py [OUT.las]
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
from distributed import Client, LocalCluster

import rayscan
import rayscan.dask as rd


def main(out, tmp):
    # %% An index file (.rsi) of the cloud: the workers map it instead of each reading the LAS file
    # and building a tree. `--attributes id` keeps the original point order in every answer.
    las = "tests/data/las/autzen_trim.las"            # 110,000 points, international feet
    rsi = os.path.join(tmp, "autzen.rsi")
    cli = os.environ.get("RAYSCAN_CLI", "build/tools/rayscan")
    subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", rsi, las], check=True)

    # %% 16 observers standing 6 ft above the ground at random points of the scan (x, y only: the
    # job puts each eye `height` above the local ground).
    pc = rayscan.read(las)
    rng = np.random.default_rng(1)
    observers = pc.xyz[rng.choice(len(pc), 16, replace=False), :2]

    # %% Two worker processes with one thread each; every task gets 4 observers and answers for all
    # points (each line of sight needs the whole cloud as occluders), and the counts add up.
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster):
        lazy = rd.visibility(rsi, observers, chunks=4, height=6.0)   # Dask arrays, nothing run yet
        count = lazy["visible_count"].compute()                     # (N,) float64

    # %% Points seen by at least one observer, and the file with the counts as a scalar field.
    print(f"{(count > 0).mean():.1%} of {len(count):,} points seen by at least one of "
          f"{len(observers)} observers; most-seen point: {int(count.max())} observers")
    if out:
        rayscan.write(out, pc, visible_count=count)


if __name__ == "__main__":  # the workers import this file too: work only in the main process
    with tempfile.TemporaryDirectory() as tmp:
        main(sys.argv[1] if len(sys.argv) > 1 else None, tmp)
