// Point queries over any SpatialIndex: box range, kNN, radius and k + radius (paper section 5.1,
// Table 1 measures the first two). Written once against the concept, like the ray query.
#pragma once

#include "rayscan/ray_query.hpp"
#include "rayscan/spatial_index.hpp"

#include <algorithm>
#include <vector>

namespace rayscan {

/// One neighbour of a point query.
struct Neighbor {
  PointIndex index;  ///< original point index
  double distance;   ///< Euclidean distance to the query point (not squared; world units)
};

namespace detail {
template <class I, class F>
void for_subtree(const I& index, typename I::Node n, F&& f) {
  if constexpr (requires { index.subtree_points(n); }) {
    const SlotRange sr = index.subtree_points(n);
    for (std::uint32_t s = sr.begin; s < sr.end; ++s) f(s);
  } else {
    const SlotRange sr = index.node_points(n);
    for (std::uint32_t s = sr.begin; s < sr.end; ++s) f(s);
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i) for_subtree(index, index.child(n, i), f);
  }
}
}  // namespace detail

/// Box range query: the original indices of all points p with box.lo <= p <= box.hi (inclusive on
/// every side), in the index's storage order (deterministic; sort the result if ascending indices
/// are needed: the peers Boost.Geometry rtree and nanoflann also return tree order). Nodes inside
/// the box are taken whole (contiguous slots) without per-point tests. An empty box (lo > hi on an
/// axis) returns nothing.
template <SpatialIndex I>
void box_query(const I& index, const AABB& box, std::vector<PointIndex>& out) {
  out.clear();
  if (index.empty() || box.empty()) return;
  const std::span<const Vec3> pos = index.positions();
  const std::span<const PointIndex> ids = index.ids();
  thread_local std::vector<typename I::Node> stack;
  stack.clear();
  stack.push_back(index.root());
  while (!stack.empty()) {
    const auto n = stack.back();
    stack.pop_back();
    const AABB nb = index.node_bounds(n);
    if (!box.overlaps(nb)) continue;
    if (box.contains(nb.lo) && box.contains(nb.hi)) {
      detail::for_subtree(index, n, [&](std::uint32_t s) { out.push_back(ids[s]); });
      continue;
    }
    const SlotRange sr = index.node_points(n);
    for (std::uint32_t s = sr.begin; s < sr.end; ++s)
      if (box.contains(pos[s])) out.push_back(ids[s]);
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i) stack.push_back(index.child(n, i));
  }
}

/// kNN with optional radius: the at most k points nearest to q with distance <= radius (inclusive),
/// sorted by (squared distance, index). k = kAllPoints means no k limit (a pure radius query);
/// radius = kInf means no radius. Ordering and pruning use squared distances; Neighbor::distance is
/// their square root. Best-first search over node MINDIST (Hjaltason & Samet 1999).
/// Throws std::invalid_argument for a NaN/negative radius or a non-finite q.
template <SpatialIndex I>
void knn_query(const I& index, const Vec3& q, std::size_t k, double radius,
               std::vector<Neighbor>& out) {
  if (std::isnan(radius) || radius < 0.0)
    throw std::invalid_argument("knn query: radius must be >= 0");
  if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
    throw std::invalid_argument("knn query: query point must be finite");
  out.clear();
  if (index.empty() || k == 0) return;
  using Node = typename I::Node;
  const bool bounded = k != kAllPoints;
  const double r2 = radius * radius;
  const std::span<const Vec3> pos = index.positions();
  const std::span<const PointIndex> ids = index.ids();
  auto& scratch = detail::ray_scratch<Node>();  // same shapes: (bound, node) and candidates
  auto& nodes = scratch.nodes;
  auto& cands = scratch.cands;
  nodes.clear();
  cands.clear();
  double worst = kInf;
  auto greater = [](const detail::NodeEntry<Node>& a, const detail::NodeEntry<Node>& b) {
    return a.lb > b.lb;
  };
  // A node is kept when its squared MINDIST is within the (relative-tolerance) bound.
  auto within = [](double lb, double bound) { return lb <= bound * (1.0 + 1e-12); };
  nodes.push_back({distance2_point_box(q, index.node_bounds(index.root())), index.root()});
  while (!nodes.empty()) {
    detail::NodeEntry<Node> e;
    if (bounded) {
      std::pop_heap(nodes.begin(), nodes.end(), greater);
      e = nodes.back();
      nodes.pop_back();
      if (!within(e.lb, worst)) break;
    } else {
      e = nodes.back();
      nodes.pop_back();
    }
    if (!within(e.lb, r2)) continue;
    const SlotRange sr = index.node_points(e.node);
    for (std::uint32_t s = sr.begin; s < sr.end; ++s) {
      const Vec3 v = pos[s] - q;
      const double d2 = glm::dot(v, v);
      if (d2 > r2 || d2 > worst) continue;
      const detail::Candidate c{d2, ids[s], 0.0, d2};
      if (!bounded) {
        cands.push_back(c);
      } else if (cands.size() < k) {
        cands.push_back(c);
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
        if (cands.size() == k) worst = cands.front().key;
      } else if (detail::cand_less(c, cands.front())) {
        std::pop_heap(cands.begin(), cands.end(), detail::cand_less);
        cands.back() = c;
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
        worst = cands.front().key;
      }
    }
    for (unsigned i = 0, nc = index.child_count(e.node); i < nc; ++i) {
      const Node ch = index.child(e.node, i);
      const double lb = distance2_point_box(q, index.node_bounds(ch));
      if (!within(lb, r2) || !within(lb, worst)) continue;
      nodes.push_back({lb, ch});
      if (bounded) std::push_heap(nodes.begin(), nodes.end(), greater);
    }
  }
  std::sort(cands.begin(), cands.end(), detail::cand_less);
  out.reserve(cands.size());
  for (const detail::Candidate& c : cands) out.push_back({c.id, std::sqrt(c.d2)});
}

/// kNN: the k nearest points (see knn_query above for order and ties).
template <SpatialIndex I>
[[nodiscard]] std::vector<Neighbor> knn(const I& index, const Vec3& q, std::size_t k) {
  std::vector<Neighbor> out;
  knn_query(index, q, k, kInf, out);
  return out;
}

/// Radius query: every point within distance r of q (inclusive), sorted by (distance, index).
template <SpatialIndex I>
[[nodiscard]] std::vector<Neighbor> radius_search(const I& index, const Vec3& q, double r) {
  std::vector<Neighbor> out;
  knn_query(index, q, kAllPoints, r, out);
  return out;
}

}  // namespace rayscan
