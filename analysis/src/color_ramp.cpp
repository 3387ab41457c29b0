#include "rayscan/analysis/color_ramp.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rayscan::analysis {

Rgb heat_ramp(double t) {
  if (!(t == t)) return {};
  t = std::clamp(t, 0.0, 1.0);
  const float s = static_cast<float>(3.0 * t);
  if (s <= 1.0f) return {s, 0.0f, 0.0f};                // black -> red
  if (s <= 2.0f) return {1.0f, s - 1.0f, 0.0f};         // red -> yellow
  return {1.0f, 1.0f, std::min(1.0f, s - 2.0f)};        // yellow -> white
}

std::string heat_ramp_legend(double lo, double hi) {
  char buf[256];
  const double d = hi - lo;
  std::snprintf(buf, sizeof buf, "black %.6g -> red %.6g -> yellow %.6g -> white %.6g", lo,
                lo + d / 3.0, lo + 2.0 * d / 3.0, hi);
  return buf;
}

}  // namespace rayscan::analysis
