// Degrees and radians for the sun and shadow code (SPA, the clear-sky model, the sun map).
#pragma once

#include <numbers>

namespace rayscan::analysis {

/// One degree in radians.
inline constexpr double kDegree = std::numbers::pi / 180.0;

}  // namespace rayscan::analysis
