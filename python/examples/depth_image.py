"""README example: read a LAS file, cast one ray per pixel from a point above the scan with the
paper's ray query (first sphere hit), and plot the depth image with matplotlib.

    PYTHONPATH=build/python /usr/bin/python3 python/examples/depth_image.py [OUT.png]
"""
import sys

import matplotlib
matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt
import numpy as np

import rayscan

pc = rayscan.read("tests/data/las/autzen_trim.las")   # 110,000 points, international feet
tree = rayscan.Octree(pc.xyz)

# Sphere radius: 1.5 x the median distance to the nearest other point (kNN with k = 2: the point
# itself and its nearest neighbour), so that neighbouring spheres overlap into a surface.
nn = tree.knn(pc.xyz[::10], k=2)
radius = 1.5 * float(np.median(nn.distance[1::2]))

# A pinhole camera 1,000 ft above the middle of the scan looking straight down; the focal length
# (in pixels) makes the scan's x extent fill 95% of the image width.
lo, hi = pc.bounds
eye = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 1000.0])
w, h = 600, 300
f = 0.95 * (w / 2) * (eye[2] - lo[2]) / ((hi[0] - lo[0]) / 2)
u, v = np.meshgrid(np.arange(w) + 0.5 - w / 2, h / 2 - (np.arange(h) + 0.5))
directions = np.stack([u, v, np.full_like(u, -f)], axis=-1).reshape(-1, 3)

hits = tree.ray_query(eye, directions, k=1, radius=radius, t_min=0.0, order="sphere_hit")
depth = hits.first("t").reshape(h, w)                 # NaN where the ray hits nothing

plt.imshow(depth, cmap="viridis")
plt.colorbar(label="depth along the ray (ft)")
plt.title(f"autzen_trim.las: {np.isfinite(depth).mean():.0%} of rays hit (r = {radius:.2f} ft)")
plt.savefig(sys.argv[1] if len(sys.argv) > 1 else "depth.png", dpi=100)
