#!/bin/sh
# Issue 11 section 5: COPC rendered in place vs read whole, interleaved rounds, one process each.
#   bench/copc_render.sh BUILD_DIR FILE.copc.laz [rounds width height spp cache_mb]
set -eu
B=${1:?build dir}; F=${2:?copc file}; R=${3:-3}; W=${4:-64}; H=${5:-48}; S=${6:-1}; C=${7:-2048}
i=0
while [ "$i" -lt "$R" ]; do
  nice "$B/bench/bench_copc_render" inplace "$F" "$W" "$H" "$S" "$C"
  nice "$B/bench/bench_copc_render" whole "$F" "$W" "$H" "$S" "$C"
  i=$((i + 1))
done
