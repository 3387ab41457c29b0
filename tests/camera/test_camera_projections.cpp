// Orthographic, equirectangular and distorted pinhole cameras, and COLMAP import, against
// formulas written here from their documentation.
#include "../common/temp_dir.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/camera/colmap.hpp"
#include "rayscan/render/scene.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <glm/gtc/quaternion.hpp>

#include <filesystem>
#include <fstream>
#include <numbers>

using namespace rayscan;
using namespace rayscan::render;

namespace {
double ray_point_distance(const Ray& r, const Vec3& p) {
  const Vec3 v = p - r.origin();
  return glm::length(v - glm::dot(v, r.direction()) * r.direction());
}
}  // namespace

TEST(Orthographic, ParallelRaysOnTheImagePlane) {
  const Camera c = Camera::orthographic({Vec3(10, 20, 100), Vec3(10, 20, 0), Vec3(0, 1, 0), 50.0}, 200, 100);
  EXPECT_EQ(c.projection(), Projection::orthographic);
  const Ray centre = c.generate_ray(99.5, 49.5);
  EXPECT_NEAR(glm::length(centre.origin() - Vec3(10, 20, 100)), 0.0, 1e-12);
  const Ray r0 = c.generate_ray(0, 0), r1 = c.generate_ray(1, 0), r2 = c.generate_ray(0, 1);
  EXPECT_EQ(r0.direction(), Vec3(0, 0, -1));
  EXPECT_EQ(r1.direction(), Vec3(0, 0, -1));
  EXPECT_NEAR(glm::length(r1.origin() - r0.origin()), 0.5, 1e-12);  // 50 / 100 px
  // Looking down with up = +y: image right is +x... cross(-z, +y) = +x; rows go towards -y.
  EXPECT_GT(r1.origin().x, r0.origin().x);
  EXPECT_LT(r2.origin().y, r0.origin().y);
  // Resizing keeps the covered plane: the centre stays, the pixel doubles.
  const Camera h = c.resized(100, 50);
  EXPECT_NEAR(glm::length(h.generate_ray(49.5, 24.5).origin() - Vec3(10, 20, 100)), 0.0, 1e-9);
  EXPECT_NEAR(glm::length(h.generate_ray(1, 0).origin() - h.generate_ray(0, 0).origin()), 1.0, 1e-12);
  EXPECT_THROW(Camera::orthographic({Vec3(0), Vec3(0, 0, -1), Vec3(0, 0, 1), 1.0}, 4, 4), std::invalid_argument);
}

TEST(Equirectangular, LongitudeLatitudeMapping) {
  const Camera c = Camera::equirectangular({Vec3(1, 2, 3), Vec3(1, 3, 3), Vec3(0, 0, 1)}, 360, 180);
  auto dir = [&](double u, double v) { return c.generate_ray(u, v).direction(); };
  // Pixel centres: u + 0.5 = W/2 is longitude 0 (forward), W 3/4 is +90 (right), v + 0.5 = 0 is the zenith.
  EXPECT_NEAR(glm::length(dir(179.5, 89.5) - Vec3(0, 1, 0)), 0.0, 1e-12);
  EXPECT_NEAR(glm::length(dir(269.5, 89.5) - Vec3(1, 0, 0)), 0.0, 1e-12);
  EXPECT_NEAR(glm::length(dir(89.5, 89.5) - Vec3(-1, 0, 0)), 0.0, 1e-12);
  EXPECT_NEAR(glm::length(dir(-0.5, 89.5) - Vec3(0, -1, 0)), 0.0, 1e-12);
  EXPECT_NEAR(glm::length(dir(179.5, -0.5) - Vec3(0, 0, 1)), 0.0, 1e-12);
  // 45 degrees up at longitude 0.
  EXPECT_NEAR(glm::length(dir(179.5, 44.5) - glm::normalize(Vec3(0, 1, 1))), 0.0, 1e-12);
  EXPECT_EQ(c.generate_ray(10, 10).origin(), Vec3(1, 2, 3));
}

namespace {
/// OpenCV's projection (calib3d documentation, "Detailed Description"): x' = X/Z, y' = Y/Z,
/// r^2 = x'^2 + y'^2, x'' = x'(1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x'y' + p2(r^2 + 2x'^2),
/// y'' = y'(1 + ...) + p1(r^2 + 2y'^2) + 2 p2 x'y', u = fx x'' + cx, v = fy y'' + cy.
glm::dvec2 opencv_project(const Vec3& Xc, double fx, double fy, double cx, double cy, double k1,
                          double k2, double p1, double p2, double k3) {
  const double x = Xc.x / Xc.z, y = Xc.y / Xc.z, r2 = x * x + y * y;
  const double rad = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
  const double xx = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yy = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return {fx * xx + cx, fy * yy + cy};
}
}  // namespace

TEST(LensDistortion, KnownPointsProjectToOpenCvPixels) {
  const LensDistortion k{-0.28, 0.07, 0.0012, -0.0007, 0.01};
  PinholeParams p;
  p.K = {{{800.0, 0.0, 321.0}, {0.0, 790.0, 239.0}, {0.0, 0.0, 1.0}}};
  const glm::dmat3 R = glm::mat3_cast(glm::angleAxis(0.3, glm::normalize(Vec3(0.2, 1.0, 0.1))));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) p.R[r][c] = R[c][r];
  p.t = Vec3(0.5, -0.2, 3.0);
  const Camera cam = Camera::pinhole_distorted(p, k, 640, 480);
  for (const Vec3& X : {Vec3(0.1, 0.2, 1.0), Vec3(-1.5, 0.8, 2.0), Vec3(1.2, -1.0, 0.5), Vec3(-0.9, -0.7, 2.5)}) {
    const Vec3 Xc = R * X + p.t;
    const glm::dvec2 uv = opencv_project(Xc, 800, 790, 321, 239, k.k1, k.k2, k.p1, k.p2, k.k3);
    EXPECT_LT(ray_point_distance(cam.generate_ray(uv.x, uv.y), X), 1e-9) << X.x;
  }
  // Round trip of the model itself.
  const glm::dvec2 q(0.31, -0.22);
  const glm::dvec2 back = undistort(k, distort(k, q));
  EXPECT_NEAR(back.x, q.x, 1e-12);
  EXPECT_NEAR(back.y, q.y, 1e-12);
}

TEST(Colmap, OpencvModelViewOfAPhotoMatchesItsProjection) {
  const auto dir = rayscan::test::process_temp_dir("rayscan_colmap");
  {
    std::ofstream c(dir / "cameras.txt");
    c << "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      << "1 PINHOLE 100 80 90 90 50 40\n"
      << "2 OPENCV 1000 750 920.5 915.2 501.3 372.8 -0.12 0.05 0.001 -0.002\n";
    std::ofstream i(dir / "images.txt");
    i << "# Image list with two lines of data per image:\n"
      << "1 1 0 0 0 0 0 0 1 a.jpg\n\n"
      << "2 0.92387953251128674 0.0 0.38268343236508978 0.0 0.3 -0.1 4.0 2 DSC_0042.JPG\n"
      << "10.0 20.0 -1 30.5 40.5 7\n";
  }
  const Camera cam = load_colmap_camera(dir, "DSC_0042.JPG");
  EXPECT_EQ(cam.width(), 1000u);
  EXPECT_EQ(cam.height(), 750u);
  // COLMAP: R from the unit quaternion (w, x, y, z) = 45 degrees about +y; pixel centres at +0.5.
  const double a = std::numbers::pi / 4;
  const glm::dmat3 R(Vec3(std::cos(a), 0, -std::sin(a)), Vec3(0, 1, 0), Vec3(std::sin(a), 0, std::cos(a)));
  for (const Vec3& X : {Vec3(0.0, 0.0, 0.0), Vec3(1.0, 0.5, -0.5), Vec3(-0.7, -0.6, 0.9)}) {
    const Vec3 Xc = R * X + Vec3(0.3, -0.1, 4.0);
    const glm::dvec2 uv = opencv_project(Xc, 920.5, 915.2, 501.3, 372.8, -0.12, 0.05, 0.001, -0.002, 0.0);
    EXPECT_LT(ray_point_distance(cam.generate_ray(uv.x - 0.5, uv.y - 0.5), X), 1e-9);
  }
  EXPECT_EQ(load_colmap_camera(dir, "a.jpg").width(), 100u);
  EXPECT_THROW(load_colmap_camera(dir, "missing.jpg"), SceneError);
  { std::ofstream c(dir / "cameras.txt"); c << "2 FISHEYE 10 10 1 2 3\n"; }
  EXPECT_THROW(load_colmap_camera(dir, "DSC_0042.JPG"), SceneError);
  std::filesystem::remove_all(dir);
}

TEST(Colmap, EachBadFieldOfACameraLineIsNamed) {
  const auto dir = rayscan::test::process_temp_dir("rayscan_colmap_fields");
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 5 1 a.png\n\n";
  const auto error_for = [&](const std::string& camera_line) {
    std::ofstream(dir / "cameras.txt") << camera_line << "\n";
    try {
      (void)load_colmap_camera(dir, "a.png");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  const std::string at = (dir / "cameras.txt").string() + ":1: ";
  EXPECT_EQ(error_for("1 PINHOLE 8 6 500 500 4 3"), "(no error)");
  EXPECT_EQ(error_for("1 PINHOLE 8 6 nan 500 4 3"), at + "model PINHOLE: parameter 1 'nan': expected a finite number");
  EXPECT_EQ(error_for("1 PINHOLE 8 6 500 500 4 inf"), at + "model PINHOLE: parameter 4 'inf': expected a finite number");
  EXPECT_EQ(error_for("1 PINHOLE 8 6 500 1e400 4 3"), at + "model PINHOLE: parameter 2 '1e400': expected a finite number");
  EXPECT_EQ(error_for("1 PINHOLE 8 6 500 500 4"), at + "model PINHOLE: expected 4 parameters, got 3");
  EXPECT_EQ(error_for("1 PINHOLE -8 6 500 500 4 3"), at + "WIDTH '-8': expected an integer in [1, 65536] (pixels)");
  EXPECT_EQ(error_for("1 PINHOLE 8 0 500 500 4 3"), at + "HEIGHT '0': expected an integer in [1, 65536] (pixels)");
  EXPECT_EQ(error_for("1 PINHOLE 65537 6 500 500 4 3"), at + "WIDTH '65537': expected an integer in [1, 65536] (pixels)");
  EXPECT_EQ(error_for("1 PINHOLE 8.5 6 500 500 4 3"), at + "WIDTH '8.5': expected an integer in [1, 65536] (pixels)");
  std::filesystem::remove_all(dir);
}

TEST(Colmap, AFifoOrADirectoryAsAModelFileIsRefusedWithoutReading) {
  // FIFOs without a writer: a plain open would wait forever (the ctest timeout catches a hang).
  const auto dir = rayscan::test::process_temp_dir("rayscan_colmap_kinds");
  ASSERT_EQ(::mkfifo((dir / "images.txt").c_str(), 0600), 0);
  std::filesystem::create_directories(dir / "cameras.txt");
  const auto error = [&] {
    try {
      (void)load_colmap_camera(dir, "a.png");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(error(), (dir / "images.txt").string() + ": is a FIFO, not a regular file (rayscan reads regular files only)");
  std::filesystem::remove(dir / "images.txt");
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 5 1 a.png\n\n";
  EXPECT_EQ(error(), (dir / "cameras.txt").string() + ": is a directory, not a regular file (rayscan reads regular files only)");
  std::filesystem::remove_all(dir);
  EXPECT_EQ(error(), (dir / "images.txt").string() + ": cannot open (a COLMAP text model needs cameras.txt and images.txt)");
}
