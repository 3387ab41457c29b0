// The translate job (rayscan/jobs/translate.hpp): LAS <-> LAZ through io::translate_las.
#include "rayscan/jobs/translate.hpp"

#include "rayscan/base/option_error.hpp"

#include <string>

namespace rayscan::jobs {

TranslateJobResult run_translate(const TranslateJobOptions& options) {
  if (options.chunk_size == 0 || options.chunk_size == 0xFFFFFFFFu)
    throw OptionError({option("chunk_size"), " " + std::to_string(options.chunk_size) +
                                                 ": expected 1 to 4294967294 points per chunk"});
  io::TranslateOptions t;
  t.compression = options.compression;
  t.chunk_size = options.chunk_size;
  const io::TranslateResult r = io::translate_las(options.in, options.out, t);
  TranslateJobResult result;
  result.points = r.points;
  result.chunks = r.chunks;
  result.compressed = r.compressed;
  result.in_bytes = r.in_bytes;
  result.out_bytes = r.out_bytes;
  return result;
}

}  // namespace rayscan::jobs
