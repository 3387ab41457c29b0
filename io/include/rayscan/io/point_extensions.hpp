// The file name extensions of the point cloud formats rayscan reads: the one list that
// format_from_extension (rayscan/io/point_io.hpp) accepts and that the commands' help and error
// lines print. The written ones are point_cloud_output_extensions (point_io.hpp).
#pragma once

#include <string>
#include <vector>

namespace rayscan::io {

/// The extensions format_from_extension reads, lower case with the dot, in the order they are
/// listed to users: ".las", ".laz", ".copc.laz", ".copc", ".ply", ".pcd", ".xyz", ".csv", ".txt",
/// ".pts", ".f64" (".copc.laz" is a ".laz" name, listed because COPC files are named so).
[[nodiscard]] const std::vector<std::string>& point_cloud_input_extensions();

/// `extensions` separated by spaces (".las .laz .ply"), as help lines list them.
[[nodiscard]] std::string extension_list(const std::vector<std::string>& extensions);

}  // namespace rayscan::io
