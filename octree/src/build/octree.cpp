#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/morton_sort.hpp"
#include "rayscan/base/list_text.hpp"
#include "rayscan/base/option_error.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <utility>

namespace rayscan {

OctreeLayout parse_octree_layout(const std::string& s) {
  for (const OctreeLayout layout : kOctreeLayouts)
    if (s == to_string(layout)) return layout;
  throw std::invalid_argument("octree layout '" + s + "': expected " + join_alternatives(octree_layout_names()));
}

const char* to_string(OctreeLayout layout) {
  switch (layout) {
    case OctreeLayout::layered: return "layered";
    case OctreeLayout::fixed: return "fixed";
    case OctreeLayout::adaptive: return "adaptive";
  }
  return "?";
}

std::vector<std::string> octree_layout_names(std::string_view quote) {
  std::vector<std::string> names;
  for (const OctreeLayout layout : kOctreeLayouts) {
    std::string name(quote);
    name += to_string(layout);
    name += quote;
    names.push_back(std::move(name));
  }
  return names;
}

void OctreeConfig::validate() const {
  // OptionErrors naming the fields: each front end writes them as its own options.
  if (capacity == 0) throw OptionError({"octree: ", option("capacity"), " must be >= 1"});
  // max_depth 0 would make the root the only leaf: every query a scan of all points. Refused for
  // every layout, as `rayscan index --max-depth` refuses it, so no front end builds such a tree.
  if (max_depth < 1 || max_depth > kMortonBits)
    throw OptionError({"octree: ", option("max_depth"), " must be in 1..21, got " + std::to_string(max_depth)});
  if (depth > kMortonBits)
    throw OptionError({"octree: ", option("depth"), " must be <= 21, got " + std::to_string(depth)});
}

struct Octree::LevelMaps {
  std::array<std::once_flag, kMortonBits + 1> once;
  std::array<std::vector<std::pair<std::uint64_t, Node>>, kMortonBits + 1> table;
};

Octree::~Octree() = default;
Octree::Octree(Octree&&) noexcept = default;
Octree& Octree::operator=(Octree&&) noexcept = default;

namespace {

using Quantizer = OctreeRules::Quantizer;
inline unsigned octant(std::uint64_t code, unsigned depth) { return OctreeRules::octant(code, depth); }

}  // namespace

double OctreeRules::root_side(const AABB& bounds) {
  if (bounds.empty()) return 1.0;
  const double side = bounds.max_extent();
  return side > 0.0 ? side * (1.0 + 1e-9) : 1.0;
}

AABB OctreeRules::root_cell(const AABB& bounds) {
  const Vec3 lo = bounds.empty() ? Vec3(0.0) : bounds.lo;
  return AABB{lo, lo + Vec3(root_side(bounds))};
}

bool OctreeRules::splits(const OctreeConfig& c, unsigned depth, std::size_t count, bool all_same) {
  switch (c.layout) {
    case OctreeLayout::fixed: return depth < c.depth;
    case OctreeLayout::adaptive: return count > c.capacity && depth < c.max_depth && !all_same;
    case OctreeLayout::layered: return count > c.capacity && depth < c.max_depth;
  }
  return false;
}

// Round to float, then step one float ulp outwards, which is far more than the double rounding of
// the offset and of adding it back to the corner, so the stored box always contains the points.
float OctreeRules::float_bound(double off, bool up) {
  if (off == 0.0) return 0.0f;
  const float f = static_cast<float>(off);
  // std::nextafter(f, +-inf) without the libm call (6 per node, 2% of a 1e7-point build): for a
  // finite non-zero float, the next one away from / towards zero is one step of its bit pattern
  // (IEEE 754 binary32: the magnitude bits are ordered like the magnitudes).
  if (f == 0.0f || !std::isfinite(f))
    return std::nextafter(f, up ? std::numeric_limits<float>::infinity()
                                : -std::numeric_limits<float>::infinity());
  const auto bits = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>((f > 0.0f) == up ? bits + 1 : bits - 1);
}

// Shared by both builders: validation, the root cell and the Morton codes.
struct OctreeBuilder {
  static void prepare(Octree& t, std::span<const Vec3> pts, const OctreeConfig& cfg,
                      DefaultInitVector<std::uint64_t>& codes) {
    cfg.validate();
    if (pts.size() >= 0xFFFFFFFFull) throw std::length_error("octree: more than 2^32 - 2 points");
    t.config_ = cfg;
    t.levels_ = std::make_unique<Octree::LevelMaps>();
    // Bounds and the first non-finite point, in parallel.
    struct Scan {
      AABB box;
      std::size_t bad = static_cast<std::size_t>(-1);
    };
    const Scan scan = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, pts.size(), 1 << 16), Scan{},
        [&](const tbb::blocked_range<std::size_t>& r, Scan acc) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Vec3& p = pts[i];
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
              acc.bad = std::min(acc.bad, i);
              break;
            }
            acc.box.expand(p);
          }
          return acc;
        },
        [](Scan x, const Scan& y) {
          x.box.expand(y.box);
          x.bad = std::min(x.bad, y.bad);
          return x;
        });
    if (scan.bad != static_cast<std::size_t>(-1))
      throw std::invalid_argument("octree: point " + std::to_string(scan.bad) +
                                  " has a non-finite coordinate");
    const AABB& b = scan.box;
    t.cell_ = OctreeRules::root_cell(b);
    t.side_ = OctreeRules::root_side(b);
    const Quantizer qz = t.quantizer();
    codes.resize(pts.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pts.size(), 1 << 16),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) codes[i] = qz.code(pts[i]);
                      });
  }

  static bool splits(const OctreeConfig& c, unsigned depth, std::size_t count, bool all_same) {
    return OctreeRules::splits(c, depth, count, all_same);
  }

  // Append the points `idx` (already in (code, index) order) as the own points of node n.
  static void emit_points(Octree& t, std::span<const Vec3> pts, Octree::Node n,
                          std::span<const std::uint32_t> idx) {
    auto& rec = t.nodes_[n];
    rec.own_begin = static_cast<std::uint32_t>(t.pos_.size());
    for (std::uint32_t i : idx) {
      t.pos_.push_back(pts[i]);
      t.ids_.push_back(i);
    }
    rec.own_end = static_cast<std::uint32_t>(t.pos_.size());
  }

  // A float bound strictly below (up = false) or above (up = true) the double offset `off`: round to
  // float, then step one float ulp outwards, which is far more than the double rounding of the
  // offset and of adding it back to the corner, so the stored box always contains the points.
  static float to_float_bound(double off, bool up) { return OctreeRules::float_bound(off, up); }

  // Bounds of the node's own points and children (children are closed first).
  static void close_node(Octree& t, Octree::Node n, unsigned depth) {
    own_bounds(t.nodes_[n], t.pos_, t.cell_.lo);
    merge_children(t.nodes_.data(), n);
    t.depth_ = std::max(t.depth_, depth);
  }
  // rec.lo / hi = the float bounds of rec's own points pos[own_begin, own_end) relative to
  // `origin` (empty: +inf / -inf).
  static void own_bounds(Octree::NodeRec& rec, std::span<const Vec3> pos, const Vec3& origin) {
    AABB own;
    for (std::uint32_t s = rec.own_begin; s < rec.own_end; ++s) own.expand(pos[s]);
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    if (!own.empty())
      for (int a = 0; a < 3; ++a) {
        lo[a] = to_float_bound(own.lo[a] - origin[a], false);
        hi[a] = to_float_bound(own.hi[a] - origin[a], true);
      }
    rec.lo = lo;
    rec.hi = hi;
  }
  // Grows nodes[n].lo / hi by the (final) bounds of its children (numbered in the same array).
  static void merge_children(Octree::NodeRec* nodes, Octree::Node n) {
    auto& rec = nodes[n];
    for (unsigned c = 0; c < rec.child_count; ++c) {
      rec.lo = glm::min(rec.lo, nodes[rec.first_child + c].lo);
      rec.hi = glm::max(rec.hi, nodes[rec.first_child + c].hi);
    }
  }

  // ---- bulk -------------------------------------------------------------------------------
  using Item = MortonKey;
  // The node arrays of the parallel build's subtrees (below) on pages of their own: they are
  // allocated by TBB's worker threads, whose glibc malloc arenas kept ~3 MB of them after they were
  // freed (`malloc_trim` trims only the main arena's top), 3 B/point more resident memory at 1e6
  // points (bench/notes/). Unmapped, they go back at once.
  template <class T>
  struct MappedAllocator {
    using value_type = T;
    MappedAllocator() noexcept = default;
    template <class U>
    MappedAllocator(const MappedAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) {
      if (n > static_cast<std::size_t>(-1) / sizeof(T)) throw std::bad_alloc();
      void* p = ::mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      return static_cast<T*>(p);
    }
    void deallocate(T* p, std::size_t n) noexcept { ::munmap(p, n * sizeof(T)); }
    template <class U>
    friend bool operator==(const MappedAllocator&, const MappedAllocator<U>&) noexcept {
      return true;
    }
  };
  using Nodes = std::vector<Octree::NodeRec, MappedAllocator<Octree::NodeRec>>;
  // Scratch of keep_first_inserted, one per thread.
  struct LayeredScratch {
    std::vector<std::uint32_t> heap;
    std::vector<Item> kept;
  };

  // The items {codes[i], i} sorted by (code, index) with sort_morton_keys, a bucket sort: a
  // comparison sort (tbb::parallel_sort) was a quarter of the 1e7-point build
  // (bench/notes/2026-11-22-packets-knn-build-remeasure.md).
  static DefaultInitVector<Item> sorted_items(const DefaultInitVector<std::uint64_t>& codes) {
    DefaultInitVector<Item> items(codes.size());  // uninitialised: first touched by the scatter
    sort_morton_keys(codes.size(), [&](std::size_t i) { return codes[i]; }, items.data());
    return items;
  }

  // Layered node of items (count > capacity, distinct idx): moves the `capacity` items of smallest
  // idx (the first inserted) to the front, both parts in their Morton order (a stable partition).
  // The threshold is the capacity-th smallest idx, kept in a max-heap of `capacity` entries in one
  // pass (few heap updates on shuffled input); the partition moves the other items backwards in
  // place. This replaced a copy + nth_element + std::stable_partition per node: 25% and 4% of the
  // 1e7-point layered build under perf (bench/notes/).
  static void keep_first_inserted(std::span<Item> items, std::uint32_t capacity, LayeredScratch& scratch) {
    auto& heap = scratch.heap;
    heap.clear();
    for (std::size_t i = 0; i < capacity; ++i) heap.push_back(items[i].idx);
    std::make_heap(heap.begin(), heap.end());
    for (std::size_t i = capacity; i < items.size(); ++i)
      if (items[i].idx < heap.front()) {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = items[i].idx;
        std::push_heap(heap.begin(), heap.end());
      }
    const std::uint32_t thr = heap.front();
    auto& kept = scratch.kept;
    kept.clear();
    std::size_t w = items.size();
    for (std::size_t i = items.size(); i-- > 0;) {
      if (items[i].idx <= thr)
        kept.push_back(items[i]);
      else
        items[--w] = items[i];  // w > i: only items already read are overwritten
    }
    std::reverse_copy(kept.begin(), kept.end(), items.begin());
  }

  // The top-down build of the subtree of node n (depth `depth`, items [b, e)) into `nodes`, where
  // n and its descendants are numbered: the tree of build_by_insertion, numbered the same way
  // (a node's children are appended as one block when the node is built, then built in octant
  // order). `cut(n, depth, b, e)` returning true leaves the node to the caller (the parallel
  // build's subtrees, below). max_depth grows to the deepest node built.
  template <class Cut>
  static void bulk(const OctreeConfig& c, std::span<Item> items, Nodes& nodes,
                   LayeredScratch& scratch, Octree::Node n, unsigned depth,
                   std::size_t b, std::size_t e, unsigned& max_depth, const Cut& cut) {
    if (cut(n, depth, b, e)) return;
    const std::size_t count = e - b;
    const bool same = count == 0 || items[b].code == items[e - 1].code;
    std::size_t rest = e;  // items [b, rest) are this node's own points
    if (splits(c, depth, count, same)) {
      rest = b;
      if (c.layout == OctreeLayout::layered) {
        keep_first_inserted(items.subspan(b, count), c.capacity, scratch);
        rest = b + c.capacity;
      }
    }
    // Own points: items [b, rest). Every node's range starts where the previous node's (in
    // depth-first order) ended and later calls only permute ranges of descendants, so after the
    // recursion slot s holds items[s].idx (gathered by the caller).
    nodes[n].own_begin = static_cast<std::uint32_t>(b);
    nodes[n].own_end = static_cast<std::uint32_t>(rest);
    max_depth = std::max(max_depth, depth);
    if (rest < e) {
      // Children: contiguous runs of equal octant digit (items are Morton-sorted and share the
      // digits above this level), found by binary search on the digit.
      std::array<std::size_t, 9> start{};
      unsigned nchild = 0;
      std::array<unsigned, 8> oct{};
      std::size_t i = rest;
      while (i < e) {
        const unsigned o = octant(items[i].code, depth);
        const std::size_t j = static_cast<std::size_t>(
            std::partition_point(items.begin() + static_cast<std::ptrdiff_t>(i),
                                 items.begin() + static_cast<std::ptrdiff_t>(e),
                                 [&](const Item& it) { return octant(it.code, depth) == o; }) -
            items.begin());
        start[nchild] = i;
        oct[nchild] = o;
        ++nchild;
        i = j;
      }
      start[nchild] = e;
      const auto first = static_cast<Octree::Node>(nodes.size());
      const std::uint64_t key = nodes[n].key;
      nodes.resize(nodes.size() + nchild);
      nodes[n].first_child = first;
      nodes[n].child_count = static_cast<std::uint8_t>(nchild);
      for (unsigned k = 0; k < nchild; ++k) {
        nodes[first + k].key = (key << 3) | oct[k];
        bulk(c, items, nodes, scratch, first + k, depth + 1, start[k], start[k + 1], max_depth, cut);
      }
    }
  }

  // A subtree of the parallel bulk build: node `root` of the upper tree, its items [b, e), and,
  // once built, the subtree in `nodes` with local numbers (nodes[0] is the root's record).
  struct Subtree {
    Octree::Node root;
    unsigned depth;
    std::size_t b, e;
    Nodes nodes;
    unsigned max_depth = 0;
    std::size_t base = 0;  // final number of nodes[1]
  };

  // The parallel bulk build (bench/notes/):
  // 1. the upper tree, serially, down to nodes of at most max(n / 64, 256) points: those become
  //    subtrees;
  // 2. each subtree in parallel: its nodes with local numbers, then positions and ids gathered
  //    into slot order for its slots [b, e) (slot s holds items[s].idx), then its node bounds
  //    (own points, then children merged into parents in reverse node order: a child's number is
  //    always larger than its parent's);
  // 3. the upper tree's own points and bounds;
  // 4. the final numbers, replaying the serial order over the upper tree: a subtree's
  //    descendants take one contiguous block of numbers at the point where the serial build would
  //    have built them, so the tree equals the serial (and the insertion) build node for node;
  // 5. every subtree copied into the one node array in parallel, child links renumbered.
  static void build(Octree& t, std::span<const Vec3> pts, std::span<Item> items) {
    const OctreeConfig& c = t.config_;
    const std::size_t n = items.size();
    const std::size_t cut_size = std::max<std::size_t>(n / 64, 256);
    Nodes upper(1);  // NodeRec{}: all zero
    upper[0].key = 1;
    std::vector<Subtree> subs;
    LayeredScratch scratch;
    unsigned max_depth = 0;
    bulk(c, items, upper, scratch, 0, 0, 0, n, max_depth,
         [&](Octree::Node node, unsigned depth, std::size_t b, std::size_t e) {
           if (e - b > cut_size) return false;
           subs.push_back(Subtree{node, depth, b, e, {}, 0, 0});
           return true;
         });
    t.pos_.resize(n);  // uninitialised: first touched by the gathers
    t.ids_.resize(n);
    auto gather = [&](std::size_t b, std::size_t e) {
      constexpr std::size_t kAhead = 16;
      for (std::size_t s = b; s != e; ++s) {
        if (s + kAhead < e) __builtin_prefetch(&pts[items[s + kAhead].idx]);
        const std::uint32_t i = items[s].idx;
        t.pos_[s] = pts[i];
        t.ids_[s] = i;
      }
    };
    const Vec3 origin = t.cell_.lo;
    tbb::parallel_for(std::size_t{0}, subs.size(), [&](std::size_t k) {
      Subtree& s = subs[k];
      LayeredScratch local_scratch;
      s.nodes.reserve((s.e - s.b) / 4 + 64);  // (adaptive, uniform: ~0.13 nodes per point)
      s.nodes.push_back(upper[s.root]);
      s.max_depth = s.depth;
      bulk(c, items, s.nodes, local_scratch, 0, s.depth, s.b, s.e, s.max_depth,
           [](Octree::Node, unsigned, std::size_t, std::size_t) { return false; });
      gather(s.b, s.e);
      for (auto& rec : s.nodes) own_bounds(rec, t.pos_, origin);
      for (std::size_t i = s.nodes.size(); i-- > 0;) merge_children(s.nodes.data(), static_cast<Octree::Node>(i));
    });
    // The upper tree: a subtree root takes its record from its subtree, the others their own
    // points (layered interior points) and then their children's bounds.
    std::vector<std::int32_t> sub_of(upper.size(), -1);
    for (std::size_t k = 0; k < subs.size(); ++k) {
      sub_of[subs[k].root] = static_cast<std::int32_t>(k);
      upper[subs[k].root] = subs[k].nodes[0];
      max_depth = std::max(max_depth, subs[k].max_depth);
    }
    for (std::size_t i = upper.size(); i-- > 0;) {
      if (sub_of[i] >= 0) continue;
      gather(upper[i].own_begin, upper[i].own_end);
      own_bounds(upper[i], t.pos_, origin);
      merge_children(upper.data(), static_cast<Octree::Node>(i));
    }
    // Final numbers: upper node u becomes number[u]; the serial build's order of allocation.
    std::vector<Octree::Node> number(upper.size(), 0);
    std::size_t next = 1;
    auto assign = [&](auto&& self, Octree::Node u) -> void {
      if (sub_of[u] >= 0) {
        Subtree& s = subs[static_cast<std::size_t>(sub_of[u])];
        s.base = next;
        next += s.nodes.size() - 1;
        return;
      }
      const Octree::NodeRec& rec = upper[u];
      const std::size_t first = next;
      next += rec.child_count;
      for (unsigned k = 0; k < rec.child_count; ++k) number[rec.first_child + k] = static_cast<Octree::Node>(first + k);
      for (unsigned k = 0; k < rec.child_count; ++k) self(self, rec.first_child + k);
    };
    assign(assign, 0);
    if (next >= 0xFFFFFFFFull) throw std::length_error("octree: more than 2^32 - 2 nodes");
    t.nodes_.resize(next);  // uninitialised: every record is written below
    // A subtree's local node j >= 1 becomes base + j - 1; its local root is the upper node.
    auto renumber = [](Octree::NodeRec rec, std::size_t base) {
      if (rec.child_count) rec.first_child = static_cast<Octree::Node>(base + rec.first_child - 1);
      return rec;
    };
    for (std::size_t u = 0; u < upper.size(); ++u) {
      if (sub_of[u] >= 0) {
        t.nodes_[number[u]] = renumber(upper[u], subs[static_cast<std::size_t>(sub_of[u])].base);
      } else {
        Octree::NodeRec rec = upper[u];
        if (rec.child_count) rec.first_child = number[rec.first_child];
        t.nodes_[number[u]] = rec;
      }
    }
    tbb::parallel_for(std::size_t{0}, subs.size(), [&](std::size_t k) {
      Subtree& s = subs[k];
      for (std::size_t j = 1; j < s.nodes.size(); ++j) t.nodes_[s.base + j - 1] = renumber(s.nodes[j], s.base);
      Nodes().swap(s.nodes);
    });
    t.depth_ = max_depth;
  }

  // ---- insertion --------------------------------------------------------------------------
  struct DynNode {
    std::array<std::int32_t, 8> child;
    std::vector<std::uint32_t> pts;
    bool internal = false;
    bool same = true;  // all pts share one Morton code (adaptive duplicate guard)
    DynNode() { child.fill(-1); }
  };

  struct Inserter {
    const OctreeConfig& c;
    const DefaultInitVector<std::uint64_t>& codes;
    std::vector<DynNode> dn;

    std::int32_t child_of(std::int32_t n, unsigned o) {
      if (dn[n].child[o] < 0) {
        dn[n].child[o] = static_cast<std::int32_t>(dn.size());
        dn.emplace_back();
      }
      return dn[n].child[o];
    }

    void insert(std::int32_t n, unsigned depth, std::uint32_t i) {
      for (;;) {
        DynNode& node = dn[n];
        if (!node.internal) {
          const bool stays = c.layout != OctreeLayout::layered ||
                             node.pts.size() < c.capacity || depth >= c.max_depth;
          if (c.layout == OctreeLayout::fixed && depth < c.depth) {
            node.internal = true;  // fixed: interior nodes never hold points
          } else if (stays) {
            if (!node.pts.empty() && codes[node.pts.front()] != codes[i]) node.same = false;
            node.pts.push_back(i);
            if (c.layout == OctreeLayout::adaptive &&
                splits(c, depth, node.pts.size(), node.same)) {
              std::vector<std::uint32_t> moved;
              moved.swap(dn[n].pts);
              dn[n].internal = true;
              for (std::uint32_t m : moved) insert(child_of(n, octant(codes[m], depth)), depth + 1, m);
            }
            return;
          } else {
            node.internal = true;  // layered node full: this point and later ones pass down
          }
        }
        n = child_of(n, octant(codes[i], depth));
        ++depth;
      }
    }
  };

  static void compact(Octree& t, std::span<const Vec3> pts, Inserter& ins, std::int32_t dnode,
                      Octree::Node n, unsigned depth) {
    DynNode& d = ins.dn[dnode];
    std::sort(d.pts.begin(), d.pts.end(), [&](std::uint32_t a, std::uint32_t b) {
      return ins.codes[a] < ins.codes[b] || (ins.codes[a] == ins.codes[b] && a < b);
    });
    emit_points(t, pts, n, d.pts);
    unsigned nchild = 0;
    for (std::int32_t ch : d.child) nchild += ch >= 0;
    if (nchild) {
      const auto first = static_cast<Octree::Node>(t.nodes_.size());
      const std::uint64_t key = t.nodes_[n].key;
      t.nodes_.resize(t.nodes_.size() + nchild, Octree::NodeRec{});
      t.nodes_[n].first_child = first;
      t.nodes_[n].child_count = static_cast<std::uint8_t>(nchild);
      unsigned k = 0;
      for (unsigned o = 0; o < 8; ++o) {
        const std::int32_t ch = ins.dn[dnode].child[o];
        if (ch < 0) continue;
        t.nodes_[first + k].key = (key << 3) | o;
        compact(t, pts, ins, ch, first + k, depth + 1);
        ++k;
      }
    }
    close_node(t, n, depth);
  }
};

Octree Octree::build_bulk(std::span<const Vec3> positions, const OctreeConfig& config) {
  Octree t;
  DefaultInitVector<std::uint64_t> codes;
  OctreeBuilder::prepare(t, positions, config, codes);
  DefaultInitVector<OctreeBuilder::Item> buf = OctreeBuilder::sorted_items(codes);
  const std::span<OctreeBuilder::Item> items(buf.data(), positions.size());
  DefaultInitVector<std::uint64_t>().swap(codes);
  OctreeBuilder::build(t, positions, items);
  t.build_child_blocks();
  return t;
}

Octree Octree::build_by_insertion(std::span<const Vec3> positions, const OctreeConfig& config) {
  Octree t;
  DefaultInitVector<std::uint64_t> codes;
  OctreeBuilder::prepare(t, positions, config, codes);
  OctreeBuilder::Inserter ins{t.config_, codes, {}};
  ins.dn.emplace_back();
  for (std::size_t i = 0; i < positions.size(); ++i)
    ins.insert(0, 0, static_cast<std::uint32_t>(i));
  t.pos_.reserve(positions.size());
  t.ids_.reserve(positions.size());
  Octree::NodeRec root{};
  root.key = 1;
  t.nodes_.push_back(root);
  OctreeBuilder::compact(t, positions, ins, 0, 0, 0);
  t.nodes_.shrink_to_fit();
  t.build_child_blocks();
  return t;
}

void Octree::build_child_blocks() {
  const std::size_t n = nodes_.size();
  block_of_.resize(n);
  std::uint32_t blocks = 0;
  for (std::size_t i = 0; i < n; ++i) {
    block_of_[i] = nodes_[i].child_count ? blocks : 0;
    blocks += nodes_[i].child_count != 0;
  }
  child_soa_.resize(std::size_t{blocks} * kChildBlockFloats);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    const NodeRec& r = nodes_[i];
    if (!r.child_count) return;
    float* b = child_soa_.data() + std::size_t{kChildBlockFloats} * block_of_[i];
    for (unsigned c = 0; c < 8; ++c) {
      const bool in = c < r.child_count;
      const NodeRec& k = nodes_[r.first_child + (in ? c : 0)];
      for (int a = 0; a < 3; ++a) {
        b[a * 8 + c] = in ? k.lo[a] : std::numeric_limits<float>::infinity();
        b[(3 + a) * 8 + c] = in ? k.hi[a] : -std::numeric_limits<float>::infinity();
      }
    }
  });

  // The entry grids (entry_grid.hpp), from the node ids' octant digits.
  entry_ = build_entry_grid(*this, depth_, n, [&](Node c) { return static_cast<unsigned>(nodes_[c].key & 7u); },
                            quantizer(), side_);
}

std::optional<Octree::Node> Octree::find(OctreeNodeId id) const {
  const unsigned d = id.depth();
  if (d > kMortonBits || nodes_.empty()) return std::nullopt;
  std::call_once(levels_->once[d], [&] {
    auto& tab = levels_->table[d];
    for (Node n = 0; n < nodes_.size(); ++n) {
      const OctreeNodeId nid = node_id(n);
      if (nid.depth() == d) tab.emplace_back(nid.morton(), n);
    }
    std::sort(tab.begin(), tab.end());
  });
  const auto& tab = levels_->table[d];
  const auto it = std::lower_bound(tab.begin(), tab.end(), std::make_pair(id.morton(), Node{0}));
  if (it == tab.end() || it->first != id.morton()) return std::nullopt;
  return it->second;
}

std::optional<Octree::Node> Octree::locate(const Vec3& p) const {
  if (nodes_.empty() || !cell_.contains(p)) return std::nullopt;
  const std::uint64_t code = quantizer().code(p);
  Node best = 0;
  for (unsigned d = 1; d <= depth_; ++d) {
    const auto n = find(OctreeNodeId(d, code >> (3 * (kMortonBits - d))));
    if (!n) break;
    best = *n;
  }
  return best;
}

AABB Octree::cell_bounds(Node n) const {
  const OctreeNodeId id = node_id(n);
  const unsigned d = id.depth();
  const std::uint64_t m = id.morton();
  const double side = (cell_.hi.x - cell_.lo.x) / static_cast<double>(1u << d);
  const Vec3 ijk(static_cast<double>(morton_compact(m)), static_cast<double>(morton_compact(m >> 1)),
                 static_cast<double>(morton_compact(m >> 2)));
  const Vec3 lo = cell_.lo + ijk * side;
  return {lo, lo + Vec3(side)};
}

std::size_t Octree::memory_bytes() const {
  return pos_.capacity() * sizeof(Vec3) + ids_.capacity() * sizeof(PointIndex) +
         nodes_.capacity() * sizeof(NodeRec) + child_soa_.capacity() * sizeof(float) +
         block_of_.capacity() * sizeof(std::uint32_t) + entry_.cells.capacity() * sizeof(EntryCell);
}

bool Octree::same_structure(const Octree& o) const {
  if (nodes_.size() != o.nodes_.size() || ids_ != o.ids_) return false;
  if (cell_.lo != o.cell_.lo || cell_.hi != o.cell_.hi) return false;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const NodeRec &a = nodes_[i], &b = o.nodes_[i];
    if (a.key != b.key || a.first_child != b.first_child || a.own_begin != b.own_begin ||
        a.own_end != b.own_end || a.child_count != b.child_count || a.lo != b.lo || a.hi != b.hi)
      return false;
  }
  return true;
}

}  // namespace rayscan
