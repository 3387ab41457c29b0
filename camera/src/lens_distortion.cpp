#include "rayscan/camera/lens_distortion.hpp"

#include <cmath>

namespace rayscan {

glm::dvec2 distort(const LensDistortion& k, const glm::dvec2& p) {
  const double x = p.x, y = p.y, r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
  return {x * radial + 2.0 * k.p1 * x * y + k.p2 * (r2 + 2.0 * x * x),
          y * radial + k.p1 * (r2 + 2.0 * y * y) + 2.0 * k.p2 * x * y};
}

glm::dvec2 undistort(const LensDistortion& k, const glm::dvec2& target) {
  glm::dvec2 p = target;
  for (int it = 0; it < 20; ++it) {
    const double x = p.x, y = p.y, r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
    const double dradial = k.k1 + r2 * (2.0 * k.k2 + 3.0 * k.k3 * r2);  // d radial / d(r^2)
    const glm::dvec2 f = distort(k, p) - target;
    // Jacobian of distort().
    const double a = radial + 2.0 * x * x * dradial + 2.0 * k.p1 * y + 6.0 * k.p2 * x;
    const double b = 2.0 * x * y * dradial + 2.0 * k.p1 * x + 2.0 * k.p2 * y;
    const double c = 2.0 * x * y * dradial + 2.0 * k.p1 * x + 2.0 * k.p2 * y;
    const double d = radial + 2.0 * y * y * dradial + 6.0 * k.p1 * y + 2.0 * k.p2 * x;
    const double det = a * d - b * c;
    if (!(std::abs(det) > 1e-300)) break;
    const glm::dvec2 step((d * f.x - b * f.y) / det, (-c * f.x + a * f.y) / det);
    p -= step;
    if (std::abs(step.x) + std::abs(step.y) < 1e-14) break;
  }
  return p;
}

}  // namespace rayscan
