#!/usr/bin/env bash
# The main job on bundled real data: builds rayscan (installing Debian packages when missing) and
# renders the Autzen scan (scenes/data/autzen_trim.las, 110,000 coloured airborne LiDAR points)
# from scenes/autzen_overview.json to out/autzen_overview.png: the README's "Render a scene" recipe.
# Usage: tools/demo.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build "$@"
./tools/build.sh "$BUILD"
mkdir -p out
"$BUILD/tools/rayscan" render scenes/autzen_overview.json --out out/autzen_overview.png
echo "demo: the rendered site is $(pwd)/out/autzen_overview.png"
echo "demo: to run the README's recipes, put rayscan on PATH: export PATH=\$PWD/$BUILD/tools:\$PATH"
