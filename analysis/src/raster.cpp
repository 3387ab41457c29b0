#include "rayscan/analysis/raster.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace rayscan::analysis {

std::int64_t GridSpec::col_of(double x) const {
  return static_cast<std::int64_t>(std::floor(x / cell)) - static_cast<std::int64_t>(std::llround(x0 / cell));
}

std::int64_t GridSpec::row_of(double y) const {
  return static_cast<std::int64_t>(std::llround(y_top / cell)) - 1 -
         static_cast<std::int64_t>(std::floor(y / cell));
}

GridSpec grid_over(const AABB& bounds, double cell, std::uint64_t max_cells) {
  if (!(cell > 0.0) || !std::isfinite(cell))
    throw std::invalid_argument("raster: cell size must be a finite number > 0");
  if (bounds.empty()) throw std::invalid_argument("raster: the cloud has no points");
  const double fx0 = std::floor(bounds.lo.x / cell), fx1 = std::floor(bounds.hi.x / cell);
  const double fy0 = std::floor(bounds.lo.y / cell), fy1 = std::floor(bounds.hi.y / cell);
  const double cols = fx1 - fx0 + 1.0, rows = fy1 - fy0 + 1.0;
  if (!(cols * rows <= double(max_cells)) || std::abs(fx0) > 9e15 || std::abs(fy1) > 9e15) {
    const double extent = std::max(bounds.hi.x - bounds.lo.x, bounds.hi.y - bounds.lo.y);
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "raster: cell size %.6g gives %.6g x %.6g cells (limit %llu); use a cell of at least %.6g",
                  cell, cols, rows, static_cast<unsigned long long>(max_cells),
                  extent / std::sqrt(double(max_cells)) * 1.01);
    throw std::invalid_argument(buf);
  }
  GridSpec g;
  g.cell = cell;
  g.x0 = fx0 * cell;
  g.y_top = (fy1 + 1.0) * cell;
  g.cols = static_cast<std::uint32_t>(cols);
  g.rows = static_cast<std::uint32_t>(rows);
  return g;
}

Raster rasterize(std::span<const Vec3> positions, std::span<const double> values, const GridSpec& grid,
                 CellReduce reduce, std::string name) {
  if (positions.size() != values.size())
    throw std::invalid_argument("raster: " + std::to_string(values.size()) + " values for " +
                                std::to_string(positions.size()) + " points");
  const std::size_t ncell = std::size_t(grid.cols) * grid.rows;
  std::vector<double> acc(ncell, reduce == CellReduce::mean ? 0.0
                                 : reduce == CellReduce::max ? -std::numeric_limits<double>::infinity()
                                                             : std::numeric_limits<double>::infinity());
  std::vector<std::uint32_t> n(ncell, 0);
  std::vector<double> top_z;  // CellReduce::top: the z of the point whose value the cell holds
  if (reduce == CellReduce::top) top_z.assign(ncell, -std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const double v = values[i];
    if (!std::isfinite(v)) continue;
    const std::int64_t c = grid.col_of(positions[i].x), r = grid.row_of(positions[i].y);
    if (c < 0 || r < 0 || c >= std::int64_t(grid.cols) || r >= std::int64_t(grid.rows)) continue;
    const std::size_t k = std::size_t(r) * grid.cols + std::size_t(c);
    switch (reduce) {
      case CellReduce::mean: acc[k] += v; break;
      case CellReduce::max: acc[k] = std::max(acc[k], v); break;
      case CellReduce::min: acc[k] = std::min(acc[k], v); break;
      case CellReduce::top:
        if (positions[i].z > top_z[k]) {
          top_z[k] = positions[i].z;
          acc[k] = v;
        }
        break;
    }
    ++n[k];
  }
  Raster out;
  out.grid = grid;
  out.name = std::move(name);
  out.values.resize(ncell);
  for (std::size_t k = 0; k < ncell; ++k)
    out.values[k] = n[k] == 0 ? std::numeric_limits<float>::quiet_NaN()
                              : static_cast<float>(reduce == CellReduce::mean ? acc[k] / n[k] : acc[k]);
  return out;
}

}  // namespace rayscan::analysis
