// Coordinates on a LAS grid as text: a LAS coordinate is the double X * scale + offset (ASPRS LAS
// 1.4 R15 section 2.4), e.g. 637173.8200000001 for X = 63717382 and scale 0.01, which las2txt and
// lasinfo print with the grid's decimals (637173.82). This is that rule for any text output of
// coordinates that came from a LAS grid (the query CSV); every other value keeps the shortest
// decimal that reads back as the same double (shortest_text).
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <array>
#include <string>

namespace rayscan::io {

/// Decimals that print every value of the grid (`scale`, `offset`) exactly: the scale's
/// step_decimals, or the offset's when it has more (scale 0.01, offset 0.125: 3). -1 when either
/// is not a short decimal (1/3), not finite, or the scale is not > 0.
[[nodiscard]] int grid_decimals(double scale, double offset);

/// Appends `v` to `out`: with `decimals` decimals (grid_decimals(scale, offset)) when `v` lies on
/// the grid exactly (integer x scale + offset as the LAS reader computes it) and that text reads
/// back onto the same grid integer; otherwise, or for `decimals` < 0, the shortest text that
/// reads back as `v` (std::to_chars).
void append_grid_coordinate(std::string& out, double v, double scale, double offset, int decimals);

/// How to print x, y and z of points that came from one LAS grid (a LAS, LAZ or COPC file's
/// header scale and offset, an index file storing the sources' LAS integers): per axis the grid
/// and its grid_decimals, -1 (the shortest form) without a grid. Default: no grid.
struct GridText {
  Vec3 scale{0.0}, offset{0.0};
  std::array<int, 3> decimals{-1, -1, -1};

  /// The text of the grid (`scale`, `offset`); an axis whose grid has no short decimals prints
  /// shortest.
  [[nodiscard]] static GridText of(const Vec3& scale, const Vec3& offset);
  /// True when some axis prints with a grid's decimals.
  [[nodiscard]] bool on_grid() const { return decimals[0] >= 0 || decimals[1] >= 0 || decimals[2] >= 0; }
  /// Appends coordinate `axis` (0..2) of a point (append_grid_coordinate).
  void append(std::string& out, double v, int axis) const {
    append_grid_coordinate(out, v, scale[axis], offset[axis], decimals[static_cast<std::size_t>(axis)]);
  }
};

}  // namespace rayscan::io
