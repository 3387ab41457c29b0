// The point sections of an index build in (code, id) order: gathered from the in-memory buffer
// (one run) or merged from the sorted run files by a tree of losers, a window of the runs'
// buffers at a time, in parallel parts written in order. docs/index-format.md, "Build (external
// memory)" 2 and 3.
#include "index_build.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

namespace rayscan::io::rsi {

namespace {

/// The merge's items in flight (ordered_pipeline's `slots`): more than kPipelineSlots, so the
/// parts' merge runs on while the in-order sink builds a subtree of the fused node build
/// (NodeBuilder::feed; ~1 MB of records per slot).
constexpr std::size_t kMergeSlots = 16;

}  // namespace

void IndexBuild::write_from_memory() {
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
      gather_write(buf.pos, keys, b, e, g_pos, *w_pos);
    } else {
      g_pos.resize(e - b);
      g_enc.resize((e - b) * codec.bytes());
      tbb::parallel_for(tbb::blocked_range<std::size_t>(b, e, 1 << 14), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) g_pos[i - b] = buf.pos[keys[i].idx];
        codec.encode(g_pos.data() + (r.begin() - b), r.end() - r.begin(), g_enc.data() + (r.begin() - b) * codec.bytes());
      });
      w_pos->write(g_enc.data(), g_enc.size());
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
    // Every 2^22 points (the first block past each multiple) and at the end, so the phase's last
    // report is its total.
    if (opt.progress && (e == keys.size() || (e & ((std::size_t{1} << 22) - 1)) < kGatherBlock))
      opt.progress("write", e, total);
  });
  finish_points();
  buf = PointBuffer{};  // release before the node build
}

/// The merge (docs/index-format.md "Build"), a window at a time: S = the least last code of the
/// buffers of the runs that have more records on disk; every record with a code below S is in
/// a buffer, so the window (those records) is merged before any buffer refills. The window is
/// cut into parts by codes taken at quantiles of its largest run slice (equal codes fall in
/// one part, so the (code, run) tie order holds within a part); the parts are merged in
/// parallel, each by a tree of losers over its run slices that takes a stretch at a time (the
/// winner's records below the runner-up's key), straight into the sections' output arrays of
/// one of a few slots, and written in order by one writer (tbb::parallel_pipeline).
struct IndexBuild::RunMerge {
  /// One part of a merge window: its records of each run.
  struct Part {
    std::vector<std::pair<const std::uint8_t*, std::size_t>> slices;  // per run: first record, count
    std::size_t n = 0;
  };
  /// One part's sections, in file order.
  struct Slot {
    std::vector<std::uint8_t> pos, ids, gps, rgb, inten, cls;
    std::size_t n = 0;
  };

  IndexBuild& b;
  std::vector<std::unique_ptr<RunReader>> readers;
  std::size_t k = 0;  ///< runs
  std::size_t pos_bytes = 0, rgb_bytes = 0;
  /// Records per part: 65,536, fewer for a small budget (the slots' arrays stay near 1/16 of it).
  std::size_t part_records = 0;
  std::array<Slot, kMergeSlots> slots;
  std::vector<std::size_t> counts;  ///< the window's records of each run
  std::size_t window = 0;           ///< ... in all
  std::size_t big = 0;              ///< the run of the largest slice

  explicit RunMerge(IndexBuild& build) : b(build) {
    const std::size_t rbuf = std::clamp<std::size_t>(
        static_cast<std::size_t>(b.opt.memory_bytes / 2 / std::max<std::size_t>(1, b.run_files.size())),
        std::size_t{1} << 16, std::size_t{64} << 20);
    for (std::size_t r = 0; r < b.run_files.size(); ++r)
      readers.push_back(
          std::make_unique<RunReader>(b.run_files[r], b.run_layouts[r].bytes, rbuf, b.run_files.size() <= 64));
    k = readers.size();
    pos_bytes = b.codec.bytes(), rgb_bytes = b.rgb8 ? 3 : 6;
    part_records = std::clamp<std::size_t>(b.opt.memory_bytes / 64 / 256, 1024, std::size_t{1} << 16);
    counts.resize(k);
  }

  /// Every window in order, then the sections' end.
  void run() {
    std::uint64_t merged = 0;
    while (next_window()) {
      merge_window();
      merged += window;
      if (b.opt.progress) b.opt.progress("merge", merged, b.total);
    }
    b.finish_points();
    if (b.opt.progress) b.opt.progress("merge", b.total, b.total);
  }

  /// The next window's records of each run (counts, window, big); false when every run is read.
  bool next_window() {
    bool any = false;
    std::uint64_t S = LoserTree::kDone;
    for (std::size_t r = 0; r < k; ++r) {
      if (readers[r]->done()) continue;
      any = true;
      if (!readers[r]->at_end()) S = std::min(S, readers[r]->code(readers[r]->left() - 1));
    }
    if (!any) return false;
    window = 0, big = 0;
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
    return true;
  }

  /// Merges the window in parts and moves every run past it.
  void merge_window() {
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
            const std::size_t first = cut[j][r], end = cut[j + 1][r];
            pt.slices[r] = {readers[r]->cur() + first * readers[r]->record_bytes(), end - first};
            pt.n += end - first;
          }
          merge_part(pt, slots[j % kMergeSlots]);
        },
        [&](std::size_t j) { write_slot(slots[j % kMergeSlots]); }, kMergeSlots);
    for (std::size_t r = 0; r < k; ++r)
      if (counts[r] > 0) readers[r]->skip(counts[r]);
  }

  /// Merges part `pt` into `sl` (resized to its records).
  void merge_part(const Part& pt, Slot& sl) const {
    const RecordLayout& L = b.L;
    sl.n = pt.n;
    sl.pos.resize(pt.n * pos_bytes);
    if (b.want_ids) sl.ids.resize(pt.n * 4);
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
      const RunLayout& R = b.run_layouts[r];
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
        if (b.want_ids) std::memcpy(sl.ids.data() + o * 4, rec + R.id_off, 4);
        if (L.gps) std::memcpy(sl.gps.data() + o * 8, rec + R.gps_off, 8);
        if (L.rgb) {
          Rgb16 v;  // copied out: a record's colour need not be 2-byte aligned
          std::memcpy(&v, rec + R.rgb_off, 6);
          if (b.rgb8) {
            b.rgbc.encode(&v, 1, sl.rgb.data() + o * 3);
          } else {
            b.rgbc.widen(&v, 1, &v);
            std::memcpy(sl.rgb.data() + o * 6, &v, 6);
          }
        }
        if (L.intensity) std::memcpy(sl.inten.data() + o * 2, rec + R.int_off, 2);
        if (L.cls) sl.cls[o] = rec[R.cls_off];
        const std::uint8_t* p = rec + R.pos_off;
        std::uint8_t* out = sl.pos.data() + o * pos_bytes;
        if (R.grid && b.codec.enc == PositionEncoding::las_int32) {
          std::memcpy(out, p, 12);
          continue;
        }
        double v[3];
        if (R.grid) {  // exact: the run was written only when every value round-tripped
          std::int32_t g[3];
          std::memcpy(g, p, 12);
          for (int a = 0; a < 3; ++a) v[a] = las_coordinate(g[a], b.codec.scale[a], b.codec.offset[a]);
        } else {
          std::memcpy(v, p, 24);
        }
        b.codec.encode(v, 1, out);
      }
      cur[r] += n * R.bytes;
      left[r] -= n;
      tree.replace(left[r] > 0 ? get<std::uint64_t>(cur[r], 0) : LoserTree::kDone);
      streak = tree.winner() == r ? streak + 1 : 0;
    }
    if (o != pt.n) throw std::logic_error("index build: a merge part lost records");
  }

  /// The in-order sink: the part's sections appended to the writers (and its positions to the
  /// fused node build, which builds the subtrees whose points are all in).
  void write_slot(const Slot& sl) const {
    if (b.fused) b.fused->feed(sl.pos.data(), sl.n);
    b.w_pos->write(sl.pos.data(), sl.pos.size());
    if (b.w_ids) b.w_ids->write(sl.ids.data(), sl.ids.size());
    if (b.w_rgb) b.w_rgb->write(sl.rgb.data(), sl.rgb.size());
    if (b.w_int) b.w_int->write(sl.inten.data(), sl.inten.size());
    if (b.w_cls) b.w_cls->write(sl.cls.data(), sl.cls.size());
    if (b.w_gps) b.w_gps->write(sl.gps.data(), sl.gps.size());
  }
};

void IndexBuild::merge_runs() { RunMerge(*this).run(); }

}  // namespace rayscan::io::rsi
