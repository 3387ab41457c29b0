// The translate job (rayscan/jobs/translate.hpp): LAS <-> LAZ through io::translate_las, any other
// pair through the readers (or an index file's MappedIndex::to_point_cloud) and io::write_point_cloud.
#include "rayscan/jobs/translate.hpp"
#include "cloud_site.hpp"
#include "copc_output.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/coordinate_bound.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/site/index_file.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <unistd.h>

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

/// Whether the options ask for a LAS grid of their own (scale, offset or automatic offset).
bool grid_requested(const TranslateJobOptions& o) { return !o.scale.empty() || o.offset || o.auto_offset; }

/// Checks scale, offset (finite, within +-kMaxCoordinate) and auto_offset before anything is
/// read; `grid_output`: the output is LAS, LAZ or COPC, the outputs that have a grid. Throws
/// OptionError (run_translate).
void check_grid_options(const TranslateJobOptions& o, bool grid_output) {
  if (!grid_requested(o)) return;
  const char* named = !o.scale.empty() ? "scale" : "offset";
  if (!grid_output)
    throw OptionError({option(named), " applies to LAS, LAZ and COPC output, not to " + o.out.string()});
  if (!o.scale.empty() && o.scale.size() != 1 && o.scale.size() != 3)
    throw OptionError({option("scale"), ": expected one value (x, y and z) or three (x,y,z), got " +
                                            std::to_string(o.scale.size())});
  for (const double s : o.scale)
    if (!(s > 0.0) || !std::isfinite(s))
      throw OptionError({option("scale"), " " + shortest_text(s) + ": expected a finite number > 0"});
  if (o.offset && o.auto_offset)
    throw OptionError({option("offset"), ": expected auto or X,Y,Z, not both"});
  // An offset beyond the coordinate bound is a LAS header the readers refuse (its stored 0 lies
  // there): refused here, before anything is read or written.
  if (o.offset)
    for (int k = 0; k < 3; ++k)
      if (const double v = (*o.offset)[k]; !(std::abs(v) <= kMaxCoordinate))
        throw OptionError({option("offset"), std::string(" ") + "XYZ"[k] + " = " + shortest_text(v) + ": " +
                                                 (std::isfinite(v) ? coordinate_bound_expected()
                                                                   : std::string("expected a finite number"))});
}

/// Refuses a chunk size given for an output that is not LAZ (`laz_out`), before anything is read:
/// only LAZ has chunks the option sizes (COPC writes one per octree node). Throws OptionError.
void check_chunk_size(const TranslateJobOptions& o, bool laz_out, bool copc) {
  if (!o.chunk_size || laz_out) return;
  throw OptionError({option("chunk_size"), " applies to LAZ output, not to " + o.out.string() +
                                               (copc ? " (COPC writes one chunk per octree node)" : "")});
}

/// `grid` (the source's, or the defaults) with the scale and offsets the options ask for: a new
/// scale gets automatic offsets unless they are given.
void apply_grid_options(const TranslateJobOptions& o, io::LasWriteOptions& grid) {
  if (!o.scale.empty()) {
    grid.scale = o.scale.size() == 1 ? Vec3(o.scale[0]) : Vec3(o.scale[0], o.scale[1], o.scale[2]);
    grid.has_offset = false;
  }
  if (o.offset) grid.offset = *o.offset, grid.has_offset = true;
  if (o.auto_offset) grid.has_offset = false;
}

/// LAZ or COPC output (`copc`) of `cloud` on `grid`: written by io::write_las into a hidden LAS
/// file beside the output, then that file compressed by io::translate_las (the job's chunk size
/// and progress) or written as COPC (its records and grid copied as they are); the temporary is
/// always removed, and errors name the files the user gave.
TranslateJobResult write_through_las(const TranslateJobOptions& options, const PointCloud& cloud,
                                     const io::LasWriteOptions& grid, bool copc) {
  if (copc && cloud.size() == 0) throw std::invalid_argument(options.in.string() + ": no points to write as COPC");
  std::string name = ".";  // built by appending (GCC 12 -Wrestrict false positive on "." + s)
  name += options.out.filename().string();
  name += '.';
  name += std::to_string(::getpid());
  name += ".grid.las";  // last: the extension the LAS writer and write_copc go by
  // Removed on the way out and by a signal, its write errors naming the output.
  const IntermediateFile intermediate(options.out.parent_path() / name, options.out);
  const std::filesystem::path& temp = intermediate.path();
  try {
    io::write_las(temp, cloud, grid);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(temporary_named_as(e.what(), temp, options.out));
  }
  TranslateJobResult r;
  try {
    if (copc) {
      r.copc = detail::write_copc_output(temp, options.out, options.memory, options.temp_dir, options.progress,
                                         options.control.threads);
      r.copc->in_bytes = std::filesystem::file_size(options.in);
    } else {
      io::TranslateOptions t;
      t.compression = LasCompression::laz;
      t.chunk_size = options.chunk_size.value_or(t.chunk_size);
      t.progress = options.progress;
      static_cast<io::TranslateResult&>(r) = io::translate_las(temp, options.out, t);
      r.in_bytes = std::filesystem::file_size(options.in);
    }
  } catch (const io::CopcMemoryError& e) {
    throw io::CopcMemoryError(temporary_named_as(e.what(), temp, options.in));
  } catch (const OptionError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(temporary_named_as(e.what(), temp, options.in));
  }
  return r;
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
  const std::string ext = lower_extension(options.out);
  const bool las_out = options.compression != LasCompression::by_extension || ext == ".las" || ext == ".laz";
  const bool laz_out = options.compression == LasCompression::laz ||
                       (options.compression == LasCompression::by_extension && ext == ".laz" && !copc);
  check_grid_options(options, las_out || copc);
  check_chunk_size(options, laz_out, copc);
  // The COPC build's options, checked whatever the output, so that a typo fails at once.
  detail::memory_budget(options.memory);
  require_temp_dir(options.temp_dir);
  const std::filesystem::path out[] = {options.out}, in[] = {options.in};
  require_outputs(out, in);
  const bool index_in = io::is_index_file(options.in);
  if (copc && index_in)
    throw std::invalid_argument(options.in.string() + ": COPC output of an index file is not supported: translate it to "
                                                      ".las first, then that file to .copc.laz");
  // The result of a COPC write.
  const auto copc_result = [](const io::CopcWriteResult& c) {
    TranslateJobResult r;
    r.copc = c;
    r.points = c.points;
    r.chunks = c.nodes;
    r.compressed = true;
    r.warnings = c.warnings;
    r.in_bytes = c.in_bytes;
    r.out_bytes = c.out_bytes;
    return r;
  };
  if (copc && !grid_requested(options))
    return copc_result(detail::write_copc_output(options.in, options.out, options.memory, options.temp_dir,
                                                 options.progress, options.control.threads));
  const bool las_in = !index_in && io::format_from_extension(options.in) == io::Format::las;
  if (las_in && las_out && !grid_requested(options)) {
    io::TranslateOptions t;
    t.compression = options.compression;
    t.chunk_size = options.chunk_size.value_or(t.chunk_size);
    t.progress = options.progress;
    TranslateJobResult r;
    static_cast<io::TranslateResult&>(r) = io::translate_las(options.in, options.out, t);  // checks chunk_size (OptionError)
    return r;
  }
  // Any readable input to any written format (io::write_point_cloud by the extension): every
  // attribute the readers keep (an index file: those it stores), positions in double (LAS output
  // quantises them to the grid the options give, else the source's LAS grid when it has one, else
  // to write_las's scale; text prints coordinates on the source's grid with its decimals).
  io::LasWriteOptions grid;
  PointCloud cloud;
  std::vector<std::string> warnings;
  // COPC stores its CRS: one GDAL cannot read in a LAS header is refused before the points are
  // read (the other formats' CRS comes with their points, checked below).
  if (copc) detail::require_readable_header_crs(options.in, nullptr, {});
  if (index_in) {
    cloud = read_index_points(options.in, grid);
  } else {
    io::FileInfo info;
    cloud = io::read_point_cloud(options.in, {}, &info);
    grid = io::las_grid_of(info);
    if (!info.crs_warning.empty()) warnings.push_back(info.crs_warning);
  }
  apply_grid_options(options, grid);
  // A CRS that GDAL cannot read (a LAS WKT record with no readable GeoKeys beside it): COPC, whose
  // CRS is its WKT record, refuses it naming the input, as it does without a grid; the point
  // formats need none and are written without it, with a warning, rather than refused.
  if (copc) io::require_readable_crs(options.in.string(), cloud.crs_wkt);
  if (!cloud.crs_wkt.empty() && !io::crs_wkt_readable(cloud.crs_wkt)) {
    warnings.push_back(io::unreadable_crs(options.in.string(), cloud.crs_wkt) + ": " + options.out.string() +
                       " is written without a CRS");
    cloud.crs_wkt.clear();
  }
  // LAZ output is compressed by the job itself, so that it takes the chunk size and reports
  // progress; COPC output gets here only with a grid of its own (otherwise written above).
  if (copc || laz_out) {
    TranslateJobResult r = write_through_las(options, cloud, grid, copc);
    if (copc) r = copc_result(*r.copc);
    r.warnings.insert(r.warnings.begin(), warnings.begin(), warnings.end());
    return r;
  }
  io::write_point_cloud(options.out, cloud, grid);
  TranslateJobResult r;
  r.warnings = std::move(warnings);
  r.points = cloud.size();
  r.compressed = ext == ".laz";
  r.in_bytes = std::filesystem::file_size(options.in);
  r.out_bytes = std::filesystem::file_size(options.out);
  return r;
}

}  // namespace rayscan::jobs
