"""NumPy in and out: PointCloud from arrays and structured arrays, subsets,
rayscan.write checked by an independent LAS parser (struct, the ASPRS LAS 1.4 R15 record layout)
and by the readers, rayscan.open on index and COPC files against the in-memory octree, the
version, and the type stubs against the module."""

import ast
import inspect
import pathlib
import re
import struct
import subprocess

import numpy as np
import pytest

import rayscan
from conftest import SOURCE


# ---- An independent LAS 1.4 reader (point formats 6-8, float64 extra bytes) ------------------

def parse_las(path):
    """The header, raw records and extra-byte fields of a LAS 1.4 file written with point format
    6, 7 or 8: dict with scale, offset (3,), X/Y/Z int32, intensity, return_number,
    classification, gps_time, rgb (or None) and extras {name: float64 values}."""
    b = pathlib.Path(path).read_bytes()
    assert b[:4] == b"LASF" and (b[24], b[25]) == (1, 4)
    header_size, = struct.unpack_from("<H", b, 94)
    data_offset, n_vlr = struct.unpack_from("<IL", b, 96)
    pdrf, rec_len = struct.unpack_from("<BH", b, 104)
    scale = np.array(struct.unpack_from("<3d", b, 131))
    offset = np.array(struct.unpack_from("<3d", b, 155))
    n, = struct.unpack_from("<Q", b, 247)
    pdrf &= 0x3F  # bits 6-7 flag compression
    assert pdrf in (6, 7, 8), pdrf
    extras = []
    at = header_size
    for _ in range(n_vlr):
        user, rid, length = struct.unpack_from("<16sHH", b, at + 2)
        body = at + 54
        if user.rstrip(b"\0") == b"LASF_Spec" and rid == 4:
            for k in range(length // 192):
                rec = body + 192 * k
                dtype = b[rec + 2]
                name = b[rec + 4:rec + 36].rstrip(b"\0").decode()
                assert dtype == 10, "expected float64 extra bytes"
                extras.append(name)
        at = body + length
    base = {6: 30, 7: 36, 8: 38}[pdrf]
    fields = [("xyz", "<i4", (3,)), ("intensity", "<u2"), ("returns", "u1"), ("flags", "u1"),
              ("classification", "u1"), ("user_data", "u1"), ("scan_angle", "<i2"),
              ("point_source_id", "<u2"), ("gps_time", "<f8")]
    if pdrf >= 7:
        fields.append(("rgb", "<u2", (3,)))
    if pdrf == 8:
        fields.append(("nir", "<u2"))
    fields += [(e, "<f8") for e in extras]
    assert base + 8 * len(extras) == rec_len
    rec = np.frombuffer(b, dtype=np.dtype(fields), count=n, offset=data_offset)
    return dict(scale=scale, offset=offset, X=rec["xyz"].astype(np.int64), intensity=rec["intensity"],
                return_number=rec["returns"] & 15, classification=rec["classification"],
                gps_time=rec["gps_time"], rgb=rec["rgb"] if pdrf >= 7 else None,
                extras={e: rec[e] for e in extras})


def structured_points(n=500, seed=3, names="pdal"):
    """A structured array as PDAL (or laspy-style code) gives it: coordinates on a 0.01 grid
    (exact in LAS at scale 0.01), 16-bit colour, intensity, class, GPS time, a return number and
    an extra field."""
    rng = np.random.default_rng(seed)
    spelled = {"pdal": ["X", "Y", "Z", "Red", "Green", "Blue", "Intensity", "Classification", "GpsTime",
                        "ReturnNumber", "Amplitude"],
               "laspy": ["x", "y", "z", "red", "green", "blue", "intensity", "classification", "gps_time",
                         "return_number", "Amplitude"]}[names]
    types = ["f8", "f8", "f8", "u2", "u2", "u2", "u2", "u1", "f8", "u1", "f4"]
    a = np.zeros(n, dtype=list(zip(spelled, types)))
    a[spelled[0]] = 500000.0 + rng.integers(0, 100000, n) * 0.01
    a[spelled[1]] = 4000000.0 + rng.integers(0, 100000, n) * 0.01
    a[spelled[2]] = rng.integers(-500, 5000, n) * 0.01
    for f in spelled[3:6]:
        a[f] = rng.integers(0, 65536, n)
    a[spelled[6]] = rng.integers(0, 65536, n)
    a[spelled[7]] = rng.integers(0, 32, n)
    a[spelled[8]] = rng.random(n) * 1e5
    a[spelled[9]] = rng.integers(1, 6, n)
    a[spelled[10]] = rng.random(n).astype(np.float32)
    return a


# ---- PointCloud from arrays ---------------------------------------------------------------

def test_point_cloud_from_arrays_keeps_every_attribute():
    rng = np.random.default_rng(1)
    xyz = rng.random((20, 3))
    rgb8 = rng.integers(0, 256, (20, 3)).astype(np.uint8)
    pc = rayscan.PointCloud(xyz, rgb=rgb8, intensity=np.arange(20), classification=np.full(20, 6),
                            gps_time=np.linspace(0, 1, 20), normals=np.tile([0, 0, 1], (20, 1)),
                            scalars={"height": xyz[:, 2] * 2, "flag": xyz[:, 0] > 0.5}, crs="LOCAL_CS[\"x\"]")
    assert len(pc) == 20 and pc.path is None and pc.format is None
    assert pc.attributes == ["xyz", "rgb", "intensity", "classification", "gps_time", "normals", "height", "flag"]
    np.testing.assert_array_equal(pc.xyz, xyz)
    assert pc.rgb.dtype == np.uint16
    np.testing.assert_array_equal(pc.rgb, rgb8.astype(np.uint16) * 257)  # 8-bit colour scaled: 255 -> 65535
    rgb16 = (rgb8.astype(np.uint16) * 100)
    np.testing.assert_array_equal(rayscan.PointCloud(xyz, rgb=rgb16).rgb, rgb16)  # 16-bit kept
    assert pc.intensity.dtype == np.uint16 and pc.intensity.tolist() == list(range(20))
    assert pc.classification.dtype == np.uint8 and set(pc.classification) == {6}
    np.testing.assert_array_equal(pc.gps_time, np.linspace(0, 1, 20))
    assert pc.normals.dtype == np.float32 and pc.normals[3].tolist() == [0, 0, 1]
    np.testing.assert_array_equal(pc.scalars["height"], xyz[:, 2] * 2)
    np.testing.assert_array_equal(pc.scalars["flag"], (xyz[:, 0] > 0.5).astype(float))
    assert pc.crs == "LOCAL_CS[\"x\"]" and "(arrays)" in repr(pc)


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(xyz=np.zeros((3, 2))), ValueError, r"xyz: expected shape \(N, 3\)"),
    (dict(xyz=[[0, 0, np.nan]]), ValueError, "point 0 has a non-finite coordinate"),
    (dict(rgb=np.zeros((4, 3))), ValueError, "rgb: expected colours of dtype uint8 .* got dtype float64"),
    (dict(rgb=np.zeros((4, 3), np.uint32)), ValueError, "rgb: expected colours of dtype uint8"),
    (dict(rgb=np.zeros((3, 3), np.uint8)), ValueError, r"rgb: .* N = 4 \(as xyz\), got shape \(3, 3\)"),
    (dict(intensity=[1, 2, 3, 70000]), ValueError, r"intensity: values must be in \[0, 65535\], got 70000"),
    (dict(classification=[0, 0, 0, -1]), ValueError, r"classification: values must be in \[0, 255\], got -1"),
    (dict(intensity=[1.5] * 4), ValueError, "intensity: expected integers"),
    (dict(scalars=[1, 2]), TypeError, "scalars must be a dict"),
    (dict(scalars={"rgb": np.zeros(4)}), ValueError, "'rgb' is a PointCloud attribute"),
    (dict(scalars={"s": np.zeros(3)}), ValueError, r"scalars\['s'\]: expected"),
    (dict(crs=4326), TypeError, "crs must be a CRS as GDAL reads it .* or None, got int"),
])
def test_point_cloud_from_bad_arrays(kwargs, error, message):
    args = dict(xyz=np.zeros((4, 3)))
    args.update(kwargs)
    with pytest.raises(error, match=message):
        rayscan.PointCloud(**args)


def test_from_structured_takes_the_crs_and_write_keeps_it(tmp_path):
    wkt = rayscan.read(SOURCE / "scenes" / "data" / "autzen_trim.las").crs
    assert wkt
    pc = rayscan.PointCloud.from_structured(structured_points(names="pdal"), crs=wkt)
    assert pc.crs == wkt
    assert rayscan.PointCloud.from_structured(structured_points(names="pdal")).crs is None
    rayscan.write(tmp_path / "crs.las", pc)
    assert rayscan.read(tmp_path / "crs.las").crs == wkt


def test_from_structured_pdal_and_laspy_names_give_the_same_cloud():
    a = structured_points(names="pdal")
    b = structured_points(names="laspy")
    pa, pb = rayscan.PointCloud.from_structured(a), rayscan.PointCloud.from_structured(b)
    for pc in (pa, pb):
        np.testing.assert_array_equal(pc.xyz, np.column_stack([a["X"], a["Y"], a["Z"]]))
        np.testing.assert_array_equal(pc.rgb, np.column_stack([a["Red"], a["Green"], a["Blue"]]))
        np.testing.assert_array_equal(pc.intensity, a["Intensity"])
        np.testing.assert_array_equal(pc.classification, a["Classification"])
        np.testing.assert_array_equal(pc.gps_time, a["GpsTime"])
        # PDAL's ReturnNumber takes rayscan's (and laspy's) name; other fields keep theirs.
        assert sorted(pc.scalars) == ["Amplitude", "return_number"]
        np.testing.assert_array_equal(pc.scalars["return_number"], a["ReturnNumber"])
        np.testing.assert_array_equal(pc.scalars["Amplitude"], a["Amplitude"].astype(np.float64))
    both = np.zeros(3, dtype=[("X", "f8"), ("x", "f8"), ("Y", "f8"), ("Z", "f8")])
    with pytest.raises(ValueError, match="'X' and 'x' name the same attribute"):
        rayscan.PointCloud.from_structured(both)
    with pytest.raises(ValueError, match="needs the fields X, Y, Z"):
        rayscan.PointCloud.from_structured(np.zeros(3, dtype=[("a", "f8")]))
    with pytest.raises(ValueError, match="go together"):
        rayscan.PointCloud.from_structured(np.zeros(3, dtype=[("X", "f8"), ("Y", "f8"), ("Z", "f8"), ("Red", "u2")]))
    with pytest.raises(ValueError, match="field 'name' has dtype <U4"):
        rayscan.PointCloud.from_structured(np.zeros(3, dtype=[("X", "f8"), ("Y", "f8"), ("Z", "f8"), ("name", "U4")]))
    with pytest.raises(ValueError, match="structured array"):
        rayscan.PointCloud.from_structured(np.zeros((3, 3)))


def test_mask_and_take_select_every_attribute(data_dir):
    pc = rayscan.read(data_dir / "las" / "autzen_trim.las")
    mask = pc.classification == 2
    sub = pc[mask]
    assert len(sub) == mask.sum() > 0 and sub.format == "LAS" and sub.attributes == pc.attributes
    for name in pc.attributes:
        np.testing.assert_array_equal(sub[name], pc[name][mask])
    idx = np.array([5, -1, 5, 0])
    taken = pc.take(idx)
    for name in pc.attributes:
        np.testing.assert_array_equal(taken[name], pc[name][idx])
    np.testing.assert_array_equal(pc[10:20].xyz, pc.xyz[10:20])
    np.testing.assert_array_equal(pc[[3, 1]].xyz, pc.xyz[[3, 1]])
    assert len(pc.take([])) == 0
    with pytest.raises(IndexError):
        pc.take([len(pc)])
    with pytest.raises(IndexError):
        pc[mask[:-1]]
    with pytest.raises(TypeError, match="use pc.take"):
        pc[3]
    with pytest.raises(TypeError, match="use pc\\[mask\\]"):
        pc.take(mask)
    with pytest.raises(KeyError):
        pc["nope"]


# ---- rayscan.write ---------------------------------------------------------------------------

def test_write_las_from_structured_array_reads_back_exactly(tmp_path):
    a = structured_points()
    pc = rayscan.PointCloud.from_structured(a)
    count = np.arange(len(a)) % 7.0
    rayscan.write(tmp_path / "out.las", pc, visible_count=count)
    las = parse_las(tmp_path / "out.las")
    # The independent parser: scaled integers on the 0.01 grid give the input coordinates exactly.
    np.testing.assert_array_equal(las["scale"], [0.01, 0.01, 0.01])
    for axis, name in enumerate("XYZ"):
        np.testing.assert_array_equal(las["X"][:, axis] * 0.01 + las["offset"][axis], a[name])
        np.testing.assert_array_equal(np.round((a[name] - las["offset"][axis]) / 0.01), las["X"][:, axis])
    np.testing.assert_array_equal(las["rgb"], np.column_stack([a["Red"], a["Green"], a["Blue"]]))
    np.testing.assert_array_equal(las["intensity"], a["Intensity"])
    np.testing.assert_array_equal(las["classification"], a["Classification"])
    np.testing.assert_array_equal(las["gps_time"], a["GpsTime"])
    np.testing.assert_array_equal(las["return_number"], a["ReturnNumber"])  # a standard LAS field
    assert sorted(las["extras"]) == ["Amplitude", "visible_count"]
    np.testing.assert_array_equal(las["extras"]["visible_count"], count)
    np.testing.assert_array_equal(las["extras"]["Amplitude"], a["Amplitude"].astype(np.float64))
    # rayscan's own reader agrees, and LAZ holds the same points.
    rayscan.write(tmp_path / "out.laz", pc, visible_count=count)
    for f in ("out.las", "out.laz"):
        back = rayscan.read(tmp_path / f)
        np.testing.assert_array_equal(back.xyz, pc.xyz)
        np.testing.assert_array_equal(back.rgb, pc.rgb)
        np.testing.assert_array_equal(back.scalars["visible_count"], count)


def test_write_las_scale_coarsens_past_two_million_units(tmp_path):
    """Coordinates off every decimal grid get 0.001 per axis, coarsened tenfold while the axis
    spans more than 2e9 steps (32-bit integers): x spanning 3e6 units gets 0.01, y and z 0.001."""
    rng = np.random.default_rng(11)
    xyz = rng.random((200, 3)) * [3.0e6, 1000.0, 10.0] + [5.0e5, 4.0e6, 100.0]
    xyz[0, 0], xyz[1, 0] = 5.0e5, 3.5e6 + 0.123456  # the full x span
    rayscan.write(tmp_path / "wide.las", xyz)
    las = parse_las(tmp_path / "wide.las")
    np.testing.assert_array_equal(las["scale"], [0.01, 0.001, 0.001])
    back = las["X"] * las["scale"] + las["offset"]
    assert np.all(np.abs(back - xyz).max(axis=0) <= np.array([0.005, 0.0005, 0.0005]) * (1 + 1e-6))
    assert np.abs(back[:, 0] - xyz[:, 0]).max() > 0.0005  # not to the nearest 0.001
    np.testing.assert_array_equal(rayscan.read(tmp_path / "wide.las").xyz, back)


@pytest.mark.parametrize("name", ["out.ply", "out.pcd", "out.xyz", "out.txt", "out.csv"])
def test_write_other_formats_round_trip(tmp_path, name):
    rng = np.random.default_rng(9)
    xyz = rng.random((50, 3)) * 1000
    pc = rayscan.PointCloud(xyz, intensity=np.arange(50), classification=np.arange(50) % 3)
    rayscan.write(tmp_path / name, pc, score=xyz[:, 0] / 3)
    back = rayscan.read(tmp_path / name)
    np.testing.assert_array_equal(back.xyz, xyz)  # double coordinates written exactly
    np.testing.assert_array_equal(back.intensity, np.arange(50))
    np.testing.assert_array_equal(back.scalars["score"], xyz[:, 0] / 3)


def test_write_fields_go_to_the_file_not_to_the_cloud(tmp_path):
    """write(path, cloud, **fields) writes the cloud plus the fields (a field replacing a scalar of
    its name) and leaves the PointCloud, its views and an array argument as they were."""
    rng = np.random.default_rng(5)
    xyz = rng.random((40, 3)) * 100
    score, other, new = xyz[:, 0] / 7, xyz[:, 1] / 3, np.arange(40) * 0.5
    pc = rayscan.PointCloud(xyz, intensity=np.arange(40), scalars={"score": score, "other": other})
    view = pc.scalars["score"]
    rayscan.write(tmp_path / "pc.ply", pc, score=new, extra=-new)
    back = rayscan.read(tmp_path / "pc.ply")
    assert list(back.scalars) == ["score", "other", "extra"]
    np.testing.assert_array_equal(back.xyz, xyz)
    np.testing.assert_array_equal(back.intensity, np.arange(40))
    np.testing.assert_array_equal(back.scalars["score"], new)
    np.testing.assert_array_equal(back.scalars["other"], other)
    np.testing.assert_array_equal(back.scalars["extra"], -new)
    assert list(pc.scalars) == ["score", "other"]
    np.testing.assert_array_equal(pc.scalars["score"], score)
    np.testing.assert_array_equal(view, score)
    copy = xyz.copy()
    rayscan.write(tmp_path / "array.ply", xyz, extra=new)  # an array's cloud takes the field in place
    back = rayscan.read(tmp_path / "array.ply")
    np.testing.assert_array_equal(back.xyz, copy)
    np.testing.assert_array_equal(back.scalars["extra"], new)
    np.testing.assert_array_equal(xyz, copy)
    with pytest.raises(ValueError, match=r"^cloud: PointCloud: point 1 has a non-finite coordinate"):
        rayscan.write(tmp_path / "nan.ply", np.array([[0.0, 0, 0], [np.nan, 0, 0]]), extra=[1.0, 2.0])


def test_write_keeps_the_source_grid_and_refuses_bad_requests(data_dir, tmp_path):
    src = data_dir / "las" / "autzen_trim.las"
    pc = rayscan.read(src)
    rayscan.write(tmp_path / "copy.las", pc[pc.classification == 2])
    # Independent check: the raw integers are the source's (the rows kept), on its scale/offset.
    a = rayscan.read(tmp_path / "copy.las")
    np.testing.assert_array_equal(a.xyz, pc.xyz[pc.classification == 2])
    rayscan.write(tmp_path / "array.las", pc.xyz)  # an (N, 3) array is a cloud too
    np.testing.assert_array_equal(rayscan.read(tmp_path / "array.las").xyz, pc.xyz)
    with pytest.raises(ValueError, match="expected a file name ending in"):
        rayscan.write(tmp_path / "out.foo", pc)
    with pytest.raises(ValueError, match="copc"):
        rayscan.write(tmp_path / "out.copc.laz", pc)
    with pytest.raises(ValueError, match="'intensity' is a PointCloud attribute"):
        rayscan.write(tmp_path / "out.las", pc, intensity=np.zeros(len(pc)))
    with pytest.raises(ValueError, match=r"count: expected .* N = "):
        rayscan.write(tmp_path / "out.las", pc, count=np.zeros(3))
    with pytest.raises(TypeError, match="cloud must be a rayscan.PointCloud or an \\(N, 3\\) array"):
        rayscan.write(tmp_path / "out.las", str(src))
    with pytest.raises(OSError):
        rayscan.write(tmp_path / "missing" / "out.las", pc)


# ---- Jobs take a path, a PointCloud or an (N, 3) array ----------------------------------------

pytestmark_jobs = pytest.mark.skipif(not hasattr(rayscan, "render"),
                                     reason="module built without the library's job API")


def wall_scene():
    """A ground grid and a wall, on a 0.25 grid (exact in LAS at scale 0.01)."""
    g = np.arange(0, 20, 0.5)
    gx, gy = np.meshgrid(g, g)
    ground = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    wy, wz = np.meshgrid(np.arange(-5, 25, 0.25), np.arange(0, 6, 0.25))
    wall = np.column_stack([np.full(wy.size, 10.0), wy.ravel(), wz.ravel()])
    return np.vstack([ground, wall])


@pytestmark_jobs
def test_visibility_of_an_array_equals_that_of_the_las_file(tmp_path):
    xyz = wall_scene()
    rayscan.write(tmp_path / "wall.las", xyz)
    eyes = [[2.0, 10.0, 1.7], [15.0, 3.0, 1.7]]
    from_file = rayscan.visibility(tmp_path / "wall.las", observers=eyes, radius=0.3)
    from_array = rayscan.visibility(xyz, observers=eyes, radius=0.3)
    from_cloud = rayscan.visibility(rayscan.read(tmp_path / "wall.las"), observers=eyes, radius=0.3)
    assert from_file["visible_count"].sum() > 0
    for r in (from_array, from_cloud):
        np.testing.assert_array_equal(r["visible_count"], from_file["visible_count"])
        np.testing.assert_array_equal(r["per_observer"], from_file["per_observer"])
    with pytest.raises(TypeError, match=r"cloud must be a file name \(str or os.PathLike\), a rayscan.PointCloud "
                                        r"or an \(N, 3\) array of coordinates, got int"):
        rayscan.visibility(42, observers=eyes)
    with pytest.raises(ValueError, match=r"cloud: expected shape \(N, 3\)"):
        rayscan.visibility(xyz[:, :2], observers=eyes)
    out = rayscan.solar(xyz, at="2026-06-21T12:00:00Z", latitude=48.0, longitude=11.0, sky_rays=0)
    ref = rayscan.solar(tmp_path / "wall.las", at="2026-06-21T12:00:00Z", latitude=48.0, longitude=11.0,
                        sky_rays=0)
    np.testing.assert_array_equal(out["in_shadow"], ref["in_shadow"])


@pytestmark_jobs
def test_render_quick_look_of_a_point_cloud_equals_that_of_its_file(tmp_path, monkeypatch):
    path = SOURCE / "scenes" / "data" / "autzen_trim.las"
    pc = rayscan.read(path)
    opts = dict(width=48, spp=1, aovs=["index"])
    from_path = rayscan.render(path, **opts)
    assert from_path["beauty"].shape == (32, 48, 3)  # the overview camera's 3:2 aspect
    assert (from_path["index"] >= 0).mean() > 0.3
    from_cloud = rayscan.render(pc, **opts)
    np.testing.assert_array_equal(from_cloud["beauty"], from_path["beauty"])
    np.testing.assert_array_equal(from_cloud["index"], from_path["index"])
    # The quick look is the scene {"cloud", radius auto, surfels, colour}: the same dict without a
    # camera gets the same overview camera.
    monkeypatch.chdir(path.parent)
    scene = {"cloud": path.name, "radius": "auto", "primitive": "surfel", "material": {"color": "rgb"}}
    np.testing.assert_array_equal(rayscan.render(scene, **opts)["beauty"], from_path["beauty"])
    # Positions alone (no colour): the array and a PointCloud of it render alike.
    a = rayscan.render(pc.xyz, width=32, spp=1)
    b = rayscan.render(rayscan.PointCloud(pc.xyz), width=32, spp=1)
    np.testing.assert_array_equal(a["beauty"], b["beauty"])


@pytestmark_jobs
def test_render_errors_name_the_dict_and_the_cloud(tmp_path):
    path = SOURCE / "scenes" / "data" / "autzen_trim.las"
    with pytest.raises(ValueError, match=r"^scene dict: /camera: expected a camera file name or a camera object"):
        rayscan.render({"cloud": str(path), "camera": 5})
    with pytest.raises(ValueError, match=r"^scene dict: /spp: expected an integer"):
        rayscan.render({"cloud": str(path), "spp": 0})
    with pytest.raises(ValueError, match=r"^scene dict: /cloud: required"):
        rayscan.render({"spp": 1})
    missing = tmp_path / "missing.las"
    with pytest.raises(Exception) as e:
        rayscan.render(missing)
    assert "missing.las" in str(e.value) and "invalid JSON" not in str(e.value)
    with pytest.raises(TypeError, match=r"scene must be a scene or point cloud file name .* got int"):
        rayscan.render(42)
    with pytest.raises(TypeError, match="do not give cloud= too"):
        rayscan.render(np.zeros((4, 3)), cloud=np.zeros((4, 3)))


@pytestmark_jobs
def test_ortho_map_dsm_of_a_flat_roof_is_its_height(tmp_path):
    """A 0.25 m grid at z = 5 over 20 x 20 m with a 4 x 4 m block at z = 8: the DSM is 5 on the
    plane and 8 on the block's top (analytic), and a PointCloud, its array and its file agree."""
    g = np.arange(0, 20, 0.25)
    gx, gy = np.meshgrid(g, g)
    z = np.where((gx >= 8) & (gx < 12) & (gy >= 8) & (gy < 12), 8.0, 5.0)
    xyz = np.column_stack([gx.ravel(), gy.ravel(), z.ravel()])
    rayscan.write(tmp_path / "roof.las", xyz)
    out = rayscan.ortho_map(xyz, 1.0, spp=1)
    rows, cols = out["dsm"].shape
    assert out["image"].shape == (rows, cols, 3) and (rows, cols) == (20, 20)
    x0, res, _, y_top, _, neg = out["geotransform"]
    assert (x0, res, y_top, neg) == (0.0, 1.0, 20.0, -1.0)
    cx, cy = x0 + (np.arange(cols) + 0.5) * res, y_top - (np.arange(rows) + 0.5) * res
    on_block = ((cx[None, :] > 8.5) & (cx[None, :] < 11.5)) & ((cy[:, None] > 8.5) & (cy[:, None] < 11.5))
    off_block = ~(((cx[None, :] > 7) & (cx[None, :] < 13)) & ((cy[:, None] > 7) & (cy[:, None] < 13)))
    inside = (cx[None, :] > 1) & (cx[None, :] < 19) & (cy[:, None] > 1) & (cy[:, None] < 19)
    np.testing.assert_allclose(out["dsm"][on_block], 8.0, atol=1e-4)
    np.testing.assert_allclose(out["dsm"][off_block & inside], 5.0, atol=1e-4)
    for other in (rayscan.ortho_map(tmp_path / "roof.las", 1.0, spp=1),
                  rayscan.ortho_map(rayscan.read(tmp_path / "roof.las"), 1.0, spp=1)):
        np.testing.assert_array_equal(other["dsm"], out["dsm"])
        np.testing.assert_array_equal(other["image"], out["image"])
    with pytest.raises(ValueError, match="res: expected a finite number > 0"):
        rayscan.ortho_map(xyz, 0.0)
    with pytest.raises(ValueError, match="expected a point cloud file"):
        rayscan.ortho_map(SOURCE / "scenes" / "autzen_overview.json", 1.0)


@pytestmark_jobs
def test_ortho_map_image_is_the_points_own_colour():
    """Two flat 10 x 10 squares of 16-bit colours v * 257 (left) and v * 256 (right): with the
    default colour="albedo" every cell more than a cell from the squares' edges holds its
    square's 8-bit sRGB colour v (+-1) once the linear image is sRGB-encoded with the standard's
    formula; colour="shaded" is the lit render, not those colours; another colour is refused."""
    colours = np.array([[200, 60, 30], [40, 120, 230]])
    g = np.arange(0.125, 20, 0.25)
    gx, gy = np.meshgrid(g, np.arange(0.125, 10, 0.25))
    left = gx.ravel() < 10
    rgb = np.where(left[:, None], colours[0] * 257, colours[1] * 256).astype(np.uint16)
    cloud = rayscan.PointCloud(np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, 3.0)]), rgb=rgb)
    out = rayscan.ortho_map(cloud, 1.0)
    shaded = rayscan.ortho_map(cloud, 1.0, spp=4, colour="shaded")
    assert out["image"].shape == shaded["image"].shape == (10, 20, 3)
    x0, res, _, y_top, _, _ = out["geotransform"]
    cx = x0 + (np.arange(20) + 0.5) * res
    cy = y_top - (np.arange(10) + 0.5) * res

    def srgb8(linear):
        v = np.clip(linear.astype(np.float64), 0, 1)
        return np.round(255 * np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055))

    inner = (cy[:, None] > 1) & (cy[:, None] < 9) & (cx[None, :] > 1) & (cx[None, :] < 19) \
        & (np.abs(cx[None, :] - 10) > 1)
    want = np.where((cx[None, :] < 10)[..., None], colours[0], colours[1]) * np.ones((10, 1, 1))
    assert inner.sum() == 128
    np.testing.assert_allclose(srgb8(out["image"])[inner], want[inner], atol=1)
    assert (np.abs(srgb8(shaded["image"])[inner] - want[inner]).max(axis=1) > 10).all()
    np.testing.assert_array_equal(shaded["dsm"], out["dsm"])
    with pytest.raises(ValueError, match="colour 'flat': expected albedo or shaded"):
        rayscan.ortho_map(cloud, 1.0, colour="flat")


@pytestmark_jobs
def test_ortho_map_coverage_is_the_geotiffs_alpha_band(tmp_path, cli):
    """coverage is the alpha band `rayscan render CLOUD --ortho-map RES --out x.tif` writes, read
    back by GDAL (stored as round(255 x coverage)): with colour="albedo" the share of the cell's
    rays that hit, fractional on the rim of a round hole in a sloped plane; with "shaded" 1 where
    the cell-centre ray hit, else 0."""
    gdal = pytest.importorskip("osgeo.gdal")
    g = np.arange(0, 20, 0.25)
    gx, gy = np.meshgrid(g, g)
    keep = ((gx - 10) ** 2 + (gy - 10) ** 2 >= 16).ravel()
    xyz = np.column_stack([gx.ravel(), gy.ravel(), 5.0 + 0.1 * gx.ravel()])[keep]
    las = tmp_path / "holed.las"
    rayscan.write(las, xyz)
    for colour, spp in (("albedo", 16), ("shaded", 2)):
        out = rayscan.ortho_map(las, 0.5, spp=spp, colour=colour)
        tif = tmp_path / f"{colour}.tif"
        subprocess.run([cli, "render", str(las), "--ortho-map", "0.5", "--ortho-colour", colour,
                        "--spp", str(spp), "--out", str(tif)], check=True, capture_output=True)
        ds = gdal.Open(str(tif))
        assert ds.RasterCount == 4 and ds.GetRasterBand(4).GetColorInterpretation() == gdal.GCI_AlphaBand
        assert ds.GetGeoTransform() == pytest.approx(out["geotransform"], abs=0)
        alpha = ds.GetRasterBand(4).ReadAsArray()
        coverage = out["coverage"]
        assert coverage.dtype == np.float32 and coverage.shape == alpha.shape == out["dsm"].shape
        assert ((coverage >= 0) & (coverage <= 1)).all()
        # The writer's rounding: lround(255.0f * coverage), half away from zero.
        np.testing.assert_array_equal(alpha, np.floor((np.float32(255) * coverage).astype(np.float64) + 0.5))
        partial = (coverage > 0) & (coverage < 1)
        assert (coverage == 0).any() and (coverage == 1).any()
        assert partial.any() if colour == "albedo" else not partial.any()


# ---- Names: first("index"), ray_query's bound --------------------------------------------------

def test_ray_query_without_a_bound_raises_unless_allow_all(uniform_cloud, random_rays):
    o, d = random_rays
    tree = rayscan.Octree(uniform_cloud)
    with pytest.raises(ValueError, match="neither k nor a finite radius.*allow_all=True"):
        tree.ray_query(o, d)
    with pytest.raises(ValueError, match="neither k nor a finite radius"):
        tree.ray_query(o, d, radius=float("inf"), t_min=0.0)
    everything = tree.ray_query(o[:3], d[:3], allow_all=True)
    assert everything.counts.tolist() == [len(uniform_cloud)] * 3
    assert tree.ray_query(o, d, any_hit=True).counts.max() <= 1  # any_hit bounds it too
    hits = tree.ray_query(o, d, k=1, radius=0.05)
    np.testing.assert_array_equal(hits.first("index"), hits.first("indices"))
    with pytest.raises(ValueError, match="field 'idx' is not one of indices, t, distance"):
        hits.first("idx")


# ---- rayscan.open: index files and COPC in place ----------------------------------------------

def test_open_index_file_answers_like_the_in_memory_octree(cli, tmp_path, data_dir):
    src = data_dir / "las" / "autzen_trim.las"
    rsi = tmp_path / "autzen.rsi"
    subprocess.run([cli, "index", "-q", "--attributes", "id", "-o", str(rsi), str(src)], check=True)
    site = rayscan.open(rsi)
    pc = rayscan.read(src)
    assert site.storage == "index_file" and len(site) == len(pc) and "index_file" in repr(site)
    tree = rayscan.Octree(pc)
    lo, hi = pc.bounds
    rng = np.random.default_rng(4)
    o = np.column_stack([rng.uniform(lo[0], hi[0], 200), rng.uniform(lo[1], hi[1], 200), np.full(200, hi[2] + 50)])
    for q in (dict(k=1, radius=3.0, order="sphere_hit"), dict(k=5, radius=10.0)):
        a, b = site.ray_query(o, [0, 0, -1], **q), tree.ray_query(o, [0, 0, -1], **q)
        np.testing.assert_array_equal(a.indices, b.indices)
        np.testing.assert_array_equal(a.t, b.t)
    a, b = site.knn(pc.xyz[::500], k=4), tree.knn(pc.xyz[::500], k=4)
    np.testing.assert_array_equal(a.indices, b.indices)
    with pytest.raises(OSError):
        rayscan.open(tmp_path / "missing.rsi")


def test_open_copc_queries_in_place(data_dir):
    path = data_dir / "laz" / "lone-star.copc.laz"
    site = rayscan.open(path)
    pc = rayscan.read(path)
    assert site.storage == "copc" and len(site) == len(pc)
    tree = rayscan.Octree(pc)
    sample = pc.xyz[:: max(1, len(pc) // 50)]
    a, b = site.knn(sample, k=3), tree.knn(sample, k=3)
    np.testing.assert_array_equal(a.distance, b.distance)
    np.testing.assert_array_equal(pc.xyz[a.indices], pc.xyz[b.indices])
    lo, hi = pc.bounds
    o = np.column_stack([sample[:, 0], sample[:, 1], np.full(len(sample), hi[2] + 10)])
    ra, rb = site.ray_query(o, [0, 0, -1], k=1, radius=1.0), tree.ray_query(o, [0, 0, -1], k=1, radius=1.0)
    np.testing.assert_array_equal(ra.t, rb.t)


def test_site_close_releases_the_file_as_a_closed_file_does(cli, tmp_path, data_dir):
    # The kernel's list of this process's mappings (/proc/self/maps) holds the index file while
    # the Site is open and not once it is closed; every later use raises ValueError as a closed
    # file's does, and closing again does nothing. A Site is a context manager.
    src = data_dir / "las" / "autzen_trim.las"
    rsi = tmp_path / "close.rsi"
    subprocess.run([cli, "index", "-q", "-o", str(rsi), str(src)], check=True)

    def mapped():
        return str(rsi) in pathlib.Path("/proc/self/maps").read_text()

    q = rayscan.read(src).xyz[:10]
    with rayscan.open(rsi) as site:
        assert mapped() and not site.closed and len(site) == 110000
        assert site.knn(q, k=1).counts.tolist() == [1] * 10
    assert site.closed and not mapped()
    for use in (lambda: site.knn(q, k=1), lambda: site.radius(q, 1.0), lambda: site.box(q[0], q[1]),
                lambda: site.ray_query(q, [0, 0, -1], k=1, radius=1.0), lambda: len(site),
                lambda: site.storage, lambda: site.has_ids):
        with pytest.raises(ValueError) as e:
            use()
        assert str(e.value) == "I/O operation on closed site"
    site.close()
    assert site.path == str(rsi) and repr(site) == f"<rayscan.Site {rsi}: closed>"
    # A COPC file and a point file read whole close alike.
    for path in (data_dir / "laz" / "lone-star.copc.laz", src):
        site = rayscan.open(path)
        site.knn(q, k=1)
        site.close()
        with pytest.raises(ValueError, match="^I/O operation on closed site$"):
            site.knn(q, k=1)


def test_site_close_waits_for_the_queries_of_other_threads(data_dir):
    # close() from another thread while a batch runs: the batch either ends whole (close waited
    # for it) or raises the closed site's ValueError, never a crash or a partial answer.
    from concurrent.futures import ThreadPoolExecutor
    pc = rayscan.read(data_dir / "las" / "autzen_trim.las")
    site = rayscan.open(data_dir / "las" / "autzen_trim.las")
    want = rayscan.Octree(pc).knn(pc.xyz, k=4).indices
    with ThreadPoolExecutor(1) as pool:
        running = pool.submit(lambda: site.knn(pc.xyz, k=4, threads=1))
        site.close()
        try:
            np.testing.assert_array_equal(running.result().indices, want)
        except ValueError as e:
            assert str(e) == "I/O operation on closed site"
    assert site.closed


def test_open_copc_from_threads_with_a_small_cache(data_dir):
    # Queries from four threads at once on a COPC site with a 1 MiB cache, which is trimmed
    # between the threads' calls (never during one): the answers equal one thread's on an
    # in-memory octree of the same points, batch by batch.
    from concurrent.futures import ThreadPoolExecutor
    path = data_dir / "laz" / "lone-star.copc.laz"
    site = rayscan.open(path, cache="1M")
    pc = rayscan.read(path)
    tree = rayscan.Octree(pc)
    rng = np.random.default_rng(5)
    batches = [pc.xyz[rng.integers(0, len(pc), 400)] for _ in range(16)]
    want = [tree.knn(b, k=4).distance for b in batches]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda b: site.knn(b, k=4, threads=1).distance, batches))
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    with pytest.raises(ValueError, match="cache"):
        rayscan.open(path, cache="lots")


# ---- Version and type stubs --------------------------------------------------------------------

def test_version_is_the_project_version(cli):
    text = (SOURCE / "CMakeLists.txt").read_text()
    project = re.search(r"project\(rayscan VERSION ([0-9.]+)", text).group(1)
    assert rayscan.__version__ == project
    out = subprocess.run([cli, "version", "--json"], check=True, capture_output=True, text=True).stdout
    assert f'"version": "{project}"' in out


def stub_functions(path):
    tree = ast.parse(pathlib.Path(path).read_text())
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            out[node.name] = node
        elif isinstance(node, ast.FunctionDef) and node.col_offset == 0:
            out[node.name] = node
    return out


def test_stubs_ship_with_the_module_and_match_its_signatures():
    here = pathlib.Path(rayscan.__file__).parent
    for f in ("__init__.pyi", "_rayscan.pyi", "py.typed"):
        assert (here / f).exists(), f
    stubs = stub_functions(here / "__init__.pyi")
    for name in rayscan.__all__:
        assert name in stubs or name in ("PointCloud", "RayQueryResult", "NeighborResult", "BoxResult"), name
    # Every public Python function and query method has the stub's parameters, in order.
    for name, obj in inspect.getmembers(rayscan, inspect.isfunction):
        if name.startswith("_"):
            continue
        params = [a.arg for a in stubs[name].args.args + stubs[name].args.kwonlyargs]
        if stubs[name].args.kwarg:
            params.append(stubs[name].args.kwarg.arg)
        assert params == list(inspect.signature(obj).parameters), name
    mixin = {n.name: n for n in stubs["_QueriesMixin"].body if isinstance(n, ast.FunctionDef)}
    for name, fn in mixin.items():
        actual = list(inspect.signature(getattr(rayscan.Octree, name)).parameters)
        assert [a.arg for a in fn.args.args] == actual, name
    # The extension's stub names every PointCloud member.
    cloud = stub_functions(here / "_rayscan.pyi")["PointCloud"]
    members = {n.name for n in cloud.body if isinstance(n, ast.FunctionDef)}
    public = {m for m in dir(rayscan.PointCloud) if not m.startswith("_")}
    assert public <= members, public - members
