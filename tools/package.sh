#!/usr/bin/env bash
# Builds rayscan's Debian packages: the Release build (tools/build.sh), then `cpack -G DEB`, which
# installs each component under the prefix /usr and computes the shared-library dependencies with
# dpkg-shlibdeps (cmake/RayscanDeb.cmake: which package holds what). The packages land in
# BUILD_DIR/packages/ (rayscan, librayscan-dev, python3-rayscan, libsqlite3-mod-rayscan,
# postgresql-15-rayscan, qgis-plugin-rayscan); install them with
#   sudo apt-get install ./BUILD_DIR/packages/rayscan_*.deb ./BUILD_DIR/packages/python3-rayscan_*.deb ...
# tests/package/clean_root.sh installs them into a clean Debian 12 root and uses them there.
# Usage: tools/package.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
. tools/script_args.sh
script_args build "$@"
SKIP_BUILD="${PACKAGE_SKIP_BUILD:-0}"  # 1: package what BUILD_DIR holds (the test's own call)
[ "$SKIP_BUILD" = 1 ] || ./tools/build.sh "$BUILD"
rm -rf "$BUILD/packages"
(cd "$BUILD" && cpack -G DEB >cpack.log 2>&1) || { cat "$BUILD/cpack.log"; echo "package: cpack failed"; exit 1; }
rm -rf "$BUILD/packages/_CPack_Packages"
for deb in "$BUILD"/packages/*.deb; do
  printf '%-60s %8s KiB\n' "$(basename "$deb")" "$(( $(stat -c %s "$deb") / 1024 ))"
done
