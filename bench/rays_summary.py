"""The ratios of a bench_rays log in one table per machine: for each cloud size, ray set and thread
count, the first sphere hit of rayscan octree-adaptive over Embree's rtcIntersect1 (median and
fastest rounds), rayscan's best coherent mode over Embree's best packet mode (camera rays), and
the thread scaling of both from the fewest to the most threads in the log.

    python3 bench/rays_summary.py bench/results/rays-xeon-2026-11-27.txt
"""
import re
import sys


def rate(s):
    """'3.36 M' / '597 k' -> rays per second."""
    v, unit = s.split()
    return float(v) * {"M": 1e6, "k": 1e3}.get(unit, 1.0)


def parse(path):
    rows = {}  # (points, rays, threads) -> dict
    points = rays = None
    threads = None
    section = None
    for line in open(path):
        if m := re.match(r"-- (\d+) points, (camera|random) ", line):
            points, rays = int(m.group(1)), m.group(2)
        elif m := re.match(r"(\d+) threads?, rays/s", line):
            threads, section = int(m.group(1)), "single"
        elif m := re.match(r"coherent rays, (\d+) threads?:", line):
            threads, section = int(m.group(1)), "coherent"
        elif line.startswith("|") and points and threads:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            r = rows.setdefault((points, rays, threads), {})
            if section == "single" and cells[0] == "rayscan octree-adaptive":
                r["rayscan"] = rate(cells[4])
                r["ratio"] = float(cells[5].rstrip("x"))
                r["fastest"] = float(cells[6].rstrip("x"))
            elif section == "single" and cells[0].startswith("Embree 3 first hit"):
                r["embree"] = rate(cells[4])
            elif section == "coherent" and len(cells) > 1 and re.match(r"[\d.]+ [Mk]", cells[1]):
                if cells[0].startswith("rayscan octree-adaptive"):
                    r["best_ours"] = max(r.get("best_ours", 0.0), rate(cells[1]))
                elif re.match(r"Embree rtcIntersect(4|8|16)", cells[0]):
                    r["best_embree"] = max(r.get("best_embree", 0.0), rate(cells[1]))
    return rows


def main():
    rows = parse(sys.argv[1])
    print("| points | rays | threads | rayscan / Embree rtcIntersect1, median (fastest) | rayscan best mode / Embree best packets |")
    print("|---:|---|---:|---:|---:|")
    for (points, rays, threads), r in sorted(rows.items()):
        packets = f"{r['best_ours'] / r['best_embree']:.2f}x" if r.get("best_embree") else "-"
        print(f"| {points:.0e} | {rays} | {threads} | {r['ratio']:.2f}x ({r['fastest']:.2f}x) | {packets} |")
    print()
    print("| points | rays | scaling | rayscan | Embree |")
    print("|---:|---|---|---:|---:|")
    for points, rays in sorted({(p, k) for p, k, _ in rows}):
        ts = sorted(t for p, k, t in rows if (p, k) == (points, rays))
        a, b = rows[(points, rays, ts[0])], rows[(points, rays, ts[-1])]
        print(f"| {points:.0e} | {rays} | {ts[0]} -> {ts[-1]} threads | {b['rayscan'] / a['rayscan']:.1f}x "
              f"| {b['embree'] / a['embree']:.1f}x |")


if __name__ == "__main__":
    main()
