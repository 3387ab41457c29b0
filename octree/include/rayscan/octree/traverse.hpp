// The tree walks of the queries, written once over any SpatialIndex: a node-test policy says
// whether to enter a node, a leaf callback does the per-node point work and may stop the walk. In
// the style of bvh v2's traversal (Meister, `bvh::v2::Bvh::traverse_top_down`: an inner-node test
// and a leaf function that returns true to stop) and nanoflann's result sets (the per-point work as
// a policy of one search loop); the walk itself is the paper's depth-first descent of a bounding
// volume hierarchy (Teuscher et al., "Ray Queries On Raw Point Clouds", section 3: "It works on top
// of any bounding volume indexing structure").
//
// The best-first walks of the kNN query (knn_query_with) and the ray query (RayTraversal,
// first_hit_packet) keep loops of their own: they expand the nearest child without a push,
// write their stack entries with SIMD sorting kernels and re-test an entry's bound when it is
// popped; they share the node tests and point kernels (the library's private
// detail/simd_kernels.hpp) with the walks here.
#pragma once

#include "rayscan/octree/spatial_index.hpp"

#include <algorithm>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

namespace rayscan {

/// A node test's answer: the node-test policy of depth_first returns one per node.
enum class Enter : std::uint8_t {
  no,     ///< skip the node and its whole subtree
  yes,    ///< visit the node (its own points go to the leaf callback) and test its children
  whole,  ///< every point of the subtree qualifies: the subtree is visited without further tests
          ///< (box_query's containment shortcut), in storage order
};

/// What depth_first hands its leaf callback for each visited node.
template <class Node>
struct NodeVisit {
  Node node;        ///< the visited node (for a whole subtree taken at once, its root)
  SlotRange slots;  ///< the storage slots to work on: node_points(node), or for a subtree the node
                    ///< test called whole, on an index with subtree_points(), the subtree's slots
  bool whole;       ///< the node test said Enter::whole for this node or an ancestor
};

namespace detail {

/// An entry of depth_first's stack: a node that passed its test, and the test's answer.
template <class Node>
struct WalkEntry {
  Node node;
  Enter how;
};

/// The calling thread's stack of depth_first, one per node type. A walk uses the entries above
/// the size it found and leaves the stack at that size, so a walk started from a leaf callback or
/// a node test (a nested walk) shares it; no allocation once warm.
template <class Node>
std::vector<WalkEntry<Node>>& walk_stack() {
  thread_local std::vector<WalkEntry<Node>> s;
  return s;
}

/// Restores walk_stack's size on every exit of a walk (a stop or an exception).
template <class Node>
struct WalkStackGuard {
  std::vector<WalkEntry<Node>>& stack;
  std::size_t base;
  ~WalkStackGuard() { stack.resize(base); }
};

/// An index that stores each subtree's points in one contiguous slot range (Octree, KdTree).
template <class I>
concept SubtreePoints = requires(const I& idx, typename I::Node n) {
  { idx.subtree_points(n) } -> std::convertible_to<SlotRange>;
};

/// A node-test policy that can also test all children of a node at once (a SIMD child bound):
/// `children(parent, nc, mask)` sets bit i of mask to enter child i with Enter::yes and returns
/// true, or returns false to have each child tested alone.
template <class T, class Node>
concept ChildBatchTest = requires(T& t, Node n, unsigned nc, std::uint32_t& mask) {
  { t.children(n, nc, mask) } -> std::convertible_to<bool>;
};

/// Calls the leaf callback; true when it asks to stop (a callback returning void never does).
template <class Leaf, class Node>
__attribute__((always_inline)) inline bool visit_leaf(Leaf& leaf, Node n, SlotRange slots, bool whole) {
  if constexpr (std::is_void_v<std::invoke_result_t<Leaf&, const NodeVisit<Node>&>>) {
    leaf(NodeVisit<Node>{n, slots, whole});
    return false;
  } else {
    return static_cast<bool>(leaf(NodeVisit<Node>{n, slots, whole}));
  }
}

}  // namespace detail

/// Depth-first walk of `index` from its root. Policies:
///  - `test(node) -> Enter`: the node test, called once for the root and for each child of an
///    entered node before it is pushed (a pure function of the node: the walks here test boxes
///    against the query's shape in world coordinates). A test object may also have the member
///    `bool children(Node parent, unsigned nc, std::uint32_t& mask)` (detail::ChildBatchTest) that
///    tests the nc <= 32 children of an entered node at once.
///  - `leaf(const NodeVisit<Node>&)`: the per-node point work, called for every entered node
///    (also those without points of their own), returning void or bool (true: stop the walk, as
///    any hit and line of sight do; bvh v2's convention).
/// Order: a node's own points before its children's; the children a test enters are pushed in
/// index order on a stack, so child nc - 1 is visited first (box_query's output order is this
/// visiting order). Under an Enter::whole node the subtree is visited in storage order (own
/// points, then children 0, 1, ... recursively), or handed over at once as its subtree_points()
/// range where the index has it (Octree, KdTree).
/// Returns true when the leaf callback stopped the walk, false when it ran out (or the index is
/// empty). Allocates nothing once warm (the stack is per thread and node type, shared by nested
/// walks); exceptions from the policies propagate, the stack is restored.
template <SpatialIndex I, class NodeTest, class Leaf>
bool depth_first(const I& index, NodeTest&& test, Leaf&& leaf) {
  using Node = typename I::Node;
  if (index.empty()) return false;
  const Enter root_how = test(index.root());
  if (root_how == Enter::no) return false;
  auto& stack = detail::walk_stack<Node>();
  const detail::WalkStackGuard<Node> guard{stack, stack.size()};
  stack.push_back({index.root(), root_how});
  while (stack.size() > guard.base) {
    const detail::WalkEntry<Node> e = stack.back();
    stack.pop_back();
    if (e.how == Enter::whole) {
      if constexpr (detail::SubtreePoints<I>) {
        if (detail::visit_leaf(leaf, e.node, index.subtree_points(e.node), true)) return true;
      } else {
        if (detail::visit_leaf(leaf, e.node, index.node_points(e.node), true)) return true;
        for (unsigned i = index.child_count(e.node); i-- > 0;) stack.push_back({index.child(e.node, i), Enter::whole});
      }
      continue;
    }
    if (detail::visit_leaf(leaf, e.node, index.node_points(e.node), false)) return true;
    const unsigned nc = index.child_count(e.node);
    if (nc == 0) continue;
    if constexpr (detail::ChildBatchTest<std::remove_reference_t<NodeTest>, Node>) {
      std::uint32_t mask = 0;
      if (nc <= 32 && test.children(e.node, nc, mask)) {
        for (unsigned i = 0; i < nc; ++i)
          if ((mask >> i) & 1u) stack.push_back({index.child(e.node, i), Enter::yes});
        continue;
      }
    }
    for (unsigned i = 0; i < nc; ++i) {
      const Node c = index.child(e.node, i);
      const Enter how = test(c);
      if (how != Enter::no) stack.push_back({c, how});
    }
  }
  return false;
}

/// Every node of `index`, each after all of its children (a post-order: the reverse of
/// depth_first's visiting order with every node entered), for bottom-up reductions over the tree
/// (surfel_node_radii, surfel_node_boxes). Empty for an empty index.
template <SpatialIndex I>
[[nodiscard]] std::vector<typename I::Node> nodes_children_first(const I& index) {
  std::vector<typename I::Node> order;
  depth_first(index, [](typename I::Node) { return Enter::yes; },
              [&](const NodeVisit<typename I::Node>& v) { order.push_back(v.node); });
  std::reverse(order.begin(), order.end());
  return order;
}

}  // namespace rayscan
