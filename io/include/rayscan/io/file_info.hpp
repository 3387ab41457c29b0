// What a reader learned about a file besides the points: the metadata `rayscan info` prints.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::io {

/// One LAS variable-length record (VLR, ASPRS LAS 1.4 R15 section 2.5) or extended VLR
/// (EVLR, section 2.7) as listed by `rayscan info`.
struct VlrInfo {
  std::string user_id;        ///< 16-character user id, e.g. "LASF_Projection"
  std::uint16_t record_id = 0;
  std::string description;    ///< 32-character description
  std::uint64_t length = 0;   ///< payload bytes after the VLR header
  std::uint64_t offset = 0;   ///< byte offset of the VLR header in the file
  bool extended = false;      ///< true for an EVLR (after the point records)
};

/// What an Extra Bytes descriptor (LAS 1.4 R15 section 2.5.6, table 24) says of one field besides
/// its name and type, for readers such as PDAL, QGIS and CloudCompare to show.
struct ExtraBytesInfo {
  /// The descriptor's description: the field's meaning and unit, e.g. "global irradiation, kWh/m2";
  /// at most 32 bytes are stored (a longer text is cut).
  std::string description;
  /// The value that means "no value" for this field (descriptor options bit 0 and its no_data
  /// field), e.g. -1 for a distance to an observer that sees nothing; none when every value is one.
  std::optional<double> no_data;
};

/// Metadata of a point cloud file, filled by read_point_cloud() when asked for. Fields that do not
/// apply to a format keep their default (empty string, nullopt, -1 or 0).
struct FileInfo {
  std::string format;    ///< "LAS", "PLY", "PCD", "text" or "f64"
  std::string version;   ///< "1.4" (LAS), "1.0" (PLY), "0.7" (PCD); "" when the format has none
  std::string encoding;  ///< PLY: ascii | binary_little_endian | binary_big_endian;
                         ///< PCD: ascii | binary | binary_compressed
  int point_format = -1;          ///< LAS point data record format (PDRF) 0..10
  int record_length = 0;          ///< LAS point record length in bytes (from the header)
  int extra_bytes_per_point = 0;  ///< LAS bytes per record beyond the PDRF's own fields
  std::uint64_t header_point_count = 0;  ///< number of points the header announces
  std::uint64_t dropped_nonfinite = 0;   ///< NaN/inf points skipped (PCD organized clouds)
  std::optional<AABB> header_bounds;     ///< bounding box stored in the header (never trusted)
  std::optional<Vec3> scale, offset;     ///< LAS scale factors and offsets (x, y, z)
  int epsg = 0;           ///< horizontal (or compound) EPSG code from the GeoKeys, 0 when unknown
  int vertical_epsg = 0;  ///< vertical EPSG code from the GeoKeys, 0 when absent
  std::string crs_source;  ///< "WKT VLR", "GeoKeys", "" when the file has no usable CRS
  /// LAS: the one warning about the file's CRS records, naming the file, also among the notes: its
  /// OGC WKT VLR holds no CRS GDAL reads, so the CRS is taken from its GeoKeys; "" when none.
  std::string crs_warning;
  std::string system_id, software;  ///< LAS system identifier and generating software
  std::uint16_t creation_year = 0, creation_day = 0;  ///< LAS file creation year / day of year
  std::uint16_t global_encoding = 0;                  ///< LAS global encoding bits
  std::array<std::uint8_t, 16> project_guid{};        ///< LAS Project ID (GUID), header bytes 8-23 as stored
  std::vector<VlrInfo> vlrs;                          ///< LAS VLRs then EVLRs in file order
  /// LAS: the Extra Bytes descriptions of the scalars read (by PointCloud::ScalarField name: a
  /// deprecated array's name[0], name[1], ... each its descriptor's), the descriptors whose
  /// description is not empty; the no_data value is not read (docs/formats.md). las_grid_of
  /// passes them on, so a derived LAS, PLY or PCD file describes those fields as the source did.
  std::map<std::string, ExtraBytesInfo> extra_bytes;
  std::uint64_t width = 0, height = 0;  ///< PCD WIDTH/HEIGHT (organized when height > 1)
  /// PCD VIEWPOINT tx ty tz qw qx qy qz: the acquisition pose. Reported, not applied to positions.
  std::optional<std::array<double, 7>> viewpoint;
  std::vector<std::string> comments;  ///< PLY comment/obj_info lines, PCD comment lines
  /// Source fields in file order with their storage type ("x:F4", "red:uchar", "classification").
  std::vector<std::string> fields;
  /// Decisions the reader took that a user should know ("RGB stored as 8 bit in 16-bit fields:
  /// scaled by 257", "RGB fields all zero: colour dropped").
  std::vector<std::string> notes;
};

}  // namespace rayscan::io
