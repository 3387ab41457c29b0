"""rayscan.read against the files' own bytes (LAS header fields and point records decoded with
NumPy here) and against `rayscan info --json`."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import rayscan


def las_records(path):
    """Decode a LAS file's point records with NumPy from the ASPRS LAS 1.4 R15 header (section
    2.4: offset to point data at byte 96, PDRF at 104, record length at 105, legacy count at 107,
    scale at 131, offset at 155; count at 247 for 1.4) -- independent of the C++ reader."""
    raw = np.fromfile(path, dtype=np.uint8)
    hdr = raw.tobytes()
    minor = hdr[25]
    offset = int(np.frombuffer(hdr, "<u4", 1, 96)[0])
    pdrf = hdr[104] & 0x3F
    reclen = int(np.frombuffer(hdr, "<u2", 1, 105)[0])
    n = int(np.frombuffer(hdr, "<u4", 1, 107)[0])
    if minor >= 4 and n == 0:
        n = int(np.frombuffer(hdr, "<u8", 1, 247)[0])
    scale = np.frombuffer(hdr, "<f8", 3, 131)
    off = np.frombuffer(hdr, "<f8", 3, 155)
    rec = raw[offset:offset + n * reclen].reshape(n, reclen)
    xyz_int = rec[:, :12].copy().view("<i4").reshape(n, 3)
    xyz = xyz_int * scale + off
    intensity = rec[:, 12:14].copy().view("<u2").ravel()
    cls = (rec[:, 15] & 0x1F) if pdrf < 6 else rec[:, 16]
    return xyz, intensity, cls, pdrf


@pytest.mark.parametrize("name", ["autzen_trim.las", "mvk-thin.las", "test1_4.las", "point-color.las"])
def test_las_positions_intensity_classification_equal_file_bytes(data_dir, name):
    path = data_dir / "las" / name
    pc = rayscan.read(path)
    xyz, intensity, cls, pdrf = las_records(path)
    assert pc.format == "LAS" and pc.point_format == pdrf
    assert pc.xyz.shape == (len(xyz), 3) and pc.xyz.dtype == np.float64
    np.testing.assert_array_equal(pc.xyz, xyz)
    np.testing.assert_array_equal(pc.intensity, intensity)
    np.testing.assert_array_equal(pc.classification, cls)
    assert pc.intensity.dtype == np.uint16 and pc.classification.dtype == np.uint8


def test_rgb_equals_file_bytes(data_dir):
    path = data_dir / "las" / "point-color.las"  # PDRF 2: red, green, blue at record bytes 20..25
    pc = rayscan.read(path)
    raw = np.fromfile(path, dtype=np.uint8)
    offset = int(raw[96:100].view("<u4")[0])
    reclen = int(raw[105:107].view("<u2")[0])
    rec = raw[offset:offset + len(pc) * reclen].reshape(len(pc), reclen)
    rgb = rec[:, 20:26].copy().view("<u2").reshape(-1, 3)
    assert pc.rgb.dtype == np.uint16 and pc.rgb.shape == (len(pc), 3)
    if rgb.max() <= 255:  # 8-bit values in 16-bit fields are scaled by 257 (docs/formats.md)
        rgb = rgb * 257
    np.testing.assert_array_equal(pc.rgb, rgb)


def test_metadata_equals_info_json(cli, data_dir):
    path = data_dir / "las" / "autzen_trim.las"
    info = json.loads(subprocess.run([cli, "info", "--json", str(path)], check=True,
                                     capture_output=True, text=True).stdout)
    pc = rayscan.read(path)
    assert len(pc) == info["count"] == info["header_count"] == 110000
    assert pc.crs is not None and pc.crs == info["crs"]["wkt"]
    assert pc.epsg == info.get("epsg")  # GeoKeys with a user-defined CRS: no EPSG code
    assert set(pc.scalars) <= set(info["fields"]) and "scan_angle" in pc.scalars
    np.testing.assert_array_equal(pc.bounds, [info["bounds"]["min"], info["bounds"]["max"]])


def test_attributes_selection_and_views(data_dir):
    path = data_dir / "las" / "mvk-thin.las"
    full = rayscan.read(path)
    assert full.attributes[0] == "xyz" and "intensity" in full.attributes
    assert "scan_angle" in full.scalars
    only = rayscan.read(path, attributes=["intensity"])
    assert only.attributes == ["xyz", "intensity"] and only.rgb is None and only.scalars == {}
    np.testing.assert_array_equal(only.intensity, full.intensity)
    sa = rayscan.read(path, attributes=["scan_angle"])
    np.testing.assert_array_equal(sa["scan_angle"], full.scalars["scan_angle"])
    # Views share the object's memory (no copy) and keep it alive.
    xyz = rayscan.read(path).xyz
    assert xyz.base is not None and xyz.flags.c_contiguous
    assert np.shares_memory(full.xyz, full.xyz) and np.shares_memory(full["xyz"], full.xyz)
    np.testing.assert_array_equal(xyz, full.xyz)
    with pytest.raises(ValueError, match="no attribute 'rgb'"):
        rayscan.read(path, attributes=["rgb"])
    with pytest.raises(KeyError):
        full["nope"]


def pcd_binary_records(path):
    """Decode a binary PCD file with NumPy from its own header (PCL's PCD v0.7: FIELDS, SIZE, TYPE,
    COUNT, POINTS, then the packed records after the DATA binary line)."""
    raw = pathlib.Path(path).read_bytes()
    header, _, body = raw.partition(b"DATA binary\n")
    keys = {}
    for line in header.decode("ascii").splitlines():
        if line and not line.startswith("#"):
            name, *values = line.split()
            keys[name] = values
    kinds = {("F", "4"): "<f4", ("F", "8"): "<f8", ("U", "1"): "u1", ("U", "2"): "<u2", ("U", "4"): "<u4",
             ("I", "1"): "i1", ("I", "2"): "<i2", ("I", "4"): "<i4"}
    dtype = np.dtype([(f, kinds[(t, z)], (int(c),) if int(c) > 1 else ())
                      for f, z, t, c in zip(keys["FIELDS"], keys["SIZE"], keys["TYPE"], keys["COUNT"])])
    return np.frombuffer(body, dtype=dtype, count=int(keys["POINTS"][0]))


def test_pcd_positions_and_normals_equal_file_bytes(data_dir):
    path = data_dir / "pcd" / "cloud_bin_0.pcd"  # declares x y z normal_x normal_y normal_z rgb
    rec = pcd_binary_records(path)
    pc = rayscan.read(path)
    assert pc.format == "PCD" and len(pc) == len(rec) == 3903
    np.testing.assert_array_equal(pc.xyz, np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64))
    assert pc.normals is not None and pc.normals.dtype == np.float32 and pc.normals.shape == (len(pc), 3)
    np.testing.assert_array_equal(pc.normals, np.column_stack([rec["normal_x"], rec["normal_y"], rec["normal_z"]]))


def test_pcd_viewpoint_line_survives_write_and_selection(tmp_path):
    # The source's VIEWPOINT line (shortest decimals) is the written file's own line again, for the
    # whole cloud and for a selection of its points; positions are not moved by it.
    line = "VIEWPOINT 1.5 -2.25 0.125 0.7071067811865476 0.7071067811865476 0 0"
    src = tmp_path / "vp.pcd"
    src.write_text("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                   + line + "\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n7 8 9\n")
    pc = rayscan.read(src)
    for name, cloud in (("all.pcd", pc), ("some.pcd", pc[np.array([True, False, True])])):
        rayscan.write(tmp_path / name, cloud)
        header = (tmp_path / name).read_bytes().partition(b"DATA binary\n")[0].decode("ascii")
        assert [l for l in header.splitlines() if l.startswith("VIEWPOINT ")] == [line], name
        np.testing.assert_array_equal(rayscan.read(tmp_path / name).xyz, cloud.xyz)
    np.testing.assert_array_equal(pc.xyz, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])


def test_ply_vertices_equal_file_text(data_dir):
    path = data_dir / "ply" / "bunny.ply"  # ASCII: element vertex 1889 (x y z confidence intensity), then faces
    header, _, body = path.read_bytes().partition(b"end_header\n")
    lines = header.decode("ascii").splitlines()
    n = next(int(line.split()[2]) for line in lines if line.startswith("element vertex"))
    props = [line.split()[2] for line in lines if line.startswith("property float")]
    vertices = np.loadtxt(body.decode("ascii").splitlines()[:n])
    assert n == 1889 and vertices.shape == (n, len(props)) and props[:3] == ["x", "y", "z"]
    pc = rayscan.read(path)
    assert pc.format == "PLY" and len(pc) == n
    np.testing.assert_array_equal(pc.xyz, vertices[:, :3])
    # Its float "intensity" property is a scalar field, not the uint16 intensity of LAS.
    assert pc.intensity is None and sorted(pc.scalars) == sorted(props[3:]) == ["confidence", "intensity"]
    for k, name in enumerate(props[3:], start=3):
        np.testing.assert_array_equal(pc.scalars[name], vertices[:, k])
        np.testing.assert_array_equal(pc[name], vertices[:, k])


@pytest.mark.parametrize("kind, values, dedicated", [
    ("float", [0.25, 0.5, 1.0], False),        # the Stanford scanner's 0..1: stays a scalar
    ("float", [1.0, 2.0, 300.0], True),         # whole and within uint16: the intensity
    ("double", [1.0, 70000.0, 2.0], False),     # past uint16: stays a scalar
    ("int", [1, 2, 65535], True),               # an integer type wider than 16 bits, values in range
])
def test_ply_named_intensity_as_the_reader_documents_it(tmp_path, kind, values, dedicated):
    """A PLY `intensity` property that is not a 16-bit integer becomes the intensity when its values
    fit uint16, else a float64 scalar of that name (docs/formats.md), and attributes=["intensity"]
    gives what the whole read gives, never "no attribute 'intensity'"; other fields are left out."""
    path = tmp_path / f"{kind}.ply"
    body = "".join(f"{i} 0 {2 * i} {v} 0.5\n" for i, v in enumerate(values))
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    f"property float z\nproperty {kind} intensity\nproperty float confidence\nend_header\n" + body)
    full = rayscan.read(path)
    only = rayscan.read(path, attributes=["intensity"])
    assert only.attributes == ["xyz", "intensity"] and full.attributes == ["xyz", "intensity", "confidence"]
    np.testing.assert_array_equal(only.xyz, [[0, 0, 0], [1, 0, 2], [2, 0, 4]])
    for pc in (full, only):
        np.testing.assert_array_equal(pc["intensity"], values)
        if dedicated:
            assert pc.intensity.dtype == np.uint16 and "intensity" not in pc.scalars
            np.testing.assert_array_equal(pc.intensity, values)
        else:
            assert pc.intensity is None and pc.scalars["intensity"].dtype == np.float64
            np.testing.assert_array_equal(pc.scalars["intensity"], values)
    assert "confidence" not in only.scalars
    with pytest.raises(ValueError, match=r"no attribute 'rgb' \(the file has: xyz, intensity, confidence\)"):
        rayscan.read(path, attributes=["intensity", "rgb"])


def test_file_errors_raise_oserror(tmp_path, data_dir):
    with pytest.raises(OSError, match="(?i)no such file"):
        rayscan.read(tmp_path / "missing.las")
    bad = tmp_path / "bad.las"
    bad.write_bytes((data_dir / "las" / "autzen_trim.las").read_bytes()[:200])  # truncated header
    with pytest.raises(OSError, match="bad.las"):
        rayscan.read(bad)
    with pytest.raises(OSError):
        rayscan.read(tmp_path / "cloud.unknown")
