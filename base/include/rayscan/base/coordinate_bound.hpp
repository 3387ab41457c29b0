// The one bound on the magnitude of a world coordinate, shared by the point readers (a point
// beyond it is refused), the point writers (a point or LAS offset beyond it is not written) and
// the observers of a visibility analysis.
#pragma once

#include "rayscan/base/number_text.hpp"

#include <string>

namespace rayscan {

/// The largest magnitude of a world coordinate (x, y or z, world units) rayscan accepts. Far
/// beyond any coordinate on Earth (geocentric ECEF about 6.4e6 m, projected grids about 2e7 ft),
/// and far below where doubles grow coarse (their spacing at 1e9 is about 1.2e-7; it reaches a
/// millimetre only near 4e12) or where ray code overflows (a direction length near 1.3e154), so a
/// ray or distance between accepted coordinates never fails inside the geometry code.
inline constexpr double kMaxCoordinate = 1e9;

/// What every error refusing a coordinate beyond kMaxCoordinate ends with, so that a reader's, a
/// writer's and an option's refusal read alike: "expected within +-1e+09, the coordinate bound in
/// world units".
[[nodiscard]] inline std::string coordinate_bound_expected() {
  return "expected within +-" + shortest_text(kMaxCoordinate) + ", the coordinate bound in world units";
}

}  // namespace rayscan
