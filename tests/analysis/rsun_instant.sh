#!/usr/bin/env bash
# Runs GRASS GIS r.sun in its instantaneous mode (mode 1) for the clear-sky tests
# (tests/analysis/test_clear_sky.cpp) and prints one line per case:
#
#   RSUN day time linke z slope compass_aspect incid beam diff refl glob sun_azimuth
#
# incid is r.sun's incidout (degrees: the sun's elevation above the surface plane; for a flat
# cell it is the sun elevation itself; '*' when the sun is behind the plane), beam/diff/refl/glob
# are W/m^2, sun_azimuth (degrees, compass) is read from the map history r.sun writes.
#
# Usage: rsun_instant.sh LAT "DAYS" "TIMES" "LINKES" "ELEVATIONS" ALBEDO SLOPE COMPASS_ASPECT
#   e.g. rsun_instant.sh 45 "15 172 355" "8 10 12 15" "2 3.5 6" "0 1500" 0.2 30 180
# Each call of r.sun computes a one-row raster (so every cell has the same latitude) whose
# columns are the cases {flat, tilted} x LINKES x ELEVATIONS; -p: no terrain shadowing.
# Local (solar) time, day of year, r.sun's own sun geometry: nothing here depends on a time zone.
# Needs `grass` (Debian package grass-core); runs in a temporary EPSG:4326 location (--tmp-location)
# so that r.sun takes the latitude from the region. Exit status non-zero on any failure.
set -euo pipefail

if [[ "${1:-}" != "--inner" ]]; then
  if [[ $# -ne 8 ]]; then
    echo "usage: $0 LAT DAYS TIMES LINKES ELEVATIONS ALBEDO SLOPE COMPASS_ASPECT" >&2
    exit 2
  fi
  exec grass --tmp-location EPSG:4326 --exec bash "$0" --inner "$@"
fi
shift
lat=$1 days=$2 times=$3 linkes=$4 elevations=$5 albedo=$6 slope=$7 compass=$8

# r.sun's aspect input is counterclockwise from east (E 0, N 90, W 180, S 270) and reads 0 as
# "undefined": compass -> (450 - compass) mod 360, with 0 written as 360.
grass_aspect=$(awk -v c="$compass" 'BEGIN { a = (450 - c) % 360; if (a <= 0) a += 360; print a }')

# Columns: flat cells first, then tilted, each over LINKES x ELEVATIONS.
col_slope=() col_aspect=() col_linke=() col_z=()
for surf in flat tilted; do
  for lk in $linkes; do
    for z in $elevations; do
      if [[ $surf == flat ]]; then col_slope+=(0); col_aspect+=(270); else col_slope+=("$slope"); col_aspect+=("$grass_aspect"); fi
      col_linke+=("$lk"); col_z+=("$z")
    done
  done
done
ncols=${#col_z[@]}
res=0.001
north=$(awk -v l="$lat" -v r="$res" 'BEGIN { printf "%.6f", l + r / 2 }')
south=$(awk -v l="$lat" -v r="$res" 'BEGIN { printf "%.6f", l - r / 2 }')
east=$(awk -v n="$ncols" -v r="$res" 'BEGIN { printf "%.6f", n * r }')

import_row() {  # name values...
  local name=$1; shift
  { echo "north: $north"; echo "south: $south"; echo "east: $east"; echo "west: 0"
    echo "rows: 1"; echo "cols: $ncols"; echo "$*"; } |
    r.in.ascii --quiet --overwrite input=- output="$name" type=FCELL
}
g.region --quiet n="$north" s="$south" e="$east" w=0 rows=1 cols="$ncols"
import_row z "${col_z[@]}"
import_row sl "${col_slope[@]}"
import_row asp "${col_aspect[@]}"
import_row lk "${col_linke[@]}"

values() { r.out.ascii -h --quiet input="$1" precision=9 null_value='*' | tr -s ' \n' ' '; }

for day in $days; do
  for t in $times; do
    r.sun -p --quiet --overwrite elevation=z slope=sl aspect=asp linke=lk albedo_value="$albedo" \
      day="$day" time="$t" incidout=inc beam_rad=beam diff_rad=diff refl_rad=refl glob_rad=glob
    azimuth=$(r.info -h map=inc | sed -n 's/.*Solar azimuth (deg): *\([-0-9.]*\).*/\1/p' | head -1)
    [[ -n $azimuth ]] || { echo "no solar azimuth in r.sun's history" >&2; exit 1; }
    read -r -a inc <<<"$(values inc)"
    read -r -a beam <<<"$(values beam)"
    read -r -a diff <<<"$(values diff)"
    read -r -a refl <<<"$(values refl)"
    read -r -a glob <<<"$(values glob)"
    for ((i = 0; i < ncols; i++)); do
      # Report the compass aspect the test used (flat cells: 180, any value does).
      c=$compass; [[ ${col_slope[i]} == 0 ]] && c=180
      echo "RSUN $day $t ${col_linke[i]} ${col_z[i]} ${col_slope[i]} $c ${inc[i]} ${beam[i]} ${diff[i]} ${refl[i]} ${glob[i]} $azimuth"
    done
  done
done
