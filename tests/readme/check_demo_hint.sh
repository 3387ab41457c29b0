#!/usr/bin/env bash
# tools/demo.sh (the README's first command) builds the program alone (BUILD_TARGETS=rayscan) and
# ends with the shell set-up of the README's Install section for its build folder: README.md's own
# `export PATH=$PWD/build/tools:...` line with `$PWD/build` replaced by the build folder's absolute
# path, for the default folder, a relative one and an absolute one. demo.sh runs in a copy of
# tools/ whose build.sh is a stand-in (it records its targets and writes a `rayscan` that does
# nothing), so nothing is installed, configured, built or rendered.
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
readme_line=$(grep -m1 '^export PATH=\$PWD/build/tools:' "$root/README.md")
[ -n "$readme_line" ] || { echo "README.md has no 'export PATH=\$PWD/build/tools:' line"; exit 1; }
fake="$tmp/repo"
mkdir -p "$fake/tools"
cp "$root/tools/demo.sh" "$root/tools/script_args.sh" "$fake/tools/"
cat >"$fake/tools/build.sh" <<'EOF'
#!/usr/bin/env bash
set -eu
cd "$(dirname "$0")/.."
mkdir -p "$1/tools"
echo "${BUILD_TARGETS:-}" >"$1.targets"
printf '#!/bin/sh\n' >"$1/tools/rayscan"
chmod +x "$1/tools/rayscan"
EOF
chmod +x "$fake/tools/build.sh"
fail=0
check() {  # check ABSOLUTE_BUILD_DIR [DEMO_ARG]
  local abs="$1"
  shift
  local out want got targets
  out=$(cd "$tmp" && "$fake/tools/demo.sh" "$@" 2>&1) || { echo "demo.sh $*: failed: $out"; fail=1; return; }
  want="${readme_line//\$PWD\/build/$abs}"
  got=$(printf '%s\n' "$out" | tail -n 1)
  if [ "$got" != "$want" ]; then
    printf 'demo.sh %s: last line\n  %s\nexpected (README.md)\n  %s\n' "$*" "$got" "$want"
    fail=1
    return
  fi
  # The line works from another folder: rayscan is the build folder's.
  got=$(cd / && eval "$got" && command -v rayscan)
  [ "$got" = "$abs/tools/rayscan" ] || { echo "demo.sh $*: rayscan on PATH is '$got', not $abs/tools/rayscan"; fail=1; }
  targets=$(cat "$abs.targets" 2>/dev/null)
  [ "$targets" = rayscan ] || { echo "demo.sh $*: built '$targets', expected the rayscan target alone"; fail=1; }
}
check "$fake/build"
check "$fake/out-dir" out-dir
check "$tmp/elsewhere/b" "$tmp/elsewhere/b"
[ "$fail" -eq 0 ] && echo "demo.sh: builds rayscan alone and prints README.md's environment line for its build folder"
exit "$fail"
