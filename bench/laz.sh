#!/usr/bin/env bash
# LAZ decode throughput: rayscan (1 and 2 threads) interleaved with laz-perf (npm, WASM) under
# Node on the same files, ROUNDS rounds; then encode throughput/ratio (pointwise PDRF 3 and
# layered PDRF 8 against LASzip's size) and COPC time to first ray.
# Usage: bench/laz.sh [BUILD_DIR (default build)] [ROUNDS (default 3)]
# laz-perf is installed with npm into ${RAYSCAN_NPM_CACHE:-$HOME/.cache/rayscan-npm} (outside
# the repository); without npm/node the laz-perf rows are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
ROUNDS="${2:-3}"
DATA="../shared/data/laz"
CACHE="${RAYSCAN_NPM_CACHE:-$HOME/.cache/rayscan-npm}"
B="$BUILD/bench/bench_laz"
have_lp=0
if command -v node >/dev/null && { [ -d "$CACHE/node_modules/laz-perf" ] || (mkdir -p "$CACHE" && cd "$CACHE" && timeout 120 npm install --no-audit --no-fund laz-perf@0.0.7 >/dev/null 2>&1); }; then have_lp=1; fi
for f in las_with_several_extra_byte_bloc.laz lone-star.laz autzen_trim.laz; do
  [ -f "$DATA/$f" ] || continue
  echo "== $f"
  for r in $(seq "$ROUNDS"); do
    "$B" decode "$DATA/$f" --threads 1
    "$B" decode "$DATA/$f" --threads 2
    if [ "$have_lp" = 1 ]; then
      node tests/io/lazperf_decode.js "$CACHE/node_modules" "$DATA/$f" | awk '{printf "laz-perf decode points=%d wall_ms=%.1f cpu_ms=%.1f points_per_wall_s=%.0f points_per_cpu_s=%.0f\n", $1, $3, $4, $1/($3/1000), $1/($4/1000)}'
    fi
  done
done
tmp=$(mktemp -d)
for r in $(seq "$ROUNDS"); do
  "$B" encode ../shared/data/las/autzen_trim.las "$tmp/a.laz"  # PDRF 3: pointwise-chunked, v2 items
  # PDRF 8 + extra bytes: layered-chunked, v3 items; compare with LASzip's file of the same records
  le=../shared/data/las/derived/las_with_several_extra_byte_bloc.las
  if [ -f "$le" ]; then
    "$B" encode "$le" "$tmp/b.laz"
    echo "layered size: rayscan $(stat -c %s "$tmp/b.laz") bytes, LASzip $(stat -c %s "$DATA/las_with_several_extra_byte_bloc.laz") bytes"
  fi
done
rm -rf "$tmp"
[ -f "$DATA/lone-star.copc.laz" ] && for r in $(seq "$ROUNDS"); do "$B" copc "$DATA/lone-star.copc.laz"; done
