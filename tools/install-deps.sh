#!/usr/bin/env bash
# Installs rayscan's build and test dependencies from Debian 12 packages when any is missing.
# Idempotent; needs root (or sudo) only when something must be installed.
set -euo pipefail
. "$(dirname "$0")/script_args.sh"
script_no_args "$@"
PKGS=(
  build-essential cmake ninja-build pkg-config
  libglm-dev libtbb-dev nlohmann-json3-dev libcli11-dev
  libopenimageio-dev openimageio-tools libopenexr-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libnanoflann-dev libboost-dev libembree-dev
  liblzf-dev libgdal-dev gdal-bin zlib1g-dev
  clang libclang-rt-14-dev
  fonts-dejavu-core
  help2man groff-base mmdebstrap file dpkg-dev
  cloudcompare xvfb xauth
  python3-dev pybind11-dev python3-numpy python3-pytest python3-matplotlib python3-open3d python3-astropy python3-dask python3-distributed
  grass-core
  qgis python3-gdal
  libsqlite3-dev sqlite3 libpq-dev postgresql-15 postgresql-server-dev-15 postgresql-15-pointcloud
  libopenmpi-dev openmpi-bin
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm run the suite's independent LAZ and COPC readers (tests/npm). A machine that has
# them from elsewhere (a NodeSource nodejs, whose npm is not Debian's package) keeps its own.
command -v node >/dev/null 2>&1 || missing+=(nodejs)
command -v npm >/dev/null 2>&1 || missing+=(npm)
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
