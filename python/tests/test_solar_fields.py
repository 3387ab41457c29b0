"""The names of rayscan.solar's arrays (rayscan.SOLAR_PERIOD_FIELDS, SOLAR_INSTANT_FIELDS) and
rayscan.dask's lazy sizes, which come from the file's bytes as rayscan.open decides, not from its
name. Oracles: the fields `rayscan solar -o` writes into a LAS file, the point count in a LAS
header's own bytes, and Site.storage."""

import shutil
import struct
import subprocess

import numpy as np
import pytest

import rayscan

_SUN = dict(latitude=44.05, longitude=-123.07, sky_rays=8)
_PERIOD = ("2024-06-21T17:00", "2024-06-21T18:00")
_INSTANT = "2024-06-21T18:00"


@pytest.fixture(scope="module")
def small_las(tmp_path_factory, data_dir):
    """Every 40th point of autzen_trim.las (2,750 points): seconds of solar at most."""
    path = tmp_path_factory.mktemp("solar_fields") / "autzen_40th.las"
    rayscan.write(path, rayscan.read(data_dir / "las" / "autzen_trim.las")[::40])
    return path


def _extra_bytes(path):
    """{name: description} of a LAS file's Extra Bytes descriptors, from the file's own bytes
    (LAS 1.4 R15: VLRs after the header, user LASF_Spec, record 4, 192-byte descriptors with the
    name at byte 4 and the description at byte 160)."""
    data = open(path, "rb").read()
    header_size, = struct.unpack_from("<H", data, 94)
    vlrs, = struct.unpack_from("<I", data, 100)
    at, out = header_size, {}
    for _ in range(vlrs):
        user, record, length = struct.unpack_from("<16sHH", data, at + 2)
        if user.rstrip(b"\0") == b"LASF_Spec" and record == 4:
            for d in range(at + 54, at + 54 + length, 192):
                name = data[d + 4:d + 36].rstrip(b"\0").decode()
                out[name] = data[d + 160:d + 192].rstrip(b"\0").decode()
        at += 54 + length
    return out


def _fields_written(cli, cloud, out, when):
    """The scalar fields `rayscan solar CLOUD WHEN -o OUT` adds to the cloud's own, in the file's
    order, each checked to have an Extra Bytes description naming its unit."""
    subprocess.run([cli, "solar", str(cloud), *when, "--lat", str(_SUN["latitude"]), "--lon",
                    str(_SUN["longitude"]), "--sky-rays", str(_SUN["sky_rays"]), "-o", str(out)],
                   check=True, capture_output=True)
    own = rayscan.read(cloud).scalars
    added = tuple(f for f in rayscan.read(out).scalars if f not in own)
    described = _extra_bytes(out)
    for f in added:
        assert described.get(f, "").endswith(("W/m2", "kWh/m2", ", h", "0-1", "0 sun")), (f, described.get(f))
    return added


def test_solar_fields_are_the_ones_the_cli_writes(cli, small_las, tmp_path):
    period = _fields_written(cli, small_las, tmp_path / "period.las", ["--start", _PERIOD[0], "--end", _PERIOD[1]])
    instant = _fields_written(cli, small_las, tmp_path / "instant.las", ["--at", _INSTANT])
    assert rayscan.SOLAR_PERIOD_FIELDS == period and "solar_global" in period
    assert rayscan.SOLAR_INSTANT_FIELDS == instant and "in_shadow" in instant
    # rayscan.solar returns exactly those arrays of N values (and its scalars beside them).
    one = rayscan.solar(small_las, start=_PERIOD[0], end=_PERIOD[1], **_SUN)
    arrays = tuple(k for k, v in one.items() if isinstance(v, np.ndarray) and v.shape == (2750,))
    assert arrays == period
    one = rayscan.solar(small_las, at=_INSTANT, **_SUN)
    arrays = tuple(k for k, v in one.items() if isinstance(v, np.ndarray) and v.shape == (2750,))
    assert arrays == instant


def _las_point_count(path):
    """The point count of a LAS 1.4 header (the 64-bit number of point records at byte 247)."""
    with open(path, "rb") as f:
        head = f.read(255)
    assert head[:4] == b"LASF" and head[24:26] == bytes([1, 4])
    return struct.unpack_from("<Q", head, 247)[0]


def test_dask_sizes_by_the_files_bytes(tmp_path, data_dir, small_las):
    """A COPC file has its header's count whatever its name (.copc.laz, .copc, .laz), as
    rayscan.open queries it in place under each; a plain LAS file is NaN (rayscan.open would read
    it whole), also under a .copc.laz name."""
    rd = pytest.importorskip("rayscan.dask")
    copc = data_dir / "laz" / "lone-star.copc.laz"
    n = _las_point_count(copc)
    assert n > 0
    for name in ("a.copc.laz", "a.copc", "a.laz"):
        path = tmp_path / name
        shutil.copyfile(copc, path)
        assert rayscan.open(path).storage == "copc"
        out = rd.solar(path, at=[_INSTANT, _INSTANT], **_SUN)
        assert tuple(f for f in out if f not in ("sun_azimuth", "sun_elevation")) == rayscan.SOLAR_INSTANT_FIELDS
        assert out["in_shadow"].shape == (2, n), name
        out = rd.solar(path, periods=[_PERIOD], **_SUN)
        assert tuple(out) == rayscan.SOLAR_PERIOD_FIELDS
        assert out["sun_hours"].shape == (1, n), name
    plain = tmp_path / "plain.copc.laz"
    shutil.copyfile(small_las, plain)
    assert rayscan.open(plain).storage == "memory"
    for path in (small_las, plain):
        assert np.isnan(rd.solar(path, at=[_INSTANT], **_SUN)["in_shadow"].shape[1])
