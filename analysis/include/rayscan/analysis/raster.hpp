// Top-down rasters of per-point values: a north-up grid over the cloud's XY extent,
// each cell reducing the values of the points that fall in it.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace rayscan::analysis {

/// A north-up grid of square cells in the cloud's world frame. Cell (col, row) (row 0 at the top,
/// i.e. north) covers x in [x0 + col c, x0 + (col + 1) c) and y in (y_top - (row + 1) c,
/// y_top - row c]; equivalently a point goes to col = floor(x / c) - floor(x_min / c),
/// row = floor(y_max / c) - floor(y / c). The GDAL geotransform is
/// (x0, c, 0, y_top, 0, -c) (GDAL Raster Data Model, "Affine GeoTransform").
struct GridSpec {
  double x0 = 0.0;      ///< west edge of column 0, world units
  double y_top = 0.0;   ///< north edge of row 0, world units
  double cell = 1.0;    ///< cell edge c, world units (> 0)
  std::uint32_t cols = 0, rows = 0;

  /// The 6 GDAL geotransform coefficients.
  [[nodiscard]] std::array<double, 6> geotransform() const { return {x0, cell, 0.0, y_top, 0.0, -cell}; }
  /// Column and row of (x, y); may be outside [0, cols) x [0, rows) for points outside the grid.
  [[nodiscard]] std::int64_t col_of(double x) const;
  [[nodiscard]] std::int64_t row_of(double y) const;
};

/// The grid of cell size `cell` covering `bounds`' XY extent, snapped to whole multiples of the cell
/// size (x0 = floor(x_min / c) c, y_top = (floor(y_max / c) + 1) c) so that rasters of neighbouring
/// tiles line up. Throws std::invalid_argument for a cell that is not finite and > 0, an empty box,
/// or a grid of more than `max_cells` cells (naming the size and a cell size that would fit).
GridSpec grid_over(const AABB& bounds, double cell, std::uint64_t max_cells = 400'000'000ull);

/// How a cell combines the values of its points. `top`: the value of the cell's highest point
/// (largest z; the first in point order on a tie), the surface a first-return DSM shows -- a roof,
/// a crown or the ground, never what lies under it.
enum class CellReduce { mean, max, min, top };

/// A single-band float raster on a GridSpec, row-major, top row first. NaN = no data.
struct Raster {
  GridSpec grid;
  std::vector<float> values;  ///< cols * rows values
  std::string name;           ///< what the values are (band description), e.g. "visible fraction"
};

/// Rasterize per-point `values` (one per position): each cell gets the mean, max or min of the
/// finite values of the points that fall in it, NaN when there is none. Points outside the grid are
/// ignored. The mean is accumulated in double in point order (deterministic).
/// Throws std::invalid_argument when the spans differ in length.
Raster rasterize(std::span<const Vec3> positions, std::span<const double> values, const GridSpec& grid,
                 CellReduce reduce, std::string name);

}  // namespace rayscan::analysis
