// The index file (.rsi): external-memory build and memory-mapped open. Layout: docs/index-format.md.
#include "rayscan/site/index_file.hpp"
#include "rayscan/base/input_file.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/crc32c.hpp"
#include "rayscan/octree/morton_sort.hpp"
#include "rayscan/octree/spacing.hpp"
#include "readers.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <thread>
#include <unordered_map>
#include <bitset>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <fstream>
#include <functional>
#include <future>
#include <limits>
#include <mutex>
#include <optional>
#include <queue>
#include <sstream>
#include <type_traits>

namespace rayscan::io {

namespace {

namespace fs = std::filesystem;
using detail::HugeArray;
using detail::kDirectAlign;
using detail::round_up_direct;

// ---- format constants (docs/index-format.md) ----------------------------------------------------
constexpr char kMagic[8] = {'R', 'S', 'I', 'N', 'D', 'E', 'X', '\0'};
constexpr std::uint32_t kVersion = 4;
constexpr std::uint32_t kEndianMarker = 0x01020304;
constexpr std::uint64_t kHeaderBytes = 4096;
constexpr std::uint64_t kAlign = 4096;
constexpr std::uint32_t kMaxSections = 16;
constexpr std::size_t kTableOffset = 128;
constexpr std::size_t kEntryBytes = 32;
constexpr std::size_t kNodeBytes = 32;
constexpr std::size_t kCrcOffset = 120;
constexpr std::size_t kSpacingOffset = 112;  // float64 median nearest-neighbour spacing
constexpr std::size_t kBoundsOffset = 640;   // float64[6] exact point bounds (after the table)
constexpr std::size_t kLevelsOffset = 688;   // uint64[22] points stored at each depth 0..21
constexpr unsigned kLevels = 22;
constexpr std::size_t kEncodingOffset = 864;  // uint32 PositionEncoding (version 3)
constexpr std::size_t kScaleOffset = 872;     // float64[3] LAS grid scale (las_int32)
constexpr std::size_t kGridOffsetOffset = 896;  // float64[3] LAS grid offset (las_int32)
constexpr std::size_t kRgbMulOffset = 920;      // uint32 rgb8 multiplier (version 4): 1, 256, 257; 0 without rgb8
/// Files up to this size get every section verified at open by default (IndexOpenOptions).
constexpr std::uint64_t kVerifyAllBytes = std::uint64_t{256} << 20;

enum SectionId : std::uint32_t {
  kSources = 1, kCrs = 2, kPositions = 3, kIds = 4, kRgb = 5, kIntensity = 6,
  kClassification = 7, kGpsTime = 8, kNodes = 9, kRgb8 = 10
};
constexpr std::uint32_t kLastSection = kRgb8;
/// True for the sections of N elements (one per point slot).
constexpr bool per_point(std::uint32_t id) { return (id >= kPositions && id <= kGpsTime) || id == kRgb8; }
const char* section_name(std::uint32_t id) {
  switch (id) {
    case kSources: return "sources";
    case kCrs: return "crs";
    case kPositions: return "positions";
    case kIds: return "ids";
    case kRgb: return "rgb";
    case kIntensity: return "intensity";
    case kClassification: return "classification";
    case kGpsTime: return "gps_time";
    case kNodes: return "nodes";
    case kRgb8: return "rgb8";
  }
  return "unknown";
}
/// Bytes per element of a per-point or per-node section; 1 for byte sections.
std::uint32_t elem_size(std::uint32_t id, PositionEncoding enc = PositionEncoding::float64) {
  switch (id) {
    case kPositions: return static_cast<std::uint32_t>(position_bytes(enc));
    case kIds: return 4;
    case kRgb: return 6;
    case kRgb8: return 3;
    case kIntensity: return 2;
    case kClassification: return 1;
    case kGpsTime: return 8;
    case kNodes: return kNodeBytes;
    default: return 1;
  }
}

static_assert(sizeof(Vec3) == 24 && alignof(Vec3) <= 8, "positions section is an array of 3 float64");
static_assert(sizeof(Rgb16) == 6, "rgb section is an array of 3 uint16");
static_assert(sizeof(IndexNodeRecord) == kNodeBytes);
static_assert(offsetof(IndexNodeRecord, lo) == 0 && offsetof(IndexNodeRecord, hi) == 12 &&
                  offsetof(IndexNodeRecord, first) == 24 && offsetof(IndexNodeRecord, packed) == 28,
              "the nodes section is read in place as IndexNodeRecord");
static_assert(std::endian::native == std::endian::little, "the index file is little-endian");

std::uint64_t align_up(std::uint64_t v) { return (v + kAlign - 1) / kAlign * kAlign; }

/// The section and header checksum (version 2: CRC-32C, hardware-accelerated; docs/index-format.md).
std::uint32_t crc32_of(const void* p, std::size_t n, std::uint32_t crc = 0) { return crc32c(p, n, crc); }

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08x", v);
  return buf;
}

[[noreturn]] void io_fail(const fs::path& p, const std::string& what) {
  throw std::runtime_error(p.string() + ": " + what + ": " + std::strerror(errno));
}

/// An owned file descriptor with full-length pwrite/pread that throw on failure (ENOSPC etc.).
class Fd {
 public:
  Fd(const fs::path& p, int flags, mode_t mode = 0644) : path_(p) {
    fd_ = ::open(p.c_str(), flags | O_CLOEXEC, mode);
    if (fd_ < 0) io_fail(p, "cannot open");
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  void pwrite_all(const void* data, std::size_t n, std::uint64_t off) {
    const auto* p = static_cast<const char*>(data);
    while (n > 0) {
      const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(off));
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        if (w == 0) errno = ENOSPC;
        io_fail(path_, "write of " + std::to_string(n) + " bytes at byte " + std::to_string(off) + " failed");
      }
      p += w;
      n -= static_cast<std::size_t>(w);
      off += static_cast<std::uint64_t>(w);
    }
  }
  /// Reads up to n bytes at off; returns bytes read (less only at end of file). On an O_DIRECT
  /// descriptor a read that ends off a block boundary is the end of the file: the loop stops
  /// there rather than read again at an unaligned offset.
  std::size_t pread_some(void* data, std::size_t n, std::uint64_t off) {
    auto* p = static_cast<char*>(data);
    std::size_t got = 0;
    while (got < n) {
      const ssize_t r = ::pread(fd_, p + got, n - got, static_cast<off_t>(off + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) io_fail(path_, "read failed at byte " + std::to_string(off + got));
      if (r == 0) break;
      got += static_cast<std::size_t>(r);
      if (direct_ && got % 4096 != 0) break;
    }
    return got;
  }
  [[nodiscard]] int get() const { return fd_; }
  /// Opens with O_DIRECT where the file system takes it (not tmpfs, say), else as a plain open.
  static Fd direct(const fs::path& p, int flags) {
    const int d = ::open(p.c_str(), flags | O_DIRECT | O_CLOEXEC, 0644);
    if (d >= 0) return Fd(d, p, true);
    return Fd(p, flags);
  }
  /// True when opened with O_DIRECT: offsets, lengths and buffers of reads and writes must be
  /// multiples of kDirectAlign (the page cache is bypassed).
  [[nodiscard]] bool is_direct() const { return direct_; }
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)), path_(std::move(o.path_)), direct_(o.direct_) {}

 private:
  Fd(int d, fs::path p, bool direct) : fd_(d), path_(std::move(p)), direct_(direct) {}
  int fd_ = -1;
  fs::path path_;
  bool direct_ = false;
};


/// Writes page-aligned buffers to O_DIRECT descriptors on a thread of its own, so that the
/// builder's in-order sink never waits for the disk: a fixed pool of buffers (page-aligned,
/// kDirectAlign multiples) is acquired, filled, submitted and recycled after its write. Errors
/// (a full disk) are kept and rethrown by the next acquire/submit/drain.
class DirectWriter {
 public:
  DirectWriter(std::size_t buffers, std::size_t bytes) : bytes_(bytes) {
    for (std::size_t i = 0; i < buffers; ++i) {
      pool_.emplace_back(bytes);
      free_.push_back(pool_.back().data());
    }
    thread_ = std::thread([this] { run(); });
  }
  DirectWriter(const DirectWriter&) = delete;
  DirectWriter& operator=(const DirectWriter&) = delete;
  ~DirectWriter() {
    {
      std::lock_guard<std::mutex> lk(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  [[nodiscard]] std::size_t buffer_bytes() const { return bytes_; }
  /// A free buffer of buffer_bytes() (waits for a write to end when all are in use).
  std::uint8_t* acquire() {
    std::unique_lock<std::mutex> lk(m_);
    cv_.wait(lk, [&] { return !free_.empty() || error_; });
    rethrow();
    std::uint8_t* b = free_.back();
    free_.pop_back();
    return b;
  }
  /// Queues the write of buf[0, len) at byte `off` of `fd` (len and off multiples of
  /// kDirectAlign); buf returns to the pool after it.
  void submit(Fd& fd, std::uint8_t* buf, std::size_t len, std::uint64_t off) {
    {
      std::lock_guard<std::mutex> lk(m_);
      rethrow();
      jobs_.push_back({&fd, buf, len, off});
    }
    cv_.notify_all();
  }
  /// Waits until every submitted write has ended; rethrows the first error.
  void drain() {
    std::unique_lock<std::mutex> lk(m_);
    cv_.wait(lk, [&] { return (jobs_.empty() && busy_ == 0) || error_; });
    rethrow();
  }

 private:
  struct Job {
    Fd* fd;
    std::uint8_t* buf;
    std::size_t len;
    std::uint64_t off;
  };
  void rethrow() {
    if (error_) std::rethrow_exception(error_);
  }
  void run() {
    std::unique_lock<std::mutex> lk(m_);
    for (;;) {
      cv_.wait(lk, [&] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // (stop_)
      const Job j = jobs_.front();
      jobs_.pop_front();
      ++busy_;
      lk.unlock();
      std::exception_ptr e;
      try {
        j.fd->pwrite_all(j.buf, j.len, j.off);
      } catch (...) {
        e = std::current_exception();
      }
      lk.lock();
      --busy_;
      if (e && !error_) error_ = e;
      free_.push_back(j.buf);
      cv_.notify_all();
    }
  }
  std::size_t bytes_;
  std::deque<HugeArray<std::uint8_t>> pool_;
  std::vector<std::uint8_t*> free_;
  std::deque<Job> jobs_;
  std::size_t busy_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
  std::mutex m_;
  std::condition_variable cv_;
  std::thread thread_;
};

/// Sequential writer into one region of a file, with a running CRC-32C of the bytes written.
/// With a DirectWriter (and an O_DIRECT descriptor; the region's offset a multiple of
/// kDirectAlign) the bytes go through its page-aligned buffers past the page cache, written in
/// the background; the last page is padded with zeros past the region's end (flush), which must
/// be free file space (sections are kAlign-aligned). Why: on a VM whose balloon reports free
/// memory to the host, each fresh page-cache page is a host fault on first touch, and buffered
/// writes of the output cost ~1.5 s of CPU per GB against ~0.1 s direct (bench/notes/).
class SectionWriter {
 public:
  SectionWriter(Fd& fd, std::uint64_t offset, std::size_t buffer_bytes, DirectWriter* direct = nullptr)
      : fd_(&fd), off_(offset) {
    if (direct != nullptr && fd.is_direct()) {
      if (offset % kDirectAlign != 0) throw std::logic_error("index build: a direct section off its alignment");
      dw_ = direct;
    } else {
      buf_.reserve(buffer_bytes);
    }
  }
  void write(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    if (dw_ != nullptr) {
      crc_ = crc32_of(b, n, crc_);
      while (n > 0) {
        if (cur_ == nullptr) cur_ = dw_->acquire(), fill_ = 0;
        const std::size_t take = std::min(n, dw_->buffer_bytes() - fill_);
        std::memcpy(cur_ + fill_, b, take);
        fill_ += take, b += take, n -= take;
        if (fill_ == dw_->buffer_bytes()) submit(fill_);
      }
      return;
    }
    if (buf_.size() + n > buf_.capacity()) flush();
    if (n >= buf_.capacity()) {
      emit(b, n);
      return;
    }
    buf_.insert(buf_.end(), b, b + n);
  }
  /// Writes what is buffered. Direct: only at the end of the section (the last page padded;
  /// the write may still run: DirectWriter::drain).
  void flush() {
    if (dw_ != nullptr) {
      if (cur_ != nullptr && fill_ > 0) {
        const std::size_t len = round_up_direct(fill_), real = fill_;
        std::memset(cur_ + fill_, 0, len - fill_);
        submit(len);
        written_ -= len - real;
      }
      return;
    }
    if (!buf_.empty()) emit(buf_.data(), buf_.size());
    buf_.clear();
  }
  [[nodiscard]] std::uint32_t crc() const { return crc_; }
  [[nodiscard]] std::uint64_t written() const { return written_; }

 private:
  void emit(const std::uint8_t* p, std::size_t n) {
    fd_->pwrite_all(p, n, off_ + written_);
    crc_ = crc32_of(p, n, crc_);
    written_ += n;
  }
  void submit(std::size_t len) {
    dw_->submit(*fd_, cur_, len, off_ + written_);
    written_ += len;
    cur_ = nullptr;
    fill_ = 0;
  }
  Fd* fd_;
  std::uint64_t off_;
  std::uint64_t written_ = 0;
  std::uint32_t crc_ = 0;
  std::vector<std::uint8_t> buf_;
  DirectWriter* dw_ = nullptr;   // direct mode: the background writer
  std::uint8_t* cur_ = nullptr;  // ... its buffer being filled, to fill_
  std::size_t fill_ = 0;
};

struct SectionEntry {
  std::uint32_t id = 0, elem = 0;
  std::uint64_t offset = 0, size = 0;
  std::uint32_t crc = 0;
};

/// The fixed header (docs/index-format.md, "Header").
struct Header {
  std::uint64_t points = 0, nodes = 0;
  AABB cell;
  OctreeConfig config;
  std::uint32_t depth = 0;
  std::uint32_t attributes = 0;
  double spacing = 0.0;  ///< median_nn_spacing_by_id of the stored points
  AABB bounds;           ///< exact bounds of the stored positions (bounds_of)
  std::array<std::uint64_t, kLevels> levels{};  ///< points per depth
  PositionEncoding encoding = PositionEncoding::float64;
  Vec3 grid_scale{1.0}, grid_offset{0.0};  ///< las_int32 only
  std::uint32_t rgb_mul = 0;  ///< the rgb8 section's multiplier (1, 256, 257), 0 without it
  std::vector<SectionEntry> sections;
};

/// The positions encoding a build writes: decided by the read pass (every point checked to decode
/// bit-identically), then applied by encode() to the sorted positions (docs/index-format.md,
/// "Positions").
struct PositionCodec {
  PositionEncoding enc = PositionEncoding::float64;
  Vec3 scale{1.0}, offset{0.0};
  Vec3 inv_scale{1.0};  ///< 1 / scale (grid_int)
  // Read pass state: still possible for every point seen so far.
  bool grid_ok = true, f32_ok = true;
  bool grid_set = false;

  static bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
  /// The int32 grid value of coordinate v on axis a, or false when v is not exactly one.
  bool grid_value(double v, int a, std::int32_t& out) const {
    const double k = std::nearbyint((v - offset[a]) / scale[a]);
    if (!(k >= -2147483648.0 && k <= 2147483647.0)) return false;
    out = static_cast<std::int32_t>(k);
    return same_bits(las_coordinate(out, scale[a], offset[a]), v);
  }
  /// grid_value() mostly without its division: q = (v - offset) * (1 / scale) differs from
  /// grid_value's quotient by less than 2e-6 while |q| <= 2^31 (a few ulps relative), so when q
  /// lies within 0.25 of an integer k both round to k and the round trip decides; otherwise
  /// grid_value does.
  bool grid_fast(double v, int a, std::int32_t& out) const {
    const double q = (v - offset[a]) * inv_scale[a], k = std::nearbyint(q);
    if (std::abs(q - k) <= 0.25 && k >= -2147483648.0 && k <= 2147483647.0) {
      out = static_cast<std::int32_t>(k);
      return same_bits(las_coordinate(out, scale[a], offset[a]), v);
    }
    return grid_value(v, a, out);
  }
  /// grid_value's int32 for a coordinate v known to have one (the read pass checked it).
  [[nodiscard]] std::int32_t grid_int(double v, int a) const {
    std::int32_t out = 0;
    (void)grid_fast(v, a, out);
    return out;
  }
  /// A new source: its integer grid (PointReader::integer_grid) must be the first source's.
  void source(const std::optional<std::pair<Vec3, Vec3>>& g) {
    if (!g) grid_ok = false;
    else if (!grid_set) scale = g->first, offset = g->second, inv_scale = 1.0 / scale, grid_set = true;
    else if (!(g->first == scale && g->second == offset)) grid_ok = false;
  }
  /// True when every coordinate of p is exactly an int32 value of the grid (las_int32 encodes it).
  [[nodiscard]] bool on_grid(const Vec3& p) const {
    std::int32_t k;
    return grid_fast(p[0], 0, k) && grid_fast(p[1], 1, k) && grid_fast(p[2], 2, k);
  }
  /// True when every coordinate of p is exactly a float (float32 encodes it).
  static bool is_f32(const Vec3& p) {
    for (int a = 0; a < 3; ++a) {
      const double v = p[a];  // (a double beyond the float range is not converted: UB)
      if (!(std::abs(v) <= static_cast<double>(std::numeric_limits<float>::max()) &&
            same_bits(static_cast<double>(static_cast<float>(v)), v)))
        return false;
    }
    return true;
  }
  /// Chooses the most compact exact encoding once every point was checked (float64 unless `compact`).
  void decide(bool compact) {
    enc = !compact                ? PositionEncoding::float64
          : grid_ok && grid_set ? PositionEncoding::las_int32
          : f32_ok            ? PositionEncoding::float32
                              : PositionEncoding::float64;
  }
  [[nodiscard]] std::size_t bytes() const { return position_bytes(enc); }
  /// Encodes the n float64 triples at `src` (any alignment) into out (n * bytes() bytes).
  void encode(const void* src, std::size_t n, std::uint8_t* out) const {
    if (enc == PositionEncoding::float64) {
      std::memcpy(out, src, n * sizeof(Vec3));
      return;
    }
    for (std::size_t i = 0; i < n; ++i) {
      double p[3];
      std::memcpy(p, static_cast<const std::uint8_t*>(src) + 24 * i, 24);
      if (enc == PositionEncoding::las_int32) {
        std::int32_t v[3];
        for (int a = 0; a < 3; ++a) v[a] = grid_int(p[a], a);  // checked by the read pass
        std::memcpy(out + 12 * i, v, 12);
      } else {
        const float f[3] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
        std::memcpy(out + 12 * i, f, 12);
      }
    }
  }
};

template <class T>
void put(std::uint8_t* b, std::size_t off, T v) {
  std::memcpy(b + off, &v, sizeof(T));
}
template <class T>
T get(const std::uint8_t* b, std::size_t off) {
  T v;
  std::memcpy(&v, b + off, sizeof(T));
  return v;
}

std::vector<std::uint8_t> encode_header(const Header& h) {
  std::vector<std::uint8_t> b(kHeaderBytes, 0);
  std::memcpy(b.data(), kMagic, 8);
  put<std::uint32_t>(b.data(), 8, kVersion);
  put<std::uint32_t>(b.data(), 12, static_cast<std::uint32_t>(kHeaderBytes));
  put<std::uint32_t>(b.data(), 16, kEndianMarker);
  put<std::uint32_t>(b.data(), 20, static_cast<std::uint32_t>(h.sections.size()));
  put<std::uint64_t>(b.data(), 24, h.points);
  put<std::uint64_t>(b.data(), 32, h.nodes);
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), 40 + 8 * k, h.cell.lo[k]);
    put<double>(b.data(), 64 + 8 * k, h.cell.hi[k]);
  }
  put<std::uint32_t>(b.data(), 88, static_cast<std::uint32_t>(h.config.layout));
  put<std::uint32_t>(b.data(), 92, h.config.capacity);
  put<std::uint32_t>(b.data(), 96, h.config.max_depth);
  put<std::uint32_t>(b.data(), 100, h.config.depth);
  put<std::uint32_t>(b.data(), 104, h.depth);
  put<std::uint32_t>(b.data(), 108, h.attributes);
  put<double>(b.data(), kSpacingOffset, h.spacing);
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), kBoundsOffset + 8 * k, h.bounds.lo[k]);
    put<double>(b.data(), kBoundsOffset + 24 + 8 * k, h.bounds.hi[k]);
  }
  for (unsigned d = 0; d < kLevels; ++d) put<std::uint64_t>(b.data(), kLevelsOffset + 8 * d, h.levels[d]);
  put<std::uint32_t>(b.data(), kEncodingOffset, static_cast<std::uint32_t>(h.encoding));
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), kScaleOffset + 8 * k, h.grid_scale[k]);
    put<double>(b.data(), kGridOffsetOffset + 8 * k, h.grid_offset[k]);
  }
  put<std::uint32_t>(b.data(), kRgbMulOffset, h.rgb_mul);
  for (std::size_t i = 0; i < h.sections.size(); ++i) {
    const SectionEntry& s = h.sections[i];
    const std::size_t o = kTableOffset + i * kEntryBytes;
    put<std::uint32_t>(b.data(), o, s.id);
    put<std::uint32_t>(b.data(), o + 4, s.elem);
    put<std::uint64_t>(b.data(), o + 8, s.offset);
    put<std::uint64_t>(b.data(), o + 16, s.size);
    put<std::uint32_t>(b.data(), o + 24, s.crc);
  }
  put<std::uint32_t>(b.data(), kCrcOffset, crc32_of(b.data(), b.size()));
  return b;
}

std::string encode_sources(const std::vector<IndexSource>& src) {
  std::string out;
  for (const IndexSource& s : src)
    out += std::to_string(s.size) + "\t" + std::to_string(s.mtime_ns) + "\t" + std::to_string(s.points) +
           "\t" + std::to_string(s.first_id) + "\t" + s.format + "\t" + s.path + "\n";
  return out;
}

std::int64_t mtime_ns(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return 0;
  return static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
}

// ---- build ---------------------------------------------------------------------------------------

/// The stored attributes of a build and the run buffer's bytes per point for the budget
/// (`bytes`: 36 plus the attributes, as sized before the compact run records, so that a --memory
/// value gives the same runs; the buffer holds a float64 position, the attributes and, in a
/// multi-run build, an 8-byte Morton code: 32 plus the attributes).
struct RecordLayout {
  bool rgb = false, intensity = false, cls = false, gps = false;
  std::size_t bytes = 36;
  explicit RecordLayout(AttributeSet a)
      : rgb(a.has(Attribute::rgb)), intensity(a.has(Attribute::intensity)),
        cls(a.has(Attribute::classification)), gps(a.has(Attribute::gps_time)) {
    bytes += (gps ? 8 : 0) + (rgb ? 6 : 0) + (intensity ? 2 : 0) + (cls ? 1 : 0);
  }
};

/// Layout of one sort-run record (docs/index-format.md "Build"): the Morton code (8 bytes), the
/// point id (4, only when the ids section is written), the stored attributes (gps_time 8, rgb 6,
/// intensity 2, classification 1), then the position: the LAS int32 grid values (12) when every
/// point read before the run was written lies exactly on the sources' grid, else 3 float64 (24).
/// The merge needs no id as its tie-break: run r holds the ids that follow run r - 1's, so
/// (code, run) order is (code, id) order.
struct RunLayout {
  bool ids = false, grid = false;
  std::size_t bytes = 8, id_off = 0, gps_off = 0, rgb_off = 0, int_off = 0, cls_off = 0, pos_off = 0;
  RunLayout(const RecordLayout& L, bool with_ids, bool grid_positions) : ids(with_ids), grid(grid_positions) {
    if (ids) id_off = bytes, bytes += 4;
    if (L.gps) gps_off = bytes, bytes += 8;
    if (L.rgb) rgb_off = bytes, bytes += 6;
    if (L.intensity) int_off = bytes, bytes += 2;
    if (L.cls) cls_off = bytes, bytes += 1;
    pos_off = bytes, bytes += grid ? 12 : 24;
  }
};

/// A folder of temporary files removed (with its contents) on destruction.
struct TempDir {
  fs::path path;
  explicit TempDir(fs::path p) : path(std::move(p)) {
    std::error_code ec;
    fs::create_directories(path, ec);
    if (ec) throw std::runtime_error(path.string() + ": cannot create the temporary folder: " + ec.message());
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

/// Sequential reader of one sorted run file with a fixed buffer. Each range is read once: once
/// it is in the buffer its disk blocks are released (`fallocate` PUNCH_HOLE, best effort: ignored
/// where the file system lacks it), so the runs shrink while the merge writes the sections and the
/// build's disk peak stays near the runs' size instead of runs + output (1e9 points: 36 GB less).
class RunReader {
 public:
  /// `buffer_bytes`: the reader's memory, split between the buffer being read and the one
  /// being filled next, in the background when `background` (a thread per read in flight: for
  /// a merge of few runs), else when the first is used up.
  RunReader(const fs::path& p, std::size_t rec, std::size_t buffer_bytes, bool background)
      : background_(background), fd_(Fd::direct(p, O_RDWR)), rec_(rec),
        cap_(std::max(round_up_direct(rec), buffer_bytes / 2 / kDirectAlign * kDirectAlign)),
        buf_{HugeArray<std::uint8_t>(kDirectAlign + cap_), HugeArray<std::uint8_t>(kDirectAlign + cap_)} {
    struct stat st {};
    if (::fstat(fd_.get(), &st) != 0) io_fail(p, "cannot stat");
    size_ = static_cast<std::uint64_t>(st.st_size) / rec_ * rec_;
    start_read(0);
    refill();
  }
  RunReader(const RunReader&) = delete;
  RunReader& operator=(const RunReader&) = delete;
  ~RunReader() {
    if (background_ && pending_.valid()) pending_.wait();  // a deferred read is never run
  }
  [[nodiscard]] bool done() const { return pos_ >= len_; }
  [[nodiscard]] const std::uint8_t* cur() const { return base_ + pos_; }
  /// Records from cur() to the end of the buffer.
  [[nodiscard]] std::size_t left() const { return (len_ - pos_) / rec_; }
  /// The Morton code of record i of the buffer, counted from cur() (i < left()).
  [[nodiscard]] std::uint64_t code(std::size_t i) const { return get<std::uint64_t>(cur() + i * rec_, 0); }
  /// The number of records from cur() whose code is below `limit` (binary search of the buffer
  /// from record `from` on, which must be below it; to `to`, default the buffer's end).
  [[nodiscard]] std::size_t lower_bound(std::uint64_t limit, std::size_t from = 0, std::size_t to = ~std::size_t{0}) const {
    std::size_t lo = from, hi = std::min(to, left());
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      if (code(mid) < limit) lo = mid + 1;
      else hi = mid;
    }
    return lo;
  }
  /// True when the buffer holds the run's last records (no refill follows).
  [[nodiscard]] bool at_end() const { return off_ >= size_; }
  /// The record size (RunLayout::bytes).
  [[nodiscard]] std::size_t record_bytes() const { return rec_; }
  /// Moves past n <= left() records; the buffer is refilled (every record moved) when it is used up.
  void skip(std::size_t n) {
    pos_ += n * rec_;
    if (pos_ >= len_) refill();
  }

 private:
  /// Reads the next cap_ bytes of the run into buffer `i`'s data area (after its carry page) in
  /// the background, then releases them from the disk.
  void start_read(int i) {
    std::uint8_t* data = buf_[i].data() + kDirectAlign;
    const std::uint64_t at = next_off_;
    next_off_ += cap_;
    pending_ = std::async(background_ ? std::launch::async : std::launch::deferred, [this, data, at] {
      const std::size_t n = fd_.pread_some(data, cap_, at);
      if (n > 0)
        (void)::fallocate(fd_.get(), FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(at),
                          static_cast<off_t>(n));
      return n;
    });
  }
  /// Switches to the buffer read in the background, behind the unread bytes of a record cut by
  /// the previous read (carried into the page before the data: records are < 4 KiB), and starts
  /// reading the next bytes into the other buffer. Direct reads need aligned offsets and
  /// lengths, hence the carry instead of reading from a record boundary.
  void refill() {
    const std::size_t carry = avail_ - pos_;  // < rec_: a partial record
    if (!pending_.valid()) {  // the run is read to its end: nothing follows
      base_ += pos_;
      avail_ = carry, len_ = 0, pos_ = 0;
      return;
    }
    const int next = 1 - cur_buf_;
    std::uint8_t* data = buf_[next].data() + kDirectAlign;
    const std::size_t n = pending_.get();  // rethrows a read error
    if (carry > 0) std::memmove(data - carry, base_ + pos_, carry);
    off_ += n;
    base_ = data - carry;
    avail_ = carry + n;
    len_ = avail_ / rec_ * rec_;
    pos_ = 0;
    cur_buf_ = next;
    if (n == cap_ && off_ < size_) start_read(1 - next);
  }
  bool background_;
  Fd fd_;
  std::size_t rec_, cap_;
  std::array<HugeArray<std::uint8_t>, 2> buf_;  ///< each: one page for the carried bytes, then cap_ bytes
  int cur_buf_ = 1;                             ///< the buffer base_ points into
  std::future<std::size_t> pending_;            ///< the background read (bytes read)
  const std::uint8_t* base_ = nullptr;  ///< first unread record of the last read
  std::size_t pos_ = 0, len_ = 0, avail_ = 0;  ///< from base_: position, whole records, bytes
  std::uint64_t off_ = 0, next_off_ = 0, size_ = 0;  ///< bytes consumed / requested / whole records
};

/// Tournament tree of losers over k sorted sequences (Knuth, TAOCP vol. 3, section 5.4.1,
/// "replacement selection" with a tree of losers): the winner is the sequence with the least
/// (key, sequence) pair; replacing the winner's key replays one leaf-to-root path, one comparison
/// per level (log2 k), where a binary heap's pop and push take two sift passes. Keys are < kDone;
/// an exhausted sequence has key kDone and sorts last.
class LoserTree {
 public:
  static constexpr std::uint64_t kDone = ~std::uint64_t{0};
  /// `keys[r]`: the first key of sequence r (kDone when it is empty).
  explicit LoserTree(const std::vector<std::uint64_t>& keys) {
    p_ = 1;
    while (p_ < keys.size()) p_ *= 2;
    key_.assign(p_, kDone);
    std::copy(keys.begin(), keys.end(), key_.begin());
    loser_.assign(p_, 0);
    std::vector<std::uint32_t> win(2 * p_);
    for (std::size_t i = 0; i < p_; ++i) win[p_ + i] = static_cast<std::uint32_t>(i);
    for (std::size_t n = p_ - 1; n >= 1; --n) {
      const std::uint32_t a = win[2 * n], b = win[2 * n + 1];
      win[n] = less(a, b) ? a : b;
      loser_[n] = less(a, b) ? b : a;
    }
    loser_[0] = win[1];
  }
  /// The sequence holding the least key (kDone when every sequence is exhausted).
  [[nodiscard]] std::uint32_t winner() const { return loser_[0]; }
  [[nodiscard]] std::uint64_t winner_key() const { return key_[loser_[0]]; }
  /// The least (key, sequence) pair among the sequences other than the winner's ({kDone, k} when
  /// there is none): one of the losers on the winner's path, since each lost only to it.
  [[nodiscard]] std::pair<std::uint64_t, std::uint32_t> runner_up() const {
    const std::uint32_t w = loser_[0];
    std::uint32_t best = w;
    for (std::size_t n = (w + p_) / 2; n >= 1; n /= 2)
      if (best == w || less(loser_[n], best)) best = loser_[n];
    if (best == w) return {kDone, static_cast<std::uint32_t>(p_)};
    return {key_[best], best};
  }
  /// Gives the winner its next key (kDone when it is exhausted) and finds the new winner.
  void replace(std::uint64_t key) {
    std::uint32_t w = loser_[0];
    key_[w] = key;
    for (std::size_t n = (w + p_) / 2; n >= 1; n /= 2)
      if (less(loser_[n], w)) std::swap(loser_[n], w);
    loser_[0] = w;
  }

 private:
  [[nodiscard]] bool less(std::uint32_t a, std::uint32_t b) const {
    return key_[a] < key_[b] || (key_[a] == key_[b] && a < b);
  }
  std::size_t p_ = 1;                 ///< leaves: k rounded up to a power of two
  std::vector<std::uint64_t> key_;    ///< current key per leaf
  std::vector<std::uint32_t> loser_;  ///< [0]: the winner; [n >= 1]: the loser at internal node n
};

/// Thrown by build_index_impl when LAS tiles read with their colour as stored cannot share one
/// colour rule (some 8-bit, some 16-bit, or one all zero): the build is repeated with the
/// readers' own per-file normalisation.
struct ColourRetry {};

/// The colour encoding a build writes (docs/index-format.md "Colour"): the read pass checks every
/// delivered rgb value v (uint16) against v = b * m with b <= 255 for each multiplier m in
/// {1, 256, 257} (8-bit colour stored raw, in the high byte, or scaled by 257); decide() picks the
/// first that held for every value (rgb8 section, 3 bytes per point, decoded as b * m, so
/// bit-identical), else 0 (the 6-byte rgb section as read).
struct RgbCodec {
  std::uint32_t bad1 = 0, bad256 = 0, bad257 = 0;  ///< non-zero: some value is not b * m
  std::uint32_t mul = 0;                           ///< decided: 1, 256, 257, or 0 (16-bit section)
  /// The factor from the values read to the values stored: 257 when LAS tiles read as stored
  /// (ReadOptions::stored_colour) all hold 8-bit colour, which their readers would have scaled.
  std::uint16_t fix = 1;
  /// Bits of each candidate multiplier that n colours rule out (bit 0: 1, bit 1: 256, bit 2: 257).
  static std::uint32_t ruled_out(const Rgb16* c, std::size_t n) {
    std::uint32_t a = 0, h = 0, q = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (const std::uint32_t v : {std::uint32_t{c[i].r}, std::uint32_t{c[i].g}, std::uint32_t{c[i].b}}) {
        a |= v > 255u;
        h |= v & 255u;
        q |= (v % 257u) != 0u;
      }
    return (a != 0 ? 1u : 0u) | (h != 0 ? 2u : 0u) | (q != 0 ? 4u : 0u);
  }
  /// Records the multipliers ruled out (ruled_out()'s bits).
  void rule_out(std::uint32_t bits) { bad1 |= bits & 1u, bad256 |= bits & 2u, bad257 |= bits & 4u; }
  [[nodiscard]] bool undecided() const { return !(bad1 && bad256 && bad257); }
  /// Picks the multiplier (compact false: always the 16-bit section).
  void decide(bool compact) {
    mul = !compact ? 0u : !bad1 ? 1u : !bad256 ? 256u : !bad257 ? 257u : 0u;
  }
  /// The readers' colour rule (docs/formats.md) from the largest stored value of each LAS input
  /// read as stored: all zero drops the colour, <= 255 means 8-bit colour scaled by 257. When
  /// every file holds 8-bit colour the values stored are the values read x 257 (fix), which are
  /// all b x 257: multiplier 257. When every file holds 16-bit colour the values read are final.
  /// Otherwise (files differ, or one is all zero) throws ColourRetry.
  /// Files without points (`points[f] == 0`) have no colour to decide (their readers decide none).
  void stored_scale(const std::vector<std::uint16_t>& file_max, const std::vector<std::uint64_t>& points) {
    bool eight = true, sixteen = true;
    for (std::size_t f = 0; f < file_max.size(); ++f) {
      if (points[f] == 0) continue;
      eight = eight && file_max[f] > 0 && file_max[f] <= 255;
      sixteen = sixteen && file_max[f] > 255;
    }
    if (eight) fix = 257, bad1 = bad256 = 1, bad257 = 0;
    else if (!sixteen) throw ColourRetry{};
  }
  /// Encodes n colours (as read) to 3 bytes each: c x fix / mul (mul != 0; every value was
  /// checked to be b * mul). Without a division in the usual cases (a per-record `div` was 7% of
  /// the merge): fix == mul is c itself, 256 a shift, and v / 257 == (v * 0xFF01) >> 24 for
  /// every v < 2^16 (checked exhaustively).
  void encode(const Rgb16* c, std::size_t n, std::uint8_t* out) const {
    auto each = [&](auto op) {
      for (std::size_t i = 0; i < n; ++i) {
        out[3 * i] = static_cast<std::uint8_t>(op(c[i].r));
        out[3 * i + 1] = static_cast<std::uint8_t>(op(c[i].g));
        out[3 * i + 2] = static_cast<std::uint8_t>(op(c[i].b));
      }
    };
    const std::uint32_t f = fix, m = mul;
    if (f == m) each([](std::uint32_t v) { return v; });
    else if (f == 1 && m == 256) each([](std::uint32_t v) { return v >> 8; });
    else if (f == 1 && m == 257) each([](std::uint32_t v) { return (v * 0xFF01u) >> 24; });
    else each([f, m](std::uint32_t v) { return v * f / m; });
  }
  /// The 16-bit values stored for n colours as read (x fix).
  void widen(const Rgb16* c, std::size_t n, Rgb16* out) const {
    for (std::size_t i = 0; i < n; ++i)
      out[i] = Rgb16{static_cast<std::uint16_t>(c[i].r * fix), static_cast<std::uint16_t>(c[i].g * fix),
                     static_cast<std::uint16_t>(c[i].b * fix)};
  }
};

/// What the read pass learns from a block of points besides the points themselves: their bounds,
/// whether the positions encodings are still possible (PositionCodec) and the colour
/// multipliers ruled out (RgbCodec::ruled_out). Joined over the parallel blocks of a chunk.
struct BlockScan {
  AABB box;
  bool grid = true, f32 = true;
  std::uint32_t rgb_out = 0;
  std::uint16_t rgb_max = 0;  ///< the largest colour channel value (when asked)
  void join(const BlockScan& o) {
    box.expand(o.box);
    grid = grid && o.grid, f32 = f32 && o.f32;
    rgb_out |= o.rgb_out;
    rgb_max = std::max(rgb_max, o.rgb_max);
  }
};

/// The points of one sort run (or of the whole input when it fits the budget), structure of
/// arrays in id order: positions and the stored attributes only, in huge-page arrays of a fixed
/// capacity (no zero-fill pass; a few hundred page faults for gigabytes).
struct PointBuffer {
  HugeArray<Vec3> pos;
  HugeArray<Rgb16> rgb;
  HugeArray<std::uint16_t> intensity;
  HugeArray<std::uint8_t> cls;
  HugeArray<double> gps;
  HugeArray<std::uint64_t> codes;  ///< Morton codes on the runs' grid (multi-run builds only)
  std::size_t n = 0;  ///< points held
  [[nodiscard]] std::size_t size() const { return n; }
  [[nodiscard]] std::size_t capacity() const { return pos.size(); }
  /// Storage for `cap` points of layout L (the arrays the layout stores).
  void allocate(std::size_t cap, const RecordLayout& L, bool with_codes) {
    pos = HugeArray<Vec3>(cap);
    if (with_codes) codes = HugeArray<std::uint64_t>(cap);
    if (L.rgb) rgb = HugeArray<Rgb16>(cap);
    if (L.intensity) intensity = HugeArray<std::uint16_t>(cap);
    if (L.cls) cls = HugeArray<std::uint8_t>(cap);
    if (L.gps) gps = HugeArray<double>(cap);
  }
  void clear() { n = 0; }
  /// Appends points [i0, i0 + count) of `c` (count <= capacity() - size()), copying and scanning
  /// them in parallel blocks: the bounds, the positions encodings still possible under `codec`
  /// and the colour multipliers ruled out (skipped once `rgbc` has ruled out every one).
  BlockScan append(const PointCloud& c, std::size_t i0, std::size_t count, const RecordLayout& L,
                   const PositionCodec& codec, const RgbCodec& rgbc, bool rgb_max,
                   const OctreeRules::Quantizer* qz) {
    const bool grid0 = codec.grid_ok, f320 = codec.f32_ok, rgb0 = L.rgb && rgbc.undecided();
    const std::size_t at = n;
    BlockScan all = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(i0, i0 + count, 1 << 14), BlockScan{},
        [&](const tbb::blocked_range<std::size_t>& r, BlockScan acc) {
          const std::size_t b = r.begin(), m = r.end() - r.begin(), d = at + (b - i0);
          std::memcpy(pos.data() + d, c.positions.data() + b, m * sizeof(Vec3));
          if (L.rgb) std::memcpy(rgb.data() + d, c.rgb.data() + b, m * sizeof(Rgb16));
          if (L.intensity) std::memcpy(intensity.data() + d, c.intensity.data() + b, m * 2);
          if (L.cls) std::memcpy(cls.data() + d, c.classification.data() + b, m);
          if (L.gps) std::memcpy(gps.data() + d, c.gps_time.data() + b, m * 8);
          bool g = grid0, f = f320;
          if (qz != nullptr)  // the code now, while the points are in cache (the sort reads it twice)
            for (std::size_t i = b; i < r.end(); ++i) codes[d + (i - b)] = qz->code(c.positions[i]);
          for (std::size_t i = b; i < r.end(); ++i) {
            const Vec3& p = c.positions[i];
            acc.box.expand(p);
            if (g) g = codec.on_grid(p);
            if (f) f = PositionCodec::is_f32(p);
          }
          acc.grid = acc.grid && g, acc.f32 = acc.f32 && f;
          if (rgb0) acc.rgb_out |= RgbCodec::ruled_out(c.rgb.data() + b, m);
          if (L.rgb && rgb_max)
            for (std::size_t i = b; i < r.end(); ++i)
              acc.rgb_max = std::max({acc.rgb_max, c.rgb[i].r, c.rgb[i].g, c.rgb[i].b});
          return acc;
        },
        [](BlockScan x, const BlockScan& y) {
          x.join(y);
          return x;
        });
    n += count;
    return all;
  }
};

/// The Morton keys of the buffered points on the grid `qz`, sorted by (code, id), into `keys`
/// (reallocated only when smaller than the buffer: the runs of a build reuse one array). The
/// sort reads each code twice: from buf.codes when the copy pass computed them (multi-run
/// builds), else computed from the positions on each read.
void sort_keys(const PointBuffer& buf, const OctreeRules::Quantizer& qz, HugeArray<MortonKey>& keys) {
  if (keys.size() < buf.size()) keys = HugeArray<MortonKey>(buf.size());
  if (buf.codes.size() > 0) sort_morton_keys(buf.size(), [&](std::size_t i) { return buf.codes[i]; }, keys.data());
  else sort_morton_keys(buf.size(), [&](std::size_t i) { return qz.code(buf.pos[i]); }, keys.data());
}

/// Calls `fn(b, e)` for consecutive blocks [b, e) of [0, n) of at most kGatherBlock keys.
constexpr std::size_t kGatherBlock = std::size_t{1} << 18;
template <class Fn>
void for_blocks(std::size_t n, Fn&& fn) {
  for (std::size_t b = 0; b < n; b += kGatherBlock) fn(b, std::min(n, b + kGatherBlock));
}

/// Runs work(i) for i in [0, n) in parallel and then sink(i) for each i in order of i, one sink
/// at a time, with at most kPipelineSlots items in flight (TBB parallel_pipeline: the
/// serial_in_order last stage ends item i before item i + kPipelineSlots starts, so a caller's
/// buffer i % kPipelineSlots is never in use by two items).
constexpr std::size_t kPipelineSlots = 4;
/// The merge's items in flight (ordered_pipeline's `slots`): more than kPipelineSlots, so the
/// parts' merge runs on while the in-order sink builds a subtree of the fused node build
/// (NodeBuilder::feed; ~1 MB of records per slot).
constexpr std::size_t kMergeSlots = 16;
template <class Work, class Sink>
void ordered_pipeline(std::size_t n, const Work& work, const Sink& sink, std::size_t slots = kPipelineSlots) {
  std::size_t next = 0;
  tbb::parallel_pipeline(
      slots,
      tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                          [&](tbb::flow_control& fc) -> std::size_t {
                                            if (next == n) {
                                              fc.stop();
                                              return 0;
                                            }
                                            return next++;
                                          }) &
          tbb::make_filter<std::size_t, std::size_t>(tbb::filter_mode::parallel,
                                                     [&](std::size_t i) {
                                                       work(i);
                                                       return i;
                                                     }) &
          tbb::make_filter<std::size_t, void>(tbb::filter_mode::serial_in_order, [&](std::size_t i) { sink(i); }));
}

/// Runs fill(i, buffer) -> bytes for blocks i in [0, n) in parallel and write(i, buffer, bytes)
/// for each block in order of i, one write at a time (ordered_pipeline), each block in one of
/// kPipelineSlots buffers of `block_bytes` allocated once (huge pages: no fresh small pages per
/// block; rounded up to whole pages, so a writer may pad a block for O_DIRECT).
template <class Fill, class Write>
void pipelined_blocks(std::size_t n, std::size_t block_bytes, const Fill& fill, const Write& write) {
  std::array<HugeArray<std::uint8_t>, kPipelineSlots> slots;
  std::array<std::size_t, kPipelineSlots> bytes{};
  for (auto& sl : slots) sl = HugeArray<std::uint8_t>(round_up_direct(std::min<std::size_t>(block_bytes, n * block_bytes)));
  ordered_pipeline(
      n, [&](std::size_t i) { bytes[i % kPipelineSlots] = fill(i, slots[i % kPipelineSlots].data()); },
      [&](std::size_t i) { write(i, slots[i % kPipelineSlots].data(), bytes[i % kPipelineSlots]); });
}

/// Gathers field `src[keys[i].idx]` for keys [b, e) into `out` (parallel) and appends it to `w`.
template <class T>
void gather_write(const HugeArray<T>& src, const HugeArray<MortonKey>& keys, std::size_t b, std::size_t e,
                  std::vector<T>& out, SectionWriter& w) {
  out.resize(e - b);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 1 << 14), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) out[i - b] = src[keys[i].idx];
  });
  w.write(out.data(), out.size() * sizeof(T));
}

/// Page size of the maps below (madvise ranges are page-aligned).
std::size_t page_bytes() {
  static const std::size_t p = [] {
    const long v = ::sysconf(_SC_PAGESIZE);
    return v > 0 ? static_cast<std::size_t>(v) : std::size_t{4096};
  }();
  return p;
}

/// Read-only map of a file region (for the codes temp file and the output's positions).
/// release_below() drops the pages of [0, byte) from the process (MADV_DONTNEED: on a shared
/// read-only map the data stays in the page cache and is faulted in again if touched), so a
/// sequential pass holds a bounded number of resident pages whatever the file size.
struct ReadMap {
  void* p = nullptr;
  std::size_t n = 0;
  std::size_t released = 0;  ///< bytes [0, released) have been dropped
  ReadMap(int fd, std::size_t bytes, const fs::path& name) : n(bytes) {
    if (n == 0) return;
    p = ::mmap(nullptr, n, PROT_READ, MAP_SHARED, fd, 0);
    if (p == MAP_FAILED) {
      p = nullptr;
      io_fail(name, "cannot memory-map");
    }
  }
  ReadMap(const ReadMap&) = delete;
  ReadMap& operator=(const ReadMap&) = delete;
  ~ReadMap() {
    if (p != nullptr) ::munmap(p, n);
  }
  void release_below(std::size_t byte) {
    const std::size_t end = std::min(byte, n) / page_bytes() * page_bytes();
    if (p == nullptr || end <= released) return;
    (void)::madvise(static_cast<std::uint8_t*>(p) + released, end - released, MADV_DONTNEED);
    released = end;
  }
  /// Drops every resident page of the map (release_below's bookkeeping is kept: it only ever
  /// drops pages again).
  void drop() const {
    if (p != nullptr) (void)::madvise(p, n, MADV_DONTNEED);
  }
  /// Maps the pages of [byte, byte + len) in one call (MADV_POPULATE_READ, best effort) instead
  /// of a page fault per few pages as a sequential pass reaches them.
  void populate(std::size_t byte, std::size_t len) const {
    const std::size_t b = std::min(byte, n) / page_bytes() * page_bytes(), e = std::min(n, byte + len);
    if (p != nullptr && e > b) (void)::madvise(static_cast<std::uint8_t*>(p) + b, e - b, MADV_POPULATE_READ);
  }
};

/// The nodes section of the temporary output (docs/index-format.md, "Nodes"): records written
/// in any order, each final when written. The builders write most of them in increasing order
/// (a subtree's descendants as one block at the next free numbers) and the rest into blocks they
/// reserved before (reserve: an upper node's children, numbered before the subtrees below them,
/// and the root).
///
/// Whole pages are written by the background writer (past the page cache where the descriptor
/// is O_DIRECT): a staging buffer holds the pages from the first one not yet written; a page
/// leaves it when the in-order writes pass it, written at once if every record of it is in, else
/// kept aside (pinned) until its reserved records are (buffered writes into fresh page cache cost
/// ~1.5 s of CPU per GB on this VM: bench/notes/). Each page's CRC is kept and combined in order
/// at the end (crc32c_combine), so nothing is read back. A full
/// disk is an error from pwrite (Fd::pwrite_all, rethrown by the writer).
class NodeFile {
 public:
  /// `fd`: the output (O_DIRECT where the file system allows it, Fd::direct), written through
  /// `writer`; `offset`: the section's start (a multiple of kDirectAlign, else std::logic_error).
  /// `stage_pages` (>= 1; 0 counts as 1): the stage's size in pages
  /// (IndexBuildOptions::node_stage_pages).
  NodeFile(Fd& fd, DirectWriter& writer, std::uint64_t offset, std::size_t stage_pages)
      : fd_(fd), dw_(writer), off_(offset), stage_pages_(std::max<std::size_t>(1, stage_pages)),
        stage_(stage_pages_ * kDirectAlign) {
    if (offset % kDirectAlign != 0) throw std::logic_error("index build: the nodes section off its alignment");
  }
  /// Records [first, first + n) will be written later, after records above them (their pages
  /// are kept until then). Must be called at the in-order frontier (first = every
  /// record written or reserved so far).
  void reserve(std::size_t first, std::size_t n) {
    if (n == 0) return;
    if (first != frontier_) throw std::logic_error("index build: node records reserved off the frontier");
    for (std::size_t r = first; r < first + n; ++r) pending_[r / kPerPage].set(r % kPerPage);
    frontier_ = first + n;
    // The stage must hold the page of every record below the frontier that is not yet written:
    // the pages it leaves lie wholly below the frontier (complete, or pinned while reserved).
    while ((frontier_ - 1) / kPerPage >= stage_page_ + stage_pages_) advance(stage_page_ + stage_pages_);
  }
  /// Writes records [first, first + n) from `recs`: a block at the frontier, or reserved records.
  void write(std::size_t first, const IndexNodeRecord* recs, std::size_t n) {
    if (n == 0) return;
    if (first >= frontier_) {  // in order: advance the stage past the pages below `first`
      if (first != frontier_) throw std::logic_error("index build: a gap in the node records");
      const auto* b = reinterpret_cast<const std::uint8_t*>(recs);
      std::size_t r = first, left = n;
      while (left > 0) {
        while (r / kPerPage >= stage_page_ + stage_pages_) advance(stage_page_ + stage_pages_);
        const std::size_t room = (stage_page_ + stage_pages_) * kPerPage - r, take = std::min(left, room);
        std::memcpy(stage_.data() + (r - stage_page_ * kPerPage) * kNodeBytes, b, take * kNodeBytes);
        b += take * kNodeBytes, r += take, left -= take;
        frontier_ = r;  // (the pages advance() writes hold records below it only)
      }
      return;
    }
    for (std::size_t i = 0; i < n; ++i) {  // reserved records
      const std::size_t r = first + i, page = r / kPerPage;
      const auto pend = pending_.find(page);
      if (pend == pending_.end() || !pend->second.test(r % kPerPage))
        throw std::logic_error("index build: node record " + std::to_string(r) + " written twice");
      pend->second.reset(r % kPerPage);
      std::uint8_t* dst;
      if (page >= stage_page_) {
        if (page >= stage_page_ + stage_pages_) throw std::logic_error("index build: a reserved node record past the stage");
        dst = stage_.data() + (r - stage_page_ * kPerPage) * kNodeBytes;
      } else {
        auto it = pinned_.find(page);
        if (it == pinned_.end()) throw std::logic_error("index build: a node page written before its records");
        dst = it->second->data() + (r % kPerPage) * kNodeBytes;
      }
      std::memcpy(dst, recs + i, kNodeBytes);
      if (pend->second.none()) {
        pending_.erase(pend);
        if (page < stage_page_) {  // the last record of a pinned page: write it
          auto it = pinned_.find(page);
          write_pages(page, it->second->data(), 1);
          pinned_.erase(it);
        }
      }
    }
  }
  /// Ends the section of `n` records and returns its CRC-32C: every page written, each page's CRC
  /// combined in order.
  std::uint32_t crc(std::size_t n) {
    if (!pending_.empty() || frontier_ != n) throw std::logic_error("index build: node records missing");
    const std::size_t bytes = n * kNodeBytes, pages = (bytes + kDirectAlign - 1) / kDirectAlign;
    if (bytes % kDirectAlign != 0)  // the last page's padding (the file is cut at the section's end)
      std::memset(stage_.data() + (bytes - stage_page_ * kDirectAlign), 0, kDirectAlign - bytes % kDirectAlign);
    advance(std::max(pages, stage_page_));
    if (!pinned_.empty()) throw std::logic_error("index build: pinned node pages left");
    std::uint32_t c = 0;
    for (std::size_t p = 0; p < pages; ++p) {
      const std::size_t len = std::min(kDirectAlign, bytes - p * kDirectAlign);
      c = p == 0 ? page_crc_[0] : crc32c_combine(c, page_crc_[p], len);
    }
    return c;
  }

 private:
  static constexpr std::size_t kPerPage = kDirectAlign / kNodeBytes;  // records per page
  using Page = std::array<std::uint8_t, kDirectAlign>;  // a pinned page (copied into a writer buffer when written)

  /// Moves the stage's start to page `to` (at most its end): every page below it leaves (written,
  /// or pinned while reserved records of it are missing). The stage then starts afresh at `to`:
  /// the in-order writes and reserve() advance by whole stages, crc() to the end of the records.
  /// Its bytes are stale until written: every record is written before its page leaves, and
  /// crc() zeroes the last page's padding.
  void advance(std::size_t to) {
    if (to > stage_page_ + stage_pages_) throw std::logic_error("index build: the node stage skipped pages");
    const std::size_t end = to;
    std::size_t p = stage_page_;
    while (p < end) {
      if (pending_.count(p) != 0) {  // pinned until its reserved records are in
        auto pg = std::make_unique_for_overwrite<Page>();
        std::memcpy(pg->data(), stage_.data() + (p - stage_page_) * kDirectAlign, kDirectAlign);
        pinned_.emplace(p, std::move(pg));
        ++p;
        continue;
      }
      std::size_t q = p + 1;  // a run of complete pages: one write
      while (q < end && pending_.count(q) == 0) ++q;
      write_pages(p, stage_.data() + (p - stage_page_) * kDirectAlign, q - p);
      p = q;
    }
    stage_page_ = to;
  }
  /// Writes `count` whole pages from page `first` on (direct, in the background) and keeps the
  /// CRC of each page's records (all of a page below the frontier; the last page's records only).
  void write_pages(std::size_t first, const std::uint8_t* data, std::size_t count) {
    const std::size_t per = dw_.buffer_bytes() / kDirectAlign;  // pages per background write
    for (std::size_t k = 0; k < count; k += per) {
      const std::size_t m = std::min(per, count - k);
      std::uint8_t* buf = dw_.acquire();
      std::memcpy(buf, data + k * kDirectAlign, m * kDirectAlign);
      dw_.submit(fd_, buf, m * kDirectAlign, off_ + (first + k) * kDirectAlign);
    }
    if (page_crc_.size() < first + count) page_crc_.resize(first + count);
    for (std::size_t k = 0; k < count; ++k) {
      // Only records below the frontier are section bytes: the final page's tail is padding.
      const std::size_t page = first + k, rec0 = page * kPerPage;
      const std::size_t recs = frontier_ > rec0 ? std::min(kPerPage, frontier_ - rec0) : 0;
      page_crc_[page] = crc32_of(data + k * kDirectAlign, recs * kNodeBytes);
    }
  }

  Fd& fd_;            ///< the output (O_DIRECT where allowed)
  DirectWriter& dw_;  ///< the background writer of its pages
  std::uint64_t off_;  ///< file offset of record 0 (page-aligned: kAlign)
  const std::size_t stage_pages_;  ///< pages staged (4 MiB by default)
  HugeArray<std::uint8_t> stage_;
  std::size_t stage_page_ = 0;  ///< the page stage_[0] holds
  std::size_t frontier_ = 0;    ///< records [0, frontier_) are written or reserved
  /// page -> its reserved records not yet written (bit r % kPerPage of record r)
  std::unordered_map<std::size_t, std::bitset<kPerPage>> pending_;
  std::unordered_map<std::size_t, std::unique_ptr<Page>> pinned_;
  std::vector<std::uint32_t> page_crc_;
};

/// Node construction over the Morton-sorted codes and positions, following Octree::build_bulk
/// for the adaptive and fixed layouts: same split rule, child order, node numbering and float
/// bounds (OctreeRules), hence the identical node array. The numbering is that of one depth-first
/// pass in which a node's children are numbered as a block when the node is visited, so the
/// descendants of any node take consecutive numbers. The build runs in three steps:
///  1. plan (serial, codes only): the upper tree, the nodes of more than `every` points that
///     split, each child range found by an exponential search on the octant digit; every other
///     node reached is the root of a subtree;
///  2. the subtrees, in parallel in the order of the depth-first pass (ordered_pipeline): each
///     numbers its descendants from 1 in that pass's order, reads its own positions (Octree's
///     close_node: the float bounds of a leaf's points, widened by the children's) and keeps its
///     records; the in-order sink replays the upper nodes' blocks met before the subtree, gives
///     its descendants the next free numbers and writes the records into the NodeFile;
///  3. the upper nodes' records, their bounds widened from their children's.
/// The sorted codes are given (`codes`), or else each subtree computes its own from the decoded
/// positions on the grid `qz` (the plan's probes likewise), so the merge writes no codes file.
/// `ahead(b, e)` is called (from any thread) before a subtree reads points [b, e), `release(e)`
/// in order after the subtree that ends at e, so the caller maps its windows ahead and drops the
/// pages behind; the subtrees in flight hold at most kPipelineSlots x `every` points. Call
/// plan() then build(); or, fused into the merge (docs/index-format.md, "Build" 4), plan_counts()
/// from the read pass's points per cell, then begin_feed(), feed() with the merged positions in
/// order and end_feed(). Both write the same records (NodeFile), numbered alike.
struct NodeBuilder {
  const OctreeConfig& cfg;
  const std::uint64_t* codes;  ///< the sorted codes, or null: computed from `pos` on `qz`
  OctreeRules::Quantizer qz;
  PositionView pos;  // the written positions section (the file's encoding); fused build: its encoding only
  Vec3 cell_lo;
  NodeFile& out;
  std::function<void(std::size_t)> release;
  std::function<void(std::size_t, std::size_t)> ahead;
  IndexProgress progress;
  std::uint64_t total = 0;
  std::size_t count = 0;  ///< nodes numbered so far
  unsigned depth = 0;
  std::array<std::uint64_t, kLevels> levels{};  ///< own points per depth
  std::uint64_t every = std::uint64_t{1} << 22;  ///< most points of a subtree built as one task

  NodeBuilder(const OctreeConfig& config, const std::uint64_t* sorted_codes, const OctreeRules::Quantizer& grid,
              PositionView positions, Vec3 cell_min, NodeFile& records, std::function<void(std::size_t)> release_below,
              std::function<void(std::size_t, std::size_t)> map_ahead, IndexProgress report, std::uint64_t points)
      : cfg(config), codes(sorted_codes), qz(grid), pos(positions), cell_lo(cell_min), out(records),
        release(std::move(release_below)), ahead(std::move(map_ahead)), progress(std::move(report)), total(points) {}

  /// Step 1 over points [0, n_points). Without sorted codes, `drop()` is called every 256 probes
  /// and at the end: each probe's page fault maps up to 64 KiB of the positions around it, so the
  /// plan's scattered probes would otherwise leave gigabytes of the map resident (at 1e9 points).
  void plan(std::size_t n_points, const std::function<void()>& drop) {
    if (n_points == 0) return;
    std::size_t probes = 0;
    (void)plan(
        [&](std::size_t i) {
          if (codes != nullptr) return codes[i];
          if (++probes % 256 == 0 && drop) drop();
          return qz.code(pos[i]);
        },
        0, 0, 0, n_points);
    if (drop) drop();
  }

  /// Step 1 from the points per cell of depth `D` (the fused build: no positions needed):
  /// `prefix[c]` = the points in the cells before cell c in Morton order, prefix.size() = 8^D + 1.
  /// The same plan as plan() over the sorted codes, as long as every node it makes an upper node
  /// lies above depth D and holds points of two cells or more (so its codes differ and its
  /// children's ranges are sums of cells); otherwise returns false and plans nothing (the caller
  /// then calls plan() on the written positions).
  bool plan_counts(std::span<const std::uint64_t> prefix, unsigned D) {
    if (prefix.size() != (std::size_t{1} << (3 * D)) + 1) throw std::logic_error("index build: a cell histogram of the wrong size");
    if (prefix.back() == 0) return true;
    bool ok = true;
    (void)plan_cells(prefix, D, 0, 0, 0, prefix.back(), ok);
    if (!ok) uppers_.clear(), tasks_.clear(), events_.clear();
    return ok;
  }

  /// Steps 2 and 3 (after plan()): the subtrees in parallel from the positions view `pos`.
  void build() {
    if (tasks_.empty()) return;
    out.reserve(0, 1);  // the root is node 0
    count = 1;
    next_event_ = 0;
    std::array<Subtree, kPipelineSlots> slots;
    ordered_pipeline(
        tasks_.size(),
        [&](std::size_t j) {
          const Task& t = tasks_[j];
          if (ahead) ahead(t.b, t.e);
          Subtree& st = slots[j % kPipelineSlots];
          // The subtree's positions decoded once (its codes, then its leaves' bounds).
          st.pos.resize(t.e - t.b);
          pos.decode(t.b, t.e - t.b, st.pos.data());
          make_subtree(t, st);
        },
        [&](std::size_t j) { commit(j, slots[j % kPipelineSlots]); });
    finish();
  }

  /// Steps 2 and 3 fused into the merge (after plan_counts()): feed(bytes, n) is called with the
  /// sorted points in order, n positions encoded as `enc` (the positions section's bytes), copied
  /// into the buffer of the subtree they belong to; each subtree whose points are all in is built
  /// by a task of its own (decode, codes, records; at
  /// most kPipelineSlots in flight) and committed in order by later feed() calls (numbers and
  /// records written), then end_feed() commits the rest and writes the upper nodes.
  void begin_feed() {
    if (!tasks_.empty()) out.reserve(0, 1);  // the root is node 0
    count = tasks_.empty() ? 0 : 1;
    next_event_ = 0;
    next_task_ = 0;
  }
  void feed(const std::uint8_t* bytes, std::size_t n) {
    const std::size_t pb = position_bytes(pos.encoding());
    while (n > 0) {
      if (next_task_ == tasks_.size()) throw std::logic_error("index build: more points than the fused node plan");
      const Task& t = tasks_[next_task_];
      if (!filling_) {  // the next subtree's positions, copied in as they arrive (tasks are contiguous)
        filling_ = std::make_unique<InFlight>();
        filling_->task = next_task_;
        filling_->enc.reserve((t.e - t.b) * pb);
      }
      const std::size_t have = filling_->enc.size() / pb, take = std::min(n, t.e - t.b - have);
      filling_->enc.insert(filling_->enc.end(), bytes, bytes + take * pb);
      bytes += take * pb, n -= take;
      if (have + take < t.e - t.b) break;  // (n == 0)
      launch(std::move(filling_));
      ++next_task_;
    }
  }
  void end_feed() {
    tasks_group_.wait();
    commit_done();
    if (tasks_.empty()) return;
    if (next_task_ != tasks_.size() || filling_ || !flight_.empty())
      throw std::logic_error("index build: the fused node build lost points");
    finish();
  }
  ~NodeBuilder() { tasks_group_.wait(); }  // (an exception may leave tasks running)


 private:
  struct Bounds {
    glm::vec3 lo, hi;
  };
  /// A node of the plan: an upper node (index into uppers_) or a subtree (index into tasks_).
  struct Ref {
    bool upper = false;
    std::uint32_t idx = 0;
  };
  struct Upper {
    std::uint64_t key;
    unsigned d;
    std::uint32_t n = 0, first = 0;  ///< its number; its first child's (set when numbered)
    unsigned nchild = 0;
    std::array<Ref, 8> child{};
    Bounds box{};
  };
  struct Task {
    std::uint64_t key;
    unsigned d;
    std::size_t b, e;
    std::uint32_t n = 0;  ///< the subtree root's number (set when its parent's block is numbered)
    Bounds box{};
  };
  /// The codes of points [base, base + n) as code(i) for the point's index i.
  struct CodeView {
    const std::uint64_t* p;
    std::size_t base;
    std::uint64_t operator()(std::size_t i) const { return p[i - base]; }
  };
  /// One subtree's records: [0] its root, [k >= 1] its k-th descendant in depth-first numbering.
  struct Subtree {
    std::vector<IndexNodeRecord> recs;
    std::vector<std::uint64_t> codes;  ///< its points' codes when they are computed
    std::vector<Vec3> pos;             ///< its points' positions, decoded
    unsigned depth = 0;
    std::array<std::uint64_t, kLevels> levels{};
    Bounds box{};
  };
  std::vector<Upper> uppers_;
  std::vector<Task> tasks_;
  std::vector<Ref> events_;  ///< upper nodes and subtrees in the order the depth-first pass visits them
  std::size_t next_event_ = 0;  ///< the sink's place in events_
  // The fused build's state (begin_feed): the next task (the positions' encoding: pos).
  std::size_t next_task_ = 0;
  /// A subtree of the fused build: its points' encoded positions, built by a task.
  struct InFlight {
    std::size_t task = 0;
    std::vector<std::uint8_t> enc;
    Subtree st;
    std::atomic<bool> done{false};
    std::exception_ptr error;
  };
  std::unique_ptr<InFlight> filling_;             // the subtree whose points are coming in
  std::deque<std::unique_ptr<InFlight>> flight_;  // in task order
  // An isolated context: the group outlives the merge window's pipeline it is first run from
  // (a bound context would take that pipeline's as its parent).
  tbb::task_group_context tasks_ctx_{tbb::task_group_context::isolated};
  tbb::task_group tasks_group_{tasks_ctx_};
  /// Builds subtree f (all its positions in) by a task; then commits what has finished, after
  /// waiting when kPipelineSlots are in flight (the subtrees held stay bounded).
  void launch(std::unique_ptr<InFlight> f) {
    InFlight* fp = f.get();
    flight_.push_back(std::move(f));
    tasks_group_.run([this, fp] {
      try {
        const Task& tk = tasks_[fp->task];
        const PositionView v(pos.encoding(), fp->enc.data(), tk.e - tk.b, pos.scale(), pos.offset());
        fp->st.pos.resize(tk.e - tk.b);
        v.decode(0, tk.e - tk.b, fp->st.pos.data());
        make_subtree(tk, fp->st);
      } catch (...) {
        fp->error = std::current_exception();
      }
      fp->done.store(true, std::memory_order_release);
    });
    if (flight_.size() >= kPipelineSlots) tasks_group_.wait();
    commit_done();
  }
  /// Commits the finished subtrees at the head of flight_, in order (the sink's thread).
  void commit_done() {
    while (!flight_.empty() && flight_.front()->done.load(std::memory_order_acquire)) {
      InFlight& f = *flight_.front();
      if (f.error) std::rethrow_exception(f.error);
      commit(f.task, f.st);
      flight_.pop_front();
    }
  }

  /// Step 2's work for task t, its positions decoded in st.pos: codes, records, bounds.
  void make_subtree(const Task& t, Subtree& st) const {
    st.recs.assign(1, IndexNodeRecord{});
    st.depth = 0;
    st.levels.fill(0);
    if (codes != nullptr) {
      st.box = visit(st, CodeView{codes, 0}, t.b, 0, t.key, t.d, t.b, t.e);
    } else {
      st.codes.resize(t.e - t.b);
      for (std::size_t i = 0; i < st.pos.size(); ++i) st.codes[i] = qz.code(st.pos[i]);
      st.box = visit(st, CodeView{st.codes.data(), t.b}, t.b, 0, t.key, t.d, t.b, t.e);
    }
  }

  /// Step 2's in-order sink for task j: the upper nodes visited before it number their children's
  /// blocks, its descendants take the next numbers, its records are written.
  void commit(std::size_t j, Subtree& st) {
    for (; next_event_ < events_.size() && events_[next_event_].upper; ++next_event_) number_children(events_[next_event_].idx);
    if (next_event_ == events_.size() || events_[next_event_].idx != j) throw std::logic_error("index build: node plan out of order");
    ++next_event_;
    Task& t = tasks_[j];
    const std::size_t base = count;  // descendant k (k >= 1) becomes node base + k - 1
    count += st.recs.size() - 1;
    if (count > std::numeric_limits<std::uint32_t>::max()) throw std::runtime_error("index build: too many nodes");
    for (IndexNodeRecord& r : st.recs)
      if (r.internal()) r.first = static_cast<std::uint32_t>(base + r.first - 1);
    out.write(t.n, st.recs.data(), 1);
    out.write(base, st.recs.data() + 1, st.recs.size() - 1);
    t.box = st.box;
    depth = std::max(depth, st.depth);
    for (unsigned d = 0; d < kLevels; ++d) levels[d] += st.levels[d];
    if (release) release(t.e);
    if (progress) progress("nodes", t.e, total);
  }

  /// Step 3: the upper nodes' records, children before parents (the plan lists them in preorder).
  void finish() {
    for (; next_event_ < events_.size(); ++next_event_)
      if (events_[next_event_].upper) number_children(events_[next_event_].idx);
    for (std::size_t u = uppers_.size(); u-- > 0;) {
      Upper& up = uppers_[u];
      const float inf = std::numeric_limits<float>::infinity();
      Bounds box{glm::vec3(inf), glm::vec3(-inf)};
      for (unsigned k = 0; k < up.nchild; ++k) {
        const Bounds& c = up.child[k].upper ? uppers_[up.child[k].idx].box : tasks_[up.child[k].idx].box;
        box.lo = glm::min(box.lo, c.lo);
        box.hi = glm::max(box.hi, c.hi);
      }
      up.box = box;
      depth = std::max(depth, up.d);
      IndexNodeRecord r;
      r.lo = box.lo;
      r.hi = box.hi;
      r.first = up.first;
      r.packed = IndexNodeRecord::pack(up.nchild, up.d == 0 ? 0u : static_cast<unsigned>(up.key & 7u), true);
      out.write(up.n, &r, 1);
    }
    if (progress) progress("nodes", total, total);
  }

  /// The plan's two kinds of node, in the depth-first pass's order (events_).
  Ref add_task(std::uint64_t key, unsigned d, std::size_t b, std::size_t e) {
    const Ref r{false, static_cast<std::uint32_t>(tasks_.size())};
    tasks_.push_back(Task{key, d, b, e});
    events_.push_back(r);
    return r;
  }
  Ref add_upper(std::uint64_t key, unsigned d) {
    const Ref r{true, static_cast<std::uint32_t>(uppers_.size())};
    uppers_.push_back(Upper{key, d});
    events_.push_back(r);
    return r;
  }

  /// plan() for the node (key, d) over points [b, e) from the cell counts (plan_counts); clears
  /// `ok` where they cannot decide.
  Ref plan_cells(std::span<const std::uint64_t> prefix, unsigned D, std::uint64_t key, unsigned d, std::size_t b,
                 std::size_t e, bool& ok) {
    const std::size_t cnt = e - b;
    if (cnt <= every) return add_task(key, d, b, e);
    // A node of more than `every` points: its codes differ when its points fill two cells or more.
    const std::size_t c0 = static_cast<std::size_t>(key << (3 * (D - d)));
    const std::size_t c1 = static_cast<std::size_t>((key + 1) << (3 * (D - d)));
    // (!splits with distinct codes implies !splits whatever `same` is: a leaf of > `every`)
    if (!OctreeRules::splits(cfg, d, cnt, false)) return add_task(key, d, b, e);
    const std::size_t cb = static_cast<std::size_t>(std::upper_bound(prefix.begin() + c0, prefix.begin() + c1 + 1, b) - prefix.begin()) - 1;
    if (d >= D || prefix[cb + 1] >= e) {  // one cell holds them all, or children below the cells
      ok = false;
      return {};
    }
    const Ref r = add_upper(key, d);
    const std::size_t step = std::size_t{1} << (3 * (D - d - 1));
    unsigned nchild = 0;
    for (unsigned o = 0; o < 8; ++o) {
      const std::size_t lo = prefix[c0 + o * step], hi = prefix[c0 + (o + 1) * step];
      if (hi == lo) continue;
      const Ref c = plan_cells(prefix, D, (key << 3) | o, d + 1, lo, hi, ok);
      if (!ok) return {};
      uppers_[r.idx].child[nchild++] = c;
    }
    uppers_[r.idx].nchild = nchild;
    return r;
  }

  /// Step 1 for the node (key, d) over [b, e): an upper node if it splits and holds more than
  /// `every` points (its children planned in order), else a subtree.
  template <class Code>
  Ref plan(const Code& code, std::uint64_t key, unsigned d, std::size_t b, std::size_t e) {
    const std::size_t cnt = e - b;
    const bool same = cnt == 0 || code(b) == code(e - 1);
    if (cnt <= every || !OctreeRules::splits(cfg, d, cnt, same)) return add_task(key, d, b, e);
    const Ref r = add_upper(key, d);
    std::array<std::size_t, 9> start{};
    std::array<unsigned, 8> oct{};
    const unsigned nchild = children(code, d, b, e, start, oct);
    uppers_[r.idx].nchild = nchild;
    for (unsigned k = 0; k < nchild; ++k) {
      const Ref c = plan(code, (key << 3) | oct[k], d + 1, start[k], start[k + 1]);
      uppers_[r.idx].child[k] = c;
    }
    return r;
  }

  /// Numbers upper node u's children as the next block (the depth-first pass's visit of u).
  void number_children(std::uint32_t u) {
    Upper& up = uppers_[u];
    out.reserve(count, up.nchild);  // (written by the subtrees' sink and finish())
    up.first = static_cast<std::uint32_t>(count);
    for (unsigned k = 0; k < up.nchild; ++k) {
      const auto n = static_cast<std::uint32_t>(count + k);
      if (up.child[k].upper) uppers_[up.child[k].idx].n = n;
      else tasks_[up.child[k].idx].n = n;
    }
    count += up.nchild;
  }

  /// The child ranges of a split node over [b, e) at depth d, in octant order: start[k] ..
  /// start[k + 1] for k < the returned count, oct[k] the octant digit.
  template <class Code>
  static unsigned children(const Code& code, unsigned d, std::size_t b, std::size_t e, std::array<std::size_t, 9>& start,
                           std::array<unsigned, 8>& oct) {
    unsigned nchild = 0;
    std::size_t i = b;
    while (i < e) {
      const unsigned o = OctreeRules::octant(code(i), d);
      const std::size_t j = gallop(code, i, e, [&](std::uint64_t c) { return OctreeRules::octant(c, d) == o; });
      start[nchild] = i;
      oct[nchild] = o;
      ++nchild;
      i = j;
    }
    start[nchild] = e;
    return nchild;
  }

  /// The first index in (i, e) whose code fails `pred`, or e (pred holds at i and for a prefix):
  /// an exponential search from i (probes at i + 1, i + 3, i + 7, ...), then a binary search in
  /// the last step (Bentley & Yao 1976). Its probes stay within twice the child's range of i, so
  /// the pass reads the codes near where it is instead of halving the parent's range.
  template <class Code, class Pred>
  static std::size_t gallop(const Code& code, std::size_t i, std::size_t e, const Pred& pred) {
    std::size_t lo = i + 1, step = 1, hi = e;
    while (lo < e) {
      const std::size_t probe = lo + std::min(step, e - lo) - 1;
      if (!pred(code(probe))) {
        hi = probe;
        break;
      }
      lo = probe + 1;
      step *= 2;
    }
    while (lo < hi) {  // pred holds before lo and fails at hi (or hi == e)
      const std::size_t mid = lo + (hi - lo) / 2;
      if (pred(code(mid))) lo = mid + 1;
      else hi = mid;
    }
    return lo;
  }

  /// Step 2's depth-first pass over one subtree: node n (local number) at depth d over [b, e).
  /// `p0` is the first point of the subtree (st.pos[0]).
  Bounds visit(Subtree& st, const CodeView& code, std::size_t p0, std::size_t n, std::uint64_t key, unsigned d,
               std::size_t b, std::size_t e) const {
    const std::size_t cnt = e - b;
    const bool same = cnt == 0 || code(b) == code(e - 1);
    const bool split = OctreeRules::splits(cfg, d, cnt, same);
    const std::size_t rest = split ? b : e;
    st.depth = std::max(st.depth, d);
    st.levels[d] += rest - b;
    // Octree's close_node: bounds of the own points (rounded outwards to float), then of the children.
    const float inf = std::numeric_limits<float>::infinity();
    Bounds box{glm::vec3(inf), glm::vec3(-inf)};
    {
      AABB own;
      for (std::size_t s = b; s < rest; ++s) own.expand(st.pos[s - p0]);
      if (!own.empty())
        for (int a = 0; a < 3; ++a) {
          box.lo[a] = OctreeRules::float_bound(own.lo[a] - cell_lo[a], false);
          box.hi[a] = OctreeRules::float_bound(own.hi[a] - cell_lo[a], true);
        }
    }
    std::size_t first = 0;
    unsigned nchild = 0;
    if (rest < e) {
      std::array<std::size_t, 9> start{};
      std::array<unsigned, 8> oct{};
      nchild = children(code, d, rest, e, start, oct);
      first = st.recs.size();
      st.recs.resize(first + nchild);
      for (unsigned k = 0; k < nchild; ++k) {
        const Bounds c = visit(st, code, p0, first + k, (key << 3) | oct[k], d + 1, start[k], start[k + 1]);
        box.lo = glm::min(box.lo, c.lo);
        box.hi = glm::max(box.hi, c.hi);
      }
    }
    // The record (docs/index-format.md, "Node record"): written once, final. A node is internal
    // (children, no own points) or a leaf (points, no children): OctreeRules::splits moves all of
    // a split node's points to its children.
    if (nchild > 0 && rest > b) throw std::logic_error("index build: node with both points and children");
    if (nchild == 0 && cnt > IndexNodeRecord::kMaxCount)
      throw std::runtime_error("index build: a leaf of " + std::to_string(cnt) + " points at depth " + std::to_string(d) +
                               " (at most " + std::to_string(IndexNodeRecord::kMaxCount) +
                               " per leaf; use a deeper --depth or --max-depth)");
    IndexNodeRecord r;
    r.lo = box.lo;
    r.hi = box.hi;
    r.first = nchild > 0 ? static_cast<std::uint32_t>(first) : static_cast<std::uint32_t>(b);
    r.packed = IndexNodeRecord::pack(nchild > 0 ? nchild : static_cast<std::uint32_t>(cnt),
                                     d == 0 ? 0u : static_cast<unsigned>(key & 7u), nchild > 0);
    st.recs[n] = r;
    return box;
  }
};

bool same_crs(const PointReader& a, const PointReader& b) {
  if (a.info().epsg != 0 && b.info().epsg != 0) return a.info().epsg == b.info().epsg;
  return a.crs_wkt() == b.crs_wkt();
}
std::string crs_label(const PointReader& r) {
  if (r.info().epsg != 0) return "EPSG:" + std::to_string(r.info().epsg);
  if (r.crs_wkt().empty()) return "no CRS";
  return "WKT \"" + r.crs_wkt().substr(0, 40) + "...\"";
}

}  // namespace

bool is_index_file(const std::filesystem::path& path) { return detail::lower(path.extension().string()) == ".rsi"; }

namespace {

IndexBuildStats build_index_impl(const std::vector<fs::path>& inputs, const fs::path& output,
                                 const IndexBuildOptions& opt, bool stored_colour);

}  // namespace

IndexBuildStats build_index_file(const std::vector<fs::path>& inputs, const fs::path& output,
                                 const IndexBuildOptions& opt) {
  try {
    return build_index_impl(inputs, output, opt, true);
  } catch (const ColourRetry&) {
    IndexBuildStats st = build_index_impl(inputs, output, opt, false);
    st.notes.insert(st.notes.begin(), "the tiles' colour differs in kind (8-bit, 16-bit or all zero): read again "
                                      "with each file's own colour rule");
    return st;
  }
}

namespace {

IndexBuildStats build_index_impl(const std::vector<fs::path>& inputs, const fs::path& output,
                                 const IndexBuildOptions& opt, bool stored_colour) {
  opt.config.validate();
  if (opt.config.layout == OctreeLayout::layered)
    throw std::invalid_argument("--layout layered: not supported by the external-memory index build "
                                "(use adaptive or fixed)");
  if (inputs.empty()) throw std::invalid_argument("rayscan index: no input file");
  if (opt.memory_bytes < (std::uint64_t{1} << 20))
    throw std::invalid_argument("--memory " + std::to_string(opt.memory_bytes) + " bytes: at least 1M");
  if ((opt.attributes & kIndexAttributes) != opt.attributes)
    throw std::invalid_argument("--attributes " + opt.attributes.to_string() + ": an index stores " +
                                kIndexAttributes.to_string());
  // The ids section only when asked (docs/index-format.md "Ids"); the readers deliver the rest.
  const bool want_ids = opt.attributes.has(Attribute::id);
  const AttributeSet read_attrs{opt.attributes.bits & ~static_cast<std::uint32_t>(Attribute::id)};
  IndexBuildStats stats;
  // LAS/LAZ colour as stored (ReadOptions::stored_colour): the readers skip their whole-file
  // colour pass (a read of every record before the first point), and the read pass below
  // applies the same rule from the largest value of each file (RgbCodec::stored_scale).
  const bool raw_colour = stored_colour && read_attrs.has(Attribute::rgb) &&
                          std::all_of(inputs.begin(), inputs.end(), [](const fs::path& in) {
                            return format_from_extension(in) == Format::las;
                          });
  // Inputs larger than the budget are read once, past the page cache (direct_records).
  std::uint64_t input_bytes = 0;
  for (const fs::path& in : inputs) {
    std::error_code ec;  // (a missing input is reported by its reader below)
    const std::uintmax_t size = fs::file_size(in, ec);
    if (!ec) input_bytes += size;
  }
  const ReadOptions ropt{.scalars = false, .stored_colour = raw_colour, .direct_records = input_bytes > opt.memory_bytes};

  // Inputs: CRS agreement, the stored attributes, the announced point counts. The readers stay
  // open for the read pass when there are few of them (a LAS file's colour scan runs once).
  constexpr std::size_t kKeepOpen = 64;
  std::vector<IndexSource> sources;
  std::vector<std::unique_ptr<PointReader>> kept(inputs.size());
  AttributeSet stored = opt.attributes;
  std::string crs;
  std::uint64_t announced = 0;
  {
    std::unique_ptr<PointReader> first_owned;
    const PointReader* first = nullptr;
    for (std::size_t f = 0; f < inputs.size(); ++f) {
      const fs::path& in = inputs[f];
      auto r = open_point_reader(in, read_attrs, ropt);
      if (first && !same_crs(*first, *r))
        throw IndexError(in.string() + ": CRS " + crs_label(*r) + " differs from " + crs_label(*first) +
                         " of " + inputs.front().string() + " (an index holds one coordinate system)");
      const AttributeSet lacking{read_attrs.bits & ~r->attributes().bits};
      if (lacking.bits != 0 && (stored.bits & lacking.bits) != 0) {
        stats.notes.push_back(in.string() + " has no " + lacking.to_string() + ": not stored");
        stored = AttributeSet{stored.bits & ~lacking.bits};
      }
      IndexSource s;
      s.path = fs::absolute(in).lexically_normal().string();
      s.size = fs::file_size(in);
      s.mtime_ns = mtime_ns(in);
      s.format = r->info().format + (r->info().version.empty() ? "" : " " + r->info().version);
      sources.push_back(s);
      announced += r->point_count();
      if (!first) crs = r->crs_wkt();
      if (inputs.size() <= kKeepOpen) {
        kept[f] = std::move(r);
        if (!first) first = kept[f].get();
      } else if (!first) {
        first_owned = std::move(r);
        first = first_owned.get();
      }
    }
  }
  const RecordLayout L(stored);
  // Points per sort run within the memory budget (a record and a sort key per point; the buffer
  // actually holds positions, the stored attributes and a 16-byte key, a little less).
  const std::size_t run_cap = std::max<std::size_t>(
      1024, static_cast<std::size_t>(opt.memory_bytes * 3 / 4 / (L.bytes + sizeof(MortonKey))));
  // All points fit the budget (the readers announce exact counts or upper bounds): one read pass
  // into memory, the bounds from it, then sort and write the sections straight from memory. Else
  // a bounds pass first (the runs need the Morton grid), sorted runs on disk and a k-way merge.
  const bool in_memory = announced <= run_cap;
  // The Morton grid of the runs (multi-run build) needs the bounds before the read pass. LAS
  // headers state them (min/max x, y, z): when every input is LAS, their union is taken on trust
  // and checked against the exact bounds of the read pass, which is repeated on the exact grid
  // when the headers were wrong (the tree must be build_bulk's, whose grid is the exact bounds).
  // Other inputs get a bounds pass first (positions only).
  AABB grid_bounds;
  bool grid_from_headers = !in_memory;
  for (const fs::path& in : inputs) {
    if (!grid_from_headers) break;
    auto r = open_point_reader(in, AttributeSet::none(), ReadOptions{.scalars = false});
    if (!r->integer_grid() || !r->info().header_bounds || r->point_count() == 0) grid_from_headers = false;
    else grid_bounds.expand(*r->info().header_bounds);
  }
  if (!in_memory && !grid_from_headers) {
    grid_bounds = AABB{};
    std::uint64_t scanned = 0;
    PointCloud chunk;
    for (const fs::path& in : inputs) {
      auto pr = open_point_reader(in, AttributeSet::none(), ReadOptions{.scalars = false});
      while (pr->read(chunk, kDefaultChunkPoints) > 0) {
        for (const Vec3& p : chunk.positions) grid_bounds.expand(p);
        scanned += chunk.size();
        if (opt.progress) opt.progress("scan", scanned, 0);
      }
    }
  }
  OctreeRules::Quantizer grid_qz(OctreeRules::root_cell(grid_bounds).lo, OctreeRules::root_side(grid_bounds));

  AtomicFile out(output);
  fs::path tmp_dir = opt.temp_dir.empty() ? output.parent_path() : opt.temp_dir;
  if (tmp_dir.empty()) tmp_dir = ".";
  TempDir runs_dir(tmp_dir / ("." + output.filename().string() + ".runs." + std::to_string(::getpid())));

  // The read pass: points in id order into the buffer; a full buffer becomes a sorted run file
  // (multi-run build) written as records (code, id, position, attributes).
  AABB bounds;
  std::uint64_t total = 0;
  PointBuffer buf;
  buf.allocate(static_cast<std::size_t>(std::min<std::uint64_t>(run_cap, announced)), L, !in_memory);
  std::vector<fs::path> run_files;
  std::vector<RunLayout> run_layouts;
  std::uint64_t run_first_id = 0;
  PositionCodec codec;
  RgbCodec rgbc;
  HugeArray<MortonKey> run_keys;
  // Points per cell of depth cell_depth on the runs' grid, counted from each sorted run: the
  // merge then builds the nodes as it goes (NodeBuilder::plan_counts, feed). The deepest level
  // <= 7 whose 12 bytes per cell (the counts and their prefix sums) fit 1/16 of the budget.
  unsigned cell_depth = 0;
  while (cell_depth < 7 && (std::uint64_t{12} << (3 * (cell_depth + 1))) <= opt.memory_bytes / 16) ++cell_depth;
  std::vector<std::uint32_t> cell_points;
  auto flush_run = [&] {
    if (buf.size() == 0) return;
    sort_keys(buf, grid_qz, run_keys);
    const HugeArray<MortonKey>& keys = run_keys;
    {  // the run's points per cell: one add per stretch of a cell (the keys are sorted)
      const unsigned shift = 3 * (kMortonBits - cell_depth);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, buf.size(), 1 << 16), [&](const auto& r) {
        for (std::size_t i = r.begin(); i < r.end();) {
          const std::uint64_t c = keys[i].code >> shift;
          std::size_t j = i + 1;
          while (j < r.end() && (keys[j].code >> shift) == c) ++j;
          std::atomic_ref<std::uint32_t>(cell_points[c]).fetch_add(static_cast<std::uint32_t>(j - i), std::memory_order_relaxed);
          i = j;
        }
      });
    }
    const fs::path rp = runs_dir.path / ("run" + std::to_string(run_files.size()));
    // codec.grid_ok covers every point read so far, this run's included (append checked them).
    const RunLayout R(L, want_ids, codec.grid_ok && codec.grid_set);
    // O_DIRECT where possible: a run is written once and read once, so it bypasses the page
    // cache (no kernel copy, no cache pages to fill and evict; bench/notes/).
    Fd fd = Fd::direct(rp, O_WRONLY | O_CREAT | O_TRUNC);
    // Blocks of records gathered in parallel and written in order by one writer at a time (a
    // file's writes serialise on its inode lock: concurrent writers only spin), so the write of
    // block i overlaps the gather of the next ones. A block is up to kGatherBlock records, fewer
    // for a small budget (the four slots then hold about a quarter of a run), and a multiple of
    // 4096 records, so that every block's offset is page-aligned for O_DIRECT.
    const std::size_t blk_recs = std::clamp<std::size_t>(run_cap / 16 / 4096 * 4096, 4096, kGatherBlock);
    const std::size_t nb = (buf.size() + blk_recs - 1) / blk_recs;
    pipelined_blocks(nb, blk_recs * R.bytes, [&](std::size_t blk, std::uint8_t* recs) {
      const std::size_t b = blk * blk_recs, e = std::min(buf.size(), b + blk_recs);
      constexpr std::size_t kAhead = 16;  // prefetch distance (keys) of the random reads
      for (std::size_t k = b; k != e; ++k) {
        if (k + kAhead < e) {
          const std::uint32_t j = keys[k + kAhead].idx;
          __builtin_prefetch(&buf.pos[j]);
          if (L.rgb) __builtin_prefetch(&buf.rgb[j]);
        }
        const std::uint32_t i = keys[k].idx;
        std::uint8_t* rec = recs + (k - b) * R.bytes;
        std::memcpy(rec, &keys[k].code, 8);
        if (R.ids) {
          const auto pid = static_cast<std::uint32_t>(run_first_id + i);
          std::memcpy(rec + R.id_off, &pid, 4);
        }
        if (L.gps) std::memcpy(rec + R.gps_off, &buf.gps[i], 8);
        if (L.rgb) std::memcpy(rec + R.rgb_off, &buf.rgb[i], 6);
        if (L.intensity) std::memcpy(rec + R.int_off, &buf.intensity[i], 2);
        if (L.cls) rec[R.cls_off] = buf.cls[i];
        if (R.grid) {
          std::int32_t v[3];
          for (int a = 0; a < 3; ++a) v[a] = codec.grid_int(buf.pos[i][a], a);
          std::memcpy(rec + R.pos_off, v, 12);
        } else {
          std::memcpy(rec + R.pos_off, &buf.pos[i], 24);
        }
      }
      return (e - b) * R.bytes;
    }, [&](std::size_t blk, std::uint8_t* recs, std::size_t bytes) {
      // Direct writes are whole pages: the last block's tail is zero-padded, then cut off below.
      const std::size_t len = fd.is_direct() ? round_up_direct(bytes) : bytes;
      std::memset(recs + bytes, 0, len - bytes);
      fd.pwrite_all(recs, len, static_cast<std::uint64_t>(blk) * blk_recs * R.bytes);
    });
    const std::uint64_t run_bytes = static_cast<std::uint64_t>(buf.size()) * R.bytes;
    if (fd.is_direct() && run_bytes % kDirectAlign != 0 && ::ftruncate(fd.get(), static_cast<off_t>(run_bytes)) != 0)
      io_fail(rp, "cannot truncate to " + std::to_string(run_bytes) + " bytes");
    run_files.push_back(rp);
    run_layouts.push_back(R);
    run_first_id += buf.size();
    buf.clear();
  };
  std::vector<std::uint16_t> file_rgb_max;  // the largest stored colour value of each input (raw_colour)
  for (int attempt = 0;; ++attempt) {
    PointCloud c;
    codec = PositionCodec{};
    rgbc = RgbCodec{};
    bounds = AABB{};
    total = 0;
    run_first_id = 0;
    if (!in_memory) cell_points.assign(std::size_t{1} << (3 * cell_depth), 0);
    for (const fs::path& rp : run_files) fs::remove(rp);
    run_files.clear();
    run_layouts.clear();
    buf.clear();
    for (IndexSource& s : sources) s.points = 0;
    file_rgb_max.assign(inputs.size(), 0);
    for (std::size_t f = 0; f < inputs.size(); ++f) {
      std::unique_ptr<PointReader> r = std::move(kept[f]);
      if (!r) r = open_point_reader(inputs[f], AttributeSet{stored.bits & read_attrs.bits}, ropt);
      sources[f].first_id = total;
      codec.source(r->integer_grid());
      std::size_t n;
      while ((n = r->read(c, kDefaultChunkPoints)) > 0) {
        if (total + n >= 0xFFFFFFFFull) throw std::length_error("rayscan index: more than 2^32 - 2 points");
        if (in_memory && buf.size() + n > buf.capacity())
          throw std::runtime_error(inputs[f].string() + ": the inputs changed during the build (more points than " +
                                   std::to_string(announced) + " announced by the headers)");
        for (std::size_t i0 = 0; i0 < n;) {
          const std::size_t take = std::min(n - i0, buf.capacity() - buf.size());
          const BlockScan sc = buf.append(c, i0, take, L, codec, rgbc, raw_colour, in_memory ? nullptr : &grid_qz);
          file_rgb_max[f] = std::max(file_rgb_max[f], sc.rgb_max);
          bounds.expand(sc.box);
          codec.grid_ok = codec.grid_ok && sc.grid, codec.f32_ok = codec.f32_ok && sc.f32;
          rgbc.rule_out(sc.rgb_out);
          i0 += take;
          if (!in_memory && buf.size() == buf.capacity()) flush_run();
        }
        total += n;
        sources[f].points += n;
        if (opt.progress) opt.progress("read", total, announced);
      }
    }
    if (in_memory) break;
    flush_run();
    if (bounds.lo == grid_bounds.lo && bounds.hi == grid_bounds.hi) break;
    if (!grid_from_headers || attempt > 0)
      throw std::runtime_error(inputs.front().string() +
                               ": the inputs changed during the build (their bounds differ from the first pass)");
    stats.notes.push_back("the LAS headers' bounds differ from the points' bounds: read again on the exact grid");
    grid_bounds = bounds;
    grid_qz = OctreeRules::Quantizer(OctreeRules::root_cell(grid_bounds).lo, OctreeRules::root_side(grid_bounds));
  }
  run_keys = HugeArray<MortonKey>{};
  if (!in_memory) buf = PointBuffer{};  // the runs are on disk: release the buffer before the merge
  stats.runs = in_memory ? (total > 0 ? 1 : 0) : run_files.size();
  const AABB cell = OctreeRules::root_cell(bounds);
  codec.decide(opt.compact_positions);
  if (raw_colour && L.rgb) {  // throws ColourRetry when the files disagree
    std::vector<std::uint64_t> points(sources.size());
    for (std::size_t f = 0; f < sources.size(); ++f) points[f] = sources[f].points;
    rgbc.stored_scale(file_rgb_max, points);
  }
  if (L.rgb) rgbc.decide(opt.compact_rgb);
  const bool rgb8 = L.rgb && rgbc.mul != 0;

  // Section placement: sources, crs, per-point sections, then nodes (size known after the build).
  Header h;
  h.points = total;
  h.cell = cell;
  h.config = opt.config;
  h.attributes = stored.bits;
  h.encoding = codec.enc;
  if (codec.enc == PositionEncoding::las_int32) h.grid_scale = codec.scale, h.grid_offset = codec.offset;
  h.rgb_mul = rgb8 ? rgbc.mul : 0u;
  const std::string src_text = encode_sources(sources);
  std::uint64_t off = kHeaderBytes;
  auto place = [&](std::uint32_t id, std::uint64_t size) {
    SectionEntry e{id, elem_size(id, codec.enc), off, size, 0};
    h.sections.push_back(e);
    off = align_up(off + size);
    return h.sections.size() - 1;
  };
  const std::size_t s_src = place(kSources, src_text.size());
  const std::size_t s_crs = place(kCrs, crs.size());
  const std::size_t s_pos = place(kPositions, total * codec.bytes());
  const std::size_t s_ids = want_ids ? place(kIds, total * 4) : 0;
  std::size_t s_rgb = 0, s_int = 0, s_cls = 0, s_gps = 0;
  if (L.rgb) s_rgb = rgb8 ? place(kRgb8, total * 3) : place(kRgb, total * 6);
  if (L.intensity) s_int = place(kIntensity, total * 2);
  if (L.cls) s_cls = place(kClassification, total);
  if (L.gps) s_gps = place(kGpsTime, total * 8);

  Fd fd(out.temp(), O_RDWR | O_CREAT | O_TRUNC);
  // The point sections are written once and not read back by this build but for the node
  // phase's positions: past the page cache where the file system allows (SectionWriter).
  Fd dfd = Fd::direct(out.temp(), O_WRONLY);
  // Its background writes: 8 buffers of up to 4 MiB, more than are ever held at once (one per
  // section writer, at most 6, and one by the node file while it copies pages in). The section
  // writers use it on an O_DIRECT descriptor only; the node file always (through the page cache
  // where the file system refuses O_DIRECT).
  DirectWriter dw(8, std::clamp<std::size_t>(opt.memory_bytes / 128 / kDirectAlign * kDirectAlign, 64 << 10, 4 << 20));
  DirectWriter* const dwp = &dw;
  {
    const std::vector<std::uint8_t> zero(kHeaderBytes, 0);  // header slot, written last
    fd.pwrite_all(zero.data(), zero.size(), 0);
  }
  auto write_blob = [&](std::size_t s, const std::string& text) {
    if (!text.empty()) fd.pwrite_all(text.data(), text.size(), h.sections[s].offset);
    h.sections[s].crc = crc32_of(text.data(), text.size());
  };
  write_blob(s_src, src_text);
  write_blob(s_crs, crs);

  // The point sections in (code, id) order: straight from memory (one run), or by a k-way merge
  // of the runs. Then the nodes from the sorted codes, or (multi-run builds whose cells decide
  // the upper tree) during the merge from the merged positions (NodeBuilder::feed).
  HugeArray<std::uint64_t> mem_codes;  // sorted codes of the in-memory build
  NodeFile node_file(dfd, dw, off, opt.node_stage_pages);  // the nodes section, after the points
  // The node phase after a merge (or of an in-memory build): subtrees of --memory/512 points at
  // most (1 Mi at most); each of the kPipelineSlots in flight holds its decoded positions, codes
  // and records (about 36 B/point) and its part of the positions map (12-24 B/point), about a
  // quarter of the budget in all (the merge's buffers are freed by then), so small budgets
  // release often too. (The fused build's subtrees are smaller: see below.)
  const std::uint64_t node_every = std::clamp<std::uint64_t>(opt.memory_bytes / 16 / 32, 1024, std::uint64_t{1} << 20);
  const OctreeRules::Quantizer node_qz(cell.lo, OctreeRules::root_side(bounds));
  std::optional<NodeBuilder> fused;
  if (!in_memory && total > 0) {
    std::vector<std::uint64_t> prefix(cell_points.size() + 1, 0);
    for (std::size_t c = 0; c < cell_points.size(); ++c) prefix[c + 1] = prefix[c] + cell_points[c];
    if (prefix.back() != total) throw std::logic_error("index build: the cells lost points");
    const PositionView enc(codec.enc, nullptr, 0, codec.scale, codec.offset);
    fused.emplace(opt.config, nullptr, node_qz, enc, cell.lo, node_file, nullptr, nullptr, nullptr, total);
    // Subtrees of --memory/2048 points at most: up to kPipelineSlots of them (~50 B/point: the
    // encoded and decoded positions, codes, records) live beside the merge's buffers.
    fused->every = std::clamp<std::uint64_t>(opt.memory_bytes / 16 / 128, 1024, std::uint64_t{1} << 20);
    if (fused->plan_counts(prefix, cell_depth)) fused->begin_feed();
    else fused.reset();
  }
  std::vector<std::uint32_t>().swap(cell_points);
  // The point sections' writers (positions, ids, the stored attributes), filled in (code, id)
  // order by either path below; finish_points flushes them and records their CRCs in the header.
  const std::size_t wbuf = in_memory ? 1 << 16 : 4 << 20;  // (buffered only; in memory: blocks go straight)
  SectionWriter w_pos(dfd, h.sections[s_pos].offset, wbuf, dwp);
  std::optional<SectionWriter> w_ids, w_rgb, w_int, w_cls, w_gps;
  if (want_ids) w_ids.emplace(dfd, h.sections[s_ids].offset, wbuf, dwp);
  if (L.rgb) w_rgb.emplace(dfd, h.sections[s_rgb].offset, wbuf, dwp);
  if (L.intensity) w_int.emplace(dfd, h.sections[s_int].offset, wbuf, dwp);
  if (L.cls) w_cls.emplace(dfd, h.sections[s_cls].offset, wbuf, dwp);
  if (L.gps) w_gps.emplace(dfd, h.sections[s_gps].offset, wbuf, dwp);
  auto finish_points = [&] {
    w_pos.flush();
    h.sections[s_pos].crc = w_pos.crc();
    if (w_ids) w_ids->flush(), h.sections[s_ids].crc = w_ids->crc();
    if (w_rgb) w_rgb->flush(), h.sections[s_rgb].crc = w_rgb->crc();
    if (w_int) w_int->flush(), h.sections[s_int].crc = w_int->crc();
    if (w_cls) w_cls->flush(), h.sections[s_cls].crc = w_cls->crc();
    if (w_gps) w_gps->flush(), h.sections[s_gps].crc = w_gps->crc();
    dw.drain();  // on disk before the node phase maps the positions
  };

  if (in_memory) {
    const OctreeRules::Quantizer qz(cell.lo, OctreeRules::root_side(bounds));
    if (opt.progress) opt.progress("sort", 0, total);
    HugeArray<MortonKey> keys;
    sort_keys(buf, qz, keys);
    mem_codes = HugeArray<std::uint64_t>(keys.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, keys.size(), 1 << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) mem_codes[i] = keys[i].code;
    });
    std::vector<Vec3> g_pos;
    std::vector<std::uint8_t> g_enc;  // encoded positions (float32, las_int32)
    std::vector<std::uint32_t> g_ids;
    std::vector<Rgb16> g_rgb;
    std::vector<std::uint8_t> g_rgb8;
    std::vector<std::uint16_t> g_int;
    std::vector<std::uint8_t> g_cls;
    std::vector<double> g_gps;
    for_blocks(keys.size(), [&](std::size_t b, std::size_t e) {
      if (codec.enc == PositionEncoding::float64) {
        gather_write(buf.pos, keys, b, e, g_pos, w_pos);
      } else {
        g_pos.resize(e - b);
        g_enc.resize((e - b) * codec.bytes());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 1 << 14), [&](const auto& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) g_pos[i - b] = buf.pos[keys[i].idx];
          codec.encode(g_pos.data() + (r.begin() - b), r.end() - r.begin(), g_enc.data() + (r.begin() - b) * codec.bytes());
        });
        w_pos.write(g_enc.data(), g_enc.size());
      }
      if (w_ids) {
        g_ids.resize(e - b);
        for (std::size_t i = b; i < e; ++i) g_ids[i - b] = keys[i].idx;  // one run: idx == id
        w_ids->write(g_ids.data(), g_ids.size() * 4);
      }
      if (L.rgb && !rgb8) {
        g_rgb.resize(e - b);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 1 << 14), [&](const auto& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) rgbc.widen(&buf.rgb[keys[i].idx], 1, &g_rgb[i - b]);
        });
        w_rgb->write(g_rgb.data(), g_rgb.size() * sizeof(Rgb16));
      }
      if (rgb8) {
        g_rgb8.resize((e - b) * 3);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 1 << 14), [&](const auto& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) rgbc.encode(&buf.rgb[keys[i].idx], 1, &g_rgb8[3 * (i - b)]);
        });
        w_rgb->write(g_rgb8.data(), g_rgb8.size());
      }
      if (L.intensity) gather_write(buf.intensity, keys, b, e, g_int, *w_int);
      if (L.cls) gather_write(buf.cls, keys, b, e, g_cls, *w_cls);
      if (L.gps) gather_write(buf.gps, keys, b, e, g_gps, *w_gps);
      if (opt.progress && (e & ((std::size_t{1} << 22) - 1)) < kGatherBlock) opt.progress("write", e, total);
    });
    finish_points();
    buf = PointBuffer{};  // release before the node build
  } else {
    const std::size_t rbuf = std::clamp<std::size_t>(
        static_cast<std::size_t>(opt.memory_bytes / 2 / std::max<std::size_t>(1, run_files.size())),
        std::size_t{1} << 16, std::size_t{64} << 20);
    std::vector<std::unique_ptr<RunReader>> readers;
    for (std::size_t r = 0; r < run_files.size(); ++r)
      readers.push_back(std::make_unique<RunReader>(run_files[r], run_layouts[r].bytes, rbuf, run_files.size() <= 64));
    // The merge (docs/index-format.md "Build"), a window at a time: S = the least last code of the
    // buffers of the runs that have more records on disk; every record with a code below S is in
    // a buffer, so the window (those records) is merged before any buffer refills. The window is
    // cut into parts by codes taken at quantiles of its largest run slice (equal codes fall in
    // one part, so the (code, run) tie order holds within a part); the parts are merged in
    // parallel, each by a tree of losers over its run slices that takes a stretch at a time (the
    // winner's records below the runner-up's key), straight into the sections' output arrays of
    // one of a few slots, and written in order by one writer (tbb::parallel_pipeline).
    const std::size_t k = readers.size();
    const std::size_t pos_bytes = codec.bytes(), rgb_bytes = rgb8 ? 3 : 6;
    struct Part {
      std::vector<std::pair<const std::uint8_t*, std::size_t>> slices;  // per run: first record, count
      std::size_t n = 0;
    };
    struct Slot {  // one part's sections, in file order
      std::vector<std::uint8_t> pos, ids, gps, rgb, inten, cls;
      std::size_t n = 0;
    };
    // Records per part: 65,536, fewer for a small budget (the slots' arrays stay near 1/16 of it).
    const std::size_t part_records = std::clamp<std::size_t>(opt.memory_bytes / 64 / 256, 1024, std::size_t{1} << 16);
    std::array<Slot, kMergeSlots> slots;
    // Merges part `pt` into `sl` (resized to its records).
    auto merge_part = [&](const Part& pt, Slot& sl) {
      sl.n = pt.n;
      sl.pos.resize(pt.n * pos_bytes);
      if (want_ids) sl.ids.resize(pt.n * 4);
      if (L.gps) sl.gps.resize(pt.n * 8);
      if (L.rgb) sl.rgb.resize(pt.n * rgb_bytes);
      if (L.intensity) sl.inten.resize(pt.n * 2);
      if (L.cls) sl.cls.resize(pt.n);
      std::vector<const std::uint8_t*> cur(k);
      std::vector<std::size_t> left(k);
      std::vector<std::uint64_t> heads(k, LoserTree::kDone);
      for (std::size_t r = 0; r < k; ++r) {
        cur[r] = pt.slices[r].first, left[r] = pt.slices[r].second;
        if (left[r] > 0) heads[r] = get<std::uint64_t>(cur[r], 0);
      }
      LoserTree tree(heads);
      constexpr std::size_t kStreak = 4;
      std::size_t o = 0, streak = 0;
      while (tree.winner_key() != LoserTree::kDone) {
        const std::uint32_t r = tree.winner();
        const RunLayout& R = run_layouts[r];
        // The stretch: one record while the runs interleave (the replace below finds the next
        // winner in one pass of the tree); after kStreak wins of one run in a row, every record
        // of the run below the runner-up's (code, run) at once (a second pass, then a scan).
        std::size_t n = 1;
        if (streak >= kStreak) {
          const auto [bcode, brun] = tree.runner_up();
          const bool incl = r < brun;
          while (n < left[r]) {
            const std::uint64_t c = get<std::uint64_t>(cur[r] + n * R.bytes, 0);
            if (!(c < bcode || (incl && c == bcode))) break;
            ++n;
          }
        }
        for (std::size_t i = 0; i < n; ++i, ++o) {
          const std::uint8_t* rec = cur[r] + i * R.bytes;
          if (want_ids) std::memcpy(sl.ids.data() + o * 4, rec + R.id_off, 4);
          if (L.gps) std::memcpy(sl.gps.data() + o * 8, rec + R.gps_off, 8);
          if (L.rgb) {
            Rgb16 v;  // copied out: a record's colour need not be 2-byte aligned
            std::memcpy(&v, rec + R.rgb_off, 6);
            if (rgb8) {
              rgbc.encode(&v, 1, sl.rgb.data() + o * 3);
            } else {
              rgbc.widen(&v, 1, &v);
              std::memcpy(sl.rgb.data() + o * 6, &v, 6);
            }
          }
          if (L.intensity) std::memcpy(sl.inten.data() + o * 2, rec + R.int_off, 2);
          if (L.cls) sl.cls[o] = rec[R.cls_off];
          const std::uint8_t* p = rec + R.pos_off;
          std::uint8_t* out = sl.pos.data() + o * pos_bytes;
          if (R.grid && codec.enc == PositionEncoding::las_int32) {
            std::memcpy(out, p, 12);
            continue;
          }
          double v[3];
          if (R.grid) {  // exact: the run was written only when every value round-tripped
            std::int32_t g[3];
            std::memcpy(g, p, 12);
            for (int a = 0; a < 3; ++a) v[a] = las_coordinate(g[a], codec.scale[a], codec.offset[a]);
          } else {
            std::memcpy(v, p, 24);
          }
          codec.encode(v, 1, out);
        }
        cur[r] += n * R.bytes;
        left[r] -= n;
        tree.replace(left[r] > 0 ? get<std::uint64_t>(cur[r], 0) : LoserTree::kDone);
        streak = tree.winner() == r ? streak + 1 : 0;
      }
      if (o != pt.n) throw std::logic_error("index build: a merge part lost records");
    };
    auto write_slot = [&](const Slot& sl) {
      if (fused) fused->feed(sl.pos.data(), sl.n);  // the subtrees whose points are all in
      w_pos.write(sl.pos.data(), sl.pos.size());
      if (w_ids) w_ids->write(sl.ids.data(), sl.ids.size());
      if (w_rgb) w_rgb->write(sl.rgb.data(), sl.rgb.size());
      if (w_int) w_int->write(sl.inten.data(), sl.inten.size());
      if (w_cls) w_cls->write(sl.cls.data(), sl.cls.size());
      if (w_gps) w_gps->write(sl.gps.data(), sl.gps.size());
    };
    std::uint64_t merged = 0;
    std::vector<std::size_t> counts(k);
    for (;;) {
      bool any = false;
      std::uint64_t S = LoserTree::kDone;
      for (std::size_t r = 0; r < k; ++r) {
        if (readers[r]->done()) continue;
        any = true;
        if (!readers[r]->at_end()) S = std::min(S, readers[r]->code(readers[r]->left() - 1));
      }
      if (!any) break;
      std::size_t window = 0, big = 0;
      for (std::size_t r = 0; r < k; ++r) {
        counts[r] = readers[r]->done() ? 0 : S == LoserTree::kDone ? readers[r]->left() : readers[r]->lower_bound(S);
        window += counts[r];
        if (counts[r] > counts[big]) big = r;
      }
      if (window == 0) {
        // Every buffered code is >= S, and the buffer of the run that set S holds S only: the next
        // records are the S records of the lowest run that starts with S, as far as its buffer goes
        // (S < 2^63, so S + 1 does not wrap).
        for (std::size_t r = 0; r < k; ++r)
          if (!readers[r]->done() && readers[r]->code(0) == S) {
            counts[r] = readers[r]->lower_bound(S + 1);
            window = counts[r];
            big = r;  // the parts' cut codes come from the one slice
            break;
          }
        if (window == 0) throw std::logic_error("index build: the merge made no progress");
      }
      // Parts: splitter codes at quantiles of the largest slice; each part's slice of run r is
      // [its lower bound of the part's first splitter, that of the next).
      const std::size_t parts = std::max<std::size_t>(1, (window + part_records - 1) / part_records);
      std::vector<std::vector<std::size_t>> cut(parts + 1, std::vector<std::size_t>(k, 0));
      cut[parts] = counts;
      for (std::size_t j = 1; j < parts; ++j) {
        const std::uint64_t c = readers[big]->code(counts[big] * j / parts);
        for (std::size_t r = 0; r < k; ++r) cut[j][r] = readers[r]->lower_bound(c, cut[j - 1][r], counts[r]);  // monotone in j
      }
      ordered_pipeline(
          parts,
          [&](std::size_t j) {
            Part pt;
            pt.slices.resize(k);
            for (std::size_t r = 0; r < k; ++r) {
              const std::size_t b = cut[j][r], e = cut[j + 1][r];
              pt.slices[r] = {readers[r]->cur() + b * readers[r]->record_bytes(), e - b};
              pt.n += e - b;
            }
            merge_part(pt, slots[j % kMergeSlots]);
          },
          [&](std::size_t j) { write_slot(slots[j % kMergeSlots]); }, kMergeSlots);
      for (std::size_t r = 0; r < k; ++r)
        if (counts[r] > 0) readers[r]->skip(counts[r]);
      merged += window;
      if (opt.progress) opt.progress("merge", merged, total);
    }
    finish_points();
    if (opt.progress) opt.progress("merge", total, total);
  }
  for (const fs::path& rp : run_files) fs::remove(rp);

  // Nodes from the sorted codes (in memory) or, after a merge, the codes of the positions section
  // (mapped; its pages are file cache; the codes are the run sort's, as the grid is the final
  // root cell and the decoded positions are the read ones bit for bit), written in place into
  // the nodes section (NodeFile). The map's pages are dropped behind the finished subtrees, so
  // the node phase's resident set (anonymous and file-backed) does not grow with the site.
  {
    const std::uint64_t nodes_off = off;  // the next aligned offset: where place() puts the nodes
    std::optional<ReadMap> file;
    std::optional<NodeBuilder> phase;
    if (fused) {
      fused->end_feed();
      stats.nodes_in_merge = true;
    } else {
      file.emplace(fd.get(), h.sections[s_pos].offset + total * codec.bytes(), out.temp());
      auto release = [&](std::size_t i) { file->release_below(h.sections[s_pos].offset + i * codec.bytes()); };
      auto ahead = [&](std::size_t b, std::size_t e) {
        file->populate(h.sections[s_pos].offset + b * codec.bytes(), (e - b) * codec.bytes());
      };
      phase.emplace(opt.config, in_memory ? mem_codes.data() : nullptr, node_qz,
                    PositionView(codec.enc, static_cast<const std::uint8_t*>(file->p) + h.sections[s_pos].offset, total,
                                 codec.scale, codec.offset),
                    cell.lo, node_file, release, ahead, opt.progress, total);
      phase->every = node_every;
      phase->plan(total, [&] { file->drop(); });
      phase->build();
    }
    NodeBuilder& nb = fused ? *fused : *phase;
    mem_codes = HugeArray<std::uint64_t>{};
    const std::size_t s_nodes = place(kNodes, nb.count * kNodeBytes);
    if (h.sections[s_nodes].offset != nodes_off) throw std::logic_error("rayscan index: nodes section misplaced");
    h.sections[s_nodes].crc = node_file.crc(nb.count);
    h.nodes = nb.count;
    h.depth = nb.depth;
    h.levels = nb.levels;
    off = h.sections[s_nodes].offset + h.sections[s_nodes].size;  // the file ends with the nodes
  }
  h.bounds = bounds;
  dw.drain();  // (the node records)
  if (::ftruncate(fd.get(), static_cast<off_t>(off)) != 0) io_fail(out.temp(), "cannot set the file size");
  {
    const std::vector<std::uint8_t> hb = encode_header(h);
    fd.pwrite_all(hb.data(), hb.size(), 0);
  }
  // The auto radius (median nearest-neighbour spacing) over the finished tree, by the renderer's
  // own function, so that opening never runs kNN for it; then the final header.
  if (total >= 2) {
    if (opt.progress) opt.progress("spacing", 0, 1);
    IndexOpenOptions oo;
    oo.verify = IndexOpenOptions::Verify::metadata_only;
    oo.check_sources = false;
    oo.trust_ids = true;  // written above: the ids need no check
    const MappedIndex m = MappedIndex::open(out.temp(), oo);
    // The map's pages are dropped from the process (MappedIndex::release_pages) behind the ids
    // pass (or every 1,024 samples read by slot without ids) and after every 256 kNN queries:
    // each page fault maps up to 64 KiB around it, so scattered reads would otherwise keep
    // gigabytes of the file resident.
    h.spacing = median_nn_spacing_by_id(
        m, 20000, [&](std::size_t) { m.release_pages(); }, 256, [&] { m.release_pages(); });
    const std::vector<std::uint8_t> hb = encode_header(h);
    fd.pwrite_all(hb.data(), hb.size(), 0);
  }
  // A last progress call before the rename: a caller that stops the build from its callback
  // (rayscan index on SIGINT/SIGTERM) still gets no output when it stops here.
  if (opt.progress) opt.progress("done", total, total);
  if (::fsync(fd.get()) != 0) io_fail(out.temp(), "fsync failed");
  out.commit();

  stats.points = total;
  stats.nodes = h.nodes;
  stats.depth = h.depth;
  stats.attributes = stored;
  stats.positions = codec.enc;
  stats.rgb_multiplier = h.rgb_mul;
  stats.file_bytes = off;
  return stats;
}

}  // namespace

// ---- open ------------------------------------------------------------------------------------------

struct MappedIndex::Map {
  int fd = -1;
  void* p = nullptr;
  std::size_t n = 0;
  // What a checked IdView's handler needs (MappedIndex::ids(); stable across moves of the index).
  std::string path;              ///< the file, for error messages
  std::uint64_t ids_offset = 0;  ///< byte offset of the ids section
  const PointIndex* ids = nullptr;
  std::size_t points = 0;
  bool trust_ids = false;  ///< IndexOpenOptions::trust_ids: ids() returns an unchecked view
  // IndexOpenOptions::read_ahead: the background thread asking for the file's pages, and its
  // stop flag (set and joined before the unmap).
  std::thread ahead;
  std::atomic<bool> stop{false};
  /// Starts reading bytes [first, first + len) (the nodes section), then, when `whole`, the whole
  /// file from its start, in 4 MiB sequential reads into a buffer that is thrown away: the pages
  /// land in the page cache, not in this process's resident set, and the queries' faults find
  /// them there. (MADV_WILLNEED in 64 MiB steps was tried: a cold 2e8 render took 24 s against
  /// 31 s without and 7.2 s with these reads; bench/notes/.)
  void start_read_ahead(std::uint64_t first, std::uint64_t len, bool whole) {
    ahead = std::thread([this, first, len, whole] {
      constexpr std::uint64_t kStep = std::uint64_t{4} << 20;
      std::vector<std::uint8_t> buf(kStep);
      const auto ask = [&](std::uint64_t b, std::uint64_t e) {
        for (std::uint64_t o = b / 4096 * 4096; o < e && !stop.load(std::memory_order_relaxed); o += kStep)
          if (::pread(fd, buf.data(), static_cast<std::size_t>(std::min(kStep, n - o)), static_cast<off_t>(o)) <= 0) return;
      };
      const std::uint64_t end = std::min<std::uint64_t>(n, first + len);
      ask(first, end);
      if (whole) ask(0, first), ask(end, n);
    });
  }
  ~Map() {
    stop = true;
    if (ahead.joinable()) ahead.join();
    if (p != nullptr) ::munmap(p, n);
    if (fd >= 0) ::close(fd);
  }
};

namespace {
/// MemAvailable of /proc/meminfo in bytes (0 when unknown).
std::uint64_t available_memory() {
  std::ifstream f("/proc/meminfo");
  std::string key;
  std::uint64_t kb = 0;
  std::string unit;
  while (f >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024;
  return 0;
}
}  // namespace

MappedIndex::MappedIndex(MappedIndex&&) noexcept = default;
MappedIndex& MappedIndex::operator=(MappedIndex&&) noexcept = default;
MappedIndex::~MappedIndex() = default;

std::uint64_t MappedIndex::file_bytes() const { return map_ ? map_->n : 0; }

MappedIndex MappedIndex::open(const fs::path& path, const IndexOpenOptions& opt) {
  const std::string nm = path.string();
  auto fail = [&nm](std::uint64_t off, const std::string& what) -> void {
    throw IndexError(nm + ": byte " + std::to_string(off) + ": " + what);
  };
  MappedIndex x;
  x.path_ = path;
  x.map_ = std::make_unique<Map>();
  Map& m = *x.map_;
  // The input policy (rayscan/base/input_file.hpp): regular files only, opened without blocking.
  std::uint64_t size = 0;
  try {
    InputFile in(path);
    size = in.size();
    m.fd = ::dup(in.fd());
  } catch (const InputFileError& e) {
    throw IndexError(e.what());
  }
  if (m.fd < 0) throw IndexError(nm + ": cannot open index file: " + std::strerror(errno));
  if (size < kHeaderBytes)
    fail(size, "file of " + std::to_string(size) + " bytes is shorter than the " + std::to_string(kHeaderBytes) +
                   "-byte index header (truncated or not an index)");
  m.n = static_cast<std::size_t>(size);
  m.p = ::mmap(nullptr, m.n, PROT_READ, MAP_SHARED, m.fd, 0);
  if (m.p == MAP_FAILED) {
    m.p = nullptr;
    throw IndexError(nm + ": cannot memory-map: " + std::strerror(errno));
  }
  const auto* b = static_cast<const std::uint8_t*>(m.p);
  if (std::memcmp(b, kMagic, 8) != 0) fail(0, "expected the signature \"RSINDEX\" (not a rayscan index file)");
  const auto version = get<std::uint32_t>(b, 8);
  if (version != kVersion)
    fail(8, "index format version " + std::to_string(version) + "; this rayscan reads version " +
                std::to_string(kVersion) + " (rebuild the index with `rayscan index`)");
  if (get<std::uint32_t>(b, 12) != kHeaderBytes) fail(12, "header size must be 4096");
  if (get<std::uint32_t>(b, 16) != kEndianMarker) fail(16, "byte-order marker 0x01020304 expected (little-endian)");
  {
    std::vector<std::uint8_t> hb(b, b + kHeaderBytes);
    put<std::uint32_t>(hb.data(), kCrcOffset, 0);
    const std::uint32_t want = get<std::uint32_t>(b, kCrcOffset), have = crc32_of(hb.data(), hb.size());
    if (want != have) fail(kCrcOffset, "header checksum " + hex32(have) + ", expected " + hex32(want) + " (corrupted)");
  }
  const auto nsec = get<std::uint32_t>(b, 20);
  if (nsec > kMaxSections) fail(20, "section count " + std::to_string(nsec) + " above 16");
  x.points_ = get<std::uint64_t>(b, 24);
  x.node_count_ = get<std::uint64_t>(b, 32);
  for (int k = 0; k < 3; ++k) {
    x.cell_.lo[k] = get<double>(b, 40 + 8 * k);
    x.cell_.hi[k] = get<double>(b, 64 + 8 * k);
  }
  const auto layout = get<std::uint32_t>(b, 88);
  if (layout > 2) fail(88, "layout " + std::to_string(layout) + " (expected 0..2)");
  x.config_.layout = static_cast<OctreeLayout>(layout);
  x.config_.capacity = get<std::uint32_t>(b, 92);
  x.config_.max_depth = get<std::uint32_t>(b, 96);
  x.config_.depth = get<std::uint32_t>(b, 100);
  x.depth_ = get<std::uint32_t>(b, 104);
  if (x.depth_ > 21) fail(104, "depth " + std::to_string(x.depth_) + " (expected 0..21, the Morton code depth)");
  x.attrs_ = AttributeSet{get<std::uint32_t>(b, 108)};
  x.spacing_ = get<double>(b, kSpacingOffset);
  if (!(x.spacing_ >= 0.0) || !std::isfinite(x.spacing_))
    fail(kSpacingOffset, "median nearest-neighbour spacing " + std::to_string(x.spacing_) + " (expected a finite number >= 0)");
  for (int k = 0; k < 3; ++k) {
    x.bounds_.lo[k] = get<double>(b, kBoundsOffset + 8 * k);
    x.bounds_.hi[k] = get<double>(b, kBoundsOffset + 24 + 8 * k);
  }
  if (x.points_ >= 0xFFFFFFFFull) fail(24, "point count " + std::to_string(x.points_) + " above 2^32 - 2");
  {
    std::uint64_t sum = 0;
    for (unsigned d = 0; d < kLevels; ++d) {
      const auto v = get<std::uint64_t>(b, kLevelsOffset + 8 * d);
      if (v > x.points_ || (d > x.depth_ && v != 0))
        fail(kLevelsOffset + 8 * d, "points at depth " + std::to_string(d) + ": " + std::to_string(v) +
                                        " (the header says " + std::to_string(x.points_) + " points, depth " +
                                        std::to_string(x.depth_) + ")");
      sum += v;
    }
    if (sum != x.points_)
      fail(kLevelsOffset, "points per level sum to " + std::to_string(sum) + ", the header says " + std::to_string(x.points_));
  }
  const auto enc_id = get<std::uint32_t>(b, kEncodingOffset);
  if (enc_id > static_cast<std::uint32_t>(PositionEncoding::las_int32))
    fail(kEncodingOffset, "positions encoding " + std::to_string(enc_id) +
                              " (expected 0 float64, 1 float32 or 2 LAS int32 grid)");
  const auto enc = static_cast<PositionEncoding>(enc_id);
  Vec3 grid_scale(1.0), grid_offset(0.0);
  if (enc == PositionEncoding::las_int32)
    for (int k = 0; k < 3; ++k) {
      grid_scale[k] = get<double>(b, kScaleOffset + 8 * k);
      grid_offset[k] = get<double>(b, kGridOffsetOffset + 8 * k);
      if (!std::isfinite(grid_scale[k]) || grid_scale[k] == 0.0 || !std::isfinite(grid_offset[k]))
        fail(kScaleOffset, "LAS grid scale/offset of axis " + std::to_string(k) + " not finite and non-zero");
    }
  const bool verify_all = opt.verify == IndexOpenOptions::Verify::always ||
                          (opt.verify == IndexOpenOptions::Verify::automatic && size <= kVerifyAllBytes);
  x.verified_ = verify_all;
  std::array<const SectionEntry*, kLastSection + 1> by_id{};
  std::vector<SectionEntry> secs(nsec);
  for (std::uint32_t i = 0; i < nsec; ++i) {
    const std::size_t o = kTableOffset + i * kEntryBytes;
    SectionEntry& e = secs[i];
    e.id = get<std::uint32_t>(b, o);
    e.elem = get<std::uint32_t>(b, o + 4);
    e.offset = get<std::uint64_t>(b, o + 8);
    e.size = get<std::uint64_t>(b, o + 16);
    e.crc = get<std::uint32_t>(b, o + 24);
    if (e.id < kSources || e.id > kLastSection) fail(o, "unknown section id " + std::to_string(e.id));
    const std::string sn = std::string("section ") + section_name(e.id);
    x.sections_.push_back({section_name(e.id), e.offset, e.size});
    if (by_id[e.id] != nullptr) fail(o, sn + " appears twice");
    by_id[e.id] = &e;
    if (e.elem != elem_size(e.id, enc))
      fail(o + 4, sn + ": element size " + std::to_string(e.elem) + ", expected " + std::to_string(elem_size(e.id, enc)));
    if (e.offset % kAlign != 0 || e.offset < kHeaderBytes)
      fail(o + 8, sn + ": offset " + std::to_string(e.offset) + " not a multiple of 4096 after the header");
    if (e.offset > size || e.size > size - e.offset)
      fail(o + 16, sn + " [" + std::to_string(e.offset) + ", " + std::to_string(e.offset + e.size) +
                       ") runs past the end of the file (size " + std::to_string(size) + "; truncated)");
    std::uint64_t expect = e.size;
    if (per_point(e.id)) expect = x.points_ * e.elem;
    if (e.id == kNodes) expect = x.node_count_ * e.elem;
    if (e.size != expect) fail(o + 16, sn + ": " + std::to_string(e.size) + " bytes, expected " + std::to_string(expect));
    const bool meta = e.id == kSources || e.id == kCrs;
    if (verify_all || meta) {
      const std::uint32_t have = crc32_of(b + e.offset, e.size);
      if (have != e.crc)
        throw IndexError(nm + ": " + sn + " (byte " + std::to_string(e.offset) + "): checksum " + hex32(have) +
                         ", expected " + hex32(e.crc) + " (corrupted)");
    }
  }
  for (std::uint32_t id : {kSources, kCrs, kPositions, kNodes})
    if (by_id[id] == nullptr) fail(kTableOffset, std::string("missing section ") + section_name(id));
  if (by_id[kRgb] && by_id[kRgb8]) fail(kTableOffset, "sections rgb and rgb8 both present (expected one)");
  const std::pair<Attribute, std::uint32_t> attr_sec[] = {{Attribute::id, kIds}, {Attribute::rgb, kRgb},
                                                           {Attribute::intensity, kIntensity},
                                                           {Attribute::classification, kClassification},
                                                           {Attribute::gps_time, kGpsTime}};
  for (const auto& [a, id] : attr_sec)
    if (x.attrs_.has(a) != (by_id[id] != nullptr || (id == kRgb && by_id[kRgb8] != nullptr)))
      fail(108, std::string("attribute set and sections disagree on ") + section_name(id));
  if ((x.attrs_.bits & ~kIndexAttributes.bits) != 0)
    fail(108, "stored attributes " + std::to_string(x.attrs_.bits) + " (expected a subset of " +
                  std::to_string(kIndexAttributes.bits) + ": " + kIndexAttributes.to_string() + ")");
  const auto rgb_mul = get<std::uint32_t>(b, kRgbMulOffset);
  if (by_id[kRgb8] ? rgb_mul != 1 && rgb_mul != 256 && rgb_mul != 257 : rgb_mul != 0)
    fail(kRgbMulOffset, "rgb8 multiplier " + std::to_string(rgb_mul) +
                            (by_id[kRgb8] ? " (expected 1, 256 or 257)" : " (expected 0 without an rgb8 section)"));
  if ((x.points_ > 0) != (x.node_count_ > 0)) fail(32, "node count " + std::to_string(x.node_count_) + " for " + std::to_string(x.points_) + " points");
  if (x.node_count_ >= 0xFFFFFFFFull) fail(32, "node count above 2^32 - 2");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(x.cell_.lo[k]) || !std::isfinite(x.cell_.hi[k]) || !(x.cell_.hi[k] > x.cell_.lo[k]))
      fail(40, "root cell is not a finite box");
  auto at = [&](std::uint32_t id) { return b + by_id[id]->offset; };
  x.nodes_ = reinterpret_cast<const IndexNodeRecord*>(at(kNodes));
  x.positions_ = PositionView(enc, at(kPositions), x.points_, grid_scale, grid_offset);
  if (by_id[kIds]) {
    x.ids_ = reinterpret_cast<const PointIndex*>(at(kIds));
    x.ids_offset_ = by_id[kIds]->offset;
  }
  if (by_id[kRgb]) x.rgb_ = std::span<const Rgb16>(reinterpret_cast<const Rgb16*>(at(kRgb)), x.points_);
  if (by_id[kRgb8]) x.rgb_ = RgbView(at(kRgb8), x.points_, rgb_mul);
  if (by_id[kIntensity]) x.intensity_ = {reinterpret_cast<const std::uint16_t*>(at(kIntensity)), x.points_};
  if (by_id[kClassification]) x.classification_ = {at(kClassification), x.points_};
  if (by_id[kGpsTime]) x.gps_ = {reinterpret_cast<const double*>(at(kGpsTime)), x.points_};
  x.crs_.assign(reinterpret_cast<const char*>(at(kCrs)), by_id[kCrs]->size);

  // Deep checks of the node records and ids (with the section CRCs above, a file that passes them
  // is exactly as built). Without them the accessors sanitise every record they return
  // (MappedIndex::child_count / node_points), so no traversal reads outside the mapping either,
  // and ids() returns a checked view: every id read is compared with N (consumers index per-point
  // arrays by id), so a corrupted id is an IndexError where it is read, never an access past an
  // array, without a pass over all N ids before the first query.
  if (verify_all) x.verify_records(by_id[kNodes]->offset);

  // Sources: "size \t mtime_ns \t points \t first_id \t format \t path" lines.
  {
    std::istringstream in(std::string(reinterpret_cast<const char*>(at(kSources)), by_id[kSources]->size));
    std::string line;
    std::uint64_t sum = 0;
    while (std::getline(in, line)) {
      IndexSource s;
      std::istringstream ls(line);
      std::string f[6];
      for (int k = 0; k < 5; ++k) std::getline(ls, f[k], '\t');
      std::getline(ls, f[5]);
      try {
        s.size = std::stoull(f[0]);
        s.mtime_ns = std::stoll(f[1]);
        s.points = std::stoull(f[2]);
        s.first_id = std::stoull(f[3]);
      } catch (const std::exception&) {
        fail(by_id[kSources]->offset, "section sources: malformed line '" + line.substr(0, 60) + "'");
      }
      s.format = f[4];
      s.path = f[5];
      sum += s.points;
      x.sources_.push_back(s);
    }
    if (sum != x.points_)
      fail(by_id[kSources]->offset, "section sources: " + std::to_string(sum) + " points, header says " + std::to_string(x.points_));
  }
  if (opt.check_sources)
    for (const IndexSource& s : x.sources_) {
      std::error_code ec;
      if (!fs::exists(s.path, ec)) continue;  // a moved index is self-contained
      const std::uint64_t sz = fs::file_size(s.path, ec);
      const std::int64_t mt = mtime_ns(s.path);
      if (!ec && (sz != s.size || mt != s.mtime_ns))
        throw IndexError(nm + ": source " + s.path + " changed since the index was built (size " + std::to_string(s.size) +
                         " -> " + std::to_string(sz) + ", mtime " + std::to_string(s.mtime_ns) + " -> " +
                         std::to_string(mt) + " ns): rebuild it with `rayscan index`");
    }
  ::madvise(m.p, m.n, MADV_RANDOM);
  if (opt.read_ahead && !x.verified_ && x.node_count_ > 0)  // (verified: open read every section just now)
    m.start_read_ahead(by_id[kNodes]->offset, by_id[kNodes]->size, m.n <= available_memory() / 2);
  m.path = nm;
  m.ids_offset = x.ids_offset_;
  m.ids = x.ids_;
  m.points = x.points_;
  m.trust_ids = opt.trust_ids;  // the builder's own output
  return x;
}

void MappedIndex::release_pages() const {
  if (map_ && map_->p != nullptr) (void)::madvise(map_->p, map_->n, MADV_DONTNEED);
}

/// Points per depth counted over the node records (the deep check of the header's table).
void MappedIndex::verify_records(std::uint64_t node_off) const {
  const std::string nm = path_.string();
  auto fail = [&nm](std::uint64_t off, const std::string& what) -> void {
    throw IndexError(nm + ": byte " + std::to_string(off) + ": " + what);
  };
  const MappedIndex& x = *this;
  // Node ranges: every later access stays inside the mapping.
  for (std::size_t n = 0; n < x.node_count_; ++n) {
    const IndexNodeRecord& r = x.nodes_[n];
    const std::uint64_t o = node_off + n * kNodeBytes;
    if (r.internal()) {
      if (r.count() < 1 || r.count() > 8 || r.first <= n || r.first + std::uint64_t{r.count()} > x.node_count_)
        fail(o + 24, "node " + std::to_string(n) + ": children [" + std::to_string(r.first) + ", +" +
                         std::to_string(r.count()) + ") outside the " + std::to_string(x.node_count_) +
                         " nodes (expected 1 to 8 nodes after it)");
    } else if (r.first + std::uint64_t{r.count()} > x.points_) {
      fail(o + 24, "node " + std::to_string(n) + ": point range [" + std::to_string(r.first) + ", +" +
                       std::to_string(r.count()) + ") outside the " + std::to_string(x.points_) + " points");
    }
    for (int k = 0; k < 3; ++k)
      if (std::isnan(r.lo[k]) || std::isnan(r.hi[k])) fail(o, "node " + std::to_string(n) + ": NaN bounds");
  }
  if (x.node_count_ > 0 && x.nodes_[0].octant() != 0) fail(node_off + 28, "root node octant must be 0");
  // Structure (Warren & Salmon ids, paper section 4.1): every node but the root is the child of
  // exactly one earlier node, octants strictly increase within a family (so sibling ids differ and
  // each id is its parent's times 8 plus the octant), and no node is deeper than the header's
  // depth. The depth of each node is kept (one byte per node) for the points per level below.
  std::vector<std::uint8_t> depth_of(x.node_count_, 0xFF);
  if (x.node_count_ > 0) depth_of[0] = 0;
  for (std::size_t n = 0; n < x.node_count_; ++n) {  // parents come before their children
    const IndexNodeRecord& r = x.nodes_[n];
    if (depth_of[n] == 0xFF)
      fail(node_off + n * kNodeBytes, "node " + std::to_string(n) + ": not the child of any earlier node");
    if (!r.internal()) continue;
    if (depth_of[n] >= x.depth_)
      fail(node_off + n * kNodeBytes + 28, "node " + std::to_string(n) + ": children below the deepest level " +
                                               std::to_string(x.depth_) + " of the header");
    for (unsigned c = 0; c < r.count(); ++c) {
      const std::size_t k = r.first + c;
      if (depth_of[k] != 0xFF || (c > 0 && x.nodes_[k].octant() <= x.nodes_[k - 1].octant()))
        fail(node_off + k * kNodeBytes + 28, "node " + std::to_string(k) + ": octant " +
                                                 std::to_string(x.nodes_[k].octant()) + " is not the next child of node " +
                                                 std::to_string(n));
      depth_of[k] = static_cast<std::uint8_t>(depth_of[n] + 1);
    }
  }
  // The header's points per level agree with the records.
  {
    std::vector<std::uint64_t> have(kLevels, 0);
    for (std::size_t n = 0; n < x.node_count_; ++n)
      if (!x.nodes_[n].internal()) have[depth_of[n]] += x.nodes_[n].count();  // depth <= header depth <= 21
    const std::vector<std::uint64_t> want = points_per_level();
    for (unsigned d = 0; d < kLevels; ++d)
      if (have[d] != (d < want.size() ? want[d] : 0))
        fail(kLevelsOffset + 8 * d, "points at depth " + std::to_string(d) + ": the header says " +
                                        std::to_string(d < want.size() ? want[d] : 0) + ", the nodes hold " +
                                        std::to_string(have[d]));
  }
  // Ids: every stored id names a point (callers index per-point arrays by id).
  check_ids();
}

IdView MappedIndex::ids() const {
  if (ids_ == nullptr) return IdView::identity(points_);  // no ids section: slot order
  const std::span<const PointIndex> ids(ids_, points_);
  if (verified_ || !map_ || map_->trust_ids) return ids;
  return IdView::checked(ids, &MappedIndex::bad_id, map_.get());
}

void MappedIndex::bad_id(const void* map, std::size_t slot) {
  const auto& m = *static_cast<const Map*>(map);
  throw IndexError(m.path + ": byte " + std::to_string(m.ids_offset + 4 * slot) + ": section ids: slot " +
                   std::to_string(slot) + " holds id " + std::to_string(m.ids[slot]) + " outside the " +
                   std::to_string(m.points) + " points (corrupted; `rayscan info --verify` checks the whole file)");
}

void MappedIndex::check_ids() const {
  if (ids_ == nullptr) return;  // the identity names every point
  std::atomic<std::size_t> bad{points_};
  // The deep check at open (verify_records); isolated so that the pass never runs an outer task.
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_, 1 << 16), [&](const auto& r) {
      for (std::size_t s = r.begin(); s != r.end(); ++s)
        if (ids_[s] >= points_) {
          std::size_t cur = bad.load();
          while (s < cur && !bad.compare_exchange_weak(cur, s)) {
          }
          return;
        }
    });
  });
  if (const std::size_t s = bad.load(); s < points_)
    throw IndexError(path_.string() + ": byte " + std::to_string(ids_offset_ + 4 * s) + ": section ids: slot " +
                     std::to_string(s) + " holds id " + std::to_string(ids_[s]) + " outside the " +
                     std::to_string(points_) + " points (corrupted; `rayscan info --verify` checks the whole file)");
}

std::vector<std::uint64_t> MappedIndex::points_per_level() const {
  // Stored in the header at build time (checked at open: sums to N, nothing below the depth).
  std::vector<std::uint64_t> out(depth_ + 1, 0);
  if (!map_ || map_->p == nullptr) return out;
  const auto* b = static_cast<const std::uint8_t*>(map_->p);
  for (unsigned d = 0; d <= depth_ && d < kLevels; ++d) out[d] = get<std::uint64_t>(b, kLevelsOffset + 8 * d);
  return out;
}

PointCloud MappedIndex::to_point_cloud() const {
  PointCloud pc;
  pc.crs_wkt = crs_;
  pc.positions.resize(points_);
  if (!rgb_.empty()) pc.rgb.resize(points_);
  if (!intensity_.empty()) pc.intensity.resize(points_);
  if (!classification_.empty()) pc.classification.resize(points_);
  if (!gps_.empty()) pc.gps_time.resize(points_);
  for (std::size_t s = 0; s < points_; ++s) {
    const PointIndex i = ids_ ? ids_[s] : static_cast<PointIndex>(s);  // no ids: slot order
    if (i >= points_)
      throw IndexError(path_.string() + ": section ids: slot " + std::to_string(s) + " holds id " + std::to_string(i) +
                       " outside the " + std::to_string(points_) + " points (corrupted)");
    pc.positions[i] = positions_[s];
    if (!rgb_.empty()) pc.rgb[i] = rgb_[s];
    if (!intensity_.empty()) pc.intensity[i] = intensity_[s];
    if (!classification_.empty()) pc.classification[i] = classification_[s];
    if (!gps_.empty()) pc.gps_time[i] = gps_[s];
  }
  return pc;
}

}  // namespace rayscan::io
