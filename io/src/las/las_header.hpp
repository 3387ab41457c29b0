// The LAS public header block, VLR and EVLR headers, parsed and bounds-checked once for every
// reader of the LAS family (the LAS reader, LAZ decoding, COPC, translate, read_las_records).
// ASPRS LAS Specification 1.4 R15: header section 2.4 (table 3), VLRs 2.5, EVLRs 2.7.
#pragma once

#include "readers.hpp"
#include "rayscan/io/file_info.hpp"
#include "rayscan/octree/position_view.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace rayscan::io::detail {

/// The Extra Bytes names (section 2.5.6) of PointCloud::normals' x, y, z: PDAL's dimension names
/// (pdal/Dimension.json), which its writers.las writes with extra_dims=all. write_las writes
/// normals under them and the LAS reader reads the three back into PointCloud::normals.
inline constexpr const char* kLasNormalNames[3] = {"NormalX", "NormalY", "NormalZ"};

/// Byte length of the fields point data record format `f` defines (section 2.6, tables 7-17);
/// -1 outside 0..10.
int pdrf_length(int f);

/// What the LAS-family code needs of a file's header (section 2.4) and its (E)VLR headers.
/// Offsets are bytes from the start of the file; counts as stored (64-bit count for LAS 1.4).
struct LasHeader {
  int version_minor = 0;         ///< 0..4 (the major version is checked to be 1)
  std::uint16_t global_encoding = 0;
  std::array<std::uint8_t, 16> project_guid{};  ///< Project ID (GUID) bytes 8-23 as stored
  std::uint64_t waveform_start = 0;  ///< start of waveform data packet record (LAS 1.3+, byte 227)
  std::string system_id, software;
  std::uint16_t creation_day = 0, creation_year = 0;
  std::uint16_t header_size = 0;  ///< public header block size (>= 227/235/375 by version)
  std::uint64_t point_offset = 0; ///< offset to point data, in [header_size, file size]
  std::uint8_t pdrf_raw = 0;      ///< the PDRF byte as stored (bits 6-7: LAZ compression)
  int pdrf = 0;                   ///< point data record format 0..10
  std::uint16_t record_length = 0;///< >= pdrf_length(pdrf)
  std::uint64_t count = 0;        ///< point count (legacy 32-bit, or the 1.4 64-bit one when set)
  Vec3 scale{1.0}, offset{0.0};   ///< finite, scale non-zero, |offset| <= kMaxCoordinate
  AABB header_bounds;             ///< max/min x, y, z as stored (never trusted)
  std::uint64_t data_end = 0;     ///< end of the point data: the EVLR start, else the file size
  std::vector<VlrInfo> vlrs;      ///< VLRs in file order, then EVLRs (payload at offset + 54 / + 60)
  /// Payload position and length of an (E)VLR the readers use; present = false when absent.
  struct Found {
    std::uint64_t at = 0, len = 0;
    bool present = false;
  };
  Found laszip;          ///< "laszip encoded" 22204 (a VLR; its presence makes the file LAZ)
  Found copc_info;       ///< "copc" 1 (COPC 1.0 info VLR)
  Found copc_hierarchy;  ///< "copc" 1000 (COPC 1.0 hierarchy EVLR)
  Found wkt;             ///< "LASF_Projection" 2112 (OGC WKT, section 2.5.1)
  Found geokeys;         ///< "LASF_Projection" 34735 (GeoKeyDirectoryTag, section 2.5.2)
  Found geodoubles;      ///< "LASF_Projection" 34736 (GeoDoubleParamsTag: the double-valued GeoKeys)
  Found extra_bytes;     ///< "LASF_Spec" 4 (Extra Bytes descriptors, section 2.5.6), the last one
  /// Every Extra Bytes VLR/EVLR in file order (a file may split its descriptors over several).
  std::vector<Found> extra_bytes_all;
  std::vector<std::string> notes;  ///< tolerated oddities (e.g. LASzip VLR without compression bits)
};

/// Parses the public header and walks the VLR and EVLR headers of `in` without reading past it.
/// Throws FormatError "file: byte N: what was expected" on a bad signature or version, a header
/// smaller than its version requires, a point offset outside [header size, file size], an (E)VLR
/// running past its region, a waveform data packet record stored in the file (LAS 1.3+, global
/// encoding bit 1; not one of the EVLRs) starting before the point data or running past the end
/// of the file, the compression bits set without a LASzip VLR, a PDRF outside 0..10,
/// a record length shorter than the PDRF's fields, a non-finite/zero scale, or an offset that is
/// not finite or beyond +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp). The point count is
/// not checked against the file size here (LAZ bounds it by its chunk table).
LasHeader parse_las_header(const Input& in);

/// The text of the OGC WKT (E)VLR `h.wkt` (section 2.5.1) of the file `d` points at, without the
/// trailing NULs and white space writers pad it with; "" when there is none. The one reading of
/// that record: the LAS reader takes it for the CRS when it holds WKT, translate_las warns when
/// it copies one that GDAL cannot read.
[[nodiscard]] std::string wkt_vlr_text(const std::uint8_t* d, const LasHeader& h);

/// "<name>: the OGC WKT VLR holds no CRS that GDAL reads ('<crs_excerpt(wkt)>')": how a warning
/// names the file `name` whose WKT record `wkt` (wkt_vlr_text) GDAL cannot read, followed by what
/// was done about it (the LAS reader took the GeoKeys, translate_las copied it unchanged).
[[nodiscard]] std::string unreadable_wkt_vlr(const std::string& name, const std::string& wkt);

/// How a LAS point record gives a coordinate, as the refusals of one beyond +-kMaxCoordinate name
/// it (beyond_coordinate_bound's `source`; the reader's refuse_las_coordinate, the writer's own):
/// "stored integer I x scale S + offset O".
[[nodiscard]] std::string las_coordinate_source(std::int32_t stored, double scale, double offset);

/// The refusal of a point record whose coordinates decode beyond +-kMaxCoordinate, shared by the
/// LAS/LAZ reader and COPC queried in place so that both name a point alike. `r` is the record
/// (X, Y, Z int32 at bytes 0, 4, 8, as in every PDRF), `index` the point's 0-based number in file
/// order, `byte` where the file holds it (the record, or the compressed chunk holding it).
/// Throws FormatError "file: byte B: point N: X coordinate is V (stored integer I x scale S +
/// offset O; expected within +-1e+09, the coordinate bound in world units)" for the first axis
/// beyond the bound ("overflows to infinity" for V).
[[noreturn]] void refuse_las_coordinate(const std::string& name, std::uint64_t byte, std::uint64_t index,
                                        const std::uint8_t* r, const Vec3& scale, const Vec3& offset);

/// X, Y, Z of the point record `r` (int32 at bytes 0, 4, 8, as in every PDRF) in world units:
/// las_coordinate with `scale` and `offset`, the LAS reader's own expression. A point beyond
/// +-kMaxCoordinate is refused by refuse_las_coordinate(name, byte, index, r, scale, offset)
/// (FormatError). Inline and allocation-free: COPC's node decode and translate call it for every
/// record; `name` is only read on the refusal.
[[nodiscard]] inline Vec3 checked_las_position(const std::string& name, std::uint64_t byte, std::uint64_t index,
                                               const std::uint8_t* r, const Vec3& scale, const Vec3& offset) {
  const double x = las_coordinate(load_le<std::int32_t>(r), scale.x, offset.x);
  const double y = las_coordinate(load_le<std::int32_t>(r + 4), scale.y, offset.y);
  const double z = las_coordinate(load_le<std::int32_t>(r + 8), scale.z, offset.z);
  if (!within_coordinate_bound(x, y, z)) refuse_las_coordinate(name, byte, index, r, scale, offset);
  return Vec3(x, y, z);
}

}  // namespace rayscan::io::detail
