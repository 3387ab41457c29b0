// The traversal template (traverse.hpp) against brute force: custom node-test / leaf policies on
// every index, early stop, nested walks, exceptions, the children-first order and whole subtrees.
#include "test_util.hpp"

#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/traverse.hpp"

#include <gtest/gtest.h>

#include <numeric>
#include <stdexcept>

using namespace rayscan;
using namespace rayscan::test;

namespace {

/// An index that forwards everything to `base` except subtree_points(), so that depth_first walks
/// an Enter::whole subtree node by node.
template <class I>
struct NoSubtreePoints {
  const I& base;
  using Node = typename I::Node;
  [[nodiscard]] bool empty() const { return base.empty(); }
  [[nodiscard]] Node root() const { return base.root(); }
  [[nodiscard]] AABB node_bounds(Node n) const { return base.node_bounds(n); }
  [[nodiscard]] SlotRange node_points(Node n) const { return base.node_points(n); }
  [[nodiscard]] unsigned child_count(Node n) const { return base.child_count(n); }
  [[nodiscard]] Node child(Node n, unsigned i) const { return base.child(n, i); }
  [[nodiscard]] auto positions() const { return base.positions(); }
  [[nodiscard]] auto ids() const { return base.ids(); }
};
static_assert(SpatialIndex<NoSubtreePoints<Octree>>);
static_assert(!detail::SubtreePoints<NoSubtreePoints<Octree>>);

std::size_t oracle_in_sphere(std::span<const Vec3> pts, const Vec3& c, double r) {
  std::size_t n = 0;
  for (const Vec3& p : pts) n += glm::dot(p - c, p - c) <= r * r;
  return n;
}

/// Counts the points within r of c with depth_first: the node test enters a box within r (whole
/// when its farthest corner is within r), the leaf counts (and records the slots it saw).
template <class I>
std::size_t walk_in_sphere(const I& index, const Vec3& c, double r, std::vector<std::uint32_t>& seen) {
  using Node = typename I::Node;
  const auto pos = index.positions();
  std::size_t n = 0;
  depth_first(
      index,
      [&](Node node) {
        const AABB b = index.node_bounds(node);
        if (distance2_point_box(c, b) > r * r) return Enter::no;
        Vec3 far;
        for (int a = 0; a < 3; ++a) far[a] = std::max(std::abs(c[a] - b.lo[a]), std::abs(c[a] - b.hi[a]));
        return glm::dot(far, far) <= r * r ? Enter::whole : Enter::yes;
      },
      [&](const NodeVisit<Node>& v) {
        for (std::uint32_t s = v.slots.begin; s < v.slots.end; ++s) {
          seen.push_back(s);
          const bool in = glm::dot(pos[s] - c, pos[s] - c) <= r * r;
          if (v.whole) {
            EXPECT_TRUE(in) << "slot " << s << " of a whole subtree lies outside";
          }
          n += in;
        }
      });
  return n;
}

TEST(Traverse, SphereCountMatchesBruteForceOnEveryIndex) {
  for (Dist d : {Dist::uniform, Dist::clustered, Dist::identical, Dist::grid, Dist::utm_mm})
    for (std::size_t n : {0u, 1u, 1000u, 20000u}) {
      const auto pts = make_points(n, d, 3);
      AABB box;
      for (const Vec3& p : pts) box.expand(p);
      if (box.empty()) box = AABB{Vec3(0.0), Vec3(1.0)};
      std::mt19937_64 rng(11 + n);
      std::uniform_real_distribution<double> u(0, 1);
      for (const IndexOptions& opt : all_index_options()) {
        const AnyIndex index = make_index(pts, opt);
        for (int i = 0; i < 10; ++i) {
          const Vec3 c = box.lo + Vec3(u(rng), u(rng), u(rng)) * (box.hi - box.lo);
          const double r = (0.02 + 0.2 * u(rng)) * std::max(box.max_extent(), 1e-3);
          std::vector<std::uint32_t> seen;
          const std::size_t got = std::visit([&](const auto& idx) { return walk_in_sphere(idx, c, r, seen); }, index);
          EXPECT_EQ(got, oracle_in_sphere(pts, c, r)) << name(d) << " n=" << n << " " << label(opt);
          std::sort(seen.begin(), seen.end());
          EXPECT_TRUE(std::adjacent_find(seen.begin(), seen.end()) == seen.end()) << "a slot visited twice";
        }
      }
    }
}

TEST(Traverse, EveryNodeVisitedOnceWithoutPruning) {
  const auto pts = make_points(5000, Dist::clustered, 4);
  for (const IndexOptions& opt : all_index_options()) {
    const AnyIndex index = make_index(pts, opt);
    std::visit(
        [&](const auto& idx) {
          using Node = typename std::decay_t<decltype(idx)>::Node;
          std::vector<std::uint32_t> slots;
          std::size_t nodes = 0;
          const bool stopped = depth_first(idx, [](Node) { return Enter::yes; }, [&](const NodeVisit<Node>& v) {
            ++nodes;
            EXPECT_FALSE(v.whole);
            for (std::uint32_t s = v.slots.begin; s < v.slots.end; ++s) slots.push_back(s);
          });
          EXPECT_FALSE(stopped);
          std::sort(slots.begin(), slots.end());
          std::vector<std::uint32_t> all(pts.size());
          std::iota(all.begin(), all.end(), 0u);
          EXPECT_EQ(slots, all) << label(opt);
          // nodes_children_first: the same nodes, each after all of its children.
          const auto order = nodes_children_first(idx);
          EXPECT_EQ(order.size(), nodes) << label(opt);
          std::vector<Node> done;
          for (const Node n : order) {
            for (unsigned i = 0; i < idx.child_count(n); ++i)
              EXPECT_NE(std::find(done.begin(), done.end(), idx.child(n, i)), done.end()) << label(opt);
            done.push_back(n);
          }
          EXPECT_EQ(order.back(), idx.root());
        },
        index);
  }
}

TEST(Traverse, LeafStopsTheWalk) {
  const auto pts = make_points(20000, Dist::uniform, 5);
  const Octree t = Octree::build_bulk(pts);
  const auto pos = t.positions();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 50; ++i) {
    const Vec3 c(u(rng), u(rng), u(rng));
    const double r = 0.002 + 0.02 * u(rng);  // small: some spheres are empty
    bool after_stop = false, stopped_once = false;
    const bool any = depth_first(
        t,
        [&](Octree::Node n) { return distance2_point_box(c, t.node_bounds(n)) <= r * r ? Enter::yes : Enter::no; },
        [&](const NodeVisit<Octree::Node>& v) {
          after_stop = after_stop || stopped_once;
          for (std::uint32_t s = v.slots.begin; s < v.slots.end; ++s)
            if (glm::dot(pos[s] - c, pos[s] - c) <= r * r) return stopped_once = true;
          return false;
        });
    EXPECT_EQ(any, oracle_in_sphere(pts, c, r) > 0);
    EXPECT_FALSE(after_stop) << "the leaf was called after it stopped the walk";
    EXPECT_TRUE(detail::walk_stack<Octree::Node>().empty());
  }
}

TEST(Traverse, NestedWalksAndExceptionsKeepTheStack) {
  const auto pts = make_points(3000, Dist::clustered, 6);
  const Octree t = Octree::build_bulk(pts);
  using Node = Octree::Node;
  const auto all = [](Node) { return Enter::yes; };
  std::size_t nodes = 0;
  depth_first(t, all, [&](const NodeVisit<Node>&) { ++nodes; });
  // A walk from every leaf callback of another: each inner walk sees the whole tree.
  std::size_t outer = 0;
  depth_first(t, all, [&](const NodeVisit<Node>&) {
    ++outer;
    std::size_t inner = 0;
    depth_first(t, all, [&](const NodeVisit<Node>&) { ++inner; });
    EXPECT_EQ(inner, nodes);
    return outer == 20;  // stop after 20
  });
  EXPECT_EQ(outer, std::min<std::size_t>(20, nodes));
  EXPECT_TRUE(detail::walk_stack<Node>().empty());
  std::size_t calls = 0;
  EXPECT_THROW(depth_first(t, all,
                           [&](const NodeVisit<Node>&) {
                             if (++calls == 3) throw std::runtime_error("leaf");
                           }),
               std::runtime_error);
  EXPECT_TRUE(detail::walk_stack<Node>().empty());
}

/// A node test that also tests all children at once (detail::ChildBatchTest), counting its calls.
struct BatchSphereTest {
  const Octree& t;
  Vec3 c;
  double r;
  int batches = 0;
  Enter operator()(Octree::Node n) const {
    return distance2_point_box(c, t.node_bounds(n)) <= r * r ? Enter::yes : Enter::no;
  }
  bool children(Octree::Node n, unsigned nc, std::uint32_t& mask) {
    ++batches;
    for (unsigned i = 0; i < nc; ++i) mask |= std::uint32_t{(*this)(t.child(n, i)) == Enter::yes} << i;
    return true;
  }
};
static_assert(detail::ChildBatchTest<BatchSphereTest, Octree::Node>);

TEST(Traverse, ChildBatchTestVisitsTheSameNodes) {
  const auto pts = make_points(20000, Dist::clustered, 8);
  const Octree t = Octree::build_bulk(pts);
  const Vec3 c = pts[123];
  const double r = 0.05;
  std::vector<Octree::Node> a, b;
  BatchSphereTest batch{t, c, r};
  depth_first(t, batch, [&](const NodeVisit<Octree::Node>& v) { a.push_back(v.node); });
  const auto single = [&](Octree::Node n) { return batch(n); };
  depth_first(t, single, [&](const NodeVisit<Octree::Node>& v) { b.push_back(v.node); });
  EXPECT_GT(batch.batches, 0);
  EXPECT_EQ(a, b);
}

TEST(Traverse, WholeSubtreesInStorageOrderWithoutSubtreePoints) {
  const auto pts = make_points(20000, Dist::uniform, 9);
  for (const IndexOptions& opt : all_index_options()) {
    const AnyIndex index = make_index(pts, opt);
    std::visit(
        [&](const auto& idx) {
          using I = std::decay_t<decltype(idx)>;
          if constexpr (detail::SubtreePoints<I>) {
            const NoSubtreePoints<I> plain{idx};
            // The root whole: every slot in ascending storage order, node by node.
            std::vector<std::uint32_t> slots;
            depth_first(plain, [](typename I::Node) { return Enter::whole; },
                        [&](const NodeVisit<typename I::Node>& v) {
                          EXPECT_TRUE(v.whole);
                          for (std::uint32_t s = v.slots.begin; s < v.slots.end; ++s) slots.push_back(s);
                        });
            std::vector<std::uint32_t> all(pts.size());
            std::iota(all.begin(), all.end(), 0u);
            EXPECT_EQ(slots, all) << label(opt);
            // box_query's output order (its visiting order) is the same with and without
            // subtree_points.
            std::mt19937_64 rng(3);
            std::uniform_real_distribution<double> u(0, 1);
            for (int i = 0; i < 20; ++i) {
              AABB qb;
              qb.expand(Vec3(u(rng), u(rng), u(rng)));
              qb.expand(Vec3(u(rng), u(rng), u(rng)));
              std::vector<PointIndex> with, without;
              box_query(idx, qb, with);
              box_query(plain, qb, without);
              EXPECT_EQ(with, without) << label(opt);
            }
          }
        },
        index);
  }
}

}  // namespace
