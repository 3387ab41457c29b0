#!/usr/bin/env bash
# Runs GRASS GIS r.sun in its daily mode (mode 2: no time=) for the solar irradiation fidelity test
# (tests/analysis/test_solar_rsun.cpp) and prints one line per day and surface:
#
#   RSUN day surface beam diff refl glob
#
# surface is "flat" (slope 0) or "tilted" (SLOPE degrees facing COMPASS_ASPECT); beam, diff, refl
# and glob are r.sun's daily irradiation, Wh/m^2/day (beam_rad, diff_rad, refl_rad, glob_rad).
#
# Usage: rsun_daily.sh LAT LON DAYS LINKE ALBEDO SLOPE COMPASS_ASPECT STEP [ELEVATION]
#   e.g. rsun_daily.sh 46.5 7.5 "15 80 172 266 355" 3 0.2 30 180 0.25
#        rsun_daily.sh 46.5 7.5 all 3 0.2 30 180 0.25      # every day 1..365 (the yearly sum)
# DAYS: day numbers of the year (1..365), or "all". STEP: r.sun's step, decimal hours. ELEVATION:
# metres (default 0). One r.sun call per day computes a one-row raster of two cells (flat,
# tilted) at latitude LAT in a temporary EPSG:4326 location (so r.sun takes the latitude from the
# region); -p: no terrain shadowing; r.sun's own sun geometry (its declination of the day number)
# and its integration over local solar time from sunrise to sunset. The days run as parallel
# r.sun processes (RSUN_JOBS, default the number of cores) inside ONE grass session, and their
# maps are read back with r.what in chunks: the 365 days take 35-40 s on 2 shared cores,
# nearly all of it the start-up of the r.sun processes.
# Needs `grass` (Debian package grass-core). Exit status non-zero on any failure.
set -euo pipefail

if [[ "${1:-}" != "--inner" ]]; then
  if [[ $# -ne 8 && $# -ne 9 ]]; then
    echo "usage: $0 LAT LON DAYS LINKE ALBEDO SLOPE COMPASS_ASPECT STEP [ELEVATION]" >&2
    exit 2
  fi
  exec grass --tmp-location EPSG:4326 --exec bash "$0" --inner "$@"
fi
shift
lat=$1 lon=$2 days=$3 linke=$4 albedo=$5 slope=$6 compass=$7 step=$8 elevation=${9:-0}
[[ $days == all ]] && days=$(seq 1 365)
read -r -a day_list <<<"${days//$'\n'/ }"

# r.sun's aspect input is counterclockwise from east (E 0, N 90, W 180, S 270) and reads 0 as
# "undefined": compass -> (450 - compass) mod 360, with 0 written as 360.
grass_aspect=$(awk -v c="$compass" 'BEGIN { a = (450 - c) % 360; if (a <= 0) a += 360; print a }')

# Two cells at latitude LAT, longitude LON: flat (slope 0) and tilted.
res=0.001
read -r north south west east x_flat x_tilt y <<<"$(awk -v la="$lat" -v lo="$lon" -v r="$res" 'BEGIN {
  printf "%.6f %.6f %.6f %.6f %.6f %.6f %.6f", la + r / 2, la - r / 2, lo, lo + 2 * r, lo + r / 2, lo + 1.5 * r, la }')"
import_row() {  # name values...
  local name=$1; shift
  { echo "north: $north"; echo "south: $south"; echo "east: $east"; echo "west: $west"
    echo "rows: 1"; echo "cols: 2"; echo "$*"; } |
    r.in.ascii --quiet --overwrite input=- output="$name" type=FCELL
}
g.region --quiet n="$north" s="$south" e="$east" w="$west" rows=1 cols=2
import_row z "$elevation" "$elevation"
import_row sl 0 "$slope"
import_row asp 270 "$grass_aspect"

# One r.sun per day, RSUN_JOBS at a time (each writes its own maps b_D, d_D, r_D, g_D).
jobs=${RSUN_JOBS:-$(nproc 2>/dev/null || echo 2)}
printf '%s\n' "${day_list[@]}" | xargs -P "$jobs" -I{} \
  r.sun -p --quiet --overwrite elevation=z slope=sl aspect=asp linke_value="$linke" \
  albedo_value="$albedo" day={} step="$step" beam_rad=b_{} diff_rad=d_{} refl_rad=r_{} glob_rad=g_{}

# Read back: r.what prints "x|y||v1|v2|..." per coordinate; at most 50 maps per call (open files).
declare -A value
for comp in b d r g; do
  for ((i = 0; i < ${#day_list[@]}; i += 50)); do
    chunk=("${day_list[@]:i:50}")
    maps=$(printf "${comp}_%s," "${chunk[@]}")
    lines=$(r.what --quiet map="${maps%,}" coordinates="$x_flat,$y,$x_tilt,$y" separator=pipe null_value='*')
    surf=0
    while IFS='|' read -r -a f; do
      # f: x y label v1 v2 ...
      for ((k = 0; k < ${#chunk[@]}; k++)); do value[$comp,$surf,${chunk[k]}]=${f[k + 3]}; done
      surf=$((surf + 1))
    done <<<"$lines"
    [[ $surf -eq 2 ]] || { echo "r.what gave $surf lines, expected 2: $lines" >&2; exit 1; }
  done
done

for day in "${day_list[@]}"; do
  for surf in 0 1; do
    name=flat; [[ $surf == 1 ]] && name=tilted
    echo "RSUN $day $name ${value[b,$surf,$day]} ${value[d,$surf,$day]} ${value[r,$surf,$day]} ${value[g,$surf,$day]}"
  done
done
