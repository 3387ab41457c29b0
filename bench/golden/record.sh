#!/usr/bin/env bash
# Records the user-visible outputs of one rayscan build, so that a refactoring can be proved to
# change nothing: run it on the old and the new build, then bench/golden/compare.sh OLD NEW.
# Outputs: every scene of scenes/ rendered with every AOV (EXR, small and few samples: the point is
# identity, not beauty; plus surfel mode), `query` for each order on two real files and their index
# files, `index` files of two inputs, `visibility` LAS/PLY/GeoTIFF/PNG, `compare --json`,
# `info --json`, `translate` both ways, SQLite query results, and the Python example's output.
# Usage: bench/golden/record.sh BUILD_DIR OUT_DIR
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD="$(cd "$1" && pwd)"
OUT="$2"
RS="$BUILD/tools/rayscan"
rm -rf "$OUT"; mkdir -p "$OUT"
OUT="$(cd "$OUT" && pwd)"
run() { "$@" >>"$OUT/log.txt" 2>&1 || { echo "record: failed: $*" >&2; tail -5 "$OUT/log.txt" >&2; exit 1; }; }

# Rays: a fixed grid over autzen_trim (international feet) and lone-star, downward and slanted.
python3 - "$OUT" <<'PY'
import sys
out = sys.argv[1]
def grid(name, x0, x1, y0, y1, z, n):
    with open(f"{out}/{name}", "w") as f:
        f.write("ox,oy,oz,dx,dy,dz\n")
        for i in range(n):
            for j in range(n):
                x = x0 + (x1 - x0) * (i + 0.5) / n
                y = y0 + (y1 - y0) * (j + 0.5) / n
                f.write(f"{x:.3f},{y:.3f},{z:.3f},{0.1 * (i - n / 2) / n:.6f},{0.1 * (j - n / 2) / n:.6f},-1\n")
grid("rays_autzen.csv", 636050, 637150, 848950, 849480, 900, 24)
grid("rays_lonestar.csv", 0, 1, 0, 1, 0, 1)  # replaced below from the file's bounds
PY
# lone-star's bounds from `info --json`.
"$RS" info tests/data/laz/lone-star.copc.laz --json > "$OUT/info_lonestar.json"
python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
info = json.load(open(f"{out}/info_lonestar.json"))
def find(d, key):
    if isinstance(d, dict):
        if key in d: return d[key]
        for v in d.values():
            r = find(v, key)
            if r is not None: return r
    return None
b = find(info, "bounds")
lo, hi = (b["min"], b["max"]) if isinstance(b, dict) else (b[:3], b[3:])
n = 20
with open(f"{out}/rays_lonestar.csv", "w") as f:
    f.write("ox,oy,oz,dx,dy,dz\n")
    for i in range(n):
        for j in range(n):
            x = lo[0] + (hi[0] - lo[0]) * (i + 0.5) / n
            y = lo[1] + (hi[1] - lo[1]) * (j + 0.5) / n
            f.write(f"{x:.3f},{y:.3f},{hi[2] + 50:.3f},{0.05 * (i - n / 2) / n:.6f},0,-1\n")
PY

# Index files of two inputs.
run "$RS" index tests/data/las/autzen_trim.las -o "$OUT/autzen.rsi" --attributes id,rgb,intensity,classification,gps_time -q
run "$RS" index tests/data/las/Haystack_Rock.las -o "$OUT/haystack.rsi" -q

# Queries: each order on two real files (and on the index file).
for order in ray time sphere_hit; do
  run "$RS" query --cloud tests/data/las/autzen_trim.las --rays "$OUT/rays_autzen.csv" --k 4 --radius 6 --order "$order" --out "$OUT/query_autzen_$order.csv"
  run "$RS" query --cloud "$OUT/autzen.rsi" --rays "$OUT/rays_autzen.csv" --k 4 --radius 6 --order "$order" --out "$OUT/query_autzen_rsi_$order.csv"
  run "$RS" query --cloud tests/data/laz/lone-star.copc.laz --rays "$OUT/rays_lonestar.csv" --k 3 --radius 2 --order "$order" --out "$OUT/query_lonestar_$order.csv"
done
for index in octree-layered octree-fixed kdtree brute; do
  run "$RS" query --cloud tests/data/las/autzen_trim.las --rays "$OUT/rays_autzen.csv" --k 2 --radius 6 --index "$index" --out "$OUT/query_autzen_$index.csv"
done

# Renders: every scene, every AOV, EXR; sphere and surfel.
AOVS=(--aov depth --aov normal --aov position --aov index --aov albedo --aov cost)
for s in scenes/*.json; do
  n="$(basename "$s" .json)"
  run "$RS" render "$s" --out "$OUT/render_$n.exr" --spp 2 --width 120 --height 80 "${AOVS[@]}" -q
  run "$RS" render "$s" --out "$OUT/render_${n}_surfel.exr" --spp 2 --width 120 --height 80 --primitive surfel "${AOVS[@]}" -q
done
run "$RS" render scenes/autzen_overview.json --out "$OUT/render_autzen_overview.png" --spp 4 --width 160 --height 100 -q
run "$RS" render scenes/autzen_overview.json --out "$OUT/render_autzen_overview_s8.png" --spp 8 --width 160 --height 100 -q
run "$RS" render tests/data/las/autzen_trim.las --out "$OUT/render_quicklook.png" --spp 2 --width 120 --height 80 -q
run "$RS" render tests/data/laz/lone-star.copc.laz --out "$OUT/render_copc.exr" --spp 2 --width 120 --height 80 "${AOVS[@]}" -q
# The render of the index file (scene with the cloud replaced).
sed 's#"data/autzen_trim.las"#"'"$OUT"'/autzen.rsi"#' scenes/autzen_overview.json > scenes/.golden_rsi.json
run "$RS" render scenes/.golden_rsi.json --out "$OUT/render_rsi.exr" --spp 2 --width 120 --height 80 "${AOVS[@]}" -q
rm -f scenes/.golden_rsi.json
run "$RS" render scenes/autzen_overview.json --ortho-map 5 --out "$OUT/ortho.tif" --dsm "$OUT/dsm.tif" -q

# compare --json (exit 1 = images differ, which is the point).
"$RS" compare "$OUT/render_autzen_overview.png" "$OUT/render_autzen_overview_s8.png" --json --diff "$OUT/diff.png" > "$OUT/compare.json" || true

# info --json on every format.
for f in tests/data/las/autzen_trim.las tests/data/las/test1_4.las tests/data/laz/autzen_trim.laz tests/data/ply/bunny.ply tests/data/pcd/lamppost.pcd "$OUT/autzen.rsi"; do
  "$RS" info "$f" --json > "$OUT/info_$(basename "$f").json" 2>>"$OUT/log.txt"
done

# translate both ways.
run "$RS" translate tests/data/las/autzen_trim.las "$OUT/autzen.laz"
run "$RS" translate tests/data/laz/autzen_trim.laz "$OUT/autzen_from_laz.las"
run "$RS" translate tests/data/las/test1_4.las "$OUT/test1_4.laz"

# visibility: counts, sky view, raster, from a camera; LAS, PLY, LAZ.
X=636600; Y=849200
run "$RS" visibility tests/data/las/autzen_trim.las --observer "$X,$Y" --height 6 -o "$OUT/vis.las" --raster "$OUT/vis.tif" --cell 10 -q
run "$RS" visibility tests/data/las/autzen_trim.las --observer "$X,$Y" --height 6 -o "$OUT/vis_surfel.ply" --primitive surfel -q
run "$RS" visibility "$OUT/autzen.rsi" --observer "$X,$Y" --height 6 --sky-view 16 -o "$OUT/vis_rsi.laz" -q

# SQLite: import and the paper's functions.
run "$RS" db import tests/data/las/autzen_trim.las -o "$OUT/site.sqlite"
if [ -f "$BUILD/sql/rayscan_sqlite.so" ]; then
  sqlite3 -cmd ".load $BUILD/sql/rayscan_sqlite" "$OUT/site.sqlite" \
    "SELECT * FROM ray_query(636600, 849200, 900, 0.01, 0.02, -1, 5, 8, 0, 1e9, 'ray');
     SELECT count(*), sum(x), sum(y), sum(z) FROM points;
     SELECT dist_ray(0,0,0, 1,1,1, 1,2,3), dist_plane(0,0,0, 0,0,1, 1,2,3);" > "$OUT/sqlite.txt"
fi
# The Python example.
if [ -d "$BUILD/python" ]; then
  PYTHONPATH="$BUILD/python" /usr/bin/python3 - > "$OUT/python.txt" <<'PY'
import numpy as np, rayscan
pc = rayscan.read("tests/data/las/autzen_trim.las")
tree = rayscan.Octree(pc.xyz)
nn = tree.knn(pc.xyz[::97], k=3)
print(np.asarray(nn.distance).tobytes().hex()[:20000])
lo, hi = pc.bounds
eye = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 500.0])
d = np.stack([np.linspace(-0.3, 0.3, 400), np.linspace(-0.2, 0.2, 400), -np.ones(400)], axis=-1)
hits = tree.ray_query(eye, d, k=1, radius=3.0, t_min=0.0, order="sphere_hit")
print(np.asarray(hits.first("t")).tobytes().hex())
PY
fi
rm -f "$OUT/log.txt"
echo "record: $(ls "$OUT" | wc -l) outputs in $OUT"
