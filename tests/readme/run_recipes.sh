#!/usr/bin/env bash
# Runs the copy-paste recipes of README.md against the bundled data, as a user would paste them.
#
# A recipe is a fenced ```sh block directly preceded by a marker line
#   <!-- recipe: NAME outputs: FILE... -->
# (outputs optional). Every other ```sh block must be preceded by <!-- not-a-recipe: REASON -->,
# so that no command block escapes the suite; only the first block of the file, the build and test
# commands (./tools/demo.sh, ./tools/test.sh) that run this suite, needs no marker.
#
#   run_recipes.sh README.md SOURCE_DIR WORK_DIR NAME   run one recipe
#   run_recipes.sh README.md --list                     print the recipe names
#   run_recipes.sh README.md --check-markers            every ```sh block is marked
#
# A recipe runs with `bash -euo pipefail` in WORK_DIR/NAME (emptied first), where `scenes` and
# `tests` are links to SOURCE_DIR's, so recipes written for the repository root read the bundled
# data (scenes/data, tests/data) and write their outputs into the work folder. `rayscan`, `python3`
# (the interpreter the module is built for), PYTHONPATH and the SQLite extension's library path come
# from the environment CTest sets (tests/readme/CMakeLists.txt). Then every listed output must exist,
# be non-empty and open with the matching tool (images: iinfo, GeoTIFF: gdalinfo, point clouds and
# index files: rayscan info, CSV: a header and a row, SQLite: a points table).
#
# Recipes that need a service: `postgres` reads the private server's state file (RAYSCAN_PG_STATE,
# written by tests/sql/pg_server.sh) and connects through PGHOST/PGPORT/PGUSER; without a server it
# is skipped (exit 77). `mpi` runs the user's `mpirun -n 2 ...` with the loopback settings of
# tests/mpi given as OMPI_* environment variables (root allowed, oversubscription, no binding).
set -euo pipefail
readme=$1
shift

# Prints the recipes as "NAME<TAB>OUTPUTS" and, with --check-markers, fails on unmarked blocks.
scan() {
  awk -v check="${1:-}" '
    /^<!-- recipe: / { line = $0; sub(/^<!-- recipe: /, "", line); sub(/ *-->.*$/, "", line)
                       name = line; sub(/ .*$/, "", name)
                       outs = ""; if (line ~ / outputs: /) { outs = line; sub(/^.* outputs: /, "", outs) }
                       pending = name; pending_outs = outs; next }
    /^<!-- not-a-recipe: / { pending = "-"; next }
    /^```sh *$/ { blocks++
                  if (blocks == 1 && pending == "") next   # the build commands at the top
                  if (pending == "") { printf "README line %d: a ```sh block without a recipe or not-a-recipe marker\n", NR > "/dev/stderr"; bad = 1 }
                  else if (pending != "-") { if (check == "") printf "%s\t%s\n", pending, pending_outs }
                  pending = ""; next }
    NF { pending = "" }
    END { if (check != "" && bad) exit 1 }
  ' "$readme"
}

# The body of recipe $1.
body() {
  awk -v want="$1" '
    inside && /^```/ { exit }
    inside { print; next }
    /^<!-- recipe: / { line = $0; sub(/^<!-- recipe: /, "", line); sub(/[ ].*$/, "", line); sub(/-->$/, "", line)
                       armed = (line == want); next }
    armed && /^```sh *$/ { inside = 1; next }
    NF { armed = 0 }
  ' "$readme"
}

case ${1:-} in
--list) scan | cut -f1; exit 0 ;;
--check-markers)
  scan check
  n=$(scan | wc -l)
  [ "$n" -gt 0 ] || { echo "no recipes found in $readme"; exit 1; }
  dup=$(scan | cut -f1 | sort | uniq -d)
  [ -z "$dup" ] || { echo "recipe names used twice: $dup"; exit 1; }
  echo "$n recipes, every sh block marked"
  exit 0 ;;
esac

src=$1 work=$2 name=$3
entry=$(scan | awk -F'\t' -v n="$name" '$1 == n')
[ -n "$entry" ] || { echo "recipe '$name' not found in $readme"; exit 1; }
outputs=$(printf '%s\n' "$entry" | cut -f2)
script=$(body "$name")
[ -n "$script" ] || { echo "recipe '$name' has an empty block"; exit 1; }

dir=$work/$name
rm -rf "$dir"
mkdir -p "$dir"
ln -s "$src/scenes" "$dir/scenes"
ln -s "$src/tests" "$dir/tests"
cd "$dir"

case $name in
postgres)
  state=${RAYSCAN_PG_STATE:-}
  if [ -z "$state" ] || [ ! -s "$state" ]; then
    echo "recipe postgres: no private PostgreSQL server (tests/sql/pg_server.sh found no PostgreSQL 15); skipped"
    exit 77
  fi
  export PGHOST=$(cat "$state") PGPORT=5432 PGUSER=postgres
  dropdb --if-exists rayscan_demo >/dev/null 2>&1 || true
  trap 'dropdb --if-exists rayscan_demo >/dev/null 2>&1 || true' EXIT
  ;;
mpi)
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  export OMPI_MCA_rmaps_base_oversubscribe=1 OMPI_MCA_hwloc_base_binding_policy=none
  export OMPI_MCA_btl=self,vader OMPI_MCA_btl_vader_single_copy_mechanism=none
  export RAYSCAN_MPI_TIMEOUT=60
  ;;
esac

printf '%s\n' "$script" >recipe.sh
echo "== recipe $name (in $dir)"
cat recipe.sh
echo "== output"
start=$(date +%s.%N)
bash -euo pipefail recipe.sh
end=$(date +%s.%N)
echo "== recipe $name: exit 0 in $(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }') s"

fail=0
for f in $outputs; do
  if [ ! -s "$f" ]; then echo "output $f: missing or empty"; fail=1; continue; fi
  why=""
  case $f in
  *.png|*.jpg|*.exr) iinfo "$f" >/dev/null || why="does not decode (iinfo)" ;;
  *.tif) info=$(gdalinfo "$f") && grep -q '^Band 1' <<<"$info" || why="gdalinfo finds no band" ;;
  *.las|*.laz|*.ply|*.pcd) rayscan info "$f" >/dev/null || why="rayscan info fails" ;;
  *.rsi) rayscan info --verify "$f" >/dev/null || why="rayscan info --verify fails" ;;
  *.csv) [ "$(wc -l <"$f")" -ge 2 ] || why="no row under the header" ;;
  *.sqlite) [ "$(sqlite3 "$f" 'SELECT count(*) FROM points')" -gt 0 ] || why="no points" ;;
  esac
  if [ -n "$why" ]; then echo "output $f: $why"; fail=1; else echo "output $f: $(stat -c %s "$f") bytes, ok"; fi
done
exit $fail
