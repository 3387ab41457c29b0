"""PointCloud subsets by any slice, the PLY round trip of named fields, the crs argument, the
read-only scalars mapping and the errors of read and take, each against an independent oracle:
NumPy's own indexing, the PLY file's own header and bytes, GDAL's osr and `rayscan info`, errno."""

import errno
import json
import pathlib
import re
import subprocess

import numpy as np
import pytest

import rayscan

SLICES = [slice(None, None, s) for s in (-3, -2, -1, 1, 2, 3)] + [
    slice(3, 0, -1), slice(0, 3, -1), slice(5, 5), slice(7, 2), slice(-4, None, 2), slice(None, -4, -3),
    slice(-100, 100, 2), slice(100, -100, -3), slice(2, 1000), slice(1000, 2000), slice(-1000, -900, -1),
    slice(None, None, 7), slice(1, -1, 3),
]


def small_cloud(n=11):
    """A cloud of n points with every attribute, each column distinct per point."""
    i = np.arange(n)
    return rayscan.PointCloud(
        np.column_stack([i * 1.5, i * 2.0 + 1, -i * 0.25]),
        rgb=np.column_stack([i, i + 100, i + 200]).astype(np.uint16) * 7,
        intensity=i * 3, classification=i % 7, gps_time=i * 0.5 + 1e5,
        normals=np.column_stack([np.cos(i), np.sin(i), np.zeros(n)]),
        scalars={"score": i ** 2.0, "flag": i % 2 == 0})


@pytest.mark.parametrize("s", SLICES, ids=str)
def test_slice_equals_numpy_slicing_of_every_attribute(s):
    pc = small_cloud()
    sub = pc[s]
    assert len(sub) == len(pc.xyz[s])
    # An empty cloud has no place for an attribute's absence besides an empty array, so only the
    # positions and scalar fields of an empty subset are there.
    kept = pc.attributes if len(sub) else ["xyz", "score", "flag"]
    assert sub.attributes == kept
    for name in kept:
        np.testing.assert_array_equal(sub[name], pc[name][s], err_msg=name)


@pytest.mark.parametrize("s", [slice(None, None, -1), slice(None, None, 2), slice(-5, 10, -7)], ids=str)
def test_slice_of_a_read_cloud_equals_numpy_slicing(data_dir, s):
    pc = rayscan.read(data_dir / "las" / "autzen_trim.las")
    sub = pc[s]
    for name in pc.attributes:
        np.testing.assert_array_equal(sub[name], pc[name][s], err_msg=name)


def test_unsigned_indices_past_the_end_raise_index_error():
    pc = small_cloud()
    for bad in (np.array([2 ** 64 - 1], np.uint64), np.array([len(pc)], np.uint64), np.array([0, 11], np.uint8)):
        with pytest.raises(IndexError, match=f"index {bad.max()} is out of bounds"):
            pc.take(bad)
        with pytest.raises(IndexError, match=f"index {bad.max()} is out of bounds"):
            pc[bad]
    ok = np.array([10, 0, 10], np.uint64)
    np.testing.assert_array_equal(pc.take(ok).xyz, pc.xyz[ok.astype(np.int64)])
    np.testing.assert_array_equal(pc[ok].xyz, pc.xyz[ok.astype(np.int64)])


def ply_body(path):
    """The vertex properties (name, dtype) and values of a binary little-endian PLY file, parsed
    from its own header (the PLY 1.0 layout), independent of rayscan's reader."""
    b = pathlib.Path(path).read_bytes()
    end = b.index(b"end_header\n") + len(b"end_header\n")
    types = {"double": "<f8", "float": "<f4", "uchar": "u1"}
    props, n = [], None
    for line in b[:end].decode().splitlines():
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            n = int(w[2])
        elif w[0] == "property":
            props.append((w[2], types[w[1]]))
    return props, np.frombuffer(b, dtype=np.dtype(props), count=n, offset=end)


# Names a PLY reader takes for positions, normals, colour or alpha when unprefixed.
ROLE_NAMES = ["a", "alpha", "nx", "ny", "nz", "normal_x", "red", "green", "blue", "r", "g", "b",
              "diffuse_red", "x", "y", "z", "class", "scalar_x", "visible_count", "Amplitude"]


def test_ply_round_trip_keeps_every_field_name(tmp_path):
    rng = np.random.default_rng(5)
    xyz = rng.uniform(-100, 100, (9, 3))
    fields = {name: rng.normal(size=9) * (k + 1) for k, name in enumerate(ROLE_NAMES)}
    out = tmp_path / "n.ply"
    rayscan.write(out, rayscan.PointCloud(xyz), **fields)
    props, body = ply_body(out)
    assert [p for p, _ in props] == ["x", "y", "z"] + ["scalar_" + n for n in ROLE_NAMES]
    back = rayscan.read(out)
    assert back.attributes == ["xyz"] + ROLE_NAMES
    assert back.normals is None and back.rgb is None
    np.testing.assert_array_equal(back.xyz, np.column_stack([body["x"], body["y"], body["z"]]))
    for name, values in fields.items():
        np.testing.assert_array_equal(body["scalar_" + name], values, err_msg=name)
        np.testing.assert_array_equal(back.scalars[name], values, err_msg=name)


def test_ply_with_real_normals_and_colour_keeps_same_named_fields(tmp_path):
    pc = small_cloud(6)
    out = tmp_path / "both.ply"
    nx, red = np.linspace(-1, 1, 6), np.arange(6) * 0.5
    rayscan.write(out, pc, nx=nx, red=red)
    back = rayscan.read(out)
    np.testing.assert_array_equal(back.normals, pc.normals)
    np.testing.assert_array_equal(back.rgb, pc.rgb // 257 * 257 + (pc.rgb % 257 >= 129) * 257)
    np.testing.assert_array_equal(back.scalars["nx"], nx)
    np.testing.assert_array_equal(back.scalars["red"], red)


@pytest.mark.parametrize("name, becomes", [
    ("gpstime", "as the gps_time attribute"), ("GPS_Time", "as the gps_time attribute"),
    ("Intensity", "as the intensity attribute"), ("CLASSIFICATION", "as the classification attribute"),
    ("ReturnNumber", "as 'return_number'"), ("ScanAngleRank", "as 'scan_angle'"), ("Infrared", "as 'nir'"),
])
@pytest.mark.parametrize("ext", ["ply", "pcd", "xyz"])
def test_write_refuses_a_name_that_reads_back_as_another_field(tmp_path, name, becomes, ext):
    out = tmp_path / f"c.{ext}"
    with pytest.raises(ValueError, match=f"^write: field '{name}' would read back from .*c.{ext} {becomes}"):
        rayscan.write(out, np.zeros((3, 3)), **{name: np.arange(3.0)})
    assert not out.exists()
    # LAS keeps an extra-bytes field by its own name.
    las = tmp_path / "c.las"
    rayscan.write(las, np.zeros((3, 3)), **{name: np.arange(3.0)})
    np.testing.assert_array_equal(rayscan.read(las).scalars[name], np.arange(3.0))


@pytest.mark.parametrize("name, becomes, exts", [
    ("nx", "as the normals", ["pcd", "xyz", "csv"]), ("normal_x", "as the normals", ["pcd"]),
    ("red", "as the colour", ["pcd", "xyz", "csv"]), ("B", "as the colour", ["pcd", "csv"]),
    ("X", "as the positions", ["pcd", "csv"]), ("i", "as the intensity attribute", ["xyz"]),
])
def test_write_refuses_for_pcd_and_text_a_name_their_readers_take_for_an_attribute(tmp_path, name, becomes, exts):
    values = np.array([0.25, -0.5, 7.0])
    for ext in exts:
        out = tmp_path / f"c.{ext}"
        with pytest.raises(ValueError, match=f"^write: field '{name}' would read back from .*c.{ext} {becomes}; "
                                             "use another name, or write PLY or LAS, which keep it$"):
            rayscan.write(out, np.zeros((3, 3)), **{name: values})
        assert not out.exists()
    # PLY keeps the name (its writer's scalar_ prefix).
    ply = tmp_path / "c.ply"
    rayscan.write(ply, np.zeros((3, 3)), **{name: values})
    back = rayscan.read(ply)
    np.testing.assert_array_equal(back.scalars[name], values)
    assert back.normals is None and back.rgb is None and back.intensity is None


def pcd_fields(path):
    """The FIELDS names and the DATA binary records (every field F 8 here) of a PCD file, from its bytes."""
    b = path.read_bytes()
    end = b.index(b"DATA binary\n") + len(b"DATA binary\n")
    header = b[:end].decode().splitlines()
    names = next(line.split()[1:] for line in header if line.startswith("FIELDS"))
    assert next(line.split()[1:] for line in header if line.startswith("SIZE")) == ["8"] * len(names)
    return names, np.frombuffer(b, dtype=[(n, "<f8") for n in names], offset=end)


def test_a_cloud_scalar_named_like_an_attribute_reads_back_from_pcd_and_text_under_a_suffix(tmp_path):
    # A cloud's own scalar (from PointCloud(scalars=) or a LAS extra-bytes field) is written, with a
    # suffix where the reader would take its name for an attribute: never read back as normals.
    xyz = np.array([[0.1, 2.0, 3.0], [4.0, 5.3, 6.0]])
    scalars = {"nx": np.array([0.5, -0.5]), "red": np.array([200.0, 3.0]), "score": np.array([1.5, 2.5])}
    pc = rayscan.PointCloud(xyz, scalars=scalars)
    pcd = tmp_path / "s.pcd"
    rayscan.write(pcd, pc)
    names, body = pcd_fields(pcd)
    assert names == ["x", "y", "z", "nx_1", "red_1", "score"]
    csv = tmp_path / "s.csv"
    rayscan.write(csv, pc)
    assert csv.read_text().splitlines()[0] == "x,y,z,nx_1,red_1,score"
    for out in (pcd, csv):
        back = rayscan.read(out)
        assert back.normals is None and back.rgb is None, out
        assert list(back.scalars) == ["nx_1", "red_1", "score"], out
        for name, written in zip(["nx", "red", "score"], ["nx_1", "red_1", "score"]):
            np.testing.assert_array_equal(back.scalars[written], scalars[name])
            if out is pcd:
                np.testing.assert_array_equal(body[written], scalars[name])


def test_a_cloud_scalar_named_like_a_dedicated_field_reads_back_from_ply_under_a_suffix(tmp_path, cli):
    # PLY as PCD and text: the reader strips "scalar_" and takes gpstime, GPSTime, Intensity for
    # that attribute, so the writer gives the cloud's own scalar a suffix; rayscan translate writes
    # the same names. Oracle: the file's own header and records (ply_body).
    xyz = np.array([[0.1, 2.0, 3.0], [4.0, 5.3, 6.0]])
    scalars = {"gpstime": np.array([5.5, 6.0]), "GPSTime": np.array([7.0, 8.0]),
               "Intensity": np.array([3.0, 4.0]), "score": np.array([1.5, 2.5])}
    out = tmp_path / "s.ply"
    rayscan.write(out, rayscan.PointCloud(xyz, scalars=scalars))
    props, body = ply_body(out)
    written = ["scalar_gpstime_1", "scalar_GPSTime_1", "scalar_Intensity_1", "scalar_score"]
    assert [p for p, _ in props] == ["x", "y", "z"] + written
    back = rayscan.read(out)
    assert back.gps_time is None and back.intensity is None
    assert list(back.scalars) == [w[len("scalar_"):] for w in written]
    for name, w in zip(scalars, written):
        np.testing.assert_array_equal(body[w], scalars[name], err_msg=w)
        np.testing.assert_array_equal(back.scalars[w[len("scalar_"):]], scalars[name], err_msg=w)
    # rayscan translate of the same cloud from LAS, whose extra bytes keep these names, writes the same.
    las = tmp_path / "s.las"
    rayscan.write(las, rayscan.PointCloud(xyz, scalars=scalars))
    assert set(scalars) <= set(rayscan.read(las).scalars)
    copy = tmp_path / "t.ply"
    subprocess.run([cli, "translate", "-q", str(las), str(copy)], check=True, capture_output=True)
    props, body = ply_body(copy)
    names = [p for p, _ in props]
    assert set(written) <= set(names) and not {"scalar_gpstime", "scalar_GPSTime", "scalar_Intensity"} & set(names)
    for name, w in zip(scalars, written):
        np.testing.assert_array_equal(body[w], scalars[name], err_msg=w)


def test_crs_never_opens_a_file_or_url(tmp_path):
    osr = pytest.importorskip("osgeo.osr")
    wgs84 = osr.SpatialReference()
    wgs84.ImportFromEPSG(4326)
    prj = tmp_path / "secret.prj"
    prj.write_text(wgs84.ExportToWkt())
    # GDAL's unrestricted reading takes the file's contents: the case is real.
    assert osr.SpatialReference().SetFromUserInput(str(prj)) == 0
    for text in (str(prj), "http://127.0.0.1:9/x.prj"):
        with pytest.raises(ValueError, match="^crs: GDAL cannot read .* as a CRS; expected .*not a file name or URL"):
            rayscan.PointCloud(np.zeros((1, 3)), crs=text)


def test_crs_refuses_text_after_the_wkt_control_characters_and_a_zero_unit(tmp_path):
    osr = pytest.importorskip("osgeo.osr")
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(2992)
    wkt = srs.ExportToWkt()
    # GDAL reads each of these, ignoring what follows the WKT: the cases are real (GDAL's C API
    # stops at a NUL, which osr's Python binding does not pass).
    for text in (wkt + " GARBAGE", wkt.replace('UNIT["foot",0.3048', 'UNIT["foot",0')):
        assert osr.SpatialReference().ImportFromWkt(text) == 0
    with pytest.raises(ValueError, match=f"^crs: control character 0x00 at character {len(wkt)} "):
        rayscan.PointCloud(np.zeros((1, 3)), crs=wkt + "\0\nend_header\nGARBAGE")
    with pytest.raises(ValueError, match=re.escape(f"crs: text after the WKT's closing bracket (character "
                                                   f"{len(wkt) - 1}): 'GARBAGE'; expected nothing after it")):
        rayscan.PointCloud(np.zeros((1, 3)), crs=wkt + " GARBAGE")
    assert wkt.count('UNIT["foot",0.3048,') == 1
    with pytest.raises(ValueError, match="^crs: the CRS has a linear unit 'foot' of size 0 "):
        rayscan.PointCloud(np.zeros((1, 3)), crs=wkt.replace('UNIT["foot",0.3048', 'UNIT["foot",0'))
    # Whitespace after the WKT is no text: kept as given, and the PLY header holds the WKT alone.
    pc = rayscan.PointCloud(np.zeros((2, 3)), crs=wkt + "\n  ")
    assert pc.crs == wkt + "\n  "
    out = tmp_path / "c.ply"
    rayscan.write(out, pc)
    header = out.read_bytes().split(b"end_header\n")[0].decode().splitlines()
    assert [line for line in header if line.startswith("comment crs ")] == ["comment crs " + wkt + "   "]


def test_crs_given_as_epsg_is_stored_as_wkt(cli, tmp_path):
    osr = pytest.importorskip("osgeo.osr")
    pc = rayscan.PointCloud(np.array([[1e6, 5e5, 100.0], [1e6 + 10, 5e5 + 10, 110.0]]), crs="EPSG:2992")
    expected = osr.SpatialReference()
    expected.ImportFromEPSG(2992)
    got = osr.SpatialReference()
    assert got.ImportFromWkt(pc.crs) == 0 and got.IsSame(expected)
    out = tmp_path / "c.las"
    rayscan.write(out, pc)
    back = rayscan.read(out)
    assert back.epsg == 2992 and back.crs == pc.crs
    info = json.loads(subprocess.run([cli, "info", "--json", str(out)], check=True, capture_output=True,
                                     text=True).stdout)
    assert info["crs"]["epsg"] == 2992 and info["crs"]["source"] == "WKT VLR"
    # WKT2 and PROJJSON name the same CRS.
    for text in (expected.ExportToWkt(["FORMAT=WKT2_2019"]), expected.ExportToPROJJSON()):
        other = osr.SpatialReference()
        assert other.ImportFromWkt(rayscan.PointCloud(pc.xyz, crs=text).crs) == 0 and other.IsSame(expected)


@pytest.mark.parametrize("bad", ["garbage", "EPSG:99999999", "", "PROJCS[broken"])
def test_crs_gdal_cannot_read_raises_value_error(bad):
    with pytest.raises(ValueError, match="^crs: GDAL cannot read .* as a CRS"):
        rayscan.PointCloud(np.zeros((1, 3)), crs=bad)
    with pytest.raises(TypeError, match="^crs must be"):
        rayscan.PointCloud(np.zeros((1, 3)), crs=2992)


def test_scalars_is_a_read_only_mapping_of_views():
    pc = small_cloud()
    s = pc.scalars
    assert list(s) == ["score", "flag"] and len(s) == 2 and "score" in s and s.get("nope") is None
    np.testing.assert_array_equal(dict(s.items())["score"], np.arange(11) ** 2.0)
    with pytest.raises(TypeError, match="read-only.*PointCloud\\(xyz, ..., scalars=.*rayscan.write\\(path, pc, h=values"):
        s["h"] = np.zeros(len(pc))
    with pytest.raises(TypeError, match="read-only"):
        del s["score"]
    assert list(pc.scalars) == ["score", "flag"]
    assert rayscan.PointCloud(np.zeros((2, 3))).scalars == {}
    # The arrays are views of the cloud, as every attribute is.
    s["score"][0] = 42.0
    assert pc.scalars["score"][0] == 42.0


def test_read_of_a_missing_file_raises_file_not_found(tmp_path):
    missing = tmp_path / "nope.las"
    with pytest.raises(FileNotFoundError) as e:
        rayscan.read(missing)
    assert e.value.errno == errno.ENOENT and e.value.filename == str(missing)
    with pytest.raises(NotADirectoryError) as e:
        (tmp_path / "file").write_bytes(b"")
        rayscan.read(tmp_path / "file" / "x.las")
    assert e.value.errno == errno.ENOTDIR
    # A file that opens but is malformed keeps the reader's message, no errno.
    bad = tmp_path / "bad.las"
    bad.write_bytes(b"LASF" + bytes(50))
    with pytest.raises(OSError, match="bad.las") as e:
        rayscan.read(bad)
    assert e.value.errno is None and type(e.value) is OSError
