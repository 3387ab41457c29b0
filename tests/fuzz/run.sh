#!/usr/bin/env bash
# Builds the libFuzzer targets (one per reader: las, ply, pcd, text, laz, copc, rsi for the
# index file, and sql for the SQL functions' argument parsing) with clang++
# -fsanitize=fuzzer,address and runs each for a bounded time on a corpus seeded from tests/data
# (plus the checked-in regression inputs in tests/fuzz/regressions/<format>/).
# Usage: tests/fuzz/run.sh [SECONDS_PER_TARGET (default 60)] [BUILD_DIR (default build-fuzz)]
# FUZZ_TARGETS="laz copc" limits the run to some targets (FUZZ_TARGETS=sql compiles only what it needs); FUZZ_SEED (default 1) fixes libFuzzer's
# random seed so that a failure in CI replays locally with the same command. FUZZ_JOBS (default 2)
# compiles that many sources and runs that many targets at a time (each target single-threaded).
# Exit status: 0 when no target crashed, 1 otherwise. Crashing inputs are written to
# BUILD_DIR/crashes/<format>-crash-*; copy them to tests/fuzz/regressions/<format>/ after fixing.
# FUZZ_BUILD=DIR runs the targets that a CMake build with RAYSCAN_FUZZ=ON made (tools/sanitize.sh:
# DIR/tests/fuzz/fuzz_<format>, the sanitizer build's own rayscan_io with coverage) and compiles
# nothing here; CI does this, after the sanitizer job. BUILD_DIR then holds corpora, logs, crashes.
# Both folders are relative to the repository's root. The targets are used as they are: build them
# first (tools/sanitize.sh DIR).
set -euo pipefail
cd "$(dirname "$0")/../.."
SECONDS_PER_TARGET="${1:-60}"
OUT="${2:-build-fuzz}"
CXX="${FUZZ_CXX:-clang++}"
if [ -z "${FUZZ_BUILD:-}" ]; then
  command -v "$CXX" >/dev/null || { echo "fuzz: $CXX not found (Debian package clang)"; exit 2; }
  mkdir -p "$OUT/obj"
fi
mkdir -p "$OUT/crashes"
JOBS="${FUZZ_JOBS:-2}"

if [ -z "${FUZZ_BUILD:-}" ]; then
FLAGS=(-std=c++20 -O1 -g -fno-omit-frame-pointer -ffp-contract=off -fsanitize=address,undefined
       -fno-sanitize-recover=undefined -Ibase/include -Ioctree/include -Iio/include -Iio/src -Isite/include
       -Icamera/include -Isql/common/include -I/usr/include/liblzf)
# base, the core, io and site: the readers call into all of them. The SQL target links only the SQL
# functions, the SQLite extension and the core's distance functions (as rayscan_sql_common does).
SOURCES=(base/src/*.cpp octree/src/*.cpp octree/src/*/*.cpp io/src/*.cpp io/src/*/*.cpp site/src/*.cpp site/src/*/*.cpp)
SQL_SOURCES=(sql/common/functions.cpp sql/sqlite/extension.cpp)
if [ "${FUZZ_TARGETS:-}" = sql ]; then  # the SQL target alone: none of the readers' sources
  SOURCES=(octree/src/query/distance.cpp)
fi
objs=()
sql_objs=("$OUT/obj/octree_src_query_distance.cpp.o")
running=0
for s in "${SOURCES[@]}" "${SQL_SOURCES[@]}"; do
  o="$OUT/obj/$(echo "$s" | tr '/' '_').o"
  if [ ! -f "$o" ] || [ "$s" -nt "$o" ] || [ -n "$(find base io site octree sql -newer "$o" -name '*.hpp' -o -newer "$o" -name '*.h' 2>/dev/null)" ]; then
    echo "fuzz: compiling $s"
    "$CXX" "${FLAGS[@]}" -fsanitize=fuzzer-no-link -c "$s" -o "$o.tmp" && mv "$o.tmp" "$o" &
    running=$((running + 1))
    if [ "$running" -ge "$JOBS" ]; then wait -n; running=$((running - 1)); fi
  fi
  case "$s" in sql/*) sql_objs+=("$o") ;; *) objs+=("$o") ;; esac
done
wait
for o in "${objs[@]}" "${sql_objs[@]}"; do [ -f "$o" ] || { echo "fuzz: compiling $o failed"; exit 1; }; done

fi

# Link every target and seed its corpus, then run up to FUZZ_JOBS targets at a time (each libFuzzer
# process is single-threaded, so one at a time left a core idle for the whole bounded run).

TARGETS=(${FUZZ_TARGETS:-las ply pcd text laz copc rsi sql epw})
for fmt in "${TARGETS[@]}"; do
  if [ -n "${FUZZ_BUILD:-}" ]; then
    [ -x "$FUZZ_BUILD/tests/fuzz/fuzz_$fmt" ] ||
      { echo "fuzz: $FUZZ_BUILD/tests/fuzz/fuzz_$fmt not built (configure with -DRAYSCAN_FUZZ=ON)"; exit 2; }
    ln -sf "$(cd "$FUZZ_BUILD" && pwd)/tests/fuzz/fuzz_$fmt" "$OUT/fuzz_$fmt"
  else
    exe="$OUT/fuzz_$fmt"
    echo "fuzz: linking $exe"
    if [ "$fmt" = sql ]; then
      "$CXX" "${FLAGS[@]}" -fsanitize=fuzzer tests/fuzz/fuzz_sql.cpp "${sql_objs[@]}" -lsqlite3 -o "$exe"
    elif [ "$fmt" = epw ]; then  # the reader alone: it depends on nothing else of rayscan
      "$CXX" "${FLAGS[@]}" -Ianalysis/include -fsanitize=fuzzer tests/fuzz/fuzz_epw.cpp analysis/src/epw.cpp -o "$exe"
    else
      "$CXX" "${FLAGS[@]}" -fsanitize=fuzzer "tests/fuzz/fuzz_$fmt.cpp" "${objs[@]}" -lgdal -llzf -lz -ltbb -o "$exe"
    fi
  fi
  corpus="$OUT/corpus/$fmt"
  mkdir -p "$corpus"  # the source tree is left as it is: a regressions folder exists only with findings
  case "$fmt" in
    las) seeds=(tests/data/las/*.las) ;;
    ply) seeds=(tests/data/ply/*.ply) ;;
    pcd) seeds=(tests/data/pcd/*.pcd) ;;
    text) seeds=() ;;
    laz) seeds=(tests/data/laz/append-bug.laz tests/data/laz/simple-laszip-compressor-version-1.2r0.laz) ;;  # + regressions/laz
    rsi) seeds=() ;;  # the small index files in regressions/rsi (built by `rayscan index`)
    copc) seeds=(tests/data/laz/*.copc.laz) ;;  # lone-star.copc.laz (bundled, 2.7 MB)
    sql) seeds=() ;;  # the calls below, and regressions/sql
    epw) seeds=() ;;  # a day of a generated file below
  esac
  for f in "${seeds[@]}"; do
    # Seeds over 256 KiB are cut to their head (libFuzzer's -max_len); small ones are whole.
    head -c 262144 "$f" > "$corpus/seed-$(basename "$f")"
  done
  if [ "$fmt" = text ]; then
    printf 'x,y,z,red,green,blue,intensity\n1.5,2.5,3.5,255,0,10,7\n' > "$corpus/seed-header.csv"
    head -n 50 tests/data/pcd/lamppost.pcd | tail -n 30 > "$corpus/seed-xyz.txt"
    head -n 40 tests/data/pcd/utm17_space.pcd | tail -n 10 > "$corpus/seed-utm.xyz"
  fi
  if [ "$fmt" = epw ]; then  # a valid file of one day (the EPW data dictionary's 8 header lines, 24 records)
    {
      echo 'LOCATION,Test,CA,USA,TMY3,724940,37.62,-122.40,-8.0,2.0'
      printf 'DESIGN CONDITIONS,0\nTYPICAL/EXTREME PERIODS,0\nGROUND TEMPERATURES,0\n'
      printf 'HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0\nCOMMENTS 1,fuzz seed\nCOMMENTS 2,\n'
      echo 'DATA PERIODS,1,1,Data,Sunday, 1/ 1, 1/ 1'
      for h in $(seq 1 24); do
        echo "1999,1,1,$h,60,?9?9?9?9,10.0,5.0,70,101325,0,0,300,$((h * 20)),$((h * 15)),$((h * 5)),0,0,0,0,180,2.0,10,10,10.0,1000,9,999999999,0,0.1,0,0,0.2,0.0,0.0"
      done
    } > "$corpus/seed-day.epw"
  fi
  if [ "$fmt" = sql ]; then  # one valid call of each kind (fuzz_sql.cpp: the input format)
    printf 'dist_ray\n0\n0\n0\n1\n0\n0\n1\n2\n3' > "$corpus/seed-dist_ray"
    printf 'dist_plane\n0\n0\n0\n0\n0\n1\n1.5\n2\n-3' > "$corpus/seed-dist_plane"
    printf 'ray_time_max\n0\n0\n0\n1\n1\n0\n0\n0\n0\n1\n1\n1' > "$corpus/seed-ray_time_max"
    printf 'ray_query\n3.5\n3.5\n5\n0\n0\n-1\n4\n2\nNULL\nNULL\n'"'"'ray' > "$corpus/seed-ray_query"
    printf 'ray_query\n0\n0\n1\n1\n1\n-0.5\n3\n1.5\n0\n9\n'"'"'time' > "$corpus/seed-ray_query_time"
    printf 'ray_prune\n3.5\n3.5\n5\n0\n0\n-1\n1\n0\n10' > "$corpus/seed-ray_prune"
    printf 'plane_prune\n0\n0\n0\n1\n0\n0' > "$corpus/seed-plane_prune"
    printf 'rs_box\n(0,0,0, 1,2,3)' > "$corpus/seed-rs_box"
    printf 'rs_ray\n(0,0,0,1,0,0,2,-inf,inf)' > "$corpus/seed-rs_ray"
    printf 'rs_plane\n( 1e3 ,0,0,0,0,1 )' > "$corpus/seed-rs_plane"
  fi
done

# One target's bounded run; its exit status (0: no crash) in $OUT/fuzz_$fmt.status.
run_target() {
  local fmt="$1"
  local regressions=()
  [ -d "tests/fuzz/regressions/$fmt" ] && regressions=("tests/fuzz/regressions/$fmt")
  # LeakSanitizer off: GDAL/PROJ keep process-lifetime caches that it would report.
  if ASAN_OPTIONS=detect_leaks=0 "$OUT/fuzz_$fmt" -max_total_time="$SECONDS_PER_TARGET" -max_len=262144 \
       -seed="${FUZZ_SEED:-1}" -timeout=20 -rss_limit_mb=3072 -print_final_stats=1 -dict="tests/fuzz/$fmt.dict" \
       -artifact_prefix="$OUT/crashes/$fmt-" "$OUT/corpus/$fmt" "${regressions[@]}" \
       > "$OUT/fuzz_$fmt.log" 2>&1; then
    echo 0 > "$OUT/fuzz_$fmt.status"
  else
    echo 1 > "$OUT/fuzz_$fmt.status"
  fi
}
running=0
for fmt in "${TARGETS[@]}"; do
  echo "fuzz: running $OUT/fuzz_$fmt for ${SECONDS_PER_TARGET}s"
  rm -f "$OUT/fuzz_$fmt.status"
  run_target "$fmt" &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then wait -n || true; running=$((running - 1)); fi
done
wait || true

status=0
for fmt in "${TARGETS[@]}"; do
  if [ "$(cat "$OUT/fuzz_$fmt.status" 2>/dev/null)" != 0 ]; then
    echo "fuzz: $fmt FAILED (see $OUT/fuzz_$fmt.log and $OUT/crashes/)"
    tail -n 40 "$OUT/fuzz_$fmt.log"
    status=1
  else
    echo "fuzz: $fmt ok: $(grep -E 'stat::number_of_executed_units' "$OUT/fuzz_$fmt.log" | awk '{print $2}') runs"
  fi
done
exit $status
