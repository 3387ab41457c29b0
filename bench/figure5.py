"""The paper's query benchmark (Teuscher et al., section 5.2, Figure 5): ray queries of the kNN,
radius and closest modalities on uniform random points in the unit cube, 1e6, 1e7 and 1e8 points
(the largest from an index file, `rayscan index`, memory-mapped), queries per second per thread at
1 and 2 threads, and a plot.

The paper measures "distance to the ray origin"; rayscan's orders are the distance to the ray's
line (eq. 1, `order="ray"`) and the parameter t along the ray (eq. 2, `order="time"`), which is the
distance from the origin for the points on the ray's cylinder. So:
  kNN k      k points nearest the ray's line, in front of the origin (t >= 0), no radius
             (ranking every point of the cloud by t alone would return the points nearest the
             origin's plane, not a ray query);
  radius r   every point within r of the ray's line, t >= 0, ranked by t;
  closest    the k = 1 and k = 8 first points along the ray (smallest t >= 0) within r.
Rays: origins uniform in the cube, directions uniform on the sphere, the same seed for every N.
Each case runs a calibration batch, then enough rays for about --seconds at one thread, measured
--repeats times per thread count (the best is kept: the machine is shared).

    /usr/bin/python3 bench/figure5.py BUILD [--points 1e6,1e7,1e8] [--threads 1,2]
        [--csv bench/results/figure5.csv] [--png bench/figure5.png] [--scratch DIR]
        [--driver BUILD/bench/bench_figure5]
The 1e8 index needs about 4.5 GB of free disk in --scratch (checked first; deleted afterwards).
--driver measures with the C++ program bench_figure5 instead of the Python module (every size in
memory, no index file; no rayscan module needed, only NumPy and matplotlib): for machines where
the module does not run.
"""
import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

RADII = (0.001, 0.003, 0.01)
CASES = ([("kNN k=%d" % k, dict(k=k, order="ray")) for k in (1, 8, 64)]
         + [("radius r=%g" % r, dict(radius=r, order="time")) for r in RADII]
         + [("closest k=%d r=0.003" % k, dict(k=k, radius=0.003, order="time")) for k in (1, 8)])


def rays(m, seed=5):
    rng = np.random.default_rng(seed)
    o = rng.uniform(0.0, 1.0, (m, 3))
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return o, d


def timed(index, o, d, kw, threads):
    t = time.perf_counter()
    res = index.ray_query(o, d, t_min=0.0, threads=threads, **kw)
    return time.perf_counter() - t, len(res.indices)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--points", default="1e6,1e7,1e8")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--csv", default="bench/results/figure5.csv")
    ap.add_argument("--png", default="bench/figure5.png")
    ap.add_argument("--scratch", default=None)
    ap.add_argument("--seconds", type=float, default=0.5, help="target time per measurement (1 thread)")
    ap.add_argument("--repeats", type=int, default=3, help="measurements per thread count (the best is kept)")
    ap.add_argument("--plot-only", action="store_true", help="plot --csv again without measuring")
    ap.add_argument("--driver", default=None, help="measure with this bench_figure5 program instead of the module")
    a = ap.parse_args()
    if a.plot_only:
        with open(a.csv) as f:
            rows = [dict(r, points=int(r["points"]), threads=int(r["threads"]), per_thread=float(r["per_thread"]),
                         queries_per_s=float(r["queries_per_s"])) for r in csv.DictReader(f)]
        sizes = sorted({r["points"] for r in rows})
        threads = sorted({r["threads"] for r in rows})
        plot(rows, sizes, threads, rows[0]["cpu"], a.png)
        return
    sizes = [int(float(x)) for x in a.points.split(",")]
    threads = [int(x) for x in a.threads.split(",")]
    rows = []
    cpu = subprocess.run(["sh", "-c", "lscpu | sed -n 's/^Model name: *//p'"], capture_output=True,
                         text=True).stdout.strip()
    if a.driver:
        print(f"CPU: {cpu}; {os.cpu_count()} CPUs; measured by {a.driver}")
        for n in sizes:
            rows += measure_with_driver(a.driver, n, threads, a.seconds, a.repeats, cpu)
        write_and_plot(rows, sizes, threads, cpu, a.csv, a.png)
        return
    sys.path.insert(0, os.path.join(a.build, "python"))
    import rayscan
    print(f"CPU: {cpu}; {os.cpu_count()} CPUs; rayscan {rayscan.__version__}")
    for n in sizes:
        scratch = None
        t0 = time.perf_counter()
        if n >= 50_000_000:
            scratch = tempfile.mkdtemp(prefix="figure5-", dir=a.scratch)
            need = n * 45
            free = shutil.disk_usage(scratch).free
            if free < need:
                shutil.rmtree(scratch)
                sys.exit(f"figure5: {scratch} has {free / 1e9:.1f} GB free, {need / 1e9:.1f} GB needed for {n:.0e} points")
            pts = os.path.join(scratch, "points.f64")
            rng = np.random.default_rng(1)
            with open(pts, "wb") as f:  # in slices: 1e8 points are 2.4 GB
                for s in range(0, n, 10_000_000):
                    rng.uniform(0.0, 1.0, (min(10_000_000, n - s), 3)).tofile(f)
            rsi = os.path.join(scratch, "points.rsi")
            subprocess.run([os.path.join(a.build, "tools", "rayscan"), "index", "-q", "-o", rsi, pts], check=True)
            os.remove(pts)
            index = rayscan.open(rsi)
            where = "index file (mapped)"
        else:
            index = rayscan.Octree(np.random.default_rng(1).uniform(0.0, 1.0, (n, 3)))
            where = "in memory"
        print(f"{n:.0e} points ({where}): ready in {time.perf_counter() - t0:.1f} s")
        for name, kw in CASES:
            o, d = rays(256)
            timed(index, o, d, kw, 1)  # warm-up
            dt, hits = timed(index, o, d, kw, 1)  # calibration
            per_ray = max(dt / 256, 1e-7)
            m = int(min(500_000, max(256, a.seconds / per_ray), 2e7 / max(1.0, hits / 256)))
            o, d = rays(m)
            for th in threads:
                dt, hits = min(timed(index, o, d, kw, th) for _ in range(a.repeats))  # best of
                rows.append(row_of(n, name, th, m, dt, hits, cpu))
        del index
        if scratch:
            shutil.rmtree(scratch)
    write_and_plot(rows, sizes, threads, cpu, a.csv, a.png)


def row_of(n, name, th, m, dt, hits, cpu):
    qps = m / dt
    print(f"  {name:<22} {th} thread(s): {m:>7} rays in {dt:6.3f} s = {qps:>11,.0f} queries/s "
          f"({qps / th:>11,.0f} per thread), {hits / m:9.2f} results per ray", flush=True)
    return dict(points=n, case=name, threads=th, rays=m, seconds=round(dt, 4), queries_per_s=round(qps, 1),
                per_thread=round(qps / th, 1), results_per_ray=round(hits / m, 2), cpu=cpu)


def measure_with_driver(driver, n, threads, seconds, repeats, cpu):
    """One size measured by bench_figure5 on the CASES above (passed as NAME|K|RADIUS|ORDER)."""
    cmd = [driver, "--points", str(n), "--threads", ",".join(map(str, threads)), "--seconds", str(seconds),
           "--repeats", str(repeats)]
    for name, kw in CASES:
        cmd += ["--case", f"{name}|{kw.get('k', 0)}|{kw.get('radius', 'inf')}|{kw['order']}"]
    rows = []
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) as p:
        for line in p.stdout:
            f = line.rstrip("\n").split("\t")
            if f[0] != "row":
                print(line, end="", flush=True)
                continue
            rows.append(row_of(int(f[1]), f[2], int(f[3]), int(f[4]), float(f[5]), int(f[6]), cpu))
    if p.returncode:
        sys.exit(f"figure5: {driver} exited with {p.returncode}")
    return rows


def write_and_plot(rows, sizes, threads, cpu, csv_path, png):
    os.makedirs(os.path.dirname(csv_path) or ".", exist_ok=True)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, sizes, threads, cpu, png)
    print(f"wrote {csv_path} and {png}")


def plot(rows, sizes, threads, cpu, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [c[0] for c in CASES]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    width = 0.8 / len(sizes)
    for j, n in enumerate(sizes):
        y = [next(r["per_thread"] for r in rows if r["points"] == n and r["case"] == c and r["threads"] == 1)
             for c in names]
        axes[0].bar(np.arange(len(names)) + (j - (len(sizes) - 1) / 2) * width, y, width, label=f"{n:.0e} points")
    axes[0].set_yscale("log")
    axes[0].set_xticks(np.arange(len(names)), names, rotation=35, ha="right")
    axes[0].set_ylabel("ray queries per second, 1 thread")
    axes[0].set_title("Ray query modalities (uniform points, unit cube)")
    axes[0].legend()
    axes[0].grid(axis="y", which="both", alpha=0.3)
    if len(threads) > 1:
        for n in sizes:
            s = []
            for c in names:
                base = next(r["queries_per_s"] for r in rows if r["points"] == n and r["case"] == c and r["threads"] == threads[0])
                top = next(r["queries_per_s"] for r in rows if r["points"] == n and r["case"] == c and r["threads"] == threads[-1])
                s.append(top / base)
            axes[1].plot(names, s, marker="o", label=f"{n:.0e} points")
        axes[1].axhline(threads[-1] / threads[0], color="grey", linestyle="--", label="linear")
        axes[1].set_ylim(0, max(threads[-1] / threads[0] * 1.25, max(max(line.get_ydata()) for line in axes[1].lines) * 1.1))
        axes[1].set_ylabel(f"speed-up {threads[0]} -> {threads[-1]} threads")
        axes[1].set_title("Thread scaling")
        axes[1].tick_params(axis="x", rotation=35)
        for t in axes[1].get_xticklabels():
            t.set_ha("right")
        axes[1].legend()
        axes[1].grid(alpha=0.3)
    fig.suptitle(f"rayscan, Figure 5 of Teuscher et al. reproduced ({cpu})", fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main()
