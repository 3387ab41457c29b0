// read_point_cloud(): a loop over the chunked reader of the file's format (point_reader.hpp).
#include "rayscan/io/point_io.hpp"

#include "rayscan/base/ascii_case.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/io/point_extensions.hpp"
#include "rayscan/io/point_reader.hpp"
#include "readers.hpp"

#include <algorithm>
#include <stdexcept>

namespace rayscan::io {

const std::vector<std::string>& point_cloud_input_extensions() {
  static const std::vector<std::string> exts{".las", ".laz", ".copc.laz", ".copc", ".ply", ".pcd",
                                             ".xyz", ".csv", ".txt", ".pts", ".f64"};
  return exts;
}

std::string extension_list(const std::vector<std::string>& extensions) {
  std::string s;
  for (const std::string& e : extensions) s += (s.empty() ? "" : " ") + e;
  return s;
}

Format format_from_extension(const std::filesystem::path& path) {
  const std::string e = lower_extension(path);
  if (e == ".las" || e == ".laz" || e == ".copc") return Format::las;
  if (e == ".ply") return Format::ply;
  if (e == ".pcd") return Format::pcd;
  if (e == ".xyz" || e == ".csv" || e == ".txt" || e == ".pts") return Format::text;
  if (e == ".f64") return Format::f64;
  // An index file is read by MappedIndex (rayscan/site/index_file.hpp), not by the point readers:
  // say so rather than call it unknown.
  const std::string what = e == ".rsi" ? "'.rsi' is a rayscan index file, not a point cloud file"
                                       : "unknown point cloud extension '" + e + "'";
  throw FormatError(path.string() + ": " + what + " (" + extensions_expected(point_cloud_input_extensions()) + ")");
}

namespace {

/// Appends `n` entries of `src` to `dst` (an attribute vector of the growing whole cloud).
template <class V>
void append(V& dst, const V& src) {
  dst.insert(dst.end(), src.begin(), src.end());
}

/// The whole-file read as a loop over the chunked reader. The first chunk asks for every point
/// the reader announces (a count validated against the file size at open, never an unchecked
/// header field), so a LAS file is decoded straight into the output arrays and a format decoded
/// at open hands its arrays over without a copy; later chunks (none unless a reader delivers
/// fewer than announced per call) are appended.
PointCloud read_all(PointReader& r, FileInfo* info) {
  PointCloud pc;
  const std::size_t total = static_cast<std::size_t>(r.point_count());
  r.read(pc, std::max<std::size_t>(total, 1));
  PointCloud chunk;
  while (r.read(chunk, kDefaultChunkPoints) > 0) {
    append(pc.positions, chunk.positions);
    append(pc.rgb, chunk.rgb);
    append(pc.intensity, chunk.intensity);
    append(pc.classification, chunk.classification);
    append(pc.gps_time, chunk.gps_time);
    append(pc.normals, chunk.normals);
    for (std::size_t k = 0; k < chunk.scalars.size(); ++k) append(pc.scalars[k].values, chunk.scalars[k].values);
  }
  pc.crs_wkt = r.crs_wkt();
  pc.viewpoint = r.info().viewpoint;
  if (info != nullptr) *info = r.info();
  return pc;
}

}  // namespace

PointCloud read_point_cloud(const std::filesystem::path& path, const ReadOptions& options, FileInfo* info) {
  auto r = open_point_reader(path, AttributeSet::all(), options);
  return read_all(*r, info);
}

PointCloud read_point_cloud(std::span<const std::uint8_t> bytes, Format format, const std::string& name,
                            const ReadOptions& options, FileInfo* info) {
  auto r = open_point_reader(bytes, format, name, AttributeSet::all(), options);
  return read_all(*r, info);
}

const std::vector<std::string>& point_cloud_output_extensions() {
  static const std::vector<std::string> exts{".las", ".laz", ".ply", ".pcd", ".xyz", ".csv", ".txt"};
  return exts;
}

bool is_copc_output(const std::filesystem::path& path) {
  const std::string name = ascii_lower(path.filename().string());
  return name.size() > 9 && name.ends_with(".copc.laz");
}

std::string point_cloud_output_problem(const std::filesystem::path& path) {
  if (is_copc_output(path))
    return "writing COPC is not supported by this command (write .laz, then `rayscan translate OUT.laz OUT.copc.laz`)";
  if (!has_extension(path, point_cloud_output_extensions())) return extensions_expected(point_cloud_output_extensions());
  return "";
}

void require_point_cloud_output(const std::filesystem::path& path) {
  if (const std::string why = point_cloud_output_problem(path); !why.empty())
    throw std::invalid_argument(path.string() + ": " + why);
}

LasWriteOptions las_grid_of(const FileInfo& source) {
  LasWriteOptions lo;
  if (source.format != "LAS" && source.format != "LAZ" && source.format != "COPC") return lo;
  if (source.scale && source.offset) {
    lo.scale = *source.scale;
    lo.offset = *source.offset;
    lo.has_offset = true;
  }
  lo.adjusted_standard_gps_time = (source.global_encoding & 1u) != 0;
  lo.project_guid = source.project_guid;
  lo.extra_bytes = source.extra_bytes;
  return lo;
}

void write_point_cloud(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& las) {
  require_point_cloud_output(path);
  const std::string ext = lower_extension(path);
  if (ext == ".ply") write_ply(path, cloud, las.extra_bytes);
  else if (ext == ".pcd") write_pcd(path, cloud, las.extra_bytes);
  else if (ext == ".xyz" || ext == ".csv" || ext == ".txt") write_text(path, cloud, las);
  else write_las(path, cloud, las);  // .las or .laz (write_las compresses .laz)
}

}  // namespace rayscan::io
