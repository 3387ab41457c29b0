#!/usr/bin/env bash
# Runs the benchmark programs of BUILD_DIR/bench that need no input file and prints their figures
# (see bench/README.md for what each measures and the figures of the reference machine).
#   bench/run.sh BUILD_DIR           full run (bench_rays at 1e6 and 1e7 points: several minutes)
#   bench/run.sh BUILD_DIR --quick   smaller sizes and fewer rounds (about a minute)
# Then bench_render, bench_io, bench_visibility and bench_sql with their default arguments.
set -euo pipefail
if [ $# -lt 1 ] || [ ! -d "$1" ]; then
  echo "usage: $0 BUILD_DIR [--quick]" >&2
  exit 2
fi
dir="$1/bench"
quick=0
[ "${2:-}" = "--quick" ] && quick=1
if [ ! -d "$dir" ]; then
  echo "run.sh: $dir does not exist (configure with -DRAYSCAN_BUILD_BENCH=ON and build)" >&2
  exit 2
fi

echo "# rayscan benchmarks, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) CPUs: $(lscpu | sed -n 's/^Model name: *//p')"
echo "# load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
ran=0
run() {
  local prog="$1"
  shift
  if [ -x "$dir/$prog" ]; then
    echo
    echo "## $prog $*"
    "$dir/$prog" "$@"
    ran=$((ran + 1))
  fi
}
if [ $quick -eq 1 ]; then
  run bench_table1 --reps 3
  run bench_rays --points-list 1000000 --reps 3 --build-reps 2
else
  run bench_table1
  run bench_rays
fi
# The programs that run on their defaults (bench_laz, bench_copc_render, bench_index_rays and
# bench_figure5 take files or cases: bench/laz.sh, copc_render.sh, index_open.sh, figure5.py).
for name in bench_render bench_io bench_visibility bench_sql; do
  run "$name"
done
# The Python module: Python batch vs C++ batch, NumPy brute force, Open3D kNN.
if [ -f "$1/python/rayscan/__init__.py" ] && [ -x "$dir/python_batch_peer" ]; then
  echo
  echo "## bench_python.py"
  if [ $quick -eq 1 ]; then
    /usr/bin/python3 "$(dirname "$0")/bench_python.py" "$1" --quick
  else
    /usr/bin/python3 "$(dirname "$0")/bench_python.py" "$1"
  fi
  ran=$((ran + 1))
fi
echo
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
if [ $ran -eq 0 ]; then
  echo "run.sh: no benchmark program found in $dir" >&2
  exit 1
fi
