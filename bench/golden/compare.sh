#!/usr/bin/env bash
# Compares two folders written by bench/golden/record.sh: every file byte for byte, and EXR
# images also pixel for pixel with OpenImageIO's `idiff -fail 0` (their headers carry no time, but
# a pixel check names the channel that differs). Exit 0 only when everything is identical.
# Usage: bench/golden/compare.sh OLD_DIR NEW_DIR
set -uo pipefail
A="$1"; B="$2"; bad=0; n=0
for f in "$A"/*; do
  b="$B/$(basename "$f")"; n=$((n + 1))
  if [ ! -f "$b" ]; then echo "missing: $(basename "$f")"; bad=1; continue; fi
  if ! cmp -s "$f" "$b"; then echo "differs: $(basename "$f")"; bad=1; fi
  case "$f" in *.exr) idiff -q -fail 0 "$f" "$b" >/dev/null 2>&1 || { echo "pixels differ: $(basename "$f")"; bad=1; } ;; esac
done
for b in "$B"/*; do [ -e "$A/$(basename "$b")" ] || { echo "extra: $(basename "$b")"; bad=1; }; done
[ $bad -eq 0 ] && echo "compare: all $n outputs identical"
exit $bad
