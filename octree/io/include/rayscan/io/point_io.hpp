// Reading and writing point cloud files. Format readers follow their published specifications
// (see docs/formats.md); this header is the single entry point the tools use.
#pragma once

#include "rayscan/point_cloud.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>

namespace rayscan::io {

/// A malformed or unreadable input file. what() is one line naming the file, the byte offset or
/// line, and what was expected: "cloud.las: byte 227: point data offset 9000 past end of file (8000)".
struct FormatError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Read any supported point cloud file, dispatching on the extension (case-insensitive):
/// .f64 (headerless little-endian float64 x,y,z triples) and .csv/.xyz/.txt (text columns).
/// Throws FormatError for unreadable or malformed files.
PointCloud read_point_cloud(const std::filesystem::path& path);

}  // namespace rayscan::io
