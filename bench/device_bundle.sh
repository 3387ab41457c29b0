#!/usr/bin/env bash
# Packs Release builds' benchmark programs with every shared library they load (and the dynamic
# loader itself) into one .tar.xz, so that they run unchanged on another x86-64 Linux machine that
# has none of Debian 12's packages (the lent Intel Xeon: `bench/device_suite.sh` unpacks and runs
# it with the bundled ld-linux and --library-path), and perf with its libraries.
# Usage: bench/device_bundle.sh OUT.tar.xz NAME=BUILD [NAME=BUILD ...]
#   each BUILD's bench_rays, bench_table1 and bench_figure5 go to bin/NAME/ (about 20 MB
#   compressed in all, perf included). Only programs that link the octree library alone: what
#   links GDAL (through the io library: bench_render, the rayscan program, the Python module)
#   brings about 45 MB more of GDAL's dependencies, past what the device tool carries beside the
#   repository (64 MiB in all).
set -euo pipefail
out="$1"; shift
stage="$(mktemp -d)"; trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/lib" "$stage/bin"
libs_of() { { ldd "$@" 2>/dev/null || true; } | awk '/=>/ && $3 ~ /^\// {print $3} /^\t\// {print $1}' | sort -u; }
elves=()
for pair in "$@"; do
  name="${pair%%=*}"; build="${pair#*=}"
  mkdir -p "$stage/bin/$name"
  for p in bench_rays bench_table1 bench_figure5; do
    cp "$build/bench/$p" "$stage/bin/$name/"; elves+=("$build/bench/$p")
  done
done
if [ -x /usr/bin/perf ]; then cp /usr/bin/perf "$stage/bin/perf"; elves+=(/usr/bin/perf); fi
libs_of "${elves[@]}" | while IFS= read -r l; do cp -L "$l" "$stage/lib/"; done
cp -L /lib64/ld-linux-x86-64.so.2 "$stage/lib/"
tar -C "$stage" -cf - . | xz -T2 -6 > "$out.tmp"
mv "$out.tmp" "$out"
echo "$out: $(du -h "$out" | cut -f1) ($(du -sh "$stage" | cut -f1) unpacked)"
