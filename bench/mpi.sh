#!/usr/bin/env bash
# MPI benchmark: 1 rank x 2 threads vs 2 ranks x 1 thread (mpirun, shared memory only) on
# this 2-core machine, interleaved rounds, plus the plain process (no mpirun) as the reference.
# Usage: bench/mpi.sh BUILD_DIR WORK_DIR [ROUNDS] [SCENE] [extra render args...]
# Prints one line per run (wall seconds, the job's own pixel-loop seconds, MPI traffic) and
# byte-compares every image with the plain run's.
set -euo pipefail
BUILD=${1:?build dir}
WORK=${2:?work dir}
ROUNDS=${3:-3}
SCENE=${4:-$(cd "$(dirname "$0")/.." && pwd)/scenes/autzen_overview.json}
shift $(( $# < 4 ? $# : 4 ))  # the optional ones too, when given
EXTRA=("$@")
R="$BUILD/tools/rayscan"
mkdir -p "$WORK"
MPI=(mpirun --bind-to none --mca btl self,vader --mca btl_vader_single_copy_mechanism none)
[ "$(id -u)" -ne 0 ] || MPI+=(--allow-run-as-root)
run() {  # name, command...
  local name=$1; shift
  local out="$WORK/$name.png"
  local t0 t1 log
  t0=$(date +%s.%N)
  log=$("$@" --out "$out" "${EXTRA[@]}" 2>&1 >/dev/null)
  t1=$(date +%s.%N)
  local loop traffic
  loop=$(grep -oE '[0-9.]+ s, [0-9]+ threads, [0-9]+x[0-9]+ px' <<<"$log" | tail -1 | cut -d' ' -f1)
  traffic=$(grep -oE 'mpi: .*' <<<"$log" || true)
  printf '%-22s wall %7.2f s  pixel loop %7s s  %s\n' "$name" "$(echo "$t1 - $t0" | bc)" "$loop" "$traffic"
  if [ -f "$WORK/plain.png" ] && [ "$name" != plain ]; then
    cmp -s "$WORK/plain.png" "$out" && echo "  identical to plain" || echo "  DIFFERS from plain"
  fi
}
for i in $(seq 1 "$ROUNDS"); do
  echo "== round $i"
  run plain "$R" render "$SCENE" --threads 2
  run mpi_1rank_x_2threads "${MPI[@]}" -n 1 "$R" render "$SCENE" --threads 2
  run mpi_2ranks_x_1thread "${MPI[@]}" -n 2 "$R" render "$SCENE" --threads 1
done
