// The nodes section of an index build: the page-staged writer of its records (NodeFile) and the
// parallel node construction over the Morton-sorted points that makes Octree::build_bulk's tree
// (NodeBuilder), either after the point sections are written or fused into the merge.
// docs/index-format.md, "Sections" (node record) and "Build (external memory)" 4.
#pragma once

#include "direct_io.hpp"
#include "rayscan/base/option_error.hpp"
#include "pipeline.hpp"

#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bitset>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

namespace rayscan::io::rsi {

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
      throw OptionError({"index build: a leaf of " + std::to_string(cnt) + " points at depth " + std::to_string(d) +
                             " (at most " + std::to_string(IndexNodeRecord::kMaxCount) + " per leaf; use a deeper ",
                         option("depth"), " or ", option("max_depth"), ")"});
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

}  // namespace rayscan::io::rsi
