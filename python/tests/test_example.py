"""The Python guide's example (python/examples/depth_image.py, shown in docs/python.md) runs and
produces a real image."""

import os
import pathlib
import subprocess
import sys

import pytest

from conftest import SOURCE


def test_depth_image_example(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "depth.png"
    subprocess.run([sys.executable, str(SOURCE / "python" / "examples" / "depth_image.py"), str(out)],
                   cwd=SOURCE, check=True, env=dict(os.environ, MPLCONFIGDIR=str(tmp_path)))
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000


def test_readme_example_matches_the_file():
    """The Python guide's code block (docs/python.md) is the example file's core (same calls, same
    numbers)."""
    readme = (SOURCE / "docs" / "python.md").read_text()
    example = (SOURCE / "python" / "examples" / "depth_image.py").read_text()
    for line in ['tree.ray_query(eye, directions, k=1, radius=radius, t_min=0.0, order="sphere_hit")',
                 'radius = 1.5 * float(np.median(nn.distance[1::2]))',
                 'f = 0.95 * (w / 2) * (eye[2] - lo[2]) / ((hi[0] - lo[0]) / 2)']:
        assert line in readme and line in example, line


def test_module_docstring_example_runs(monkeypatch):
    """help(rayscan)'s example is real: run as a doctest from the source tree, every output as shown."""
    import doctest

    import rayscan
    monkeypatch.chdir(SOURCE)
    result = doctest.testmod(rayscan, optionflags=doctest.NORMALIZE_WHITESPACE, report=True)
    assert result.attempted >= 10 and result.failed == 0, result


def test_every_public_property_has_a_docstring():
    import rayscan
    classes = [rayscan.PointCloud, rayscan.Octree, rayscan.KdTree, rayscan.BruteForce, rayscan.Site]
    missing = []
    for cls in classes:
        for name in dir(cls):
            attr = getattr(cls, name)
            if not name.startswith("_") and isinstance(attr, property) and not (attr.__doc__ or "").strip():
                missing.append(f"{cls.__name__}.{name}")
    assert missing == []
    for name in ("xyz", "rgb", "intensity", "classification", "gps_time", "normals", "scalars", "crs", "epsg"):
        assert getattr(rayscan.PointCloud, name).__doc__.strip(), name
    for cls, names in ((rayscan.Octree, ("capacity", "depth", "layout", "node_count")),
                       (rayscan.KdTree, ("capacity", "node_count")), (rayscan.Site, ("path",))):
        for name in names:
            assert getattr(cls, name).__doc__.strip(), (cls, name)
