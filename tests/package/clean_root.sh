#!/usr/bin/env bash
# The Debian packages on a clean Debian 12: builds them from BUILD_DIR (tools/package.sh), makes a
# fresh bookworm root (mmdebstrap's `apt` variant: essential packages and apt only), installs the
# packages there with apt-get, which fetches their dependencies from Debian's archive, and uses
# them as a user would, inside the root (chroot in private mount and PID namespaces, so that no
# mount and no process outlives the test):
#   - `rayscan render` (the quick look) on the bundled Autzen scan: the PNG is byte-identical to the
#     build tree's own quick look, rendered here with the same defaults;
#   - `man rayscan` shows the page the package installed;
#   - `import rayscan` prints rayscan.__version__ (= the project version) and runs a ray query
#     whose nearest hits equal a NumPy brute force;
#   - sqlite3 loads the extension (`.load rayscan_sqlite`): the R*Tree-pruned dist_ray query
#     returns the rows of the unpruned scan;
#   - a PostgreSQL 15 server (its own cluster on a Unix socket, no TCP) gets `CREATE EXTENSION
#     rayscan` and a `ray_dwithin` query answered through the GiST index (EXPLAIN shows the
#     Index Cond) with the rows of a sequential scan;
#   - the packages not installed (librayscan-dev, qgis-plugin-rayscan) resolve against the
#     archive (apt-get install --simulate).
# The base root is cached as a tarball in RAYSCAN_ROOT_CACHE (default /var/cache/rayscan) and the
# host's apt archive (/var/cache/apt/archives) is bound into the root, so a machine that keeps
# them downloads neither again. Needs root and Debian's archive (network); exit 77 (CTest's skip)
# when not root.
# Usage: tests/package/clean_root.sh BUILD_DIR
set -euo pipefail
SRC="$(cd "$(dirname "$0")/../.." && pwd)"
BUILD="$(realpath "${1:?usage: clean_root.sh BUILD_DIR}")"
[ "$(id -u)" -eq 0 ] || { echo "clean_root: chroot and mounts need root; skipped"; exit 77; }
command -v mmdebstrap >/dev/null || { echo "clean_root: mmdebstrap not found (tools/install-deps.sh installs it)"; exit 1; }

echo "== packages (tools/package.sh)"
[ "${CLEAN_ROOT_REUSE_PACKAGES:-0}" = 1 ] || PACKAGE_SKIP_BUILD=1 "$SRC/tools/package.sh" "$BUILD"
version=$(sed -n 's/^project(rayscan VERSION \([0-9.]*\).*/\1/p' "$SRC/CMakeLists.txt")

cache="${RAYSCAN_ROOT_CACHE:-/var/cache/rayscan}"
base="$cache/bookworm-apt.tar"
if [ ! -f "$base" ] || [ ! -s "$base" ]; then
  echo "== base root: mmdebstrap --variant=apt bookworm (cached as $base)"
  mkdir -p "$cache"
  # The host's own Debian sources (deb822) when it has them, else Debian's redirector.
  mirror=http://deb.debian.org/debian
  [ -f /etc/apt/sources.list.d/debian.sources ] && mirror=/etc/apt/sources.list.d/debian.sources
  t0=$SECONDS
  # A tarball by name (mmdebstrap picks the format from the name), made aside and renamed, so an
  # interrupted run leaves no cache that looks complete.
  rm -rf "$base" "$cache/bookworm-apt.part.tar"
  mmdebstrap --quiet --variant=apt --mode=root --format=tar --aptopt='Acquire::Check-Valid-Until "false"' \
    bookworm "$cache/bookworm-apt.part.tar" "$mirror"
  mv "$cache/bookworm-apt.part.tar" "$base"
  echo "base root made in $((SECONDS - t0)) s"
fi

work="$BUILD/tests/package/clean-root"
rm -rf "$work"
mkdir -p "$work/root"
trap 'rm -rf "$work/root"' EXIT
tar -xf "$base" -C "$work/root"
t="$work/root/rayscan-test"
mkdir -p "$t/debs" "$t/data" "$t/out"
cp "$BUILD"/packages/*.deb "$t/debs/"
cp "$SRC/scenes/data/autzen_trim.las" "$t/data/"
# The oracle of the quick look: the build tree's binary, same input, same defaults.
"$BUILD/tools/rayscan" render "$t/data/autzen_trim.las" --out "$work/quicklook_build.png" >/dev/null

cat >"$t/inside.sh" <<'INSIDE'
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive LC_ALL=C.UTF-8 PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root
cd /rayscan-test
version="$1"
# No service starts from a package's maintainer scripts inside this root (Debian's policy-rc.d).
printf '#!/bin/sh\nexit 101\n' >/usr/sbin/policy-rc.d && chmod +x /usr/sbin/policy-rc.d
echo "== apt-get install ./rayscan*.deb (dependencies from Debian's archive)"
apt-get update -qq
t0=$SECONDS
apt-get install -y -qq --no-install-recommends -o Dpkg::Options::=--force-unsafe-io ./debs/rayscan_*.deb ./debs/python3-rayscan_*.deb \
  ./debs/libsqlite3-mod-rayscan_*.deb ./debs/postgresql-15-rayscan_*.deb man-db sqlite3 >apt.log 2>&1 ||
  { tail -40 apt.log; exit 1; }
echo "installed in $((SECONDS - t0)) s: $(dpkg-query -W -f='${Package} ${Version}\n' 'rayscan' 'python3-rayscan' \
  'libsqlite3-mod-rayscan' 'postgresql-15-rayscan' | tr '\n' ';')"
others=$(ls ./debs/librayscan-dev_*.deb ./debs/qgis-plugin-rayscan_*.deb 2>/dev/null || true)
echo "== apt-get install --simulate" $others
apt-get install -s -qq --no-install-recommends $others >sim.log 2>&1 || { tail -20 sim.log; exit 1; }
grep -c '^Inst' sim.log | sed 's/^/packages it would install: /'

echo "== rayscan --version"
rayscan --version | head -1
echo "== quick look: rayscan render data/autzen_trim.las --out out/quicklook.png"
rayscan render data/autzen_trim.las --out out/quicklook.png

echo "== man rayscan"
[ "$(man -w rayscan)" = /usr/share/man/man1/rayscan.1.gz ] || { echo "man -w rayscan: $(man -w rayscan)"; exit 1; }
man -P cat rayscan 2>/dev/null | sed -n '1,8p'
man -P cat rayscan 2>/dev/null | grep -q '^SYNOPSIS' || { echo "man rayscan: no SYNOPSIS"; exit 1; }

echo "== python3: import rayscan, a ray query against a NumPy brute force"
python3 - "$version" <<'PY'
import sys
import numpy as np
import rayscan
print("rayscan", rayscan.__version__, "from", rayscan.__file__)
assert rayscan.__version__ == sys.argv[1], (rayscan.__version__, sys.argv[1])
assert rayscan.__file__.startswith("/usr/lib/python3/dist-packages/rayscan/"), rayscan.__file__
rng = np.random.default_rng(7)
pts = rng.uniform(0.0, 1.0, (20000, 3))
origins = rng.uniform(0.0, 1.0, (500, 3))
dirs = rng.normal(size=(500, 3))
dirs /= np.linalg.norm(dirs, axis=1)[:, None]
radius = 0.02
hits = rayscan.Octree(pts).ray_query(origins, dirs, k=1, radius=radius, t_min=0.0, order="ray")
got = hits.first("indices")
want = np.full(len(origins), -1)
for i, (o, d) in enumerate(zip(origins, dirs)):
    v = pts - o
    t = v @ d
    dist = np.linalg.norm(v - t[:, None] * d, axis=1)
    ok = (t >= 0.0) & (dist <= radius)
    if ok.any():
        want[i] = np.flatnonzero(ok)[np.argmin(dist[ok])]
assert np.array_equal(got, want), np.flatnonzero(got != want)[:10]
print(f"ray query: {np.count_nonzero(want >= 0)} of {len(want)} rays hit; all equal the brute force")
PY

# A vertical ray through the Autzen scan (international feet), as in docs/sql.md.
ray="636500, 849200, 600,  0, 0, -1"
echo "== sqlite3: .load rayscan_sqlite"
rayscan db import data/autzen_trim.las -o out/autzen.sqlite >/dev/null
sqlite3 out/autzen.sqlite >out/sqlite.txt <<SQL
.load rayscan_sqlite
SELECT count(*) FROM chunks c JOIN points p ON p.rowid >= c.first_row AND p.rowid < c.first_row + c.count
 WHERE c.id MATCH ray_prune($ray, 4.0) AND dist_ray($ray, p.x, p.y, p.z) <= 4.0;
SELECT count(*) FROM points p WHERE dist_ray($ray, p.x, p.y, p.z) <= 4.0;
SELECT json_extract(rayscan_stats(), '$.chunks_visited') || ' of ' || json_extract(rayscan_stats(), '$.chunks_total');
SQL
mapfile -t s <out/sqlite.txt
echo "pruned: ${s[0]} points; full scan: ${s[1]} points"
[ "${s[0]}" = "${s[1]}" ] && [ "${s[0]}" -gt 0 ] || { echo "sqlite: pruned and full scan differ"; exit 1; }

echo "== PostgreSQL 15: CREATE EXTENSION rayscan, a pruned query"
pgbin=/usr/lib/postgresql/15/bin
mkdir -p /tmp/pg && chown postgres /tmp/pg
runuser -u postgres -- "$pgbin/initdb" -D /tmp/pg/data -A trust -U postgres >/dev/null
runuser -u postgres -- "$pgbin/pg_ctl" -D /tmp/pg/data -o "-k /tmp/pg -c listen_addresses=''" -l /tmp/pg/log -w start >/dev/null
export PGHOST=/tmp/pg PGUSER=postgres PGDATABASE=postgres
psql -qAt -v ON_ERROR_STOP=1 -c "CREATE EXTENSION rayscan" -c "SELECT extname || ' ' || extversion FROM pg_extension WHERE extname = 'rayscan'"
# A database made with the first released version updates in place (rayscan--0.1--0.2.sql, then
# rayscan--0.2--0.3.sql to rayscan--0.4--0.5.sql): the update's box equality then serves DISTINCT,
# and every member of the extension has a description.
psql -qAt -v ON_ERROR_STOP=1 -c "CREATE DATABASE updated"
up=$(psql -d updated -qAt -v ON_ERROR_STOP=1 -c "CREATE EXTENSION rayscan VERSION '0.1'" -c "ALTER EXTENSION rayscan UPDATE" \
  -c "SELECT extversion FROM pg_extension WHERE extname = 'rayscan'" \
  -c "SELECT count(DISTINCT b) FROM (VALUES (rs_box(1, 2, 3)), (rs_box(1, 2, 3)), (rs_box(0, 0, 0))) v(b)" \
  -c "SELECT count(*) FROM pg_depend d WHERE d.deptype = 'e' AND d.refobjid = (SELECT oid FROM pg_extension WHERE extname = 'rayscan') AND NOT EXISTS (SELECT FROM pg_description c WHERE c.classoid = d.classid AND c.objoid = d.objid AND c.objsubid = 0 AND c.description <> '')" | tr '\n' ' ')
[ "$up" = "0.5 2 0 " ] || { echo "postgresql: 0.1 -> 0.5 update gave '$up', expected version 0.5, 2 distinct boxes and 0 objects without a description"; exit 1; }
echo "extension updated from 0.1: $up"
rayscan db import data/autzen_trim.las --postgres "host=/tmp/pg user=postgres dbname=postgres" --table autzen >/dev/null
psql -qAt -v ON_ERROR_STOP=1 >out/pg.txt <<SQL
CREATE INDEX autzen_pt ON autzen USING gist (rs_box(x, y, z));
ANALYZE autzen;
SET enable_seqscan = off;
EXPLAIN (COSTS OFF) SELECT point_index FROM autzen WHERE ray_dwithin(rs_box(x, y, z), $ray, 4.0);
SELECT string_agg(point_index::text, ',' ORDER BY point_index) FROM autzen WHERE ray_dwithin(rs_box(x, y, z), $ray, 4.0);
SET enable_seqscan = on; SET enable_indexscan = off; SET enable_bitmapscan = off;
SELECT string_agg(point_index::text, ',' ORDER BY point_index) FROM autzen WHERE dist_ray($ray, x, y, z) <= 4.0;
SQL
grep -v '^[0-9,]*$' out/pg.txt
rows=$(grep -E '^[0-9,]+$' out/pg.txt)
[ "$(echo "$rows" | wc -l)" = 2 ] && [ "$(echo "$rows" | sed -n 1p)" = "$(echo "$rows" | sed -n 2p)" ] ||
  { echo "postgresql: the index-pruned rows differ from the sequential scan"; exit 1; }
grep -q 'Index Cond: (rs_box(x, y, z) && ray_dwithin_ray' out/pg.txt || { echo "postgresql: no Index Cond"; exit 1; }
n=$(echo "$rows" | sed -n 1p | tr ',' '\n' | wc -l)
echo "index-pruned: $n points, equal to the sequential scan; sqlite found ${s[0]}"
[ "$n" = "${s[0]}" ] || { echo "postgresql and sqlite differ"; exit 1; }
runuser -u postgres -- "$pgbin/pg_ctl" -D /tmp/pg/data -m fast -w stop >/dev/null
INSIDE

echo "== into the clean root"
root="$work/root"
cp /etc/resolv.conf "$root/etc/resolv.conf"
unshare --mount --pid --fork --propagation private bash -euo pipefail -c '
  root="$1"; version="$2"
  mount -t proc proc "$root/proc"
  mount --rbind /dev "$root/dev"
  mount -t tmpfs tmpfs "$root/tmp"
  if [ -d /var/cache/apt/archives ]; then
    mkdir -p "$root/var/cache/apt/archives"
    mount --bind /var/cache/apt/archives "$root/var/cache/apt/archives"
  fi
  chroot "$root" /bin/bash /rayscan-test/inside.sh "$version"
' bash "$root" "$version"

echo "== the quick look of the package against the build tree's"
# Pixels identical (OpenImageIO's idiff, no tolerance) and every metadata item equal except the
# cloud's path, which names the file where each run found it (inside and outside the root).
idiff -fail 0 -failpercent 0 -warn 0 "$t/out/quicklook.png" "$work/quicklook_build.png" >/dev/null ||
  { echo "the package's quick look differs from the build tree's in its pixels"; exit 1; }
meta() { oiiotool --info -v "$1" | grep -v -e '^Reading ' -e 'rayscan:cloud' | sed "s|^$1 *:|image:|"; }
diff <(meta "$t/out/quicklook.png") <(meta "$work/quicklook_build.png") ||
  { echo "the package's quick look differs from the build tree's in its metadata"; exit 1; }
echo "identical pixels and metadata ($(stat -c %s "$work/quicklook_build.png") bytes)"
echo "clean_root: all checks passed"
