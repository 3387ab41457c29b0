#!/usr/bin/env bash
# Installs rayscan's build and test dependencies from Debian 12 packages when any is missing: by
# default the whole set that tools/test.sh and CI need (besides the build's: QGIS, GRASS,
# CloudCompare, Open3D, a PostgreSQL 15 server, Clang, mmdebstrap, Node.js and npm, ...); with
# --build-only just what configuring and building rayscan needs (the program, its man pages, the
# Python module, the SQL extensions, the Debian packages; tools/build.sh and tools/demo.sh).
# Idempotent; needs root (or sudo) only when something must be installed.
# Usage: tools/install-deps.sh [--build-only]
set -euo pipefail
. "$(dirname "$0")/script_args.sh"
only_build=0
if [ "${1:-}" = --build-only ]; then
  only_build=1
  shift
fi
if [ $# -gt 0 ]; then
  case "$1" in -h | --help) script_options "$1" ;; esac
  echo "install-deps.sh: expected no argument or --build-only, got '$1' (see --help)" >&2
  exit 2
fi
# What configuring and building need (the suite is configured with the build: GoogleTest, zlib;
# OpenImageIO's CMake package refuses to load without its programs, openimageio-tools), with
# help2man for the man pages, DejaVu Sans for the text rayscan draws into images, NumPy for
# `import rayscan`, and dpkg-dev and file for tools/package.sh (cpack's dpkg-shlibdeps). Open MPI
# too: whether a build folder builds with MPI is settled when it is first configured, so one set
# up without it would stay so after the full set.
BUILD_PKGS=(
  build-essential cmake ninja-build pkg-config
  libglm-dev libtbb-dev nlohmann-json3-dev libcli11-dev
  libopenimageio-dev openimageio-tools libopenexr-dev liblzf-dev libgdal-dev zlib1g-dev libgtest-dev
  fonts-dejavu-core help2man
  python3-dev pybind11-dev python3-numpy
  libsqlite3-dev libpq-dev postgresql-server-dev-15
  libopenmpi-dev openmpi-bin
  dpkg-dev file
)
# The suite's oracles and peers (third-party readers and tools, benchmark peers, servers), and the
# sanitizer and fuzz jobs' Clang.
TEST_PKGS=(
  gdal-bin libgmock-dev libbenchmark-dev
  libnanoflann-dev libboost-dev libembree-dev
  clang libclang-rt-14-dev
  groff-base mmdebstrap
  cloudcompare xvfb xauth
  python3-pytest python3-matplotlib python3-open3d python3-astropy python3-dask python3-distributed
  grass-core
  qgis python3-gdal
  sqlite3 postgresql-15 postgresql-15-pointcloud
)
PKGS=("${BUILD_PKGS[@]}")
[ "$only_build" -eq 1 ] || PKGS+=("${TEST_PKGS[@]}")
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm run the suite's independent LAZ and COPC readers (tests/npm). A machine that has
# them from elsewhere (a NodeSource nodejs, whose npm is not Debian's package) keeps its own.
if [ "$only_build" -eq 0 ]; then
  command -v node >/dev/null 2>&1 || missing+=(nodejs)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null 2>&1 || {
    echo "install-deps: ${#missing[@]} packages missing (${missing[*]}): run as root, or install sudo" >&2
    exit 1
  }
  SUDO="sudo"
fi
echo "install-deps: installing ${missing[*]}"
# Through env: sudo resets the environment (Debian's env_reset), which would drop a plain prefix.
$SUDO apt-get update -qq
$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
