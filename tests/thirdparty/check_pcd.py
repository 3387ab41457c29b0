"""Open3D reads rayscan's PCD output: positions and colours equal rayscan's own text export of the
same cloud (shortest round-trip decimals: the oracle is independent of the PCD bytes).
Usage: check_pcd.py GEO.pcd GEO.xyz CAM.pcd CAM.xyz VIS.pcd VIS.xyz  (GEO: double coordinates, CAM:
float, VIS: a visibility output, whose header has '#' comment lines describing visible_count and
visible_distance: those fields too)."""
import sys

import numpy as np
import open3d as o3d


def text_cloud(path):
    with open(path) as f:
        names = f.readline().split()
    data = np.loadtxt(path, skiprows=1, ndmin=2)
    return names, data


def check(pcd, xyz, legacy, fields=()):
    names, data = text_cloud(xyz)
    want = data[:, :3]
    t = o3d.t.io.read_point_cloud(pcd)
    got = t.point.positions.numpy().astype(np.float64)
    if got.shape != want.shape or not np.array_equal(got, want):
        print(f"FAIL: {pcd}: Open3D's tensor reader gives other positions than {xyz}")
        return False
    if "red" in names:
        # The text columns hold the source's colour values: 8-bit ones as they are (all <= 255,
        # the readers' rule, docs/formats.md), else 16-bit ones, which the PCD stores rounded.
        rgb = data[:, names.index("red"):names.index("red") + 3]
        want8 = rgb if rgb.max() <= 255 else np.floor((rgb + 128) / 257)
        got8 = t.point.colors.numpy().astype(np.float64)
        if got8.max() <= 1.0:  # some Open3D versions give colours in [0, 1]
            got8 = np.round(got8 * 255)
        if not np.array_equal(got8, want8):
            print(f"FAIL: {pcd}: colours differ from {xyz}")
            return False
    for name in fields:
        if name not in t.point:
            print(f"FAIL: {pcd}: Open3D's tensor reader has no field {name}")
            return False
        got = t.point[name].numpy().astype(np.float64).ravel()
        if not np.array_equal(got, data[:, names.index(name)]):
            print(f"FAIL: {pcd}: field {name} differs from {xyz}")
            return False
    if legacy:
        p = np.asarray(o3d.io.read_point_cloud(pcd).points)
        if not np.array_equal(p, want):
            print(f"FAIL: {pcd}: Open3D's legacy reader gives other positions than {xyz}")
            return False
    print(f"ok: {pcd}: {len(want)} points, positions{' and colours' if 'red' in names else ''}"
          f"{''.join(', ' + n for n in fields)} as in {xyz}")
    return True


ok = (check(sys.argv[1], sys.argv[2], legacy=False) and check(sys.argv[3], sys.argv[4], legacy=True)
      and check(sys.argv[5], sys.argv[6], legacy=False, fields=("visible_count", "visible_distance")))
sys.exit(0 if ok else 1)
