#!/usr/bin/env bash
# Runs GRASS GIS r.sun with its own terrain shadowing on a DSM GeoTIFF (rayscan's own, from
# `rayscan render CLOUD --ortho-map C --dsm dsm.tif`) for a sample of days, for the autzen
# fidelity test (tests/analysis/test_solar_dsm.cpp), and writes
#
#   OUT_DIR/rsun_global.tif   the weighted sum of the days' glob_rad, kWh/m^2, Float32, NoData
#                             -9999, on exactly the DSM's grid and CRS (same geotransform)
#   OUT_DIR/rsun_beam.tif, rsun_diffuse.tif, rsun_reflected.tif   the same sums of beam_rad,
#                             diff_rad and refl_rad, when RSUN_COMPONENTS=1
#
# and prints one line per day and a summary:
#
#   RSUN_DAY day weight seconds      (the wall time of that day's r.sun, run alone)
#   RSUN_CELLS valid_cells all_cells
#
# Usage: rsun_dsm.sh DSM.tif OUT_DIR "DAY:WEIGHT DAY:WEIGHT ..." LINKE ALBEDO STEP
#   e.g. rsun_dsm.sh dsm.tif out "15:31 46:28 74:31 105:30 135:31 166:30 196:31 227:31 258:30 \
#        288:31 319:30 349:31" 3 0.2 0.5        # the 15th of each month x its days: a year
# The sum is sum(WEIGHT x glob_rad(DAY)) / 1000.
#
# Units. r.sun reads the elevation in the horizontal unit of the location (its manual: "Other
# coordinates: elevation in the same unit as the easting-northing coordinates") for its shadows,
# and in metres for the ESRA clear-sky air mass (p/p0 = exp(-z / 8434.5)); r.slope.aspect wants
# z in the horizontal unit (zscale=1). A CRS in feet (autzen: Lambert conic, international foot)
# therefore cannot be used as it is: z in feet makes the air mass wrong (426 ft read as 426 m),
# z in metres over feet makes every slope and shadow 3.28 x too flat. Instead the DSM is moved,
# unchanged cell for cell, into the same projection with metre units: every coordinate of a
# projected CRS in feet is its metre coordinate / 0.3048 (the false easting and northing are
# metres in the definition), so the geotransform is multiplied by the unit's size, the PROJ
# definition gets +units=m, and z is multiplied by the same factor with r.mapcalc. Slope and
# aspect come from r.slope.aspect on that DSM; r.sun takes latitude and longitude per cell from
# the projection. r.sun's time is local solar time from sunrise to sunset (no time zone).
#
# Needs `grass` (Debian grass-core) and GDAL's command line tools (gdal-bin). The days run one
# after the other (so that each is timed alone), each r.sun with RSUN_NPROCS threads (default 1).
# Exit status non-zero on any failure.
set -euo pipefail

if [[ "${1:-}" != "--inner" ]]; then
  if [[ $# -ne 6 ]]; then
    echo "usage: $0 DSM.tif OUT_DIR \"DAY:WEIGHT ...\" LINKE ALBEDO STEP" >&2
    exit 2
  fi
  dsm=$1 out=$2
  mkdir -p "$out"
  # The CRS's linear unit, from its PROJ definition.
  proj=$(gdalsrsinfo -o proj4 "$dsm" | tr -d "'" | grep '+proj' | head -1)
  [[ -n $proj ]] || { echo "$dsm has no CRS" >&2; exit 1; }
  case "$proj" in
    *+units=m\ * | *+units=m) unit=1 ;;
    *+units=ft\ * | *+units=ft) unit=0.3048 ;;
    *+units=us-ft\ * | *+units=us-ft) unit=0.30480060960121924 ;;
    *+to_meter=*) unit=$(sed -E 's/.*\+to_meter=([0-9.eE+-]+).*/\1/' <<<"$proj") ;;
    *) echo "unsupported units in $proj" >&2; exit 1 ;;
  esac
  proj_m=$(sed -E 's/\+units=[a-z-]+//; s/\+to_meter=[0-9.eE+-]+//' <<<"$proj")
  proj_m="$proj_m +units=m"
  # The grid in metres: the same cells, coordinates x unit.
  corner() { gdalinfo "$dsm" | sed -n "s/^$1 *( *\([-0-9.eE+]*\), *\([-0-9.eE+]*\)).*/\1 \2/p"; }
  read -r ulx uly <<<"$(corner 'Upper Left')"
  read -r lrx lry <<<"$(corner 'Lower Right')"
  [[ -n $ulx && -n $lry ]] || { echo "cannot read the corners of $dsm" >&2; exit 1; }
  read -r mulx muly mlrx mlry <<<"$(awk -v u="$unit" -v a="$ulx" -v b="$uly" -v c="$lrx" -v d="$lry" \
    'BEGIN { printf "%.10f %.10f %.10f %.10f", a * u, b * u, c * u, d * u }')"
  gdal_translate -q -a_srs "$proj_m" -a_ullr "$mulx" "$muly" "$mlrx" "$mlry" "$dsm" "$out/dsm_xy_m.tif"
  loc=$(mktemp -d "${TMPDIR:-/tmp}/rsun_dsm_XXXXXX")
  trap 'rm -rf "$loc"' EXIT
  grass -c "$out/dsm_xy_m.tif" -e "$loc/loc" >/dev/null 2>&1
  grass "$loc/loc/PERMANENT" --exec bash "$0" --inner "$out" "$3" "$4" "$5" "$6" "$unit"
  # Back onto the DSM's own grid and CRS (the cells are the same; only the coordinates' unit).
  gdalsrsinfo -o wkt "$dsm" >"$out/dsm_crs.wkt"
  for name in global beam diffuse reflected; do
    [[ -f "$out/rsun_${name}_m.tif" ]] || continue
    gdal_translate -q -a_srs "$out/dsm_crs.wkt" -a_ullr "$ulx" "$uly" "$lrx" "$lry" "$out/rsun_${name}_m.tif" \
      "$out/rsun_$name.tif"
    rm -f "$out/rsun_${name}_m.tif"
  done
  rm -f "$out/dsm_xy_m.tif" "$out/dsm_crs.wkt"
  exit 0
fi
shift
out=$1 days=$2 linke=$3 albedo=$4 step=$5 unit=$6

r.in.gdal --quiet --overwrite input="$out/dsm_xy_m.tif" output=dsm_in
g.region --quiet raster=dsm_in
r.mapcalc --quiet --overwrite expression="z = dsm_in * $unit"
r.slope.aspect --quiet --overwrite elevation=z slope=slope aspect=aspect

components=""
[[ ${RSUN_COMPONENTS:-0} == 1 ]] && components=1
expr="0"
for dw in $days; do
  day=${dw%%:*} weight=${dw##*:}
  t0=$(date +%s.%N)
  r.sun --quiet --overwrite elevation=z slope=slope aspect=aspect linke_value="$linke" \
    albedo_value="$albedo" day="$day" step="$step" nprocs="${RSUN_NPROCS:-1}" glob_rad="g_$day" \
    ${components:+beam_rad="b_$day" diff_rad="d_$day" refl_rad="r_$day"}
  t1=$(date +%s.%N)
  echo "RSUN_DAY $day $weight $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')"
  expr="$expr + $weight * g_$day"
done
export_sum() {  # map-prefix name
  r.mapcalc --quiet --overwrite expression="sum_$2 = float((${expr//g_/$1_}) / 1000.0)"
  r.out.gdal --quiet --overwrite -c input="sum_$2" output="$out/rsun_$2_m.tif" format=GTiff type=Float32 \
    nodata=-9999 createopt="COMPRESS=DEFLATE"
}
export_sum g global
if [[ -n $components ]]; then export_sum b beam; export_sum d diffuse; export_sum r reflected; fi
eval "$(r.univar -g map=sum_global)"
echo "RSUN_CELLS $n $cells"
