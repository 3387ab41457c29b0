#!/usr/bin/python3
"""rayscan's default viewshed against gdal_viewshed and GRASS r.viewshed on rayscan's own DSM.

The protocol of docs/visibility.md: `rayscan render CLOUD --ortho-map CELL --dsm dsm.tif`, then per
observer `gdal_viewshed -oz EYE -tz 0 -cc 0`, GRASS `r.viewshed -b observer_elevation=EYE
target_elevation=0` (in a temporary GRASS location made from the DSM) and `rayscan visibility
--observer X,Y --height EYE --raster --cell CELL` (its defaults); prints, per observer, the
pairwise agreement on the cells valid in all three rasters and each one's visible share. Needs
numpy, gdal-bin and grass-core (Debian). Figures: bench/notes/2026-11-27-viewshed-on-the-dsm.md.

usage: bench/viewshed_vs_tools.py RAYSCAN CLOUD WORKDIR [--cell 3] [--eye 6] --observer X,Y [...]
"""
import argparse
import os
import subprocess

import numpy as np

from viewshed_vs_gdal import read_tif


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rayscan")
    ap.add_argument("cloud")
    ap.add_argument("work")
    ap.add_argument("--cell", type=float, default=3.0)
    ap.add_argument("--eye", type=float, default=6.0)
    ap.add_argument("--observer", action="append", required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    work = os.path.abspath(a.work)

    def sh(cmd):
        subprocess.run(cmd, shell=True, check=True, cwd=work, stdout=subprocess.DEVNULL)

    def band(name):  # the raster as floats, NaN for NoData (the GDAL script's reader)
        return read_tif(os.path.join(work, name), work)

    cloud = os.path.abspath(a.cloud)
    a.rayscan = os.path.abspath(a.rayscan)
    sh(f"{a.rayscan} render -q {cloud} --ortho-map {a.cell} --dsm dsm.tif --out ortho.tif")
    dsm = band("dsm.tif")
    obs = [tuple(float(v) for v in o.split(",")) for o in a.observer]
    with open(os.path.join(work, "grass.sh"), "w") as f:
        f.write(f"set -e\nr.in.gdal --q -o input={work}/dsm.tif output=dsm\ng.region raster=dsm\n")
        for i, (x, y) in enumerate(obs):
            f.write(f"r.viewshed -b --o --q input=dsm output=vs{i} coordinates={x},{y} "
                    f"observer_elevation={a.eye} target_elevation=0\n"
                    f"r.out.gdal --q -f --o input=vs{i} output={work}/grass{i}.tif format=GTiff\n")
    sh("rm -rf location && grass -c dsm.tif location -e && grass location/PERMANENT --exec bash grass.sh > grass.log 2>&1")
    print("| observer | cells | rayscan~gdal | rayscan~grass | gdal~grass | visible: rayscan / gdal / grass |")
    for i, (x, y) in enumerate(obs):
        sh(f"gdal_viewshed -q -ox {x} -oy {y} -oz {a.eye} -tz 0 -cc 0 -vv 1 -iv 0 -ov 0 dsm.tif gdal{i}.tif")
        sh(f"{a.rayscan} visibility -q {cloud} --observer {x},{y} --height {a.eye} --raster v{i}.tif "
           f"--cell {a.cell} --no-preview")
        g, r, v = band(f"gdal{i}.tif") > 0.5, band(f"grass{i}.tif"), band(f"v{i}.tif")
        ok = ~np.isnan(dsm) & ~np.isnan(v) & ~np.isnan(r)
        r, v = r > 0.5, v > 0.5
        pct = lambda m: 100.0 * np.mean(m[ok])
        print(f"| ({x}, {y}) | {ok.sum()} | {pct(v == g):.1f}% | {pct(v == r):.1f}% | {pct(g == r):.1f}% | "
              f"{pct(v):.1f} / {pct(g):.1f} / {pct(r):.1f}% |", flush=True)


if __name__ == "__main__":
    main()
