// Box range, kNN, radius and k+r point queries against brute force on every index.
#include "test_util.hpp"

#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

using namespace rayscan;
using namespace rayscan::test;

namespace {

std::vector<Neighbor> oracle_knn(std::span<const Vec3> pts, const Vec3& q, std::size_t k, double r) {
  std::vector<std::pair<double, PointIndex>> all;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3 v = pts[i] - q;
    const double d2 = glm::dot(v, v);
    if (d2 <= r * r) all.emplace_back(d2, static_cast<PointIndex>(i));
  }
  std::sort(all.begin(), all.end());
  if (k < all.size()) all.resize(k);
  std::vector<Neighbor> out;
  for (auto& [d2, i] : all) out.push_back({i, std::sqrt(d2)});
  return out;
}

TEST(PointQuery, MatchBruteForceOnEveryIndex) {
  for (Dist d : {Dist::uniform, Dist::clustered, Dist::identical, Dist::grid, Dist::utm_mm})
    for (std::size_t n : {0u, 1u, 2u, 1000u, 30000u}) {
      const auto pts = make_points(n, d, 21);
      AABB box;
      for (const Vec3& p : pts) box.expand(p);
      if (box.empty()) box = AABB{Vec3(0.0), Vec3(1.0)};
      const double s = std::max(box.max_extent(), 1e-3);
      std::mt19937_64 rng(5 + n);
      std::uniform_real_distribution<double> u(0, 1);
      for (const IndexOptions& opt : all_index_options()) {
        const AnyIndex index = make_index(pts, opt);
        const std::string ctx = std::string(name(d)) + " n=" + std::to_string(n) + " " + label(opt);
        for (int i = 0; i < 15; ++i) {
          const Vec3 q = (i % 3 == 0 && n > 0) ? pts[(i * 7919) % n]
                                               : box.lo + Vec3(u(rng), u(rng), u(rng)) * (box.hi - box.lo);
          // Box range with inclusive bounds: a box spanned by two random points (paper 5.1).
          AABB qb;
          qb.expand(box.lo + Vec3(u(rng), u(rng), u(rng)) * (box.hi - box.lo));
          qb.expand(n > 0 ? pts[(i * 31) % n] : box.lo);  // a corner exactly on a data point
          std::vector<PointIndex> want_box;
          for (std::size_t j = 0; j < n; ++j)
            if (qb.contains(pts[j])) want_box.push_back(static_cast<PointIndex>(j));
          std::vector<PointIndex> got_box;
          std::visit([&](const auto& idx) { box_query(idx, qb, got_box); }, index);
          std::sort(got_box.begin(), got_box.end());
          ASSERT_EQ(got_box, want_box) << ctx;
          for (const auto& kr : {std::pair<std::size_t, double>{8, kInf}, {kAllPoints, 0.05 * s},
                                 {5, 0.03 * s}, {n + 3, kInf}, {1, 0.0}}) {
            const std::size_t k = kr.first;  // (no structured binding: a lambda below captures them)
            const double r = kr.second;
            std::vector<Neighbor> got;
            std::visit([&](const auto& idx) { knn_query(idx, q, k, r, got); }, index);
            const auto want = oracle_knn(pts, q, k, r);
            ASSERT_EQ(got.size(), want.size()) << ctx << " k=" << k << " r=" << r;
            for (std::size_t j = 0; j < got.size(); ++j) {
              ASSERT_EQ(got[j].index, want[j].index) << ctx << " rank " << j;
              ASSERT_EQ(got[j].distance, want[j].distance) << ctx << " rank " << j;
            }
          }
        }
      }
    }
}

TEST(PointQuery, KnnEntryPointSearchEqualsTheRootSearchAndTheOracle) {
  // knn_query with the entry-point search (the subtree of q's grid cell first, then the cells the
  // ball of the k-th distance reaches, or the node of the smallest cell holding it) against the
  // search from the root (set_entry_point_search(false)) bit for bit and the brute-force oracle:
  // uniform, clustered (empty cells: their nodes lie above the grid's depth), lattice and UTM
  // clouds, adaptive and fixed octrees of a few depths; queries at random, on data points, exactly
  // on the grid's cell faces, edges and corners, and outside the root cell; k = 1, 8, 9 (k <= 8
  // in vector lanes), 40 (a heap) and more than the points, radius unlimited or small.
  const EntrySearchGuard entry_guard;
  std::size_t grids = 0, queries = 0;
  for (const Dist d : {Dist::uniform, Dist::clustered, Dist::grid, Dist::utm_mm})
    for (const auto& [layout, cap] : {std::pair{OctreeLayout::adaptive, 64u}, {OctreeLayout::adaptive, 8u},
                                      {OctreeLayout::fixed, 64u}}) {
      const auto pts = make_points(20000, d, 61);
      OctreeConfig cfg = OctreeConfig::for_layout(layout);
      cfg.capacity = cap;
      cfg.depth = 4;
      const Octree tree = Octree::build_bulk(pts, cfg);
      const auto g = tree.entry_grid();
      const std::string ctx0 = std::string(name(d)) + " cap " + std::to_string(cap) +
                               (layout == OctreeLayout::fixed ? " fixed" : " adaptive");
      if (d == Dist::uniform) {
        ASSERT_GE(g.depth, 2u) << ctx0 << ": a tree this deep has entry grids";
      }
      grids += g.cells != nullptr;
      const AABB cell = tree.root_cell();
      const double s = cell.max_extent();
      const double step = g.cells ? g.side / double(1u << g.depth) : s / 8.0;
      std::mt19937_64 rng(67);
      std::uniform_real_distribution<double> u(0, 1);
      std::uniform_int_distribution<int> lattice(0, 1 << std::max(g.depth, 3u));
      for (int i = 0; i < 60; ++i) {
        Vec3 q;
        switch (i % 4) {
          case 0: q = pts[(i * 7919) % pts.size()]; break;
          case 1: q = cell.lo + Vec3(u(rng), u(rng), u(rng)) * s; break;
          case 2:  // a grid cell's corner, or a point on one of its faces or edges
            for (int a = 0; a < 3; ++a)
              q[a] = cell.lo[a] + (a == i % 3 && i % 8 < 4 ? u(rng) * s : step * lattice(rng));
            break;
          default: q = cell.lo + Vec3(u(rng) * 1.4 - 0.2, u(rng), u(rng) * 1.4 - 0.2) * s; break;  // also outside
        }
        const auto all = oracle_knn(pts, q, pts.size(), kInf);  // (every point, nearest first)
        for (const auto& [k, r] : {std::pair<std::size_t, double>{1, kInf}, {8, kInf}, {9, kInf}, {40, kInf},
                                   {8, 0.02 * s}, {pts.size() + 1, 0.01 * s}}) {
          const std::string ctx = ctx0 + " query " + std::to_string(i) + " k=" + std::to_string(k) +
                                  " r=" + std::to_string(r);
          std::vector<Neighbor> on, off;
          set_entry_point_search(true);
          knn_query(tree, q, k, r, on);
          set_entry_point_search(false);
          knn_query(tree, q, k, r, off);
          std::vector<Neighbor> want;
          for (const Neighbor& nb : all)
            if (want.size() < k && glm::dot(pts[nb.index] - q, pts[nb.index] - q) <= r * r) want.push_back(nb);
          ASSERT_EQ(on.size(), want.size()) << ctx;
          ASSERT_EQ(off.size(), want.size()) << ctx;
          for (std::size_t j = 0; j < want.size(); ++j) {
            ASSERT_EQ(on[j].index, want[j].index) << ctx << " rank " << j;
            ASSERT_EQ(on[j].distance, want[j].distance) << ctx << " rank " << j;
            ASSERT_EQ(off[j].index, want[j].index) << ctx << " rank " << j;
          }
          ++queries;
        }
      }
    }
  EXPECT_GE(grids, 8u);
  EXPECT_EQ(queries, 4u * 3u * 60u * 6u);
}

TEST(PointQuery, KnnFromAQueryPointFarOutside) {
  // A query point 1e19-1e20 from the cloud: its squared distances (about 1e39) pass float's range,
  // so the float child bounds of the SIMD paths cannot prune by them; every point ties or nearly
  // ties, and the answer must still be brute force's (smallest squared distance, then index), on
  // every forced path (simd_*_properties), with and without the entry-point search.
  std::vector<Vec3> pts;
  for (int i = 0; i < 64; ++i) pts.emplace_back(i % 4, (i / 4) % 4, i / 16);
  OctreeConfig cfg;
  cfg.capacity = 1;
  const Octree tree = Octree::build_bulk(pts, cfg);
  const EntrySearchGuard entry_guard;
  for (const double m : {1e18, 2e19, 1e20, -3e19})
    for (const bool on : {true, false})
      for (const std::size_t k : {std::size_t{1}, std::size_t{5}}) {
        set_entry_point_search(on);
        const Vec3 q(m, 0.5 * m, m);
        std::vector<Neighbor> got;
        knn_query(tree, q, k, kInf, got);
        const auto want = oracle_knn(pts, q, k, kInf);
        ASSERT_EQ(got.size(), want.size()) << m;
        for (std::size_t j = 0; j < want.size(); ++j)
          EXPECT_EQ(got[j].index, want[j].index) << "q at " << m << ", search " << on << ", k " << k << ", rank " << j;
      }
}

TEST(PointQuery, InvalidArgumentsThrow) {
  const auto pts = make_points(10, Dist::uniform);
  const Octree t = Octree::build_bulk(pts);
  std::vector<Neighbor> out;
  EXPECT_THROW(knn_query(t, Vec3(0.0), 3, -1.0, out), std::invalid_argument);
  EXPECT_THROW(knn_query(t, Vec3(std::nan(""), 0, 0), 3, 1.0, out), std::invalid_argument);
  EXPECT_THROW((void)make_index(pts, IndexOptions{"rtree"}), std::invalid_argument);
}

}  // namespace

namespace {

[[noreturn]] void throw_bad_id(const void* context, std::size_t slot) {
  throw std::runtime_error(std::string(static_cast<const char*>(context)) + " slot " + std::to_string(slot));
}

}  // namespace

// IdView::append_to, box_query's bulk copy of a whole node's ids, against operator[] slot by slot
// on each kind of view: stored, implied (the identity) and checked (an id >= size() throws).
TEST(IdView, AppendToEqualsOperatorIndexOnEveryKindOfView) {
  const std::vector<PointIndex> stored{7, 3, 9, 0, 5, 1, 8, 2, 6, 4};
  const IdView plain{std::span<const PointIndex>(stored)};
  const IdView implied = IdView::identity(stored.size());
  const char* what = "ids";
  const IdView checked = IdView::checked(stored, throw_bad_id, what);
  for (const IdView& v : {plain, implied, checked})
    for (std::size_t b = 0; b <= v.size(); ++b)
      for (std::size_t e = b; e <= v.size(); ++e) {
        std::vector<PointIndex> got{42};  // appended after what is there
        v.append_to(got, b, e);
        std::vector<PointIndex> want{42};
        for (std::size_t s = b; s < e; ++s) want.push_back(v[s]);
        ASSERT_EQ(got, want) << b << ".." << e;
      }
  std::vector<PointIndex> bad = stored;
  bad[6] = 10;  // not below size()
  const IdView checked_bad = IdView::checked(bad, throw_bad_id, what);
  std::vector<PointIndex> out;
  checked_bad.append_to(out, 0, 6);
  EXPECT_EQ(out.size(), 6u);
  try {
    checked_bad.append_to(out, 2, 9);
    FAIL() << "an id >= size() was appended";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "ids slot 6");
  }
  // The plain view does not check: the same bytes are copied as they are.
  out.clear();
  IdView{std::span<const PointIndex>(bad)}.append_to(out, 5, 8);
  EXPECT_EQ(out, (std::vector<PointIndex>{1, 10, 2}));
}

// IdView::map_slots, box_query's mapping of a kernel's kept local slots to ids, against
// operator[] on each kind of view; a checked view throws on a bad id as operator[] does.
TEST(IdView, MapSlotsEqualsOperatorIndexOnEveryKindOfView) {
  const std::vector<PointIndex> stored{7, 3, 9, 0, 5, 1, 8, 2, 6, 4};
  const char* what = "ids";
  const IdView plain{std::span<const PointIndex>(stored)};
  const IdView checked = IdView::checked(stored, throw_bad_id, what);
  for (const IdView& v : {plain, IdView::identity(stored.size()), checked})
    for (std::size_t base = 0; base < v.size(); ++base) {
      std::vector<PointIndex> local;  // every other slot from base, descending (any order maps)
      for (std::size_t s = v.size(); s-- > base;)
        if ((s - base) % 2 == 0) local.push_back(static_cast<PointIndex>(s - base));
      std::vector<PointIndex> want;
      for (PointIndex j : local) want.push_back(v[base + j]);
      v.map_slots(local.data(), local.size(), base);
      ASSERT_EQ(local, want) << "base " << base;
    }
  std::vector<PointIndex> bad = stored;
  bad[6] = 10;  // not below size()
  std::vector<PointIndex> local{0, 1, 2};
  try {
    IdView::checked(bad, throw_bad_id, what).map_slots(local.data(), local.size(), 4);
    FAIL() << "an id >= size() was mapped";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "ids slot 6");
  }
}
