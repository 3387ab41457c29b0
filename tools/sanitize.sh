#!/usr/bin/env bash
# The sanitizer job: the whole test suite built with -fsanitize=address,undefined (RelWithDebInfo,
# benchmarks off) in its own build folder and run by CTest. RelWithDebInfo here means -O1 -g1
# (optimised, line tables only) instead of CMake's -O2 -g: the level the AddressSanitizer
# documentation recommends, far faster to compile than -O2 -g with both sanitizers, and file:line
# in every sanitizer stack trace. Built with Clang unless the environment variable SANITIZE_CXX
# names another compiler; build and suite times: bench/notes/2026-11-28-sanitize-job.md.
# Any sanitizer report fails the test that triggered it (UBSan halts on the first error; ASan
# always does), and a failing test fails the job (and CI). LeakSanitizer is off: GDAL/PROJ and
# OpenImageIO keep process-lifetime caches that it would report. ccache is used when installed.
# Usage: tools/sanitize.sh [BUILD_DIR]   (default: build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build-asan "$@"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# Clang (Debian's clang 14, installed for the fuzz job) unless SANITIZE_CXX names another compiler:
# it compiles the sanitized build in less CPU time than GCC 12 (the per-ISA query instances most),
# a second compiler checks the code that the release build compiles with GCC, and the
# fuzz targets are built here with it (RAYSCAN_FUZZ: tests/fuzz/run.sh then compiles nothing).
cxx="${SANITIZE_CXX:-clang++}"
compiler=(-DCMAKE_CXX_COMPILER="$cxx")
case "$cxx" in *clang++*) compiler+=(-DCMAKE_C_COMPILER="${cxx/clang++/clang}" -DRAYSCAN_FUZZ=ON) ;;
                 *) compiler+=(-DRAYSCAN_FUZZ=OFF) ;; esac
# A build folder configured with another compiler is started afresh: CMake would drop its cache and
# re-run without the options below (and no object of the other compiler can be reused).
cached=$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' "$BUILD/CMakeCache.txt" 2>/dev/null || true)
want=$(command -v "$cxx" || echo "$cxx")
if [ -n "$cached" ] && [ "$(readlink -f "$(command -v "$cached" || echo "$cached")")" != "$(readlink -f "$want")" ]; then
  echo "sanitize: $BUILD was configured with $cached, not $want: starting it afresh"
  rm -rf "$BUILD"
fi
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRAYSCAN_SANITIZE=ON "${compiler[@]}" \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
  -DRAYSCAN_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
cmake --build "$BUILD" -j "$(nproc)"
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=0:hard_rss_limit_mb=4096"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export RAYSCAN_SANITIZED=1
# The third-party group runs CloudCompare/Open3D, which are not built here: the normal suite has it.
# The property suites' forced run of the CPU's own best SIMD path (simd_<path>_properties) repeats
# their plain run, which takes that path by default: left out here (a large share of the
# sanitized suite), run by the normal suite with the other three.
best=$(env -u RAYSCAN_SIMD "$BUILD/tools/rayscan" --version | sed -n 's/.*SIMD path \([a-z0-9]*\),.*/\1/p')
ctest --test-dir "$BUILD" --output-on-failure -j "$(nproc)" --timeout 900 -LE thirdparty -E "^simd_${best:-none}_properties\$"
