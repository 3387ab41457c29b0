// The translate job: lossless LAS <-> LAZ conversion (same header, VLRs/EVLRs and byte-identical
// point records; io::translate_las), any readable point file to COPC (io::write_copc) for a
// .copc.laz name, and any readable point file or index file to LAS, LAZ, PLY, PCD or text by the
// output's extension (io::write_point_cloud). `rayscan translate` runs it.
#pragma once

#include "rayscan/base/job.hpp"
#include "rayscan/io/translate.hpp"
#include "rayscan/site/copc_writer.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The io library type this job's options are made of.
using io::LasCompression;

/// Inputs of run_translate().
struct TranslateJobOptions {
  /// The file to read: any format read_point_cloud reads, or an index file (.rsi,
  /// io::is_index_file: its points in the sources' order with the attributes it stores).
  std::filesystem::path in;
  std::filesystem::path out;  ///< the file to write (through a temporary file renamed into place)
  /// Output format: by the output's extension (.las, .laz, .ply, .pcd, .xyz, .csv, .txt: io::write_point_cloud), or las
  /// or laz whatever the name (a LAS/LAZ input is then converted losslessly).
  LasCompression compression = LasCompression::by_extension;
  /// Points per LAZ chunk (LASzip's default 50000): 1 to 4294967294 (0xFFFFFFFF marks
  /// variable-sized chunks in a LASzip VLR).
  std::uint32_t chunk_size = 50000;
  /// COPC output: the memory budget of the in-memory octree build, a byte size as
  /// parse_byte_size reads it ("4G", "512M"); unused for other outputs.
  std::string memory = "4G";
  JobControl control;  ///< COPC output: threads compressing nodes (0 = all cores); unused otherwise
  /// LAS <-> LAZ: called with (phase, points done, points in the file) as the conversion streams
  /// (io::TranslateOptions::progress); may be empty.
  std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)> progress;
};

/// Output of run_translate(): points, chunks, compressed, input and output sizes; for COPC
/// output also the octree written (chunks = nodes).
struct TranslateJobResult : io::TranslateResult {
  std::optional<io::CopcWriteResult> copc;  ///< set when a COPC file was written
};

/// The output extensions run_translate writes by the name, lower case with the dot, in the order
/// its messages list them: io::point_cloud_output_extensions() with ".copc.laz" after ".laz".
[[nodiscard]] const std::vector<std::string>& translate_output_extensions();

/// Converts `in` to `out`. A name ending in .copc.laz (io::is_copc_output; with the format left
/// by_extension) is written as COPC 1.0 by io::write_copc (rayscan/site/copc_writer.hpp). LAS/LAZ to LAS/LAZ streams one chunk at a time (memory independent of
/// the file size; details in rayscan/io/translate.hpp); any other pair reads the cloud whole and
/// writes it with io::write_point_cloud (PLY output keeps positions exactly; LAS output quantises
/// them to the source's LAS grid, io::las_grid_of, or an index file's LAS-integer positions' grid,
/// else to write_las's scale). An index file gives its points in the sources' order
/// (MappedIndex::to_point_cloud: positions, colour, intensity, classification, GPS time and CRS,
/// the attributes an index stores; colour stored as byte x 257 is written back as 8-bit values).
/// The output's format and path are checked before the input is read (translate_output_extensions,
/// require_outputs). Throws OptionError naming "chunk_size" for a chunk size outside
/// [1, 4294967294], std::invalid_argument for an output extension with no writer ("<out>: expected
/// a file name ending in .las, .laz, .copc.laz, ...") and for an unsupported conversion (LAZ or COPC
/// output of the waveform point formats 4, 5, 9, 10; COPC output of an index file), io::IndexError
/// for a malformed index file, io::CopcMemoryError when a COPC build exceeds `memory`,
/// io::FormatError for a malformed input, OutputFileError or std::runtime_error for I/O failures
/// (the previous output, if any, is then left unchanged).
TranslateJobResult run_translate(const TranslateJobOptions& options);

}  // namespace rayscan::jobs
