// Internal: LAZ (LASzip-compressed LAS) container: the LASzip VLR, the chunk table and a decoder
// that turns the compressed chunks back into the LAS point records they came from, byte for
// byte. Format reference (read, not copied): LASzip src/laszip.cpp (VLR layout, item types),
// src/lasreadpoint.cpp (setup: compressor 1 has no chunks; read_chunk_table, chunk start, layered
// chunk header);
// laz-perf cpp/lazperf/vlr.cpp, readers.cpp. docs/formats.md "LAZ".
#pragma once

#include "bytes.hpp"
#include "readers.hpp"
#include "laz/items_v1.hpp"
#include "laz/items_v3.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace rayscan::io::laz {

using detail::Input;

/// LASzip item types (laszip.hpp LASitem::Type).
enum ItemType : std::uint16_t {
  kByte = 0, kPoint10 = 6, kGpsTime11 = 7, kRgb12 = 8, kWavePacket13 = 9,
  kPoint14 = 10, kRgb14 = 11, kRgbNir14 = 12, kWavePacket14 = 13, kByte14 = 14,
};

/// One entry of the LASzip VLR item list: type, size in bytes, compression version.
struct Item {
  std::uint16_t type = 0, size = 0, version = 0;
};

/// The LASzip VLR (user id "laszip encoded", record 22204): 34 bytes then 6 per item.
struct LaszipVlr {
  std::uint16_t compressor = 0;  ///< 0 none, 1 pointwise, 2 pointwise-chunked, 3 layered-chunked
  std::uint16_t coder = 0;       ///< 0 arithmetic
  std::uint8_t version_major = 0, version_minor = 0;
  std::uint16_t revision = 0;
  std::uint32_t options = 0;
  std::uint32_t chunk_size = 0;  ///< points per chunk; 0xFFFFFFFF (or 0) = variable; unused by compressor 1
  std::int64_t special_evlrs = -1, special_evlr_offset = -1;
  std::vector<Item> items;

  /// Chunk point counts come from the chunk table: LASreadPoint::setup (lasreadpoint.cpp) leaves
  /// its chunk size "variable" (U32_MAX) when the VLR stores 0xFFFFFFFF or 0.
  [[nodiscard]] bool variable_chunks() const {
    return compressor != 1 && (chunk_size == 0xFFFFFFFFu || chunk_size == 0);
  }
  [[nodiscard]] bool layered() const { return compressor == 3; }
  /// Sum of the item sizes (must equal the LAS record length).
  [[nodiscard]] std::size_t record_length() const;
};

/// Parses and validates the VLR payload `p[0, len)` found at byte `offset` of file `name`,
/// against the header's point data record format and record length. Throws FormatError naming
/// the byte of the offending field for a short payload, an unknown compressor/coder, an unknown
/// item type, a compressor/item type/item version combination without a decoder (the message
/// names all three), items out of record order, or items that do not add up to the record
/// length. Accepted: compressor 1 or 2 with POINT10, GPSTIME11, RGB12, BYTE of version 1 or 2
/// (any mix), compressor 3 with POINT14, RGB14, RGBNIR14, BYTE14 of version 3 or 4.
LaszipVlr parse_laszip_vlr(const std::uint8_t* p, std::uint64_t len, const std::string& name,
                           std::uint64_t offset, int pdrf, std::size_t record_length);

/// One chunk: its bytes [offset, offset + bytes) in the file and its points.
struct Chunk {
  std::uint64_t offset = 0, bytes = 0;
  std::uint64_t first_point = 0, points = 0;
};

/// Reads the chunk table (LASzip lasreadpoint.cpp read_chunk_table: an int64 at the start of
/// point data gives its position, -1/0 meaning "at the last 8 bytes of the file"; then uint32
/// version 0, uint32 chunk count, and the arithmetic-coded chunk point counts (variable chunk
/// size only) and byte sizes). `data_end` bounds the point data (file size or EVLR start).
/// A missing or damaged table is rebuilt by walking the chunks when the chunk size is fixed
/// (a note is appended); otherwise FormatError. Chunk counts must add up to `point_count`.
/// Compressor 1 (pointwise) has no table and no table offset: one chunk of all points spanning
/// [point_offset, data_end).
std::vector<Chunk> read_chunk_table(const Input& in, const LaszipVlr& vlr, std::uint64_t point_offset,
                                    std::uint64_t data_end, std::uint64_t point_count,
                                    std::vector<std::string>& notes);

/// Decodes chunks into LAS point records. One instance decodes one chunk at a time (not thread
/// safe; use one per thread). `layers` (Layer bits) selects what a layered chunk decodes: X, Y
/// and the return numbers are always decoded; fields of skipped layers keep the chunk's first
/// value. Pointwise items (versions 1 and 2) always decode everything; a compressor 1 stream is
/// decoded as one chunk holding all points.
class ChunkDecoder {
 public:
  ChunkDecoder(const LaszipVlr& vlr, std::uint32_t layers = kLayerAll);
  ~ChunkDecoder();
  ChunkDecoder(const ChunkDecoder&) = delete;
  ChunkDecoder& operator=(const ChunkDecoder&) = delete;

  /// Starts chunk `index` whose bytes are in[chunk.offset, + chunk.bytes) (bytes may be 0 for
  /// an unknown end: then up to `limit`). Throws FormatError (file, chunk, byte) if the chunk
  /// header is truncated or its layer sizes run past the chunk, or if a layered chunk stores a
  /// point count different from `chunk.points`.
  void start(const Input& in, std::size_t index, const Chunk& chunk, std::uint64_t limit);
  /// Decodes the next `n` records of the chunk into `out` (n * record_length bytes). A pointwise
  /// stream that needs bytes past its end throws FormatError (chunk, byte) at once.
  void next(std::size_t n, std::uint8_t* out);
  /// Checks that the streams of the finished chunk were consumed up to their end: reading past
  /// it, or (when `strict`) leaving more than a few padding bytes unread, means a corrupted
  /// stream; throws FormatError naming the chunk and the byte offset.
  void finish(bool strict = true);
  /// File offset just past the bytes the pointwise decoder consumed (to walk chunks without a
  /// table).
  [[nodiscard]] std::uint64_t consumed_end() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};


/// Read-only memory map of a whole file: the streaming readers' detail::MappedFile
/// (readers.hpp), one mapping class for the LAS, LAZ and COPC code.
using FileMap = detail::MappedFile;

/// The LASzip VLR payload the writers emit (laszip.cpp LASzip::pack): pointwise-chunked with
/// version 2 items for `pdrf` 0-3 (LASzip 2.2), layered-chunked with version 3 items for `pdrf`
/// 6-8 (LASzip 3.4 r3, what laszip and laz-perf write for LAS 1.4 formats), `extra` bytes as a
/// BYTE/BYTE14 item; `chunk_size` points per chunk, 0xFFFFFFFF for variable chunks (COPC).
/// Defined in translate.cpp.
std::vector<std::uint8_t> laszip_vlr_payload(int pdrf, std::size_t extra, std::uint32_t chunk_size);

/// The chunk table read_chunk_table() reads: version 0, the chunk count, then arithmetic-coded
/// per chunk its point count (only when `points` is non-empty: variable chunks) and its byte size
/// (`bytes`). Defined in translate.cpp.
std::vector<std::uint8_t> chunk_table_bytes(std::span<const std::uint32_t> points, std::span<const std::uint32_t> bytes);

/// Decompresses all `count` records of a LAZ file into `out` (count * record_length bytes),
/// chunks in parallel (TBB; the output is identical for any thread count).
void decompress_all(const Input& in, const LaszipVlr& vlr, const std::vector<Chunk>& chunks,
                    std::uint8_t* out, std::uint32_t layers = kLayerAll);

}  // namespace rayscan::io::laz
