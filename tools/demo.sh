#!/usr/bin/env bash
# The main job on bundled real data: builds the rayscan program (installing the Debian packages the
# build needs when missing) and renders the Autzen scan (scenes/data/autzen_trim.las, 110,000
# coloured airborne LiDAR points) from scenes/autzen_overview.json to out/autzen_overview.png: the
# README's "Render a scene" recipe.
# Usage: tools/demo.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build "$@"
BUILD_TARGETS=rayscan ./tools/build.sh "$BUILD"
mkdir -p out
"$BUILD/tools/rayscan" render scenes/autzen_overview.json --out out/autzen_overview.png
echo "demo: the rendered site is $(pwd)/out/autzen_overview.png"
# The README's environment line (its Install section) for this build folder, absolute or not.
case "$BUILD" in /*) dir="$BUILD" ;; *) dir="$(pwd)/$BUILD" ;; esac
dir=$(printf %q "$dir")
again=./tools/build.sh
[ "$BUILD" = build ] || again+=" $(printf %q "$BUILD")"
echo "demo: for all of the README's recipes, build the rest ($again), install the programs they"
echo "demo: call besides rayscan (./tools/install-deps.sh) and set up the shell:"
echo "export PATH=$dir/tools:\$PATH PYTHONPATH=$dir/python LD_LIBRARY_PATH=$dir/sql"
