// Internal: the per-format readers behind read_point_cloud(). Each reads the whole Input and
// throws FormatError (see bytes.hpp) on malformed data.
#pragma once

#include "bytes.hpp"

namespace rayscan::io::detail {

/// ASPRS LAS 1.0-1.4 (R15); refuses LAZ/COPC. See las_reader.cpp.
PointCloud read_las(const Input& in, const ReadOptions& opt, FileInfo& info);
/// PLY 1.0 ascii / binary_little_endian / binary_big_endian. See ply_reader.cpp.
PointCloud read_ply(const Input& in, const ReadOptions& opt, FileInfo& info);
/// PCD 0.6/0.7 ascii / binary / binary_compressed. See pcd_reader.cpp.
PointCloud read_pcd(const Input& in, const ReadOptions& opt, FileInfo& info);
/// XYZ/CSV/TXT columns. See text_reader.cpp.
PointCloud read_text(const Input& in, const ReadOptions& opt, FileInfo& info);

/// CRS from the GeoKeys of a GeoKeyDirectoryTag VLR (LAS 1.4 R15 section 2.5.2; GeoTIFF 1.0
/// section 2.7): fills info.epsg / vertical_epsg; returns WKT when GDAL/OSR can build it, else "".
std::string crs_from_geokeys(const std::uint8_t* data, std::uint64_t len, FileInfo& info);
/// EPSG code identified from a WKT string (0 when OSR cannot identify it).
int epsg_from_wkt(const std::string& wkt);

}  // namespace rayscan::io::detail
