// Coordinates on a LAS grid as text (rayscan/io/grid_text.hpp).
#include "rayscan/io/grid_text.hpp"

#include "rayscan/base/number_text.hpp"

#include "las/las_grid.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace rayscan::io {

int grid_decimals(double scale, double offset) {
  if (!std::isfinite(offset)) return -1;
  const int ds = step_decimals(scale), doff = offset == 0.0 ? 0 : step_decimals(std::abs(offset));
  return ds < 0 || doff < 0 ? -1 : std::max(ds, doff);
}

void append_grid_coordinate(std::string& out, double v, double scale, double offset, int decimals) {
  if (decimals >= 0 && detail::on_las_grid(v, scale, offset, detail::OnGrid::exact)) {
    // Beyond about 15 significant digits the decimals might name another grid point: checked.
    char fixed[400];  // (a double in fixed notation has at most 309 integer digits)
    const auto r = std::to_chars(fixed, fixed + sizeof fixed, v, std::chars_format::fixed, decimals);
    double back = 0;
    if (r.ec == std::errc() && std::from_chars(fixed, r.ptr, back).ec == std::errc() &&
        std::round((back - offset) / scale) == std::round((v - offset) / scale)) {
      out.append(fixed, r.ptr);
      return;
    }
  }
  char buf[32];  // the longest shortest form of a double is 24 characters
  out.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

GridText GridText::of(const Vec3& scale, const Vec3& offset) {
  GridText g;
  g.scale = scale;
  g.offset = offset;
  for (int k = 0; k < 3; ++k) g.decimals[static_cast<std::size_t>(k)] = grid_decimals(scale[k], offset[k]);
  return g;
}

}  // namespace rayscan::io
