#!/bin/bash
# bench/index_open.sh SCRATCH ROUNDS LABEL=BINARY:SCENE...: index-file benchmark "open an index file
# and start tracing". Runs each (rayscan binary, scene) pair once per round, interleaved, and
# prints per run: process wall time, and from the render's own timing lines the open time
# ("mapped index file ... in X s"), the auto-radius time and the time to the first traced tile
# after the job's start. Scenes are JSON whose "cloud" is an .rsi under SCRATCH (built by
# `rayscan index`, e.g. from build/bench/make_site). See bench/README.md.
set -u
scratch=$1; rounds=$2; shift 2
cd "$scratch" || exit 2
for r in $(seq 1 "$rounds"); do
  for pair in "$@"; do
    label=${pair%%=*}; rest=${pair#*=}; bin=${rest%%:*}; scene=${rest#*:}
    start=$(date +%s.%N)
    out=$("$bin" render "$scene" 2>&1 | tr '\r' '\n')
    wall=$(echo "$(date +%s.%N) - $start" | bc)
    open=$(echo "$out" | sed -n 's/.*mapped index file .* in \([0-9.]*\) s.*/\1/p')
    rad=$(echo "$out" | sed -n 's/.*radius auto: .*(\([0-9.]*\) s).*/\1/p')
    first=$(echo "$out" | sed -n 's/.*first tile traced \([0-9.]*\) s after.*/\1/p')
    printf '%s round %s load %s: wall %.2f s, open %s s, auto radius %s s, first tile %s s\n' \
      "$label" "$r" "$(cut -d' ' -f1 /proc/loadavg)" "$wall" "${open:--}" "${rad:--}" "${first:--}"
  done
done
