#include "rayscan/io/point_io.hpp"

#include "text_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>

namespace rayscan::io {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

PointCloud read_f64(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw FormatError(path.string() + ": cannot open file");
  const auto size = static_cast<std::uint64_t>(in.tellg());
  if (size % 24 != 0)
    throw FormatError(path.string() + ": byte " + std::to_string(size - size % 24) +
                      ": file size " + std::to_string(size) +
                      " is not a multiple of 24 (3 little-endian float64 per point)");
  in.seekg(0);
  PointCloud pc;
  pc.positions.resize(size / 24);
  static_assert(std::endian::native == std::endian::little);
  in.read(reinterpret_cast<char*>(pc.positions.data()), static_cast<std::streamsize>(size));
  if (!in) throw FormatError(path.string() + ": read failed");
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const Vec3& p = pc.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw FormatError(path.string() + ": byte " + std::to_string(i * 24) + ": point " +
                        std::to_string(i) + " has a non-finite coordinate");
  }
  return pc;
}

}  // namespace

PointCloud read_point_cloud(const std::filesystem::path& path) {
  const std::string ext = lower_ext(path);
  if (!std::filesystem::exists(path)) throw FormatError(path.string() + ": no such file");
  if (ext == ".f64") return read_f64(path);
  if (ext == ".csv" || ext == ".xyz" || ext == ".txt") return read_text(path);
  throw FormatError(path.string() + ": unknown point cloud extension '" + ext +
                    "' (expected .f64, .csv, .xyz or .txt)");
}

}  // namespace rayscan::io
