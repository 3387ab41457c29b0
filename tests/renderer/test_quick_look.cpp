// The quick look: the automatic overview camera frames the cloud's bounding box
// (checked by projecting the box corners with Camera::look_at's own rays' geometry: an
// independent pinhole projection from the look-at parameters), `--print-scene` prints a scene
// that renders the same image when fed back (the render is a pure function of the scene and seed),
// the scene's up is the up axis the camera stands on, and an index file renders the same quick
// look as its source.
#include "../common/temp_dir.hpp"
#include "rayscan/jobs/quick_look.hpp"

#include "../common/run_command.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/material.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <random>
#include <set>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <string>

namespace fs = std::filesystem;
using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;

namespace {

/// Normalised image coordinates (x right, y up, both in [-1, 1] inside the image) of p seen by
/// the pinhole look-at camera p / width x height (RTIOW section 11: viewport 2 tan(vfov / 2) high).
std::array<double, 3> project(const LookAtParams& c, std::uint32_t w, std::uint32_t h, const Vec3& p) {
  const Vec3 f = glm::normalize(c.look_at - c.position);
  const Vec3 r = glm::normalize(glm::cross(f, c.up));
  const Vec3 u = glm::cross(r, f);
  const Vec3 v = p - c.position;
  const double z = glm::dot(v, f);
  const double tv = std::tan(c.vfov_deg * std::numbers::pi / 360.0), th = tv * w / h;
  return {glm::dot(v, r) / z / th, glm::dot(v, u) / z / tv, z};
}

fs::path quick_look_temp_dir() { return rayscan::test::process_temp_dir("rayscan_quick_look"); }

}  // namespace

TEST(OverviewCamera, FramesEveryCornerOfTheBoxTightly) {
  for (const auto& [lo, hi, w, h] : {std::tuple{Vec3(636001.76, 848935.2, 406.26), Vec3(637179.22, 849497.9, 520.51), 600u, 400u},
                                     std::tuple{Vec3(-1, -2, 0), Vec3(1, 2, 10), 300u, 500u},
                                     std::tuple{Vec3(5, 5, 5), Vec3(5, 5, 5), 64u, 64u}}) {
    AABB box;
    box.lo = lo;
    box.hi = hi;
    const LookAtParams c = overview_view(box, w, h);
    EXPECT_EQ(c.up, Vec3(0, 0, 1));
    EXPECT_EQ(c.look_at, 0.5 * (lo + hi));
    // From above at the documented pitch, from the south-west.
    const Vec3 d = glm::normalize(c.look_at - c.position);
    EXPECT_NEAR(std::asin(-d.z) * 180 / std::numbers::pi, kOverviewPitchDeg, 1e-9);
    EXPECT_GT(d.x, 0.0);  // looking north-east
    EXPECT_GT(d.y, 0.0);
    double extent = 0.0;
    Vec3 half = 0.5 * (hi - lo);
    if (glm::length(half) == 0.0) half = Vec3(0.5);
    for (int k = 0; k < 8; ++k) {
      const Vec3 p = c.look_at + Vec3((k & 1) ? half.x : -half.x, (k & 2) ? half.y : -half.y, (k & 4) ? half.z : -half.z);
      const auto q = project(c, w, h, p);
      EXPECT_GT(q[2], 0.0);
      EXPECT_LE(std::abs(q[0]), 1.0);
      EXPECT_LE(std::abs(q[1]), 1.0);
      extent = std::max({extent, std::abs(q[0]), std::abs(q[1])});
    }
    EXPECT_GT(extent, 0.97);  // tight: some corner touches the 2% margin
  }
  AABB empty;
  EXPECT_THROW(overview_view(empty, 10, 10), std::invalid_argument);
}

TEST(QuickLook, CloudRendersAndPrintedSceneReproducesTheImage) {
  const fs::path d = quick_look_temp_dir();
  {
    std::ofstream xyz(d / "c.xyz");
    for (int i = 0; i < 20; ++i)
      for (int j = 0; j < 20; ++j) xyz << i * 0.5 << " " << j * 0.5 << " " << 0.1 * std::sin(i + j) << "\n";
  }
  const std::string bin = RAYSCAN_BIN;
  const auto a = rayscan::test::run_command(bin + " render -q " + (d / "c.xyz").string() + " --spp 2 --width 60 --out " +
                                   (d / "a.png").string());
  ASSERT_EQ(a.code, 0) << a.out;
  const auto p = rayscan::test::run_command(bin + " render " + (d / "c.xyz").string() + " --spp 2 --width 60 --out " +
                                       (d / "b.png").string() + " --print-scene",
                                   false);
  ASSERT_EQ(p.code, 0) << p.out;
  EXPECT_FALSE(fs::exists(d / "b.png"));  // --print-scene does not render
  std::ofstream(d / "printed.json") << p.out;
  EXPECT_NE(p.out.find("\"width\": 60"), std::string::npos) << p.out;
  EXPECT_NE(p.out.find("\"height\": 40"), std::string::npos) << p.out;  // 3:2 kept
  EXPECT_NE(p.out.find("\"color\": \"elevation\""), std::string::npos) << p.out;  // no RGB in the file
  // Rendered from another folder: paths in the printed scene are absolute.
  const auto b = rayscan::test::run_command("cd / && " + bin + " render -q " + (d / "printed.json").string());
  ASSERT_EQ(b.code, 0) << b.out;
  const auto cmp = rayscan::test::run_command(bin + " compare " + (d / "a.png").string() + " " + (d / "b.png").string());
  EXPECT_EQ(cmp.code, 0) << cmp.out;  // identical images (idiff default: no pixel over 1e-6)
  // A scene file without a camera gets the same overview camera (and with the quick look's up,
  // the same image).
  const nlohmann::json printed = nlohmann::json::parse(p.out);
  std::ofstream(d / "nocam.json") << R"({"cloud": "c.xyz", "radius": "auto", "primitive": "surfel", "material": {"color": "elevation"},
    "spp": 2, "output": {"image": "n.png"}, "up": )" << printed.at("up").dump() << "}";
  const auto n = rayscan::test::run_command(bin + " render -q " + (d / "nocam.json").string() + " --width 60");
  ASSERT_EQ(n.code, 0) << n.out;
  const auto cn = rayscan::test::run_command(bin + " compare " + (d / "a.png").string() + " " + (d / "n.png").string());
  EXPECT_EQ(cn.code, 0) << cn.out;
  fs::remove_all(d);
}

// "Zoom to extent" on the bundled real scans: every point projects inside the image and the
// points' projected bounds span at least 80% of the frame's shorter side (the box-corner fit left
// 40-60%), with the up axis the CLI chooses (+z for georeferenced clouds, -y for a depth camera's
// PCD). Oracle: the independent pinhole projection `project` of every point.
TEST(OverviewCamera, ZoomToExtentFillsTheFrameOnRealScans) {
  for (const std::string name : {"autzen_trim.las", "Haystack_Rock.las", "office1.pcd",
                                 "table_scene_mug_stereo_textured.pcd"}) {
    io::FileInfo info;
    const PointCloud pc = io::read_point_cloud(std::string(RAYSCAN_SCENES_DIR) + "/data/" + name, {}, &info);
    std::optional<Vec3> sensor;
    if (info.viewpoint) sensor = Vec3((*info.viewpoint)[0], (*info.viewpoint)[1], (*info.viewpoint)[2]);
    const CloudSummary s = summarize_cloud(pc.positions, !pc.rgb.empty(), !pc.crs_wkt.empty(), sensor);
    const std::uint32_t w = kOverviewWidth, h = kOverviewHeight;
    const LookAtParams c = overview_view(s.sample, s.up, w, h);
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const Vec3& p : pc.positions) {  // every point, not only the sample
      const auto q = project(c, w, h, p);
      ASSERT_GT(q[2], 0.0) << name;
      x0 = std::min(x0, q[0]), x1 = std::max(x1, q[0]), y0 = std::min(y0, q[1]), y1 = std::max(y1, q[1]);
    }
    // The sample frames the cloud: points outside it stay within a pixel or two of the margin.
    EXPECT_GE(x0, -1.01) << name;
    EXPECT_LE(x1, 1.01) << name;
    EXPECT_GE(y0, -1.01) << name;
    EXPECT_LE(y1, 1.01) << name;
    // Extents in pixels; the shorter side is the height (3:2).
    const double px_w = 0.5 * (x1 - x0) * w, px_h = 0.5 * (y1 - y0) * h;
    std::printf("%s: up (%.3f, %.3f, %.3f); projected bounds %.0f x %.0f px of %u x %u (%.0f%% of the height)\n",
                name.c_str(), s.up.up.x, s.up.up.y, s.up.up.z, px_w, px_h, w, h, 100.0 * px_h / h);
    EXPECT_GE(std::max(px_w / w, px_h / h), 0.95) << name;  // tight along one side (2% margin)
    EXPECT_GE(px_h / h, 0.8) << name;  // the shorter side
    // Centred: the margins on opposite sides are equal to within 2% of the frame.
    EXPECT_NEAR(x0 + x1, 0.0, 0.04) << name;
    EXPECT_NEAR(y0 + y1, 0.0, 0.04) << name;
  }
}

// The up axis: +z for a georeferenced cloud whatever its shape; -y for a depth camera's cloud in
// its optical frame (office1: the walls and the door are vertical in the camera's image, so the
// floor-to-ceiling direction is -y); for a cloud without a CRS or scanner, the normal of the
// dominant plane (a floor tilted by a known rotation, with boxes standing on it: the analytic
// answer is the rotated +z), turned towards the points' centroid.
TEST(UpAxis, GeoreferencedDepthCameraAndDominantPlane) {
  const std::vector<Vec3> few = {Vec3(0, 0, 0), Vec3(1, 0, 0)};
  EXPECT_EQ(estimate_up_axis(few, true, std::nullopt).up, Vec3(0, 0, 1));
  EXPECT_EQ(estimate_up_axis(few, false, std::nullopt).up, Vec3(0, 0, 1));  // too few points: +z

  io::FileInfo info;
  const PointCloud office = io::read_point_cloud(std::string(RAYSCAN_SCENES_DIR) + "/data/office1.pcd", {}, &info);
  ASSERT_TRUE(info.viewpoint.has_value());
  const CloudSummary so = summarize_cloud(office.positions, true, false, Vec3(0.0));
  EXPECT_GE(glm::dot(so.up.up, Vec3(0, -1, 0)), 0.93969262078590838) << so.up.how;  // within 20 degrees of -y
  ASSERT_TRUE(so.up.facing.has_value());
  EXPECT_GT(so.up.facing->z, 0.0);  // the scanner looks along +z

  // A tilted floor (rotation by 30 degrees about x, then 20 about z) with boxes on it.
  const double a = 30.0 * std::numbers::pi / 180.0, b = 20.0 * std::numbers::pi / 180.0;
  auto rot = [&](const Vec3& p) {
    const Vec3 q(p.x, std::cos(a) * p.y - std::sin(a) * p.z, std::sin(a) * p.y + std::cos(a) * p.z);
    return Vec3(std::cos(b) * q.x - std::sin(b) * q.y, std::sin(b) * q.x + std::cos(b) * q.y, q.z);
  };
  std::vector<Vec3> pts;
  for (int i = 0; i < 120; ++i)
    for (int j = 0; j < 120; ++j) pts.push_back(rot(Vec3(0.1 * i + 0.01 * std::sin(j), 0.1 * j + 0.01 * std::cos(i), 0.0)));
  for (int k = 0; k < 4; ++k)  // box tops 1 unit above the floor, and their sides
    for (int i = 0; i < 15; ++i)
      for (int j = 0; j < 15; ++j) {
        const double x0 = 1.0 + 3.0 * k, y0 = 2.0 + 2.0 * k;
        pts.push_back(rot(Vec3(x0 + 0.1 * i, y0 + 0.1 * j, 1.0)));
        pts.push_back(rot(Vec3(x0, y0 + 0.1 * i, 0.07 * j)));
      }
  const UpAxis up = estimate_up_axis(pts, false, std::nullopt);
  const Vec3 want = rot(Vec3(0, 0, 1));
  EXPECT_GE(glm::dot(up.up, want), std::cos(2.0 * std::numbers::pi / 180.0)) << up.how;
  // The same cloud upside down: the centroid is now on the other side, so is the answer.
  std::vector<Vec3> flipped;
  for (const Vec3& p : pts) flipped.push_back(-p);
  EXPECT_GE(glm::dot(estimate_up_axis(flipped, false, std::nullopt).up, -want), std::cos(2.0 * std::numbers::pi / 180.0));
}

// A PCD of an airborne scan in UTM metres (autzen-utm.pcd: no CRS, the identity VIEWPOINT every
// PCD writer puts in its header) is no depth camera's view: its points lie ~1e6 m east and north
// of the origin, not ahead of it along +z. Its up is the ground's normal pointing away from the
// ground (the centroid's side, not the origin's, which lies 100 m below it): within 2 degrees of +z.
TEST(UpAxis, AnIdentityViewpointFarFromThePointsIsNoCameraAndNoScanner) {
  io::FileInfo info;
  const PointCloud utm = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/pcd/autzen-utm.pcd", {}, &info);
  ASSERT_TRUE(info.viewpoint.has_value());
  const Vec3 origin((*info.viewpoint)[0], (*info.viewpoint)[1], (*info.viewpoint)[2]);
  ASSERT_EQ(origin, Vec3(0.0));
  ASSERT_TRUE(utm.crs_wkt.empty());
  const CloudSummary s = summarize_cloud(utm.positions, true, false, origin);
  EXPECT_GE(glm::dot(s.up.up, Vec3(0, 0, 1)), std::cos(2.0 * std::numbers::pi / 180.0)) << s.up.how;
  EXPECT_EQ(s.up.how.find("depth camera"), std::string::npos) << s.up.how;
  EXPECT_EQ(s.up.how.find("scanner"), std::string::npos) << s.up.how;
}

namespace {

/// A floor tilted by 30 degrees about x, then 20 about z, with four boxes standing on it (tops 1
/// unit above the floor): the analytic up axis is the rotated +z.
struct TiltedFloor {
  double a = 30.0 * std::numbers::pi / 180.0, b = 20.0 * std::numbers::pi / 180.0;
  Vec3 rot(const Vec3& p) const {
    const Vec3 q(p.x, std::cos(a) * p.y - std::sin(a) * p.z, std::sin(a) * p.y + std::cos(a) * p.z);
    return Vec3(std::cos(b) * q.x - std::sin(b) * q.y, std::sin(b) * q.x + std::cos(b) * q.y, q.z);
  }
  std::vector<Vec3> floor, tops, sides;
  TiltedFloor() {
    for (int i = 0; i < 120; ++i)
      for (int j = 0; j < 120; ++j)
        floor.push_back(rot(Vec3(0.1 * i + 0.01 * std::sin(j), 0.1 * j + 0.01 * std::cos(i), 0.0)));
    for (int k = 0; k < 4; ++k)
      for (int i = 0; i < 15; ++i)
        for (int j = 0; j < 15; ++j) {
          const double x0 = 1.0 + 3.0 * k, y0 = 2.0 + 2.0 * k;
          tops.push_back(rot(Vec3(x0 + 0.1 * i, y0 + 0.1 * j, 1.0)));
          sides.push_back(rot(Vec3(x0, y0 + 0.1 * i, 0.07 * j)));
        }
  }
  std::vector<Vec3> all() const {
    std::vector<Vec3> v = floor;
    v.insert(v.end(), tops.begin(), tops.end());
    v.insert(v.end(), sides.begin(), sides.end());
    return v;
  }
};

/// Largest difference of one channel between any two of `colours`.
float colour_spread(std::span<const Color> colours) {
  float spread = 0.0f;
  for (int c = 0; c < 3; ++c) {
    const auto [lo, hi] = std::minmax_element(colours.begin(), colours.end(),
                                              [c](const Color& x, const Color& y) { return x[c] < y[c]; });
    spread = std::max(spread, (*hi)[c] - (*lo)[c]);
  }
  return spread;
}

}  // namespace

// The quick look's scene up (the elevation ramp's and the sky's axis) is the up axis its camera
// stands on and the CLI prints: on a tilted floor with boxes (no CRS) it is the analytic floor
// normal, so the elevation colour of the level floor is one colour and that of the box tops
// another (as a level table top and floor); along +z, a fixed scene up, the same floor would span
// most of the ramp. Oracle: the analytic normal and the points' known heights above the floor.
TEST(QuickLook, SceneUpIsThePrintedUpAxis) {
  const TiltedFloor t;
  const std::vector<Vec3> pts = t.all();
  const Vec3 want = t.rot(Vec3(0, 0, 1));
  const CloudSummary s = summarize_cloud(pts, false, false, std::nullopt);
  const ResolvedScene q = resolve_quick_look(s, SceneOverrides{});
  EXPECT_EQ(q.scene.up, s.up.up);  // the estimate itself, unchanged by the scene parser's normalisation
  EXPECT_EQ(q.up.up, s.up.up);
  EXPECT_GE(glm::dot(q.scene.up, want), std::cos(0.5 * std::numbers::pi / 180.0)) << s.up.how;
  // --print-scene's JSON reads back to the same up, and the camera stands on it.
  const nlohmann::json j = nlohmann::json::parse(q.json);
  const auto vec = [](const nlohmann::json& v) { return Vec3(v[0].get<double>(), v[1].get<double>(), v[2].get<double>()); };
  EXPECT_EQ(vec(j.at("up")), q.scene.up);
  EXPECT_GE(glm::dot(glm::normalize(vec(j.at("camera").at("up"))), q.scene.up), 1.0 - 1e-12);

  PointCloud pc;
  pc.positions = pts;
  const std::vector<Color> albedo = compute_albedo(pc, q.scene.material, q.scene.up);
  const std::span<const Color> floor(albedo.data(), t.floor.size()), tops(albedo.data() + t.floor.size(), t.tops.size());
  const std::vector<Color> along_z = compute_albedo(pc, q.scene.material, Vec3(0, 0, 1));
  std::printf("colour spread: floor %.3f, box tops %.3f; floor along +z %.3f\n", colour_spread(floor),
              colour_spread(tops), colour_spread(std::span<const Color>(along_z.data(), t.floor.size())));
  EXPECT_LE(colour_spread(floor), 0.06f);
  EXPECT_LE(colour_spread(tops), 0.06f);  // the estimate is within about 0.2 degrees of the analytic axis
  EXPECT_GE(glm::length(floor[0] - tops[0]), 0.3f);  // the ramp's two ends
  EXPECT_GE(colour_spread(std::span<const Color>(along_z.data(), t.floor.size())), 0.5f);

  // The CLI prints the same axis (to 3 decimals) as the scene's up.
  const fs::path d = quick_look_temp_dir();
  {
    std::ofstream xyz(d / "tilted.xyz");
    xyz.precision(17);
    for (const Vec3& p : pts) xyz << p.x << " " << p.y << " " << p.z << "\n";
  }
  const std::string bin = RAYSCAN_BIN;
  const auto r = rayscan::test::run_command(bin + " render " + (d / "tilted.xyz").string() +
                                            " --spp 1 --width 30 --out " + (d / "t.png").string());
  ASSERT_EQ(r.code, 0) << r.out;
  double x = 0, y = 0, z = 0;
  const std::size_t at = r.out.find("up axis (");
  ASSERT_NE(at, std::string::npos) << r.out;
  ASSERT_EQ(std::sscanf(r.out.c_str() + at, "up axis (%lf, %lf, %lf)", &x, &y, &z), 3) << r.out;
  const auto ps = rayscan::test::run_command(bin + " render " + (d / "tilted.xyz").string() + " --print-scene", false);
  ASSERT_EQ(ps.code, 0) << ps.out;
  const nlohmann::json printed = nlohmann::json::parse(ps.out);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(printed.at("up")[k].get<double>(), (std::array{x, y, z})[k], 5.1e-4) << r.out;
  fs::remove_all(d);
}

// The sample, up axis and overview camera are functions of the points, not of their order (an
// index file stores them in Morton order): autzen's points without their CRS (so the up axis is
// estimated from the sample), reversed and shuffled, give bit-identical summaries. The sample is
// kOverviewSample of the points themselves (each one of them, distinct ones distinct), and a cloud
// of few distinct positions repeated many times is sampled the same in any order too.
TEST(QuickLook, SummaryDoesNotDependOnThePointsOrder) {
  const PointCloud pc = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las", {});
  ASSERT_GT(pc.size(), kOverviewSample);
  std::vector<Vec3> reversed(pc.positions.rbegin(), pc.positions.rend()), shuffled = pc.positions;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937_64(7));
  const CloudSummary a = summarize_cloud(pc.positions, false, false, std::nullopt);
  ASSERT_EQ(a.sample.size(), kOverviewSample);
  EXPECT_NE(a.up.up, Vec3(0, 0, 1)) << a.up.how;  // estimated, not a fallback
  const auto bits = [](const Vec3& p) {
    return std::array{std::bit_cast<std::uint64_t>(p.x), std::bit_cast<std::uint64_t>(p.y), std::bit_cast<std::uint64_t>(p.z)};
  };
  std::set<std::array<std::uint64_t, 3>> cloud, sample;
  for (const Vec3& p : pc.positions) cloud.insert(bits(p));
  for (const Vec3& p : a.sample) {
    EXPECT_TRUE(cloud.count(bits(p))) << "a sample point that is not a point of the cloud";
    sample.insert(bits(p));
  }
  EXPECT_EQ(sample.size(), a.sample.size());  // autzen has no duplicate positions
  const LookAtParams ca = overview_view(a.sample, a.up, kOverviewWidth, kOverviewHeight);
  for (const std::vector<Vec3>* other : {&reversed, &shuffled}) {
    const CloudSummary b = summarize_cloud(*other, false, false, std::nullopt);
    EXPECT_EQ(b.sample, a.sample);
    EXPECT_EQ(b.up.up, a.up.up);
    const LookAtParams cb = overview_view(b.sample, b.up, kOverviewWidth, kOverviewHeight);
    EXPECT_EQ(cb.position, ca.position);
    EXPECT_EQ(cb.look_at, ca.look_at);
  }
  // 8 distinct positions, 25,000 copies of each: kOverviewSample of the copies, the same in any order.
  std::vector<Vec3> copies;
  for (int c = 0; c < 25000; ++c)
    for (int k = 0; k < 8; ++k) copies.push_back(Vec3(k & 1, (k >> 1) & 1, k >> 2));
  const CloudSummary ra = summarize_cloud(copies, false, false, std::nullopt);
  std::shuffle(copies.begin(), copies.end(), std::mt19937_64(11));
  const CloudSummary rb = summarize_cloud(copies, false, false, std::nullopt);
  EXPECT_EQ(ra.sample.size(), kOverviewSample);
  EXPECT_EQ(ra.sample, rb.sample);
  // Fewer points than kOverviewSample: all of them.
  const std::vector<Vec3> few(pc.positions.begin(), pc.positions.begin() + 1000);
  EXPECT_EQ(summarize_cloud(few, false, false, std::nullopt).sample.size(), 1000u);
}

// An index file with the source's colours renders the same quick look as its source, bit for bit
// (autzen, 110,000 points: more than kOverviewSample, so a sample taken in storage order would
// differ), for a georeferenced LAS file (up +z) and for the same points as a text file without a
// CRS (up estimated), with the source's ids and without them (points in index order: the camera,
// up axis and sample do not depend on the order; autzen has no two discs a ray meets at the same
// distance, whose tie the point index breaks). Oracle: `rayscan compare` of the PNGs (exit 0: no
// pixel differs) and the printed scenes' cameras.
TEST(QuickLook, IndexFileRendersTheSameQuickLookAsItsSource) {
  const fs::path d = quick_look_temp_dir();
  const std::string bin = RAYSCAN_BIN;
  const fs::path las = fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las";
  const auto tr = rayscan::test::run_command(bin + " translate " + las.string() + " " + (d / "autzen.xyz").string());
  ASSERT_EQ(tr.code, 0) << tr.out;
  for (const auto& [src, attributes] : {std::pair{las, "id,rgb"}, std::pair{las, "rgb"},
                                         std::pair{d / "autzen.xyz", "id,rgb"}, std::pair{d / "autzen.xyz", "rgb"}}) {
    const std::string rsi = (d / (src.filename().string() + ".rsi")).string();
    const auto ix =
        rayscan::test::run_command(bin + " index " + src.string() + " -o " + rsi + " --attributes " + attributes + " -q");
    ASSERT_EQ(ix.code, 0) << ix.out;
    nlohmann::json cams[2];
    int k = 0;
    for (const std::string& in : {src.string(), rsi}) {
      const std::string look = bin + " render " + in + " --spp 1 --width 60";
      const auto r = rayscan::test::run_command(look + " -q --out " + (d / ("q" + std::to_string(k) + ".png")).string());
      ASSERT_EQ(r.code, 0) << r.out;
      const auto ps = rayscan::test::run_command(look + " --print-scene", false);
      ASSERT_EQ(ps.code, 0) << ps.out;
      const nlohmann::json j = nlohmann::json::parse(ps.out);
      EXPECT_EQ(j.at("material").at("color"), "rgb") << in;
      if (src == las) EXPECT_EQ(j.at("up"), nlohmann::json::parse("[0.0, 0.0, 1.0]"));  // georeferenced: +z
      else EXPECT_NE(j.at("up"), nlohmann::json::parse("[0.0, 0.0, 1.0]"));  // estimated
      cams[k++] = j.at("camera");
    }
    EXPECT_EQ(cams[0], cams[1]) << src << " " << attributes;
    const auto cmp = rayscan::test::run_command(bin + " compare " + (d / "q0.png").string() + " " + (d / "q1.png").string());
    EXPECT_EQ(cmp.code, 0) << src << " " << attributes << "\n" << cmp.out;
  }
  fs::remove_all(d);
}

namespace {

/// True when estimate_up_axis chose the sign by the convention (its reason text says which rule).
bool sign_by_convention(const UpAxis& u) { return u.how.find("largest component") != std::string::npos; }

/// An 80 x 40 grid of points 0.25 apart through `origin` along the unit vectors `a` and `b`, each
/// point moved `noise(i, j)` along `a` x `b`.
std::vector<Vec3> grid_plane(const Vec3& origin, const Vec3& a, const Vec3& b,
                             const std::function<double(int, int)>& noise = {}) {
  std::vector<Vec3> v;
  const Vec3 n = glm::cross(a, b);
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 80; ++i)
      v.push_back(origin + (0.125 + 0.25 * i) * a + (0.125 + 0.25 * j) * b + (noise ? noise(i, j) : 0.0) * n);
  return v;
}

}  // namespace

// A flat cloud without a CRS has nothing to tell up from down (its centroid lies in its plane):
// its up axis is the plane's normal with the largest-magnitude component positive, the +z / +y /
// +x convention of scanners and meshes, wherever the plane lies and whichever way its points are
// listed. Oracle: the planes' analytic normals. A cloud with relief off its dominant plane keeps
// the centroid's side (UpAxis.GeoreferencedDepthCameraAndDominantPlane: the flipped tilted floor).
TEST(UpAxis, AFlatCloudTakesTheSignOfItsNormalsLargestComponent) {
  const double deg = std::cos(1.0 * std::numbers::pi / 180.0);
  const auto expect_up = [&](const std::vector<Vec3>& pts, const Vec3& want, const char* what) {
    const UpAxis u = estimate_up_axis(pts, false, std::nullopt);
    EXPECT_GE(glm::dot(u.up, want), deg) << what << ": " << u.how;
    EXPECT_TRUE(sign_by_convention(u)) << what << ": " << u.how;
    std::vector<Vec3> mirrored;  // the same points through the origin: the same plane orientation
    for (const Vec3& p : pts) mirrored.push_back(-p);
    const UpAxis m = estimate_up_axis(mirrored, false, std::nullopt);
    EXPECT_GE(glm::dot(m.up, want), deg) << what << " mirrored: " << m.how;
  };
  const Vec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
  expect_up(grid_plane(Vec3(0, 0, 3), x, y), z, "level at z = 3");
  expect_up(grid_plane(Vec3(0, 0, 3), y, x), z, "level at z = 3, listed along y first");
  expect_up(grid_plane(Vec3(0, 0, -3), x, y), z, "level at z = -3");
  expect_up(grid_plane(Vec3(0, 5, 0), x, z), y, "a wall at y = 5");
  expect_up(grid_plane(Vec3(-7, 0, 0), y, z), x, "a wall at x = -7");
  // Noise of +-0.03 off the plane (a scan's; 0.13% of the grid's size, above the 0.1% floor): the
  // plane's thickness is then the points' median distance from it.
  expect_up(grid_plane(Vec3(0, 0, 3), x, y, [](int i, int j) { return 0.03 * std::sin(12.9898 * i + 78.233 * j); }),
            z, "level with noise");
  // The tilted floor without its boxes: its normal rot(+z) = (0.17, -0.47, 0.87) keeps z positive.
  const TiltedFloor t;
  expect_up(t.floor, t.rot(z), "tilted floor");
  // A georeferenced flat cloud: exactly +z, the CRS's vertical.
  EXPECT_EQ(estimate_up_axis(grid_plane(Vec3(0, 0, 3), x, y), true, std::nullopt).up, z);
}

// The CLI's quick look of a flat cloud without a CRS (80 x 40 points on z = 3) prints and uses up
// +z with the camera above the plane looking down; the log says what the elevation colours mean.
// Oracle: the points' known heights: the ramp's ends are their 2nd and 98th percentile (ranks
// n * 2 / 100 and n * 98 / 100 of the sorted heights; along an estimated axis other than +z,
// heights above the lowest point along it), in "world units" without a CRS and in the CRS's unit
// for autzen (international foot, EPSG:2992) through an index file without colours.
TEST(QuickLook, FlatCloudIsSeenFromAboveAndTheElevationColoursAreLogged) {
  const fs::path d = quick_look_temp_dir() / "flat";
  fs::create_directories(d);
  {
    std::ofstream xyz(d / "sq.xyz");
    for (const Vec3& p : grid_plane(Vec3(0, 0, 3), Vec3(1, 0, 0), Vec3(0, 1, 0))) xyz << p.x << " " << p.y << " " << p.z << "\n";
  }
  const std::string bin = RAYSCAN_BIN;
  const auto p = rayscan::test::run_command(bin + " render " + (d / "sq.xyz").string() + " --print-scene", false);
  ASSERT_EQ(p.code, 0) << p.out;
  const nlohmann::json j = nlohmann::json::parse(p.out);
  EXPECT_EQ(j.at("up"), nlohmann::json::parse("[0.0, 0.0, 1.0]")) << p.out;
  EXPECT_GT(j.at("camera").at("position")[2].get<double>(), 3.0) << p.out;  // above the plane
  EXPECT_GT(j.at("camera").at("up")[2].get<double>(), 0.0) << p.out;

  // The log line's axis, ramp, ends and unit.
  struct LoggedRamp {
    Vec3 up;
    std::string ramp, unit;
    double lo = 0.0, hi = 0.0;
  };
  // The line along +z gives the points' heights; along another axis, heights above the lowest
  // point along it (`above_lowest`).
  const auto logged = [&](const std::string& cloud, bool above_lowest = false) {
    const auto r = rayscan::test::run_command(bin + " render " + cloud + " --width 30 --spp 1 --out " + (d / "x.png").string());
    EXPECT_EQ(r.code, 0) << r.out;
    const std::string key =
        above_lowest ? "colour: height above the lowest point along up (" : "colour: elevation along up (";
    const std::size_t at = r.out.find(key);
    LoggedRamp g;
    if (at == std::string::npos) {
      ADD_FAILURE() << "no elevation colour line: " << r.out;
      return g;
    }
    const std::string line = r.out.substr(at, r.out.find('\n', at) - at);
    char ramp[32] = {}, unit[64] = {};
    EXPECT_EQ(std::sscanf(line.c_str() + key.size(), "%lf, %lf, %lf), %31[^,], %lf (dark) .. %lf (bright) %63[^,]", &g.up.x,
                          &g.up.y, &g.up.z, ramp, &g.lo, &g.hi, unit),
              7)
        << line;
    g.ramp = ramp;
    g.unit = unit;
    EXPECT_NE(line.find(above_lowest ? "the 2nd and 98th percentiles of the points' heights along that axis"
                                     : "the 2nd and 98th percentiles of the points' heights"),
              std::string::npos)
        << line;
    return g;
  };
  const auto percentiles = [](std::vector<double> h) {
    std::sort(h.begin(), h.end());
    return std::array<double, 2>{h[h.size() * 2 / 100], h[h.size() * 98 / 100]};
  };
  {
    // Every height is 3: the ramp spans 3 .. 3 + 1 (a range needs two ends), all points dark.
    const LoggedRamp g = logged((d / "sq.xyz").string());
    EXPECT_EQ(g.up, Vec3(0, 0, 1));
    EXPECT_EQ(g.ramp, "viridis");
    EXPECT_EQ(g.unit, "world units");
    EXPECT_EQ(g.lo, 3.0);
    EXPECT_EQ(g.hi, 4.0);
  }
  {
    // A rough floor (+-0.002) with three boxes' tops at 1, 1.7 and 2.4: the ends are the 2nd and
    // 98th percentile of the heights along the printed up axis, estimated from the rough floor
    // (not exactly +z), so above the lowest point along it.
    std::vector<Vec3> pts = grid_plane(Vec3(0.0), Vec3(1, 0, 0), Vec3(0, 1, 0),
                                       [](int i, int j) { return 0.002 * std::sin(12.9898 * i + 78.233 * j); });
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) pts.push_back(Vec3(2.0 + 6.0 * k + 0.25 * i, 3.0 + 0.25 * j, 1.0 + 0.7 * k));
    {
      std::ofstream xyz(d / "boxes.xyz");
      xyz.precision(17);
      for (const Vec3& q : pts) xyz << q.x << " " << q.y << " " << q.z << "\n";
    }
    const auto ps = rayscan::test::run_command(bin + " render " + (d / "boxes.xyz").string() + " --print-scene", false);
    ASSERT_EQ(ps.code, 0) << ps.out;
    const nlohmann::json u = nlohmann::json::parse(ps.out).at("up");
    const Vec3 up(u[0].get<double>(), u[1].get<double>(), u[2].get<double>());
    ASSERT_GE(up.z, 0.999) << ps.out;  // the floor's normal, towards the boxes
    ASSERT_NE(up, Vec3(0, 0, 1)) << ps.out;
    std::vector<double> h;
    for (const Vec3& q : pts) h.push_back(glm::dot(q, up));
    const double lowest = *std::min_element(h.begin(), h.end());
    for (double& x : h) x -= lowest;
    const LoggedRamp g = logged((d / "boxes.xyz").string(), true);
    const auto want = percentiles(h);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.up[c], up[c], 5e-3) << c;  // printed to 3 digits
    EXPECT_NEAR(g.lo, want[0], 1e-6);
    EXPECT_NEAR(g.hi, want[1], 1e-6);
    EXPECT_LT(want[0], 0.004);  // within the floor's roughness of its lowest point
    EXPECT_GT(want[1], 1.65);   // from the second box's top
    EXPECT_EQ(g.unit, "world units");
  }
  {
    const fs::path las = fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las";
    const auto idx = rayscan::test::run_command(bin + " index -q " + las.string() + " -o " + (d / "a.rsi").string());
    ASSERT_EQ(idx.code, 0) << idx.out;
    std::vector<double> h;
    for (const Vec3& q : io::read_point_cloud(las).positions) h.push_back(q.z);
    const LoggedRamp g = logged((d / "a.rsi").string());
    const auto want = percentiles(h);
    EXPECT_EQ(g.up, Vec3(0, 0, 1));
    EXPECT_NEAR(g.lo, want[0], 1e-6 * std::abs(want[0]));
    EXPECT_NEAR(g.hi, want[1], 1e-6 * std::abs(want[1]));
    EXPECT_EQ(g.unit, "foot");
  }
  {
    // The same points without a CRS (positions only, in an index file): the up axis is estimated,
    // a fraction of a degree off +z, and p . up far from the origin is no height at all (about
    // -1250 for z 406..521). The line gives the ends as heights above the lowest point along the
    // printed axis: oracle, those heights of the file's points, and within the z range's span.
    const PointCloud pc = io::read_point_cloud(fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las");
    {
      std::ofstream xyz(d / "nocrs.xyz");
      xyz.precision(17);
      for (const Vec3& q : pc.positions) xyz << q.x << " " << q.y << " " << q.z << "\n";
    }
    const auto idx = rayscan::test::run_command(bin + " index -q " + (d / "nocrs.xyz").string() + " -o " +
                                                (d / "nocrs.rsi").string());
    ASSERT_EQ(idx.code, 0) << idx.out;
    const auto ps = rayscan::test::run_command(bin + " render " + (d / "nocrs.rsi").string() + " --print-scene", false);
    ASSERT_EQ(ps.code, 0) << ps.out;
    const nlohmann::json u = nlohmann::json::parse(ps.out).at("up");
    const Vec3 up(u[0].get<double>(), u[1].get<double>(), u[2].get<double>());
    ASSERT_NE(up, Vec3(0, 0, 1)) << ps.out;  // estimated: not exactly +z
    ASSERT_GE(up.z, 0.999) << ps.out;
    std::vector<double> h;
    for (const Vec3& q : pc.positions) h.push_back(glm::dot(q, up));
    const double lowest = *std::min_element(h.begin(), h.end());
    for (double& x : h) x -= lowest;
    const auto want = percentiles(h);
    const LoggedRamp g = logged((d / "nocrs.rsi").string(), true);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.up[c], up[c], 5e-3) << c;
    EXPECT_NEAR(g.lo, want[0], 1e-4);  // printed to 7 digits
    EXPECT_NEAR(g.hi, want[1], 1e-4);
    const auto [zlo, zhi] = std::minmax_element(pc.positions.begin(), pc.positions.end(),
                                                [](const Vec3& a, const Vec3& b) { return a.z < b.z; });
    EXPECT_GT(g.lo, 0.0);
    EXPECT_LT(g.hi, zhi->z - zlo->z);
    EXPECT_EQ(g.unit, "world units");
  }
  fs::remove_all(d);
}

// A quick look sizes its surfels (or its spheres' "auto" radius) from the spacing of the points,
// so a cloud with fewer than 2 distinct points has none: one line naming the cloud as given and
// what is needed (exit 2, no image), not the generated scene's keys, whichever the primitive, and
// for --print-scene too (its scene could not render). A scene file that gives a radius renders
// the same one-point cloud, and one left at "auto" keeps its key's error. Oracles: the LAS file's
// own header (1 point), two coincident points written here.
TEST(QuickLook, TooFewDistinctPointsIsOneLineNamingTheCloud) {
  const fs::path d = quick_look_temp_dir();
  const std::string bin = RAYSCAN_BIN;
  const fs::path one = fs::path(RAYSCAN_TEST_DATA) / "las" / "1.0_0.las", png = d / "few.png";
  ASSERT_EQ(io::read_point_cloud(one).size(), 1u);
  const auto expect_refused = [&](const std::string& args, const std::string& line) {
    const auto r = rayscan::test::run_command(bin + " render -q " + args + " --out " + png.string());
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_EQ(r.out, "rayscan render: " + line + "\n") << args;
    EXPECT_FALSE(fs::exists(png)) << args;
  };
  const std::string needs = ": a quick look needs at least 2 distinct points, to size them from their spacing; ";
  const std::string remedy = " (a scene file with a numeric \"radius\" renders it)";
  for (const char* flags : {"", " --primitive sphere", " --primitive surfel", " --print-scene"})
    expect_refused(one.string() + flags, one.string() + needs + "the cloud has 1 point" + remedy);
  std::ofstream(d / "same.xyz") << "1 2 3\n1 2 3\n";
  expect_refused((d / "same.xyz").string(),
                 (d / "same.xyz").string() + needs + "the cloud's 2 points all lie at one position" + remedy);

  // A scene file: its radius decides; "auto" is its own key's error.
  std::ofstream(d / "one.json") << R"({"cloud": ")" << one.string()
                                << R"(", "radius": 1.0, "spp": 1, "material": {"color": "elevation"}})";
  const auto ok = rayscan::test::run_command(bin + " render -q " + (d / "one.json").string() + " --width 30 --out " +
                                             png.string());
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(png));
  fs::remove(png);
  std::ofstream(d / "auto.json") << R"({"cloud": ")" << one.string()
                                 << R"(", "radius": "auto", "material": {"color": "elevation"}})";
  expect_refused((d / "auto.json").string(),
                 (d / "auto.json").string() + ": /radius: \"auto\" needs at least two distinct points; give a number");
  fs::remove_all(d);
}
