// The translate job (rayscan/jobs/translate.hpp): LAS <-> LAZ through io::translate_las.
#include "rayscan/jobs/translate.hpp"

#include "rayscan/base/atomic_file.hpp"

namespace rayscan::jobs {

TranslateJobResult run_translate(const TranslateJobOptions& options) {
  const std::filesystem::path out[] = {options.out}, in[] = {options.in};
  require_outputs(out, in);
  io::TranslateOptions t;
  t.compression = options.compression;
  t.chunk_size = options.chunk_size;
  return io::translate_las(options.in, options.out, t);  // checks chunk_size (OptionError)
}

}  // namespace rayscan::jobs
