// The ray query's per-thread state: the candidate, the k-heap and the node stack, and the child
// ordering of the depth-first loop.
// Part of the ray query's private implementation (include detail/ray_query_impl.hpp).
#pragma once

#include "rayscan/octree/ray_query_types.hpp"
#include "rayscan/octree/detail/simd_kernels.hpp"

#include <atomic>

namespace rayscan::detail {

struct Candidate {
  double key;
  PointIndex id;
  std::uint32_t slot;  ///< storage slot of the point (RayHit::slot)
  double t;
  double d2;
};
inline bool cand_less(const Candidate& a, const Candidate& b) {
  return a.key < b.key || (a.key == b.key && a.id < b.id);
}
/// The RayHit that candidate c answers (RayHit::distance = sqrt(c.d2)): every query's one conversion.
inline RayHit to_ray_hit(const Candidate& c) { return {c.id, c.slot, c.t, std::sqrt(c.d2), c.key}; }
/// The answer of ray j of a batch whose traversal set bit j of `found` when best[j] holds its hit
/// (first_hit_pair, first_hit_packet): to_ray_hit(best[j]), or nullopt.
inline std::optional<RayHit> hit_of(std::uint32_t found, const Candidate* best, unsigned j) {
  return (found >> j) & 1u ? std::optional<RayHit>(to_ray_hit(best[j])) : std::nullopt;
}
/// The batch functions' length check: throws std::invalid_argument("<who>: N results for M rays")
/// unless `results` == `rays` (one output per ray).
inline void require_one_result_per_ray(const char* who, std::size_t results, std::size_t rays) {
  if (results != rays)
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(results) + " results for " +
                                std::to_string(rays) + " rays");
}

template <class Node>
struct NodeEntry {
  double lb;  // lower bound of the ordering key of any result inside the node
  Node node;
};
// The entry layout simd::SortPushKeys8Fn writes (16 bytes: lb at 0, a 32-bit node at 8).
static_assert(sizeof(NodeEntry<std::uint32_t>) == 16 && offsetof(NodeEntry<std::uint32_t>, node) == 8);

/// Indexes with 32-bit nodes whose children are consecutive handles (child(n, i) ==
/// child(n, 0) + i, declared by I::kContiguousChildren): the first-hit child step writes its
/// pushes with one kernel (simd::SortPushKeys8Fn).
template <class I>
concept ContiguousChildren32 = sizeof(typename I::Node) == 4 && requires { requires I::kContiguousChildren; };

/// Indexes with an entry grid (entry_grid(): an EntryGrid, on Octree and MappedIndex): the first
/// hit starts at the node of the cell where the ray enters (RayTraversal::entry_node, entry_final).
template <class I>
concept EntryGridIndex = requires(const I& idx) {
  idx.entry_grid().cells->node;
  idx.entry_grid().depth;
};

/// The entry-point search's setting (set_entry_point_search: an EntryPointSearch as int; default
/// automatic). A variable, not a function defined elsewhere: a call in the per-ISA traversals
/// would make the compiler save the ray's registers around it on every ray.
inline std::atomic<int> g_entry_point_search{static_cast<int>(EntryPointSearch::automatic)};
/// Whether the search is on at all (not EntryPointSearch::off).
inline bool entry_point_search_enabled() {
  return g_entry_point_search.load(std::memory_order_relaxed) != static_cast<int>(EntryPointSearch::off);
}
/// Whether first hits use every grid, also one not for them (EntryPointSearch::always).
inline bool entry_point_search_always() {
  return g_entry_point_search.load(std::memory_order_relaxed) == static_cast<int>(EntryPointSearch::always);
}

/// Reusable per-thread scratch so that a query allocates nothing once warm.
template <class Node>
struct RayScratch {
  // The node stack: entries [0, top) (traverse_from); the vector only grows, so that a push
  // needs no capacity test of its own (one per node, for all of its children).
  std::vector<NodeEntry<Node>> nodes;
  std::size_t top = 0;
  std::vector<Candidate> cands;
  std::vector<std::uint32_t> sel;  // survivors of the SIMD point filter (local slot offsets)
  std::vector<std::uint32_t> sel_rays;  // packet point filter: each survivor's rays (a mask)
  std::vector<Vec3> block;         // a leaf's positions decoded for the filter (compact encodings)
};

/// The calling thread's scratch number kSlot (0: every query's; 1: the second ray of
/// first_hit_pair, whose node stack must be its own).
template <class Node, unsigned kSlot = 0>
RayScratch<Node>& ray_scratch() {
  thread_local RayScratch<Node> s;
  return s;
}

/// The kernels member of a traversal with kernel policy K: simd::Kernels, the run-time table of the
/// active path (held by reference), or a compile-time policy of simd_kernels.hpp (an empty value
/// whose kernels are constants, called directly and inlined into a per-ISA traversal instance).
template <class K>
using KernelsOf = std::conditional_t<std::is_same_v<K, simd::Kernels>, const simd::Kernels&, K>;
/// Whether a kernel is present (nullptr on the scalar path); a function, so that a policy's
/// constant kernel does not draw -Waddress.
template <class Fn>
constexpr bool has_kernel(Fn f) {
  return f != nullptr;
}
template <class K>
KernelsOf<K> kernels_of() {
  if constexpr (std::is_same_v<K, simd::Kernels>)
    return simd::active_kernels();
  else
    return K{};
}

/// The child step on child order keys (simd.hpp, child_key), shared by the first-hit traversal
/// and knn_query: of node n's children in mask m (keys[0..8) from child_slab_keys or
/// child_dist2_keys, the lanes outside m ~0u), every one but the nearest is written to
/// stack[top, ...) as Entry{child_key_bound(key), child}, farthest first; returns the new top. The
/// caller goes on with the nearest (its `near` key). The stack needs room for 8 entries. Two
/// children: the farther after one compare; three or more: sorted by a network and, on
/// ContiguousChildren32 indexes, written by the same kernel (sort_push_keys8), else by a loop
/// (bench/notes/: the first hit's child step).
template <class I, class Kern, class Entry>
__attribute__((always_inline)) inline std::size_t push_farther_children(const I& index, const Kern& kern,
                                                                        typename I::Node n, unsigned m,
                                                                        std::uint32_t* keys, Entry* stack,
                                                                        std::size_t top) {
  auto entry = [&](std::uint32_t key) __attribute__((always_inline)) {
    Entry x{};  // (other members, as knn_query's points flag: zero)
    x.lb = simd::child_key_bound(key);
    x.node = index.child(n, simd::child_key_index(key));
    return x;
  };
  const unsigned m1 = m & (m - 1);
  if (m1 == 0) return top;  // one child: nothing to push
  if ((m1 & (m1 - 1)) == 0) {
    stack[top++] = entry(std::max(keys[__builtin_ctz(m)], keys[__builtin_ctz(m1)]));
  } else if (ContiguousChildren32<I> && has_kernel(kern.sort_push_keys8)) {
    const unsigned nk = static_cast<unsigned>(__builtin_popcount(m));
    kern.sort_push_keys8(keys, nk, static_cast<std::uint32_t>(index.child(n, 0)), stack + top);
    top += nk - 1;
  } else {  // keys[0..n) ascending after the sort, the lanes outside m (~0u) after them
    kern.sort_keys8(keys);
    for (unsigned j = static_cast<unsigned>(__builtin_popcount(m)); --j > 0;)
      stack[top++] = entry(keys[j]);
  }
  return top;
}

}  // namespace rayscan::detail
