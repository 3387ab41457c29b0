// The info job: what `pdal info` reports for a point cloud file -- format, version, point data
// record format, point counts (and dropped non-finite points), recomputed bounds (and the
// header's where they differ), attributes with their ranges, scale/offset, CRS, VLRs.
// `rayscan info` prints its reports.
#pragma once

#include "rayscan/io/cloud_stats.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/io/file_info.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/base/job.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The io library types this job's options and results are made of.
using io::AttributeRange;
using io::AttributeSet;
using io::CopcInfo;
using io::FileInfo;
using io::IndexSectionInfo;
using io::IndexSource;

/// Inputs of run_info().
struct InfoJobOptions {
  std::filesystem::path file;  ///< point cloud file (any format read_point_cloud reads)
  bool verify = false;         ///< index files: verify every section's checksum (CLI --verify)
  bool stats = false;          ///< report each attribute's mean and standard deviation (CLI --stats)
  JobControl control;          ///< the jobs' common controls; run_info reads none (one reader thread)
};

/// What `rayscan info` reports for an index file (.rsi, rayscan/site/index_file.hpp).
struct IndexFileSummary {
  std::string layout;                          ///< octree organisation ("adaptive", ...)
  std::uint32_t capacity = 0;                  ///< points per leaf
  std::uint64_t nodes = 0, depth = 0;
  std::vector<std::uint64_t> points_per_level;  ///< points stored at each octree depth
  std::uint64_t file_bytes = 0;
  double bytes_per_point = 0;
  std::string attributes;                      ///< AttributeSet::to_string() ("" = positions only)
  std::string positions;                       ///< encoding: "float64", "float32", "las_int32 (scale ..., offset ...)"
  std::string ids;                             ///< "stored (original order)" or "not stored (points in index order)"
  std::string rgb;                             ///< "" (none), "16-bit (6 bytes/point)" or "8-bit x M (3 bytes/point)"
  AABB root_cell;                              ///< the octree's root cube (world units)
  std::string checksums;                       ///< which sections were verified
  double spacing = 0;                          ///< median nearest-neighbour spacing (the auto radius)
  std::vector<IndexSectionInfo> sections;      ///< the section table (bytes per section)
  std::vector<IndexSource> sources;            ///< the files the index was built from
};

/// Output of run_info(): what `rayscan info` prints, as text or JSON.
struct InfoJobResult {
  std::string file;                          ///< the file described
  FileInfo info;                             ///< what the reader found
  std::uint64_t count = 0;                   ///< points read
  /// Recomputed from the points (empty box for 0 points); for an index file the exact bounds its
  /// header stores.
  AABB bounds;
  /// The header's box misstates the points' (io::header_bounds_differ: on the file's grid, more
  /// than half a scale step off; the index build's rule too).
  bool header_differs = false;
  std::vector<AttributeRange> attributes;    ///< every attribute present, in a fixed order, with its
                                             ///< min, max, mean and standard deviation (one pass)
  bool stats = false;                        ///< the reports include the mean and standard deviation
  std::map<int, std::uint64_t> classes;      ///< points per ASPRS class code
  /// The cloud's CRS as WKT ("" = none). info.epsg and info.vertical_epsg are its codes: the
  /// GeoKeys' when the CRS came from them (info.crs_source "GeoKeys"), else identified in this WKT
  /// (io::epsg_codes_from_wkt), so that a cloud and its index file report the same ones.
  std::string crs_wkt;
  std::string crs_name;                      ///< its name as GDAL reads it from the WKT ("" = none or unreadable)
  std::string crs_wkt2;                      ///< the same CRS as WKT2 (ISO 19162:2019, GDAL/PROJ)
  std::string crs_projjson;                  ///< the same CRS as PROJJSON (PROJ's JSON schema)
  /// Units of the CRS as GDAL/PROJ name them ("metre", "US survey foot", "foot", "degree"):
  /// horizontal (angular for a geographic CRS, else io::crs_horizontal_unit: the linear unit of a
  /// projected, local or geocentric one) and vertical (io::crs_vertical_unit of a vertical CRS or
  /// a compound one's vertical part); "" when there is no CRS, no such part, or a unit whose size
  /// is no positive number.
  std::string horizontal_unit, vertical_unit;
  /// What a careful reader should know (a geographic CRS over coordinates that are not degrees,
  /// or a projected one over coordinates that look like degrees), one sentence each.
  std::vector<std::string> warnings;
  /// Set for an index file (.rsi); then info is mostly empty (info.scale and info.offset: the
  /// positions' LAS grid when they are stored on one; info.crs_source "index file" when it stores a
  /// CRS, whose EPSG codes, units and warnings are found as for a cloud's).
  std::optional<IndexFileSummary> index;
  std::optional<CopcInfo> copc;              ///< set for a COPC file: its octree (hierarchy)
};

/// The warnings `rayscan info` gives when a CRS cannot describe the coordinates it is attached to,
/// one sentence each ending "the file's CRS is probably wrong": a geographic CRS (degrees) over
/// coordinates beyond +-180 / +-90, a geocentric (ECEF) one over points that do not lie near the
/// Earth's surface, a projected one over coordinates that all lie within +-180 / +-90. `bounds`:
/// the points' bounds in the file's coordinates. None for an empty `crs_wkt` or a WKT GDAL cannot
/// read; never throws for those. Other jobs that copy a cloud's CRS into an output (a GeoTIFF) give
/// the same warnings.
std::vector<std::string> crs_warnings(const std::string& crs_wkt, const AABB& bounds);

/// Reads `file` (read_point_cloud with all scalars) and summarises it. Throws io::FormatError for a
/// malformed or unsupported file.
InfoJobResult run_info(const InfoJobOptions& options);

/// The report as JSON (pdal info style), 2-space indent.
std::string info_report_json(const InfoJobResult& result);

/// The report as aligned text lines.
std::string info_report_text(const InfoJobResult& result);

}  // namespace rayscan::jobs
