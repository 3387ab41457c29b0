#include "rayscan/octree/distance.hpp"

#include <algorithm>

namespace rayscan {

double segment_box_distance2(const Vec3& o, const Vec3& u, double t0, double t1, const AABB& b) {
  if (b.empty() || !(t0 <= t1)) return kInf;
  // Breakpoints of the piecewise quadratic g(t) = dist^2(o + t u, b) inside (t0, t1).
  double bp[8];
  int n = 0;
  for (int i = 0; i < 3; ++i) {
    if (u[i] == 0.0) continue;
    const double ta = (b.lo[i] - o[i]) / u[i];
    const double tb = (b.hi[i] - o[i]) / u[i];
    if (ta > t0 && ta < t1) bp[n++] = ta;
    if (tb > t0 && tb < t1) bp[n++] = tb;
  }
  std::sort(bp, bp + n);
  double best = kInf;
  double a = t0;
  for (int piece = 0; piece <= n; ++piece) {
    const double c = piece < n ? bp[piece] : t1;
    // A representative t strictly inside the piece (or its single point).
    double m;
    if (std::isfinite(a) && std::isfinite(c)) m = 0.5 * (a + c);
    else if (std::isfinite(a)) m = a + 1.0;
    else if (std::isfinite(c)) m = c - 1.0;
    else m = 0.0;
    // On this piece the violated faces are fixed: g(t) = sum_active (o_i + t u_i - f_i)^2.
    double num = 0.0, den = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double x = o[i] + m * u[i];
      double f;
      if (x < b.lo[i]) f = b.lo[i];
      else if (x > b.hi[i]) f = b.hi[i];
      else continue;
      num -= u[i] * (o[i] - f);
      den += u[i] * u[i];
    }
    double t = den > 0.0 ? num / den : m;
    t = std::clamp(t, a, c);
    if (!std::isfinite(t)) t = m;
    best = std::min(best, distance2_point_box(o + t * u, b));
    if (best == 0.0) return 0.0;
    a = c;
  }
  return best;
}

Interval dist_ray_bounds(const Vec3& o, const Vec3& dir, const AABB& b) {
  if (b.empty()) return {};
  const Vec3 u = dir / glm::length(dir);
  const double lo = std::sqrt(segment_box_distance2(o, u, -kInf, kInf, b));
  double hi2 = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Vec3 p{(c & 1) ? b.hi.x : b.lo.x, (c & 2) ? b.hi.y : b.lo.y, (c & 4) ? b.hi.z : b.lo.z};
    const Vec3 v = p - o;
    const Vec3 w = v - glm::dot(v, u) * u;
    hi2 = std::max(hi2, glm::dot(w, w));
  }
  // lo (closest point of the line to the box) and hi (farthest corner) are computed by different
  // formulas; for a degenerate (point) box rounding can put hi a few ulps below lo, which would
  // read as an empty interval and prune a qualifying point. Both bound the same value: keep lo <= hi.
  return {lo, std::max(lo, std::sqrt(hi2))};
}

}  // namespace rayscan
