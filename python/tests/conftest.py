"""Shared fixtures of the rayscan Python tests: paths from CTest's environment (python.pytest in
python/CMakeLists.txt) with fallbacks for a manual `PYTHONPATH=build/python python3 -m pytest`."""

import os
import pathlib
import shutil
import signal
import threading

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("RAYSCAN_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DATA = pathlib.Path(os.environ.get("RAYSCAN_TEST_DATA", SOURCE / "tests" / "data"))


@pytest.fixture(scope="session")
def data_dir():
    return DATA


@pytest.fixture(scope="session")
def cli():
    """Path of the rayscan command line (the C++ oracle for `rayscan query` / `info`)."""
    path = os.environ.get("RAYSCAN_CLI") or shutil.which("rayscan")
    if not path or not os.path.exists(path):
        cand = SOURCE / "build" / "tools" / "rayscan"
        path = str(cand) if cand.exists() else None
    if not path:
        pytest.skip("rayscan CLI not found (set RAYSCAN_CLI)")
    return path


def brute_ray_query(xyz, o, d, k=None, radius=np.inf, t_min=-np.inf, t_max=np.inf, order="ray"):
    """NumPy oracle of the ray query for one ray: the C++ formulas (ray_point_terms,
    sphere_entry, Ray's normalisation) evaluated in the same operation order, ranked by
    (key, index). Returns (indices, t, distance)."""
    o = np.asarray(o, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    m = np.abs(d).max()
    u = d / m
    d = u / np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    v = xyz - o
    tp = v[:, 0] * d[0] + v[:, 1] * d[1] + v[:, 2] * d[2]
    w = v - tp[:, None] * d
    d2 = w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1] + w[:, 2] * w[:, 2]
    keep = d2 <= radius * radius
    if order == "sphere_hit":
        t = tp - np.sqrt(np.maximum(0.0, radius * radius - d2))
    else:
        t = tp
    keep &= (t >= t_min) & (t <= t_max)
    idx = np.nonzero(keep)[0]
    key = np.sqrt(d2[idx]) if order == "ray" else t[idx]
    rank = np.lexsort((idx, key))
    idx = idx[rank]
    if k is not None:
        idx = idx[:k]
    return idx, t[idx], np.sqrt(d2[idx])


@pytest.fixture(scope="session")
def uniform_cloud():
    """2,000 uniform points in the unit cube (fixed seed) with duplicates, for exact ties."""
    rng = np.random.default_rng(20241121)
    xyz = rng.random((2000, 3))
    xyz[1500:1510] = xyz[0]  # exact duplicates: ties broken by index
    return xyz


@pytest.fixture(scope="session")
def random_rays():
    """64 rays from a sphere of radius 2 around the cube centre aimed at uniform points in it."""
    rng = np.random.default_rng(7)
    v = rng.normal(size=(64, 3))
    o = 0.5 + 2.0 * v / np.linalg.norm(v, axis=1, keepdims=True)
    target = rng.random((64, 3))
    return o, target - o


def sigint_once_entered(monkeypatch, owner, name, call):
    """The KeyboardInterrupt of call(), with a real SIGINT sent as Ctrl-C would once the call has
    begun: owner.<name> (the binding call() goes through) is wrapped to signal its entry, and a
    helper thread then sends SIGINT (it gets the GIL when the binding releases it). No time is
    measured. Fails the test if call() does not raise KeyboardInterrupt."""
    entered, never_entered = threading.Event(), []
    run = getattr(owner, name)

    def entering(*args):
        entered.set()
        return run(*args)

    def send():
        entered.wait()
        if not never_entered:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(owner, name, entering)
    sender = threading.Thread(target=send)
    sender.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            call()
    finally:
        if not entered.is_set():  # the call failed before the binding: release the sender unused
            never_entered.append(True)
            entered.set()
        sender.join()
        monkeypatch.undo()
    return e.value
