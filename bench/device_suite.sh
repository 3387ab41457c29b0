#!/usr/bin/env bash
# Runs a bench/device_bundle.sh bundle on the machine it was carried to (the lent Intel Xeon), from
# the repository root, writing each part's output to $OUT (default ./device-out):
#   rays      bench_rays, 1e6 and 1e7 points, camera and random rays, 1/2/4/8/16 threads, Embree
#             single rays and packets interleaved (each NAME in the bundle, or those in $RAYS_NAMES)
#   table1    bench_table1 --no-insert (kNN vs nanoflann, box vs Boost R*)
#   perf      perf record -e cpu-clock of bench_rays --profile sphere and sphere4x4 (where perf runs)
#   figure5   bench/figure5.py (the machine's python3 with NumPy and matplotlib) measuring with
#             bench_figure5 (the last NAME's): 1e6, 1e7 and 1e8 points in memory, 1/2/4/8/16 threads
#   ab        bench/ab.sh of the bundle's first two NAMEs, AB_ROUNDS rounds at 1,2,16 threads
# Usage: bench/device_suite.sh BUNDLE.tar.xz PART[,PART...]
set -uo pipefail
bundle="$1"; parts=",$2,"
OUT="${OUT:-$PWD/device-out}"; mkdir -p "$OUT"
B=/tmp/rayscan-bundle
rm -rf "$B"; mkdir -p "$B"; xz -dc "$bundle" | tar -C "$B" -xf -
LD=("$B/lib/ld-linux-x86-64.so.2" --library-path "$B/lib")
names=($(ls "$B/bin" | grep -v '^perf$'))
for n in "${names[@]}"; do  # wrappers, so that bench/ab.sh and figure5.py can call them by path
  mkdir -p "$B/w/$n/bench"
  for p in "$B/bin/$n"/*; do
    printf '#!/bin/sh\nexec %s --library-path %s %s "$@"\n' "${LD[0]}" "$B/lib" "$p" > "$B/w/$n/bench/${p##*/}"
    chmod +x "$B/w/$n/bench/${p##*/}"
  done
done
{ date -u +%FT%TZ; lscpu | sed -n 's/^Model name: *//p'; nproc; cut -d' ' -f1-3 /proc/loadavg; uname -r; } > "$OUT/machine.txt"
cat "$OUT/machine.txt"
has() { [[ "$parts" == *",$1,"* ]]; }
T0=$SECONDS
stamp() { echo "== $1 at +$((SECONDS - T0)) s"; }

if has rays; then
  stamp rays
  for n in ${RAYS_NAMES:-${names[@]}}; do
    "$B/w/$n/bench/bench_rays" --points-list 1000000,10000000 --threads 1,2,4,8,16 --reps 3 \
      --build-reps 2 --no-memory --slow-rays 1000 > "$OUT/rays-$n.txt" 2>&1
    tail -3 "$OUT/rays-$n.txt"
  done
fi
if has table1; then
  stamp table1
  for n in "${names[@]}"; do "$B/w/$n/bench/bench_table1" --no-insert --reps 7 > "$OUT/table1-$n.txt" 2>&1; done
fi
if has perf && [ -x "$B/bin/perf" ]; then
  stamp perf
  n="${names[0]}"
  for q in sphere sphere4x4 embree; do  # (one file: the device tool returns at most 8)
    for np in 1000000 10000000; do
      echo "## perf: bench_rays --profile $q --profile-reps 10 --points-list $np" >> "$OUT/perf.txt"
      "${LD[@]}" "$B/bin/perf" record -q -e cpu-clock -F 1000 -o /tmp/perf.data -- "${LD[@]}" "$B/bin/$n/bench_rays" \
        --profile $q --profile-reps 10 --points-list $np --indexes octree-adaptive 2>&1 | grep '^profile' >> "$OUT/perf.txt"
      "${LD[@]}" "$B/bin/perf" report -i /tmp/perf.data --stdio --no-children --sort dso,symbol 2>/dev/null \
        | grep -v '^#' | grep -v '^$' | sed 's/  */ /g' | cut -c1-200 | head -30 >> "$OUT/perf.txt"
    done
  done
fi
if has figure5; then
  # figure5.py with the machine's own python3 (NumPy, matplotlib), measuring with bench_figure5
  stamp figure5
  python3 bench/figure5.py "$B" --driver "$B/w/${names[-1]}/bench/bench_figure5" --points 1e6,1e7,1e8 \
    --threads 1,2,4,8,16 --seconds 0.5 --repeats 2 --csv "$OUT/figure5.csv" --png "$OUT/figure5.png" > "$OUT/figure5.txt" 2>&1
  tail -4 "$OUT/figure5.txt"
fi
if has ab && [ "${#names[@]}" -ge 2 ]; then
  stamp ab
  THREADS=1,2,16 bash bench/ab.sh "$B/w/${names[0]}" "$B/w/${names[1]}" "${AB_ROUNDS:-3}" > "$OUT/ab.txt" 2>&1
fi
stamp done
