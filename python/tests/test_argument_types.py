"""The argument contract of the index classes, their queries, rayscan.open and the jobs (render,
ortho_map, visibility, solar, compare): a value of the
wrong type raises TypeError with one line that names the argument (never pybind11's "incompatible
function arguments" listing of a private method, never a ValueError), whatever the argument's
kind: integer, number, text, flag, array or file name. An Octree argument its layout does not use
is refused as the CLI refuses it. Site.has_ids says whether results are original point indices or
an index file's slots, checked against `rayscan query` on the same file."""

import csv
import re
import subprocess

import numpy as np
import pytest

import rayscan
from conftest import DATA, SOURCE

LAS = DATA / "las" / "autzen_trim.las"
XYZ = np.random.default_rng(7).random((300, 3))
O, D = np.zeros(3), np.ones(3)

# Values of the wrong type for each kind of argument. None is a wrong type only where the
# argument has no None meaning (a count with a default of None takes it).
WRONG = {
    "int": [3.0, "3", None, [3], True],
    "opt_int": [3.0, "3", [3], True],
    "k": [3.0, "3", [3], True, np.float64(3)],
    "number": ["1", None, b"1", [1.0], True],
    "text": [1, None, b"ray", ["ray"]],
    "flag": ["no", "yes", 1, 0, None, [True]],
    "array": ["abc", None, b"abc", np.array([["a", "b", "c"]]), np.ones((2, 3), bool),
              np.zeros((2, 3), complex), [[1, "a", 3]], [[None, None, None]]],
    "path": [3, None, b"cloud.las", [str(LAS)]],
    # The jobs' kinds: None means "not given" for the optional ones.
    "opt_number": ["1", b"1", [1.0], True],
    "opt_text": [1, b"2026-06-21", ["2026-06-21"]],
    "opt_path": [3, b"camera.json", [str(LAS)]],
    "names": [3, None, b"depth", [3], ["depth", None]],
    "cloud": [3, None, b"cloud.las", {"x": 1.0}, np.array([["a", "b", "c"]])],
    "opt_cloud": [3, b"cloud.las", {"x": 1.0}, np.array([["a", "b", "c"]])],
    "scene": [3, None, b"scene.json", {1, 2}],
    "observers": [b"abc", np.array([["a", "b", "c"]]), np.ones((2, 3), bool), [[1, "a", 3]], [[None, None, None]]],
    "image": [3.5, 3, None, True, b"reference.png", {"x": 1.0}],
    "linke": ["3", None, b"3", True, ["3"] * 12],
}


@pytest.fixture(scope="module")
def indexes(tmp_path_factory):
    ply = tmp_path_factory.mktemp("site") / "cloud.ply"
    rayscan.write(str(ply), XYZ)
    return {"octree": rayscan.Octree(XYZ), "kdtree": rayscan.KdTree(XYZ), "brute": rayscan.BruteForce(XYZ),
            "site": rayscan.open(ply)}


# (argument name as the message names it, kind, call with the value in that argument's place).
# Every typed argument of the constructors and of rayscan.open; the queries are run on each index.
CONSTRUCTORS = [
    ("xyz", "array", lambda v: rayscan.Octree(v)),
    ("layout", "text", lambda v: rayscan.Octree(XYZ, layout=v)),
    ("capacity", "opt_int", lambda v: rayscan.Octree(XYZ, capacity=v)),
    ("depth", "opt_int", lambda v: rayscan.Octree(XYZ, layout="fixed", depth=v)),
    ("max_depth", "opt_int", lambda v: rayscan.Octree(XYZ, max_depth=v)),
    ("insertion", "flag", lambda v: rayscan.Octree(XYZ, insertion=v)),
    ("xyz", "array", lambda v: rayscan.KdTree(v)),
    ("capacity", "opt_int", lambda v: rayscan.KdTree(XYZ, capacity=v)),
    ("xyz", "array", lambda v: rayscan.BruteForce(v)),
    ("xyz", "array", lambda v: rayscan.PointCloud(v)),
    ("path", "path", lambda v: rayscan.open(v)),
    ("cache", "text", lambda v: rayscan.open(LAS, cache=v)),
]
QUERIES = [
    ("origins", "array", lambda ix, v: ix.ray_query(v, D, k=1)),
    ("directions", "array", lambda ix, v: ix.ray_query(O, v, k=1)),
    ("k", "k", lambda ix, v: ix.ray_query(O, D, k=v)),
    ("radius", "number", lambda ix, v: ix.ray_query(O, D, k=1, radius=v)),
    ("t_min", "number", lambda ix, v: ix.ray_query(O, D, k=1, t_min=v)),
    ("t_max", "number", lambda ix, v: ix.ray_query(O, D, k=1, t_max=v)),
    ("order", "text", lambda ix, v: ix.ray_query(O, D, k=1, order=v)),
    ("any_hit", "flag", lambda ix, v: ix.ray_query(O, D, k=1, any_hit=v)),
    ("allow_all", "flag", lambda ix, v: ix.ray_query(O, D, allow_all=v)),
    ("threads", "int", lambda ix, v: ix.ray_query(O, D, k=1, threads=v)),
    ("points", "array", lambda ix, v: ix.knn(v, k=3)),
    ("k", "k", lambda ix, v: ix.knn(O, k=v)),
    ("radius", "number", lambda ix, v: ix.knn(O, k=3, radius=v)),
    ("threads", "int", lambda ix, v: ix.knn(O, k=3, threads=v)),
    ("points", "array", lambda ix, v: ix.radius(v, 0.1)),
    ("radius", "number", lambda ix, v: ix.radius(O, v)),
    ("threads", "int", lambda ix, v: ix.radius(O, 0.1, threads=v)),
    ("lo", "array", lambda ix, v: ix.box(v, D)),
    ("hi", "array", lambda ix, v: ix.box(O, v)),
    ("threads", "int", lambda ix, v: ix.box(O, D, threads=v)),
]


# Every typed argument of the jobs, each in a call that is valid but for it (a job that accepted the
# wrong value would run on XYZ in a moment).
SUN = dict(at="2026-06-21T12:00", latitude=44.0, longitude=-123.0, sky_rays=0)
EYE = [[0.5, 0.5, 2.0]]
IMG = np.zeros((4, 4, 3))
JOBS = [
    ("scene", "scene", lambda v: rayscan.render(v, width=8, height=8, spp=1)),
    ("cloud", "opt_cloud", lambda v: rayscan.render(SOURCE / "scenes" / "autzen_overview.json", cloud=v,
                                                    width=8, spp=1)),
    ("width", "opt_int", lambda v: rayscan.render(XYZ, width=v, height=8, spp=1)),
    ("height", "opt_int", lambda v: rayscan.render(XYZ, width=8, height=v, spp=1)),
    ("spp", "opt_int", lambda v: rayscan.render(XYZ, width=8, height=8, spp=v)),
    ("seed", "opt_int", lambda v: rayscan.render(XYZ, width=8, height=8, spp=1, seed=v)),
    ("aovs", "names", lambda v: rayscan.render(XYZ, width=8, height=8, spp=1, aovs=v)),
    ("camera", "opt_path", lambda v: rayscan.render(XYZ, width=8, height=8, spp=1, camera=v)),
    ("threads", "int", lambda v: rayscan.render(XYZ, width=8, height=8, spp=1, threads=v)),
    ("cloud", "cloud", lambda v: rayscan.ortho_map(v, 0.25, spp=1)),
    ("res", "number", lambda v: rayscan.ortho_map(XYZ, v, spp=1)),
    ("spp", "opt_int", lambda v: rayscan.ortho_map(XYZ, 0.25, spp=v)),
    ("seed", "opt_int", lambda v: rayscan.ortho_map(XYZ, 0.25, spp=1, seed=v)),
    ("threads", "int", lambda v: rayscan.ortho_map(XYZ, 0.25, spp=1, threads=v)),
    ("colour", "text", lambda v: rayscan.ortho_map(XYZ, 0.25, spp=1, colour=v)),
    ("cloud", "cloud", lambda v: rayscan.visibility(v, observers=EYE)),
    ("observers", "observers", lambda v: rayscan.visibility(XYZ, observers=v)),
    ("radius", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, radius=v)),
    ("height", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, height=v)),
    ("max_distance", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, max_distance=v)),
    ("tolerance", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, tolerance=v)),
    ("target_height", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, target_height=v)),
    ("sky_rays", "int", lambda v: rayscan.visibility(XYZ, observers=EYE, sky_rays=v)),
    ("camera", "opt_path", lambda v: rayscan.visibility(XYZ, observers=EYE, camera=v)),
    ("distance", "flag", lambda v: rayscan.visibility(XYZ, observers=EYE, distance=v)),
    ("threads", "int", lambda v: rayscan.visibility(XYZ, observers=EYE, threads=v)),
    ("cache", "text", lambda v: rayscan.visibility(XYZ, observers=EYE, cache=v)),
    ("ground_radius", "opt_number", lambda v: rayscan.visibility(XYZ, observers=EYE, ground_radius=v)),
    ("cloud", "cloud", lambda v: rayscan.solar(v, **SUN)),
    ("start", "opt_text", lambda v: rayscan.solar(XYZ, start=v, end="2026-06-22", latitude=44.0, longitude=-123.0)),
    ("end", "opt_text", lambda v: rayscan.solar(XYZ, start="2026-06-21", end=v, latitude=44.0, longitude=-123.0)),
    ("step", "text", lambda v: rayscan.solar(XYZ, start="2026-06-21", end="2026-06-21", step=v, latitude=44.0,
                                             longitude=-123.0, sky_rays=0)),
    ("at", "opt_text", lambda v: rayscan.solar(XYZ, at=v, latitude=44.0, longitude=-123.0)),
    ("latitude", "opt_number", lambda v: rayscan.solar(XYZ, **{**SUN, "latitude": v})),
    ("longitude", "opt_number", lambda v: rayscan.solar(XYZ, **{**SUN, "longitude": v})),
    ("linke", "linke", lambda v: rayscan.solar(XYZ, linke=v, **SUN)),
    ("albedo", "number", lambda v: rayscan.solar(XYZ, albedo=v, **SUN)),
    ("weather", "opt_path", lambda v: rayscan.solar(XYZ, weather=v, **SUN)),
    ("sector", "number", lambda v: rayscan.solar(XYZ, sector=v, **SUN)),
    ("sky_rays", "int", lambda v: rayscan.solar(XYZ, **{**SUN, "sky_rays": v})),
    ("primitive", "text", lambda v: rayscan.solar(XYZ, primitive=v, **SUN)),
    ("radius", "opt_number", lambda v: rayscan.solar(XYZ, radius=v, **SUN)),
    ("threads", "int", lambda v: rayscan.solar(XYZ, threads=v, **SUN)),
    ("cache", "text", lambda v: rayscan.solar(XYZ, cache=v, **SUN)),
    ("reference", "image", lambda v: rayscan.compare(v, IMG)),
    ("image", "image", lambda v: rayscan.compare(IMG, v)),
    ("channels", "names", lambda v: rayscan.compare(IMG, IMG, channels=v)),
    ("mask", "flag", lambda v: rayscan.compare(IMG, IMG, mask=v)),
    ("alpha", "flag", lambda v: rayscan.compare(IMG, IMG, alpha=v)),
    ("resize", "flag", lambda v: rayscan.compare(IMG, IMG, resize=v)),
    ("fail", "opt_number", lambda v: rayscan.compare(IMG, IMG, fail=v)),
    ("fail_percent", "opt_number", lambda v: rayscan.compare(IMG, IMG, fail_percent=v)),
    ("fail_psnr", "opt_number", lambda v: rayscan.compare(IMG, IMG, fail_psnr=v)),
    ("fail_ssim", "opt_number", lambda v: rayscan.compare(IMG, IMG, fail_ssim=v)),
    ("warn", "opt_number", lambda v: rayscan.compare(IMG, IMG, warn=v)),
]


def expect_type_error(call, name):
    with pytest.raises(Exception) as e:
        call()
    message = str(e.value)
    assert type(e.value) is TypeError, (type(e.value).__name__, message)
    assert "\n" not in message and "incompatible" not in message, message
    # The argument named first ("knn: k must be ..." names the method too).
    assert re.match(rf"(knn: )?{name}\b", message), message
    return message


@pytest.mark.parametrize("name,kind,call", CONSTRUCTORS, ids=[f"{i}-{c[0]}" for i, c in enumerate(CONSTRUCTORS)])
def test_constructor_arguments_of_the_wrong_type_raise_type_error(name, kind, call):
    for value in WRONG[kind]:
        expect_type_error(lambda: call(value), name)


@pytest.mark.parametrize("index", ["octree", "kdtree", "brute", "site"])
@pytest.mark.parametrize("name,kind,call", QUERIES, ids=[f"{c[0]}-{i}" for i, c in enumerate(QUERIES)])
def test_query_arguments_of_the_wrong_type_raise_type_error(indexes, index, name, kind, call):
    ix = indexes[index]
    for value in WRONG[kind]:
        expect_type_error(lambda: call(ix, value), name)
    # knn without k: None has no meaning there (radius() is the query without a count).
    if name == "k" and kind == "k":
        expect_type_error(lambda: ix.knn(O, k=None), "k")


@pytest.mark.skipif(not hasattr(rayscan, "render"), reason="module built without the library's job API")
@pytest.mark.parametrize("name,kind,call", JOBS, ids=[f"{i}-{c[0]}" for i, c in enumerate(JOBS)])
def test_job_arguments_of_the_wrong_type_raise_type_error(name, kind, call):
    for value in WRONG[kind]:
        expect_type_error(lambda: call(value), name)


def test_job_flags_of_the_right_type_reach_the_job():
    # NumPy bools are flags, as for the queries. The one pixel that differs is transparent in the
    # reference: the mask ignores it, and only with alpha is the alpha channel compared.
    ref = np.zeros((4, 4, 4))
    ref[..., 3] = 1.0
    ref[0, 0, 3] = 0.0
    img = ref.copy()
    img[0, 0, :3] = 1.0
    assert rayscan.compare(ref, img, mask=np.False_)["max_error"] == 1.0
    masked = rayscan.compare(ref, img, mask=np.True_)
    assert masked["pixels_ignored"] == 1 and masked["max_error"] == 0.0
    assert "A" not in rayscan.compare(ref, img)["per_channel"]
    assert "A" in rayscan.compare(ref, img, alpha=np.bool_(True))["per_channel"]
    near = rayscan.visibility(XYZ, observers=EYE, distance=np.True_)["visible_distance"]
    seen = near >= 0
    assert seen.any()
    np.testing.assert_allclose(near[seen], np.linalg.norm(XYZ[seen] - EYE, axis=1), rtol=1e-12)
    assert "visible_distance" not in rayscan.visibility(XYZ, observers=EYE, distance=False)


def test_right_types_are_accepted_including_numpy_scalars(indexes):
    tree = indexes["octree"]
    a = tree.ray_query(O, D, k=np.int32(2), radius=np.float32(0.5), any_hit=np.bool_(False),
                       allow_all=np.True_, order="ray")
    b = tree.ray_query(O, D, k=2, radius=0.5)
    assert a.indices.tolist() == b.indices.tolist() and len(b.indices) == 2
    assert rayscan.Octree(XYZ, insertion=np.bool_(True), capacity=np.uint8(4)).capacity == 4
    # Integer arrays are real numbers: the same answer as float64.
    assert tree.knn(np.array([[0, 0, 0]], dtype=np.int16), k=np.uint64(3)).indices.tolist() == \
        tree.knn(O, k=3).indices.tolist()


def test_a_file_name_where_points_are_expected_says_what_takes_a_file():
    for make in (rayscan.Octree, rayscan.KdTree, rayscan.BruteForce, rayscan.PointCloud):
        for path in (str(LAS), LAS):
            message = expect_type_error(lambda: make(path), "xyz")
            assert message == (f"xyz: expected an (N, 3) array of real numbers, got {type(path).__name__} (a point "
                               "file is read by rayscan.read(path) or opened for queries by rayscan.open(path))")
    assert str(pytest.raises(TypeError, rayscan.Octree(XYZ).knn, None, 3).value) == \
        "points: expected an (N, 3) or (3,) array of real numbers, got NoneType"


def test_bad_values_of_the_right_type_stay_value_errors(indexes):
    tree = indexes["octree"]
    for call, message in [
        (lambda: tree.knn(O, k=-1), "k must be None or an integer >= 0, got -1"),
        (lambda: tree.ray_query(O, D, k=-(2**70)), f"k must be None or an integer >= 0, got {-(2**70)}"),
        (lambda: tree.knn(np.zeros((2, 2)), k=1), "points: expected shape (N, 3) or (3,), got (2, 2)"),
        (lambda: rayscan.Octree(XYZ, layout="sparse"), "octree layout 'sparse': expected adaptive, layered or fixed"),
    ]:
        with pytest.raises(ValueError) as e:
            call()
        assert type(e.value) is ValueError and str(e.value) == message, str(e.value)
    # A layout of the wrong type: the same layouts, in the same order, as Python writes them.
    assert str(pytest.raises(TypeError, rayscan.Octree, XYZ, layout=3).value) == \
        "layout must be 'adaptive', 'layered' or 'fixed', got int"


# ---- Octree arguments its layout does not use --------------------------------------------------

# (layout, keyword, value, the CLI command and flags that refuse the same combination)
UNUSED = [
    ("fixed", "capacity", 8, ["query", "--index", "octree-fixed", "--capacity", "8"]),
    ("fixed", "max_depth", 5, ["index", "--layout", "fixed", "--max-depth", "5"]),
    ("adaptive", "depth", 3, ["query", "--index", "octree-adaptive", "--depth", "3"]),
    ("layered", "depth", 3, ["query", "--index", "octree-layered", "--depth", "3"]),
]


@pytest.mark.parametrize("layout,keyword,value,cli_args", UNUSED)
def test_octree_refuses_an_argument_its_layout_ignores_as_the_cli_does(cli, tmp_path, layout, keyword, value,
                                                                       cli_args):
    with pytest.raises(ValueError) as e:
        rayscan.Octree(XYZ, layout=layout, **{keyword: value})
    assert type(e.value) is ValueError
    uses = "layout='fixed'" if keyword == "depth" else "layout='adaptive' and 'layered'"
    assert str(e.value) == f"{keyword} applies to {uses} only (got layout='{layout}')"
    # The command line refuses the same combination (exit 2, "applies to"): an independent check
    # that the Python rule is the CLI's.
    io = ["--cloud", str(LAS), "--rays", str(tmp_path / "rays.csv")] if cli_args[0] == "query" else \
        ["-o", str(tmp_path / "out.rsi"), str(LAS)]
    r = subprocess.run([cli, *cli_args, *io], capture_output=True, text=True)
    assert r.returncode == 2 and "applies to" in r.stderr, r.stderr
    assert not (tmp_path / "out.rsi").exists()


def test_octree_takes_the_arguments_its_layout_uses():
    fixed = rayscan.Octree(XYZ, layout="fixed", depth=3)
    # A fixed tree's leaves all lie at `depth`, and it has no capacity (None, left out of the repr).
    assert fixed.depth == 3 and fixed.capacity is None
    assert repr(fixed) == f"<rayscan.Octree 300 points, layout=fixed, {fixed.node_count} nodes, depth 3>"
    assert rayscan.Octree(XYZ, layout="fixed").depth == 6  # the default depth
    # max_depth bounds the adaptive and layered trees: capacity 1 would split 300 points deeper.
    for layout in ("adaptive", "layered"):
        assert rayscan.Octree(XYZ, layout=layout, capacity=1, max_depth=2).depth == 2
        assert rayscan.Octree(XYZ, layout=layout, capacity=1).depth > 2
    assert rayscan.Octree(XYZ, capacity=5).capacity == 5


# ---- Site.has_ids: original indices or index slots ---------------------------------------------

@pytest.mark.parametrize("with_ids", [True, False])
def test_site_has_ids_says_whether_results_are_original_indices(cli, tmp_path, with_ids):
    """An .rsi built with `--attributes id` answers with the points' original indices (those of
    the in-memory octree over rayscan.read's points); one built without answers with its slots,
    as `rayscan query` on the same file does, and has_ids says which."""
    src = tmp_path / "cloud.ply"
    rng = np.random.default_rng(12)
    xyz = rng.random((2000, 3))
    rayscan.write(str(src), xyz)
    rsi = tmp_path / "cloud.rsi"
    subprocess.run([cli, "index", "-q", *(["--attributes", "id"] if with_ids else []), "-o", str(rsi), str(src)],
                   check=True, capture_output=True)
    site = rayscan.open(rsi)
    assert site.storage == "index_file" and site.has_ids is with_ids
    o = np.column_stack([rng.random((50, 2)), np.full(50, 2.0)])
    res = site.ray_query(o, [0, 0, -1], k=3, radius=0.05)
    # `rayscan query` on the same index file: its index column is the file's ids, or its slots.
    rays = tmp_path / "rays.f64"
    np.hstack([o, np.tile([0.0, 0.0, -1.0], (50, 1))]).astype("<f8").tofile(rays)
    out = tmp_path / "hits.csv"
    subprocess.run([cli, "query", "-q", "--cloud", str(rsi), "--rays", str(rays), "--k", "3", "--radius", "0.05",
                    "--out", str(out)], check=True)
    with open(out) as f:
        cli_indices = [int(row["index"]) for row in csv.DictReader(f)]
    assert len(res.indices) > 50 and res.indices.tolist() == cli_indices
    original = rayscan.Octree(rayscan.read(src)).ray_query(o, [0, 0, -1], k=3, radius=0.05)
    np.testing.assert_array_equal(res.t, original.t)
    assert (res.indices.tolist() == original.indices.tolist()) is with_ids


def test_has_ids_of_the_other_storages(data_dir):
    # A point file indexed in memory and a COPC file in place both number points as rayscan.read.
    for path, storage in ((data_dir / "las" / "autzen_trim.las", "memory"),
                          (data_dir / "laz" / "lone-star.copc.laz", "copc")):
        site = rayscan.open(path)
        assert site.storage == storage and site.has_ids is True
    with pytest.raises(AttributeError):
        site.has_ids = False  # read-only
