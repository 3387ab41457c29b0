// The translate job (rayscan/jobs/translate.hpp): LAS <-> LAZ through io::translate_las, any other
// pair through the readers (or an index file's MappedIndex::to_point_cloud) and io::write_point_cloud.
#include "rayscan/jobs/translate.hpp"
#include "copc_output.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/site/index_file.hpp"

#include <tbb/task_arena.h>

#include <algorithm>

namespace rayscan::jobs {

const std::vector<std::string>& translate_output_extensions() {
  static const std::vector<std::string> exts = [] {
    std::vector<std::string> e = io::point_cloud_output_extensions();
    e.insert(std::find(e.begin(), e.end(), ".laz") + 1, ".copc.laz");
    return e;
  }();
  return exts;
}

namespace {

/// The points of the index file `path` in the sources' order with the attributes it stores, and
/// the LAS grid its positions keep (the sources' scale and offset when it stores them as LAS
/// integers), so LAS output of it is bit-exact.
PointCloud read_index_points(const std::filesystem::path& path, io::LasWriteOptions& grid) {
  const io::MappedIndex m = io::MappedIndex::open(path);
  PointCloud cloud = m.to_point_cloud();
  // Colour stored as byte x 257 is what the readers deliver for 8-bit source colour (a LAS file's
  // 16-bit fields holding 0..255, a PLY's uchar): written back as those bytes, as from the source.
  cloud.rgb_from_8bit_las = m.rgb().multiplier() == 257;
  if (m.position_encoding() == PositionEncoding::las_int32) {
    grid.scale = m.positions().scale();
    grid.offset = m.positions().offset();
    grid.has_offset = true;
  }
  return cloud;
}

}  // namespace

TranslateJobResult run_translate(const TranslateJobOptions& options) {
  // The output's format is checked before anything is read (a .ply or .xyz name once received
  // LAS bytes with exit 0, a .copc.laz name a plain LAZ).
  const bool copc = options.compression == LasCompression::by_extension && io::is_copc_output(options.out);
  // A plain LAS/LAZ under a COPC name would be taken for COPC by every reader that trusts names.
  if (options.compression != LasCompression::by_extension && io::is_copc_output(options.out))
    throw OptionError({option("compression"), std::string(options.compression == LasCompression::las ? " las" : " laz") +
                                             " writes plain LAS/LAZ, not COPC: " + options.out.string() +
                                             " names a COPC file (leave the format to the name to write COPC)"});
  // Listed with .copc.laz, which this job writes too (io::require_point_cloud_output's list is
  // that of write_point_cloud).
  if (options.compression == LasCompression::by_extension && !copc &&
      !has_extension(options.out, io::point_cloud_output_extensions()))
    throw std::invalid_argument(options.out.string() + ": " + extensions_expected(translate_output_extensions()));
  const std::filesystem::path out[] = {options.out}, in[] = {options.in};
  require_outputs(out, in);
  const bool index_in = io::is_index_file(options.in);
  if (copc && index_in)
    throw std::invalid_argument(options.in.string() + ": COPC output of an index file is not supported: translate it to "
                                                      ".las first, then that file to .copc.laz");
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
  const bool las_in = !index_in && io::format_from_extension(options.in) == io::Format::las;
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
  // attribute the readers keep (an index file: those it stores), positions in double (LAS output
  // quantises them to the source's LAS grid when it has one, else to write_las's scale).
  io::LasWriteOptions grid;
  PointCloud cloud;
  if (index_in) {
    cloud = read_index_points(options.in, grid);
  } else {
    io::FileInfo info;
    cloud = io::read_point_cloud(options.in, {}, &info);
    grid = io::las_grid_of(info);
  }
  io::write_point_cloud(options.out, cloud, grid);
  TranslateJobResult r;
  r.points = cloud.size();
  r.compressed = ext == ".laz";
  r.in_bytes = std::filesystem::file_size(options.in);
  r.out_bytes = std::filesystem::file_size(options.out);
  return r;
}

}  // namespace rayscan::jobs
