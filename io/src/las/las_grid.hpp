// The LAS integer grid of one coordinate axis (ASPRS LAS 1.4 R15 section 2.4: a coordinate is its
// record's 32-bit integer x scale + offset): the one test of whether values lie on a grid, shared
// by the LAS writer's choice of scale and the text writer's choice of decimals.
#pragma once

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace rayscan::io::detail {

/// How closely a value must match a grid point.
enum class OnGrid {
  /// Bit for bit: the value is integer x scale + offset as the LAS reader computes it (a value
  /// read from LAS, or written from one through PLY or PCD, which keep doubles).
  exact,
  /// To within the rounding of decimal text: a few units in the last place, the difference
  /// between a grid value printed with the grid's decimals and read back (849087.7) and the
  /// reader's double (849087.7000000001).
  decimal,
};

/// The value the LAS reader gives for `v` stored on the grid (`scale` > 0, `offset`): the
/// integer nearest (v - offset) / scale, times scale, plus offset.
[[nodiscard]] inline double las_grid_value(double v, double scale, double offset) {
  return std::round((v - offset) / scale) * scale + offset;
}

/// Whether `v` lies on the grid (`scale` > 0, `offset`) as closely as `how` asks.
[[nodiscard]] inline bool on_las_grid(double v, double scale, double offset, OnGrid how) {
  const double g = las_grid_value(v, scale, offset);
  if (how == OnGrid::exact) return g == v;
  // Each of v, g and offset carries at most about one unit in the last place of the largest.
  return std::abs(g - v) <= 4.0 * DBL_EPSILON * std::max({std::abs(v), std::abs(g), std::abs(offset)});
}

}  // namespace rayscan::io::detail
