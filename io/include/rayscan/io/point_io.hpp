// Reading and writing point cloud files: the single entry point the tools use. Each format reader
// follows its published specification (docs/formats.md lists the versions and sections).
#pragma once

#include "rayscan/io/file_info.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

namespace rayscan::io {

/// A malformed, unsupported or unreadable input file. what() is one line naming the file, the
/// byte offset or line, and what was expected:
/// "cloud.las: byte 96: point data offset 9000 past end of file (size 8000)".
struct FormatError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// File formats rayscan reads.
enum class Format { las, ply, pcd, text, f64 };

/// What a reader keeps besides positions.
struct ReadOptions {
  /// Keep attributes that have no dedicated PointCloud field as named ScalarFields (8 bytes per
  /// point each): LAS return_number, number_of_returns, classification_flags, scanner_channel,
  /// scan_direction_flag, edge_of_flight_line, scan_angle (degrees), user_data,
  /// point_source_id, nir and Extra Bytes fields; PLY/PCD properties such as "confidence".
  /// Turn off for very large clouds when only positions, colour, intensity, classification,
  /// GPS time and normals are needed.
  bool scalars = true;
  /// LAS/LAZ: deliver the colour fields as stored, skipping the whole-file 8-bit decision of
  /// docs/formats.md (no colour pass over the file at open, no x 257 scaling, an all-zero colour
  /// kept). For a caller that makes that decision itself from the values it reads (the index
  /// build); other formats ignore it.
  bool stored_colour = false;
  /// Uncompressed LAS from a file: read the point records with O_DIRECT into the reader's own
  /// two buffers (the next block read in the background while one is decoded) instead of through
  /// the page cache. For one sequential pass over files larger than memory (the index build,
  /// bench/notes/); the file system must allow O_DIRECT, else the map
  /// is used as usual. Other formats ignore it.
  bool direct_records = false;
};

/// The format of `path` from its extension (case-insensitive): .las .laz .copc → las; .ply;
/// .pcd; .xyz .csv .txt .pts → text; .f64 (headerless little-endian float64 x,y,z triples).
/// Throws FormatError for any other extension.
Format format_from_extension(const std::filesystem::path& path);

/// Reads any supported point cloud file (format from format_from_extension). The file is memory
/// mapped; pages already decoded are released while reading, so peak memory is the output
/// arrays plus a bounded window. Fills `info` when non-null. Positions are finite doubles in the
/// file's own world frame and units; the cloud satisfies PointCloud::validate().
/// Throws FormatError (one line: file, byte offset or line, what was expected) for unreadable,
/// malformed or unsupported (LAZ/COPC) files, and (LAS, LAZ, PCD, text, .f64) for a point with a
/// coordinate beyond +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp).
PointCloud read_point_cloud(const std::filesystem::path& path, const ReadOptions& options = {},
                            FileInfo* info = nullptr);

/// Reads a point cloud from bytes already in memory (the libFuzzer entry point). `name` is used
/// in error messages. Same contract as read_point_cloud().
PointCloud read_point_cloud(std::span<const std::uint8_t> bytes, Format format,
                            const std::string& name, const ReadOptions& options = {},
                            FileInfo* info = nullptr);

/// Options of write_las().
struct LasWriteOptions {
  /// LAS scale factors (x, y, z); 0 = choose: the coarsest of 1, 0.1, 0.01, 0.001 on which every
  /// coordinate of the axis reads back bit for bit (a cloud that came from LAS through PLY or PCD
  /// is written back exactly), failing that the coarsest on which every coordinate lies to within
  /// the rounding of decimal text (a cloud that came from LAS through write_text's decimals gets
  /// its integers back), else 0.001 (millimetre in metre units), coarsened by powers of ten until
  /// the cloud's extent fits 32-bit integers. For the longitude and latitude of a geographic CRS
  /// (PointCloud::crs_wkt; degrees) the same down to 1e-7 degrees (about 1 cm), not 0.001 (about
  /// 100 m); in another angular unit the power of ten within 1e-7 degrees (radians: 1e-9).
  Vec3 scale{0.0};
  /// LAS offsets; used only when `has_offset`, otherwise the bounding box minimum rounded down
  /// to a whole multiple of 1000 * scale (towards zero where that would leave kMaxCoordinate).
  Vec3 offset{0.0};
  bool has_offset = false;
  std::string system_id = "rayscan";  ///< header System Identifier (max 32 characters)
  /// Global encoding bit 0, the meaning of the GPS time field (LAS 1.4 R15 table 4): true =
  /// Adjusted Standard GPS Time (GPS seconds - 1e9), false = GPS Week Time (seconds of the week).
  /// A derived file takes it from its LAS source (las_grid_of) so its GPS times keep their meaning.
  bool adjusted_standard_gps_time = false;
  /// Header Project ID (GUID), bytes 8-23 as the source stored them; zeros when there is none.
  std::array<std::uint8_t, 16> project_guid{};
  /// Extra Bytes descriptions by ScalarField name (a field not named here is described as
  /// "rayscan per-point scalar", without a no-data value).
  std::map<std::string, ExtraBytesInfo> extra_bytes;
};

/// Writes `cloud` as ASPRS LAS 1.4 R15: point data record format 6 (7 with rgb, 8 with rgb and a
/// scalar called "nir"). Scalars named return_number, number_of_returns, classification_flags,
/// scanner_channel, scan_direction_flag, edge_of_flight_line, scan_angle (degrees), user_data,
/// point_source_id go to their standard fields; colour read from 8-bit values of a LAS or text file
/// (PointCloud::rgb_from_8bit_las) is written back as those values; normals become the float64
/// extra bytes NormalX, NormalY, NormalZ (PDAL's names; the reader maps them back to normals);
/// every other ScalarField becomes a float64 extra byte described in an Extra Bytes VLR (section
/// 2.5.6), a name longer than the descriptor's 32 bytes or already used ending in "~1", "~2", ...
/// so that every field stays distinct; crs_wkt becomes an OGC WKT VLR (2112). The header's GPS
/// time type bit and project GUID come from `options` (las_grid_of: the source's). Positions are quantised to the scale: a point read from LAS and written back with
/// the same scale and offset is bit-exact. Written to "<dir>/.<name>.tmp.<pid>" (rayscan::AtomicFile) and renamed into place.
/// A path ending in .laz (case-insensitive) is written as LAZ: the same records compressed by
/// translate_las (LASzip layered-chunked compressor, item version 3; docs/formats.md "LAZ" 5).
/// Throws std::invalid_argument, before the file is created, for a cloud failing validate() or
/// holding a position beyond +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp, the readers'
/// bound), an offset beyond that bound, or coordinates that do not fit the 32-bit integer grid
/// or read back from it beyond the bound; std::runtime_error for I/O failures (no partial file
/// is left).
void write_las(const std::filesystem::path& path, const PointCloud& cloud,
               const LasWriteOptions& options = {});

/// Writes `cloud` as PLY 1.0 binary_little_endian, one "vertex" element: double x y z, then
/// float nx ny nz, uchar red green blue (16-bit colour rounded to 8 bit), float
/// scalar_intensity, uchar scalar_classification, double scalar_gps_time, and one double
/// property "scalar_<name>" per ScalarField (characters other than [A-Za-z0-9_] replaced by '_').
/// The names and types are the ones CloudCompare (scalar_ prefix) and Open3D (uchar, float,
/// double) both load (docs/formats.md, "PLY property names"); read_point_cloud strips the prefix
/// again. Each ScalarField named in `descriptions` (the LAS writer's Extra Bytes descriptions,
/// LasWriteOptions::extra_bytes) gets a header line "comment field scalar_<name>: <description>"
/// (and "; no data <value>" when it declares one), so a unit travels with the file; readers skip
/// comments (read_point_cloud keeps them in FileInfo::comments). Written via temp file + rename.
/// Throws std::invalid_argument for a cloud failing validate() or holding a position beyond
/// +-kMaxCoordinate (nothing is written), std::runtime_error on I/O failure.
void write_ply(const std::filesystem::path& path, const PointCloud& cloud,
               const std::map<std::string, ExtraBytesInfo>& descriptions = {});

/// Writes `cloud` as PCD v0.7 (PCL's format), DATA binary, unorganised (WIDTH = points, HEIGHT
/// 1, VIEWPOINT: the cloud's viewpoint, a PCD source's, else the identity): FIELDS x y z (F 4
/// when every coordinate is a float exactly, as PCL's point types and Open3D's legacy reader
/// need; else F 8, so georeferenced coordinates survive: PCL's PCLPointCloud2 and Open3D's tensor
/// reader read it), then normal_x normal_y normal_z (F 4), rgb (PCL's packed 0x00RRGGBB in a
/// 4-byte float field, 16-bit colour rounded to 8 bit), intensity (F 4), classification (U 1),
/// gps_time (F 8) and one F 8 field per ScalarField (name sanitised to [A-Za-z0-9_], made
/// unique). Each ScalarField named in `descriptions` (as for write_ply) gets a comment line
/// "# field <name>: <description>" after the first line, before VERSION. PCD has no CRS: a
/// cloud's crs_wkt is not written. Written via temp file + rename.
/// Throws std::invalid_argument for a cloud failing validate() or holding a position beyond
/// +-kMaxCoordinate (nothing is written), std::runtime_error on I/O failure.
void write_pcd(const std::filesystem::path& path, const PointCloud& cloud,
               const std::map<std::string, ExtraBytesInfo>& descriptions = {});

/// Writes `cloud` as text: a header line naming the columns (x y z, red green blue, nx ny nz,
/// intensity, classification, gps_time, then the scalars' sanitised names),
/// then one point per line; separated by ',' for a .csv name, else by a space (.xyz, .txt).
/// Coordinates of an axis that all lie exactly on the LAS grid of `grid` (its scale and offset,
/// when has_offset: las_grid_of the source) are printed with the grid's decimals, as las2txt does
/// (scale 0.01: 849087.70, not the reader's double 849087.7000000001; a scale of 0.00025: 5
/// decimals; the offset's decimals when it has more); each other value is the shortest decimal
/// that reads back as the same double, so read_point_cloud returns it bit for bit, and write_las
/// stores grid coordinates on the same integers again. Colour as the source held it: 16-bit values, or, for colour read
/// from 8-bit values (PointCloud::rgb_from_8bit_las: a LAS file's or a text file's), those 8-bit
/// values, which read_point_cloud scales by 257 again (docs/formats.md). No CRS. Written via temp
/// file + rename. Throws
/// std::invalid_argument for a cloud failing validate() or holding a position beyond
/// +-kMaxCoordinate (nothing is written), std::runtime_error on I/O failure.
void write_text(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& grid = {});

/// The extensions write_point_cloud() writes, lower case with the dot: ".las", ".laz", ".ply",
/// ".pcd", ".xyz", ".csv", ".txt".
[[nodiscard]] const std::vector<std::string>& point_cloud_output_extensions();

/// True when `path`'s file name ends in ".copc.laz" (ASCII case-insensitive, with a stem before
/// it): the one rule by which an output is meant to be COPC (rayscan/site/copc_writer.hpp).
[[nodiscard]] bool is_copc_output(const std::filesystem::path& path);

/// Why write_point_cloud() cannot write `path`, or "" when it can: "expected a file name ending
/// in .las, .laz, .ply, ..." for another extension, and a refusal for a COPC name
/// (is_copc_output: COPC is built from a file by `rayscan translate` and `rayscan index`, not from
/// an in-memory cloud; a plain LAZ under that name would claim an octree it does not have). The
/// one rule of require_point_cloud_output() and the jobs' option checks.
[[nodiscard]] std::string point_cloud_output_problem(const std::filesystem::path& path);

/// Throws std::invalid_argument "<path>: <point_cloud_output_problem(path)>" unless
/// write_point_cloud() can write `path`. For checking a job's output before its work.
void require_point_cloud_output(const std::filesystem::path& path);

/// The LAS write options that keep the integer grid (scale and offset) of the LAS, LAZ or COPC
/// source that `source` describes, so that its points written back as LAS/LAZ are bit-exact, and
/// its header's GPS time type (global encoding bit 0) and project GUID, so that a derived file's
/// GPS times keep their meaning, and its Extra Bytes descriptions (FileInfo::extra_bytes), so
/// that a derived LAS, PLY or PCD file describes the source's fields as the source did; the
/// defaults (scale chosen from the points, GPS week time, zero GUID, no descriptions) for any
/// other source.
[[nodiscard]] LasWriteOptions las_grid_of(const FileInfo& source);

/// Writes `cloud` in the format its extension names (case-insensitive; the one writer choice of
/// every job): .las and .laz with write_las (`las`: scale and offset), .ply with write_ply, .pcd
/// with write_pcd (both describing the fields of `las.extra_bytes` in header comments), .xyz /
/// .csv / .txt with write_text (`las`: the grid whose decimals it prints; the one header line
/// names the columns only, so the descriptions are not written).
/// Throws what require_point_cloud_output() throws before writing anything, else what the
/// writer throws.
void write_point_cloud(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& las = {});

}  // namespace rayscan::io
