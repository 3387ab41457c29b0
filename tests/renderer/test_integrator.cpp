// Analytic scenes: exact sphere depth head-on, white furnace, convex sphere of
// albedo a under uniform light, sun shadows.
#include "rayscan/render/render.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace rayscan;
using namespace rayscan::render;

namespace {

Camera head_on(const Vec3& target, double distance, std::uint32_t size) {
  LookAtParams la;
  la.position = target + Vec3(0.0, -distance, 0.0);
  la.look_at = target;
  la.vfov_deg = 20.0;
  return Camera::look_at(la, size, size);
}

Scene base_scene(const Camera& cam) {
  Scene s;
  s.camera = cam;
  s.background.gradient = false;
  s.background.color = Color(1.0f);
  s.spp = 4;
  s.seed = 7;
  return s;
}

struct Cloud {
  std::vector<Vec3> centers;
  std::vector<Color> albedo;
  AnyIndex index;
  Cloud(std::vector<Vec3> c, Color a, const std::string& type = "octree-adaptive")
      : centers(std::move(c)), albedo(centers.size(), a), index(make_index(centers, IndexOptions{type})) {}
};

}  // namespace

class HeadOn : public ::testing::TestWithParam<std::tuple<HitMode, Vec3>> {};

TEST_P(HeadOn, CentrePixelDepthIsTheExactSphereDepth) {
  const auto [mode, target] = GetParam();
  Cloud g({target}, Color(0.5f));
  Scene s = base_scene(head_on(target, 10.0, 33));  // odd size: pixel (16,16) is on the axis
  s.hit = mode;
  s.output.aovs = {Aov::depth, Aov::normal, Aov::index};
  Framebuffer fb;
  render_image(g.index, make_settings(s, g.centers, g.albedo, 0.5), fb);
  const std::size_t c = 16 * 33 + 16;
  EXPECT_EQ(fb.depth[c], 9.5f);  // |camera - centre| - r, exactly representable
  EXPECT_EQ(fb.index[c], 0u);
  EXPECT_NEAR(fb.normal[c].y, -1.0f, 1e-6f);
  EXPECT_EQ(fb.index[0], rayscan::kNoPoint);  // the corner ray misses (sphere spans ~3 degrees of 20)
  EXPECT_TRUE(std::isinf(fb.depth[0]));
}

INSTANTIATE_TEST_SUITE_P(Modes, HeadOn,
                         ::testing::Values(std::make_tuple(HitMode::sphere, Vec3(0.0)),
                                           std::make_tuple(HitMode::closest_point, Vec3(0.0)),
                                           // UTM-sized coordinates: no precision loss 1e6 from the origin
                                           std::make_tuple(HitMode::sphere, Vec3(636590.0, 5e6, 420.0)),
                                           std::make_tuple(HitMode::closest_point, Vec3(1e6, 2e6, 3e3))));

TEST(Integrator, ConvexSphereOfAlbedoAUnderUniformLightGivesA) {
  // Every bounce off a single convex sphere escapes, so each hitting sample is exactly a x 1.
  const float a = 0.37f;
  Cloud g({Vec3(5.0, 7.0, 9.0)}, Color(a));
  Scene s = base_scene(head_on(Vec3(5.0, 7.0, 9.0), 10.0, 31));
  s.spp = 16;
  s.max_depth = 8;
  Framebuffer fb;
  render_image(g.index, make_settings(s, g.centers, g.albedo, 1.0), fb);
  // Pixels well inside the disk (radius ~ 1/(10 tan 10deg) * 15.5 = 8.8 px) are a; the corner is 1.
  for (int dy = -4; dy <= 4; ++dy)
    for (int dx = -4; dx <= 4; ++dx) {
      const Color& c = fb.beauty[std::size_t(15 + dy) * 31 + std::size_t(15 + dx)];
      EXPECT_NEAR(c.r, a, 1e-6f);
      EXPECT_NEAR(c.b, a, 1e-6f);
    }
  EXPECT_EQ(fb.beauty[0], Color(1.0f));
}

TEST(Integrator, WhiteFurnaceGivesOne) {
  // A clump of overlapping spheres of albedo 1 under a uniform background of 1: every path that
  // escapes carries exactly 1, so pixels are 1 up to paths cut by max_depth.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> pts;
  while (pts.size() < 400) {
    const Vec3 p(u(rng), u(rng), u(rng));
    if (glm::length(p) <= 1.0) pts.push_back(p);
  }
  Cloud g(pts, Color(1.0f));
  Scene s = base_scene(head_on(Vec3(0.0), 6.0, 21));
  s.spp = 16;
  s.max_depth = 64;
  s.output.aovs = {Aov::index};
  Framebuffer fb;
  const RenderStats st = render_image(g.index, make_settings(s, g.centers, g.albedo, 0.2), fb);
  int hits = 0;
  for (std::size_t i = 0; i < fb.beauty.size(); ++i) {
    hits += fb.index[i] != rayscan::kNoPoint;
    EXPECT_LE(fb.beauty[i].g, 1.0f + 1e-6f);
    EXPECT_GE(fb.beauty[i].g, 0.99f);
  }
  EXPECT_GT(hits, 50);                            // the clump covers the image centre
  EXPECT_GT(st.queries, st.primary_rays * 2);     // paths did bounce inside the clump
}

TEST(Integrator, SunShadowIsDark) {
  // Camera looks horizontally at a vertical wall of points; a blocker between the wall and a sun
  // that shines along the view direction (from behind the camera) shadows the wall behind it.
  std::vector<Vec3> pts;
  for (int i = -20; i <= 20; ++i)
    for (int k = -20; k <= 20; ++k) pts.emplace_back(0.25 * i, 0.0, 0.25 * k);
  Cloud wall(pts, Color(0.5f));
  pts.emplace_back(0.0, -2.0, 0.0);  // blocker 2 m in front of the wall... seen by the camera too
  Cloud blocked(pts, Color(0.5f));
  LookAtParams la;
  la.position = {3.0, -10.0, 0.0};   // off to the side: the shadow on the wall is visible and
                                     // no camera ray near it grazes the blocker
  la.look_at = {0.0, 0.0, 0.0};
  la.vfov_deg = 30.0;
  Scene s = base_scene(Camera::look_at(la, 61, 61));
  s.background.color = Color(0.0f);
  s.sun.enabled = true;
  s.sun.direction = {0.0, -1.0, 0.0};  // the sun is on the -y side (behind the camera)
  s.sun.irradiance = 3.14159265f;
  s.sun.color = Color(1.0f);
  s.sun.angular_diameter_deg = 0.0;
  s.max_depth = 1;
  s.output.aovs = {Aov::position, Aov::index};
  Framebuffer a, b;
  render_image(wall.index, make_settings(s, wall.centers, wall.albedo, 0.2), a);
  render_image(blocked.index, make_settings(s, blocked.centers, blocked.albedo, 0.2), b);
  // Find wall pixels (index < wall size) whose hit point lies right behind the blocker.
  int shadowed = 0;
  for (std::size_t i = 0; i < b.beauty.size(); ++i) {
    if (b.index[i] >= wall.centers.size()) continue;
    const glm::dvec3 p = glm::dvec3(b.position[i]) + b.position_origin;
    if (std::abs(p.x) < 0.1 && std::abs(p.z) < 0.1) {
      EXPECT_EQ(b.beauty[i], Color(0.0f)) << i % 61 << "," << i / 61 << " p " << p.x << " " << p.y << " " << p.z;
      EXPECT_GT(a.beauty[i].r, 0.2f);
      ++shadowed;
    }
  }
  EXPECT_GT(shadowed, 0);
}
