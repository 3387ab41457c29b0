"""Argument checking of the module: a value of the wrong type raises TypeError, a value out of range
(any size of integer, a file name with a NUL byte) ValueError, each with the library's one-line
message naming the argument and what was expected, never pybind11's "incompatible function
arguments" or an OSError without a reason. The boundary values themselves are accepted."""

import pathlib

import numpy as np
import pytest

import rayscan
from conftest import SOURCE

HUGE = 2**70  # past every C++ integer type


def check(call, kind, message):
    with pytest.raises(kind) as e:
        call()
    assert type(e.value) is kind, (type(e.value), str(e.value))
    assert str(e.value) == message, str(e.value)


def test_index_and_query_integers(uniform_cloud):
    xyz = uniform_cloud
    tree = rayscan.Octree(xyz)
    o, d = np.zeros(3), np.ones(3)
    count = "an integer in [1, 2^32 - 1]"
    check(lambda: rayscan.Octree(xyz, capacity=HUGE), ValueError, f"capacity must be {count}, got {HUGE}")
    check(lambda: rayscan.KdTree(xyz, capacity=2**32), ValueError, f"capacity must be {count}, got {2**32}")
    check(lambda: rayscan.Octree(xyz, capacity=-1), ValueError, f"capacity must be {count}, got -1")
    check(lambda: rayscan.Octree(xyz, capacity=2.5), TypeError, f"capacity must be {count}, got float")
    check(lambda: rayscan.KdTree(xyz, capacity="8"), TypeError, f"capacity must be {count}, got str")
    check(lambda: rayscan.Octree(xyz, capacity=True), TypeError, f"capacity must be {count}, got bool")
    check(lambda: rayscan.Octree(xyz, layout="fixed", depth=-HUGE), ValueError,
          f"depth must be None or an integer in [0, 21], got {-HUGE}")
    check(lambda: rayscan.Octree(xyz, max_depth=1.0), TypeError, "max_depth must be None or an integer in [1, 21], got float")
    # max_depth 0 (one leaf holding every point) is refused as `rayscan index --max-depth` refuses it.
    for layout in ("adaptive", "layered", "fixed"):
        check(lambda: rayscan.Octree(xyz, layout=layout, max_depth=0), ValueError,
              "max_depth must be None or an integer in [1, 21], got 0")
    check(lambda: rayscan.Octree(xyz, max_depth=22), ValueError, "max_depth must be None or an integer in [1, 21], got 22")
    assert rayscan.Octree(xyz, capacity=4, max_depth=1).depth == 1
    threads = "0 (all cores) or a positive count up to 4096"
    check(lambda: tree.ray_query(o, d, threads=HUGE), ValueError, f"threads must be {threads}, got {HUGE}")
    check(lambda: tree.knn(o, k=1, threads=-1), ValueError, f"threads must be {threads}, got -1")
    check(lambda: tree.box(o, d, threads=1.0), TypeError, f"threads must be {threads}, got float")
    # The boundaries and NumPy integers are accepted.
    assert rayscan.KdTree(xyz, capacity=2**32 - 1).capacity == 2**32 - 1
    assert rayscan.Octree(xyz, capacity=np.uint16(7), max_depth=np.int8(1)).capacity == 7
    assert rayscan.Octree(xyz, layout="fixed", depth=np.int8(0)).depth == 0
    assert len(tree.box(o, d, threads=np.int64(4096)).offsets) == 2


def test_direction_that_cannot_be_normalised_is_refused_like_the_cli(uniform_cloud):
    tree = rayscan.Octree(uniform_cloud)
    rule = ("Ray: direction must be non-zero and finite with a length between about 1.5e-154 and "
            "1.3e154 (so that it normalises exactly)")
    for d in ([0, 0, 1e-320], [1e300, 1e300, 1.0]):
        check(lambda: tree.ray_query([0.5, 0.5, 2.0], d), ValueError, "ray 0: " + rule)
    # Just inside the range: the answer of the unit direction.
    a = tree.ray_query([0.5, 0.5, 2.0], [0, 0, -1e-150], k=5)
    b = tree.ray_query([0.5, 0.5, 2.0], [0, 0, -1.0], k=5)
    assert a.indices.tolist() == b.indices.tolist() and len(b.indices) == 5


def test_read_arguments(data_dir, tmp_path):
    las = data_dir / "las" / "autzen_trim.las"
    check(lambda: rayscan.read(las, [1, 2]), TypeError,
          "attributes must be a str or a list of str, got a list holding int (item 0)")
    check(lambda: rayscan.read(las, ["xyz", None]), TypeError,
          "attributes must be a str or a list of str, got a list holding NoneType (item 1)")
    check(lambda: rayscan.read(las, 5), TypeError, "attributes must be a str or a list of str, got int")
    check(lambda: rayscan.read(str(las) + "\0.las"), ValueError,
          "path " + repr(str(las) + "\0.las") + " contains a NUL byte; expected a file name")
    check(lambda: rayscan.read(bytes(las)), TypeError, "path must be a file name (str or os.PathLike), got bytes")
    check(lambda: rayscan.read(12), TypeError, "path must be a file name (str or os.PathLike), got int")
    # A path-like object and a tuple of names are accepted.
    pc = rayscan.read(pathlib.Path(las), ("xyz", "intensity"))
    assert pc.attributes == ["xyz", "intensity"] and len(pc) > 0


@pytest.mark.skipif(not hasattr(rayscan, "render"), reason="module built without the library's job API")
def test_job_arguments(tmp_path):
    scene = SOURCE / "scenes" / "autzen_overview.json"
    u64 = "an integer in [0, 2^64 - 1]"
    check(lambda: rayscan.render(scene, seed=-1), ValueError, f"seed must be {u64}, got -1")
    check(lambda: rayscan.render(scene, seed=2**64), ValueError, f"seed must be {u64}, got {2**64}")
    check(lambda: rayscan.render(scene, seed="1"), TypeError, f"seed must be {u64}, got str")
    check(lambda: rayscan.render(scene, width=HUGE), ValueError,
          f"width must be None or an integer in [1, 65536], got {HUGE}")
    check(lambda: rayscan.render(scene, spp=0), ValueError, "spp must be None or an integer in [1, 1048576], got 0")
    check(lambda: rayscan.render(scene, aovs=[1]), TypeError,
          "aovs must be a str or a list of str, got a list holding int (item 0)")
    check(lambda: rayscan.render(str(scene) + "\0"), ValueError,
          "scene " + repr(str(scene) + "\0") + " contains a NUL byte; expected a file name")
    check(lambda: rayscan.render(scene, camera="cam\0.json"), ValueError,
          "camera 'cam\\x00.json' contains a NUL byte; expected a file name")
    cloud = SOURCE / "scenes" / "data" / "autzen_trim.las"
    obs = [[0.0, 0.0, 0.0]]
    check(lambda: rayscan.visibility(cloud, obs, sky_rays=-1), ValueError,
          "sky_rays must be an integer in [0, 2^32 - 1], got -1")
    check(lambda: rayscan.visibility(cloud, obs, sky_rays=HUGE), ValueError,
          f"sky_rays must be an integer in [0, 2^32 - 1], got {HUGE}")
    check(lambda: rayscan.visibility(cloud, obs, cache="lots"), ValueError,
          "cache: size 'lots': expected a positive number with an optional K, M, G or T suffix")
    check(lambda: rayscan.visibility("a\0.las", obs), ValueError,
          "cloud 'a\\x00.las' contains a NUL byte; expected a file name")
    check(lambda: rayscan.compare("ref\0.png", np.zeros((2, 2))), ValueError,
          "reference 'ref\\x00.png' contains a NUL byte; expected a file name")
    check(lambda: rayscan.compare(np.zeros((2, 2)), np.zeros((2, 2)), channels=[3]), TypeError,
          "channels must be a str or a list of str, got a list holding int (item 0)")
    # A NaN limit compares false with every metric and would pass any pair.
    check(lambda: rayscan.compare(np.zeros((4, 4, 3)), np.ones((4, 4, 3)), fail_psnr=float("nan")), ValueError,
          "fail_psnr: expected a finite number, got nan")
    check(lambda: rayscan.compare(np.zeros((4, 4, 3)), np.ones((4, 4, 3)), fail=float("nan")), ValueError,
          "fail: expected a finite number, got nan")


def test_numbers_and_text_of_the_wrong_type_name_the_argument(uniform_cloud):
    """None, a str or a datetime where a number or text is expected: a TypeError naming the
    argument, never pybind11's "incompatible function arguments"; NumPy scalars are numbers."""
    import datetime
    tree = rayscan.Octree(uniform_cloud)
    o, d = np.zeros(3), np.ones(3)
    radius = "a number >= 0 (world units; inf for no limit)"
    check(lambda: tree.ray_query(o, d, k=1, radius=None), TypeError, f"radius must be {radius}, got NoneType")
    check(lambda: tree.ray_query(o, d, k=1, t_min="0"), TypeError,
          "t_min must be a number (world units along the ray), got str")
    check(lambda: tree.ray_query(o, d, k=1, order=1), TypeError,
          "order must be 'ray', 'time' or 'sphere_hit', got int")
    check(lambda: tree.knn(o, k=1, radius="1"), TypeError, f"radius must be {radius}, got str")
    check(lambda: tree.radius(o, True), TypeError, f"radius must be {radius}, got bool")
    a = tree.ray_query(o, d, k=3, radius=np.float32(0.25), t_max=np.int64(5))
    b = tree.ray_query(o, d, k=3, radius=0.25, t_max=5.0)
    assert a.indices.tolist() == b.indices.tolist() and len(a.indices) == 3
    if not hasattr(rayscan, "render"):
        return
    xyz = uniform_cloud
    auto = "None (auto) or a number > 0 (world units)"
    check(lambda: rayscan.visibility(xyz, [[0.5, 0.5, 2.0]], radius="1"), TypeError, f"radius must be {auto}, got str")
    check(lambda: rayscan.visibility(xyz, [[0.5, 0.5]], height="2"), TypeError,
          "height must be None or a number (eye height above the local ground, world units), got str")
    check(lambda: rayscan.visibility(xyz, [[0.5, 0.5, 2.0]], cache=2**30), TypeError,
          'cache must be a byte size as text ("2G", "512M"), got int')
    when = datetime.datetime(2026, 6, 21, 12)
    check(lambda: rayscan.solar(xyz, at=when, latitude=48.0, longitude=11.0), TypeError,
          'at must be None or ISO 8601 text ("2024-06-21T12:00"; a datetime\'s isoformat()), got datetime')
    check(lambda: rayscan.solar(xyz, at="2026-06-21T12:00", latitude=48.0, longitude=11.0, radius="1"), TypeError,
          f"radius must be {auto}, got str")
    check(lambda: rayscan.solar(xyz, at="2026-06-21T12:00", latitude="48", longitude=11.0), TypeError,
          "latitude must be None or a number (degrees north), got str")
    check(lambda: rayscan.solar(xyz, at="2026-06-21T12:00", latitude=48.0, longitude=11.0, albedo=None), TypeError,
          "albedo must be a number in [0, 1], got NoneType")
    check(lambda: rayscan.solar(xyz, at="2026-06-21T12:00", latitude=48.0, longitude=11.0, linke=[3, "4"]),
          TypeError, "linke must be a number or a list of 12 numbers (Linke turbidity), got str")
    check(lambda: rayscan.compare(np.zeros((2, 2)), np.zeros((2, 2)), fail="0.1"), TypeError,
          "fail must be None or a number (absolute error per sample), got str")
    check(lambda: rayscan.ortho_map(xyz, None), TypeError, "res must be a number > 0 (world units per pixel), got NoneType")
    # The same instant as text and from the datetime's isoformat(), NumPy numbers for the floats.
    s1 = rayscan.solar(xyz, at=when.isoformat(), latitude=np.float64(48.0), longitude=11, sky_rays=0, radius=0.05)
    s2 = rayscan.solar(xyz, at="2026-06-21T12:00:00", latitude=48.0, longitude=11.0, sky_rays=0, radius=0.05)
    np.testing.assert_array_equal(s1["in_shadow"], s2["in_shadow"])
    assert s1["sun_elevation"] == s2["sun_elevation"] > 0


def test_threads_above_the_cores_run_on_the_cores_without_a_warning():
    """threads= larger than the machine runs on every core, as the jobs' --threads does: same
    answers, and no TBB warning on stderr (TBB prints one for an arena larger than its workers)."""
    import os
    import subprocess
    import sys

    code = (
        "import numpy as np, rayscan\n"
        "rng = np.random.default_rng(3)\n"
        "tree = rayscan.Octree(rng.random((2000, 3)))\n"
        "o = rng.random((500, 3)); d = rng.normal(size=(500, 3))\n"
        "a = tree.ray_query(o, d, k=1, radius=0.05, threads=1).first()\n"
        "b = tree.ray_query(o, d, k=1, radius=0.05, threads=%d).first()\n"
        "assert (a == b).all()\n" % (8 * (os.cpu_count() or 1))
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "TBB Warning" not in r.stderr, r.stderr
