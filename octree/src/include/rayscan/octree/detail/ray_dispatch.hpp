// The traversal's instances per instruction set and the run-time choice between them (root test,
// ray_traverse, first_hit_pair).
// Part of the ray query's private implementation (include detail/ray_query_impl.hpp).
#pragma once

#include "rayscan/octree/detail/ray_traversal.hpp"

namespace rayscan::detail {

/// The first-hit traversals' root test by the path's ray_box kernel (simd::RayBoxFn), where it has
/// one and the query a finite radius (the node test's grown slabs; with an infinite radius it
/// bounds the projection instead), before any traversal set-up: a conservative test, miss only
/// when the traversal's own test of the root would fail, at a fraction of the set-up that test
/// needs (its tolerance, 1 / d, the grown origins). A ray it lets in enters the root without the
/// traversal's own test where the kernel's stands for it (RayTraversal::enters_root): the node
/// tests are pruning only, and the root's children are tested as ever, so answers are unchanged and
/// only RayQueryStats may count the root for a ray within the kernel's wider margin. Most of
/// bench_rays' camera misses (~47% of its rays) are decided here: 356 -> 183 instructions each,
/// and hits no slower (bench/notes/). KeyPolicy: the traversal's.
/// Whether root_test decides by the ray_box kernel for query q (else it answers exact).
template <class K, class KeyPolicy>
__attribute__((always_inline)) inline bool root_kernel_applies(const KernelsOf<K>& kern, const RayQuery& q) {
  if (!has_kernel(kern.ray_box) || !(q.radius < kInf)) return false;
  // (Per-node radii with order ray: the traversal's constructor refuses the query, for every ray.)
  if constexpr (KeyPolicy::node_radius)
    if (q.order == RayOrder::ray) return false;
  return true;
}

template <class K, class KeyPolicy, SpatialIndex I>
__attribute__((always_inline)) inline RootTest root_test(const KernelsOf<K>& kern, const I& index, const Ray& ray,
                                                         const RayQuery& q) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));  // (the kernel reads 3 doubles from &v.x)
  if (!root_kernel_applies<K, KeyPolicy>(kern, q)) return RootTest::exact;
  const AABB b = index.node_bounds(index.root());
  // t_max + radius bounds the traversal's t_hi for every order (sphere keys: t_p <= key + r).
  return kern.ray_box(&b.lo.x, &b.hi.x, &ray.origin().x, &ray.direction().x, q.radius, q.t_min, q.t_max + q.radius)
             ? RootTest::enter
             : RootTest::miss;
}

/// The traversal of one ray with kernel policy K after root_test found `root` (enter or exact),
/// from the root. Returns true when `best` was set (kBest1 only).
/// `scratch`: the per-thread scratch (nullptr: the traversal fetches ray_scratch<Node>() itself).
template <bool kBest1, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline bool ray_traverse_from_root(RootTest root, const I& index, const Ray& ray,
                                                                  const RayQuery& q, Candidate& best,
                                                                  RayQueryStats* stats, const KeyPolicy& key_policy,
                                                                  RayScratch<typename I::Node>* scratch = nullptr) {
  RayTraversal<kBest1, I, KeyPolicy, K> rt(index, ray, q, best, stats, key_policy, scratch);
  double lb0;
  if (!rt.enters_root(root, lb0)) {  // missed the root: no further set-up
    if constexpr (!kBest1) rt.scratch.cands.clear();  // (ray_query reads them)
    return false;
  }
  rt.prepare();
  if constexpr (kBest1)
    rt.traverse_first_hit(lb0);
  else
    rt.traverse_from(index.root(), lb0);
  return rt.found;
}

/// The ray query for one ray with kernel policy K: the traversal above from the root, the first
/// hit's after root_test. Returns true when `best` was set (kBest1 only). `scratch` as
/// ray_traverse_from_root's.
template <bool kBest1, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline bool ray_traverse_with(const I& index, const Ray& ray, const RayQuery& q,
                                                             Candidate& best, RayQueryStats* stats,
                                                             const KeyPolicy& key_policy,
                                                             RayScratch<typename I::Node>* scratch = nullptr) {
  RootTest root = RootTest::exact;
  if constexpr (kBest1) {
    root = root_test<K, KeyPolicy>(kernels_of<K>(), index, ray, q);
    if (root == RootTest::miss) return false;
  }
  return ray_traverse_from_root<kBest1, K>(root, index, ray, q, best, stats, key_policy, scratch);
}

/// ray_traverse_with with the table kernels (simd::Kernels: the active path's kernels through
/// function pointers), as one out-of-line function: the instance every path without a per-ISA one
/// runs (SSE2 and scalar, k > 1, refined keys, indexes without float child boxes). Its instances
/// are compiled once per index type, with the ray query's entry points in the libraries of the
/// indexes (RAYSCAN_RAY_QUERY_INSTANCES), instead of in every translation unit that queries (CI
/// build time, bench/notes/).
template <bool kBest1, SpatialIndex I, class KeyPolicy>
__attribute__((noinline)) bool ray_traverse_base(const I& index, const Ray& ray, const RayQuery& q, Candidate& best,
                                                 RayQueryStats* stats, const KeyPolicy& key_policy) {
  return ray_traverse_with<kBest1, simd::Kernels>(index, ray, q, best, stats, key_policy);
}

#if RAYSCAN_SIMD_X86
/// ray_traverse_with compiled for AVX2 + FMA with the AVX2 kernels, everything it calls inlined
/// (flatten; a kernel cannot be always_inline into the traversal's default-target member
/// functions): no indirect kernel call, no spill of the ray's state around one, VEX encodings
/// for the scalar double code. Same double arithmetic as the baseline instance (-ffp-contract=off: no
/// fused multiply-add is formed from the traversal's own expressions), so the answers are
/// bit-identical. Called only after simd_path() chose avx2 (__builtin_cpu_supports).
/// `scratch` (ray_scratch<Node>() of the calling thread) is fetched by the caller: a thread_local
/// with a guard, read in here, made GCC spill the ray's registers and clear the upper halves
/// (vzeroupper) around the guard's possible call on every ray, a cost the Intel Xeon's profile
/// showed and the AMD EPYC's hid (bench/notes/).
template <bool kBest1, SpatialIndex I, class KeyPolicy>
__attribute__((target("avx2,fma"), flatten, noinline)) bool ray_traverse_avx2(
    const I& index, const Ray& ray, const RayQuery& q, Candidate& best, RayQueryStats* stats,
    const KeyPolicy& key_policy, RayScratch<typename I::Node>* scratch = nullptr) {
  return ray_traverse_with<kBest1, simd::Avx2Kernels>(index, ray, q, best, stats, key_policy, scratch);
}
/// As ray_traverse_avx2, for the AVX-512 path (F + VL).
template <bool kBest1, SpatialIndex I, class KeyPolicy>
__attribute__((target("avx512f,avx512vl,avx2,fma"), flatten, noinline)) bool ray_traverse_avx512(
    const I& index, const Ray& ray, const RayQuery& q, Candidate& best, RayQueryStats* stats,
    const KeyPolicy& key_policy, RayScratch<typename I::Node>* scratch = nullptr) {
  return ray_traverse_with<kBest1, simd::Avx512Kernels>(index, ray, q, best, stats, key_policy, scratch);
}
#endif

/// Whether the traversal of index I with key policy KeyPolicy has instances compiled per ISA
/// (ray_traverse_avx2 / _avx512 with kBest1, first_hit_packet_avx2 / _avx512 and, with OrderKey,
/// first_hit_pair_avx2 / _avx512): the first hit
/// (k = 1, the renderer's and visibility's query) of the plain ray query (OrderKey)
/// on indexes with float child boxes. Queries with k > 1 and the refined keys of surfel rendering
/// keep the table instance: each per-ISA instance is the whole traversal inlined once more, and
/// instancing every combination made the build 1.75x slower (bench/notes/). The instances
/// are compiled once per index type, in the library (RAYSCAN_RAY_QUERY_INSTANCES).
template <class I, class KeyPolicy>
inline constexpr bool kIsaInstances = FloatChildBoxes<I> && std::is_same_v<KeyPolicy, OrderKey>;

/// The ray query for one ray: the traversal above from the root, on the active SIMD path
/// (simd_path()): where kIsaInstances, the instance compiled for that path's instruction set
/// (ray_traverse_avx2 / _avx512), else the instance that calls the path's kernels through
/// simd::Kernels. Returns true when `best` was set (kBest1 only).
template <bool kBest1, SpatialIndex I, class KeyPolicy = OrderKey>
bool ray_traverse(const I& index, const Ray& ray, const RayQuery& q, Candidate& best, RayQueryStats* stats,
                  const KeyPolicy& key_policy = {}) {
#if RAYSCAN_SIMD_X86
  if constexpr (kBest1 && kIsaInstances<I, KeyPolicy>) {
    switch (simd::active_kernels().path) {
      case SimdPath::avx2:
        return ray_traverse_avx2<kBest1>(index, ray, q, best, stats, key_policy, &ray_scratch<typename I::Node>());
      case SimdPath::avx512:
        return ray_traverse_avx512<kBest1>(index, ray, q, best, stats, key_policy, &ray_scratch<typename I::Node>());
      default: break;
    }
  }
#endif
  return ray_traverse_base<kBest1>(index, ray, q, best, stats, key_policy);
}

/// The first hits of two rays, their traversals interleaved one node at a time (RayTraversal::step
/// of the one traversal, each ray on its own node stack: ray_scratch slots 0 and 1), so that the
/// core overlaps the two chains of dependent loads and tests from one node to the next, which set
/// a single ray's speed (bench/notes/). best[j] and bit j of the result
/// are ray_traverse<true>'s answer for rays[j], bit for bit (each ray's own order, bounds and
/// candidates; only the interleaving differs). With kernel policy K as ray_traverse_with. A ray
/// that root_test finds missing leaves the other to be traced alone (slot 0).
template <class K, SpatialIndex I>
__attribute__((always_inline)) inline unsigned first_hit_pair_with(const I& index, const Ray* rays, const RayQuery& q,
                                                                   Candidate* best, RayQueryStats* stats) {
  using Traversal = RayTraversal<true, I, OrderKey, K>;
  using Node = typename I::Node;
  const OrderKey key_policy;
  const KernelsOf<K> kern = kernels_of<K>();
  const RootTest root0 = root_test<K, OrderKey>(kern, index, rays[0], q);
  const RootTest root1 = root_test<K, OrderKey>(kern, index, rays[1], q);
  if (root0 == RootTest::miss || root1 == RootTest::miss) {  // one ray at most to trace: alone (slot 0)
    if (root0 == root1) return 0;
    const unsigned j = root0 == RootTest::miss ? 1 : 0;
    return ray_traverse_from_root<true, K>(j ? root1 : root0, index, rays[j], q, best[j], stats, key_policy) ? 1u << j
                                                                                                           : 0u;
  }
  // Each ray's steps: from its entry grid node first where the entry-point search applies, then
  // from the root unless that node's hit is final (RayTraversal::entry_node, entry_final).
  auto advance = [](Traversal& r, typename Traversal::Cursor& c, bool& from_entry, Node entry, double lb_root) {
    if (r.step(c)) return true;
    if (!from_entry) return false;
    from_entry = false;
    r.end(c);
    Node restart = r.index.root();
    if (r.entry_final(entry, restart, lb_root)) return false;
    c = r.begin_at(restart, lb_root);
    return true;
  };
  Traversal r0(index, rays[0], q, best[0], stats, key_policy);
  Traversal r1(index, rays[1], q, best[1], stats, key_policy, &ray_scratch<typename I::Node, 1>());
  double lb0, lb1;
  bool a0 = r0.enters_root(root0, lb0);  // (a ray that misses the root: no further set-up)
  bool a1 = r1.enters_root(root1, lb1);
  typename Traversal::Cursor c0{}, c1{};
  Node n0{}, n1{};
  bool e0 = false, e1 = false;  // stepping from the entry node
  if (a0) {
    r0.prepare();
    double lb;
    e0 = r0.entry_search_applies() && r0.entry_node(n0, lb);
    c0 = e0 ? r0.begin_at(n0, lb) : r0.begin_at(index.root(), lb0);
  }
  if (a1) {
    r1.prepare();
    double lb;
    e1 = r1.entry_search_applies() && r1.entry_node(n1, lb);
    c1 = e1 ? r1.begin_at(n1, lb) : r1.begin_at(index.root(), lb1);
  }
  const bool s0 = a0, s1 = a1;
  while (a0 && a1) {
    a0 = advance(r0, c0, e0, n0, lb0);
    a1 = advance(r1, c1, e1, n1, lb1);
  }
  while (a0) a0 = advance(r0, c0, e0, n0, lb0);
  while (a1) a1 = advance(r1, c1, e1, n1, lb1);
  if (s0) r0.end(c0);
  if (s1) r1.end(c1);
  return (r0.found ? 1u : 0u) | (r1.found ? 2u : 0u);
}

/// first_hit_pair_with with the table kernels (the instance of paths and indexes without per-ISA
/// ones; compiled once per index type, RAYSCAN_RAY_QUERY_INSTANCES).
template <SpatialIndex I>
__attribute__((noinline)) unsigned first_hit_pair_base(const I& index, const Ray* rays, const RayQuery& q,
                                                       Candidate* best, RayQueryStats* stats) {
  return first_hit_pair_with<simd::Kernels>(index, rays, q, best, stats);
}

#if RAYSCAN_SIMD_X86
/// first_hit_pair_with compiled for AVX2 + FMA, as ray_traverse_avx2.
template <SpatialIndex I>
__attribute__((target("avx2,fma"), flatten, noinline)) unsigned first_hit_pair_avx2(const I& index, const Ray* rays,
                                                                                    const RayQuery& q, Candidate* best,
                                                                                    RayQueryStats* stats) {
  return first_hit_pair_with<simd::Avx2Kernels>(index, rays, q, best, stats);
}
/// first_hit_pair_with compiled for AVX-512 (F + VL), as ray_traverse_avx512.
template <SpatialIndex I>
__attribute__((target("avx512f,avx512vl,avx2,fma"), flatten, noinline)) unsigned first_hit_pair_avx512(
    const I& index, const Ray* rays, const RayQuery& q, Candidate* best, RayQueryStats* stats) {
  return first_hit_pair_with<simd::Avx512Kernels>(index, rays, q, best, stats);
}
#endif

/// first_hit_pair_with on the active SIMD path (as ray_traverse: the per-ISA instance where
/// kIsaInstances, else the table one).
template <SpatialIndex I>
unsigned first_hit_pair(const I& index, const Ray* rays, const RayQuery& q, Candidate* best, RayQueryStats* stats) {
#if RAYSCAN_SIMD_X86
  if constexpr (kIsaInstances<I, OrderKey>) {
    switch (simd::active_kernels().path) {
      case SimdPath::avx2: return first_hit_pair_avx2(index, rays, q, best, stats);
      case SimdPath::avx512: return first_hit_pair_avx512(index, rays, q, best, stats);
      default: break;
    }
  }
#endif
  return first_hit_pair_base(index, rays, q, best, stats);
}

}  // namespace rayscan::detail
