// Internal: the steps of write_copc() (rayscan/site/copc_writer.hpp): the input's records in a
// COPC point format (copc_records.cpp), the octree that distributes them over nodes
// (copc_tree.cpp), and the file assembly (copc_writer.cpp).
#pragma once

#include "readers.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/octree/geometry.hpp"
#include "rayscan/site/copc_writer.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::io::copc {

/// One (E)VLR carried over from the input: header fields and payload.
struct CarriedVlr {
  std::string user;
  std::uint16_t record = 0;
  std::string description;
  std::vector<std::uint8_t> payload;
};

/// The mapped file the records are read from: the input itself (an uncompressed LAS of PDRF
/// 6-8), or a temporary file of converted records (IntermediateFile: its errors name the COPC
/// output; removed when this is destroyed, after the mapping, and by a signal). Not copyable.
struct RecordFile {
  std::optional<IntermediateFile> temp;  ///< the converted records' file; declared first: removed last
  std::unique_ptr<detail::MappedFile> map;
};

/// The input as PDRF 6, 7 or 8 records (plus extra bytes) and the header fields a COPC file
/// keeps from it. The records stay on disk (mapped): the build keeps 12 bytes per point in
/// memory, whatever the record length.
struct Records {
  int pdrf = 6;                     ///< 6, 7 or 8
  std::uint16_t record_length = 0;  ///< PDRF length + extra bytes
  std::uint64_t count = 0;
  /// Point data offset and record length of the LAS/LAZ file the records were read from (for
  /// another format, of the LAS it was converted to): the byte the LAS reader names for a record.
  std::uint64_t in_point_offset = 0;
  std::uint16_t in_record_length = 0;
  const std::uint8_t* bytes = nullptr;  ///< count * record_length, inside `file`'s mapping
  std::shared_ptr<RecordFile> file;
  Vec3 scale{0.01}, offset{0.0};
  std::uint16_t file_source_id = 0;
  std::uint16_t global_encoding = 0;  ///< bit 0 (GPS time type) kept from the input; bit 4 set with a WKT
  std::uint8_t guid[16] = {};
  std::uint16_t creation_day = 0, creation_year = 0;
  std::string crs_wkt;              ///< OGC WKT of the input's CRS ("" when none)
  std::vector<CarriedVlr> vlrs;     ///< input VLRs kept (not LASzip, COPC or CRS ones)
  std::vector<CarriedVlr> evlrs;    ///< input EVLRs kept (not COPC or CRS ones)
  std::uint64_t in_bytes = 0;
  std::vector<std::string> notes;
  std::vector<std::string> warnings;  ///< CopcWriteResult::warnings
};

/// Opens `in` as Records (see write_copc() for the conversions): an uncompressed PDRF 6-8 LAS is
/// mapped as it is; LAZ (decoded in parallel by batches of chunks), PDRF 0-3 (converted) and
/// other formats (through write_las) are written to a temporary uncompressed file in
/// `options.temp_dir` first. Throws CopcMemoryError when the build's 12 bytes per point exceed
/// `memory_bytes` (checked from the header before the points are read), FormatError,
/// std::invalid_argument as write_copc(); a failed write of the temporary file is an
/// OutputFileError naming `out`, the COPC output it is written for.
Records read_records(const std::filesystem::path& in, const std::filesystem::path& out, const CopcWriteOptions& options);

/// The COPC root cube (COPC 1.0 "Info VLR": center and halfsize) in file units.
struct Cube {
  Vec3 center{0.0};
  double halfsize = 0;
  [[nodiscard]] Vec3 lo() const { return center - Vec3(halfsize); }
};

/// A point in the build: its Morton code in the root cube and its record index (12 bytes: the
/// build's whole memory per point).
#pragma pack(push, 1)
struct Slot {
  std::uint64_t key;
  std::uint32_t index;
};
#pragma pack(pop)
static_assert(sizeof(Slot) == 12);

/// One octree node: VoxelKey, and its points as the range [begin, begin + count) of
/// Tree::slots (within the node in the build's own deterministic order; the writer orders the
/// records it compresses).
struct Node {
  std::int32_t level = 0, x = 0, y = 0, z = 0;
  std::uint64_t begin = 0;
  std::uint32_t count = 0;
};

/// Whole-file statistics of the records that the LAS 1.4 header (section 2.4: bounds, points by
/// return) and the COPC info VLR (GPS time range) need.
struct RecordStats {
  std::int32_t lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX};  ///< least integer X, Y, Z
  std::int32_t hi[3] = {INT32_MIN, INT32_MIN, INT32_MIN};  ///< largest integer X, Y, Z
  double gps_min = 0, gps_max = 0;    ///< GPS time range, NaN times left out (0, 0: none)
  std::uint64_t by_return[15] = {};   ///< points with return number 1 to 15
};

/// RecordStats of `r` (PDRF 6-8 layout: X, Y, Z at bytes 0-11, the return number in the low 4
/// bits of byte 14, GPS time at byte 22), in one parallel pass (TBB).
RecordStats record_stats(const Records& r);

/// The distributed points: nodes in depth-first pre-order (children in Morton digit order),
/// each with at least one point.
struct Tree {
  RecordStats stats;  ///< of all the records (its bounds give the cube)
  Cube cube;
  std::vector<Node> nodes;
  std::vector<Slot> slots;  ///< the points, grouped by node (nodes' ranges)
};

/// Bytes per point the build keeps in memory (CopcWriteOptions::memory_bytes).
inline constexpr std::uint64_t kBytesPerPoint = sizeof(Slot);
/// Bytes besides: the decode and compression batches (a bound, for the memory check).
inline constexpr std::uint64_t kBatchBytes = std::uint64_t{256} << 20;

/// Cube of `r`'s points and their distribution over the octree (write_copc()'s rule: a node
/// above `leaf_points` keeps the point nearest each cell centre of its kCopcGridCells^3 grid).
Tree build_tree(const Records& r, const CopcWriteOptions& options);

}  // namespace rayscan::io::copc
