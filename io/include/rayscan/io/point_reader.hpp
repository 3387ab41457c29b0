// Chunked (streaming) point readers: open a file, read the next N points with a chosen set of
// attributes, close. Every format reader (LAS, PLY, PCD, text, f64, and LAZ/COPC) implements
// PointReader; read_point_cloud() is a loop over it, `rayscan info` and `rayscan index` stream
// through it so their memory stays bounded whatever the file size (PDAL "streaming mode").
#pragma once

#include "rayscan/io/file_info.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>

namespace rayscan::io {

/// Optional per-point attributes a reader can deliver besides positions (bit set). Positions are
/// always delivered.
enum class Attribute : std::uint32_t {
  rgb = 1u << 0,             ///< PointCloud::rgb (16 bit per channel, normalised as in formats.md)
  intensity = 1u << 1,       ///< PointCloud::intensity
  classification = 1u << 2,  ///< PointCloud::classification
  gps_time = 1u << 3,        ///< PointCloud::gps_time
  normals = 1u << 4,         ///< PointCloud::normals
  scalars = 1u << 5,         ///< PointCloud::scalars (every other named field, 8 bytes/point each)
  id = 1u << 6,              ///< the original point ids of an index file (`rayscan index --attributes id`;
                             ///< docs/index-format.md "Ids"); readers ignore it (a cloud's id is its order)
};

/// A set of Attribute values. Default: every attribute.
struct AttributeSet {
  std::uint32_t bits = 0x7F;
  /// No attribute: positions only.
  static constexpr AttributeSet none() { return AttributeSet{0}; }
  /// Every attribute.
  static constexpr AttributeSet all() { return AttributeSet{0x7F}; }
  [[nodiscard]] constexpr bool has(Attribute a) const { return (bits & static_cast<std::uint32_t>(a)) != 0; }
  constexpr AttributeSet& add(Attribute a) {
    bits |= static_cast<std::uint32_t>(a);
    return *this;
  }
  [[nodiscard]] constexpr AttributeSet operator&(AttributeSet o) const { return AttributeSet{bits & o.bits}; }
  friend constexpr bool operator==(AttributeSet, AttributeSet) = default;
  /// Parses a comma-separated list of "rgb", "intensity", "classification", "gps_time",
  /// "normals", "scalars", "id", "all", "none" (e.g. the `--attributes` option; "all" includes id). Throws
  /// std::invalid_argument naming an unknown word and the allowed ones.
  static AttributeSet parse(const std::string& list);
  /// The comma-separated names of the set ("rgb,intensity"; "" for none).
  [[nodiscard]] std::string to_string() const;
};

/// A chunked reader over one point cloud file, opened by open_point_reader().
///
/// Contract (every format):
///  - Header metadata is parsed and validated at open: info() and crs_wkt() are complete then,
///    except that info().notes and info().dropped_nonfinite may grow while reading.
///  - read(chunk, n) fills `chunk` with the next 1..n points in file order and returns how many;
///    0 means the end of the file. `chunk` is overwritten (vectors cleared, capacity reused);
///    chunk.positions always, each other attribute vector holds chunk.size() entries when the
///    attribute is in attributes() and empty otherwise. chunk.crs_wkt is left empty.
///  - Values are exactly those read_point_cloud() returns for the same file and options (it is a
///    loop over read()): in particular colour normalisation (8-bit values scaled by 257, all-zero
///    colour dropped) is decided for the whole file, never per chunk, and PLY/PCD/text scalars
///    promoted to intensity/classification/GPS time are promoted in every chunk or in none.
///  - Memory: a reader holds a bounded window of the file (memory-mapped pages already decoded are
///    released) plus its chunk; formats whose encoding forbids random access may hold more (see
///    the reader's own documentation; the PCD binary_compressed and ASCII PLY/PCD/text readers
///    currently decode the whole file at open and then hand it out in chunks).
///  - Errors: read() and open throw FormatError, one line naming the file and the byte offset or
///    line. After an exception the reader must not be used again.
///
/// LAZ/COPC go through the LAS reader (las_reader.cpp). A new format: derive from PointReader,
/// parse the header in the constructor, decode lazily in read(), add the extension to
/// format_from_extension() and a case in open_point_reader(). Not thread-safe; one per thread.
class PointReader {
 public:
  virtual ~PointReader() = default;
  PointReader() = default;
  PointReader(const PointReader&) = delete;
  PointReader& operator=(const PointReader&) = delete;

  /// Metadata of the file (format, version, header counts and bounds, scale/offset, CRS codes).
  [[nodiscard]] virtual const FileInfo& info() const = 0;
  /// Coordinate reference system as WKT, "" when unknown.
  [[nodiscard]] virtual const std::string& crs_wkt() const = 0;
  /// Number of points the reader will deliver, when known at open (LAS, binary PLY/PCD, f64, or a
  /// format decoded at open); otherwise the header's announcement (an upper bound: PCD drops
  /// non-finite points).
  [[nodiscard]] virtual std::uint64_t point_count() const = 0;
  /// The attributes chunks carry: the requested set intersected with what the file stores.
  [[nodiscard]] virtual AttributeSet attributes() const = 0;
  /// Reads the next up to `max_points` (>= 1) points into `chunk`; returns the number read, 0 at
  /// the end. Throws FormatError for malformed data.
  virtual std::size_t read(PointCloud& chunk, std::size_t max_points) = 0;
  /// For sources with an exact integer grid (LAS): the scale and offset such that every position
  /// delivered is exactly `int32 * scale + offset` computed in double; nullopt otherwise.
  [[nodiscard]] virtual std::optional<std::pair<Vec3, Vec3>> integer_grid() const { return std::nullopt; }
};

/// Opens `path` for chunked reading (format from format_from_extension()). `attributes` selects
/// what chunks carry (positions always); ReadOptions::scalars = false removes
/// Attribute::scalars. Throws FormatError (file cannot be opened, unknown extension, malformed
/// header).
std::unique_ptr<PointReader> open_point_reader(const std::filesystem::path& path,
                                               AttributeSet attributes = AttributeSet::all(),
                                               const ReadOptions& options = {});

/// Opens bytes already in memory (tests, the fuzzers). `bytes` must outlive the reader; `name` is
/// used in error messages. Same contract as the path overload.
std::unique_ptr<PointReader> open_point_reader(std::span<const std::uint8_t> bytes, Format format,
                                               const std::string& name,
                                               AttributeSet attributes = AttributeSet::all(),
                                               const ReadOptions& options = {});

/// Default chunk size of loops over a PointReader (points): 1 Mi points (24 MB of positions).
inline constexpr std::size_t kDefaultChunkPoints = std::size_t{1} << 20;

}  // namespace rayscan::io
