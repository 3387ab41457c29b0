"""rayscan.render / visibility / compare (the library's job calls) against independent oracles:
the ray query (render's index/depth AOVs), NumPy (compare's metrics) and analytic geometry
(visibility behind a wall)."""

import json
import struct
import subprocess
import zlib

import numpy as np
import pytest

import rayscan
from conftest import SOURCE

pytestmark = pytest.mark.skipif(not hasattr(rayscan, "render"),
                                reason="module built without the library's job API")


def test_render_aovs_agree_with_the_ray_query():
    scene = SOURCE / "scenes" / "autzen_overview.json"
    out = rayscan.render(scene, width=96, spp=1, aovs=["depth", "index", "position"])
    h, w = out["depth"].shape
    assert w == 96 and out["beauty"].shape == (h, w, 3) and out["beauty"].dtype == np.float32
    assert out["index"].dtype == np.int64 and out["position"].shape == (h, w, 3)
    idx = out["index"]
    hit = idx >= 0
    assert 0.2 < hit.mean() <= 1.0
    assert np.all(np.isinf(out["depth"][~hit]))
    r = out["radius"]
    pc = rayscan.read(SOURCE / "scenes" / "data" / "autzen_trim.las")
    origin = out["position_origin"]
    rel = out["position"][hit].astype(np.float64)
    # The hit lies on the sphere of radius r around the point it reports.
    dist = np.linalg.norm(origin + rel - pc.xyz[idx[hit]], axis=1)
    np.testing.assert_allclose(dist, r, rtol=1e-3, atol=1e-3 * r)
    # depth = distance from the camera centre along the (unit) pixel ray.
    np.testing.assert_allclose(out["depth"][hit], np.linalg.norm(rel, axis=1), rtol=1e-5)
    # The same rays through the Python ray query find the same first points.
    tree = rayscan.Octree(pc)
    res = tree.ray_query(origin, rel, k=1, radius=r, t_min=0.0, order="sphere_hit")
    assert np.mean(res.first() == idx[hit]) > 0.99


def test_render_from_dict_and_memory_cloud(tmp_path, monkeypatch):
    monkeypatch.chdir(SOURCE / "scenes")
    import json
    scene = json.loads((SOURCE / "scenes" / "autzen_overview.json").read_text())
    a = rayscan.render(scene, width=48, spp=2, seed=3)
    b = rayscan.render(SOURCE / "scenes" / "autzen_overview.json", width=48, spp=2, seed=3,
                       cloud=rayscan.read(SOURCE / "scenes" / "data" / "autzen_trim.las"))
    np.testing.assert_array_equal(a["beauty"], b["beauty"])  # deterministic for a seed
    with pytest.raises(ValueError, match="aov"):
        rayscan.render(scene, width=48, spp=1, aovs=["nope"])


def test_render_quick_look_of_a_file_counts_its_read():
    # A cloud file's quick look reads the file once, for the overview camera and the render, as
    # `rayscan render CLOUD` does; the render reports that read as its own and counts it in its
    # time to the first traced tile. The same points given in memory read nothing.
    las = SOURCE / "scenes" / "data" / "autzen_trim.las"
    st = rayscan.render(las, width=24, spp=1)["stats"]
    assert st["read_seconds"] > 0.0
    assert st["first_tile_seconds"] >= st["read_seconds"]
    mem = rayscan.render(rayscan.read(las), width=24, spp=1)["stats"]
    assert mem["read_seconds"] == 0.0
    assert mem["first_tile_seconds"] > 0.0


def test_compare_metrics_equal_numpy():
    rng = np.random.default_rng(5)
    ref = rng.random((40, 50, 3)).astype(np.float32)
    img = np.clip(ref + rng.normal(0, 0.05, ref.shape), 0, 1).astype(np.float32)
    m = rayscan.compare(ref, img)
    e = img.astype(np.float64) - ref
    assert m["mae"] == pytest.approx(np.abs(e).mean(), rel=1e-6)
    assert m["rmse"] == pytest.approx(np.sqrt((e * e).mean()), rel=1e-6)
    assert m["psnr"] == pytest.approx(20 * np.log10(1.0 / np.sqrt((e * e).mean())), rel=1e-6)
    assert m["max_error"] == pytest.approx(np.abs(e).max(), rel=1e-6)
    assert m["verdict"] == "fail" and m["width"] == 50 and m["height"] == 40
    same = rayscan.compare(ref, ref)
    assert same["rmse"] == 0 and same["psnr"] == float("inf") and same["verdict"] == "pass"
    with pytest.raises(ValueError, match="reference: expected"):
        rayscan.compare(np.zeros(5), ref)
    with pytest.raises(ValueError):
        rayscan.compare(ref, ref[:20])  # size mismatch


def test_compare_levels_without_a_pixel_test_report_none():
    """A level with no pixel test has no count over a threshold (None, as the CLI's "off" and
    --json null); one with a test counts the samples over it: 1 of 64 pixels off by 0.5."""
    ref = np.zeros((8, 8, 3))
    img = ref.copy()
    img[0, 0, 0] = 0.5
    m = rayscan.compare(ref, img, fail=0.2)
    assert m["fail_threshold"] == 0.2 and m["percent_over_fail"] == pytest.approx(100 / 64)
    assert m["warn_threshold"] is None and m["percent_over_warn"] is None
    m = rayscan.compare(ref, img, fail=0.6, warn=0.1)
    assert m["percent_over_fail"] == 0 and m["percent_over_warn"] == pytest.approx(100 / 64)
    assert m["verdict"] == "warn"


def write_pfm(path, img):
    """An (H, W, 3) float image as a little-endian PFM (rows stored bottom to top): NaN kept."""
    h, w = img.shape[:2]
    path.write_bytes(b"PF\n%d %d\n-1.0\n" % (w, h) + np.ascontiguousarray(img[::-1], dtype="<f4").tobytes())


def write_rgba_png(path, img):
    """An (H, W, 4) uint8 image as an 8-bit RGBA PNG (no filtering)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    h, w = img.shape[:2]
    rows = b"".join(b"\0" + img[y].tobytes() for y in range(h))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)) +
                     chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def test_compare_ssim_windows_and_reason_equal_the_cli_json(tmp_path, cli):
    """ssim, ssim_undefined, ssim_windows and ssim_window_positions are the CLI's --json ssim.value,
    .undefined, .windows and .window_positions on the same files (the oracle), and the counts are
    the 11x11 window positions that do not cover the left-out pixels."""
    rng = np.random.default_rng(11)
    a = rng.random((40, 50, 3)).astype(np.float32)
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1).astype(np.float32)
    a[20, 25, 1] = b[20, 25, 1] = np.nan  # NaN matching NaN: its 121 windows are left out
    write_pfm(tmp_path / "nan_a.pfm", a)
    write_pfm(tmp_path / "nan_b.pfm", b)
    tiny = rng.random((15, 15, 3)).astype(np.float32)
    tiny[7, 7, 0] = np.nan  # in every window of a 15x15 image: SSIM undefined
    write_pfm(tmp_path / "tiny.pfm", tiny)
    ref = rng.integers(0, 256, (30, 40, 4), dtype=np.uint8)
    ref[..., 3] = 255
    ref[:, :20, 3] = 0  # transparent left half: masked with mask=True / --mask
    img = ref.copy()
    img[:, :20, :3] = 255 - img[:, :20, :3]
    write_rgba_png(tmp_path / "m_ref.png", ref)
    write_rgba_png(tmp_path / "m_img.png", img)
    cases = [("nan_a.pfm", "nan_b.pfm", False, 40 * 30 - 11 * 11, 40 * 30),
             ("tiny.pfm", "tiny.pfm", False, 0, 5 * 5),
             ("m_ref.png", "m_img.png", True, 10 * 20, 20 * 30)]
    for ref_name, img_name, mask, windows, positions in cases:
        files = [str(tmp_path / ref_name), str(tmp_path / img_name)]
        run = subprocess.run([cli, "compare", *files, "--json", *(["--mask"] if mask else [])],
                             capture_output=True, text=True)
        assert run.returncode in (0, 1), run.stderr
        want = json.loads(run.stdout)["ssim"]
        got = rayscan.compare(*files, mask=mask)
        assert (got["ssim_windows"], got["ssim_window_positions"]) == (windows, positions), ref_name
        assert got["ssim_windows"] == want["windows"] and got["ssim_window_positions"] == want["window_positions"]
        assert got["ssim_undefined"] == want["undefined"], ref_name
        if want["value"] is None:
            assert np.isnan(got["ssim"]) and got["ssim_undefined"], ref_name
        else:
            assert got["ssim"] == want["value"] and got["ssim_undefined"] is None, ref_name
    assert want["value"] == 1.0  # the masked pair differs only where it is masked


def test_visibility_behind_a_wall():
    """A flat ground grid (spacing 0.5) and a 6 m wall at x = 10; an eye at (2, 10, 1.7): ground
    beyond the wall is hidden, ground in front of it is seen."""
    g = np.arange(0, 20, 0.5)
    gx, gy = np.meshgrid(g, g)
    ground = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    wy, wz = np.meshgrid(np.arange(-5, 25, 0.25), np.arange(0, 6, 0.25))
    wall = np.column_stack([np.full(wy.size, 10.0), wy.ravel(), wz.ravel()])
    xyz = np.vstack([ground, wall])
    path = pytest.importorskip("tempfile").mkdtemp()
    f = f"{path}/scene.f64"
    xyz.astype("<f8").tofile(f)
    out = rayscan.visibility(f, observers=[[2.0, 10.0, 1.7]], radius=0.3)
    count = out["visible_count"]
    assert count.shape == (len(xyz),) and out["radius"] == 0.3
    n = len(ground)
    behind = ground[:, 0] > 10.5
    front = (ground[:, 0] < 9.0) & (np.abs(ground[:, 1] - 10) < 8)
    assert np.all(count[:n][behind] == 0)
    assert np.mean(count[:n][front] == 1) > 0.9
    assert out["per_observer"][0] == int(count.sum())
    with pytest.raises(ValueError):
        rayscan.visibility(f, observers=[[2.0, 10.0, np.nan]], radius=0.3)


def test_solar_shadow_of_a_wall_is_its_projection_along_the_sun():
    """A ground grid and a 6 m wall along y at x = 10; at an instant the shadowed ground points
    are those whose ray to the sun meets the wall (analytic: the wall projected along the sun)."""
    g = np.arange(0, 30, 0.25)
    gx, gy = np.meshgrid(g, g)
    ground = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    wy, wz = np.meshgrid(np.arange(5, 25, 0.1), np.arange(0.1, 6.0001, 0.1))
    wall = np.column_stack([np.full(wy.size, 10.0), wy.ravel(), wz.ravel()])
    xyz = np.vstack([ground, wall])
    path = pytest.importorskip("tempfile").mkdtemp()
    f = f"{path}/wall.f64"
    xyz.astype("<f8").tofile(f)
    out = rayscan.solar(f, at="2026-06-21T16:00:00Z", latitude=48.0, longitude=11.0, sky_rays=0)
    az, el = np.radians(out["sun_azimuth"]), np.radians(out["sun_elevation"])
    assert 0.3 < el < 1.2 and out["in_shadow"].shape == (len(xyz),)
    s = np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])
    # Where the ray from each ground point along s crosses the wall's plane x = 10.
    t = (10.0 - ground[:, 0]) / s[0]
    y, z = ground[:, 1] + t * s[1], t * s[2]
    analytic = (t > 0) & (y > 5) & (y < 24.9) & (z < 6.0)
    got = out["in_shadow"][: len(ground)] == 1
    near_wall = np.abs(ground[:, 0] - 10) < 0.3
    both, either = np.sum(analytic & got & ~near_wall), np.sum((analytic | got) & ~near_wall)
    assert either > 500 and both / either > 0.97
    with pytest.raises(ValueError):
        rayscan.solar(f, at="2026-13-01", latitude=48.0, longitude=11.0)


def flat_ground(spacing=0.5, size=20.0):
    g = np.arange(0, size, spacing)
    gx, gy = np.meshgrid(g, g)
    return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])


def test_visibility_refuses_a_non_finite_eye_height():
    """height places eyes given as (x, y) above the local ground: a finite one puts the eye at
    ground + height (flat ground at z = 0: z = height); NaN would place every eye at NaN and see
    nothing without an error, infinity or a huge height would fail in a ray without naming the
    option. The bound is the command line's --height range, +-1e9."""
    xyz = flat_ground()
    out = rayscan.visibility(xyz, observers=[[5.0, 5.0]], height=1.7, radius=0.3)
    assert out["observers"].tolist() == [[5.0, 5.0, 1.7]] and out["visible_count"].sum() > 0
    for bad, text in ((np.nan, "nan"), (np.inf, "inf"), (-np.inf, "-inf"), (1e300, "1e+300")):
        with pytest.raises(ValueError) as e:
            rayscan.visibility(xyz, observers=[[5.0, 5.0]], height=bad, radius=0.3)
        assert str(e.value) == ("height: expected an eye height above the local ground, a finite number "
                                f"in [-1e+09, 1e+09] (world units), got {text}")


def test_visibility_refuses_far_observer_coordinates():
    """An observer array's coordinates are checked as a file's are (+-1e9, world units), naming
    the row and the coordinate, instead of failing inside a ray."""
    with pytest.raises(ValueError) as e:
        rayscan.visibility(flat_ground(), observers=[[5.0, 5.0, 2.0], [0.5, 1e160, 3.0]], radius=0.3)
    assert str(e.value) == ("observers[1]: y: expected a finite number in [-1e+09, 1e+09] "
                            "(world units), got 1e+160")


def test_files_that_cannot_be_opened_raise_the_oserror_of_their_errno(tmp_path):
    """Whichever argument names it, a missing file is a FileNotFoundError and a directory an
    IsADirectoryError, as Python's open() raises them (the errno of the failed open(2), errno.ENOENT
    / errno.EISDIR, strerror and filename set: one `except FileNotFoundError` for every call), with
    the input policy's message (rayscan/base/input_file.hpp) as the note, as for point clouds."""
    import errno
    import os
    xyz = flat_ground()
    img = np.zeros((4, 4, 3), dtype=np.float32)
    calls = {  # the file's extension, the call naming a file of that name
        "compare reference": (".png", lambda f: rayscan.compare(f, img)),
        "compare image": (".png", lambda f: rayscan.compare(img, f)),
        "render scene": (".json", lambda f: rayscan.render(f)),
        "render quick look": (".las", lambda f: rayscan.render(f)),
        "render cloud": (".las", lambda f: rayscan.render({"radius": 0.5}, cloud=f)),
        "render camera": (".json", lambda f: rayscan.render(xyz, camera=f)),
        "ortho_map cloud": (".las", lambda f: rayscan.ortho_map(f, 1.0)),
        "visibility observers": (".csv", lambda f: rayscan.visibility(xyz, observers=f, radius=0.3)),
        "visibility camera": (".json", lambda f: rayscan.visibility(xyz, observers=[[1.0, 1.0, 2.0]], camera=f)),
        "solar weather": (".epw", lambda f: rayscan.solar(xyz, start="2026-06-21", end="2026-06-21", latitude=48.0,
                                                          longitude=11.0, weather=f, sky_rays=0)),
        "visibility cloud": (".las", lambda f: rayscan.visibility(f, observers=[[1.0, 1.0, 2.0]])),
        "visibility index": (".rsi", lambda f: rayscan.visibility(f, observers=[[1.0, 1.0, 2.0]])),
        "solar cloud": (".las", lambda f: rayscan.solar(f, at="2026-06-21T12:00Z", latitude=48.0, longitude=11.0,
                                                        sky_rays=0)),
        "open": (".rsi", lambda f: rayscan.open(f)),
        "open point file": (".laz", lambda f: rayscan.open(f)),
        "read": (".las", lambda f: rayscan.read(f)),
        "read without extension": ("", lambda f: rayscan.read(f)),
    }
    for name, (ext, call) in calls.items():
        missing = str(tmp_path / ("missing" + ext))
        with pytest.raises(FileNotFoundError) as e:
            call(missing)
        assert (e.value.errno, e.value.strerror, e.value.filename) == (errno.ENOENT, os.strerror(errno.ENOENT),
                                                                       missing), name
        assert e.value.__notes__ == [f"{missing}: cannot open file: No such file or directory"], name
        folder = str(tmp_path / ("folder" + ext))
        os.makedirs(folder, exist_ok=True)
        with pytest.raises(IsADirectoryError) as e:
            call(folder)
        assert (e.value.errno, e.value.filename) == (errno.EISDIR, folder), name
        assert e.value.__notes__ == [f"{folder}: is a directory, not a regular file (rayscan reads regular files "
                                     "only)"], name


def test_malformed_files_raise_as_documented(tmp_path):
    """A malformed scene or observer file is a ValueError naming the file (bad content, like a
    bad option); a malformed image or weather file is an OSError naming it (as a point file)."""
    xyz = flat_ground()
    scene = tmp_path / "scene.json"
    scene.write_text("{")
    with pytest.raises(ValueError) as e:
        rayscan.render(scene)
    assert type(e.value) is ValueError and str(e.value).startswith(f"{scene}: byte 2: invalid JSON"), str(e.value)
    obs = tmp_path / "obs.csv"
    obs.write_text("x,y,z\n1,2,abc\n")
    with pytest.raises(ValueError) as e:
        rayscan.visibility(xyz, observers=obs, radius=0.3)
    assert type(e.value) is ValueError and str(e.value).startswith(f"{obs}: line 2"), str(e.value)
    epw = tmp_path / "weather.epw"
    epw.write_text("not a weather file\n")
    with pytest.raises(OSError) as e:
        rayscan.solar(xyz, start="2026-06-21", end="2026-06-21", latitude=48.0, longitude=11.0, weather=epw,
                      sky_rays=0)
    assert str(e.value).startswith(f"{epw}: line 1: expected the header line starting with 'LOCATION,'")
    png = tmp_path / "image.png"
    png.write_bytes(b"not an image")
    with pytest.raises((OSError, RuntimeError)) as e:
        rayscan.compare(png, np.zeros((4, 4, 3), dtype=np.float32))
    if "OpenImageIO module" in str(e.value):
        pytest.skip("built without the OpenImageIO module: image files cannot be read at all")
    assert type(e.value) is OSError and str(e.value).startswith(f"{png}: "), str(e.value)


def test_none_for_the_scene_or_an_image_is_a_type_error():
    img = np.zeros((4, 4, 3), dtype=np.float32)
    with pytest.raises(TypeError) as e:
        rayscan.render(None)
    assert str(e.value) == ("scene must be a scene or point cloud file name (str or os.PathLike), a scene dict, a "
                            "rayscan.PointCloud or an (N, 3) array of coordinates, got NoneType")
    expected = "must be an image file name (str or os.PathLike) or an (H, W) or (H, W, C) array of numbers, got "
    for args, name, got in (((None, img), "reference", "NoneType"), ((img, None), "image", "NoneType"),
                            (({}, img), "reference", "dict")):
        with pytest.raises(TypeError) as e:
            rayscan.compare(*args)
        assert str(e.value) == name + " " + expected + got
