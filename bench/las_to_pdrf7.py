#!/usr/bin/python3
"""las_to_pdrf7.py IN.las OUT.las [COPY_POINTS]: rewrites a LAS 1.2 PDRF 3 file (bench/make_site's
output) as LAS 1.4 PDRF 7 with the same points in the same order (ASPRS LAS 1.4 R15 tables 10
and 13: return bits widened, classification flags moved, scan angle rank x 1/0.006), so that the
COPC benchmark compares COPC and plain LAZ on identical PDRF 7 records. With COPY_POINTS (the
source's point count: make_site writes copy k as records [k * COPY_POINTS, (k + 1) * COPY_POINTS))
each copy's GPS times are shifted by k * 10 s, as separate acquisitions would be: the copies'
identical times would otherwise let a GPS-time order interleave the copies' duplicates, which no
real scan has. Streams in blocks."""
import struct
import sys

import numpy as np

src, dst = sys.argv[1], sys.argv[2]
copy_points = int(sys.argv[3]) if len(sys.argv) > 3 else 0
with open(src, "rb") as f:
    head = f.read(227)
    assert head[:4] == b"LASF" and head[104] & 63 == 3, "expected a LAS PDRF 3 file"
    point_offset, = struct.unpack_from("<I", head, 96)
    rec_len, = struct.unpack_from("<H", head, 105)
    count, = struct.unpack_from("<I", head, 107)
    scale_offset_bounds = head[131:227]
    f.seek(point_offset)
    out = open(dst, "wb")
    h = bytearray(375)
    h[0:4] = b"LASF"
    struct.pack_into("<H", h, 6, 1)  # GPS time type: adjusted standard (as make_site's source)
    h[24], h[25] = 1, 4
    h[26:58] = b"rayscan".ljust(32, b"\0")
    h[58:90] = b"las_to_pdrf7".ljust(32, b"\0")
    struct.pack_into("<HIIBH", h, 94, 375, 375, 0, 7, 36)
    h[131:227] = scale_offset_bounds
    struct.pack_into("<Q", h, 247, count)
    out.write(h)
    by_ret = np.zeros(16, dtype=np.uint64)
    block = 1 << 20
    done = 0
    while done < count:
        n = min(block, count - done)
        a = np.frombuffer(f.read(n * rec_len), dtype=np.uint8).reshape(n, rec_len)
        b = np.zeros((n, 36), dtype=np.uint8)
        b[:, 0:14] = a[:, 0:14]
        ret, nret = a[:, 14] & 7, (a[:, 14] >> 3) & 7
        b[:, 14] = ret | (nret << 4)
        b[:, 15] = ((a[:, 15] >> 5) & 7) | (((a[:, 14] >> 6) & 1) << 6) | (((a[:, 14] >> 7) & 1) << 7)
        b[:, 16] = a[:, 15] & 31
        b[:, 17] = a[:, 17]
        angle = np.rint(a[:, 16].view(np.int8).astype(np.float64) / 0.006).astype("<i2")
        b[:, 18:20] = angle.view(np.uint8).reshape(n, 2)
        b[:, 20:22] = a[:, 18:20]
        b[:, 22:30] = a[:, 20:28]
        if copy_points:
            t = a[:, 20:28].copy().view("<f8").reshape(n)
            t += ((np.arange(done, done + n) // copy_points) * 10.0)
            b[:, 22:30] = t.astype("<f8").view(np.uint8).reshape(n, 8)
        b[:, 30:36] = a[:, 28:34]
        by_ret += np.bincount(ret, minlength=16).astype(np.uint64)
        out.write(b.tobytes())
        done += n
    out.seek(255)
    out.write(struct.pack("<15Q", *[int(x) for x in by_ret[1:16]]))
    out.close()
