// The compare, visibility and solar jobs as library calls (compare.hpp, visibility.hpp, solar.hpp).
// Oracles: hand-computed errors of constructed images, the lower-level compute_visibility and
// compute_sky_view calls, the geometry of an open plane, and a map's bytes from a fuller run.
#include "rayscan/base/option_error.hpp"
#include "rayscan/analysis/dsm_viewshed.hpp"
#include "rayscan/jobs/compare.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/jobs/visibility.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/scene_json.hpp"

#include "../common/temp_dir.hpp"
#include "image_test_util.hpp"
#include "small_copc.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <unistd.h>
#include <utility>
#include <variant>

using namespace rayscan;
using namespace rayscan::analysis;
using namespace rayscan::jobs;
using rayscan::analysis::test::px;

namespace {

std::string what_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

PointCloud plane_with_wall() {
  // A 4 x 4 m ground grid (0.1 m) and a 2 m wall at x = 2 from y = 1 to y = 3.
  PointCloud pc;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) pc.positions.emplace_back(0.1 * i, 0.1 * j, 0.0);
  for (int j = 10; j <= 30; ++j)
    for (int k = 1; k <= 20; ++k) pc.positions.emplace_back(2.0, 0.1 * j, 0.1 * k);
  return pc;
}

}  // namespace

TEST(CompareJob, InMemoryImagesMetricsVerdictAndMask) {
  Image ref = make_image(16, 16, {"R", "G", "B", "A"}, 0.25f);
  Image img = make_image(16, 16, {"R", "G", "B"}, 0.25f);
  ref.alpha_channel = 3;
  px(img, 3, 5, 1) = 0.75f;  // one sample off by 0.5
  CompareJobOptions o;
  o.reference = &ref;
  o.image = &img;
  CompareJobResult r = run_compare(o);
  EXPECT_EQ(r.metrics.channels, (std::vector<std::string>{"R", "G", "B"}));
  EXPECT_FLOAT_EQ(r.metrics.max_error, 0.5f);
  EXPECT_EQ(r.metrics.max_x, 3);
  EXPECT_EQ(r.metrics.max_y, 5);
  EXPECT_NEAR(r.metrics.mae, 0.5 / (16 * 16 * 3), 1e-12);
  EXPECT_EQ(r.metrics.over_fail, 1u);
  EXPECT_EQ(r.judgement.verdict, Verdict::fail);  // idiff default: any pixel over 1e-6
  EXPECT_NE(compare_report_text(r).find("FAILURE"), std::string::npos);

  o.fail.threshold = 0.6;  // a given criterion replaces the default
  o.warn.threshold = 0.1;
  r = run_compare(o);
  EXPECT_EQ(r.judgement.verdict, Verdict::warn);
  EXPECT_NE(compare_report_json(r).find("\"verdict\": \"warn\""), std::string::npos);

  o.fail = {};
  o.warn = {};
  px(ref, 3, 5, 3) = 0.0f;  // reference alpha 0 there: masked
  o.mask = true;
  r = run_compare(o);
  EXPECT_EQ(r.judgement.verdict, Verdict::pass);
  EXPECT_EQ(r.metrics.pixels_ignored, 1u);
  EXPECT_EQ(r.mask_sources, "(memory):A == 0");

  o.channels = {"depth"};
  EXPECT_EQ(what_of([&] { (void)run_compare(o); }),
            "(memory): no channel 'depth' (nor its renderer name 'Z') (channels: R,G,B,A)");
  o.channels = {};
  Image small = make_image(8, 8, {"R", "G", "B"}, 0.25f);
  o.image = &small;
  o.mask = false;
  EXPECT_EQ(what_of([&] { (void)run_compare(o); }),
            "image sizes differ: (memory) is 16x16, (memory) is 8x8 (use resize to compare at the reference's size)");
}

// The text report counts the pixels over a level's threshold only where that level has a pixel
// test (docs/cli.md: the warning level is off when fail criteria are given and no warning one is);
// otherwise the line says the threshold is off. Oracle: one sample off by 0.5 of 256 pixels, so
// exactly 1 pixel (0.390625%) is over any threshold below 0.5.
TEST(CompareJob, ReportCountsPixelsOnlyOverThresholdsInEffect) {
  const Image ref = make_image(16, 16, {"R", "G", "B"}, 0.25f);
  Image img = make_image(16, 16, {"R", "G", "B"}, 0.25f);
  px(img, 3, 5, 1) = 0.75f;
  CompareJobOptions o;
  o.reference = &ref;
  o.image = &img;
  const std::string kFailOver = "  1 pixel (0.390625%) over 0.1 (fail threshold)\n";
  const std::string kWarnOver = "  1 pixel (0.390625%) over 0.1 (warn threshold)\n";
  const std::string kFailOff = "  fail threshold  off (no pixel test at this level)\n";
  const std::string kWarnOff = "  warn threshold  off (no pixel test at this level)\n";
  const auto has = [](const std::string& text, const std::string& line) { return text.find(line) != std::string::npos; };

  // Fail criteria alone: the warn level is off, so no count over its default 1e-6.
  o.fail.threshold = 0.1;
  o.fail.percent = 10.0;
  CompareJobResult r = run_compare(o);
  std::string t = compare_report_text(r);
  EXPECT_EQ(r.judgement.verdict, Verdict::pass);
  EXPECT_TRUE(has(t, kFailOver)) << t;
  EXPECT_TRUE(has(t, kWarnOff)) << t;
  EXPECT_FALSE(has(t, "(warn threshold)")) << t;
  EXPECT_TRUE(t.ends_with("\nPASS\n")) << t;
  // The JSON report says the same: a count where the level has a pixel test, null where it is off.
  nlohmann::json j = nlohmann::json::parse(compare_report_json(r))["over_threshold"];
  EXPECT_EQ(j["fail"], (nlohmann::json{{"threshold", 0.1}, {"pixels", 1}, {"percent", 0.390625}})) << j.dump();
  EXPECT_TRUE(j["warn"].is_null()) << j.dump();

  // A warn threshold given: its count is reported, and it decides the verdict.
  o.warn.threshold = 0.1;
  r = run_compare(o);
  t = compare_report_text(r);
  EXPECT_EQ(r.judgement.verdict, Verdict::warn);
  EXPECT_TRUE(has(t, kFailOver)) << t;
  EXPECT_TRUE(has(t, kWarnOver)) << t;
  EXPECT_TRUE(t.ends_with("\nWARNING\n")) << t;
  j = nlohmann::json::parse(compare_report_json(r))["over_threshold"];
  EXPECT_EQ(j["warn"], (nlohmann::json{{"threshold", 0.1}, {"pixels", 1}, {"percent", 0.390625}})) << j.dump();

  // An SSIM limit alone: neither level has a pixel test.
  o.fail = {};
  o.warn = {};
  o.fail.min_ssim = -1.0;
  r = run_compare(o);
  t = compare_report_text(r);
  EXPECT_TRUE(has(t, kFailOff)) << t;
  EXPECT_TRUE(has(t, kWarnOff)) << t;
  j = nlohmann::json::parse(compare_report_json(r))["over_threshold"];
  EXPECT_TRUE(j["fail"].is_null()) << j.dump();
  EXPECT_TRUE(j["warn"].is_null()) << j.dump();

  // No criterion: idiff's defaults, both levels counting over 1e-6.
  o.fail = {};
  r = run_compare(o);
  t = compare_report_text(r);
  EXPECT_TRUE(has(t, "  1 pixel (0.390625%) over 1e-06 (fail threshold)\n")) << t;
  EXPECT_TRUE(has(t, "  1 pixel (0.390625%) over 1e-06 (warn threshold)\n")) << t;
  EXPECT_TRUE(t.ends_with("\nFAILURE\n")) << t;
  j = nlohmann::json::parse(compare_report_json(r))["over_threshold"];
  EXPECT_EQ(j["fail"]["pixels"], 1) << j.dump();
  EXPECT_EQ(j["warn"]["pixels"], 1) << j.dump();
}

TEST(VisibilityJob, InMemoryCloudEqualsTheLowerLevelCalls) {
  const PointCloud pc = plane_with_wall();
  VisibilityJobOptions o;
  o.cloud = &pc;
  o.radius = 0.08;
  o.primitive = "sphere";  // compared with the sphere model's lower-level calls below
  Observer eye;
  eye.position = Vec3(0.5, 2.0, 1.7);
  eye.has_z = true;
  o.observers = {eye};
  o.sky_rays = 16;
  o.control.threads = 2;
  const VisibilityJobResult r = run_visibility(o);

  const AnyIndex index = make_index(pc.positions, IndexOptions{});
  VisibilityOptions vo;
  vo.radius = 0.08;
  vo.tolerance = 0.16;     // default 2 x radius
  vo.target_height = 0.08; // default 1 x radius
  const VisibilityResult want = compute_visibility(index, pc.positions, r.observers, vo);
  EXPECT_EQ(r.line_of_sight.count, want.count);
  SkyViewOptions so;
  so.rays = 16;
  so.radius = 0.08;
  so.lift = 0.16;
  EXPECT_EQ(r.sky_view, compute_sky_view(index, pc.positions, so));
  // Geometry: ground right behind the wall (x = 2.5, y = 2) is hidden from the eye at x = 0.5, and
  // ground in front of it (x = 1, y = 2) is seen.
  const std::size_t behind = 25 * 41 + 20, front = 10 * 41 + 20;
  EXPECT_EQ(pc.positions[behind], Vec3(2.5, 2.0, 0.0));
  EXPECT_EQ(r.line_of_sight.count[behind], 0u);
  EXPECT_EQ(r.line_of_sight.count[front], 1u);
  const ScalarField* f = r.cloud.scalar("visible_count");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->values[front], 1.0);
  EXPECT_NE(r.cloud.scalar("sky_view"), nullptr);
  EXPECT_NE(visibility_report_json(r).find("\"visible_points\""), std::string::npos);
}

TEST(VisibilityJob, OptionErrorsComeBeforeAnyWork) {
  const PointCloud pc = plane_with_wall();
  VisibilityJobOptions o;
  o.cloud = &pc;
  // The message names each option by its field alone, for each front end to spell.
  EXPECT_EQ(what_of([&] { (void)run_visibility(o); }),
            "nothing to compute: give observers (observers_file or observers), a sky view (sky_rays > 0) or a "
            "camera (camera_file)");
  o.sky_rays = 4;
  // A ground radius is refused as an option even when no eye is placed on the ground.
  for (const auto& [bad, shown] : {std::pair{0.0, "0"}, {-1.0, "-1"}, {std::nan(""), "nan"}, {HUGE_VAL, "inf"}}) {
    o.ground_radius = bad;
    EXPECT_EQ(what_of([&] { (void)run_visibility(o); }),
              std::string("ground_radius: expected a finite number > 0 (world units), got ") + shown);
  }
  o.ground_radius.reset();
  o.raster = "map.png";
  o.cell = 1.0;
  EXPECT_EQ(what_of([&] { (void)run_visibility(o); }),
            "raster 'map.png': expected a file name ending in .tif (GeoTIFF)");
  o.raster = "";
  o.cell.reset();
  o.out = "x.e57";
  EXPECT_EQ(what_of([&] { (void)run_visibility(o); }), "out 'x.e57': expected a file name ending in .las, .laz, .ply, .pcd, .xyz, .csv or .txt");
  o.out = "x.copc.laz";  // a plain LAZ under a COPC name would claim an octree it does not have
  EXPECT_EQ(what_of([&] { (void)run_visibility(o); }).rfind("out 'x.copc.laz': writing COPC is not supported by this command", 0), 0u);
  o.out = "";
  o.raster_value = "count";
  o.raster = "m.tif";
  o.cell = 1.0;
  EXPECT_EQ(what_of([&] { (void)run_visibility(o); }), "raster_value count needs observers");
}

// The lengths of the line of sight are refused by their field, with the value, by check_options
// and by the run before the cloud file is opened (it does not exist here, so a run that read it
// would name the file instead); the observers given in code are checked there too, numbered from
// 1. What needs the file is the run's: check_options passes options whose cloud is missing.
TEST(VisibilityJob, CheckOptionsRefusesValuesBeforeAnyFile) {
  VisibilityJobOptions o;
  o.cloud_file = "/nonexistent/cloud.las";
  o.sky_rays = 4;
  EXPECT_NO_THROW(check_options(o));
  EXPECT_NE(what_of([&] { (void)run_visibility(o); }).find("/nonexistent/cloud.las"), std::string::npos);
  const auto refused = [&](auto set, const std::string& expected) {
    VisibilityJobOptions bad = o;
    set(bad);
    EXPECT_EQ(what_of([&] { check_options(bad); }), expected);
    EXPECT_EQ(what_of([&] { (void)run_visibility(bad); }), expected);
  };
  refused([](VisibilityJobOptions& b) { b.radius = -1.0; },
          "radius: expected a finite number > 0 (world units) or auto, got -1");
  refused([](VisibilityJobOptions& b) { b.radius = HUGE_VAL; },
          "radius: expected a finite number > 0 (world units) or auto, got inf");
  refused([](VisibilityJobOptions& b) { b.tolerance = -0.5; },
          "tolerance: expected a finite number >= 0 (world units), got -0.5");
  refused([](VisibilityJobOptions& b) { b.target_height = std::nan(""); },
          "target_height: expected a finite number >= 0 (world units), got nan");
  refused([](VisibilityJobOptions& b) { b.max_distance = -2.0; },
          "max_distance: expected a number >= 0 (world units; infinity: unlimited), got -2");
  refused([](VisibilityJobOptions& b) { b.radius_factor = 0.0; },
          "radius_factor: " + auto_radius_factor_problem(0.0));
  Observer eye;
  eye.position = Vec3(1.0, 2.0, std::nan(""));
  refused([&](VisibilityJobOptions& b) { b.observers = {Observer{}, eye}; },
          what_of([&] { validate_observer(eye, "observer 2"); }));
  // Infinity is an unlimited range, as no max_distance is.
  VisibilityJobOptions unlimited = o;
  unlimited.max_distance = HUGE_VAL;
  EXPECT_NO_THROW(check_options(unlimited));
}

// A period's options (monthly, a step other than the default) with an instant or a day, and a
// day's `every` without one, are refused by check_options and the run before the cloud file is
// opened, naming both options.
TEST(SolarJob, CheckOptionsRefusesWhatTheRunWouldIgnore) {
  SolarJobOptions o;
  o.cloud_file = "/nonexistent/cloud.las";
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.at = "2026-06-21T12:00Z";
  EXPECT_NO_THROW(check_options(o));
  EXPECT_NE(what_of([&] { (void)run_solar(o); }).find("/nonexistent/cloud.las"), std::string::npos);
  const auto refused = [&](auto set, const std::string& expected) {
    SolarJobOptions bad = o;
    set(bad);
    EXPECT_EQ(what_of([&] { check_options(bad); }), expected);
    EXPECT_EQ(what_of([&] { (void)run_solar(bad); }), expected);
  };
  refused([](SolarJobOptions& b) { b.monthly = true; }, "monthly needs a period (start, end), not at");
  refused([](SolarJobOptions& b) { b.step = "15min"; }, "step needs a period (start, end), not at");
  refused([](SolarJobOptions& b) { b.every = "1h"; }, "every needs a day of shadows (day), not at");
  refused([](SolarJobOptions& b) { b.at.clear(), b.day = "2026-06-21", b.monthly = true; },
          "monthly needs a period (start, end), not day");
  refused([](SolarJobOptions& b) { b.at.clear(), b.start = "2026-06-21", b.end = "2026-06-22", b.every = "1h"; },
          "every needs a day of shadows (day), not a period (start, end)");
  refused([](SolarJobOptions& b) { b.tolerance = -1.0; },
          "tolerance: expected a finite number >= 0 (world units), got -1");
  refused([](SolarJobOptions& b) { b.radius = 0.0; },
          "radius: expected a finite number > 0 (world units) or auto, got 0");
}

// `visibility SITE.rsi` queries the mapped index file in place (no tree is
// built) and writes its per-point fields in the sources' original point order. Oracle: the same
// job on the source file (in-memory index); every field must be equal point for point.
TEST(VisibilityJob, IndexFileEqualsTheSourceCloudInOriginalOrder) {
  namespace fs = std::filesystem;
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_vis_rsi");
  PointCloud pc = plane_with_wall();
  std::reverse(pc.positions.begin(), pc.positions.end());  // original order != Morton order
  const fs::path src = dir / "site.ply", rsi = dir / "site.rsi";
  io::write_ply(src, pc);
  io::IndexBuildOptions bo;
  bo.config.capacity = 8;
  bo.attributes = io::AttributeSet::parse("id");  // original order
  io::build_index_file({src}, rsi, bo);
  const fs::path rsi_slots = dir / "slots.rsi";  // without ids: index (slot) order
  bo.attributes = io::AttributeSet::none();
  io::build_index_file({src}, rsi_slots, bo);
  VisibilityJobResult r[4];
  for (int k = 0; k < 4; ++k) {
    VisibilityJobOptions o;
    o.cloud_file = k == 0 ? src : k == 2 ? rsi_slots : rsi;
    if (k >= 2) o.radius = r[0].radius.radius;  // the auto radius samples in the reported order
    Observer eye;
    eye.position = Vec3(0.5, 2.0, 0.0);
    eye.height = 1.7;  // placed on the local ground through the index
    o.observers = {eye};
    o.distance = true;
    o.sky_rays = 8;
    LookAtParams la;
    la.position = Vec3(-1.0, 2.0, 1.5);
    la.look_at = Vec3(2.0, 2.0, 0.5);
    o.camera = Camera::look_at(la, 24, 16);
    o.control.threads = 2;
    r[k] = run_visibility(o);
  }
  ASSERT_EQ(r[0].cloud.size(), pc.size());
  EXPECT_EQ(r[0].cloud.positions, r[1].cloud.positions);
  EXPECT_EQ(r[0].observers[0].position, r[1].observers[0].position);
  EXPECT_EQ(r[0].radius.radius, r[1].radius.radius);
  EXPECT_EQ(r[0].line_of_sight.count, r[1].line_of_sight.count);
  EXPECT_EQ(r[0].line_of_sight.nearest, r[1].line_of_sight.nearest);
  EXPECT_EQ(r[0].sky_view, r[1].sky_view);
  EXPECT_EQ(r[0].camera_hits, r[1].camera_hits);
  // Not vacuous: some points are hidden, some seen, some hit by the camera.
  const auto& c = r[1].line_of_sight.count;
  EXPECT_GT(std::count(c.begin(), c.end(), 0u), 10);
  EXPECT_GT(std::count(c.begin(), c.end(), 1u), 10);
  EXPECT_GT(std::count_if(r[1].camera_hits.begin(), r[1].camera_hits.end(), [](auto v) { return v > 0; }), 10);
  // The index without ids reports every field in slot order, self-consistently: slot s of it is
  // point ids[s] of the same tree with ids (r[3], same radius). The sky view is seeded by the
  // point's reported number, so only the geometric fields are compared.
  {
    const io::MappedIndex with_ids = io::MappedIndex::open(rsi), slots = io::MappedIndex::open(rsi_slots);
    EXPECT_FALSE(slots.has_ids());
    EXPECT_TRUE(slots.ids().is_identity());
    ASSERT_EQ(r[2].cloud.size(), pc.size());
    for (std::size_t s = 0; s < pc.size(); ++s) {
      const PointIndex i = with_ids.ids()[s];
      ASSERT_EQ(r[2].cloud.positions[s], r[3].cloud.positions[i]) << s;
      const Vec3 p = slots.positions()[s];
      ASSERT_EQ(r[2].cloud.positions[s], p) << s;
      EXPECT_EQ(r[2].line_of_sight.count[s], r[3].line_of_sight.count[i]) << s;
      EXPECT_EQ(r[2].line_of_sight.nearest[s], r[3].line_of_sight.nearest[i]) << s;
      EXPECT_EQ(r[2].camera_hits[s], r[3].camera_hits[i]) << s;
    }
  }
  fs::remove_all(dir);
}

namespace {

// True when the two arrays hold the same values bit for bit (NaN and the sign of zero included).
template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// What every comparison of a COPC file in place with the same file read whole checks: the same
// points in the same order, radius, placed observers and per-point fields.
void expect_same_visibility(const VisibilityJobResult& a, const VisibilityJobResult& w) {
  ASSERT_EQ(a.cloud.size(), w.cloud.size());
  EXPECT_EQ(a.cloud.positions, w.cloud.positions);
  EXPECT_EQ(a.radius.radius, w.radius.radius);
  EXPECT_EQ(a.radius.spacing, w.radius.spacing);
  ASSERT_EQ(a.observers.size(), w.observers.size());
  for (std::size_t k = 0; k < a.observers.size(); ++k) EXPECT_EQ(a.observers[k].position, w.observers[k].position);
  EXPECT_EQ(a.surfel_median_radius, w.surfel_median_radius);
  EXPECT_EQ(a.surfel_max_radius, w.surfel_max_radius);
  EXPECT_EQ(a.line_of_sight.count, w.line_of_sight.count);
  EXPECT_EQ(a.line_of_sight.per_observer, w.line_of_sight.per_observer);
  EXPECT_TRUE(same_bits(a.line_of_sight.nearest, w.line_of_sight.nearest));
  EXPECT_TRUE(same_bits(a.sky_view, w.sky_view));
  EXPECT_EQ(a.camera_hits, w.camera_hits);
  ASSERT_EQ(a.cloud.scalars.size(), w.cloud.scalars.size());
  for (std::size_t f = 0; f < a.cloud.scalars.size(); ++f) {
    EXPECT_EQ(a.cloud.scalars[f].name, w.cloud.scalars[f].name);
    EXPECT_TRUE(same_bits(a.cloud.scalars[f].values, w.cloud.scalars[f].values)) << a.cloud.scalars[f].name;
  }
}

// An observer 1.7 m above the local ground at the middle of the small COPC's site.
Observer copc_observer(const AABB& b) {
  Observer eye;
  eye.position = b.center();
  eye.height = 1.7;
  return eye;
}

// The bounds of the points of the COPC file `copc`, read whole.
AABB copc_bounds(const std::filesystem::path& copc) {
  return io::read_point_cloud(copc, io::ReadOptions{.scalars = false}).bounds();
}

// Visibility of the COPC file `copc` with spheres (in place by default).
VisibilityJobOptions copc_sphere_options(const std::filesystem::path& copc) {
  VisibilityJobOptions o;
  o.cloud_file = copc;
  o.primitive = "sphere";
  return o;
}

}  // namespace

// A COPC file is queried in place (io::CopcIndex; its points still read as the output cloud, no
// tree built). Oracle: the same job on the same file read whole (copc_in_place = false: the
// in-memory octree). Line of sight (spheres, the ground found by a box query on the hierarchy),
// distance, sky view and camera marks, the auto radius included, bit for bit, with the default
// cache and with a cache far smaller than the file, which must stay bounded.
TEST(VisibilityJob, CopcInPlaceSpheresEqualTheFileReadWhole) {
  const std::filesystem::path& copc = rayscan::analysis::test::small_copc();
  const io::CopcIndex probe(copc);
  const AABB b = copc_bounds(copc);
  VisibilityJobOptions o = copc_sphere_options(copc);
  o.observers = {copc_observer(b)};
  o.distance = true;
  o.sky_rays = 8;
  LookAtParams la;
  la.position = b.center() + Vec3(0.0, -0.6 * (b.hi.y - b.lo.y), 40.0);
  la.look_at = b.center();
  o.camera = Camera::look_at(la, 32, 24);
  o.control.threads = 2;
  o.copc_in_place = false;
  const VisibilityJobResult whole = run_visibility(o);
  EXPECT_EQ(whole.copc_decodes, 0u);
  o.copc_in_place = true;
  const VisibilityJobResult in_place = run_visibility(o);
  EXPECT_GT(in_place.copc_decodes, 0u);
  expect_same_visibility(in_place, whole);
  // A cache of 256 KB, a few of the file's nodes: chunks' ends evict while others query.
  o.cache_bytes = std::size_t{256} << 10;
  const VisibilityJobResult small = run_visibility(o);
  expect_same_visibility(small, whole);
  std::printf("small COPC: %zu nodes; default cache: %llu decodes, peak %zu B; 256 KB cache: %llu decodes, peak %zu B\n",
              probe.node_count(), static_cast<unsigned long long>(in_place.copc_decodes),
              in_place.copc_peak_cache_bytes, static_cast<unsigned long long>(small.copc_decodes),
              small.copc_peak_cache_bytes);
  // With the default budget every node is decoded once and kept; with 256 KB the ends of the
  // chunks evict (evicted nodes are decoded again) and the peak stays within the budget plus what
  // the two chunks in flight reached: here up to every node, as a chunk's sky rays leave its
  // points in every direction across the site, so the bound is the file's decoded size, the
  // default run's peak. (The camera test below decodes only part of the file.)
  EXPECT_EQ(in_place.copc_decodes, probe.node_count());
  EXPECT_GT(small.copc_decodes, probe.node_count());
  EXPECT_LE(small.copc_peak_cache_bytes, in_place.copc_peak_cache_bytes);
  // Not vacuous: some points hidden, some seen, some hit by the camera.
  const auto& c = whole.line_of_sight.count;
  EXPECT_GT(std::count(c.begin(), c.end(), 0u), 100);
  EXPECT_GT(std::count(c.begin(), c.end(), 1u), 100);
  EXPECT_GT(std::count_if(whole.camera_hits.begin(), whole.camera_hits.end(), [](auto v) { return v > 0; }), 100);
}

// The default primitive, surfels: their normals and radii by kNN over the hierarchy, the line of
// sight through the discs' height field, bit for bit as the file read whole, with a small cache.
TEST(VisibilityJob, CopcInPlaceSurfelsEqualTheFileReadWhole) {
  const std::filesystem::path& copc = rayscan::analysis::test::small_copc();
  const PointCloud pc = io::read_point_cloud(copc, io::ReadOptions{.scalars = false});
  VisibilityJobOptions o;
  o.cloud_file = copc;
  o.observers = {copc_observer(pc.bounds())};
  o.control.threads = 2;
  o.cache_bytes = std::size_t{256} << 10;
  o.copc_in_place = false;
  const VisibilityJobResult whole = run_visibility(o);
  o.copc_in_place = true;
  const VisibilityJobResult in_place = run_visibility(o);
  EXPECT_EQ(in_place.primitive, "surfel");
  EXPECT_GT(in_place.copc_decodes, 0u);
  expect_same_visibility(in_place, whole);
  const auto& c = whole.line_of_sight.count;
  EXPECT_GT(std::count(c.begin(), c.end(), 0u), 100);
  EXPECT_GT(std::count(c.begin(), c.end(), 1u), 100);
}

// Camera marks of a corner of the site with a given radius (no auto radius, no surfels: nothing
// else reads the hierarchy) decode only the nodes the camera's rays reach.
TEST(VisibilityJob, CopcInPlaceCameraDecodesOnlyTheNodesItSees) {
  const std::filesystem::path& copc = rayscan::analysis::test::small_copc();
  const io::CopcIndex probe(copc);
  const AABB b = copc_bounds(copc);
  VisibilityJobOptions o = copc_sphere_options(copc);
  o.radius = 0.5;
  LookAtParams la;
  la.position = b.lo + Vec3(-5.0, -5.0, 30.0);
  la.look_at = b.lo + 0.15 * (b.hi - b.lo);
  la.vfov_deg = 25.0;
  o.camera = Camera::look_at(la, 32, 24);
  o.control.threads = 2;
  const VisibilityJobResult in_place = run_visibility(o);
  EXPECT_GT(in_place.copc_decodes, 0u);
  EXPECT_LT(in_place.copc_decodes, probe.node_count()) << "a corner view decoded every node";
  o.copc_in_place = false;
  const VisibilityJobResult whole = run_visibility(o);
  expect_same_visibility(in_place, whole);
  EXPECT_GT(std::count_if(whole.camera_hits.begin(), whole.camera_hits.end(), [](auto v) { return v > 0; }), 50);
}

namespace {

std::string file_bytes(const std::filesystem::path& p) {
  std::FILE* f = std::fopen(p.string().c_str(), "rb");
  if (!f) return {};
  std::string s;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) s.append(buf, n);
  std::fclose(f);
  return s;
}

}  // namespace

// A viewshed map alone (all_fields false, as the CLI without -o or --json) places the observers
// but skips the per-point line of sight, which only visible_count and visible_distance use.
// Oracles: the GeoTIFF's own bytes from the run that traces it, and the result's counters.
TEST(VisibilityJob, ViewshedMapAloneSkipsThePerPointLineOfSight) {
  namespace fs = std::filesystem;
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_vis_skip");
  const PointCloud pc = plane_with_wall();
  VisibilityJobOptions o;
  o.cloud = &pc;
  o.radius = 0.08;
  Observer eye;
  eye.position = Vec3(0.5, 2.0, 1.7);
  eye.has_z = true;
  o.observers = {eye};
  o.cell = 0.2;
  o.write_preview = false;
  o.control.threads = 2;
  o.raster = dir / "all.tif";
  const VisibilityJobResult all = run_visibility(o);
  EXPECT_EQ(all.line_of_sight.count.size(), pc.size());
  EXPECT_GT(all.line_of_sight.pairs, 0u);
  o.all_fields = false;
  o.raster = dir / "map.tif";
  const VisibilityJobResult map = run_visibility(o);
  EXPECT_TRUE(map.line_of_sight.count.empty());
  EXPECT_EQ(map.line_of_sight.pairs, 0u);
  EXPECT_EQ(map.cloud.scalar("visible_count"), nullptr);
  EXPECT_EQ(map.observers[0].position, all.observers[0].position);
  const std::string want = file_bytes(dir / "all.tif");
  ASSERT_GT(want.size(), 100u);
  EXPECT_EQ(file_bytes(dir / "map.tif"), want);
  // A map of the points' line of sight still runs it.
  o.raster_value = "viewshed-points";
  o.raster = dir / "points.tif";
  EXPECT_EQ(run_visibility(o).line_of_sight.count, all.line_of_sight.count);
  fs::remove_all(dir);
}

// The viewshed map's DSM is traced over the job's own index and surfels: the job's log has one
// index build and one surfel estimate (the DSM's render logs the surfels as the caller's), and the
// map equals dsm_viewshed over the DSM that run_ortho_map renders on its own, building its index
// and estimating its discs (what `render --ortho-map C --dsm` writes), bit for bit. Oracle: that
// separate render; the log counts.
TEST(VisibilityJob, ViewshedDsmReusesTheJobsIndexAndSurfels) {
  PointCloud pc = plane_with_wall();
  // A 1 m high block top from x = 1.6 to 2.4 (the wall's discs are edge-on to a top-down map).
  for (int i = 16; i <= 24; ++i)
    for (int j = 10; j <= 30; ++j) pc.positions.emplace_back(0.1 * i, 0.1 * j, 1.0);
  VisibilityJobOptions o;
  o.cloud = &pc;
  Observer eye;
  eye.position = Vec3(0.5, 2.0, 0.5);
  eye.has_z = true;
  o.observers = {eye};
  o.cell = 0.2;
  o.raster = std::filesystem::temp_directory_path() / ("rayscan_vis_dsm_" + std::to_string(::getpid()) + ".tif");
  o.write_preview = false;
  o.all_fields = false;
  o.control.threads = 2;
  std::vector<std::string> log;
  o.control.log = [&](const std::string& line) { log.push_back(line); };
  const VisibilityJobResult r = run_visibility(o);
  std::filesystem::remove(o.raster);
  ASSERT_TRUE(r.raster);
  const auto lines = [&](const std::string& part) {
    return std::count_if(log.begin(), log.end(), [&](const std::string& l) { return l.find(part) != std::string::npos; });
  };
  EXPECT_EQ(lines("built octree-adaptive index"), 1);
  EXPECT_EQ(lines("PCA"), 1) << "one surfel estimate";
  EXPECT_EQ(lines("DSM: surfels: the caller's"), 1);

  OrthoMapJobOptions mo;
  render::SceneParseOptions po;
  po.camera_required = false;
  po.cloud_required = false;
  mo.render.scene =
      render::parse_scene_json({{"primitive", "surfel"}, {"spp", 1}, {"material", {{"color", "elevation"}}}}, {}, po);
  mo.render.cloud = &pc;
  mo.render.write = false;
  mo.render.control.threads = 2;
  mo.ortho_map = 0.2;
  const OrthoMapJobResult dsm = run_ortho_map(mo);
  const Raster want = dsm_viewshed(dsm.dsm, r.observers, r.max_distance, 0.0, 1);
  ASSERT_EQ(r.raster->values.size(), want.values.size());
  std::size_t seen = 0, hidden = 0;
  for (std::size_t i = 0; i < want.values.size(); ++i) {
    const float a = r.raster->values[i], b = want.values[i];
    EXPECT_TRUE(a == b || (std::isnan(a) && std::isnan(b))) << "cell " << i << ": " << a << " vs " << b;
    seen += b == 1.0f;
    hidden += b == 0.0f;
  }
  EXPECT_GT(seen, 0u);
  EXPECT_GT(hidden, 0u) << "the wall hides some ground";
}

// Without a time the job names its three modes by their fields; the day's clause is its own parts
// (from "," to ")"), which a front end without that option leaves out.
TEST(SolarJob, NoTimeNamesPeriodInstantAndDay) {
  const PointCloud pc = plane_with_wall();
  SolarJobOptions o;
  o.cloud = &pc;
  o.latitude = 48.0;
  o.longitude = 11.0;
  for (const char* start : {"", "2026-06-21"}) {
    o.start = start;
    try {
      (void)run_solar(o);
      ADD_FAILURE() << "no OptionError";
    } catch (const OptionError& e) {
      EXPECT_STREQ(e.what(), "give a period (start and end) or an instant (at), or a day of shadows (day)");
      const std::vector<OptionError::Part>& p = e.parts();
      ASSERT_GE(p.size(), 3u);
      EXPECT_EQ(std::get<std::string>(p[p.size() - 3]), ", or a day of shadows (");
      EXPECT_EQ(std::get<OptionName>(p[p.size() - 2]).field, "day");
      EXPECT_EQ(std::get<std::string>(p.back()), ")");
    }
  }
}

// An instant's shadow map alone (all_fields false, as the CLI without -o) traces only the sun ray:
// the sky-map rays feed the diffuse, reflected and global alone. Oracles: the GeoTIFF's own bytes
// from the run that traces the sky, and the result's counters (rays = points x directions).
TEST(SolarJob, ShadowMapAloneTracesNoSkyRays) {
  namespace fs = std::filesystem;
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_solar_skip");
  const PointCloud pc = plane_with_wall();
  SolarJobOptions o;
  o.cloud = &pc;
  o.radius = 0.08;
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.at = "2026-03-20T16:00:00+01:00";  // a low western sun: the wall casts a shadow
  o.cell = 0.2;
  o.write_preview = false;
  o.control.threads = 2;
  o.raster = dir / "all.tif";
  const SolarJobResult all = run_solar(o);
  EXPECT_EQ(all.sky_rays, 64u);
  EXPECT_EQ(all.rays, pc.size() * 65);
  EXPECT_NE(all.cloud.scalar("irradiance_diffuse"), nullptr);
  o.all_fields = false;
  o.raster = dir / "shadow.tif";
  const SolarJobResult shadow = run_solar(o);
  EXPECT_EQ(shadow.sky_rays, 0u);
  EXPECT_EQ(shadow.rays, pc.size());
  // The fields the sky would have given are left out, not filled with the open sky's values.
  EXPECT_EQ(shadow.cloud.scalar("irradiance_diffuse"), nullptr);
  EXPECT_EQ(shadow.cloud.scalar("irradiance_global"), nullptr);
  ASSERT_NE(shadow.cloud.scalar("in_shadow"), nullptr);
  const std::vector<double>& lit = shadow.cloud.scalar("in_shadow")->values;
  EXPECT_GT(std::count(lit.begin(), lit.end(), 1.0), 10);  // not vacuous: some shade, some sun
  EXPECT_GT(std::count(lit.begin(), lit.end(), 0.0), 10);
  EXPECT_EQ(lit, all.cloud.scalar("in_shadow")->values);
  const std::string want = file_bytes(dir / "all.tif");
  ASSERT_GT(want.size(), 100u);
  EXPECT_EQ(file_bytes(dir / "shadow.tif"), want);
  // A map of the global irradiance needs the sky.
  o.raster_value = "global";
  o.raster = dir / "global.tif";
  EXPECT_EQ(run_solar(o).sky_rays, 64u);
  fs::remove_all(dir);
}
