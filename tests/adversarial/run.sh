#!/usr/bin/env bash
# The adversarial corpus: hostile but realistic inputs and output paths for every
# command. Each case must exit with code 2, print exactly one line on stderr that names the
# offending file (or option) and the place (byte, line, field or option), never hang (each run
# has a 60 s timeout and a 2 GiB address-space limit, so unbounded reads fail the case), and
# leave every pre-existing output byte-identical.
# Usage: tests/adversarial/run.sh RAYSCAN_EXE   (run by CTest as "adversarial_corpus")
set -u
RAYSCAN="$1"
HERE="$(cd "$(dirname "$0")" && pwd)"
DATA="$HERE/../data"
W="$(mktemp -d)"
trap 'rm -rf "$W"' EXIT
fails=0
cases=0

# expect_error NAME WANT1 [WANT2] -- ARGS...: rayscan ARGS exits 2 with one stderr line holding
# WANT1 (and WANT2), nothing half-written, outputs under $W/old* unchanged.
expect_error() {
  local name="$1"; shift
  local wants=()
  while [ "$1" != "--" ]; do wants+=("$1"); shift; done
  shift
  cases=$((cases + 1))
  for f in "$W"/old*; do [ -f "$f" ] && printf 'OLD %s\n' "$f" > "$f"; done
  local err code
  err="$( ([ -n "${RAYSCAN_SANITIZED:-}" ] || ulimit -v 2097152; timeout 60 "$RAYSCAN" "$@") 2>&1 >/dev/null)"
  code=$?
  local ok=1 why=""
  [ "$code" -eq 2 ] || { ok=0; why="exit code $code, expected 2"; }
  local lines
  lines=$(printf '%s' "$err" | awk 'END{print NR}')
  [ "$lines" -eq 1 ] || { ok=0; why="$why; $lines stderr lines, expected 1"; }
  for w in "${wants[@]}"; do
    [[ "$err" == *"$w"* ]] || { ok=0; why="$why; message lacks '$w'"; }
  done
  [[ "$err" == "rayscan "* ]] || { ok=0; why="$why; message does not start with 'rayscan '"; }
  for f in "$W"/old*; do
    [ -f "$f" ] || continue
    [ "$(cat "$f")" = "OLD $f" ] || { ok=0; why="$why; $f was changed"; }
  done
  [ -z "$(find "$W" -name '.*.tmp.*' 2>/dev/null)" ] || { ok=0; why="$why; a temporary file was left"; }
  if [ "$ok" -eq 1 ]; then
    echo "ok   $name"
  else
    echo "FAIL $name: $why"
    echo "     stderr: $err"
    fails=$((fails + 1))
  fi
}

# ---- Fixtures: a tiny cloud, scene and camera; old outputs that must survive.
printf '0 0 0\n1 0 0\n0 1 0\n1 1 0.5\n' > "$W/c.xyz"
cat > "$W/cam.json" <<'J'
{"width": 8, "height": 6, "position": [0.5, -10, 2], "look_at": [0.5, 0.5, 0]}
J
cat > "$W/s.json" <<'J'
{"cloud": "c.xyz", "radius": 0.5, "spp": 1, "material": {"color": [0.5, 0.5, 0.5]},
 "camera": "cam.json"}
J
cat > "$W/tall.json" <<'J'
{"width": 1, "height": 65536, "position": [0.5, -10, 2], "look_at": [0.5, 0.5, 0]}
J
sed 's/"radius": 0.5/"radius": 1e400/' "$W/s.json" > "$W/s_huge_radius.json"
touch "$W/old.png" "$W/old.las"
mkfifo "$W/fifo.pcd" "$W/fifo.png" "$W/fifo.json" "$W/fifo.epw"
mkdir "$W/dir.json" "$W/dir.epw" "$W/colmap"
mkfifo "$W/colmap/images.txt" "$W/colmap/cameras.txt"
ln -s /dev/zero "$W/observers.csv"
ln -s /dev/zero "$W/rays.csv"
ln -s "$W/old.png" "$W/link.png"
mkdir "$W/old.aovs.exr"
printf 'ox,oy,oz,dx,dy,dz\n0,0,5,0,0,-1\n' > "$W/rays_ok.csv"
NL="$W/new
line.xyz"
printf '0 0 0\n' > "$NL"

# ---- Special files as inputs (never read, never block).
expect_error camera-dev-zero "/dev/zero" "character device" -- render -q "$W/s.json" --camera /dev/zero --out "$W/old.png"
expect_error scene-dev-zero "/dev/zero" "character device" -- render -q /dev/zero --out "$W/old.png"
expect_error scene-fifo "fifo.json" "FIFO" -- render -q "$W/fifo.json" --out "$W/old.png"
expect_error visibility-camera-dev-zero "/dev/zero" "character device" -- visibility -q "$W/c.xyz" --from-camera /dev/zero -o "$W/old.las"
expect_error observers-symlink-dev-zero "observers.csv" "character device" -- visibility -q "$W/c.xyz" --observers "$W/observers.csv" -o "$W/old.las"
expect_error rays-symlink-dev-zero "rays.csv" "character device" -- query --cloud "$W/c.xyz" --rays "$W/rays.csv" --radius 1 --out "$W/old.csv"
expect_error info-fifo "fifo.pcd" "FIFO" -- info "$W/fifo.pcd"
expect_error compare-dev-zero "/dev/zero" "character device" -- compare /dev/zero "$W/old.png"
expect_error frames-fifo "fifo.json" "is a FIFO" -- render -q "$W/s.json" --frames "$W/fifo.json" --out "$W/old.png"
expect_error frames-directory "dir.json" "is a directory" -- render -q "$W/s.json" --frames "$W/dir.json" --out "$W/old.png"
expect_error colmap-fifo "colmap/images.txt" "is a FIFO" -- render -q "$W/s.json" --colmap "$W/colmap" --image a.png --out "$W/old.png"
SOLAR=(solar -q "$W/c.xyz" --lat 44 --lon -123 --start 2026-06-01 --end 2026-06-02 -o "$W/old.las")
expect_error weather-fifo "fifo.epw" "is a FIFO" -- "${SOLAR[@]}" --weather "$W/fifo.epw"
expect_error weather-directory "dir.epw" "is a directory" -- "${SOLAR[@]}" --weather "$W/dir.epw"
# ---- Huge counts and lying sizes.
# A 130-byte PLY reproducer (2^40 face items without properties before its one vertex; walking
# them took about an hour): valid, so info reads exactly that vertex. The 60 s timeout of every
# case only tells a hang from a wrong answer.
cases=$((cases + 1))
out="$( ([ -n "${RAYSCAN_SANITIZED:-}" ] || ulimit -v 2097152; timeout 60 "$RAYSCAN" info "$HERE/huge_count_no_properties.ply") 2>&1)"
code=$?
if [ "$code" -eq 124 ]; then
  echo "FAIL ply-2e40-items-no-properties: hung (killed after 60 s)"; fails=$((fails + 1))
elif [ "$code" -eq 0 ] && grep -Eqx 'points: +1' <<<"$out" && grep -Eqx 'bounds min: +1 2 3' <<<"$out" &&
     grep -Eqx 'bounds max: +1 2 3' <<<"$out"; then
  echo "ok   ply-2e40-items-no-properties (its one vertex, 1 2 3)"
else
  echo "FAIL ply-2e40-items-no-properties: exit code $code, expected 0 and one point at 1 2 3"
  printf '     output: %s\n' "$out"
  fails=$((fails + 1))
fi
# An ascii value its declared integer type cannot hold (uchar 99999): refused, not rescaled.
expect_error ply-uchar-99999 "uchar_out_of_range.ply" "line 15" "red" "0..255" -- info "$HERE/uchar_out_of_range.ply"
expect_error ply-2e63-items "huge_count.ply" "line" "9223372036854775807" -- info "$HERE/huge_count.ply"
expect_error las-truncated "truncated.las" "byte 96" "past end of file" -- info "$HERE/truncated.las"
expect_error png-header-claims-10000x10000 "huge_header.png" "10000x10000" -- compare "$HERE/huge_header.png" "$HERE/huge_header.png"
expect_error png-lying-size "lying_size.png" "8000x8000x3" "but the file has only" -- compare "$HERE/lying_size.png" "$HERE/lying_size.png"
# ---- NaN / inf / out-of-range numbers, wrapping integers.
expect_error pcd-1e400 "out_of_range.pcd" "line 13" "1e400" -- info "$HERE/out_of_range.pcd"
expect_error scene-radius-1e400 "s_huge_radius.json" "byte" "1e400" -- render -q "$W/s_huge_radius.json" --out "$W/old.png"
expect_error width-wraps-height "--width" "65536" -- render -q "$W/s.json" --camera "$W/tall.json" --width 65536 --out "$W/old.png"
expect_error seed-negative "--seed" "-1" -- render -q "$W/s.json" --seed -1 --out "$W/old.png"
expect_error fail-nan "--fail" "nan" -- compare "$W/old.png" "$W/old.png" --fail nan
expect_error capacity-inf "--capacity" "an integer in" -- query --cloud "$W/c.xyz" --rays "$W/rays_ok.csv" --capacity inf
expect_error max-distance-huge "--max-distance" "finite" -- visibility -q "$W/c.xyz" --observer 0.5,0.5,3 --max-distance 1e400
expect_error spp-zero "--spp" -- render -q "$W/s.json" --spp 0 --out "$W/old.png"
expect_error newline-in-path 'new\nline.xyz' -- render -q "$W/s.json" --camera "$NL" --out "$W/old.png"
# ---- Outputs over special files; multi-file outputs all or nothing.
expect_error out-fifo "fifo.png" "FIFO" -- render -q "$W/s.json" --out "$W/fifo.png"
expect_error out-symlink "link.png" "symbolic link" -- render -q "$W/s.json" --out "$W/link.png"
expect_error out-dev-null "/dev/null" "character device" -- query --cloud "$W/c.xyz" --rays "$W/rays_ok.csv" --out /dev/null
expect_error aov-over-directory "old.aovs.exr" "directory" -- render -q "$W/s.json" --aov depth --out "$W/old.png"
expect_error visibility-raster-in-proc "x.tif" -- visibility -q "$W/c.xyz" --observer 0.5,0.5,3 -o "$W/old.las" --raster /proc/x.tif --cell 1 --no-preview
[ -p "$W/fifo.png" ] || { echo "FAIL the FIFO output path was replaced"; fails=$((fails + 1)); }
[ -L "$W/link.png" ] || { echo "FAIL the symlink output path was replaced"; fails=$((fails + 1)); }
[ -c /dev/null ] || { echo "FAIL /dev/null is no longer a character device"; fails=$((fails + 1)); }

# ---- Corrupted index files, a LAZ count above its chunks, an output that is an input.
# Crafted here from the bundled autzen_trim.las (a 300 MiB reproducer is a sparse tail, not a file
# in the repository). The root node record's packed field (nodes section + 28) := 0x80000000, an
# internal node of 0 children: surfel set-up must refuse it, not read past the empty kNN result.
if "$RAYSCAN" index -q "$DATA/las/autzen_trim.las" -o "$W/x.rsi" >/dev/null 2>&1; then
  python3 - "$W/x.rsi" <<'PY'
import struct, sys
p = sys.argv[1]
b = bytearray(open(p, 'rb').read())
for i in range(struct.unpack_from('<I', b, 20)[0]):
    sid, _, off = struct.unpack_from('<IIQ', b, 128 + 32 * i)
    if sid == 9:
        struct.pack_into('<I', b, off + 28, 0x80000000)
open(p[:-4] + '_root.rsi', 'wb').write(b)
PY
  cp "$W/x_root.rsi" "$W/x_pad.rsi"
  truncate -s 300M "$W/x_pad.rsi"
  expect_error rsi-corrupt-root "x_root.rsi" "checksum" -- visibility -q "$W/x_root.rsi" --primitive surfel --observer 636500,849200 -o "$W/old.las"
  expect_error rsi-padded-past-256MiB "x_pad.rsi" "bytes after the end of the last section" -- visibility -q "$W/x_pad.rsi" --primitive surfel --observer 636500,849200 -o "$W/old.las"
  expect_error rsi-padded-render "x_pad.rsi" "bytes after the end of the last section" -- render -q "$W/x_pad.rsi" --primitive surfel --out "$W/old.png"
else
  echo "FAIL index of autzen_trim.las for the corrupted-index cases"; fails=$((fails + 1))
fi
python3 - "$DATA/laz/autzen_trim.laz" "$W/count.laz" <<'PY'
import struct, sys
b = bytearray(open(sys.argv[1], 'rb').read())
struct.pack_into('<I', b, 107, struct.unpack_from('<I', b, 107)[0] + 1)
if b[25] >= 4:
    struct.pack_into('<Q', b, 247, struct.unpack_from('<Q', b, 247)[0] + 1)
open(sys.argv[2], 'wb').write(b)
PY
expect_error laz-count-above-chunks "count.laz" "past its end" -- translate "$W/count.laz" "$W/old.las"
cp "$W/c.xyz" "$W/c_before.xyz"
expect_error query-out-is-input "c.xyz" "is the same file as the input" -- query --cloud "$W/c.xyz" --rays "$W/rays_ok.csv" --out "$W/c.xyz"
cmp -s "$W/c.xyz" "$W/c_before.xyz" || { echo "FAIL query-out-is-input: the input was changed"; fails=$((fails + 1)); }

# Requirement 5: no render time in the EXR header, so two renders of one scene are byte-identical.
cases=$((cases + 1))
if "$RAYSCAN" render -q "$W/s.json" --aov depth --out "$W/r1.exr" >/dev/null 2>&1 &&
   "$RAYSCAN" render -q "$W/s.json" --aov depth --threads 1 --out "$W/r2.exr" >/dev/null 2>&1 &&
   cmp -s "$W/r1.exr" "$W/r2.exr"; then
  echo "ok   render-deterministic-bytes"
else
  echo "FAIL render-deterministic-bytes: two renders of one scene differ (cmp)"; fails=$((fails + 1))
fi

echo "adversarial corpus: $((cases - fails)) of $cases cases passed"
[ "$fails" -eq 0 ]
