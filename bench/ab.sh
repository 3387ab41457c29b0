#!/usr/bin/env bash
# Interleaved A/B of two builds on the core benchmarks: bench_rays (1e6 uniform points, camera and
# random rays at THREADS threads, default 1,2; rayscan octree-adaptive against Embree) and
# bench_table1 (kNN and box queries against nanoflann and Boost R*), ROUNDS rounds with the order
# alternating (old first in odd rounds), so that both see the same machine state. Each program
# prints its own ratios to the peer; compare the old and new ratios of the same round
# (bench/ab_summary.py LOG). Needs the two builds' bench/ programs.
# Usage: [THREADS=1,2,16] bench/ab.sh OLD_BUILD NEW_BUILD [ROUNDS (default 2)] > log.txt
set -euo pipefail
OLD="$1"; NEW="$2"; ROUNDS="${3:-2}"; THREADS="${THREADS:-1,2}"
echo "# bench/ab.sh $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) CPUs: $(lscpu | sed -n 's/^Model name: *//p')"
echo "# old: $OLD  new: $NEW  load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq 1 "$ROUNDS"); do
  order="old new"; [ $((r % 2)) = 0 ] && order="new old"
  for side in $order; do
    b="$OLD"; [ "$side" = new ] && b="$NEW"
    echo; echo "## round $r $side: bench_rays"
    "$b/bench/bench_rays" --points-list 1000000 --indexes octree-adaptive --threads "$THREADS" --reps 5 --no-memory --no-build
    echo; echo "## round $r $side: bench_table1"
    "$b/bench/bench_table1" --no-insert --reps 5
  done
done
echo "# load after: $(cut -d' ' -f1-3 /proc/loadavg)"
