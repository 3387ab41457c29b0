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
