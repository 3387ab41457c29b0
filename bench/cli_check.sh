#!/bin/sh
# cli_check.sh PROGRAM [ARGS...]: the command-line conventions of a benchmark program (CTest,
# bench/CMakeLists.txt): `PROGRAM --help` exits 0 and prints "Usage:"; an unknown option exits 2
# with one line on stderr that starts with the program's name and says "see --help". ARGS are
# put before the unknown option (a subcommand, say).
set -u
prog="$1"
shift
name=$(basename "$prog")
out=$("$prog" --help 2>&1)
rc=$?
[ "$rc" -eq 0 ] || { echo "$name --help: exit $rc, expected 0"; exit 1; }
case "$out" in *Usage:*) ;; *) echo "$name --help: no 'Usage:' in: $out"; exit 1 ;; esac
err=$("$prog" "$@" --no-such-option 2>&1 >/dev/null)
rc=$?
[ "$rc" -eq 2 ] || { echo "$name --no-such-option: exit $rc, expected 2"; exit 1; }
[ "$(printf '%s\n' "$err" | wc -l)" -eq 1 ] || { echo "$name --no-such-option: not one line: $err"; exit 1; }
case "$err" in "$name: "*"(see --help)") ;; *) echo "$name --no-such-option: unexpected message: $err"; exit 1 ;; esac
echo "$name: --help exit 0, a usage error exit 2 with: $err"
