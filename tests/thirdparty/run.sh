#!/usr/bin/env bash
# Third-party readers open rayscan's PLY output with every field: CloudCompare
# (Debian `cloudcompare`, command line under `xvfb-run`) and Open3D (Debian `python3-open3d`).
# The oracle is the PLY file's own bytes, parsed here with numpy from its header. Then Open3D
# reads rayscan's PCD output (check_pcd.py): double coordinates (a georeferenced LAS) through its
# tensor reader, float ones (a depth camera's PCD) through its legacy reader too, and a visibility
# output whose header describes its fields in comment lines through the tensor reader with them.
# Exit 0 = pass, 1 = a tool missed or changed a field, 77 = skipped (a tool is not installed;
# CTest reports the test as skipped and prints the reason).
# Usage: tests/thirdparty/run.sh RAYSCAN_EXE
set -u
RAYSCAN="$1"
HERE="$(cd "$(dirname "$0")" && pwd)"
PY=/usr/bin/python3  # Debian's interpreter: python3-open3d and python3-numpy live there
W="$(mktemp -d)"
trap 'rm -rf "$W"' EXIT
missing=""
command -v CloudCompare >/dev/null || missing="$missing CloudCompare (apt-get install cloudcompare)"
command -v xvfb-run >/dev/null || missing="$missing xvfb-run (apt-get install xvfb)"
"$PY" -c 'import open3d' 2>/dev/null || missing="$missing open3d (apt-get install python3-open3d)"
if [ -n "$missing" ]; then
  echo "SKIP: third-party tools missing:$missing"
  exit 77
fi
SRC="$HERE/../data/las/point-color-time.las"
# A derived cloud with LAS fields, colour, intensity, classification, GPS time and new fields.
obs=$("$PY" -c "
import struct,sys
b=open('$SRC','rb').read()
mx,mn,my,ny_,mz,nz=struct.unpack('<6d',b[179:227])
print(f'{(mx+mn)/2},{(my+ny_)/2},{mz+10}')")
"$RAYSCAN" visibility -q "$SRC" --observer "$obs" --distance -o "$W/v.ply" || exit 1
(cd "$W" && timeout 120 xvfb-run -a CloudCompare -SILENT -O -GLOBAL_SHIFT AUTO v.ply -C_EXPORT_FMT ASC -ADD_HEADER -SAVE_CLOUDS > cc.log 2>&1)
asc=$(ls "$W"/v_*.asc 2>/dev/null | head -n 1)
[ -n "$asc" ] || { echo "FAIL: CloudCompare wrote no ASC export"; cat "$W/cc.log"; exit 1; }
"$PY" "$HERE/check_ply.py" "$W/v.ply" "$asc" || exit 1
"$RAYSCAN" translate "$SRC" "$W/geo.pcd" > /dev/null || exit 1
"$RAYSCAN" translate "$HERE/../data/pcd/milk.pcd" "$W/cam.pcd" > /dev/null || exit 1
# The text oracle is written from the PCD as our reader reads it: from the LAS directly, text
# prints the LAS grid's decimals (849087.70), which read back as a neighbouring double.
"$RAYSCAN" translate "$W/geo.pcd" "$W/geo.xyz" > /dev/null || exit 1
"$RAYSCAN" translate "$HERE/../data/pcd/milk.pcd" "$W/cam.xyz" > /dev/null || exit 1
# The analysis fields described in '#' comment lines of the PCD header (their units), against
# our text export of that PCD.
"$RAYSCAN" visibility -q "$SRC" --observer "$obs" --distance -o "$W/v.pcd" || exit 1
"$RAYSCAN" translate "$W/v.pcd" "$W/v.xyz" > /dev/null || exit 1
"$PY" "$HERE/check_pcd.py" "$W/geo.pcd" "$W/geo.xyz" "$W/cam.pcd" "$W/cam.xyz" "$W/v.pcd" "$W/v.xyz"
