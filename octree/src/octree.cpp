#include "rayscan/octree.hpp"
#include "rayscan/morton_sort.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace rayscan {

OctreeLayout parse_octree_layout(const std::string& s) {
  if (s == "layered") return OctreeLayout::layered;
  if (s == "fixed") return OctreeLayout::fixed;
  if (s == "adaptive") return OctreeLayout::adaptive;
  throw std::invalid_argument("octree layout '" + s + "': expected layered, fixed or adaptive");
}

const char* to_string(OctreeLayout layout) {
  switch (layout) {
    case OctreeLayout::layered: return "layered";
    case OctreeLayout::fixed: return "fixed";
    case OctreeLayout::adaptive: return "adaptive";
  }
  return "?";
}

void OctreeConfig::validate() const {
  if (capacity == 0) throw std::invalid_argument("octree: capacity must be >= 1");
  if (max_depth > kMortonBits)
    throw std::invalid_argument("octree: max_depth must be <= 21, got " + std::to_string(max_depth));
  if (depth > kMortonBits)
    throw std::invalid_argument("octree: depth must be <= 21, got " + std::to_string(depth));
}

struct Octree::LevelMaps {
  std::array<std::once_flag, kMortonBits + 1> once;
  std::array<std::vector<std::pair<std::uint64_t, Node>>, kMortonBits + 1> table;
};

Octree::~Octree() = default;
Octree::Octree(Octree&&) noexcept = default;
Octree& Octree::operator=(Octree&&) noexcept = default;

namespace {

constexpr std::uint32_t kCells = 1u << kMortonBits;
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

OctreeRules::Quantizer::Quantizer(const Vec3& corner, double side) : lo(corner), scale(kCells / side) {}

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
  return std::nextafter(f, up ? std::numeric_limits<float>::infinity()
                              : -std::numeric_limits<float>::infinity());
}

// Shared by both builders: validation, the root cell and the Morton codes.
struct OctreeBuilder {
  static void prepare(Octree& t, std::span<const Vec3> pts, const OctreeConfig& cfg,
                      std::vector<std::uint64_t>& codes) {
    cfg.validate();
    if (pts.size() >= 0xFFFFFFFFull) throw std::length_error("octree: more than 2^32 - 2 points");
    t.config_ = cfg;
    t.levels_ = std::make_unique<Octree::LevelMaps>();
    AABB b;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Vec3& p = pts[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw std::invalid_argument("octree: point " + std::to_string(i) +
                                    " has a non-finite coordinate");
      b.expand(p);
    }
    t.cell_ = OctreeRules::root_cell(b);
    const Quantizer qz(t.cell_.lo, OctreeRules::root_side(b));
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
    own_bounds(t, n);
    merge_children(t, n);
    t.depth_ = std::max(t.depth_, depth);
  }
  // rec.lo / hi = the float bounds of n's own points (empty: +inf / -inf).
  static void own_bounds(Octree& t, Octree::Node n) {
    auto& rec = t.nodes_[n];
    AABB own;
    for (std::uint32_t s = rec.own_begin; s < rec.own_end; ++s) own.expand(t.pos_[s]);
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    if (!own.empty())
      for (int a = 0; a < 3; ++a) {
        lo[a] = to_float_bound(own.lo[a] - t.cell_.lo[a], false);
        hi[a] = to_float_bound(own.hi[a] - t.cell_.lo[a], true);
      }
    rec.lo = lo;
    rec.hi = hi;
  }
  // Grows rec.lo / hi by the (final) bounds of n's children.
  static void merge_children(Octree& t, Octree::Node n) {
    auto& rec = t.nodes_[n];
    for (unsigned c = 0; c < rec.child_count; ++c) {
      rec.lo = glm::min(rec.lo, t.nodes_[rec.first_child + c].lo);
      rec.hi = glm::max(rec.hi, t.nodes_[rec.first_child + c].hi);
    }
  }

  // ---- bulk -------------------------------------------------------------------------------
  using Item = MortonKey;

  // The items {codes[i], i} sorted by (code, index) (sort_morton_keys; it replaced
  // tbb::parallel_sort, which was the largest part of the 1e7-point build after the gather:
  // bench/README.md, issue 12).
  static std::unique_ptr<Item[]> sorted_items(const std::vector<std::uint64_t>& codes) {
    std::unique_ptr<Item[]> items(new Item[codes.size()]);  // uninitialised: first touched by the scatter
    sort_morton_keys(codes.size(), [&](std::size_t i) { return codes[i]; }, items.get());
    return items;
  }

  static void bulk(Octree& t, std::span<const Vec3> pts, std::span<Item> items,
                   std::vector<std::uint32_t>& scratch, Octree::Node n, unsigned depth,
                   std::size_t b, std::size_t e) {
    const OctreeConfig& c = t.config_;
    const std::size_t count = e - b;
    const bool same = count == 0 || items[b].code == items[e - 1].code;
    std::size_t rest = e;  // items [b, rest) are this node's own points
    if (splits(c, depth, count, same)) {
      rest = b;
      if (c.layout == OctreeLayout::layered) {
        // Keep the `capacity` smallest original indices (the first inserted); stable partition keeps
        // Morton order on both sides.
        scratch.clear();
        for (std::size_t i = b; i < e; ++i) scratch.push_back(items[i].idx);
        std::nth_element(scratch.begin(), scratch.begin() + (c.capacity - 1), scratch.end());
        const std::uint32_t thr = scratch[c.capacity - 1];
        std::stable_partition(items.begin() + b, items.begin() + e,
                              [thr](const Item& it) { return it.idx <= thr; });
        rest = b + c.capacity;
      }
    }
    // Own points: items [b, rest). Every node's range starts where the previous node's (in
    // depth-first order) ended and later calls only permute ranges of descendants, so after the
    // recursion slot s holds items[s].idx (gathered in parallel by finish_bulk).
    t.nodes_[n].own_begin = static_cast<std::uint32_t>(b);
    t.nodes_[n].own_end = static_cast<std::uint32_t>(rest);
    t.depth_ = std::max(t.depth_, depth);
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
      const auto first = static_cast<Octree::Node>(t.nodes_.size());
      const std::uint64_t key = t.nodes_[n].key;
      t.nodes_.resize(t.nodes_.size() + nchild);
      t.nodes_[n].first_child = first;
      t.nodes_[n].child_count = static_cast<std::uint8_t>(nchild);
      for (unsigned k = 0; k < nchild; ++k) {
        t.nodes_[first + k].key = (key << 3) | oct[k];
        bulk(t, pts, items, scratch, first + k, depth + 1, start[k], start[k + 1]);
      }
    }
  }

  // After bulk(): positions and ids in slot order (a parallel gather: the random reads of the
  // input were ~75% of the serial recursion's time), then the node bounds of close_node: each
  // node's own points in parallel, then children merged into parents in reverse node order
  // (children always have larger indices than their parent).
  static void finish_bulk(Octree& t, std::span<const Vec3> pts, std::span<const Item> items) {
    const std::size_t n = items.size();
    t.pos_.resize(n);
    t.ids_.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<std::size_t>& r) {
      constexpr std::size_t kAhead = 16;
      for (std::size_t s = r.begin(); s != r.end(); ++s) {
        if (s + kAhead < n) __builtin_prefetch(&pts[items[s + kAhead].idx]);
        const std::uint32_t i = items[s].idx;
        t.pos_[s] = pts[i];
        t.ids_[s] = i;
      }
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.nodes_.size(), 1 << 12),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) own_bounds(t, static_cast<Octree::Node>(i));
                      });
    for (std::size_t i = t.nodes_.size(); i-- > 0;) merge_children(t, static_cast<Octree::Node>(i));
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
    const std::vector<std::uint64_t>& codes;
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
      t.nodes_.resize(t.nodes_.size() + nchild);
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
  std::vector<std::uint64_t> codes;
  OctreeBuilder::prepare(t, positions, config, codes);
  const std::unique_ptr<OctreeBuilder::Item[]> buf = OctreeBuilder::sorted_items(codes);
  const std::span<OctreeBuilder::Item> items(buf.get(), positions.size());
  std::vector<std::uint64_t>().swap(codes);
  t.nodes_.emplace_back();
  std::vector<std::uint32_t> scratch;
  OctreeBuilder::bulk(t, positions, items, scratch, 0, 0, 0, items.size());
  t.nodes_.shrink_to_fit();
  OctreeBuilder::finish_bulk(t, positions, items);
  return t;
}

Octree Octree::build_by_insertion(std::span<const Vec3> positions, const OctreeConfig& config) {
  Octree t;
  std::vector<std::uint64_t> codes;
  OctreeBuilder::prepare(t, positions, config, codes);
  OctreeBuilder::Inserter ins{t.config_, codes, {}};
  ins.dn.emplace_back();
  for (std::size_t i = 0; i < positions.size(); ++i)
    ins.insert(0, 0, static_cast<std::uint32_t>(i));
  t.pos_.reserve(positions.size());
  t.ids_.reserve(positions.size());
  t.nodes_.emplace_back();
  OctreeBuilder::compact(t, positions, ins, 0, 0, 0);
  t.nodes_.shrink_to_fit();
  return t;
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
  const Quantizer qz(cell_.lo, cell_.hi.x - cell_.lo.x);
  const std::uint64_t code = qz.code(p);
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
         nodes_.capacity() * sizeof(NodeRec);
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
