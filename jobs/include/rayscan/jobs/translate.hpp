// The translate job: lossless LAS <-> LAZ conversion (same header, VLRs/EVLRs and byte-identical
// point records; io::translate_las). `rayscan translate` runs it.
#pragma once

#include "rayscan/base/job.hpp"
#include "rayscan/io/translate.hpp"

#include <cstdint>
#include <filesystem>

namespace rayscan::jobs {

// The io library type this job's options are made of.
using io::LasCompression;

/// Inputs of run_translate().
struct TranslateJobOptions {
  std::filesystem::path in;   ///< the .las or .laz file to read (LAZ recognised by its LASzip VLR)
  std::filesystem::path out;  ///< the file to write (through a temporary file renamed into place)
  /// Output compression: by the output's extension (.laz: LAZ, else LAS), or las or laz.
  LasCompression compression = LasCompression::by_extension;
  /// Points per LAZ chunk (LASzip's default 50000): 1 to 4294967294 (0xFFFFFFFF marks
  /// variable-sized chunks in a LASzip VLR).
  std::uint32_t chunk_size = 50000;
  JobControl control;  ///< unused today (the conversion streams on one thread)
};

/// Output of run_translate(): points, chunks, compressed, input and output sizes.
using TranslateJobResult = io::TranslateResult;

/// Converts `in` to `out` one chunk at a time (memory independent of the file size; details in
/// rayscan/io/translate.hpp). Throws OptionError naming "chunk_size" for a chunk size outside
/// [1, 4294967294], io::FormatError for a malformed input, std::invalid_argument for an
/// unsupported conversion (LAZ output of the waveform point formats 4, 5, 9, 10),
/// std::runtime_error for I/O failures (the previous output, if any, is then left unchanged).
TranslateJobResult run_translate(const TranslateJobOptions& options);

}  // namespace rayscan::jobs
