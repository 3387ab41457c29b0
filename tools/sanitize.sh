#!/usr/bin/env bash
# The sanitizer job: the whole test suite built with
# -fsanitize=address,undefined (RelWithDebInfo, benchmarks off) in its own build folder and run
# by CTest. RelWithDebInfo here means -O1 -g1 (optimised, line tables only) instead of CMake's
# -O2 -g: with both sanitizers GCC 12 compiles the heaviest translation unit (query_job.cpp) in
# 48 s CPU at -O1 -g1 against 103 s at -O2 -g (16 s for the plain -O3 build), which halves the
# from-scratch build CI pays; -O1 is the level the AddressSanitizer documentation recommends,
# and -g1 keeps file:line in every sanitizer stack trace. Measured from scratch (ccache recaching,
# 2026-11-22, 137 build steps): 2,301 s user + 91 s system CPU (so about 20 min of wall time on
# 2 idle cores); the suite then took 718 s on the shared machine at load 4-6 (the four
# forced-SIMD property runs are most of it). Again on 2026-11-25 (154 steps, no ccache): 1,062 s
# wall, 2,139 s of compile CPU (renderer/src/render.cpp alone 366 s); the suite 1,142 s, partly
# shared with other compiles (bench/notes/). With unity builds, instances compiled once and
# OpenImageIO loaded on first use, from scratch on the same machine: 85 steps, 678 s wall
# (1,337 s of steps on 2 cores), the suite 368 s: 17.5 min in all.
# With Clang 14 (and the 7 fuzz targets, rayscan_io with coverage), from scratch: 106
# steps, 371 s wall (765 s of steps), the suite 392 s: 12.8 min in all; the fuzz job that follows
# in CI then compiles nothing (354 -> 187 s).
# Any sanitizer report fails the test that triggered it (UBSan halts on the first error; ASan
# always does), and a failing test fails the job (and CI). LeakSanitizer is off: GDAL/PROJ and
# OpenImageIO keep process-lifetime caches that it would report. ccache is used when installed.
# Usage: tools/sanitize.sh [BUILD_DIR]   (default: build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build-asan}"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# Clang (Debian's clang 14, installed for the fuzz job) unless SANITIZE_CXX names another compiler:
# it compiles the sanitized build in 0.6x GCC 12's CPU time (the per-ISA query instances 4-5x
# faster), a second compiler checks the code that the release build compiles with GCC, and the
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
# their plain run, which takes that path by default: left out here (149 s of the sanitized suite
# on an AVX-512 machine), run by the normal suite with the other three.
best=$(env -u RAYSCAN_SIMD "$BUILD/tools/rayscan" --version | sed -n 's/.*SIMD path \([a-z0-9]*\),.*/\1/p')
ctest --test-dir "$BUILD" --output-on-failure -j "$(nproc)" --timeout 900 -LE thirdparty -E "^simd_${best:-none}_properties\$"
