// The external sort of the index build: the point buffer of one sort run and its key sort, the
// layout of the run records on disk, the runs' buffered reader, and the tree of losers
// that merges them. docs/index-format.md, "Build (external memory)" 1 to 3.
#pragma once

#include "codecs.hpp"
#include "direct_io.hpp"
#include "rayscan/octree/morton_sort.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <future>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::io::rsi {

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
inline void sort_keys(const PointBuffer& buf, const OctreeRules::Quantizer& qz, HugeArray<MortonKey>& keys) {
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

}  // namespace rayscan::io::rsi
