#!/usr/bin/env python3
"""Summarises a bench/ab.sh log: per round and side, rayscan octree-adaptive's first-hit ratio to
Embree rtcIntersect1 (median and fastest rounds; camera and random rays, at each thread count) and
Table 1's ratios of the octree (adaptive) to the fastest peer (box, kNN); then old/new per row.
Usage: bench/ab_summary.py LOG"""
import re, sys
rows = {}  # (round, side) -> {name: ratio}
key = None; rays = None; threads = None
for line in open(sys.argv[1]):
    m = re.match(r"## round (\d+) (old|new): (\w+)", line)
    if m:
        key = (int(m.group(1)), m.group(2)); rows.setdefault(key, {}); continue
    m = re.match(r"-- \d+ points, (camera|random)", line)
    if m: rays = m.group(1); continue
    m = re.match(r"(\d+) threads?, rays/s", line)
    if m: threads = m.group(1); continue
    if line.startswith("| rayscan octree-adaptive |") and rays:
        c = [x.strip() for x in line.strip().strip("|").split("|")]
        if len(c) >= 7:
            rows[key][f"{rays} {threads}t median"] = float(c[5].rstrip("x"))
            rows[key][f"{rays} {threads}t fastest"] = float(c[6].rstrip("x"))
    if line.startswith("| rayscan octree adaptive |"):
        c = [x.strip() for x in line.strip().strip("|").split("|")]
        rows[key]["table1 box"] = float(re.search(r"\(([\d.]+)x\)", c[3]).group(1))
        rows[key]["table1 kNN"] = float(re.search(r"\(([\d.]+)x\)", c[4]).group(1))
names = sorted({n for r in rows.values() for n in r})
rounds = sorted({k[0] for k in rows})
print("| row | " + " | ".join(f"round {r} old / new (new/old)" for r in rounds) + " |")
print("|---|" + "---|" * len(rounds))
for n in names:
    cells = []
    for r in rounds:
        o, w = rows.get((r, "old"), {}).get(n), rows.get((r, "new"), {}).get(n)
        cells.append(f"{o:.2f} / {w:.2f} ({w / o:.3f})" if o and w else "-")
    print(f"| {n} | " + " | ".join(cells) + " |")
