// The quick look: the automatic overview camera frames the cloud's bounding box
// (checked by projecting the box corners with Camera::look_at's own rays' geometry: an
// independent pinhole projection from the look-at parameters), and `--print-scene` prints a scene
// that renders the same image when fed back (the render is a pure function of the scene and seed).
#include "../common/temp_dir.hpp"
#include "rayscan/jobs/quick_look.hpp"

#include "../common/run_command.hpp"

#include <gtest/gtest.h>


#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

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
  const auto a = test::run_command(bin + " render -q " + (d / "c.xyz").string() + " --spp 2 --width 60 --out " +
                                   (d / "a.png").string());
  ASSERT_EQ(a.code, 0) << a.out;
  const auto p = test::run_command(bin + " render " + (d / "c.xyz").string() + " --spp 2 --width 60 --out " +
                                       (d / "b.png").string() + " --print-scene",
                                   false);
  ASSERT_EQ(p.code, 0) << p.out;
  EXPECT_FALSE(fs::exists(d / "b.png"));  // --print-scene does not render
  std::ofstream(d / "printed.json") << p.out;
  EXPECT_NE(p.out.find("\"width\": 60"), std::string::npos) << p.out;
  EXPECT_NE(p.out.find("\"height\": 40"), std::string::npos) << p.out;  // 3:2 kept
  EXPECT_NE(p.out.find("\"color\": \"elevation\""), std::string::npos) << p.out;  // no RGB in the file
  // Rendered from another folder: paths in the printed scene are absolute.
  const auto b = test::run_command("cd / && " + bin + " render -q " + (d / "printed.json").string());
  ASSERT_EQ(b.code, 0) << b.out;
  const auto cmp = test::run_command(bin + " compare " + (d / "a.png").string() + " " + (d / "b.png").string());
  EXPECT_EQ(cmp.code, 0) << cmp.out;  // identical images (idiff default: no pixel over 1e-6)
  // A scene file without a camera gets the same overview camera.
  std::ofstream(d / "nocam.json") << R"({"cloud": "c.xyz", "radius": "auto", "material": {"color": "elevation"},
    "spp": 2, "output": {"image": "n.png"}})";
  const auto n = test::run_command(bin + " render -q " + (d / "nocam.json").string() + " --width 60");
  ASSERT_EQ(n.code, 0) << n.out;
  const auto cn = test::run_command(bin + " compare " + (d / "a.png").string() + " " + (d / "n.png").string());
  EXPECT_EQ(cn.code, 0) << cn.out;
  fs::remove_all(d);
}
