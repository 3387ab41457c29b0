#!/usr/bin/python3
"""rayscan visibility against gdal_viewshed on a real scan.

The protocol: a DSM of CELL-sized cells (max z per cell, gaps filled by repeated
4-neighbour averaging), one observer EYE above the ground, `gdal_viewshed -oz EYE -tz 0 -cc 0`;
then `rayscan visibility --raster-value viewshed --cell CELL` on the same cloud (same grid: rayscan
snaps its grid to whole cells, and so does this DSM), and the share of the cells that contain points
on which the two agree. Needs only numpy and the GDAL command-line tools (no Python GDAL binding).

usage: bench/viewshed_vs_gdal.py RAYSCAN CLOUD.las WORKDIR [--cell 3] [--eye 6] [--observer X,Y ...]
Prints, per observer, gdal's visible fraction and one line per rayscan mode. --observer may be
repeated; without it the lowest cell near the XY centre is used (on autzen that is a pit by the
river where gdal sees 0.1% of the cells: give observers on open ground). Figures: bench/README.md. LAS 1.0-1.4 point data records are read directly (X, Y, Z
int32 at offsets 0, 4, 8 of each record; LAS 1.4 specification, section 2.6 and table 7).
"""
import argparse
import os
import struct
import subprocess
import sys

import numpy as np


def read_las_xyz(path):
    with open(path, "rb") as f:
        h = f.read(375)
    if h[:4] != b"LASF":
        sys.exit(f"{path}: not a LAS file")
    offset = struct.unpack_from("<I", h, 96)[0]
    rec_len = struct.unpack_from("<H", h, 105)[0]
    count = struct.unpack_from("<I", h, 107)[0]
    if count == 0 and h[25] >= 4:
        count = struct.unpack_from("<Q", h, 247)[0]
    scale = struct.unpack_from("<3d", h, 131)
    off = struct.unpack_from("<3d", h, 155)
    raw = np.fromfile(path, dtype=np.uint8, count=offset + count * rec_len)[offset:]
    rec = raw.reshape(count, rec_len)
    xyz = rec[:, :12].copy().view("<i4").reshape(count, 3).astype(np.float64)
    return xyz * np.array(scale) + np.array(off)


def write_aaigrid(path, grid, x0, y0, cell, nodata=-9999.0):
    rows, cols = grid.shape
    with open(path, "w") as f:
        f.write(f"ncols {cols}\nnrows {rows}\nxllcorner {x0!r}\nyllcorner {y0!r}\ncellsize {cell!r}\n"
                f"NODATA_value {nodata}\n")
        np.savetxt(f, np.where(np.isnan(grid), nodata, grid), fmt="%.3f")


def read_tif(path, work):
    asc = os.path.join(work, os.path.basename(path) + ".asc")
    subprocess.run(["gdal_translate", "-q", "-of", "AAIGrid", path, asc], check=True)
    with open(asc) as f:
        header = {}
        for _ in range(5):
            k, v = f.readline().split()
            header[k.lower()] = float(v)
        line = f.readline()
        if line.lower().startswith("nodata"):
            header["nodata_value"] = float(line.split()[1])
            data = np.loadtxt(f)
        else:
            data = np.loadtxt([line] + f.readlines())
    data = np.atleast_2d(data)
    if "nodata_value" in header:
        data = np.where(data == header["nodata_value"], np.nan, data)
    return data


def exact_los(filled, has_points, x0, ytop, c, ox, oy, eye, steps=200):
    """A second oracle: an exact line of sight on the same DSM, for each cell with points, from the
    observer's cell (DSM + eye) to the cell's centre at its DSM height, sampling the nearest cell
    every 1/steps of the way (the two end cells excluded); blocked where the DSM is above the line."""
    rows, cols = filled.shape
    oc, orow = int((ox - x0) // c), int((ytop - oy) // c)
    oz = filled[orow, oc] + eye
    r, cc = np.nonzero(has_points)
    tx, ty, tz = x0 + (cc + 0.5) * c, ytop - (r + 0.5) * c, filled[r, cc]
    sx, sy = x0 + (oc + 0.5) * c, ytop - (orow + 0.5) * c
    vis = np.ones(len(r), bool)
    for s in np.linspace(0.0, 1.0, steps + 1)[1:-1]:
        px, py, pz = sx + (tx - sx) * s, sy + (ty - sy) * s, oz + (tz - oz) * s
        pc, pr = np.floor((px - x0) / c).astype(int), np.floor((ytop - py) / c).astype(int)
        inside = (pc >= 0) & (pc < cols) & (pr >= 0) & (pr < rows)
        h = np.where(inside, filled[np.clip(pr, 0, rows - 1), np.clip(pc, 0, cols - 1)], -np.inf)
        own = ((pr == r) & (pc == cc)) | ((pr == orow) & (pc == oc))
        vis &= ~((h > pz) & ~own)
    out = np.zeros(filled.shape, bool)
    out[r, cc] = vis
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rayscan")
    ap.add_argument("cloud")
    ap.add_argument("work")
    ap.add_argument("--cell", type=float, default=3.0)
    ap.add_argument("--eye", type=float, default=6.0)
    ap.add_argument("--observer", action="append", default=[],
                    help="X,Y, repeatable (default: the lowest cell near the XY centre)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    xyz = read_las_xyz(a.cloud)
    c = a.cell
    x0 = np.floor(xyz[:, 0].min() / c) * c
    ytop = (np.floor(xyz[:, 1].max() / c) + 1) * c
    cols = int(np.floor(xyz[:, 0].max() / c) - np.floor(xyz[:, 0].min() / c)) + 1
    rows = int(np.floor(ytop / c - 1e-9) - np.floor(xyz[:, 1].min() / c)) + 1
    col = (np.floor(xyz[:, 0] / c) - np.floor(xyz[:, 0].min() / c)).astype(int)
    row = (np.floor(xyz[:, 1].max() / c) - np.floor(xyz[:, 1] / c)).astype(int)
    dsm = np.full((rows, cols), -np.inf)
    np.maximum.at(dsm, (row, col), xyz[:, 2])
    has_points = np.isfinite(dsm)
    dsm[~has_points] = np.nan
    filled = dsm.copy()
    while np.isnan(filled).any():  # gaps: mean of the known 4-neighbours, repeated
        p = np.pad(filled, 1, constant_values=np.nan)
        nb = np.stack([p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]])
        cnt = np.sum(~np.isnan(nb), axis=0)
        mean = np.where(cnt > 0, np.nansum(nb, axis=0) / np.maximum(cnt, 1), np.nan)
        filled = np.where(np.isnan(filled), mean, filled)
    dsm_path = os.path.join(a.work, "dsm.asc")
    write_aaigrid(dsm_path, filled, x0, ytop - rows * c, c)
    observers = [tuple(float(v) for v in o.split(",")) for o in a.observer]
    if not observers:
        cx, cy = (xyz[:, 0].min() + xyz[:, 0].max()) / 2, (xyz[:, 1].min() + xyz[:, 1].max()) / 2
        # the lowest cell near the centre: open ground, not a roof
        r0, c0 = int((ytop - cy) // c), int((cx - x0) // c)
        win = filled[max(0, r0 - 10):r0 + 11, max(0, c0 - 10):c0 + 11]
        rr, cc = np.unravel_index(np.nanargmin(win), win.shape)
        rr += max(0, r0 - 10)
        cc += max(0, c0 - 10)
        observers = [(x0 + (cc + 0.5) * c, ytop - (rr + 0.5) * c)]
    print(f"cloud {a.cloud}: {len(xyz)} points; DSM {cols} x {rows} cells of {c}, {has_points.sum()} with points")
    for ox, oy in observers:
        gdal_out = os.path.join(a.work, "gdal.tif")
        subprocess.run(["gdal_viewshed", "-q", "-ox", repr(ox), "-oy", repr(oy), "-oz", repr(a.eye), "-tz", "0",
                        "-cc", "0", "-vv", "1", "-iv", "0", "-ov", "0", dsm_path, gdal_out], check=True)
        gv = read_tif(gdal_out, a.work) > 0.5
        print(f"observer ({ox:.2f}, {oy:.2f}) eye {a.eye}: gdal_viewshed {100 * gv[has_points].mean():.1f}% visible")
        los = exact_los(filled, has_points, x0, ytop, c, ox, oy, a.eye)
        print(f"  exact line of sight on the same DSM (second oracle): agrees with gdal_viewshed on "
              f"{100 * np.mean(los[has_points] == gv[has_points]):.1f}% ({100 * los[has_points].mean():.1f}% visible)")
        for name, extra in [("surfel, target height 0", ["--primitive", "surfel"]),
                            ("sphere, target height 0", ["--primitive", "sphere", "--target-height", "0"]),
                            ("sphere, target height r (default)", ["--primitive", "sphere"])]:
            out = os.path.join(a.work, "rayscan.tif")
            subprocess.run([a.rayscan, "visibility", a.cloud, "--observer", f"{ox!r},{oy!r}", "--height",
                            repr(a.eye), "--raster", out, "--cell", repr(c), "--raster-value", "viewshed",
                            "--no-preview", "-q"] + extra, check=True, stdout=subprocess.DEVNULL)
            rv = read_tif(out, a.work)
            if rv.shape != gv.shape:
                sys.exit(f"grid mismatch: rayscan {rv.shape}, DSM {gv.shape}")
            m = has_points & ~np.isnan(rv)
            agree = np.mean((rv[m] > 0.5) == gv[m])
            print(f"  rayscan {name}: agrees on {100 * agree:.1f}% of the cells with points "
                  f"(rayscan {100 * np.mean(rv[m] > 0.5):.1f}% visible)")

if __name__ == "__main__":
    main()
