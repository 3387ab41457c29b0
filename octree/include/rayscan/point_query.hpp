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
/// SIMD (issue 12, the same policies as ray_query): on the active simd_path() an index with
/// detail::FloatChildBoxes bounds all children's MINDIST at once in float (lower bounds, rounded
/// down), and each node's points pass a SIMD distance filter with a widened bound before the exact
/// double test, so the answers are bit-identical on every path.
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
  const AABB root_box = index.node_bounds(index.root());
  nodes.push_back({distance2_point_box(q, root_box), index.root()});
  // SIMD policies (simd.hpp): see ray_query for the margins.
  const simd::Kernels& kern = simd::active_kernels();
  const double vmax = glm::length(q - root_box.center()) + 0.5 * glm::length(root_box.hi - root_box.lo);
  const double slack_d2 = 1e-12 * vmax * vmax + 1e-300;
  simd::PointFilterD pf{{q.x, q.y, q.z}, {0.0, 0.0, 0.0}, 0.0, -kInf, kInf};  // d = 0: |p - q|^2
  [[maybe_unused]] float qf[3] = {0, 0, 0};
  [[maybe_unused]] float margin_f = 0;
  if constexpr (detail::FloatChildBoxes<I>) {
    const Vec3 q_rel = q - index.float_origin();
    for (int a = 0; a < 3; ++a) qf[a] = static_cast<float>(q_rel[a]);
    const double mag = std::max({std::abs(q_rel.x), std::abs(q_rel.y), std::abs(q_rel.z)}) + index.float_extent();
    margin_f = detail::round_float_up(0x1p-20 * mag);
  }
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
    auto eval_slot = [&](std::uint32_t s) __attribute__((always_inline)) {
      const Vec3 v = pos[s] - q;
      const double d2 = glm::dot(v, v);
      if (d2 > r2 || d2 > worst) return;
      const detail::Candidate c{d2, ids[s], s, 0.0, d2};
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
    };
    if (kern.point_filter && sr.size() >= 4) {
      pf.d2_max = std::min(r2, worst) * (1.0 + 1e-12) + slack_d2;
      auto& sel = scratch.sel;
      if (sel.size() < sr.size()) sel.resize(sr.size());
      const unsigned n = kern.point_filter(&pos[sr.begin].x, sr.size(), pf, sel.data());
      for (unsigned j = 0; j < n; ++j) eval_slot(sr.begin + sel[j]);
    } else {
      for (std::uint32_t s = sr.begin; s < sr.end; ++s) eval_slot(s);
    }
    const unsigned nc = index.child_count(e.node);
    if constexpr (detail::FloatChildBoxes<I>) {
      if (kern.child_dist2 && nc <= 8) {
        float lb2[8];
        kern.child_dist2(index.child_boxes_f(e.node), qf, margin_f, lb2);
        for (unsigned i = 0; i < nc; ++i) {
          const double lb = lb2[i];
          if (!within(lb, r2) || !within(lb, worst)) continue;
          nodes.push_back({lb, index.child(e.node, i)});
          if (bounded) std::push_heap(nodes.begin(), nodes.end(), greater);
        }
        continue;
      }
    }
    for (unsigned i = 0; i < nc; ++i) {
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
