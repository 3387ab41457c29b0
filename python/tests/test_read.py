"""rayscan.read against the files' own bytes (LAS header fields and point records decoded with
NumPy here) and against `rayscan info --json`."""

import json
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
    text = json.dumps(info)
    assert pc.crs is not None and pc.crs[:6] in text
    assert str(len(pc)) in text
    for name in pc.scalars:
        assert name in text


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


def test_ply_and_pcd(data_dir):
    pc = rayscan.read(data_dir / "pcd" / "cloud_bin_0.pcd")
    assert pc.format == "PCD" and pc.xyz.shape[1] == 3
    if pc.normals is not None:
        assert pc.normals.dtype == np.float32 and pc.normals.shape == (len(pc), 3)
    ply = rayscan.read(data_dir / "ply" / "bunny.ply")
    assert ply.format == "PLY" and len(ply) > 0


def test_file_errors_raise_oserror(tmp_path, data_dir):
    with pytest.raises(OSError, match="(?i)no such file"):
        rayscan.read(tmp_path / "missing.las")
    bad = tmp_path / "bad.las"
    bad.write_bytes((data_dir / "las" / "autzen_trim.las").read_bytes()[:200])  # truncated header
    with pytest.raises(OSError, match="bad.las"):
        rayscan.read(bad)
    with pytest.raises(OSError):
        rayscan.read(tmp_path / "cloud.unknown")
