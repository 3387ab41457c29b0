// The translate job: lossless LAS <-> LAZ conversion (same header, VLRs/EVLRs and byte-identical
// point records; io::translate_las), any readable point file to COPC (io::write_copc) for a
// .copc.laz name, and any readable point file or index file to LAS, LAZ, PLY, PCD or text by the
// output's extension (io::write_point_cloud). `rayscan translate` runs it.
#pragma once

#include "rayscan/base/job.hpp"
#include "rayscan/io/translate.hpp"
#include "rayscan/octree/geometry.hpp"
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
  /// LAZ output: points per chunk, 1 to 4294967294 (0xFFFFFFFF marks variable-sized chunks in a
  /// LASzip VLR); unset: LASzip's 50000 (io::TranslateOptions::chunk_size). Refused for any other
  /// output (LAS, PLY, PCD, text, and COPC, which writes one chunk per octree node).
  std::optional<std::uint32_t> chunk_size;
  /// COPC output: the memory budget of the in-memory octree build, a byte size as
  /// parse_byte_size reads it ("4G", "512M"); unused for other outputs, but checked for every one.
  std::string memory = "4G";
  /// COPC output: the existing folder of the build's temporary records file (empty: the output's
  /// folder), as IndexJobOptions::temp_dir; unused for other outputs, but checked for every one.
  std::filesystem::path temp_dir;
  JobControl control;  ///< COPC output: threads compressing nodes (0 = all cores); unused otherwise
  /// LAS, LAZ and COPC output: the scale factors, the size of one step of the records' X, Y, Z
  /// integers in file units (PDAL writers.las scale_x, scale_y, scale_z): one value for all three
  /// axes, or three; each finite and > 0. Empty: the source's grid (a LAS, LAZ or COPC input's,
  /// or an index file's LAS integers), else io::write_las's automatic choice. With a scale the
  /// offsets are automatic unless `offset` gives them, and a LAS/LAZ input is read and rewritten
  /// by io::write_las (PDRF 6-8) instead of copied.
  std::vector<double> scale;
  /// LAS, LAZ and COPC output: the offsets X, Y, Z in file units (writers.las offset_x, ...).
  /// Unset: the source's with the source's scale, else automatic.
  std::optional<Vec3> offset;
  /// LAS, LAZ and COPC output: automatic offsets (writers.las offset_x "auto": the points' low
  /// corner rounded down to 1000 scale steps, io::LasWriteOptions::offset), also where the
  /// source's grid would be kept. Not with `offset`.
  bool auto_offset = false;
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
/// else to write_las's scale; `scale` and `offset` replace that grid, for COPC output through a
/// temporary LAS file beside the output; text output prints coordinates on the source's grid with
/// its decimals, io::write_text). An index file gives its points in the sources' order
/// (MappedIndex::to_point_cloud: positions, colour, intensity, classification, GPS time and CRS,
/// the attributes an index stores; colour stored as byte x 257 is written back as 8-bit values).
/// The output's format and path are checked before the input is read (translate_output_extensions,
/// require_outputs), and so are `memory` and `temp_dir` whatever the output. Throws OptionError
/// naming "memory" or "temp_dir" (not an existing folder), "chunk_size" for a chunk size outside
/// [1, 4294967294] or given for an output that is not LAZ, std::invalid_argument for an output
/// extension with no writer ("<out>: expected
/// a file name ending in .las, .laz, .copc.laz, ...") and for an unsupported conversion (LAZ or COPC
/// output of the waveform point formats 4, 5, 9, 10; COPC output of an index file), io::IndexError
/// for a malformed index file, OptionError naming "scale" or "offset" for a scale that is not
/// finite and > 0, a count other than 1 or 3, an offset that is not finite or beyond
/// +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp, the readers' bound), `offset` with
/// `auto_offset`, or either with an output that is not LAS, LAZ or COPC, std::invalid_argument
/// (from io::write_las: point, axis, value) for a coordinate whose (value - offset) / scale does not
/// fit a 32-bit integer or reads back beyond +-kMaxCoordinate, io::CopcMemoryError when a COPC build exceeds `memory`,
/// io::FormatError for a malformed input, OutputFileError or std::runtime_error for I/O failures
/// (the previous output, if any, is then left unchanged).
TranslateJobResult run_translate(const TranslateJobOptions& options);

}  // namespace rayscan::jobs
