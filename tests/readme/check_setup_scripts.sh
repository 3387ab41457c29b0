#!/usr/bin/env bash
# The setup scripts of the README's first lines and their siblings (tools/*.sh) take their
# arguments one way (tools/script_args.sh): --help prints the header (what the script does and,
# for those that take a build folder, its usage line) and exits 0; an unknown option or one
# argument too many exits 2 with one line naming the script, before anything is installed,
# configured or built (a typo never becomes a build folder). Run from any directory.
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
fail=0
check() {  # check NAME WANT_RC WANT_TEXT ARGS...: exit status, and WANT_TEXT in the output
  local name="$1" want="$2" text="$3"
  shift 3
  local out rc
  out=$("$root/tools/$name" "$@" 2>&1)
  rc=$?
  if [ "$rc" -ne "$want" ]; then
    echo "tools/$name $*: exit $rc, expected $want: $out"
    fail=1
  elif [[ "$out" != *"$text"* ]]; then
    echo "tools/$name $*: '$text' not in: $out"
    fail=1
  elif [ "$want" -ne 0 ] && [ "$(printf '%s\n' "$out" | wc -l)" -ne 1 ]; then
    echo "tools/$name $*: not one line: $out"
    fail=1
  fi
}
for s in build.sh test.sh demo.sh package.sh sanitize.sh; do
  check "$s" 0 "Usage: tools/$s [BUILD_DIR]" --help
  check "$s" 0 "Usage: tools/$s [BUILD_DIR]" -h
  check "$s" 2 "$s: unknown option '--bogus' (see --help)" --bogus
  check "$s" 2 "$s: one argument at most (the build folder), got 2 (see --help)" dir1 dir2
done
check install-deps.sh 0 "Installs rayscan's build and test dependencies" --help
check install-deps.sh 2 "install-deps.sh: expected no argument or --build-only, got 'build' (see --help)" build
check install-deps.sh 2 "install-deps.sh: expected no argument or --build-only, got '--bogus' (see --help)" --bogus
check install-deps.sh 0 "Usage: tools/install-deps.sh [--build-only]" --help
check install-deps.sh 2 "install-deps.sh: expected no argument or --build-only, got 'build' (see --help)" --build-only build
check install-deps.sh 2 "install-deps.sh: expected no argument or --build-only, got '--build-only' (see --help)" --build-only --build-only
check install-deps.sh 0 "Usage: tools/install-deps.sh [--build-only]" --build-only --help
# Nothing was created where the refused arguments would have gone.
for d in --bogus dir1 dir2; do
  if [ -e "$d" ] || [ -e "$root/$d" ]; then
    echo "a refused argument left '$d' behind"
    fail=1
  fi
done
[ "$fail" -eq 0 ] && echo "setup scripts: --help exit 0, refused arguments exit 2 with one line"
exit "$fail"
