// Lossless LAS <-> LAZ conversion (`rayscan translate`, like `laszip -i in -o out` or
// `pdal translate`): same header fields, VLRs and EVLRs (the LASzip VLR added or removed, COPC
// VLRs dropped since the output is no longer a COPC file) and byte-identical point records.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace rayscan::io {

/// Output compression of translate_las().
enum class LasCompression {
  by_extension,  ///< LAZ when the output path ends in .laz (case-insensitive), else LAS
  las,           ///< plain LAS
  laz,           ///< LAZ
};

/// Options of translate_las().
struct TranslateOptions {
  LasCompression compression = LasCompression::by_extension;
  std::uint32_t chunk_size = 50000;  ///< points per LAZ chunk (LASzip's default)
  /// Called with (phase "copy" or "encode", points done, points in the file) every 2^21 points
  /// and once at the end (may be empty; a LAZ input is decoded as it is read).
  std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)> progress;
};

/// What translate_las() did.
struct TranslateResult {
  std::uint64_t points = 0;     ///< point records converted
  std::uint64_t chunks = 0;     ///< LAZ chunks written (0 for LAS output)
  bool compressed = false;      ///< the output is LAZ
  std::uint64_t in_bytes = 0;   ///< size of the input file, bytes
  std::uint64_t out_bytes = 0;  ///< size of the output file, bytes
  /// What the copy kept that a user should know, one line each naming the input: an OGC WKT VLR
  /// whose text GDAL cannot read as a CRS, copied unchanged as every VLR is (as PDAL copies it).
  std::vector<std::string> warnings;
};

/// Converts the LAS or LAZ file `in` (LAZ recognised by its LASzip VLR) to `out`, streaming one
/// chunk at a time (memory independent of the file size). LAZ output uses, for point data record
/// formats 0-3 (+ extra bytes), the pointwise-chunked compressor with LASzip item version 2
/// (POINT10, GPSTIME11, RGB12, BYTE), and for formats 6-8 (+ extra bytes) the layered-chunked
/// compressor with item version 3 (POINT14, RGB14, RGBNIR14, BYTE14; one arithmetic coder per
/// layer). The VLRs are copied as they are, the CRS's too: an OGC WKT VLR that GDAL cannot read
/// is kept (no CRS is written in its place, so none contradicts it) and named once in
/// TranslateResult::warnings. Writes through a temporary file renamed into place (AtomicFile).
/// Throws FormatError
/// for malformed input (e.g. a waveform data packet record start, byte 227, neither after the
/// point records nor at an EVLR; a point whose coordinates decode beyond +-kMaxCoordinate, named
/// as the LAS reader names it, so no output the readers refuse is written), std::invalid_argument for an unsupported conversion (LAZ output
/// of the waveform formats 4, 5, 9, 10; LAZ input or output of a file holding its waveform data
/// packets, global encoding bit 1, which LAS -> LAS copies and re-addresses), OptionError naming "chunk_size" for 0 or 0xFFFFFFFF (the
/// LASzip VLR's variable-chunk marker), std::runtime_error for I/O failures. Sources:
/// ASPRS LAS 1.4 R15 sections 2.4-2.7; LASzip (docs/formats.md "LAZ" sections 4-5).
TranslateResult translate_las(const std::filesystem::path& in, const std::filesystem::path& out,
                              const TranslateOptions& options = {});

}  // namespace rayscan::io
