// The ray of the paper's section 2 ("Ray"): origin o and unit direction d; t measures distance
// along the ray from o (so t values are in world units).
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rayscan {

/// Whether `d` can be a ray's direction or a plane's normal: its squared length |d|^2 is a finite,
/// normal double (DBL_MIN <= |d|^2 <= DBL_MAX, about 1.5e-154 <= |d| <= 1.3e154). The library
/// normalises such vectors as d / |d| (Ray, and dist_ray, dist_plane and their bounds in
/// distance.hpp, which take d as given); outside this range |d|^2 underflows into the subnormals
/// (d = (0,0,1e-320): |d| = 0, so d / |d| is not finite) or overflows, and every distance computed
/// from d is wrong. Zero, NaN and infinite vectors fail too. The SQL functions, the Python module
/// and the command line all reach this one rule (through Ray, or directly in the SQL glue).
[[nodiscard]] inline bool is_valid_direction(const Vec3& d) noexcept {
  const double len2 = d.x * d.x + d.y * d.y + d.z * d.z;
  return len2 >= std::numeric_limits<double>::min() && len2 <= std::numeric_limits<double>::max();
}

/// A ray o + t d in double world coordinates. The direction is normalised on construction, so t
/// is a distance in world units (paper section 2, "Ray").
/// Throws std::invalid_argument when the direction fails is_valid_direction or the origin is not
/// finite.
class Ray {
 public:
  /// Build a ray; `direction` need not be unit length (it is normalised here).
  /// Throws std::invalid_argument for a direction that fails is_valid_direction or a non-finite
  /// origin.
  Ray(const Vec3& origin, const Vec3& direction) : o_(origin) {
    if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z))
      throw std::invalid_argument("Ray: origin must be finite");
    if (!is_valid_direction(direction))
      throw std::invalid_argument(
          "Ray: direction must be non-zero and finite with a length between about 1.5e-154 and "
          "1.3e154 (so that it normalises exactly)");
    // d / max|d_i| first, then over its length: the one rounding of the unit direction that every
    // result of the library (and the SQL functions' ray_time) is computed with.
    const double m = std::max({std::abs(direction.x), std::abs(direction.y), std::abs(direction.z)});
    const Vec3 u = direction / m;
    d_ = u / glm::length(u);
  }

  /// Ray origin o (world coordinates).
  [[nodiscard]] const Vec3& origin() const { return o_; }
  /// Unit direction d.
  [[nodiscard]] const Vec3& direction() const { return d_; }
  /// The point o + t d.
  [[nodiscard]] Vec3 at(double t) const { return o_ + t * d_; }

 private:
  Vec3 o_;
  Vec3 d_;
};

}  // namespace rayscan
