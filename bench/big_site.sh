#!/bin/bash
# bench/big_site.sh SCRATCH N MEMORY [ATTRIBUTES] [PDRF] [DELETE_LAS]: the index-file "1e9-point site"
# benchmark (bench/README.md). Generates SCRATCH/sN.las with build/bench/make_site (LAS 1.2, PDRF
# 0 = 20 B/point or 3 = 34 B/point; check `df -h` first), builds SCRATCH/sN.rsi with
# `rayscan index --memory MEMORY --attributes ATTRIBUTES` under `nice ionice -c3`, sampling every
# 0.5 s the process's RssAnon / RssFile (/proc/PID/status) and the file system's free space, and
# printing each progress phase's start time. With DELETE_LAS=1 the LAS file is deleted as soon
# as the read pass is over (the progress shows the merge; the readers are closed by then), for sites whose LAS, runs and index do not fit the disk together. Then renders
# SCRATCH/sN.json (600x400, SPP samples, radius RADIUS or "auto", elevation colours unless
# ATTRIBUTES has rgb) from the index under the same sampler. Data stays in SCRATCH: delete it
# afterwards.
set -u
scratch=$1; n=$2; mem=$3; attrs=${4:-none}; pdrf=${5:-0}; del=${6:-0}; spp=${SPP:-16}; radius=${RADIUS:-'"auto"'}
B=$(cd "$(dirname "$0")/.." && pwd)/build
R=${RAYSCAN:-$B/tools/rayscan}
cd "$scratch" || exit 2
name=s$n
stamp() { echo "[$(date -u +%T) load $(cut -d' ' -f1-3 /proc/loadavg) avail $(df -BM --output=avail . | tail -1 | tr -d ' ')] $*"; }

# sample PID LOG: peaks of RssAnon / RssFile and the minimum free space while PID runs.
sample() {
  local pid=$1 pa=0 pf=0 fmin=999999999 a f d
  while kill -0 "$pid" 2>/dev/null; do
    a=$(awk '/RssAnon/{print $2}' /proc/$pid/status 2>/dev/null); f=$(awk '/RssFile/{print $2}' /proc/$pid/status 2>/dev/null)
    d=$(df -BM --output=avail . | tail -1 | tr -dc '0-9')
    [ -n "$a" ] && [ "$a" -gt "$pa" ] && pa=$a
    [ -n "$f" ] && [ "$f" -gt "$pf" ] && pf=$f
    [ -n "$d" ] && [ "$d" -lt "$fmin" ] && fmin=$d
    if [ "$del" = 1 ] && [ -e "$name.las" ] && tr '\r' '\n' < index.progress 2>/dev/null | grep -q '^index: merge'; then
      rm -f "$name.las"; stamp "read pass over: deleted $name.las"
    fi
    sleep 0.5
  done
  echo "peak RssAnon=$((pa / 1024)) MiB peak RssFile=$((pf / 1024)) MiB min free=${fmin} MiB"
}

stamp "df: $(df -h . | tail -1)"
if [ ! -e "$name.las" ] && [ ! -e "$name.rsi" ]; then
  stamp "make_site $name.las $n --pdrf $pdrf"
  /usr/bin/time -f "make_site wall=%e s user=%U s sys=%S s maxrss=%M KiB" nice ionice -c3 "$B/bench/make_site" "$name.las" "$n" --pdrf "$pdrf"
fi
if [ ! -e "$name.rsi" ]; then
  stamp "index $name.las --memory $mem --attributes $attrs"
  /usr/bin/time -f "index wall=%e s user=%U s sys=%S s maxrss=%M KiB" -o index.time \
    nice ionice -c3 "$R" index "$name.las" -o "$name.rsi" --memory "$mem" --attributes "$attrs" 2> index.progress &
  ipid=$!
  sleep 0.2
  pid=$(pgrep -P "$ipid" -n); pid=$(pgrep -P "${pid:-$ipid}" -n || echo "$pid")  # time -> nice/ionice exec -> rayscan
  ( last=""; while kill -0 "$ipid" 2>/dev/null; do
      ph=$(tr '\r' '\n' < index.progress | grep -o 'index: [a-z]*' | tail -1)
      [ -n "$ph" ] && [ "$ph" != "$last" ] && stamp "phase: $ph" && last=$ph
      sleep 1; done ) &
  sample "$pid"
  wait "$ipid"; stamp "index rc=$?"; cat index.time
  tr '\r' '\n' < index.progress | grep -v '^index: ' | grep -v '^$'
  ls -l "$name.rsi"
  "$R" info "$name.rsi"
fi
if [ "$attrs" = none ] || [[ "$attrs" != *rgb* ]]; then color='"color": "elevation", "ramp": "terrain", "range": [400, 520]'; else color='"color": "rgb"'; fi
cat > "$name.json" <<EOF
{ "cloud": "$name.rsi", "radius": $radius, "material": {$color},
  "background": {"type": "gradient", "horizon": [1.0, 1.0, 1.0], "zenith": [0.5, 0.7, 1.0], "intensity": 0.6},
  "sun": {"azimuth_deg": 210, "elevation_deg": 35, "irradiance": 2.5},
  "camera": {"width": 600, "height": 400, "position": [636900, 847500, 1900], "look_at": [638356, 850060, 460], "up": [0, 0, 1], "vfov_deg": 42},
  "spp": $spp, "max_depth": 3, "seed": 1, "output": {"image": "$name.png"} }
EOF
stamp "render $name.json ($spp spp)"
start=$(date +%s.%N)
nice "$R" render "$name.json" > render.log 2>&1 &
rpid=$!
sample "$rpid"
wait "$rpid"; rc=$?
stamp "render rc=$rc wall=$(echo "$(date +%s.%N) - $start" | bc) s"
tr '\r' '\n' < render.log | grep "rayscan render" | grep -v tiles
