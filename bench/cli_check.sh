#!/bin/sh
# cli_check.sh PROGRAM BAD_ARGS...: the command-line conventions of a benchmark program (CTest,
# bench/CMakeLists.txt): `PROGRAM --help` exits 0 and prints "Usage:"; an unknown option, and the
# invocation BAD_ARGS (a value that is not a number or out of its range), each exit 2 with one
# line on stderr that starts with the program's name, before any work.
set -u
prog="$1"
shift
name=$(basename "$prog")
out=$("$prog" --help 2>&1)
rc=$?
[ "$rc" -eq 0 ] || { echo "$name --help: exit $rc, expected 0"; exit 1; }
case "$out" in *Usage:*) ;; *) echo "$name --help: no 'Usage:' in: $out"; exit 1 ;; esac
refused() {  # refused ARGS...: exit 2, one line naming the program
  err=$("$prog" "$@" 2>&1 >/dev/null)
  rc=$?
  [ "$rc" -eq 2 ] || { echo "$name $*: exit $rc, expected 2"; exit 1; }
  [ "$(printf '%s\n' "$err" | wc -l)" -eq 1 ] || { echo "$name $*: not one line: $err"; exit 1; }
  case "$err" in "$name: "*) ;; *) echo "$name $*: the line does not start with '$name: ': $err"; exit 1 ;; esac
  echo "$name $*: exit 2: $err"
}
refused --no-such-option
[ $# -eq 0 ] || refused "$@"
