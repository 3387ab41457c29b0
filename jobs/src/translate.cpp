// The translate job (rayscan/jobs/translate.hpp): LAS <-> LAZ through io::translate_las, any other
// pair through the readers and io::write_point_cloud.
#include "rayscan/jobs/translate.hpp"
#include "copc_output.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/io/point_io.hpp"

#include <tbb/task_arena.h>

namespace rayscan::jobs {

TranslateJobResult run_translate(const TranslateJobOptions& options) {
  // The output's format is checked before anything is read (a .ply or .xyz name once received
  // LAS bytes with exit 0, a .copc.laz name a plain LAZ).
  const bool copc = options.compression == LasCompression::by_extension && io::is_copc_output(options.out);
  // A plain LAS/LAZ under a COPC name would be taken for COPC by every reader that trusts names.
  if (options.compression != LasCompression::by_extension && io::is_copc_output(options.out))
    throw OptionError({option("compression"), std::string(options.compression == LasCompression::las ? " las" : " laz") +
                                             " writes plain LAS/LAZ, not COPC: " + options.out.string() +
                                             " names a COPC file (leave the format to the name to write COPC)"});
  if (options.compression == LasCompression::by_extension && !copc) io::require_point_cloud_output(options.out);
  const std::filesystem::path out[] = {options.out}, in[] = {options.in};
  require_outputs(out, in);
  if (copc) {
    TranslateJobResult r;
    r.copc = detail::write_copc_output(options.in, options.out, options.memory, {}, options.progress,
                                       options.control.threads);
    r.points = r.copc->points;
    r.chunks = r.copc->nodes;
    r.compressed = true;
    r.in_bytes = r.copc->in_bytes;
    r.out_bytes = r.copc->out_bytes;
    return r;
  }
  const bool las_in = io::format_from_extension(options.in) == io::Format::las;
  const std::string ext = lower_extension(options.out);
  const bool las_out = options.compression != LasCompression::by_extension || ext == ".las" || ext == ".laz";
  if (las_in && las_out) {
    io::TranslateOptions t;
    t.compression = options.compression;
    t.chunk_size = options.chunk_size;
    t.progress = options.progress;
    TranslateJobResult r;
    static_cast<io::TranslateResult&>(r) = io::translate_las(options.in, options.out, t);  // checks chunk_size (OptionError)
    return r;
  }
  // Any readable input to any written format (io::write_point_cloud by the extension): every
  // attribute the readers keep, positions in double (LAS output quantises them to write_las's
  // scale).
  const PointCloud cloud = io::read_point_cloud(options.in);
  io::write_point_cloud(options.out, cloud);
  TranslateJobResult r;
  r.points = cloud.size();
  r.compressed = ext == ".laz";
  r.in_bytes = std::filesystem::file_size(options.in);
  r.out_bytes = std::filesystem::file_size(options.out);
  return r;
}

}  // namespace rayscan::jobs
