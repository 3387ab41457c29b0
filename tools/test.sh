#!/usr/bin/env bash
# Sets up (every Debian package the suite uses, tools/install-deps.sh; the build, tools/build.sh)
# and runs the whole test suite with CTest.
# Usage: tools/test.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build "$@"
./tools/install-deps.sh
./tools/build.sh "$BUILD"
ctest --test-dir "$BUILD" --output-on-failure -j "$(nproc)"
