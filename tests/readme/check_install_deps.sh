#!/usr/bin/env bash
# tools/install-deps.sh on a machine where nothing is installed, with stand-ins for dpkg-query (every
# package missing), id, sudo (which resets the environment, as Debian's env_reset does) and apt-get
# (which records its arguments and DEBIAN_FRONTEND): apt-get gets DEBIAN_FRONTEND=noninteractive
# as root and through sudo; without root and without sudo the script says so in one line and runs
# nothing; --build-only asks for the build's packages alone (no QGIS, no Node.js), the default for
# those and the suite's. Nothing is installed.
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bin="$tmp/bin"
log="$tmp/apt.log"
mkdir -p "$bin"
for tool in dirname grep env; do ln -s "$(command -v "$tool")" "$bin/$tool"; done
printf '#!%s\nexit 1\n' "$BASH" >"$bin/dpkg-query"
printf '#!%s\n[ "$1" = -u ] && echo "$FAKE_UID"\n' "$BASH" >"$bin/id"
printf '#!%s\necho "DEBIAN_FRONTEND=${DEBIAN_FRONTEND:-} $*" >>"%s"\n' "$BASH" "$log" >"$bin/apt-get"
printf '#!%s\nexec env -i PATH="$PATH" "$@"\n' "$BASH" >"$tmp/sudo"
chmod +x "$bin"/* "$tmp/sudo"
fail=0
run() {  # run UID WITH_SUDO ARGS...: output in $out, exit status in $rc, apt-get calls in $log
  local uid="$1" with_sudo="$2"
  shift 2
  : >"$log"
  rm -f "$bin/sudo"
  [ "$with_sudo" = 0 ] || ln -s "$tmp/sudo" "$bin/sudo"
  out=$(cd "$tmp" && FAKE_UID="$uid" PATH="$bin" "$BASH" "$root/tools/install-deps.sh" "$@" 2>&1)
  rc=$?
}
installs() { grep ' install ' "$log"; }

run 1000 0
if [ "$rc" -ne 1 ] || [[ "$out" != *"run as root, or install sudo"* ]] || [ "$(printf '%s\n' "$out" | wc -l)" -ne 1 ] \
   || [ -s "$log" ]; then
  echo "no root, no sudo: exit $rc (expected 1, one line 'run as root, or install sudo', no apt-get): $out"
  fail=1
fi
for uid in 0 1000; do
  run "$uid" 1
  if [ "$rc" -ne 0 ] || [ "$(installs | grep -c '^DEBIAN_FRONTEND=noninteractive ')" -ne 1 ]; then
    echo "uid $uid with sudo: exit $rc; apt-get install without DEBIAN_FRONTEND=noninteractive: $out; $(cat "$log")"
    fail=1
  fi
done
run 0 1 --build-only
build=" $(installs) "
run 0 1
full=" $(installs) "
for p in cmake libgdal-dev pybind11-dev libsqlite3-dev; do
  [[ "$build" == *" $p "* && "$full" == *" $p "* ]] || { echo "$p missing from a set: --build-only:$build; full:$full"; fail=1; }
done
for p in qgis grass-core cloudcompare postgresql-15 nodejs; do
  [[ "$build" != *" $p "* && "$full" == *" $p "* ]] || { echo "$p: in --build-only or not in the full set: --build-only:$build; full:$full"; fail=1; }
done
for p in ${build#*install -y -qq --no-install-recommends}; do
  [[ "$full" == *" $p "* ]] || { echo "--build-only's $p is not in the full set"; fail=1; }
done
[ "$fail" -eq 0 ] && echo "install-deps: noninteractive apt-get as root and through sudo, one line without either, --build-only a subset"
exit "$fail"
