#!/usr/bin/env bash
# The sanitizer job (issue 8, requirement 3): the whole test suite built with
# -fsanitize=address,undefined (RelWithDebInfo, benchmarks off) in its own build folder and run
# by CTest. Any sanitizer report fails the test that triggered it (UBSan halts on the first
# error; ASan always does). LeakSanitizer is off: GDAL/PROJ and OpenImageIO keep process-lifetime
# caches that it would report. ccache is used when installed.
# Usage: tools/sanitize.sh [BUILD_DIR]   (default: build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build-asan}"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRAYSCAN_SANITIZE=ON \
  -DRAYSCAN_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
cmake --build "$BUILD" -j "$(nproc)"
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=0:hard_rss_limit_mb=4096"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export RAYSCAN_SANITIZED=1
# The third-party group runs CloudCompare/Open3D, which are not built here: the normal suite has it.
ctest --test-dir "$BUILD" --output-on-failure -j "$(nproc)" --timeout 900 -LE thirdparty
