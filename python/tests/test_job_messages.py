"""The jobs' error messages in Python's terms: every option they name is a keyword the call takes
(never a command-line spelling or a field of the C++ options struct), observer rows are numbered
once, from 0, as the caller indexes them, and a non-finite point is named by the caller's row.
Each expected message is checked whole; the keywords it names are checked against the call's
own signature."""

import inspect

import numpy as np
import pytest

import rayscan
from conftest import SOURCE

pytestmark = pytest.mark.skipif(not hasattr(rayscan, "render"),
                                reason="module built without the library's job API")

AUTZEN = SOURCE / "scenes" / "data" / "autzen_trim.las"


def message(call, kind=ValueError):
    with pytest.raises(kind) as e:
        call()
    assert type(e.value) is kind, (type(e.value), str(e.value))
    return str(e.value)


def keywords(function):
    return set(inspect.signature(function).parameters)


def flat_ground(spacing=0.5, size=20.0):
    """A square of ground points at z = 0, x and y in [0, size - spacing]."""
    g = np.arange(0, size, spacing)
    gx, gy = np.meshgrid(g, g)
    return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])


def test_ground_radius_is_a_keyword_and_bounds_the_ground_search():
    # Ground points reach x = 19.5; an eye at (25, 5) is 5.5 from the nearest. Within a ground
    # radius of 5 no point lies under it: the message names the caller's row (1, the second
    # observer) once and the keyword that widens the search; with 6 the eye stands `height` above
    # the flat ground (z = 0).
    xyz = flat_ground()
    eyes = [[5.0, 5.0], [25.0, 5.0]]
    text = message(lambda: rayscan.visibility(xyz, observers=eyes, height=2.0, radius=0.3, ground_radius=5.0))
    assert text == ("observers[1]: no point within the ground radius 5 of (25.000000, 5.000000) to put the "
                    "eye above; move it or raise ground_radius")
    assert "ground_radius" in keywords(rayscan.visibility)
    out = rayscan.visibility(xyz, observers=eyes, height=2.0, radius=0.3, ground_radius=6.0)
    assert out["observers"].tolist() == [[5.0, 5.0, 2.0], [25.0, 5.0, 2.0]]
    # Without it, the default is 5 x radius: 1.5 here.
    text = message(lambda: rayscan.visibility(xyz, observers=eyes, height=2.0, radius=0.3))
    assert text.startswith("observers[1]: no point within the ground radius 1.5 of (25.000000, 5.000000)"), text
    # Refused as an option, also where no eye is placed on the ground (the sky view alone).
    for bad, shown in ((0.0, "0"), (-1.0, "-1"), (float("nan"), "nan"), (float("inf"), "inf")):
        for run in ({"observers": eyes, "height": 2.0}, {"sky_rays": 4}):
            assert message(lambda: rayscan.visibility(xyz, ground_radius=bad, **run)) == (
                f"ground_radius: expected a finite number > 0 (world units), got {shown}")
    assert message(lambda: rayscan.visibility(xyz, observers=eyes, height=2.0, ground_radius="5"), TypeError) == (
        "ground_radius must be None (5 x radius) or a number > 0 (world units), got str")


def test_line_of_sight_lengths_are_refused_by_their_keyword_before_the_file():
    # The file does not exist: a call that read it would raise its OSError instead. None is the
    # automatic radius, the word the message offers.
    missing = "/nonexistent/cloud.las"
    for kw, expected in (
            (dict(radius=-1.0), "radius: expected a finite number > 0 (world units) or None, got -1"),
            (dict(radius=float("inf")), "radius: expected a finite number > 0 (world units) or None, got inf"),
            (dict(tolerance=-0.5), "tolerance: expected a finite number >= 0 (world units), got -0.5"),
            (dict(target_height=float("nan")), "target_height: expected a finite number >= 0 (world units), got nan"),
            (dict(max_distance=-2.0),
             "max_distance: expected a number >= 0 (world units; infinity: unlimited), got -2")):
        assert message(lambda: rayscan.visibility(missing, sky_rays=4, **kw)) == expected
        assert set(kw) <= keywords(rayscan.visibility)
    assert message(lambda: rayscan.solar(missing, at="2024-06-21T12:00", latitude=45.0, longitude=0.0,
                                         radius=0.0)) == (
        "radius: expected a finite number > 0 (world units) or None, got 0")


def test_solar_step_is_refused_for_an_instant():
    # An instant has no step: one other than the default is refused, naming both keywords, before
    # the file (which does not exist) is read; the default is the call's own and passes to the file.
    missing = "/nonexistent/cloud.las"
    assert message(lambda: rayscan.solar(missing, at="2024-06-21T12:00", step="15min", latitude=45.0,
                                         longitude=0.0)) == "step needs a period (start, end), not at"
    assert {"step", "start", "end", "at"} <= keywords(rayscan.solar)
    with pytest.raises(OSError):
        rayscan.solar(missing, at="2024-06-21T12:00", latitude=45.0, longitude=0.0)


def test_observer_rows_are_numbered_once_from_zero():
    xyz = flat_ground()
    # A coordinate out of range in the third row (the bound itself is test_jobs.py's).
    text = message(lambda: rayscan.visibility(xyz, observers=[[1.0, 1.0, 2.0], [2.0, 2.0, 2.0], [3.0, 1e300, 2.0]],
                                              radius=0.3))
    assert text.startswith("observers[2]: y: expected a finite number"), text
    # (K, 2) rows without a height to place them: the first is named.
    text = message(lambda: rayscan.visibility(xyz, observers=[[1.0, 1.0], [3.0, 3.0]], radius=0.3))
    assert text == "observers[0]: no z and no height; give z, a height, or a default height (height)"
    assert "height" in keywords(rayscan.visibility)


def test_nothing_to_compute_names_the_keywords():
    xyz = flat_ground()
    # The job names a file and positions as two options; the call takes both as observers=.
    for observers in (None, np.zeros((0, 2))):
        assert message(lambda: rayscan.visibility(xyz, observers=observers)) == (
            "nothing to compute: give observers (observers), a sky view (sky_rays > 0) or a camera (camera)")
    assert {"observers", "sky_rays", "camera"} <= keywords(rayscan.visibility)


def test_solar_without_a_time_names_its_keywords():
    # The command line's day of shadows (--day) is no keyword of this call: left out.
    xyz = flat_ground()
    expected = "give a period (start and end) or an instant (at)"
    for kw in ({}, {"start": "2024-06-21"}, {"end": "2024-06-21"}):
        assert message(lambda: rayscan.solar(xyz, latitude=45.0, longitude=0.0, **kw)) == expected
    assert {"start", "end", "at"} <= keywords(rayscan.solar)


def test_render_size_is_checked_as_given():
    # The command line's range, 1..65536, for each side given, named as the keyword; a side that
    # the camera's aspect ratio derives from the other is named by that rule.
    cloud = flat_ground()
    expected = "None or an integer in [1, 65536]"
    assert message(lambda: rayscan.render(AUTZEN, width=70000, height=100)) == f"width must be {expected}, got 70000"
    assert message(lambda: rayscan.render(AUTZEN, width=100, height=65537)) == f"height must be {expected}, got 65537"
    assert message(lambda: rayscan.render(AUTZEN, width=0)) == f"width must be {expected}, got 0"
    assert message(lambda: rayscan.render(AUTZEN, height=65536)) == (
        "the camera's aspect ratio 600:400 gives an image width of 98304 pixels, expected 1 to 65536; give both "
        "width and height")
    assert message(lambda: rayscan.render(AUTZEN, spp=(1 << 20) + 1)) == (
        "spp must be None or an integer in [1, 1048576], got 1048577")
    out = rayscan.render(cloud, width=65536, height=1, spp=1)
    assert out["beauty"].shape == (1, 65536, 3)


@pytest.mark.parametrize("georeferenced", [False, True])
def test_a_non_finite_point_is_named_by_the_callers_row(georeferenced):
    # 1000 points of Autzen, one made infinite, another NaN later on: the first bad row is the
    # one named (NumPy's own finiteness test is the oracle), whichever job and however the job
    # orders the points it looks at first (the quick look samples a cloud without a CRS in hash
    # order; a georeferenced one is framed from its bounds).
    src = rayscan.read(AUTZEN)[:1000]
    pc = src if georeferenced else rayscan.PointCloud(src.xyz.copy())
    assert (pc.crs is not None) == georeferenced
    pc.xyz[5] = np.inf
    pc.xyz[700, 2] = np.nan
    row = int(np.flatnonzero(~np.isfinite(pc.xyz).all(axis=1))[0])
    assert row == 5
    bad = f"PointCloud: point {row} has a non-finite coordinate"
    calls = {
        "scene": lambda: rayscan.render(pc, width=8, height=8, spp=1),
        "cloud": lambda: rayscan.ortho_map(pc, 5.0),
    }
    for name, call in calls.items():
        assert message(call) == f"{name}: {bad}"
    assert message(lambda: rayscan.render(SOURCE / "scenes" / "autzen_overview.json", cloud=pc, width=8, spp=1)) == (
        f"cloud: {bad}")
    assert message(lambda: rayscan.visibility(pc, sky_rays=4)) == f"cloud: {bad}"
    assert message(lambda: rayscan.solar(pc, at="2024-06-21T20:00", latitude=44.0, longitude=-123.0)) == (
        f"cloud: {bad}")


@pytest.mark.parametrize("given", ["PointCloud", "array"])
def test_points_in_memory_are_named_by_the_keyword_that_gave_them(given):
    # The jobs name points handed over in memory "(memory)" by default, a name the caller never
    # wrote: the module has them name the keyword instead (source_label), as it names a bad point. And the automatic
    # radius, which the call asks for with None, is "radius None (auto)".
    def points(xyz):
        xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
        return rayscan.PointCloud(xyz) if given == "PointCloud" else xyz

    none, one = points([]), points([[1.0, 2.0, 3.0]])
    assert message(lambda: rayscan.visibility(none, sky_rays=4, radius=1.0)) == "cloud: the point cloud has no points"
    assert message(lambda: rayscan.solar(none, at="2024-06-21T20:00", latitude=44.0, longitude=-123.0,
                                         radius=1.0)) == "cloud: the point cloud has no points"
    quick_look = ("a quick look needs at least 2 distinct points, to size them from their spacing; the cloud has "
                  "1 point (a scene file with a numeric \"radius\" renders it)")
    assert message(lambda: rayscan.render(one, width=8, height=8, spp=1)) == f"scene: {quick_look}"
    assert message(lambda: rayscan.ortho_map(one, 5.0)) == f"cloud: {quick_look}"
    auto = "radius None (auto) needs at least two distinct points; give a number"
    assert message(lambda: rayscan.visibility(one, sky_rays=4)) == auto
    assert message(lambda: rayscan.solar(one, at="2024-06-21T20:00", latitude=44.0, longitude=-123.0)) == auto
    assert {"cloud", "radius"} <= keywords(rayscan.visibility) & keywords(rayscan.solar)
    assert "scene" in keywords(rayscan.render) and "cloud" in keywords(rayscan.ortho_map)
