// The point records of a LAS or LAZ file exactly as the LAS specification lays them out, LAZ
// decompressed: what `rayscan translate` copies and what the LAZ tests compare byte for byte.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace rayscan::io {

/// Layers of a layered (LAS 1.4, PDRF 6-10) LAZ chunk a reader may skip: X, Y and the return
/// numbers are always decoded; a field whose layer is not asked for keeps the value of its
/// chunk's first record. Pointwise LAZ (PDRF 0-5) and plain LAS always give every field.
/// Source: LASzip lasreaditemcompressed_v3.cpp (decompress_selective); docs/formats.md "LAZ".
namespace las_layers {
inline constexpr std::uint32_t z = 1u << 0, classification = 1u << 1, flags = 1u << 2,
                               intensity = 1u << 3, scan_angle = 1u << 4, user_data = 1u << 5,
                               point_source = 1u << 6, gps_time = 1u << 7, rgb = 1u << 8,
                               nir = 1u << 9, extra_bytes = 1u << 10, all = 0xFFFFFFFFu;
}  // namespace las_layers

/// Header facts and point records of a LAS/LAZ file (ASPRS LAS 1.4 R15 section 2.4).
struct LasRecords {
  int version_minor = 0;             ///< LAS 1.x
  int pdrf = 0;                      ///< point data record format 0..10 (compression bits cleared)
  std::uint16_t record_length = 0;   ///< bytes per record, including extra bytes
  std::uint64_t count = 0;           ///< number of records (header point count)
  std::uint64_t point_offset = 0;    ///< offset to point data
  bool compressed = false;           ///< the file is LAZ (has the LASzip VLR)
  bool copc = false;                 ///< the file has a COPC info VLR
  std::uint64_t chunks = 0;          ///< LAZ chunks (0 for plain LAS)
  std::vector<std::uint8_t> records; ///< count * record_length bytes, file order
  std::vector<std::string> notes;    ///< reader decisions (e.g. chunk table rebuilt)
};

/// Reads every point record of a LAS or LAZ file (LAZ detected by its LASzip VLR, never by the
/// extension), decompressing LAZ chunks in parallel (TBB, deterministic). `layers`
/// (las_layers bits) selects what layered LAZ decodes. Throws FormatError (one line: file,
/// chunk, byte offset, what was expected) for malformed or unsupported input.
LasRecords read_las_records(const std::filesystem::path& path, std::uint32_t layers = las_layers::all);

/// Same from bytes in memory (`name` used in errors; the fuzzing entry point).
LasRecords read_las_records(std::span<const std::uint8_t> bytes, const std::string& name,
                            std::uint32_t layers = las_layers::all);

}  // namespace rayscan::io
