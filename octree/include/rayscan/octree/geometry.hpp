// Small value types shared by every part of rayscan: 3-vectors, intervals and axis-aligned boxes.
// Style after pbrt-v4 (Pharr, Jakob, Humphreys, 4th ed., sections 3.3 "Points", 3.7 "Bounding
// Boxes"): plain values, no invariants hidden behind setters.
#pragma once

#include <glm/vec3.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rayscan {

/// A position or direction in world coordinates, double precision (metres, feet, ... as the cloud's
/// CRS says). Double keeps millimetres at UTM / State Plane magnitudes (1e6..1e7).
using Vec3 = glm::dvec3;

/// +infinity, the "not set" value of the paper's Algorithm 1 for r, k, t_max.
inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// True when every coordinate of `v` is finite (no NaN, no infinity).
[[nodiscard]] inline bool is_finite(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// A closed interval [lo, hi] of reals; empty when lo > hi. Used for the "bounds evaluation"
/// of the distance functions (paper section 4.2) and for the projected time interval of a node
/// (paper eq. 4).
struct Interval {
  double lo = kInf;   ///< lower end (inclusive)
  double hi = -kInf;  ///< upper end (inclusive)

  /// True when the interval holds no value (lo > hi).
  [[nodiscard]] constexpr bool empty() const { return lo > hi; }
  /// True when lo <= v <= hi.
  [[nodiscard]] constexpr bool contains(double v) const { return lo <= v && v <= hi; }
};

/// An axis-aligned bounding box [lo, hi] in world coordinates (inclusive on both sides).
/// A default-constructed box is empty (lo = +inf, hi = -inf) and grows with expand().
struct AABB {
  Vec3 lo{kInf};
  Vec3 hi{-kInf};

  /// True when the box holds no point (any lo > hi).
  [[nodiscard]] bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  /// Grow the box to contain p.
  void expand(const Vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  /// Grow the box to contain b.
  void expand(const AABB& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  /// True when lo <= p <= hi on every axis (closed box).
  [[nodiscard]] bool contains(const Vec3& p) const {
    // `&`, not `&&`: all six comparisons without a branch (where the answer is unpredictable, as
    // for the points of a node a query box cuts, a branch per axis mispredicts).
    return (p.x >= lo.x) & (p.x <= hi.x) & (p.y >= lo.y) & (p.y <= hi.y) & (p.z >= lo.z) & (p.z <= hi.z);
  }
  /// True when the two closed boxes share at least one point.
  [[nodiscard]] bool overlaps(const AABB& b) const {
    return lo.x <= b.hi.x && b.lo.x <= hi.x && lo.y <= b.hi.y && b.lo.y <= hi.y &&
           lo.z <= b.hi.z && b.lo.z <= hi.z;
  }
  /// Centre of the box, (lo + hi) / 2.
  [[nodiscard]] Vec3 center() const { return 0.5 * (lo + hi); }
  /// Edge lengths hi - lo (undefined for an empty box).
  [[nodiscard]] Vec3 extent() const { return hi - lo; }
  /// Length of the longest edge, 0 for a single point, 0 for an empty box.
  [[nodiscard]] double max_extent() const {
    if (empty()) return 0.0;
    const Vec3 e = extent();
    return std::max({e.x, e.y, e.z});
  }
};

/// Squared Euclidean distance from p to the closed box b (0 inside). Used by kNN/radius point
/// queries to order and prune nodes (the MINDIST of Roussopoulos et al. 1995).
[[nodiscard]] inline double distance2_point_box(const Vec3& p, const AABB& b) {
  const Vec3 q = glm::clamp(p, b.lo, b.hi);
  const Vec3 v = p - q;
  return glm::dot(v, v);
}

}  // namespace rayscan
