#!/usr/bin/env bash
# Installs the Debian packages the build needs when missing (tools/install-deps.sh --build-only),
# then configures and builds rayscan (Release): every target, or those named in the environment
# variable BUILD_TARGETS (e.g. BUILD_TARGETS=rayscan, the program alone).
# Usage: tools/build.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build "$@"
./tools/install-deps.sh --build-only
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
targets=()
[ -z "${BUILD_TARGETS:-}" ] || read -r -a targets <<<"--target $BUILD_TARGETS"
cmake --build "$BUILD" -j "$(nproc)" "${targets[@]}"
