// The ray of the paper's section 2 ("Ray"): origin o and unit direction d; t measures distance
// along the ray from o (so t values are in world units).
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rayscan {

/// A ray o + t d in double world coordinates. The direction is normalised on construction, so t
/// is a distance in world units (paper section 2, "Ray").
/// Throws std::invalid_argument when the direction is zero or any component is not finite.
class Ray {
 public:
  /// Build a ray; `direction` need not be unit length (it is normalised here).
  /// Throws std::invalid_argument for a zero or non-finite direction or a non-finite origin.
  Ray(const Vec3& origin, const Vec3& direction) : o_(origin) {
    if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z))
      throw std::invalid_argument("Ray: origin must be finite");
    // Scale by the largest component first so huge finite directions do not overflow the length.
    const double m = std::max({std::abs(direction.x), std::abs(direction.y), std::abs(direction.z)});
    if (!(m > 0.0) || !std::isfinite(m))
      throw std::invalid_argument("Ray: direction must be non-zero and finite");
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
