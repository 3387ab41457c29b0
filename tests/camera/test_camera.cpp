// Camera: look-at and K/[R|t] descriptions of the same pose give the same rays;
// a world point projected with K(RX + t) lies on the ray through its pixel.
#include "rayscan/camera/camera.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace rayscan;

namespace {

void expect_near(const Vec3& a, const Vec3& b, double tol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

struct Pose {
  LookAtParams la;
  PinholeParams ph;
};

// The OpenCV pinhole of a look-at pose, built independently: camera axes x = right, y = down,
// z = forward; R has them as rows; t = -R C; K from the vertical field of view.
Pose make_pose(const Vec3& eye, const Vec3& target, const Vec3& up, double vfov, int w, int h) {
  Pose p;
  p.la.position = eye;
  p.la.look_at = target;
  p.la.up = up;
  p.la.vfov_deg = vfov;
  const Vec3 z = glm::normalize(target - eye);
  const Vec3 x = glm::normalize(glm::cross(z, up));
  const Vec3 y = glm::cross(z, x);
  const double f = (h / 2.0) / std::tan(vfov / 2.0 * std::numbers::pi / 180.0);
  p.ph.K = {{{f, 0, (w - 1) / 2.0}, {0, f, (h - 1) / 2.0}, {0, 0, 1}}};
  p.ph.R = {{{x.x, x.y, x.z}, {y.x, y.y, y.z}, {z.x, z.y, z.z}}};
  p.ph.t = -Vec3(glm::dot(x, eye), glm::dot(y, eye), glm::dot(z, eye));
  return p;
}

}  // namespace

TEST(Camera, LookAtAndPinholeGiveTheSameRays) {
  // UTM-sized coordinates: the pose must survive 1e6 m offsets.
  const Pose p = make_pose({636400.0, 848300.0, 1100.0}, {636590.0, 849216.0, 420.0}, {0, 0, 1}, 45.0, 600, 400);
  const Camera a = Camera::look_at(p.la, 600, 400);
  const Camera b = Camera::pinhole(p.ph, 600, 400);
  for (double u : {0.0, 17.25, 299.5, 599.0})
    for (double v : {0.0, 133.0, 199.5, 399.0}) {
      const Ray ra = a.generate_ray(u, v), rb = b.generate_ray(u, v);
      expect_near(ra.origin(), rb.origin(), 1e-6);
      expect_near(ra.direction(), rb.direction(), 1e-12);
    }
}

TEST(Camera, ProjectedPointLiesOnItsPixelRay) {
  const Pose p = make_pose({10.0, -20.0, 5.0}, {0.0, 0.0, 1.0}, {0, 0, 1}, 60.0, 320, 240);
  const Camera cam = Camera::pinhole(p.ph, 320, 240);
  const Vec3 X(2.0, 3.0, -1.0);
  // x_cam = R X + t, pixel = K x_cam / z.
  Vec3 xc;
  for (int r = 0; r < 3; ++r) xc[r] = p.ph.R[r][0] * X.x + p.ph.R[r][1] * X.y + p.ph.R[r][2] * X.z + p.ph.t[r];
  const double u = (p.ph.K[0][0] * xc.x + p.ph.K[0][2] * xc.z) / xc.z;
  const double v = (p.ph.K[1][1] * xc.y + p.ph.K[1][2] * xc.z) / xc.z;
  const Ray ray = cam.generate_ray(u, v);
  const Vec3 w = X - ray.origin();
  const double dist = glm::length(w - glm::dot(w, ray.direction()) * ray.direction());
  EXPECT_LT(dist, 1e-9);
  EXPECT_GT(glm::dot(w, ray.direction()), 0.0);
}

TEST(Camera, CentrePixelLooksAtTarget) {
  LookAtParams la;
  la.position = {1e6, 2e6, 100.0};
  la.look_at = {1e6 + 30.0, 2e6 + 40.0, 100.0};
  const Camera cam = Camera::look_at(la, 101, 51);  // odd sizes: the centre pixel is (50, 25)
  const Ray r = cam.generate_ray(50, 25);
  expect_near(r.direction(), Vec3(0.6, 0.8, 0.0), 1e-15);
  // Top rows look up (OpenCV: y down).
  EXPECT_GT(cam.generate_ray(50, 0).direction().z, 0.0);
  EXPECT_NEAR(std::asin(cam.generate_ray(50, -0.5).direction().z) * 2.0, 40.0 * std::numbers::pi / 180.0, 1e-12);
}

TEST(Camera, ResizedKeepsTheFieldOfView) {
  LookAtParams la;
  la.position = {0, 0, 0};
  la.look_at = {0, 1, 0};
  const Camera a = Camera::look_at(la, 600, 400);
  const Camera b = a.resized(60, 40);
  // Image corners (pixel edges) map to the same directions.
  expect_near(a.generate_ray(-0.5, -0.5).direction(), b.generate_ray(-0.5, -0.5).direction(), 1e-12);
  expect_near(a.generate_ray(599.5, 399.5).direction(), b.generate_ray(59.5, 39.5).direction(), 1e-12);
  EXPECT_EQ(b.width(), 60u);
  EXPECT_EQ(b.height(), 40u);
}

TEST(Camera, RejectsBadParameters) {
  LookAtParams la;
  la.vfov_deg = 180.0;
  EXPECT_THROW(Camera::look_at(la, 10, 10), std::invalid_argument);
  la.vfov_deg = 40.0;
  la.up = {0, 0, 1};
  la.look_at = {0, 0, 5};  // parallel to up
  EXPECT_THROW(Camera::look_at(la, 10, 10), std::invalid_argument);
  PinholeParams ph;
  ph.K = {{{100, 0, 5}, {0, 100, 5}, {0, 0, 1}}};
  ph.R = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 2}}};  // not a rotation
  EXPECT_THROW(Camera::pinhole(ph, 10, 10), std::invalid_argument);
}
