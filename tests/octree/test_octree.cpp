// Octree structure (paper section 4.1): insertion == bulk, the three organisations' invariants,
// Warren & Salmon ids and the lazy per-level maps, duplicates, storage order and permutation.
#include "test_util.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/base/default_init_vector.hpp"
#include "rayscan/octree/morton_sort.hpp"
#include "rayscan/octree/octree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <limits>
#include <numeric>
#include <random>

using namespace rayscan;
using namespace rayscan::test;

namespace {

struct Cfg {
  OctreeLayout layout;
  std::uint32_t capacity;
  unsigned depth;
  unsigned max_depth;
};

std::vector<Cfg> configs() {
  return {{OctreeLayout::adaptive, 1, 6, 21}, {OctreeLayout::adaptive, 16, 6, 21},
          {OctreeLayout::adaptive, 16, 6, 3}, {OctreeLayout::layered, 4, 6, 21},
          {OctreeLayout::layered, 32, 6, 2},  {OctreeLayout::fixed, 16, 0, 21},
          {OctreeLayout::fixed, 16, 5, 21}};
}

OctreeConfig to_config(const Cfg& c) {
  OctreeConfig o;
  o.layout = c.layout;
  o.capacity = c.capacity;
  o.depth = c.depth;
  o.max_depth = c.max_depth;
  return o;
}

// Checks every structural invariant the header documents.
void check_invariants(const Octree& t, std::span<const Vec3> pts, const OctreeConfig& c) {
  ASSERT_EQ(t.positions().size(), pts.size());
  // ids is a permutation and positions are the reordered input.
  std::vector<PointIndex> ids(t.ids().begin(), t.ids().end());
  for (std::size_t s = 0; s < ids.size(); ++s) ASSERT_EQ(t.positions()[s], pts[ids[s]]);
  std::sort(ids.begin(), ids.end());
  for (std::size_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], i);
  if (pts.empty()) return;
  // Walk: subtree slots contiguous, children tile the subtree after own points, boxes tight.
  std::vector<std::pair<Octree::Node, unsigned>> stack{{t.root(), 0}};
  std::size_t visited = 0;
  while (!stack.empty()) {
    auto [n, depth] = stack.back();
    stack.pop_back();
    ++visited;
    EXPECT_EQ(t.node_id(n).depth(), depth);
    const SlotRange own = t.node_points(n);
    const SlotRange sub = t.subtree_points(n);
    EXPECT_EQ(own.begin, sub.begin);
    // Bounds contain every subtree point and are tight up to float rounding of the offsets.
    AABB tight;
    for (std::uint32_t s = sub.begin; s < sub.end; ++s) tight.expand(t.positions()[s]);
    const AABB nb = t.node_bounds(n);
    const double slack = 1e-6 * std::max(t.root_cell().max_extent(), 1.0);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(nb.lo[a], tight.lo[a]);
      EXPECT_GE(nb.hi[a], tight.hi[a]);
      EXPECT_LE(tight.lo[a] - nb.lo[a], slack);
      EXPECT_LE(nb.hi[a] - tight.hi[a], slack);
    }
    // Every point of the subtree lies in the node's cell (up to the cell's rounding).
    const AABB cell = t.cell_bounds(n);
    const double eps = 1e-9 * t.root_cell().max_extent();
    for (std::uint32_t s = sub.begin; s < sub.end; ++s) {
      const Vec3& p = t.positions()[s];
      EXPECT_TRUE(p.x >= cell.lo.x - eps && p.x <= cell.hi.x + eps && p.y >= cell.lo.y - eps &&
                  p.y <= cell.hi.y + eps && p.z >= cell.lo.z - eps && p.z <= cell.hi.z + eps);
    }
    std::uint32_t next = own.end;
    for (unsigned i = 0; i < t.child_count(n); ++i) {
      const auto ch = t.child(n, i);
      EXPECT_EQ(t.subtree_points(ch).begin, next);
      next = t.subtree_points(ch).end;
      EXPECT_EQ(t.node_id(ch).parent(), t.node_id(n));
      EXPECT_GT(t.subtree_points(ch).size(), 0u) << "empty child";
      stack.push_back({ch, depth + 1});
    }
    EXPECT_EQ(next, sub.end);
    const bool leaf = t.child_count(n) == 0;
    switch (c.layout) {
      case OctreeLayout::fixed:
        if (leaf) {
          EXPECT_EQ(depth, c.depth);
        } else {
          EXPECT_EQ(own.size(), 0u);
        }
        break;
      case OctreeLayout::layered:
        if (!leaf) {
          EXPECT_EQ(own.size(), c.capacity);
        } else if (depth < c.max_depth) {
          EXPECT_LE(own.size(), c.capacity);
        }
        break;
      case OctreeLayout::adaptive:
        if (!leaf) {
          EXPECT_EQ(own.size(), 0u);
        } else if (depth < c.max_depth && own.size() > c.capacity) {
          // Only an all-duplicate leaf may exceed the capacity.
          for (std::uint32_t s = own.begin; s < own.end; ++s)
            EXPECT_EQ(t.positions()[s], t.positions()[own.begin]);
        }
        break;
    }
  }
  EXPECT_EQ(visited, t.node_count());
}

TEST(OctreeRules, FloatBoundIsTheNextFloatOutwardsOfTheRoundedOffset) {
  // The oracle: std::nextafter of the offset rounded to float, towards +inf (up) or -inf (down);
  // 0 stays 0. Offsets of every magnitude and sign, ones that round to 0, to FLT_MAX and past it.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> exp2(-160, 140);
  std::vector<double> offs = {0.0, -0.0, 1.0, -1.0, 1e-50, -1e-50, 0x1p-149, -0x1p-149, 0x1p-126,
                              double(std::numeric_limits<float>::max()), -double(std::numeric_limits<float>::max()),
                              1e39, -1e39};
  for (int i = 0; i < 100000; ++i) offs.push_back(std::ldexp(mant(rng), exp2(rng)));
  for (const double off : offs)
    for (const bool up : {false, true}) {
      const float f = static_cast<float>(off);
      const float want = off == 0.0 ? 0.0f
                                    : std::nextafter(f, up ? std::numeric_limits<float>::infinity()
                                                           : -std::numeric_limits<float>::infinity());
      const float got = OctreeRules::float_bound(off, up);
      ASSERT_EQ(std::bit_cast<std::uint32_t>(got), std::bit_cast<std::uint32_t>(want)) << off << " up " << up;
    }
}

TEST(Octree, InsertionAndBulkBuildIdenticalTrees) {
  for (Dist d : {Dist::uniform, Dist::clustered, Dist::identical, Dist::grid, Dist::utm_mm})
    for (std::size_t n : {0u, 1u, 2u, 1000u, 20000u})
      for (const Cfg& cfg : configs()) {
        const auto pts = make_points(n, d, 17);
        const OctreeConfig c = to_config(cfg);
        const Octree bulk = Octree::build_bulk(pts, c);
        const Octree ins = Octree::build_by_insertion(pts, c);
        SCOPED_TRACE(std::string(name(d)) + " n=" + std::to_string(n) + " " + to_string(c.layout) +
                     " cap=" + std::to_string(c.capacity));
        EXPECT_TRUE(bulk.same_structure(ins));
        check_invariants(bulk, pts, c);
        if (::testing::Test::HasFailure()) return;
      }
}

// The child blocks (child_boxes_f's soa) hold every interior node's child boxes transposed, bit
// for bit the records' float boxes, for both builders and every layout; leaves have none.
TEST(Octree, ChildBlocksAreTheChildRecordsTransposed) {
  for (OctreeLayout layout : {OctreeLayout::layered, OctreeLayout::fixed, OctreeLayout::adaptive})
    for (Dist d : {Dist::uniform, Dist::clustered}) {
      const auto pts = make_points(20000, d, 23);
      const OctreeConfig cfg = OctreeConfig::for_layout(layout);
      const Octree trees[] = {Octree::build_bulk(pts, cfg), Octree::build_by_insertion(pts, cfg)};
      for (const Octree& t : trees) {
        std::size_t interior = 0;
        for (Octree::Node n = 0; n < t.node_count(); ++n) {
          const simd::ChildBoxesF b = t.child_boxes_f(n);
          if (t.child_count(n) == 0) {
            EXPECT_EQ(b.soa, nullptr);
            continue;
          }
          ++interior;
          ASSERT_NE(b.soa, nullptr);
          ASSERT_EQ(b.soa, t.child_blocks() + 48 * std::size_t{t.block_of(n)});
          for (unsigned c = 0; c < b.count; ++c)
            for (unsigned f = 0; f < 6; ++f)
              ASSERT_EQ(b.soa[f * 8 + c], b.base[c * b.stride + f]) << "node " << n << " child " << c;
        }
        EXPECT_GT(interior, 0u);
      }
    }
}

TEST(Octree, EntryGridsHoldTheDeepestNodeOfEachCell) {
  // Every cell (i, j, k) of every level l of the entry grids names the deepest node whose cell
  // contains it (its Warren & Salmon id a prefix of the cell's, and no child of it with a longer
  // one), and every point's cell at every level (from the point's own Morton code) names a node
  // whose subtree holds that point: the property the entry-point search relies on. Depth
  // min(depth - 1, 5), at most 8 cells a node; none for the layered layout (its nodes above hold
  // points of their own) or a single node. A small deep tree keeps a small grid.
  for (OctreeLayout layout : {OctreeLayout::fixed, OctreeLayout::adaptive, OctreeLayout::layered})
    for (Dist d : {Dist::uniform, Dist::clustered, Dist::grid}) {
      const auto pts = make_points(30000, d, 29);
      OctreeConfig cfg = OctreeConfig::for_layout(layout);
      cfg.capacity = 16;
      const Octree trees[] = {Octree::build_bulk(pts, cfg), Octree::build_by_insertion(pts, cfg)};
      for (const Octree& t : trees) {
        const std::string ctx = std::string(to_string(layout)) + " " + name(d);
        const Octree::EntryGrid g = t.entry_grid();
        if (layout == OctreeLayout::layered) {
          EXPECT_EQ(g.cells, nullptr) << ctx;
          EXPECT_EQ(g.depth, 0u) << ctx;
          continue;
        }
        ASSERT_NE(g.cells, nullptr) << ctx;
        unsigned want = std::min(t.depth() - 1, Octree::kEntryGridMaxDepth);
        while (want > 1 && (std::size_t{1} << (3 * want)) > 8 * t.node_count()) --want;
        ASSERT_EQ(g.depth, want) << ctx;
        ASSERT_GE(g.depth, 2u) << ctx;
        // First hits use the grid where the cloud fills its cube (uniform: a node in almost every
        // deepest cell), not where most cells are empty (five small clusters).
        if (d == Dist::uniform) {
          EXPECT_TRUE(g.first_hits) << ctx;
        } else if (d == Dist::clustered) {
          EXPECT_FALSE(g.first_hits) << ctx;
        }
        EXPECT_EQ(g.quant.lo, t.root_cell().lo);
        for (unsigned l = 0; l <= g.depth; ++l) {
          const std::uint32_t w = 1u << l;
          for (std::uint32_t k = 0; k < w; ++k)
            for (std::uint32_t j = 0; j < w; ++j)
              for (std::uint32_t i = 0; i < w; ++i) {
                const Octree::EntryCell c = g.at(l, i, j, k);
                const OctreeNodeId id = t.node_id(c.node);
                ASSERT_EQ(c.depth, id.depth()) << ctx;
                ASSERT_LE(c.depth, l) << ctx;
                const unsigned sh = l - c.depth;
                const std::uint64_t m = morton_encode(i >> sh, j >> sh, k >> sh);
                ASSERT_EQ(id.morton(), m) << ctx << " level " << l << " cell " << i << "," << j << "," << k;
                if (c.depth < l) {
                  const std::uint64_t below = morton_encode(i >> (sh - 1), j >> (sh - 1), k >> (sh - 1));
                  for (unsigned ch = 0; ch < t.child_count(c.node); ++ch) {
                    ASSERT_NE(t.node_id(t.child(c.node, ch)).morton(), below)
                        << ctx << ": a deeper node holds level " << l << " cell " << i << "," << j << "," << k;
                  }
                }
              }
        }
        AABB bounds;
        for (const Vec3& p : pts) bounds.expand(p);
        const OctreeRules::Quantizer quant(t.root_cell().lo, OctreeRules::root_side(bounds));
        EXPECT_EQ(t.quantizer().scale, quant.scale) << ctx;
        const auto pos = t.positions();
        for (std::uint32_t s = 0; s < pos.size(); s += 7) {
          const std::uint64_t code = quant.code(pos[s]);
          for (unsigned l = 0; l <= g.depth; ++l) {
            const std::uint64_t cell = code >> (3 * (kMortonBits - l));
            const auto i = static_cast<std::uint32_t>(morton_compact(cell)), j = static_cast<std::uint32_t>(morton_compact(cell >> 1)),
                       k = static_cast<std::uint32_t>(morton_compact(cell >> 2));
            const Octree::Node n = g.at(l, i, j, k).node;
            const SlotRange sub = t.subtree_points(n);
            ASSERT_TRUE(s >= sub.begin && s < sub.end) << ctx << ": slot " << s << " level " << l;
          }
        }
      }
    }
  const std::vector<Vec3> one{Vec3(1, 2, 3)};
  EXPECT_EQ(Octree::build_bulk(one).entry_grid().cells, nullptr);
  const auto few = make_points(60, Dist::clustered, 31);
  OctreeConfig deep;
  deep.capacity = 1;
  const Octree small = Octree::build_bulk(few, deep);
  ASSERT_GE(small.depth(), 7u);
  const unsigned gd = small.entry_grid().depth;
  EXPECT_LT(gd, Octree::kEntryGridMaxDepth);
  EXPECT_LE(std::size_t{1} << (3 * gd), 8 * small.node_count());
}

// build_entry_grid checks the octants it is given against the nodes' bounds: the tree's own digits
// give the tree's grid; digits that name other cells (a damaged index file's octants: siblings'
// shifted by one, or one child's alone) give no grid, so queries start at the root.
TEST(Octree, EntryGridOfOctantsThatDoNotMatchTheBoundsIsNone) {
  const auto pts = make_points(20000, Dist::uniform, 37);
  const Octree t = Octree::build_bulk(pts);
  const EntryGrid g = t.entry_grid();
  ASSERT_NE(g.cells, nullptr);
  const std::size_t cells = EntryGrid::slot(g.depth + 1, 0, 0, 0);
  auto digit = [&](Octree::Node c) { return static_cast<unsigned>(t.node_id(c).bits() & 7u); };
  const EntryCells same = build_entry_grid(t, t.depth(), t.node_count(), digit, t.quantizer(), g.side);
  ASSERT_EQ(same.cells.size(), cells);
  for (std::size_t c = 0; c < cells; ++c) ASSERT_EQ(same.cells[c].node, g.cells[c].node) << c;
  // Node 1 is the root's first child; its digit, or every depth-2 digit, moved by one.
  const EntryCells one = build_entry_grid(t, t.depth(), t.node_count(),
                                          [&](Octree::Node c) { return c == 1 ? (digit(c) + 1) & 7u : digit(c); },
                                          t.quantizer(), g.side);
  EXPECT_TRUE(one.cells.empty());
  EXPECT_EQ(one.depth, 0u);
  const EntryCells shifted = build_entry_grid(
      t, t.depth(), t.node_count(),
      [&](Octree::Node c) { return t.node_id(c).depth() == 2 ? (digit(c) + 1) & 7u : digit(c); }, t.quantizer(),
      g.side);
  EXPECT_TRUE(shifted.cells.empty());
}

TEST(Octree, DuplicatesDoNotSplitEndlessly) {
  std::vector<Vec3> pts(50000, Vec3(1.5, -2.0, 3.25));
  pts.emplace_back(1.0, 1.0, 1.0);  // one distinct point forces a real root split
  OctreeConfig c;
  c.capacity = 8;
  const Octree t = Octree::build_bulk(pts, c);
  EXPECT_LT(t.node_count(), 50u);  // a chain to the depth where the two separate, nothing more
  check_invariants(t, pts, c);
}

TEST(Octree, LayeredKeepsFirstInsertedPointsPerLevel) {
  const auto pts = make_points(5000, Dist::uniform, 4);
  OctreeConfig c;
  c.layout = OctreeLayout::layered;
  c.capacity = 10;
  const Octree t = Octree::build_by_insertion(pts, c);
  // The root keeps points 0..9, the first ten inserted: a subsample.
  std::vector<PointIndex> root_ids;
  for (std::uint32_t s = t.node_points(t.root()).begin; s < t.node_points(t.root()).end; ++s)
    root_ids.push_back(t.ids()[s]);
  std::sort(root_ids.begin(), root_ids.end());
  std::vector<PointIndex> first(10);
  std::iota(first.begin(), first.end(), 0u);
  EXPECT_EQ(root_ids, first);
}

TEST(Octree, LevelMapsFindEveryNodeAndLocateFindsTheDeepestCell) {
  const auto pts = make_points(3000, Dist::clustered, 8);
  const Octree t = Octree::build_bulk(pts, OctreeConfig{OctreeLayout::adaptive, 4, 21, 6});
  for (Octree::Node n = 0; n < t.node_count(); ++n) {
    const auto found = t.find(t.node_id(n));
    ASSERT_TRUE(found.has_value());
    EXPECT_EQ(*found, n);
  }
  EXPECT_FALSE(t.find(OctreeNodeId(21, 12345)).has_value());
  for (std::size_t i = 0; i < pts.size(); i += 37) {
    const auto n = t.locate(pts[i]);
    ASSERT_TRUE(n.has_value());
    EXPECT_EQ(t.child_count(*n), 0u);  // adaptive: the deepest node holding p is a leaf
    const SlotRange sr = t.node_points(*n);
    bool holds = false;
    for (std::uint32_t s = sr.begin; s < sr.end; ++s) holds = holds || t.ids()[s] == i;
    EXPECT_TRUE(holds) << "point " << i;
  }
  EXPECT_FALSE(t.locate(Vec3(100, 100, 100)).has_value());
}

TEST(Octree, RejectsBadInput) {
  std::vector<Vec3> pts = {Vec3(0.0), Vec3(std::nan(""), 0, 0)};
  EXPECT_THROW(Octree::build_bulk(pts), std::invalid_argument);
  EXPECT_THROW(Octree::build_by_insertion(pts), std::invalid_argument);
  OctreeConfig c;
  c.capacity = 0;
  EXPECT_THROW(Octree::build_bulk(std::span<const Vec3>{}, c), std::invalid_argument);
  c = {};
  c.max_depth = 22;
  EXPECT_THROW(Octree::build_bulk(std::span<const Vec3>{}, c), std::invalid_argument);
  EXPECT_THROW(parse_octree_layout("grid"), std::invalid_argument);
}

// max_depth has the range of `rayscan index --max-depth` (1..21) for every layout and both
// builders, and make_index (the scene files' and Python's path) inherits it; the bounds build.
TEST(Octree, MaxDepthRangeIsTheCliRange) {
  const auto pts = make_points(500, Dist::uniform, 3);
  for (OctreeLayout l : {OctreeLayout::adaptive, OctreeLayout::layered, OctreeLayout::fixed}) {
    SCOPED_TRACE(to_string(l));
    for (unsigned bad : {0u, 22u}) {
      OctreeConfig c = OctreeConfig::for_layout(l);
      c.max_depth = bad;
      const std::string want = "octree: max_depth must be in 1..21, got " + std::to_string(bad);
      for (bool insertion : {false, true}) {
        try {
          (void)(insertion ? Octree::build_by_insertion(pts, c) : Octree::build_bulk(pts, c));
          ADD_FAILURE() << "max_depth " << bad << " was accepted";
        } catch (const std::invalid_argument& e) {
          EXPECT_EQ(std::string(e.what()), want);
        }
      }
      IndexOptions o;
      o.type = std::string("octree-") + to_string(l);
      o.max_depth = bad;
      EXPECT_THROW((void)make_index(pts, o), std::invalid_argument);
    }
    for (unsigned good : {1u, 21u}) {
      OctreeConfig c = OctreeConfig::for_layout(l);
      c.max_depth = good;
      c.capacity = 4;
      const Octree t = Octree::build_bulk(pts, c);
      EXPECT_EQ(t.ids().size(), pts.size());
      // 500 points over capacity 4: an adaptive or layered tree splits down to max_depth 1.
      if (l != OctreeLayout::fixed && good == 1) {
        EXPECT_EQ(t.depth(), 1u);
      }
    }
  }
}

// make_index without a capacity builds each layout at its own default (default_capacity: the
// layered octree must not inherit the adaptive leaf size of OctreeConfig{}); a given capacity wins,
// and index_capacity reports what was built.
TEST(Octree, MakeIndexTakesEachLayoutsDefaultCapacity) {
  const auto pts = make_points(20000, Dist::uniform, 5);
  for (OctreeLayout l : {OctreeLayout::adaptive, OctreeLayout::layered, OctreeLayout::fixed}) {
    SCOPED_TRACE(to_string(l));
    IndexOptions o;
    o.type = std::string("octree-") + to_string(l);
    const AnyIndex built = make_index(pts, o);
    const Octree& t = std::get<Octree>(built);
    EXPECT_EQ(t.config().capacity, default_capacity(l));
    EXPECT_EQ(index_capacity(o), default_capacity(l));
    EXPECT_TRUE(t.same_structure(Octree::build_bulk(pts, OctreeConfig::for_layout(l))));
    o.capacity = 9;
    const AnyIndex nine = make_index(pts, o);
    EXPECT_EQ(std::get<Octree>(nine).config().capacity, 9u);
    EXPECT_EQ(index_capacity(o), 9u);
  }
  IndexOptions kd;
  kd.type = "kdtree";
  EXPECT_EQ(index_capacity(kd), kDefaultKdTreeLeaf);
}

TEST(Octree, MemoryStaysUnderFortyBytesPerPoint) {
  const auto pts = make_points(200000, Dist::uniform, 2);
  const Octree t = Octree::build_bulk(pts);  // default config
  EXPECT_LE(static_cast<double>(t.memory_bytes()) / pts.size(), 40.0);
}

}  // namespace

// ---- the Morton sort (rayscan/octree/morton_sort.hpp) against std::sort of the same keys ------------

namespace {
// Codes of n points: uniform 63-bit codes, or clustered (few distinct high bits, many duplicates).
std::vector<std::uint64_t> morton_test_codes(std::size_t n, bool clustered, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint64_t> c(n);
  for (auto& v : c) {
    const std::uint64_t r = rng() >> 1;  // < 2^63
    v = clustered ? (std::uint64_t{5} << 58) | (r % 97) << 20 | (r % 3) : r;
  }
  return c;
}

// sort_morton_keys over `codes` equals std::sort of the keys {codes[i], i} (the oracle).
void expect_sorted_like_std_sort(const std::vector<std::uint64_t>& codes) {
  const std::size_t n = codes.size();
  std::vector<MortonKey> expect(n);
  for (std::size_t i = 0; i < n; ++i) expect[i] = {codes[i], static_cast<std::uint32_t>(i)};
  std::sort(expect.begin(), expect.end());
  std::vector<MortonKey> got(n);
  sort_morton_keys(n, [&](std::size_t i) { return codes[i]; }, got.data());
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(got[i].code, expect[i].code) << "at " << i;
    ASSERT_EQ(got[i].idx, expect[i].idx) << "at " << i;
  }
}
}  // namespace

// The kernel's view of the mapping that holds address p: its /proc/self/smaps "THPeligible" flag
// (1 when the range may take transparent huge pages: MADV_HUGEPAGE under THP mode "madvise"),
// or -1 when no mapping or no flag is found.
static int thp_eligible(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.rfind("THPeligible:", 0) == 0) return std::stoi(line.substr(12));
  }
  return -1;
}

TEST(DefaultInitVector, LargeArraysAreHugePageAlignedAndAdvised) {
  using rayscan::DefaultInitAllocator;
  using rayscan::DefaultInitVector;
  constexpr std::size_t kBig = DefaultInitAllocator<double>::kHugeBytes / sizeof(double) + 3;  // just above
  DefaultInitVector<double> big(kBig);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % DefaultInitAllocator<double>::kHugePage, 0u);
  for (std::size_t i = 0; i < kBig; ++i) big[i] = static_cast<double>(i);
  // The advice reached the kernel (unless THP is off on this machine: then nothing to check).
  std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string m((std::istreambuf_iterator<char>(mode)), std::istreambuf_iterator<char>());
  if (m.find("[never]") == std::string::npos && !m.empty()) {
    EXPECT_EQ(thp_eligible(big.data()), 1) << "THP mode: " << m;
  }
  // Below the threshold: std::allocator's memory (not advised, not necessarily aligned); growing
  // across the threshold and shrinking back keep the elements (allocate / deallocate pair up).
  DefaultInitVector<double> small(1000);
  for (std::size_t i = 0; i < small.size(); ++i) small[i] = static_cast<double>(3 * i);
  small.resize(kBig);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(small.data()) % DefaultInitAllocator<double>::kHugePage, 0u);
  small.resize(1000);
  small.shrink_to_fit();
  for (std::size_t i = 0; i < small.size(); ++i) ASSERT_EQ(small[i], static_cast<double>(3 * i));
  EXPECT_EQ(big[kBig - 1], static_cast<double>(kBig - 1));
  EXPECT_THROW((void)DefaultInitAllocator<double>().allocate(std::numeric_limits<std::size_t>::max() / 4),
               std::bad_array_new_length);
}

TEST(MortonSort, EqualsStdSortOfTheKeys) {
  for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{7}, std::size_t{100}, std::size_t{5000},
                        std::size_t{300000}})
    for (bool clustered : {false, true}) {
      SCOPED_TRACE("n " + std::to_string(n) + " clustered " + std::to_string(clustered));
      expect_sorted_like_std_sort(morton_test_codes(n, clustered, 17 + n));
      if (::testing::Test::HasFatalFailure()) return;
    }
}

TEST(MortonSort, BucketsOfTiedCodesKeepIndexOrder) {
  // 300,000 keys in 2,048 buckets of ~146 (the 8-bit counting pass and small sorts of
  // sort_morton_buckets), each bucket holding few distinct codes: all in one sub-bucket of the
  // counting pass (b < 8 sets only bits below its top 8) or spread over up to 256 sub-buckets of
  // ~1-18 keys (insertion sort and std::sort). Ties must come out in index order.
  for (std::uint64_t sub : {std::uint64_t{8}, std::uint64_t{256}}) {
    std::mt19937_64 rng(5 + sub);
    const std::size_t n = 300000;
    std::vector<std::uint64_t> codes(n);
    for (auto& c : codes) c = (rng() % 2048) << 52 | (rng() % sub) << (sub == 8 ? 20 : 44) | (rng() % 2);
    SCOPED_TRACE("sub " + std::to_string(sub));
    expect_sorted_like_std_sort(codes);
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(MortonSort, LowBitsRadixSortIsStable) {
  // 30-bit codes (a COPC node's local tree) with many ties: ties must keep their input order.
  std::mt19937_64 rng(3);
  std::vector<MortonKey> keys(20000), tmp(keys.size());
  for (std::uint32_t i = 0; i < keys.size(); ++i) keys[i] = {(rng() % 500) << 12 | (rng() % 2), i};
  std::vector<MortonKey> expect = keys;
  std::stable_sort(expect.begin(), expect.end(), [](const MortonKey& a, const MortonKey& b) { return a.code < b.code; });
  radix_sort_low_bits(keys.data(), keys.size(), tmp.data(), 30);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    ASSERT_EQ(keys[i].code, expect[i].code) << i;
    ASSERT_EQ(keys[i].idx, expect[i].idx) << i;
  }
}
