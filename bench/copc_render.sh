#!/bin/sh
# COPC rendered in place vs read whole, interleaved rounds, one process each.
#   bench/copc_render.sh BUILD_DIR FILE.copc.laz [rounds width height spp cache_mb]
#   bench/copc_render.sh BUILD_DIR site:N [rounds width height spp cache_mb]
# "site:N" (e.g. site:2e7) generates the file first: BUILD_DIR/bench/make_site writes an N-point
# LAS site, `rayscan translate` turns it into a COPC file, both under $COPC_SCRATCH (default
# BUILD_DIR/copc-bench-data), deleted at the end. Needs ~50 bytes per point of free disk.
set -eu
B=${1:?build dir}; F=${2:?copc file or site:N}; R=${3:-3}; W=${4:-64}; H=${5:-48}; S=${6:-1}; C=${7:-2048}
case "$F" in
  site:*)
    N=${F#site:}
    D=${COPC_SCRATCH:-$B/copc-bench-data}
    mkdir -p "$D"
    need_kb=$(awk -v n="$N" 'BEGIN { printf "%d", n * 50 / 1024 }')
    free_kb=$(df -Pk "$D" | awk 'NR == 2 { print $4 }')
    if [ "$free_kb" -lt "$need_kb" ]; then
      echo "copc_render.sh: $D has $free_kb KB free, $need_kb KB needed for $N points" >&2
      exit 2
    fi
    trap 'rm -f "$D/site.las" "$D/site.copc.laz"' EXIT
    nice "$B/bench/make_site" "$D/site.las" "$N"
    nice "$B/tools/rayscan" translate -q "$D/site.las" "$D/site.copc.laz"
    rm -f "$D/site.las"
    F=$D/site.copc.laz
    ;;
esac
i=0
while [ "$i" -lt "$R" ]; do
  nice "$B/bench/bench_copc_render" inplace "$F" "$W" "$H" "$S" "$C"
  nice "$B/bench/bench_copc_render" whole "$F" "$W" "$H" "$S" "$C"
  i=$((i + 1))
done
