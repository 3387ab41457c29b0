"""Compares what CloudCompare (its ASC export) and Open3D read from a rayscan PLY file with the
file's own bytes (parsed here from the PLY header with numpy). Every vertex property must be
loaded by both tools with its values. Usage: check_ply.py FILE.ply CLOUDCOMPARE_EXPORT.asc"""
import sys

import numpy as np
import open3d as o3d

TYPES = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4", "uint": "<u4",
         "float": "<f4", "double": "<f8"}


def read_ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    names, dtype, count = [], [], 0
    for line in data[:end].decode().splitlines():
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            count = int(w[2])
        elif w and w[0] == "property":
            names.append(w[2])
            dtype.append((w[2], TYPES[w[1]]))
        elif w and w[0] == "format":
            assert w[1] == "binary_little_endian", w
    arr = np.frombuffer(data, dtype=np.dtype(dtype), count=count, offset=end)
    return names, arr


def close(a, b, rel=1e-6):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= rel * np.maximum(1.0, np.abs(a))))


def main():
    ply, asc = sys.argv[1], sys.argv[2]
    names, arr = read_ply(ply)
    failures = []
    print(f"{ply}: {len(arr)} points, properties: {' '.join(names)}")

    # CloudCompare: the ASC export's header names every column it loaded.
    with open(asc) as f:
        header = f.readline().lstrip("/").split()
    cc = np.loadtxt(asc, comments="//", ndmin=2)
    col = {n: i for i, n in enumerate(header)}
    cc_name = {"x": "X", "y": "Y", "z": "Z", "red": "R", "green": "G", "blue": "B"}
    for n in names:
        c = cc_name.get(n, n[7:] if n.startswith("scalar_") else n)
        if c not in col:
            failures.append(f"CloudCompare did not load property '{n}' (columns: {' '.join(header)})")
        elif n in ("x", "y", "z"):
            # CloudCompare stores coordinates as float32 after its global shift: within 1 mm.
            if not np.all(np.abs(arr[n] - cc[:, col[c]]) <= 1e-3):
                failures.append(f"CloudCompare changed the values of '{n}' by more than 1 mm")
        elif not close(arr[n], cc[:, col[c]], 1e-6):  # scalar fields: float32 in CloudCompare
            failures.append(f"CloudCompare changed the values of '{n}'")
    print(f"CloudCompare columns: {' '.join(header)}")

    # Open3D (tensor API): positions, colors and one attribute per other property.
    pc = o3d.t.io.read_point_cloud(ply)
    attrs = {k: pc.point[k].numpy() for k in pc.point}
    print(f"Open3D attributes: {' '.join(sorted(attrs))}")
    if not close(np.stack([arr["x"], arr["y"], arr["z"]], 1), attrs.get("positions", np.zeros(0)), 0):
        failures.append("Open3D positions differ")
    if "red" in names and not close(np.stack([arr["red"], arr["green"], arr["blue"]], 1), attrs.get("colors", np.zeros(0)), 0):
        failures.append("Open3D colors differ")
    for n in names:
        if n in ("x", "y", "z", "red", "green", "blue"):
            continue
        if n not in attrs:
            failures.append(f"Open3D did not load property '{n}'")
        elif not close(arr[n], attrs[n].ravel(), 0):
            failures.append(f"Open3D changed the values of '{n}'")
    for f in failures:
        print("FAIL:", f)
    print("ok" if not failures else f"{len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
