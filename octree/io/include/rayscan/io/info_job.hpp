// The info job: what `pdal info` reports for a point cloud file -- format, version, point data
// record format, point counts (and dropped non-finite points), recomputed bounds (and the
// header's where they differ), attributes with their ranges, scale/offset, CRS, VLRs.
// `rayscan info` prints its reports.
#pragma once

#include "rayscan/io/file_info.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/job.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace rayscan::io {

/// Inputs of run_info().
struct InfoJobOptions {
  std::filesystem::path file;  ///< point cloud file (any format read_point_cloud reads)
  JobControl control;          ///< unused today (the reader is single-threaded)
};

/// The range of one attribute over all points.
struct AttributeRange {
  std::string name;  ///< X, Y, Z, intensity, classification, gps_time, red..., normal_x..., scalar names
  double lo = 0, hi = 0;
};

/// Output of run_info().
struct InfoJobResult {
  std::string file;                          ///< the file described
  FileInfo info;                             ///< what the reader found
  std::uint64_t count = 0;                   ///< points read
  AABB bounds;                               ///< recomputed from the points (empty box for 0 points)
  bool header_differs = false;               ///< the header's box differs by more than half a scale step
  std::vector<AttributeRange> attributes;    ///< every attribute present, in a fixed order
  std::map<int, std::uint64_t> classes;      ///< points per ASPRS class code
  std::string crs_wkt;                       ///< the cloud's CRS as WKT ("" = none)
};

/// Reads `file` (read_point_cloud with all scalars) and summarises it. Throws io::FormatError for a
/// malformed or unsupported file.
InfoJobResult run_info(const InfoJobOptions& options);

/// The report as JSON (pdal info style), 2-space indent.
std::string info_report_json(const InfoJobResult& result);

/// The report as aligned text lines.
std::string info_report_text(const InfoJobResult& result);

}  // namespace rayscan::io
