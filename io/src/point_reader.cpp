// open_point_reader(): the chunked readers of every format, and the memory map they read from.
#include "rayscan/io/point_reader.hpp"

#include "field_names.hpp"
#include "readers.hpp"

#include "rayscan/base/input_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace rayscan::io {

namespace detail {

MappedFile::MappedFile(const std::filesystem::path& path) {
  // The input policy (rayscan/base/input_file.hpp): regular files only, opened without blocking.
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

MappedFile::~MappedFile() {
  if (data_ != nullptr) ::munmap(const_cast<std::uint8_t*>(data_), size_);
  if (fd_ >= 0) ::close(fd_);
}

void MappedFile::drop(std::uint64_t begin, std::uint64_t end) const {
  const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
  end = std::min<std::uint64_t>(end, size_);
  if (data_ == nullptr || begin >= end) return;
  const std::uint64_t b = begin / page * page, e = std::min<std::uint64_t>((end + page - 1) / page * page, size_);
  ::madvise(const_cast<std::uint8_t*>(data_) + b, e - b, MADV_DONTNEED);
}

void MappedFile::release(std::uint64_t upto) {
  const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
  const std::uint64_t end = std::min<std::uint64_t>(upto, size_) / page * page;
  // A second pass over the file (the LAS colour scan at open, then the decode) starts again from
  // the beginning: its pages are released afresh.
  if (end < released_) released_ = 0, ahead_ = 0;
  if (end > released_) {
    ::madvise(const_cast<std::uint8_t*>(data_) + released_, end - released_, MADV_DONTNEED);
    released_ = end;
  }
  // Read ahead of the decode: the next 256 MiB are asked for in steps of 64 MiB (MADV_WILLNEED
  // starts the reads and returns), so the disk reads while the blocks before are decoded,
  // instead of each page fault waiting for its readahead (bench/notes/).
  constexpr std::uint64_t kAhead = std::uint64_t{256} << 20, kStep = std::uint64_t{64} << 20;
  if (ahead_ < end) ahead_ = end;
  const std::uint64_t want = std::min<std::uint64_t>(size_, end + kAhead) / page * page;
  if (want > ahead_ && (want - ahead_ >= kStep || want == size_ / page * page)) {
    ::madvise(const_cast<std::uint8_t*>(data_) + ahead_, want - ahead_, MADV_WILLNEED);
    ahead_ = want;
  }
}

}  // namespace detail

namespace {

using detail::Source;

/// Moves scalars that are really intensity / classification / GPS time into their dedicated
/// fields when their values fit exactly (e.g. PCD "intensity" F4 holding 0..246 integers), and
/// renames the other LAS fields spelt as PDAL does (ReturnNumber, ...) to the names write_las
/// stores in the standard LAS fields (las_standard_scalar_name); a name already taken by
/// another field stays as it is. The names are those of detail::dedicated_field_name, which the
/// text writer avoids for its scalars.
void promote_scalars(PointCloud& pc, const ReadOptions& opt, FileInfo& info) {
  std::string renamed;
  for (ScalarField& f : pc.scalars) {
    const char* las = opt.scalars ? las_standard_scalar_name(f.name) : nullptr;
    if (las == nullptr || f.name == las || pc.scalar(las) != nullptr) continue;
    renamed += (renamed.empty() ? "" : ", ") + f.name + " as " + las;
    f.name = las;
  }
  if (!renamed.empty()) info.notes.push_back("LAS fields read by their other names: " + renamed);
  for (std::size_t k = 0; k < pc.scalars.size();) {
    ScalarField& f = pc.scalars[k];
    const char* dedicated = detail::dedicated_field_name(f.name);
    const std::string n = dedicated != nullptr ? dedicated : "";
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
    } else if (n == "gps_time" && pc.gps_time.empty()) {
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

/// Headerless little-endian float64 x,y,z triples, streamed straight from the map. A point with a
/// non-finite coordinate, or one beyond +-kMaxCoordinate, is refused naming its byte.
class F64Reader final : public PointReader {
 public:
  explicit F64Reader(std::shared_ptr<Source> src) : src_(std::move(src)) {
    const detail::Input& in = src_->in;
    info_.format = "f64";
    if (in.size() % 24 != 0)
      detail::fail_at(in.name, in.size() - in.size() % 24,
                      "file size " + std::to_string(in.size()) +
                          " is not a multiple of 24 (3 little-endian float64 per point)");
    info_.header_point_count = in.size() / 24;
  }
  const FileInfo& info() const override { return info_; }
  const std::string& crs_wkt() const override { return crs_; }
  std::uint64_t point_count() const override { return info_.header_point_count; }
  AttributeSet attributes() const override { return AttributeSet::none(); }
  std::size_t read(PointCloud& pc, std::size_t max_points) override {
    const detail::Input& in = src_->in;
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(max_points, point_count() - next_));
    std::vector<Vec3> keep = std::move(pc.positions);
    pc = PointCloud{};
    pc.positions = std::move(keep);
    pc.positions.resize(n);
    if (n > 0) std::memcpy(pc.positions.data(), in.bytes.data() + next_ * 24, n * 24);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& p = pc.positions[i];
      if (detail::within_coordinate_bound(p.x, p.y, p.z)) continue;  // one compare per axis
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        detail::fail_at(in.name, (next_ + i) * 24,
                        "point " + std::to_string(next_ + i) + " has a non-finite coordinate");
      detail::fail_at(in.name, (next_ + i) * 24, detail::beyond_coordinate_bound(next_ + i, p.x, p.y, p.z));
    }
    next_ += n;
    in.done(next_ * 24);
    return n;
  }

 private:
  std::shared_ptr<Source> src_;
  FileInfo info_;
  std::string crs_;
  std::uint64_t next_ = 0;
};

/// Formats whose encoding is decoded in one pass at open (ASCII PLY/PCD, text, PCD
/// binary_compressed, and for now binary PLY/PCD): the whole cloud is decoded by the format
/// reader, then handed out in chunks (the memory of each handed-out chunk is not returned early).
class DecodedReader final : public PointReader {
 public:
  DecodedReader(const std::shared_ptr<Source>& src, Format format, AttributeSet want,
                const ReadOptions& opt) {
    const detail::Input& in = src->in;
    switch (format) {
      case Format::ply: pc_ = detail::read_ply(in, opt, info_); break;
      case Format::pcd: pc_ = detail::read_pcd(in, opt, info_); break;
      default: pc_ = detail::read_text(in, opt, info_); break;
    }
    promote_scalars(pc_, opt, info_);
    AttributeSet have = AttributeSet::none();
    if (!pc_.rgb.empty()) have.add(Attribute::rgb);
    if (!pc_.intensity.empty()) have.add(Attribute::intensity);
    if (!pc_.classification.empty()) have.add(Attribute::classification);
    if (!pc_.gps_time.empty()) have.add(Attribute::gps_time);
    if (!pc_.normals.empty()) have.add(Attribute::normals);
    if (!pc_.scalars.empty() && opt.scalars) have.add(Attribute::scalars);
    attrs_ = want & have;
    crs_ = std::move(pc_.crs_wkt);
    count_ = pc_.size();
  }
  const FileInfo& info() const override { return info_; }
  const std::string& crs_wkt() const override { return crs_; }
  std::uint64_t point_count() const override { return count_; }
  AttributeSet attributes() const override { return attrs_; }
  std::size_t read(PointCloud& out, std::size_t max_points) override {
    const std::size_t b = next_, n = std::min<std::size_t>(max_points, pc_.size() - next_), e = b + n;
    if (b == 0 && n == pc_.size() && n > 0) {  // everything in one chunk: hand the arrays over
      out = std::move(pc_);
      if (!attrs_.has(Attribute::rgb)) out.rgb.clear();
      if (!attrs_.has(Attribute::intensity)) out.intensity.clear();
      if (!attrs_.has(Attribute::classification)) out.classification.clear();
      if (!attrs_.has(Attribute::gps_time)) out.gps_time.clear();
      if (!attrs_.has(Attribute::normals)) out.normals.clear();
      if (!attrs_.has(Attribute::scalars)) out.scalars.clear();
      out.crs_wkt.clear();
      pc_ = PointCloud{};
      next_ = e;
      done_ = true;
      return n;
    }
    if (done_) return 0;
    auto take = [&](auto& dst, auto& src, bool keep) {
      dst.clear();
      if (keep && !src.empty()) dst.assign(src.begin() + static_cast<std::ptrdiff_t>(b), src.begin() + static_cast<std::ptrdiff_t>(e));
    };
    take(out.positions, pc_.positions, true);
    take(out.rgb, pc_.rgb, attrs_.has(Attribute::rgb));
    take(out.intensity, pc_.intensity, attrs_.has(Attribute::intensity));
    take(out.classification, pc_.classification, attrs_.has(Attribute::classification));
    take(out.gps_time, pc_.gps_time, attrs_.has(Attribute::gps_time));
    take(out.normals, pc_.normals, attrs_.has(Attribute::normals));
    out.scalars.clear();
    if (attrs_.has(Attribute::scalars))
      for (const ScalarField& f : pc_.scalars) {
        out.scalars.push_back({f.name, {}});
        take(out.scalars.back().values, f.values, true);
      }
    out.crs_wkt.clear();
    next_ = e;
    return n;
  }

 private:
  PointCloud pc_;
  FileInfo info_;
  std::string crs_;
  AttributeSet attrs_;
  std::size_t next_ = 0, count_ = 0;
  bool done_ = false;
};

std::unique_ptr<PointReader> open_source(const std::shared_ptr<Source>& src, Format format,
                                         AttributeSet attrs, const ReadOptions& opt) {
  if (!opt.scalars) attrs = AttributeSet{attrs.bits & ~static_cast<std::uint32_t>(Attribute::scalars)};
  attrs = AttributeSet{attrs.bits & ~static_cast<std::uint32_t>(Attribute::id)};  // ids are an index file's
  switch (format) {
    case Format::las: return detail::open_las(src, attrs, opt);
    case Format::f64: return std::make_unique<F64Reader>(src);
    default: return std::make_unique<DecodedReader>(src, format, attrs, opt);
  }
}

}  // namespace

AttributeSet AttributeSet::parse(const std::string& list) {
  static const std::pair<const char*, Attribute> names[] = {
      {"rgb", Attribute::rgb},           {"intensity", Attribute::intensity},
      {"classification", Attribute::classification}, {"gps_time", Attribute::gps_time},
      {"normals", Attribute::normals},   {"scalars", Attribute::scalars}, {"id", Attribute::id}};
  AttributeSet s = none();
  std::size_t p = 0;
  while (p <= list.size()) {
    std::size_t q = list.find(',', p);
    if (q == std::string::npos) q = list.size();
    std::string w = ascii_lower(list.substr(p, q - p));
    p = q + 1;
    if (w.empty() || w == "none") continue;  // NOLINT
    if (w == "all") {
      s = all();
      continue;
    }
    bool ok = false;
    for (const auto& [n, a] : names)
      if (w == n) s.add(a), ok = true;
    if (!ok)
      throw std::invalid_argument("attribute '" + w +
                                  "': expected rgb, intensity, classification, gps_time, normals, "
                                  "scalars, id, all or none");
  }
  return s;
}

std::string AttributeSet::to_string() const {
  static const char* names[] = {"rgb", "intensity", "classification", "gps_time", "normals", "scalars", "id"};
  std::string out;
  for (int k = 0; k < 7; ++k)
    if (bits & (1u << k)) {
      if (!out.empty()) out.push_back(',');
      out.append(names[k]);
    }
  return out;
}

std::unique_ptr<PointReader> open_point_reader(const std::filesystem::path& path, AttributeSet attributes,
                                               const ReadOptions& options) {
  const Format format = format_from_extension(path);
  auto src = std::make_shared<Source>();
  src->map = std::make_unique<detail::MappedFile>(path);
  detail::MappedFile* map = src->map.get();
  src->in = detail::Input{map->bytes(), path.string(), [map](std::uint64_t upto) { map->release(upto); }};
  return open_source(src, format, attributes, options);
}

std::unique_ptr<PointReader> open_point_reader(std::span<const std::uint8_t> bytes, Format format,
                                               const std::string& name, AttributeSet attributes,
                                               const ReadOptions& options) {
  auto src = std::make_shared<Source>();
  src->in = detail::Input{bytes, name, {}};
  return open_source(src, format, attributes, options);
}

}  // namespace rayscan::io
