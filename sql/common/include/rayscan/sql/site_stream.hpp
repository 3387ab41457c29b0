// The points of a site being imported, streamed chunk by chunk in Morton order (so an import works
// for clouds larger than RAM). Both engines' importers write what this hands out, so the SQLite
// and PostgreSQL layouts are the same rows in the same order.
#pragma once

#include "rayscan/octree/geometry.hpp"
#include "rayscan/sql/chunking.hpp"
#include "rayscan/sql/import.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace rayscan::sql {

/// One extra column of the points table: its SQL name and type.
struct ColumnInfo {
  std::string name;  ///< an SQL identifier ("intensity", "red", ...)
  bool integer;      ///< INTEGER / bigint (true) or REAL / float8
};

/// The rows of one chunk, in Morton order: row r of the chunk is row `first_row + r` of the site.
struct ChunkRows {
  std::uint64_t chunk = 0;         ///< chunk id, 0-based
  std::uint64_t first_row = 0;     ///< 0-based row of the chunk's first point in the site
  AABB box;                        ///< exact bounds of `positions`
  std::vector<Vec3> positions;     ///< the reader's exact doubles (world units)
  std::vector<PointRef> refs;      ///< source file and index there, per row
  /// Extra column values, column-major: values[c * size() + r] (integers are exact in a double).
  std::vector<double> values;
  [[nodiscard]] std::size_t size() const { return positions.size(); }
};

/// A site opened for import: metadata first, then the chunks in order through next().
/// Implementations: the index file (default; bounded memory) and the clouds read whole (only when
/// a requested attribute is a scalar field the index file does not store).
class SiteStream {
 public:
  virtual ~SiteStream() = default;
  /// The site's input files, the rows of the `sources` table: element i is the source that
  /// PointRef::source == i names. Point cloud inputs come in the order given and are named as
  /// given; one `.rsi` input gives the sources its build recorded (paths as stored in the file).
  /// `points` is what each contributed (they sum to total_points()); `crs_wkt` is the index's CRS,
  /// which every input shares, except for clouds read whole, where it is each file's own ("" when
  /// unknown). Fixed at open, valid as long as the stream.
  [[nodiscard]] virtual const std::vector<SourceRow>& sources() const = 0;
  /// The extra columns of the points table, in the order of ImportOptions::attributes, which is
  /// also the order of ChunkRows::values: "rgb" gives three integer columns "red", "green",
  /// "blue"; intensity and classification are integer columns; gps_time and a cloud's scalar
  /// field are REAL / float8. Empty when no attribute was asked for. Fixed at open.
  [[nodiscard]] virtual const std::vector<ColumnInfo>& columns() const = 0;
  /// Fills `out` with the next chunk (vectors reused); false after the last one. Throws
  /// io::IndexError for an id outside the index's sources (a corrupted, unverified file).
  virtual bool next(ChunkRows& out) = 0;
};

/// The points of a site: the sum of its sources' counts.
[[nodiscard]] inline std::uint64_t total_points(const SiteStream& site) {
  std::uint64_t n = 0;
  for (const SourceRow& r : site.sources()) n += r.points;
  return n;
}

/// Opens `paths` for import with `options` (chunk size, attributes, memory, temp_dir):
///  - one `.rsi` index file: its points in storage order (the index's Morton order), chunked;
///    attributes must be stored in it (else std::invalid_argument naming the file); each row's
///    point number is its original number in its source when the index stores ids, else
///    (built without `--attributes id`) its slot in the index (index order);
///  - point cloud files: a temporary index file (with ids) is built with io::build_index_file (external
///    Morton sort within options.memory_bytes, in options.temp_dir), streamed as above and removed
///    when the stream is destroyed; peak memory stays within the budget whatever the site's size;
///  - when an attribute is not one of intensity, classification, gps_time, rgb (a scalar field
///    such as a LAS extra-bytes dimension, which index files do not store): the clouds are read
///    whole and ordered by make_chunk_layout (memory grows with the site).
/// Throws io::FormatError (unreadable input), io::IndexError (inputs disagree on CRS, corrupted
/// index), std::invalid_argument (bad option; "<file>: attribute 'gps_time' requested but the file
/// has none"), std::runtime_error (I/O, e.g. disk full while writing the temporary index: an
/// OutputFileError naming `output`, the file the import writes, or the temporary index itself
/// when `output` is empty, as for PostgreSQL).
[[nodiscard]] std::unique_ptr<SiteStream> open_site(const std::vector<std::filesystem::path>& paths,
                                                    const ImportOptions& options,
                                                    const std::filesystem::path& output = {});

}  // namespace rayscan::sql
