"""Ctrl-C stops the long jobs (render, ortho_map, visibility, solar, compare) before their end: the
job runs on a worker thread while the calling thread looks for signals, and a KeyboardInterrupt
sets the job's cancel flag, which it checks per render tile, chunk of points or block of image rows. The SIGINT is a real one,
sent as Ctrl-C would once the call has begun (a helper thread sends it when the call is entered;
it gets the GIL when the call releases it for the job). Each job is sized to take many seconds to
its end; the exception's note, which only a job that stopped at its check gets, tells that it did
not run to it (no time is measured). The module then answers the next call as before the
interruption."""

import functools

import numpy as np
import pytest

import rayscan
from conftest import SOURCE, sigint_once_entered

pytestmark = pytest.mark.skipif(not hasattr(rayscan, "render"),
                                reason="module built without the library's job API")


@functools.cache
def large_images():
    """Two 4000 x 4000 RGB float images a little apart: their comparison (errors, SSIM, FLIP) runs
    for seconds."""
    ref = np.random.default_rng(2).random((4000, 4000, 3), dtype=np.float32)
    return ref, ref + np.float32(0.01)


@pytest.fixture(scope="module")
def autzen():
    return rayscan.read(SOURCE / "scenes" / "data" / "autzen_trim.las")


# (job, the long call, a short call whose result is compared before and after the interruption)
JOBS = [
    ("render",
     lambda pc: rayscan.render(pc, width=800, height=600, spp=64),
     lambda pc: rayscan.render(pc, width=24, height=16, spp=2, seed=5)["beauty"]),
    ("ortho_map",
     lambda pc: rayscan.ortho_map(pc, 1.0, colour="shaded", spp=16),
     lambda pc: rayscan.ortho_map(pc, 200.0, spp=1)["dsm"]),
    ("visibility",
     lambda pc: rayscan.visibility(pc, observers=pc.xyz[::2000] + [0.0, 0.0, 6.0], sky_rays=1024),
     lambda pc: rayscan.visibility(pc.xyz[:3000], observers=pc.xyz[:1] + [0.0, 0.0, 6.0])["visible_count"]),
    ("solar",
     lambda pc: rayscan.solar(pc, start="2026-01-01", end="2026-12-31", sector=0.5, sky_rays=1024),
     lambda pc: rayscan.solar(pc.xyz[:3000], at="2026-06-21T18:00:00Z", latitude=44.0, longitude=-123.0,
                              sky_rays=0)["in_shadow"]),
    ("compare",
     lambda pc: rayscan.compare(*large_images()),
     lambda pc: [rayscan.compare(large_images()[0][:64, :64], large_images()[1][:64, :64])[k]
                 for k in ("mae", "ssim", "flip")]),
]


@pytest.mark.parametrize("name,long_call,short_call", JOBS, ids=[j[0] for j in JOBS])
def test_ctrl_c_stops_a_job_before_its_end(monkeypatch, autzen, name, long_call, short_call):
    before = short_call(autzen)
    e = sigint_once_entered(monkeypatch, rayscan._rayscan, "_" + name, lambda: long_call(autzen))
    assert getattr(e, "__notes__", []) == [f"{name} interrupted before its end"], \
        "KeyboardInterrupt without the job's note: raised outside the job, or after its end"
    np.testing.assert_array_equal(short_call(autzen), before)

