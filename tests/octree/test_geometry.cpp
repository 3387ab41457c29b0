// Distance predicates (paper eqs. 1-6) and their bounds evaluation, Morton codes and node ids,
// against independent formulas (cross product, corner enumeration, ternary search over edges).
#include "test_util.hpp"

#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/morton.hpp"
#include "rayscan/octree/ray.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <limits>

#include <gtest/gtest.h>

#include <random>

using namespace rayscan;

namespace {

// Independent: distance from the line to a segment [a, b] by ternary search (convex in s).
double line_segment_distance(const Vec3& o, const Vec3& u, const Vec3& a, const Vec3& b) {
  auto f = [&](double s) {
    const Vec3 p = a + s * (b - a);
    return glm::length(glm::cross(p - o, u));
  };
  double lo = 0, hi = 1;
  for (int i = 0; i < 200; ++i) {
    const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    if (f(m1) < f(m2)) hi = m2;
    else lo = m1;
  }
  return f(0.5 * (lo + hi));
}

bool line_hits_box(const Vec3& o, const Vec3& u, const AABB& b) {
  return !slab_interval(o, 1.0 / u, b, 0.0, -kInf, kInf).empty();
}

// Independent exact line-box distance: 0 if the line crosses the box, otherwise the minimum over
// the 12 edges (a line that misses a box is closest to it on an edge).
double oracle_line_box(const Vec3& o, const Vec3& u, const AABB& b) {
  if (line_hits_box(o, u, b)) return 0.0;
  double best = kInf;
  for (int c = 0; c < 8; ++c)
    for (int axis = 0; axis < 3; ++axis) {
      if (c & (1 << axis)) continue;
      const Vec3 a{(c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z};
      Vec3 e = a;
      e[axis] = b.hi[axis];
      best = std::min(best, line_segment_distance(o, u, a, e));
    }
  return best;
}

TEST(Distance, DistRayMatchesEquation1CrossProduct) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-10, 10);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 o(u(rng), u(rng), u(rng)), d(u(rng), u(rng), u(rng)), p(u(rng), u(rng), u(rng));
    const Vec3 a = o, b = o + 100.0 * d;  // eq. 1 with b = o + 100 d, as in the paper
    const double eq1 = glm::length(glm::cross(p - a, p - b)) / glm::length(b - a);
    EXPECT_NEAR(dist_ray(o, d, p), eq1, 1e-9 * (1 + eq1));
    // dist_plane with n = d is the projection time t_p (section 3.2).
    EXPECT_NEAR(dist_plane(o, d, p), glm::dot(p - o, d) / glm::length(d), 1e-12 * 100);
  }
}

TEST(Distance, BoundsEvaluationEnclosesAndIsTight) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int i = 0; i < 500; ++i) {
    AABB b;
    b.expand(Vec3(u(rng), u(rng), u(rng)));
    b.expand(Vec3(u(rng), u(rng), u(rng)));
    if (i % 10 == 0) b.hi.y = b.lo.y;  // degenerate (flat) box
    const Vec3 o(u(rng) * 3, u(rng) * 3, u(rng) * 3);
    Vec3 d(u(rng), u(rng), u(rng));
    if (i % 7 == 0) d = Vec3(0, 0, 1);  // axis-parallel
    const Vec3 un = d / glm::length(d);
    // dist_plane_bounds: exact min/max over the 8 corners (linear function).
    double pmin = kInf, pmax = -kInf, rmax = 0;
    for (int c = 0; c < 8; ++c) {
      const Vec3 p{(c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z};
      pmin = std::min(pmin, dist_plane(o, d, p));
      pmax = std::max(pmax, dist_plane(o, d, p));
      rmax = std::max(rmax, dist_ray(o, d, p));
    }
    const Interval pi = dist_plane_bounds(o, d, b);
    EXPECT_NEAR(pi.lo, pmin, 1e-12 * 10);
    EXPECT_NEAR(pi.hi, pmax, 1e-12 * 10);
    const Interval ri = dist_ray_bounds(o, d, b);
    EXPECT_NEAR(ri.lo, oracle_line_box(o, un, b), 1e-7) << "box " << i;
    EXPECT_NEAR(ri.hi, rmax, 1e-9);
    // eq. 3 never exceeds the exact minimum.
    EXPECT_LE(node_ray_distance_eq3(o, d, b), ri.lo + 1e-12);
    // Random points inside the box lie inside both intervals.
    std::uniform_real_distribution<double> t(0, 1);
    for (int k = 0; k < 20; ++k) {
      const Vec3 p = b.lo + Vec3(t(rng), t(rng), t(rng)) * (b.hi - b.lo);
      EXPECT_GE(dist_ray(o, d, p), ri.lo - 1e-9);
      EXPECT_LE(dist_ray(o, d, p), ri.hi + 1e-9);
      EXPECT_GE(dist_plane(o, d, p), pi.lo - 1e-9);
      EXPECT_LE(dist_plane(o, d, p), pi.hi + 1e-9);
    }
  }
}

// A point box (what a GiST index of points stores): lo and hi come from different formulas, and
// rounding once put hi below lo, an "empty" interval that pruned the point (found by the
// PostgreSQL ray_dwithin test). The interval must never be empty and must hold dist_ray.
TEST(Distance, DistRayBoundsOfAPointBoxIsNeverEmpty) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> c(-1e3, 1e3), dir(-1, 1);
  const Vec3 base(636267.02826426388, 848956.8609175015, 873.74799999998879);
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = base + Vec3(c(rng), c(rng), c(rng) * 0.1 - 440);
    const Vec3 d(dir(rng), dir(rng), dir(rng) - 1.5);
    const Interval iv = dist_ray_bounds(base, d, AABB{p, p});
    ASSERT_FALSE(iv.empty()) << i;
    ASSERT_LE(iv.lo, iv.hi);
    EXPECT_NEAR(iv.lo, dist_ray(base, d, p), 1e-9 * (1 + glm::length(p - base)));
  }
}

// A line touching a box's edge or corner is at distance 0 from it (analytic), so no bound of the
// box-to-line distance may exceed the node tests' rounding allowance there. At UTM magnitudes the
// bounds round box centres at the coordinates' ulp (9.3e-10 m at 5.3e6): the first box is the
// kd-tree leaf whose point a ray at r = 0 lost (separating-axis bound 3.7e-10 m against this box's
// allowance of 2.2e-10 m without the magnitude term; bench/notes/).
TEST(Distance, BoxBoundsOfATouchingLineStayWithinTheNodeTestTolerance) {
  const AABB leaf{Vec3(600000.04599999997, 5300000.0290000001, 100.015),
                  Vec3(600000.071, 5300000.0480000004, 100.029)};
  const Vec3 leaf_o(599999.86800000002, 5300000.0480000004, 100.015), x(1, 0, 0);
  EXPECT_LE(node_ray_distance_sat(leaf_o, x, leaf), node_test_tolerance(leaf_o, leaf));
  std::mt19937_64 rng(29);
  std::uniform_int_distribution<int> mm(0, 100);
  const Vec3 base(600000.0, 5300000.0, 100.0);
  for (int i = 0; i < 20000; ++i) {
    Vec3 lo = base + 0.001 * test::draw3([&] { return double(mm(rng)); });
    Vec3 hi = base + 0.001 * test::draw3([&] { return double(mm(rng)); });
    const AABB b{glm::min(lo, hi), glm::max(lo, hi)};
    const int axis = i % 3;
    Vec3 u(0.0);
    u[axis] = (i / 3) % 2 ? 1.0 : -1.0;
    // Through a corner of b (the other two coordinates exactly a corner's), from outside the box.
    Vec3 o((i & 8) ? b.hi.x : b.lo.x, (i & 16) ? b.hi.y : b.lo.y, (i & 32) ? b.hi.z : b.lo.z);
    o[axis] = b.center()[axis] - u[axis] * (0.05 + 0.001 * mm(rng));
    const double tol = node_test_tolerance(o, b);
    ASSERT_LE(node_ray_distance_sat(o, u, b), tol) << i;
    ASSERT_LE(std::sqrt(segment_box_distance2(o, u, -kInf, kInf, b)), tol) << i;
    ASSERT_LE(dist_ray_bounds(o, u, b).lo, tol) << i;
  }
}

TEST(Distance, SegmentBoxDistanceRespectsTimeInterval) {
  // Unit box, line along x at height 2 above it: distance 1 from the box on t in [1, 2] (x in [0,1]).
  const AABB b{Vec3(0.0), Vec3(1.0)};
  const Vec3 o(-1, 0.5, 2), u(1, 0, 0);
  EXPECT_DOUBLE_EQ(segment_box_distance2(o, u, -kInf, kInf, b), 1.0);
  // Restricted to t in [-kInf, 0] (x <= -1): closest point is (-1, 0.5, 2) -> (0, 0.5, 1): sqrt 2.
  EXPECT_NEAR(segment_box_distance2(o, u, -kInf, 0.0, b), 2.0, 1e-12);
  EXPECT_EQ(segment_box_distance2(o, u, 1.0, 0.0, b), kInf);  // empty interval
  EXPECT_EQ(segment_box_distance2(o, u, -kInf, kInf, AABB{}), kInf);  // empty box
}

TEST(Morton, EncodeCompactRoundTripAndOrder) {
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<std::uint32_t> c(0, (1u << 21) - 1);
  for (int i = 0; i < 1000; ++i) {
    const std::uint32_t x = c(rng), y = c(rng), z = c(rng);
    const std::uint64_t m = morton_encode(x, y, z);
    EXPECT_EQ(morton_compact(m), x);
    EXPECT_EQ(morton_compact(m >> 1), y);
    EXPECT_EQ(morton_compact(m >> 2), z);
  }
  EXPECT_EQ(morton_encode(1, 0, 0), 1u);
  EXPECT_EQ(morton_encode(0, 1, 0), 2u);
  EXPECT_EQ(morton_encode(0, 0, 1), 4u);
  EXPECT_EQ(morton_encode(2, 0, 0), 8u);
}

TEST(Morton, WarrenSalmonNodeIdEncodesDepthAndCode) {
  const OctreeNodeId root = OctreeNodeId::root();
  EXPECT_EQ(root.bits(), 1u);
  EXPECT_EQ(root.depth(), 0u);
  const OctreeNodeId c = root.child(5).child(3);
  EXPECT_EQ(c.depth(), 2u);
  EXPECT_EQ(c.morton(), (5u << 3) | 3u);
  EXPECT_EQ(c.bits(), (1u << 6) | (5u << 3) | 3u);
  EXPECT_EQ(c.parent(), root.child(5));
  const OctreeNodeId deep(21, (std::uint64_t{1} << 63) - 1);
  EXPECT_EQ(deep.depth(), 21u);
  EXPECT_EQ(deep.morton(), (std::uint64_t{1} << 63) - 1);
}

TEST(Distance, RayPointKernelMatchesTextbookFormulas) {
  // ray_point_terms / sphere_entry are shared by the traversal and the brute-force oracle, so they
  // are checked here against independent formulas: t = d.(p - o) / |d|, eq. 1 via the cross
  // product, and the near root of the ray/sphere quadratic |o + t d - p|^2 = r^2.
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-5, 5);
  for (int i = 0; i < 2000; ++i) {
    const Ray ray(Vec3(u(rng), u(rng), u(rng)), Vec3(u(rng), u(rng), u(rng)));
    const Vec3 p(u(rng), u(rng), u(rng));
    const Vec3 o = ray.origin(), d = ray.direction();
    const RayPointTerms pt = ray_point_terms(o, d, p);
    EXPECT_NEAR(pt.t, glm::dot(p - o, d), 1e-12);
    const double cross = glm::length(glm::cross(p - o, d));
    EXPECT_NEAR(std::sqrt(pt.d2), cross, 1e-9);
    const double r = std::sqrt(pt.d2) + std::abs(u(rng)) * 0.2;  // the ray meets this sphere
    // Quadratic t^2 + 2 b t + c = 0 with b = d.(o - p), c = |o - p|^2 - r^2; near root.
    const double b = glm::dot(d, o - p), c = glm::dot(o - p, o - p) - r * r;
    const double disc = b * b - c;
    ASSERT_GE(disc, -1e-9);
    const double t_near = -b - std::sqrt(std::max(0.0, disc));
    EXPECT_NEAR(sphere_entry(pt.t, pt.d2, r), t_near, 1e-7);
  }
}

TEST(Ray, DirectionsWithinTheNormalisableRangeAreAccepted) {
  // The extremes is_valid_direction admits still give a unit direction.
  for (const double s : {1e-150, 1e150}) {
    ASSERT_TRUE(is_valid_direction(Vec3(s, s, s)));
    const Ray r(Vec3(0.0), Vec3(s, s, s));
    EXPECT_NEAR(glm::length(r.direction()), 1.0, 1e-15);
    EXPECT_NEAR(r.direction().x, std::sqrt(1.0 / 3.0), 1e-15);
  }
}

// A direction whose squared length underflows (0,0,1e-320) or overflows (1e300,...) cannot be
// normalised as d / |d| by the distance functions: every ray, SQL function and Python call refuses
// it through the one rule, with one message.
TEST(Ray, DirectionsOutsideTheNormalisableRangeAreRejected) {
  const double inf = std::numeric_limits<double>::infinity(), nan = std::nan("");
  for (const Vec3& d : {Vec3(0, 0, 1e-320), Vec3(1e-160, 0, 0), Vec3(1e-155, 1e-155, 1e-155),
                        Vec3(1e300, 1e300, 1.0), Vec3(1e155, 0, 0), Vec3(0.0), Vec3(inf, 0, 0),
                        Vec3(nan, 1, 0)}) {
    EXPECT_FALSE(is_valid_direction(d)) << d.x << "," << d.y << "," << d.z;
    try {
      (void)Ray(Vec3(0.0), d);
      ADD_FAILURE() << "accepted " << d.x << "," << d.y << "," << d.z;
    } catch (const std::invalid_argument& e) {
      EXPECT_STREQ(e.what(), "Ray: direction must be non-zero and finite with a length between about "
                             "1.5e-154 and 1.3e154 (so that it normalises exactly)");
    }
  }
  // The boundary: |d|^2 = DBL_MIN is the smallest normal square.
  EXPECT_TRUE(is_valid_direction(Vec3(std::sqrt(std::numeric_limits<double>::min()), 0, 0)));
  EXPECT_FALSE(is_valid_direction(Vec3(std::sqrt(std::numeric_limits<double>::min()) * 0.5, 0, 0)));
}

TEST(Ray, DirectionIsNormalised) {
  const Ray r(Vec3(1, 2, 3), Vec3(0, 3, 4));
  EXPECT_DOUBLE_EQ(glm::length(r.direction()), 1.0);
  EXPECT_DOUBLE_EQ(r.at(5).z, 3 + 4);
}

}  // namespace
