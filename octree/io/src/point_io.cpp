// read_point_cloud(): memory-maps the file and dispatches to the format reader.
#include "rayscan/io/point_io.hpp"

#include "rayscan/file_names.hpp"

#include "readers.hpp"

#include "rayscan/input_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

namespace rayscan::io {

namespace {

/// Read-only memory map of a whole file (POSIX mmap). Empty files map to an empty span.
class MappedFile {
 public:
  explicit MappedFile(const std::filesystem::path& path) {
    // The input policy (rayscan/input_file.hpp): regular files only, opened without blocking.
    try {
      InputFile f(path);
      size_ = static_cast<std::size_t>(f.size());
      fd_ = ::dup(f.fd());
    } catch (const InputFileError& e) {
      throw FormatError(e.what());
    }
    if (fd_ < 0) throw FormatError(path.string() + ": cannot open file: " + std::strerror(errno));
    if (size_ > 0) {
      void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
      if (p == MAP_FAILED) {
        ::close(fd_);
        throw FormatError(path.string() + ": cannot memory-map file: " + std::strerror(errno));
      }
      data_ = static_cast<const std::uint8_t*>(p);
      ::madvise(p, size_, MADV_SEQUENTIAL);
    }
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile() {
    if (data_ != nullptr) ::munmap(const_cast<std::uint8_t*>(data_), size_);
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] std::span<const std::uint8_t> bytes() const { return {data_, size_}; }
  /// Drops the pages of [0, upto) from the resident set (they stay in the page cache).
  void release(std::uint64_t upto) {
    const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
    const std::uint64_t end = std::min<std::uint64_t>(upto, size_) / page * page;
    if (end > released_) {
      ::madvise(const_cast<std::uint8_t*>(data_) + released_, end - released_, MADV_DONTNEED);
      released_ = end;
    }
  }

 private:
  int fd_ = -1;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::uint64_t released_ = 0;
};

PointCloud read_f64(const detail::Input& in, FileInfo& info) {
  info.format = "f64";
  if (in.size() % 24 != 0)
    detail::fail_at(in.name, in.size() - in.size() % 24,
                    "file size " + std::to_string(in.size()) +
                        " is not a multiple of 24 (3 little-endian float64 per point)");
  PointCloud pc;
  pc.positions.resize(in.size() / 24);
  if (!pc.positions.empty()) std::memcpy(pc.positions.data(), in.bytes.data(), in.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const Vec3& p = pc.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      detail::fail_at(in.name, i * 24, "point " + std::to_string(i) + " has a non-finite coordinate");
  }
  info.header_point_count = pc.size();
  return pc;
}

/// Moves scalars that are really intensity / classification / GPS time into their dedicated
/// fields when their values fit exactly (e.g. PCD "intensity" F4 holding 0..246 integers).
void promote_scalars(PointCloud& pc, const ReadOptions& opt, FileInfo& info) {
  for (std::size_t k = 0; k < pc.scalars.size();) {
    ScalarField& f = pc.scalars[k];
    const std::string n = detail::lower(f.name);
    bool moved = false;
    auto integral_in = [&](double hi) {
      return std::all_of(f.values.begin(), f.values.end(),
                         [hi](double v) { return v >= 0 && v <= hi && v == std::floor(v); });
    };
    if (n == "intensity" && pc.intensity.empty() && integral_in(65535.0)) {
      pc.intensity.assign(f.values.begin(), f.values.end());
      moved = true;
    } else if (n == "classification" && pc.classification.empty() && integral_in(255.0)) {
      pc.classification.assign(f.values.begin(), f.values.end());
      moved = true;
    } else if ((n == "gpstime" || n == "gps_time") && pc.gps_time.empty()) {
      pc.gps_time = std::move(f.values);
      moved = true;
    }
    if (moved) {
      info.notes.push_back("field '" + f.name + "' read as " +
                           (n == "intensity" ? "intensity" : n == "classification" ? "classification" : "GPS time"));
      pc.scalars.erase(pc.scalars.begin() + static_cast<std::ptrdiff_t>(k));
    } else if (!opt.scalars) {
      pc.scalars.erase(pc.scalars.begin() + static_cast<std::ptrdiff_t>(k));
    } else {
      ++k;
    }
  }
}

}  // namespace

Format format_from_extension(const std::filesystem::path& path) {
  const std::string e = lower_extension(path);
  if (e == ".las" || e == ".laz" || e == ".copc") return Format::las;
  if (e == ".ply") return Format::ply;
  if (e == ".pcd") return Format::pcd;
  if (e == ".xyz" || e == ".csv" || e == ".txt" || e == ".pts") return Format::text;
  if (e == ".f64") return Format::f64;
  throw FormatError(path.string() + ": unknown point cloud extension '" + e +
                    "' (expected .las, .ply, .pcd, .xyz, .csv, .txt, .pts or .f64)");
}

namespace {
PointCloud dispatch(const detail::Input& in, Format format, const ReadOptions& options, FileInfo* info) {
  FileInfo local;
  FileInfo& fi = info != nullptr ? *info : local;
  fi = FileInfo{};
  PointCloud pc;
  switch (format) {
    case Format::las: pc = detail::read_las(in, options, fi); break;
    case Format::ply: pc = detail::read_ply(in, options, fi); break;
    case Format::pcd: pc = detail::read_pcd(in, options, fi); break;
    case Format::text: pc = detail::read_text(in, options, fi); break;
    case Format::f64: pc = read_f64(in, fi); break;
  }
  if (format != Format::las) promote_scalars(pc, options, fi);
  return pc;
}
}  // namespace

PointCloud read_point_cloud(const std::filesystem::path& path, const ReadOptions& options, FileInfo* info) {
  const Format format = format_from_extension(path);
  MappedFile map(path);
  detail::Input in{map.bytes(), path.string(), [&map](std::uint64_t upto) { map.release(upto); }};
  return dispatch(in, format, options, info);
}

PointCloud read_point_cloud(std::span<const std::uint8_t> bytes, Format format, const std::string& name,
                            const ReadOptions& options, FileInfo* info) {
  detail::Input in{bytes, name, {}};
  return dispatch(in, format, options, info);
}

}  // namespace rayscan::io
