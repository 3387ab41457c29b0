// Rendering real data: determinism across thread counts, depth AOV against a brute-force
// ray/sphere oracle, image write errors, every scene in scenes/ renders at reduced size, and the
// strata of the albedo AOV's sub-pixel rays. The files read back through OpenImageIO are in
// test_render_files.cpp.
#include "render_test_data.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/image_output.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/render.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

using namespace rayscan;
using namespace rayscan::render;
namespace fs = std::filesystem;

namespace {

using rayscan::render::test::subset;
using rayscan::render::test::subset_scene;

}  // namespace

TEST(Render, BitIdenticalForAnyThreadCount) {
  const PointCloud& pc = subset();
  const std::vector<Color> albedo(pc.size(), Color(0.6f, 0.5f, 0.4f));
  const AnyIndex index = make_index(pc.positions, IndexOptions{});
  Scene s = subset_scene(64, 48);
  s.output.aovs = {Aov::depth, Aov::cost};
  const RenderSettings set = make_settings(s, pc.positions, albedo, 0.8);
  Framebuffer one, many;
  RenderOptions o1, o3;
  o1.threads = 1;
  o3.threads = 3;
  o3.tile_size = 7;  // different tiling too
  render_image(index, set, one, o1);
  render_image(index, set, many, o3);
  ASSERT_EQ(one.beauty.size(), many.beauty.size());
  EXPECT_EQ(std::memcmp(one.beauty.data(), many.beauty.data(), one.beauty.size() * sizeof(Color)), 0);
  EXPECT_EQ(std::memcmp(one.depth.data(), many.depth.data(), one.depth.size() * sizeof(float)), 0);
  EXPECT_EQ(std::memcmp(one.cost.data(), many.cost.data(), one.cost.size() * sizeof(float)), 0);
  // And the seed matters.
  Scene s2 = s;
  s2.seed = 1;
  Framebuffer other;
  render_image(index, make_settings(s2, pc.positions, albedo, 0.8), other, o1);
  EXPECT_NE(std::memcmp(one.beauty.data(), other.beauty.data(), one.beauty.size() * sizeof(Color)), 0);
}

class DepthOracle : public ::testing::TestWithParam<std::string> {};

TEST_P(DepthOracle, DepthAovMatchesBruteForceRaySphere) {
  const PointCloud& pc = subset();
  const double r = 0.8;  // feet; median spacing of the subset is ~1.3 ft
  const std::vector<Color> albedo(pc.size(), Color(0.5f));
  IndexOptions io;
  io.type = GetParam();
  const AnyIndex index = make_index(pc.positions, io);
  Scene s = subset_scene(48, 36);
  s.spp = 1;
  s.output.aovs = {Aov::depth, Aov::index};
  Framebuffer fb;
  render_image(index, make_settings(s, pc.positions, albedo, r), fb);
  int hits = 0;
  for (std::uint32_t y = 0; y < fb.height; ++y)
    for (std::uint32_t x = 0; x < fb.width; ++x) {
      // Oracle: the textbook quadratic |o + t d - c|^2 = r^2 (RTIOW section 6.2), every point.
      const Ray ray = s.camera->generate_ray(x, y);
      double best = kInf;
      for (const Vec3& c : pc.positions) {
        const Vec3 oc = ray.origin() - c;
        const double hb = glm::dot(oc, ray.direction());
        const double disc = hb * hb - (glm::dot(oc, oc) - r * r);
        if (disc < 0.0) continue;
        const double t = -hb - std::sqrt(disc);
        if (t >= 0.0) best = std::min(best, t);
      }
      const std::size_t p = std::size_t(y) * fb.width + x;
      if (std::isinf(best)) {
        EXPECT_TRUE(std::isinf(fb.depth[p])) << x << "," << y;
        EXPECT_EQ(fb.index[p], rayscan::kNoPoint);
      } else {
        ++hits;
        EXPECT_NEAR(fb.depth[p], best, 1e-6 * best) << x << "," << y;
        // The reported point's own sphere is entered at that depth.
        ASSERT_LT(fb.index[p], pc.size());
        const Vec3 oc = ray.origin() - pc.positions[fb.index[p]];
        const double hb = glm::dot(oc, ray.direction());
        EXPECT_NEAR(-hb - std::sqrt(hb * hb - (glm::dot(oc, oc) - r * r)), best, 1e-6 * best);
      }
    }
  EXPECT_GT(hits, int(fb.width * fb.height / 8));
}

INSTANTIATE_TEST_SUITE_P(Indexes, DepthOracle,
                         ::testing::Values("octree-adaptive", "octree-layered", "kdtree"));

TEST(ImageOutput, UnwritableFolderIsAnErrorNamingTheFile) {
  Framebuffer fb;
  fb.width = fb.height = 1;
  fb.beauty = {Color(0.5f)};
  OutputDesc out;
  out.image = "/proc/rayscan_no_such_dir/x.png";
  try {
    write_image(fb, out, {});
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("x.png"), std::string::npos) << e.what();
  }
}

TEST(Scenes, EverySceneRendersAtReducedSize) {
  int count = 0;
  for (const auto& e : fs::directory_iterator(RAYSCAN_SCENES_DIR)) {
    if (e.path().extension() != ".json") continue;
    SCOPED_TRACE(e.path().string());
    ++count;
    Scene s = load_scene(e.path());
    const PointCloud pc = io::read_point_cloud(s.cloud);
    ASSERT_FALSE(pc.empty());
    const std::vector<Color> albedo = compute_albedo(pc, s.material, s.up);
    const AnyIndex index = make_index(pc.positions, s.index);
    const double r = s.radius ? *s.radius : s.auto_radius_factor * median_nn_spacing(index, pc.positions, 2000);
    s.camera = s.camera->resized(48, 32);
    s.spp = 1;
    s.output.aovs = {Aov::index};
    Framebuffer fb;
    render_image(index, make_settings(s, pc.positions, albedo, r), fb);
    // The camera sees the cloud: a good share of the pixels hit a point.
    const auto hit = std::count_if(fb.index.begin(), fb.index.end(), [](std::uint32_t i) { return i != rayscan::kNoPoint; });
    EXPECT_GT(hit, 48 * 32 / 5);
  }
  EXPECT_GE(count, 4);
}

TEST(Albedo, EightBitColourOfAnIndexFileNeedsNoPassAndEqualsTheSixteenBitForm) {
  // The 3-byte colour form with multiplier 1 (an index file built from 8-bit colours) is 8-bit by
  // construction, so the rule skips its whole-cloud test; oracle: the same values as Rgb16 in
  // place, which the rule reads in full. Every point's albedo must be equal, bit for bit.
  const std::size_t n = 1000;
  std::vector<std::uint8_t> bytes(3 * n);
  std::vector<Rgb16> wide(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) bytes[3 * i + c] = static_cast<std::uint8_t>((i * 37 + c * 101) % 256);
    wide[i] = {bytes[3 * i], bytes[3 * i + 1], bytes[3 * i + 2]};
  }
  const std::vector<Vec3> pos(n, Vec3(0.0));
  MaterialDesc mat;  // colour "rgb"
  const AlbedoAttributes narrow_a{pos, RgbView(bytes.data(), n, 1), {}, {}};
  const AlbedoAttributes wide_a{pos, RgbView(std::span<const Rgb16>(wide)), {}, {}};
  const AlbedoRule narrow_rule(narrow_a, n, mat, Vec3(0, 0, 1));
  const AlbedoRule wide_rule(wide_a, n, mat, Vec3(0, 0, 1));
  for (std::size_t i = 0; i < n; ++i) {
    const Color a = narrow_rule.at(narrow_a, i), b = wide_rule.at(wide_a, i);
    ASSERT_EQ(a, b) << i;
  }
  // Not vacuous: 8-bit scaling (255 -> 1), not 16-bit (255 -> 255 / 65535).
  std::size_t bright = 0;
  for (std::size_t i = 0; i < n; ++i) bright += narrow_rule.at(narrow_a, i).r > 0.9f;
  EXPECT_GT(bright, 0u);
}

// The albedo AOV's sub-pixel points (stratified_pixel_point) for every n up to 64: the strata,
// each one's rectangle from its jitter corners (0, 0) and (1, 1), lie in the pixel, do not overlap
// pairwise and their areas sum to 1, so they cut the pixel into n pieces (area by area, an
// analytic partition); each stratum's reported area is its rectangle's; n = 16 is the 4 x 4 grid.
TEST(Render, StratifiedPixelPointsCutThePixelIntoNStrata) {
  struct Rect {
    double x0, y0, x1, y1;
  };
  for (std::uint32_t n = 1; n <= 64; ++n) {
    SCOPED_TRACE("n = " + std::to_string(n));
    std::vector<Rect> strata;
    double total = 0.0;
    for (std::uint32_t j = 0; j < n; ++j) {
      const PixelSample lo = stratified_pixel_point(j, n, 0.0, 0.0), hi = stratified_pixel_point(j, n, 1.0, 1.0);
      const PixelSample mid = stratified_pixel_point(j, n, 0.5, 0.25);
      const Rect r{lo.dx, lo.dy, hi.dx, hi.dy};
      EXPECT_GE(r.x0, -0.5);
      EXPECT_GE(r.y0, -0.5);
      EXPECT_LE(r.x1, 0.5 + 1e-12);
      EXPECT_LE(r.y1, 0.5 + 1e-12);
      EXPECT_NEAR(lo.area, (r.x1 - r.x0) * (r.y1 - r.y0), 1e-12);
      EXPECT_EQ(mid.area, lo.area);
      EXPECT_NEAR(mid.dx, r.x0 + 0.5 * (r.x1 - r.x0), 1e-12);  // the jitter runs across the stratum
      EXPECT_NEAR(mid.dy, r.y0 + 0.25 * (r.y1 - r.y0), 1e-12);
      for (const Rect& o : strata) {
        const double w = std::min(r.x1, o.x1) - std::max(r.x0, o.x0), h = std::min(r.y1, o.y1) - std::max(r.y0, o.y0);
        EXPECT_FALSE(w > 1e-12 && h > 1e-12) << "stratum " << j << " overlaps stratum " << (&o - strata.data());
      }
      strata.push_back(r);
      total += lo.area;
    }
    EXPECT_NEAR(total, 1.0, 1e-12);
  }
  for (std::uint32_t j = 0; j < 16; ++j) {
    const PixelSample p = stratified_pixel_point(j, 16, 0.0, 0.0);
    EXPECT_EQ(p.dx, -0.5 + 0.25 * (j % 4));
    EXPECT_EQ(p.dy, -0.5 + 0.25 * (j / 4));
    EXPECT_EQ(p.area, 1.0 / 16);
  }
  EXPECT_THROW((void)stratified_pixel_point(0, 0, 0.5, 0.5), std::invalid_argument);
  EXPECT_THROW((void)stratified_pixel_point(5, 5, 0.5, 0.5), std::invalid_argument);
}
