#!/usr/bin/env python3
"""Draws docs/gallery/solar_vs_rsun.png: rayscan's yearly map of autzen_trim and its difference
from GRASS r.sun on rayscan's own DSM, the comparison of the test
SolarDsmRsun.YearlyGlobalOfOpenTerrainCellsMatchesGrassRsunOnRayscansOwnDsm
(tests/analysis/test_solar_dsm.cpp), shown in docs/solar.md.

Usage: docs/gallery/make_solar_vs_rsun.py [BUILD_DIR]   (default: build; one to two minutes)

It runs what the test runs, with the test's settings: `rayscan render --ortho-map 3 --dsm`,
tests/analysis/rsun_dsm.sh (r.sun, the 15th of each month weighted by the month's days, 30 min,
Linke 3, albedo 0.2) and `rayscan solar` on the same 12 days, one thread. Open terrain is the
test's: ground (top point within 1 ft of the cell's highest class-2 point or of the lowest point of
it and its 8 neighbours), DSM slope (Horn) under 15 degrees, DSM horizon (32 azimuths, 100 ft)
under 20 degrees. The script prints the open-terrain figures it puts in the title; they are the
test's own printed figures computed a second time, so the two must agree.

Needs numpy and matplotlib (with its Pillow), `grass` (Debian grass-core) and GDAL's command line
tools (gdal-bin). Exit status 2 when BUILD_DIR has no rayscan, 1 when a command fails.
"""
import io
import json
import math
import os
import re
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402 (matplotlib's own dependency)

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = os.path.join(SOURCE, "docs", "gallery", "solar_vs_rsun.png")
CLOUD = os.path.join(SOURCE, "scenes", "data", "autzen_trim.las")
FOOT = 0.3048  # autzen's CRS unit (international foot), metres
CELL = 3.0  # feet
MONTH_DAYS = [31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31]
YEAR, LINKE, ALBEDO = 2026, 3.0, 0.2
GROUND_TOLERANCE, MAX_SLOPE, MAX_HORIZON, HORIZON_REACH, TOLERANCE = 1.0, 15.0, 20.0, 100.0, 0.05


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def read_grid(path, work):
    """A single-band raster as (float64 array, top row first, NoData -> NaN; origin x, top y, cell)."""
    info = json.loads(subprocess.run(["gdalinfo", "-json", path], check=True, capture_output=True, text=True).stdout)
    cols, rows = info["size"]
    x0, dx, _, y_top, _, dy = info["geoTransform"]
    raw = os.path.join(work, "grid.bin")
    run(["gdal_translate", "-q", "-of", "ENVI", "-ot", "Float64", path, raw])
    v = np.fromfile(raw, dtype="<f8").reshape(rows, cols)
    nodata = info["bands"][0].get("noDataValue")
    if nodata is not None:
        v[v == nodata] = np.nan
    v[~np.isfinite(v)] = np.nan
    assert dx == -dy, path
    return v, (x0, y_top, dx)


def lround(x):
    return np.sign(x) * np.floor(np.abs(x) + 0.5)


def percentile(v, p):
    """The test's percentile: the element of rank lround(p (n - 1))."""
    if v.size == 0:
        return math.nan
    k = min(v.size - 1, int(lround(p * (v.size - 1))))
    return float(np.partition(v, k)[k])


def shifted(a, dr, dc, fill):
    """a[r + dr, c + dc] at [r, c], `fill` outside the grid."""
    out = np.full_like(a, fill)
    rows, cols = a.shape
    if abs(dr) >= rows or abs(dc) >= cols:
        return out
    out[max(0, -dr):rows - max(0, dr), max(0, -dc):cols - max(0, dc)] = a[max(0, dr):rows - max(0, -dr),
                                                                          max(0, dc):cols - max(0, -dc)]
    return out


def open_terrain(dsm, grid, points):
    """The test's open-terrain cells (boolean, the DSM's shape)."""
    rows, cols = dsm.shape
    x0, y_top, c = grid
    x, y, z, cls = points
    col = np.floor(x / c).astype(np.int64) - int(round(x0 / c))
    row = int(round(y_top / c)) - 1 - np.floor(y / c).astype(np.int64)
    inside = (col >= 0) & (row >= 0) & (col < cols) & (row < rows)
    k = row[inside] * cols + col[inside]
    z, cls = z[inside], cls[inside]
    top = np.full(rows * cols, -np.inf)
    low = np.full(rows * cols, np.inf)
    ground = np.full(rows * cols, -np.inf)
    np.maximum.at(top, k, z)
    np.minimum.at(low, k, z)
    np.maximum.at(ground, k[cls == 2], z[cls == 2])
    top, low, ground = top.reshape(rows, cols), low.reshape(rows, cols), ground.reshape(rows, cols)

    # Horn's slope where all nine cells are valid.
    zz = [[shifted(dsm, i - 1, j - 1, np.nan) for j in range(3)] for i in range(3)]
    gx = ((zz[0][2] + 2 * zz[1][2] + zz[2][2]) - (zz[0][0] + 2 * zz[1][0] + zz[2][0])) / (8 * c)
    gy = ((zz[2][0] + 2 * zz[2][1] + zz[2][2]) - (zz[0][0] + 2 * zz[0][1] + zz[0][2])) / (8 * c)
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))

    # Horizon: steps move monotonically outwards, so skipping cells past the edge is the test's break.
    horizon = np.full(dsm.shape, -90.0)
    for a in range(32):
        az = 2 * math.pi * a / 32
        for s in range(1, int(HORIZON_REACH / c) + 1):
            dq, dr = int(lround(math.sin(az) * s)), -int(lround(math.cos(az) * s))
            angle = np.degrees(np.arctan((shifted(dsm, dr, dq, np.nan) - dsm) / (s * c)))
            horizon = np.fmax(horizon, angle)
    horizon[~np.isfinite(dsm)] = np.nan

    def lowest_within(reach):
        pad = np.pad(low, reach, constant_values=np.inf)
        return np.lib.stride_tricks.sliding_window_view(pad, (2 * reach + 1, 2 * reach + 1)).min(axis=(2, 3))

    with np.errstate(invalid="ignore"):
        by_class = np.isfinite(ground) & (top - ground <= GROUND_TOLERANCE)
        by_height = top - lowest_within(1) <= GROUND_TOLERANCE
        flat = np.isfinite(slope) & (slope < MAX_SLOPE)
        unobstructed = horizon < MAX_HORIZON
    return (by_class | by_height) & flat & unobstructed


def main():
    build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(SOURCE, "build")
    rayscan = os.path.join(build, "tools", "rayscan")
    if not os.access(rayscan, os.X_OK):
        print(f"make_solar_vs_rsun: no rayscan executable at {rayscan} (give the build folder)", file=sys.stderr)
        sys.exit(2)
    with tempfile.TemporaryDirectory(prefix="solar_vs_rsun_") as work:
        dsm_file = os.path.join(work, "dsm.tif")
        run([rayscan, "render", "-q", CLOUD, "--ortho-map", "3", "--dsm", dsm_file, "--out",
             os.path.join(work, "ortho.tif")])
        days, day = [], 0
        for n in MONTH_DAYS:
            days.append(f"{day + 15}:{n}")
            day += n
        run(["bash", os.path.join(SOURCE, "tests", "analysis", "rsun_dsm.sh"), dsm_file, os.path.join(work, "rsun"),
             " ".join(days), f"{LINKE:g}", f"{ALBEDO:g}", "0.5"])
        dsm, grid = read_grid(dsm_file, work)
        assert grid[2] == CELL, grid
        rsun, rsun_grid = read_grid(os.path.join(work, "rsun", "rsun_global.tif"), work)
        assert rsun_grid == grid and rsun.shape == dsm.shape, "r.sun's raster is not on the DSM's grid"
        ours = np.zeros_like(dsm)
        csv = os.path.join(work, "points.csv")
        for m in range(1, 13):
            out = os.path.join(work, f"rs_{m:02d}.tif")
            date = f"{YEAR:04d}-{m:02d}-15"
            run([rayscan, "solar", CLOUD, "--start", date, "--end", date, "--step", "30min", "--linke", f"{LINKE:g}",
                 "--albedo", f"{ALBEDO:g}", "--raster", out, "--cell", "3", "--raster-value", "global",
                 "--no-preview", "--threads", "1", "-q"] + (["-o", csv] if m == 1 else []))
            g, g_grid = read_grid(out, work)
            assert g_grid == grid and g.shape == dsm.shape, f"{out} is not on the DSM's grid"
            ours += MONTH_DAYS[m - 1] * g
        with open(csv) as f:
            header = f.readline().strip().split(",")
        cols = [header.index(name) for name in ("x", "y", "z", "classification")]
        points = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=cols, unpack=True)

    with np.errstate(invalid="ignore", divide="ignore"):
        valid = np.isfinite(ours) & np.isfinite(rsun) & (rsun > 0)
        rel = np.where(valid, (ours - rsun) / rsun, np.nan)
    opened = open_terrain(dsm, grid, points) & valid
    r = rel[opened]
    within, median = float(np.mean(np.abs(r) <= TOLERANCE)), percentile(r, 0.5)
    print(f"open terrain: {r.size} cells, {100 * within:.1f} % within 5 %, median {100 * median:+.2f} %")
    # `grass --version` prints "GRASS GIS 8.2.1" and its licence, on stderr.
    grass = subprocess.run(["grass", "--version"], check=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True).stdout
    version = re.search(r"GRASS GIS (\S+)", grass)
    draw(dsm, ours, rel, opened, f"GRASS {version[1] if version else '?'}, on rayscan's DSM",
         f"open terrain: {100 * within:.1f} % of {r.size} cells within 5 %, median {100 * median:+.2f} %", OUT)
    print(f"solar_vs_rsun: wrote {OUT}")


def draw(dsm, ours, rel, opened, rsun_what, summary, out):
    """The two panels: rayscan's yearly map (kWh/m2) and rel (fraction of r.sun), over the DSM's cells."""
    # Metres from the grid's lower-left corner (the CRS is in feet).
    rows, cols = dsm.shape
    extent = [0, cols * CELL * FOOT, 0, rows * CELL * FOOT]
    surface = np.ma.masked_where(~np.isfinite(dsm), np.ones_like(dsm))
    fig, (top_ax, bottom_ax) = plt.subplots(2, 1, figsize=(8.1, 8.2), dpi=100, layout="constrained")
    for ax in (top_ax, bottom_ax):
        ax.imshow(surface, cmap="gray", vmin=0, vmax=1.25, extent=extent, interpolation="nearest")
        ax.set_xlabel("m east")
        ax.set_ylabel("m north")
    im = top_ax.imshow(np.ma.masked_invalid(ours), cmap="inferno", extent=extent, interpolation="nearest",
                       vmin=0, vmax=2300)
    top_ax.set_title("rayscan solar: yearly global irradiation of each cell's highest point (kWh/m², clear sky)\n"
                     "grey: a cell of rayscan's DSM without a value here", fontsize=10)
    fig.colorbar(im, ax=top_ax, label="kWh/m² per year", extend="max")
    bounds = [-50, -20, -10, -5, -2, 2, 5, 10, 20, 50]
    im = bottom_ax.imshow(np.ma.masked_invalid(100 * rel), cmap="RdBu_r", extent=extent, interpolation="nearest",
                          norm=mcolors.BoundaryNorm(bounds, 256, extend="both"))
    bottom_ax.contour(opened.astype(float), levels=[0.5], colors="black", linewidths=0.6, origin="upper",
                      extent=extent)
    bottom_ax.set_title(f"rayscan − r.sun ({rsun_what}), % of r.sun; black: open terrain\n{summary}", fontsize=10)
    fig.colorbar(im, ax=bottom_ax, label="% difference", extend="both")
    # A 256-colour palette: the figure has under 2,000 colours, and it keeps the PNG near 100 KB.
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=100, format="png")
    plt.close(fig)
    rgb = Image.open(buffer).convert("RGB")
    rgb.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(out, optimize=True)


if __name__ == "__main__":
    try:
        main()
    except (subprocess.CalledProcessError, FileNotFoundError) as e:
        print(f"make_solar_vs_rsun: {e}", file=sys.stderr)
        sys.exit(1)
