// PCA normals and spacing radii against analytic surfaces.
#include "rayscan/octree/normals.hpp"

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>
#include <cstdint>
#include <mutex>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using namespace rayscan;

namespace {

double angle_deg(const Vec3& a, const Vec3& b) {
  const double c = std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

/// A tilted plane through `origin` sampled on a 1 x 3 grid (spacing s along u, 3 s along v) with
/// Gaussian noise of sigma along the normal, like one scanner's lines.
std::vector<Vec3> tilted_plane(const Vec3& origin, const Vec3& n, double s, int nu, int nv, double sigma,
                               unsigned seed) {
  const Vec3 u = glm::normalize(glm::cross(n, Vec3(0.3, 0.2, 1.0)));
  const Vec3 v = glm::cross(n, u);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<Vec3> p;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) p.push_back(origin + (i * s) * u + (j * 3.0 * s) * v + g(rng) * n);
  return p;
}

}  // namespace

TEST(SmallestEigenvector, DiagonalAndRotatedMatrices) {
  auto e = smallest_eigenvector(3.0, 0.0, 0.0, 2.0, 0.0, 0.5);
  ASSERT_TRUE(e);
  EXPECT_NEAR(std::abs(e->z), 1.0, 1e-12);
  // A = Q diag(4, 1, 0.01) Q^T with Q a rotation: the eigenvector is Q e3.
  const glm::dmat3 Q = glm::dmat3(glm::rotate(glm::dmat4(1.0), 0.7, glm::normalize(Vec3(1, 2, 3))));
  const glm::dmat3 A = Q * glm::dmat3(glm::dvec3(4, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 0.01)) *
                       glm::transpose(Q);
  e = smallest_eigenvector(A[0][0], A[1][0], A[2][0], A[1][1], A[2][1], A[2][2]);
  ASSERT_TRUE(e);
  EXPECT_NEAR(std::abs(glm::dot(*e, Q[2])), 1.0, 1e-10);
  // Exactly planar points: smallest eigenvalue 0.
  e = smallest_eigenvector(1.0, 0.0, 0.0, 1.0, 0.0, 0.0);
  ASSERT_TRUE(e);
  EXPECT_NEAR(std::abs(e->z), 1.0, 1e-12);
  EXPECT_FALSE(smallest_eigenvector(1.0, 0.0, 0.0, 1.0, 0.0, 1.0));  // isotropic: undetermined
}

TEST(EstimateSurfels, AnisotropicNoisyPlaneAtUtmMagnitude) {
  const Vec3 n = glm::normalize(Vec3(0.2, -0.3, 1.0));
  const double s = 0.1;
  const auto pts = tilted_plane(Vec3(6.0e5, 5.3e6, 120.0), n, s, 60, 20, 0.02 * s, 3);
  const AnyIndex idx = make_index(pts, IndexOptions{});
  const SurfelAttributes a = estimate_surfels(idx, pts);
  ASSERT_EQ(a.normals.size(), pts.size());
  std::vector<double> err;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_GT(glm::dot(Vec3(a.normals[i]), Vec3(0, 0, 1)), 0.0) << "oriented along up";
    err.push_back(angle_deg(Vec3(a.normals[i]), n));
  }
  std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
  EXPECT_LT(err[err.size() / 2], 3.0);
  // Radius closes the 1 x 3 grid: the farthest point of a cell from every sample is at
  // sqrt(0.5^2 + 1.5^2) s = 1.58 s; interior points' radius = 0.6 x 8th neighbour (3 s) = 1.8 s.
  std::vector<float> r = a.radii;
  std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
  EXPECT_GT(r[r.size() / 2], 1.58 * s);
  EXPECT_LT(r[r.size() / 2], 2.2 * s);
  EXPECT_LE(a.max_radius, 4.0 * a.median_radius + 1e-12);
}

TEST(EstimateSurfels, SphereNormalsPointToTheViewpointOrOutwards) {
  // Fibonacci sphere of radius 10 around c: normals are radial; oriented to an inside viewpoint
  // they point inwards, with up they point to +z on the upper half.
  const Vec3 c(5.0, -2.0, 3.0);
  std::vector<Vec3> pts;
  const int N = 4000;
  for (int i = 0; i < N; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / N, rr = std::sqrt(1.0 - z * z);
    const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
    pts.push_back(c + 10.0 * Vec3(rr * std::cos(phi), rr * std::sin(phi), z));
  }
  const AnyIndex idx = make_index(pts, IndexOptions{"kdtree"});
  SurfelOptions o;
  o.orientation.viewpoint = c;
  const SurfelAttributes a = estimate_surfels(idx, pts, o);
  double worst = 0.0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3 inward = glm::normalize(c - pts[i]);
    EXPECT_GT(glm::dot(Vec3(a.normals[i]), inward), 0.0);
    worst = std::max(worst, angle_deg(Vec3(a.normals[i]), inward));
  }
  EXPECT_LT(worst, 3.0);
}

TEST(EstimateSurfels, FileNormalsAreNormalisedAndOriented) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) pts.push_back(Vec3(i, j, 0.0));
  std::vector<glm::vec3> fn(pts.size(), glm::vec3(0.0f, 0.0f, -2.0f));
  const AnyIndex idx = make_index(pts, IndexOptions{"brute"});
  const SurfelAttributes a = estimate_surfels(idx, pts, {}, fn);
  for (const auto& v : a.normals) EXPECT_EQ(v, glm::vec3(0.0f, 0.0f, 1.0f));
  EXPECT_THROW(estimate_surfels(idx, pts, {}, std::span<const glm::vec3>(fn).first(5)), std::invalid_argument);
  SurfelOptions bad;
  bad.k_normal = 2;
  EXPECT_THROW(estimate_surfels(idx, pts, bad), std::invalid_argument);
}

TEST(EstimateSurfels, ThicknessIsTheStepOfADepthQuantisedTerrace) {
  // Two flat terraces of a unit grid, z = 0 for x < 30 and z = 7 for x >= 30 (a depth camera's
  // disparity step, 7 spacings), as the office1 Kinect wall. Analytic answers: the points within 2
  // spacings of the step see the other terrace (lateral <= 2 < kThicknessReach x r, r = 0.6 x sqrt 2,
  // offset 7 < kThicknessHeight x r): thickness exactly 7; no point has more than 7; far from the
  // step (patch spread aside) both terraces are flat: 0.
  std::vector<Vec3> pts;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 60; ++x) pts.push_back(Vec3(x, y, x < 30 ? 0.0 : 7.0));
  const AnyIndex idx = make_index(pts, IndexOptions{});
  const SurfelAttributes a = estimate_surfels(idx, pts);
  ASSERT_EQ(a.thickness.size(), pts.size());
  std::size_t far = 0, far_zero = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(std::abs(a.normals[i].z), 1.0f, 1e-6f);
    EXPECT_LE(a.thickness[i], 7.0f + 1e-5f) << "no layer is farther than the step";
    const double x = pts[i].x;
    if (x >= 28 && x <= 31) {
      EXPECT_NEAR(a.thickness[i], 7.0f, 1e-5f) << "point " << i << " next to the step";
    }
    if (std::abs(x - 29.5) > 12) {
      ++far;
      far_zero += a.thickness[i] < 1e-5f;
    }
  }
  EXPECT_GT(double(far_zero), 0.9 * double(far)) << far_zero << " of " << far << " far points are flat";
  SurfelOptions o;
  o.measure_thickness = false;
  const SurfelAttributes b = estimate_surfels(idx, pts, o);
  for (const float t : b.thickness) ASSERT_EQ(t, 0.0f);
}

// The estimate's progress (SurfelOptions::progress): every report is the phase "surfels" with the
// total = the point count, none counts more than that, the last (from the calling thread, after
// the work) is done == total, with and without the thickness pass; the attributes do not change.
// Oracle: the cloud's point count (5000 points, several blocks of 1024 and of thickness patches).
TEST(EstimateSurfels, ProgressEndsWithEveryPointDone) {
  const auto pts = tilted_plane(Vec3(10.0, 20.0, 3.0), glm::normalize(Vec3(0.1, 0.2, 1.0)), 0.1, 100, 50, 0.001, 5);
  ASSERT_EQ(pts.size(), 5000u);
  const AnyIndex idx = make_index(pts, IndexOptions{});
  for (const bool thickness : {true, false}) {
    struct Report {
      std::string phase;
      std::uint64_t done, total;
    };
    std::mutex m;
    std::vector<Report> reports;
    SurfelOptions o;
    o.measure_thickness = thickness;
    o.progress = [&](const char* phase, std::uint64_t done, std::uint64_t total) {
      const std::lock_guard lock(m);
      reports.push_back({phase, done, total});
    };
    const SurfelAttributes a = estimate_surfels(idx, pts, o);
    ASSERT_GE(reports.size(), 3u) << "a start, the blocks and the end";
    for (const Report& r : reports) {
      EXPECT_EQ(r.phase, "surfels");
      EXPECT_EQ(r.total, pts.size());
      EXPECT_LE(r.done, pts.size());
    }
    EXPECT_EQ(reports.front().done, 0u);
    EXPECT_EQ(reports.back().done, pts.size()) << "thickness " << thickness;
    SurfelOptions quiet = o;
    quiet.progress = nullptr;
    const SurfelAttributes b = estimate_surfels(idx, pts, quiet);
    EXPECT_EQ(a.normals, b.normals);
    EXPECT_EQ(a.radii, b.radii);
    EXPECT_EQ(a.thickness, b.thickness);
  }
}
