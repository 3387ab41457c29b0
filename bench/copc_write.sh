#!/usr/bin/env bash
# COPC writer: throughput (points/s, wall) and output size against plain LAZ of the same records
# and the .rsi index build, on a generated site (bench/make_site: autzen tiled and densified,
# LAS 1.2 PDRF 3) and the same points as LAS 1.4 PDRF 7 (bench/las_to_pdrf7.py; each copy of
# the source with its own GPS times), and on the bundled real scans. Then copc.js
# (npm copc, with laz-perf) reads the COPC output: node count, points per level.
# Usage: bench/copc_write.sh [BUILD_DIR (default build)] [N points (default 2e7)] [SCRATCH dir]
# The files go to a new folder inside SCRATCH (default /work/scratch), deleted at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
N="${2:-2e7}"
SCRATCH="${3:-/work/scratch}"
R="$BUILD/tools/rayscan"
CACHE="${RAYSCAN_NPM_CACHE:-$HOME/.cache/rayscan-npm-ci}"  # (tests/common/npm_tools.hpp installs it)
mkdir -p "$SCRATCH"
S=$(mktemp -d "$SCRATCH/copc-bench.XXXXXX")  # only this folder is deleted
trap 'rm -rf "$S"' EXIT
echo "CPU: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; N=$N"
"$BUILD/bench/make_site" "$S/site.las" "$N" >/dev/null
src_points=$("$R" info --json scenes/data/autzen_trim.las | /usr/bin/python3 -c 'import json, sys; print(json.load(sys.stdin)["count"])')
/usr/bin/python3 bench/las_to_pdrf7.py "$S/site.las" "$S/site7.las" "$src_points"
run() {  # label, command...: wall seconds, peak RSS, output size
  local label="$1" out="$2"
  shift 2
  /usr/bin/time -f "%e %M" -o "$S/time" "$@" >/dev/null 2>"$S/err" || { cat "$S/err"; return 1; }
  read -r secs kb <"$S/time"
  printf "%-34s %8.2f s %7.2f M points/s  peak %6.0f MiB  %12d bytes\n" "$label" "$secs" \
    "$(awk -v n="$N" -v s="$secs" 'BEGIN { print n / s / 1e6 }')" "$(awk -v k="$kb" 'BEGIN { print k / 1024 }')" "$(stat -c %s "$out")"
}
run "translate PDRF7 LAS -> LAZ"        "$S/site7.laz"      "$R" translate -q "$S/site7.las" "$S/site7.laz"
run "translate PDRF7 LAS -> COPC"       "$S/site7.copc.laz" "$R" translate -q "$S/site7.las" "$S/site7.copc.laz"
run "translate PDRF3 LAS -> LAZ"        "$S/site.laz"       "$R" translate -q "$S/site.las" "$S/site.laz"
run "translate PDRF3 LAS -> COPC (->7)" "$S/site.copc.laz"  "$R" translate -q "$S/site.las" "$S/site.copc.laz"
run "index PDRF3 LAS -> .rsi"           "$S/site.rsi"       "$R" index -q "$S/site.las" -o "$S/site.rsi"
run "index PDRF3 LAS -> .rsi (rgb)"     "$S/site_rgb.rsi"   "$R" index -q --attributes rgb "$S/site.las" -o "$S/site_rgb.rsi"
for f in ../shared/data/laz/lone-star.laz scenes/data/autzen_trim.las tests/data/las/autzen_trim_7.las; do
  [ -f "$f" ] || continue
  "$R" translate -q "$f" "$S/real.laz" >/dev/null
  "$R" translate -q "$f" "$S/real.copc.laz" >/dev/null 2>&1
  echo "real $(basename "$f"): LAZ $(stat -c %s "$S/real.laz") bytes, COPC $(stat -c %s "$S/real.copc.laz") bytes ($(python3 -c "print(round($(stat -c %s "$S/real.copc.laz") / $(stat -c %s "$S/real.laz"), 3))"))"
done
python3 -c "
import os
a, b = os.path.getsize('$S/site7.copc.laz'), os.path.getsize('$S/site7.laz')
print(f'COPC / LAZ (same PDRF 7 records): {a / b:.3f}')"
if command -v node >/dev/null && [ -d "$CACHE/node_modules/copc" ]; then
  echo "copc.js on site7.copc.laz:"
  node tests/site/copcjs_read.js "$CACHE/node_modules" "$S/site7.copc.laz"
fi
