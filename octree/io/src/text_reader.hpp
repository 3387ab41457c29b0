#pragma once
#include "rayscan/io/point_io.hpp"

namespace rayscan::io {
/// XYZ/CSV/TXT reader: whitespace or comma separated; an optional first line naming the columns
/// (x, y, z, r, g, b, intensity in any order; case-insensitive); without a header the first three
/// columns are x y z. Values are parsed as double. Throws FormatError naming file and line.
PointCloud read_text(const std::filesystem::path& path);
}  // namespace rayscan::io
