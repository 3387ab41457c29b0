// The definition of knn_query (point_query.hpp declares it, with its documentation): the kNN
// traversal (knn_query_with) with the ray query's SIMD policies, and its instances compiled per
// ISA. Private to the library: included by the translation units that compile the instances for
// the library's index types (octree/src/query/point_query.cpp, site/src/query_instances.cpp) and
// by the tests of the traversal. Needs -ffp-contract=off (rayscan_octree_impl's compile option).
#pragma once

#include "rayscan/octree/detail/ray_query_impl.hpp"
#include "rayscan/octree/point_query.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <vector>

namespace rayscan {

namespace detail {

/// A kNN candidate: squared distance and original index (ordered by both: exact ties resolved by
/// the smaller index, like the brute-force oracle).
struct KnnCand {
  double d2;
  PointIndex id;
};
inline bool knn_less(const KnnCand& a, const KnnCand& b) { return a.d2 < b.d2 || (a.d2 == b.d2 && a.id < b.id); }
/// 4 lanes of Best8's squared distances (a GNU vector: one AVX2 register).
using Best4D = double __attribute__((vector_size(32)));
/// 4 lanes of Best8's ids (64-bit, so that one compare mask selects distances and ids; an id
/// < 2^32 compares the same signed), or of a compare's mask (all ones or 0).
using Best4I = std::int64_t __attribute__((vector_size(32)));
/// knn_query's k best for k <= 8 in 8 lanes, each of d2 and id two vectors of 4: ascending by
/// (d2, id), lanes past the held ones {inf, INT64_MAX} (never less than a candidate).
struct Best8 {
  static constexpr std::int64_t kNoId = std::numeric_limits<std::int64_t>::max();
  Best4D d2[2] = {Best4D{} + kInf, Best4D{} + kInf};
  Best4I id[2] = {Best4I{} + kNoId, Best4I{} + kNoId};
};
/// Inserts candidate (d2, id) into `best` without a branch: the lanes less than it (by (d2, id))
/// are a prefix; from the first other lane on, the candidate and the entries shifted up by one
/// lane (the last lane's entry drops out). All 8 lanes stay sorted.
__attribute__((always_inline)) inline void best8_insert(Best8& best, double d2, PointIndex id_in) {
  const std::int64_t id = id_in;
  const Best4D cd = Best4D{} + d2;
  const Best4I ci = Best4I{} + id;
  const Best4I lt0 = (best.d2[0] < cd) | ((best.d2[0] == cd) & (best.id[0] < ci));
  const Best4I lt1 = (best.d2[1] < cd) | ((best.d2[1] == cd) & (best.id[1] < ci));
  const Best4I prev0 = __builtin_shufflevector(lt0, Best4I{} - 1, 4, 0, 1, 2);  // lane i: lt of lane i - 1
  const Best4I prev1 = __builtin_shufflevector(lt1, lt0, 7, 0, 1, 2);
  best.d2[1] = lt1 ? best.d2[1] : (prev1 ? cd : __builtin_shufflevector(best.d2[1], best.d2[0], 7, 0, 1, 2));
  best.id[1] = lt1 ? best.id[1] : (prev1 ? ci : __builtin_shufflevector(best.id[1], best.id[0], 7, 0, 1, 2));
  best.d2[0] = lt0 ? best.d2[0] : (prev0 ? cd : __builtin_shufflevector(best.d2[0], best.d2[0], 0, 0, 1, 2));
  best.id[0] = lt0 ? best.id[0] : (prev0 ? ci : __builtin_shufflevector(best.id[0], best.id[0], 0, 0, 1, 2));
}
/// Whether knn_query_with<K> keeps k <= 8 in Best8: on the instances compiled for a SIMD path
/// (a compile-time policy of simd_kernels.hpp; knn_query uses them on indexes with
/// FloatChildBoxes), whose registers hold its lanes; the run-time table (scalar and SSE2, and
/// every path on the other indexes) keeps the insertion sort.
template <class K>
inline constexpr bool kVectorBest = !std::is_same_v<K, simd::Kernels>;

/// A stack entry of the kNN traversal: a node (points = false: test its children, then its own
/// points) or a node's own points alone (points = true, deferred below its children).
template <class Node>
struct KnnEntry {
  double lb;  ///< lower bound of the squared distance of any point the entry covers
  Node node;
  bool points;
};
// The layout simd::SortPushKeys8Fn writes (lb at 0, a 32-bit node at 8, zero bytes from 12: points
// reads false).
static_assert(sizeof(KnnEntry<std::uint32_t>) == 16 && offsetof(KnnEntry<std::uint32_t>, node) == 8 &&
              offsetof(KnnEntry<std::uint32_t>, points) == 12);

/// Per-thread scratch of knn_query (allocates nothing once warm).
template <class Node>
struct KnnScratch {
  std::vector<KnnEntry<Node>> stack;  // storage: its size is the capacity (knn_query_with keeps the top)
  std::vector<KnnCand> cands;
  std::vector<std::uint32_t> sel;  // survivors of the SIMD point filter (local slot offsets)
};
template <class Node>
KnnScratch<Node>& knn_scratch() {
  thread_local KnnScratch<Node> s;
  return s;
}

/// Up to this k the k best are kept as a sorted array (insertion), above it as a binary heap.
inline constexpr std::size_t kKnnSortedMax = 32;

/// A query point in the float frame of an index's child boxes, the inputs of simd child_dist2:
/// q - float_origin() rounded to float, and the position-space margin covering that rounding and
/// the boxes' own (2^-20 of the magnitudes involved, rounded up). Zero on indexes without
/// FloatChildBoxes (unused there). `usable` is false where those magnitudes pass 2^60 (a query
/// point 1e18 from the cloud): a squared distance in float could then overflow to inf and prune
/// a child the double bound keeps, so the callers take their double child bounds instead.
struct FloatQueryPoint {
  float q[3] = {0.0f, 0.0f, 0.0f};
  float margin = 0.0f;
  bool usable = false;
};
template <SpatialIndex I>
__attribute__((always_inline)) inline FloatQueryPoint float_query_point([[maybe_unused]] const I& index, [[maybe_unused]] const Vec3& q) {
  FloatQueryPoint f;
  if constexpr (FloatChildBoxes<I>) {
    const Vec3 q_rel = q - index.float_origin();
    for (int a = 0; a < 3; ++a) f.q[a] = static_cast<float>(q_rel[a]);
    const double mag = std::max({std::abs(q_rel.x), std::abs(q_rel.y), std::abs(q_rel.z)}) + index.float_extent();
    f.margin = round_float_up(0x1p-20 * mag);
    f.usable = mag <= 0x1p60;
  }
  return f;
}

}  // namespace detail

namespace detail {

/// Whether a kNN stack entry with squared MINDIST lb is kept under the pruning bound b (a relative
/// tolerance of 1e-12).
__attribute__((always_inline)) inline bool knn_within(double lb, double b) { return lb <= b * (1.0 + 1e-12); }

/// knn_query_with's child step for node e.node (nc >= 1 children; its own points' entry already
/// pushed): the children within `bound` (squared distance, world units squared) pushed on the
/// stack st[0, top) far-to-near, the nearest one left in `e` to expand next (returns true), or
/// false when no child is kept. Child bounds: on FloatChildBoxes indexes the SIMD kernels of K
/// (child order keys sorted by a network, or child_dist2 lower bounds in float, rounded down),
/// else distance2_point_box in double; more than 8 children are pushed unordered. The stack has
/// room for max(nc, 8) + 1 more entries.
template <class K, SpatialIndex I>
__attribute__((always_inline)) inline bool knn_push_children(const I& index, const KernelsOf<K>& kern, const Vec3& q,
                                                             [[maybe_unused]] const FloatQueryPoint& qf, double bound,
                                                             unsigned nc, KnnEntry<typename I::Node>& e,
                                                             KnnEntry<typename I::Node>* st, std::size_t& top) {
  using Node = typename I::Node;
  if constexpr (FloatChildBoxes<I>) {
    if (qf.usable && has_kernel(kern.child_dist2_keys) && nc <= 8) {
      // The children's bounds as keys (simd.hpp, ChildDist2KeysFn) against the bound rounded up
      // to float: the mask may keep a child knn_within() drops (dropped when popped, or expanded
      // for nothing when nearest), never the reverse. The farther children pushed as
      // RayTraversal's child step pushes them (push_farther_children).
      alignas(32) std::uint32_t keys[8];
      std::uint32_t near;
      const float bf = round_float_up(bound * (1.0 + 1e-12));
      const unsigned m = kern.child_dist2_keys(index.child_boxes_f(e.node), qf.q, qf.margin, bf, keys, near);
      if (m == 0) return false;
      top = push_farther_children(index, kern, e.node, m, keys, st, top);
      e = {simd::child_key_bound(near), index.child(e.node, simd::child_key_index(near)), false};
      return true;
    }
  }
  double lb[8];
  Node ch[8];
  unsigned m = 0;
  auto add = [&](double l, Node c) __attribute__((always_inline)) {
    if (!knn_within(l, bound)) return;
    unsigned j = m++;
    for (; j > 0 && lb[j - 1] < l; --j) {  // descending by bound
      lb[j] = lb[j - 1];
      ch[j] = ch[j - 1];
    }
    lb[j] = l;
    ch[j] = c;
  };
  bool done = false;
  if constexpr (FloatChildBoxes<I>) {
    if (qf.usable && has_kernel(kern.child_dist2) && nc <= 8) {
      float lb2[8];
      kern.child_dist2(index.child_boxes_f(e.node), qf.q, qf.margin, lb2);
      for (unsigned i = 0; i < nc; ++i) add(lb2[i], index.child(e.node, i));
      done = true;
    }
  }
  if (!done) {
    if (nc <= 8) {
      for (unsigned i = 0; i < nc; ++i) {
        const Node c = index.child(e.node, i);
        add(distance2_point_box(q, index.node_bounds(c)), c);
      }
    } else {  // more than 8 children (not an octree): unordered
      for (unsigned i = 0; i < nc; ++i) {
        const Node c = index.child(e.node, i);
        const double l = distance2_point_box(q, index.node_bounds(c));
        if (knn_within(l, bound)) st[top++] = {l, c, false};
      }
    }
  }
  if (m == 0) return false;
  for (unsigned j = 0; j + 1 < m; ++j) st[top++] = {lb[j], ch[j], false};
  e = {lb[m - 1], ch[m - 1], false};
  return true;
}

/// knn_query's traversal with kernel policy K (as RayTraversal's: simd::Kernels or a compile-time
/// policy of simd_kernels.hpp), for a valid radius and q, a non-empty index and k >= 1; `out` is
/// cleared.
template <class K, SpatialIndex I>
__attribute__((always_inline)) inline void knn_query_with(const I& index, const Vec3& q, std::size_t k,
                                                          double radius, std::vector<Neighbor>& out) {
  using Node = typename I::Node;
  using detail::KnnCand;
  const bool bounded = k != kAllPoints;
  const bool sorted_set = bounded && k <= detail::kKnnSortedMax;
  const double r2 = radius * radius;
  const auto pos = index.positions();
  const IdView ids = index.ids();
  auto& scratch = detail::knn_scratch<Node>();
  auto& stack = scratch.stack;
  auto& cands = scratch.cands;
  std::size_t held = 0;  // sorted_set: cands[0, held) sorted ascending (small_set: best's lanes [0, held))
  // k <= 8 on the compiled SIMD instances: the k best in two vectors of 4 lanes sorted ascending,
  // the lanes past the held ones {inf, max} (never less than a candidate), filled by a
  // branch-free insertion; elsewhere cands, by insertion sort.
  const bool small_set = detail::kVectorBest<K> && bounded && k <= 8;
  detail::Best8 best;
  if (sorted_set) {
    if (cands.size() < k) cands.resize(k);  // once per thread: no per-query fill
  } else {
    cands.clear();
  }
  double worst = kInf;   // the k-th smallest squared distance once k are held
  double bound = r2;     // min(r2, worst): the pruning bound
  const AABB root_box = index.node_bounds(index.root());
  // SIMD policies (simd.hpp): see ray_query for the margins.
  const KernelsOf<K> kern = kernels_of<K>();
  const double vmax = glm::length(q - root_box.center()) + 0.5 * glm::length(root_box.hi - root_box.lo);
  const double slack_d2 = 1e-12 * vmax * vmax + 1e-300;
  simd::PointFilterD pf{{q.x, q.y, q.z}, {0.0, 0.0, 0.0}, 0.0, -kInf, kInf};  // d = 0: |p - q|^2
  [[maybe_unused]] const detail::FloatQueryPoint qf = detail::float_query_point(index, q);
  auto insert = [&](std::uint32_t s) __attribute__((always_inline)) {
    const Vec3 v = pos[s] - q;
    const double d2 = glm::dot(v, v);
    // bound <= r2 and <= worst; the vector k best rejects past worst itself, branch-free (a
    // candidate past it lands in a lane >= k), so there only the radius is tested (kInf: never).
    if (small_set ? d2 > r2 : d2 > bound) return;
    const KnnCand c{d2, ids[s]};
    if (!bounded) {
      cands.push_back(c);
      return;
    }
    if constexpr (detail::kVectorBest<K>) {
      if (small_set) {
        // Branch-free (the sorted insertion's loop exits mispredicted: bench/notes/): the lanes
        // less than c are a prefix; from the first other lane on, c and the entries shifted up by
        // one lane. All 8 lanes stay sorted, so the k-th is right for any k <= 8 and a candidate
        // past it only moves lanes >= k.
        detail::best8_insert(best, d2, c.id);
        held += held < k;
        worst = best.d2[(k - 1) / 4][(k - 1) % 4];
        bound = std::min(r2, worst);
        return;
      }
    }
    if (sorted_set) {
      std::size_t i;
      if (held < k) {
        i = held++;
      } else {
        if (!detail::knn_less(c, cands[k - 1])) return;
        i = k - 1;
      }
      for (; i > 0 && detail::knn_less(c, cands[i - 1]); --i) cands[i] = cands[i - 1];
      cands[i] = c;
      if (held == k) worst = cands[k - 1].d2;
    } else if (cands.size() < k) {
      cands.push_back(c);
      std::push_heap(cands.begin(), cands.end(), detail::knn_less);
      if (cands.size() == k) worst = cands.front().d2;
    } else {
      if (!detail::knn_less(c, cands.front())) return;
      std::pop_heap(cands.begin(), cands.end(), detail::knn_less);
      cands.back() = c;
      std::push_heap(cands.begin(), cands.end(), detail::knn_less);
      worst = cands.front().d2;
    }
    bound = std::min(r2, worst);
  };
  // Leaf work: the node's own points, through the SIMD filter once a finite bound exists.
  auto eval_points = [&](Node n) __attribute__((always_inline)) {
    const SlotRange sr = index.node_points(n);
    if (has_kernel(kern.point_filter) && sr.size() >= 4 && bound < kInf) {
      pf.d2_max = bound * (1.0 + 1e-12) + slack_d2;
      auto& sel = scratch.sel;
      if (sel.size() < sr.size()) sel.resize(sr.size());
      const unsigned m = kern.point_filter(position_block(pos, sr.begin, sr.size()), sr.size(), pf, sel.data());
      for (unsigned j = 0; j < m; ++j) insert(sr.begin + sel[j]);
    } else {
      for (std::uint32_t s = sr.begin; s < sr.end; ++s) insert(s);
    }
  };
  // The stack's storage and size in locals (as RayTraversal::traverse_from), grown before a node's
  // pushes: at most its 8 children and its own points' entry (or nc + 1 for more children).
  detail::KnnEntry<Node>* st = stack.data();
  std::size_t cap = stack.size();
  // The search of the subtree of `start` (its squared MINDIST lb0), nearest first, leaving out the
  // subtree of `skip` (already searched; an invalid node: none).
  auto search = [&](Node start, double lb0, Node skip) __attribute__((always_inline)) {
    std::size_t top = 0;
    // e: the node to expand next: popped, or the nearest child of the last one, expanded right away
    // instead of through the stack (as RayTraversal::traverse_from; it passed knn_within() just now).
    detail::KnnEntry<Node> e{lb0, start, false};
    bool next = detail::knn_within(e.lb, bound);
    while (true) {
      if (!next) {
        if (top == 0) break;
        e = st[--top];
        if (!detail::knn_within(e.lb, bound)) continue;
      }
      next = false;
      if (e.node == skip) continue;
      const unsigned nc = index.child_count(e.node);
      if (e.points || nc == 0) {
        eval_points(e.node);
        continue;
      }
      if (const std::size_t room = std::max(nc, 8u) + 1; top + room > cap) [[unlikely]] {
        stack.resize(cap + room + 64);
        st = stack.data();
        cap = stack.size();
      }
      // The children after the node's own points on the stack, far-to-near so that the nearest is
      // expanded first.
      if (index.node_points(e.node).size() > 0) st[top++] = {e.lb, e.node, true};
      next = detail::knn_push_children<K>(index, kern, q, qf, bound, nc, e, st, top);
    }
  };
  constexpr Node kNoNode = static_cast<Node>(-1);
  // The entry-point search (as the first hit's, RayTraversal::entry_node), or false where it does
  // not apply: the subtree of H, the node of the deepest grid cell holding q, first, which leaves
  // the k-th distance as a bound; then, unless the ball of that radius around q is inside H's
  // cell, the other cells the ball reaches (or the node of the smallest grid cell holding it,
  // without H). A point's grid cell is its Morton cell's top bits (EntryGrid::coord), monotone in
  // each coordinate, so every point in the ball's box lies in the grid cells between its corners'.
  // Later points only shrink the ball, so one such step suffices.
  auto search_from_entry_grid = [&]() __attribute__((always_inline)) -> bool {
    if constexpr (EntryGridIndex<I>) {
      const auto g = index.entry_grid();
      if (g.cells == nullptr || !bounded || !entry_point_search_enabled()) return false;
      unsigned c[3];
      for (unsigned a = 0; a < 3; ++a) c[a] = g.coord(q[a], a);
      const auto& hc = g.at(g.depth, c[0], c[1], c[2]);
      search(hc.node, distance2_point_box(q, index.node_bounds(hc.node)), kNoNode);
      if (hc.node == index.root()) return true;
      if (!(bound < kInf)) {  // fewer than k points in H and no radius: the rest of the tree
        search(index.root(), distance2_point_box(q, root_box), hc.node);
        return true;
      }
      // The ball's box, grown past every rounding of the distances (knn_within's 1e-12) and of
      // its corners.
      const double rad = std::sqrt(bound) * (1.0 + 1e-9) + 0x1p-40 * (g.side + vmax);
      unsigned lo[3], hi[3], diff = 0;
      for (unsigned a = 0; a < 3; ++a) {
        lo[a] = g.coord(q[a] - rad, a);
        hi[a] = g.coord(q[a] + rad, a);
        diff |= lo[a] ^ hi[a];
      }
      const unsigned l = g.shared_level(diff);
      if (l >= hc.depth) return true;  // the ball is inside H's cell
      // A box over at most 8 cells of the deepest level, each its own node at that depth
      // (distinct cells, none above another): their nodes but H, nearest first.
      if (hc.depth == g.depth && (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1) <= 8) {
        detail::KnnEntry<Node> nb[8];  // (H's cell is in the box: at most 7 others)
        unsigned m = 0;
        bool own_cells = true;
        for (unsigned k2 = lo[2]; k2 <= hi[2]; ++k2)
          for (unsigned j = lo[1]; j <= hi[1]; ++j)
            for (unsigned i = lo[0]; i <= hi[0]; ++i) {
              const auto& cc = g.at(g.depth, i, j, k2);
              own_cells = own_cells && cc.depth == g.depth;
              if (cc.node != hc.node) nb[m++] = {distance2_point_box(q, index.node_bounds(cc.node)), cc.node, false};
            }
        if (own_cells) {
          for (unsigned j = 1; j < m; ++j)  // (insertion: at most 7 entries)
            for (unsigned i = j; i > 0 && nb[i].lb < nb[i - 1].lb; --i) std::swap(nb[i], nb[i - 1]);
          for (unsigned j = 0; j < m; ++j)
            if (detail::knn_within(nb[j].lb, bound)) search(nb[j].node, nb[j].lb, kNoNode);
          return true;
        }
      }
      const unsigned sh = g.depth - l;
      const auto& ac = g.at(l, c[0] >> sh, c[1] >> sh, c[2] >> sh);
      search(ac.node, distance2_point_box(q, index.node_bounds(ac.node)), hc.node);
      return true;
    } else {
      return false;
    }
  };
  if (!search_from_entry_grid()) search(index.root(), distance2_point_box(q, root_box), kNoNode);
  if (!sorted_set) {
    std::sort(cands.begin(), cands.end(), detail::knn_less);
    held = cands.size();
  }
  out.reserve(held);
  if (small_set) {
    for (std::size_t i = 0; i < held; ++i)
      out.push_back({static_cast<PointIndex>(best.id[i / 4][i % 4]), std::sqrt(best.d2[i / 4][i % 4])});
    return;
  }
  for (std::size_t i = 0; i < held; ++i) out.push_back({cands[i].id, std::sqrt(cands[i].d2)});
}

#if RAYSCAN_SIMD_X86
/// knn_query_with compiled for AVX2 + FMA with the AVX2 kernels inlined (flatten, as
/// ray_traverse_avx2).
template <SpatialIndex I>
__attribute__((target("avx2,fma"), flatten, noinline)) void knn_query_avx2(const I& index, const Vec3& q,
                                                                           std::size_t k, double radius,
                                                                           std::vector<Neighbor>& out) {
  knn_query_with<simd::Avx2Kernels>(index, q, k, radius, out);
}
/// As knn_query_avx2, for the AVX-512 path (F + VL).
template <SpatialIndex I>
__attribute__((target("avx512f,avx512vl,avx2,fma"), flatten, noinline)) void knn_query_avx512(
    const I& index, const Vec3& q, std::size_t k, double radius, std::vector<Neighbor>& out) {
  knn_query_with<simd::Avx512Kernels>(index, q, k, radius, out);
}
#endif

}  // namespace detail

template <SpatialIndex I>
void knn_query(const I& index, const Vec3& q, std::size_t k, double radius, std::vector<Neighbor>& out) {
  if (std::isnan(radius) || radius < 0.0)
    throw std::invalid_argument("knn query: radius must be >= 0");
  if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
    throw std::invalid_argument("knn query: query point must be finite");
  out.clear();
  if (index.empty() || k == 0) return;
#if RAYSCAN_SIMD_X86
  // On FloatChildBoxes indexes, the instance compiled for the active path (as ray_traverse).
  if constexpr (detail::FloatChildBoxes<I>) {
    switch (simd::active_kernels().path) {
      case SimdPath::avx2: return detail::knn_query_avx2(index, q, k, radius, out);
      case SimdPath::avx512: return detail::knn_query_avx512(index, q, k, radius, out);
      default: break;
    }
  }
#endif
  detail::knn_query_with<simd::Kernels>(index, q, k, radius, out);
}

}  // namespace rayscan
