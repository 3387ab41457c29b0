#!/bin/sh
# `rayscan visibility` and `rayscan solar` on a COPC file queried in place vs the same points read
# whole (in-memory octree), interleaved rounds (whole, in place, whole, in place), one process
# each, wall time and peak RSS from /usr/bin/time -v, and whether the written LAS files are equal
# byte for byte. The whole-file runs read a plain LAZ copy of the file (`rayscan translate`: the
# same records in the same order, the same scale and offset), as the CLI has no switch to read a
# COPC file whole (the job option copc_in_place = false does it in code).
#   bench/copc_analyses.sh BUILD_DIR FILE.copc.laz OBSERVER_X,Y LAT LON [rounds] [AT]
# (lone-star: bench/copc_analyses.sh build tests/data/laz/lone-star.copc.laz 515384.8,4918360.7 44.4 -68.2)
set -eu
B=${1:?build dir}; F=${2:?copc file}; OBS=${3:?observer x,y}; LAT=${4:?latitude}; LON=${5:?longitude}
R=${6:-2}; AT=${7:-2026-06-21T16:00:00Z}
D=$(mktemp -d "${TMPDIR:-/tmp}/copc-analyses.XXXXXX")
trap 'rm -rf "$D"' EXIT
RS="$B/tools/rayscan"
date
lscpu | grep 'Model name'
nproc
uptime
"$RS" translate -q "$F" "$D/whole.laz"
run() {  # run NAME MODE ARGS...: one timed run, its log lines about time and COPC, wall and RSS
  name=$1; mode=$2; shift 2
  src=$F
  [ "$mode" = whole ] && src=$D/whole.laz
  /usr/bin/time -v "$RS" "$@" "$src" -o "$D/$name-$mode.las" >"$D/out.txt" 2>"$D/err.txt"
  wall=$(grep 'Elapsed (wall clock)' "$D/err.txt" | awk '{ print $NF }')
  rss=$(grep 'Maximum resident set size' "$D/err.txt" | awk '{ printf "%.1f", $NF / 1024 }')
  echo "== $name $mode: wall $wall  peak RSS ${rss} MB"
  grep -E 'rayscan (visibility|solar): (read|mapped|built|radius|surfels|steep|COPC|line of sight|shadows|traced|sun)' "$D/err.txt" | sed 's/^/   /' || true
}
i=0
while [ "$i" -lt "$R" ]; do
  for mode in whole inplace; do
    run vis-sphere "$mode" visibility --observer "$OBS" --height 1.7 --primitive sphere
    run vis-surfel "$mode" visibility --observer "$OBS" --height 1.7
    run solar-at "$mode" solar --at "$AT" --lat "$LAT" --lon "$LON"
  done
  for name in vis-sphere vis-surfel solar-at; do
    if cmp -s "$D/$name-whole.las" "$D/$name-inplace.las"; then
      echo "== $name round $i: written LAS files identical ($(stat -c %s "$D/$name-inplace.las") bytes)"
    else
      echo "== $name round $i: written LAS files DIFFER"
    fi
  done
  i=$((i + 1))
done
# A cache far smaller than the decoded file (about 23 MB): the chunks' ends evict, nodes are
# decoded again; the fields must not change.
for name in vis-sphere vis-surfel; do
  [ "$name" = vis-sphere ] && prim=sphere || prim=surfel
  run "$name" inplace-4M visibility --observer "$OBS" --height 1.7 --primitive "$prim" --cache 4M
  if cmp -s "$D/$name-whole.las" "$D/$name-inplace-4M.las"; then
    echo "== $name --cache 4M: written LAS file identical to the whole-file run's"
  else
    echo "== $name --cache 4M: written LAS file DIFFERS"
  fi
done
date
