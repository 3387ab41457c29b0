// The packet first hit: up to 16 rays driven down one shared node stack with RayTraversal's node
// test and leaf work.
// Part of the ray query's private implementation (include detail/ray_query_impl.hpp).
#pragma once

#include "rayscan/octree/detail/ray_dispatch.hpp"

#include <cstring>

namespace rayscan::detail {

/// The packet first hit of up to N <= 16 rays (kBest1 policy, OrderKey). One traversal state per
/// ray (RayTraversal above: its node test, leaf work and candidate sink), driven down one shared
/// node stack: a node is visited when any of the rays of its entry's mask still has it live, each
/// live ray evaluates the node's points and tests the node's children with its own node test, and
/// a child is pushed once with the mask of the rays that hit it (and each one's lower bound), so
/// rays whose t_far (the k-bound) is beaten drop out of the subtrees behind their hit. When a
/// node is left with a single live ray the packet has diverged there and that ray finishes the
/// subtree alone (RayTraversal::traverse_from, the single-ray loop itself).
///
/// SIMD over the rays where the path has the kernels: the root test of every ray at once
/// (packet_ray_box), the children's slab test (packet_child_slab), each ray's live() bound kept per
/// lane (a popped entry's live rays are one mask of compares), and a leaf's points filtered for
/// all live rays at once (packet_point_filter, when they fill half of the lanes it computes); each
/// kernel keeps exactly what the single-ray test keeps, or more.
///
/// Why a loop of its own rather than a policy of traverse_from: the stack entries carry a ray
/// mask and a bound per ray, and the child order is chosen for the packet; every exact test of a
/// node or a point is the single-ray code. Each ray's answer is the exact minimum (key, id)
/// over every candidate, which conservative pruning always reaches, so it is bit-identical to
/// ray_first_hit on that ray whatever order the nodes are visited in. Returns the mask of rays
/// that found a hit (best[i] set).
///
/// `keys[i]` is ray i's point-key policy (OrderKey, or a RefinedKey whose refinement depends on the
/// ray, e.g. the discs of surfel rendering; nullptr only with OrderKey). With per-node
/// radii each ray enters a node with its own bound (RayTraversal::enter_node; or keeps the root's
/// when the filter has per-slot radii and the boxes are float geometry boxes); with float
/// geometry boxes (RefinedKey::child_boxes_f) the children are tested on them, all rays at once.
///
/// `K`: the kernel policy, as RayTraversal's (first_hit_packet_avx2 / _avx512 below run the
/// instances compiled per ISA).
/// A stack entry of first_hit_packet: a node and the rays (of at most N) for which it passed
/// the node test, each with its lower bound.
template <class Node, unsigned N>
struct PacketEntry {
  Node node;
  std::uint32_t mask;  // rays for which the node passed the node test
  double lb[N];        // each one's lower bound (valid where mask has the bit)
};

/// Sets lane i of `lanes` (first_hit_packet's SIMD-over-rays child test) to ray traversal r's
/// float slab ray (on the geometry boxes' own frame when RT::per_box_f).
template <class RT>
__attribute__((always_inline)) inline void set_packet_lane(simd::SlabPacketF& lanes, const RT& r, unsigned i) {
  const simd::SlabRayF& f = RT::per_box_f ? r.sr_box : r.sr;
  for (int a = 0; a < 3; ++a) {
    lanes.o_plus[a][i] = f.o_plus[a];
    lanes.o_minus[a][i] = f.o_minus[a];
    lanes.inv_d[a][i] = f.inv_d[a];
  }
  lanes.t_lo[i] = f.t_lo;
  lanes.t_hi[i] = f.t_hi;
}

/// first_hit_packet's child test policy: true (and `lanes` filled: one lane per ray of `mask`,
/// the others a ray that hits nothing) when the children are tested SIMD over the rays
/// (packet_child_slab: one lane per ray, each child box broadcast), which needs every ray's slab
/// result final (orders time / sphere_hit, no planes) and float-testable; false: each ray's own
/// test_children (SIMD over the children).
template <class RT, class K, SpatialIndex I>
__attribute__((always_inline)) inline bool packet_lanes_over_rays([[maybe_unused]] const KernelsOf<K>& kern,
                                                                  RT* const* st, [[maybe_unused]] std::uint32_t mask,
                                                                  [[maybe_unused]] simd::SlabPacketF& lanes) {
  if constexpr (FloatChildBoxes<I>) {
    // (Only the prepared rays, those in the root's mask, count and get a lane; no other ray is
    // ever in a stack entry's mask.)
    bool over_rays = has_kernel(kern.packet_child_slab);
    for (std::uint32_t m = mask; m; m &= m - 1) {
      const RT& r = *st[__builtin_ctz(m)];
      over_rays = over_rays && r.slab_is_final && r.simd_children && r.pad < kInf;
    }
    if (!over_rays) return false;
    for (unsigned i = 0; i < 16; ++i) {  // unused lanes: a ray that hits nothing (t_lo > t_hi)
      for (int a = 0; a < 3; ++a) lanes.o_plus[a][i] = lanes.o_minus[a][i] = lanes.inv_d[a][i] = 0.0f;
      lanes.t_lo[i] = 1.0f;
      lanes.t_hi[i] = 0.0f;
    }
    for (std::uint32_t m = mask; m; m &= m - 1) {
      const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
      set_packet_lane(lanes, *st[i], i);
    }
    return true;
  }
  return false;
}

/// first_hit_packet's leaf test policy: true (and `f` filled: lane i of each ray of `mask`, the
/// other lanes a filter nothing passes) when a node's points may be filtered SIMD over the rays
/// (packet_point_filter), which needs every ray's point filter plain (no per-point radii or
/// normals, no per-node radius: those change the filter per point or per node); false: each ray
/// filters the points alone (RayTraversal::eval_points).
template <class RT, class K>
__attribute__((always_inline)) inline bool packet_leaf_over_rays([[maybe_unused]] const KernelsOf<K>& kern,
                                                                 RT* const* st, std::uint32_t mask,
                                                                 simd::PointFilterPacketD& f) {
  if (RT::per_node || !has_kernel(kern.packet_point_filter)) return false;
  for (std::uint32_t m = mask; m; m &= m - 1) {
    const RT& r = *st[__builtin_ctz(m)];
    if (r.radii_filter || r.normals_filter) return false;
  }
  for (unsigned i = 0; i < 16; ++i) {  // lanes without a ray: t_lo > t_hi (never read into a mask)
    for (int a = 0; a < 3; ++a) f.o[a][i] = f.d[a][i] = 0.0;
    f.d2_max[i] = 0.0;
    f.t_lo[i] = 1.0;
    f.t_hi[i] = 0.0;
  }
  for (std::uint32_t m = mask; m; m &= m - 1) st[__builtin_ctz(m)]->set_filter_lane(f, __builtin_ctz(m));
  return true;
}

/// Whether the leaf test over the rays (packet_point_filter of kernel policy K) pays for the rays
/// `act`: the kernel computes every lane of each group of W rays (W = 8 on AVX-512, 4 else) that
/// holds one of them, each ray alone costs about twice a lane, so it pays when at least half of
/// the computed lanes are rays of `act`.
template <class K>
__attribute__((always_inline)) inline bool packet_leaf_pays(const KernelsOf<K>& kern, std::uint32_t act) {
  const unsigned w = kern.path == SimdPath::avx512 ? 8u : 4u;
  unsigned groups = 0;
  for (unsigned l = 0; l < 16; l += w) groups += ((act >> l) & ((1u << w) - 1u)) != 0;
  return 2u * static_cast<unsigned>(__builtin_popcount(act)) >= groups * w;
}

/// The points of a node (slots `range`) for the rays `act` (at least two), SIMD over the rays:
/// the packet filter (lanes f, packet_leaf_over_rays) and then each survivor's exact test for each
/// ray that kept it (RayTraversal::eval_slot), in slot order per ray as eval_points. The caller
/// refreshes the lanes of the rays whose bound moved.
template <class RT, class K>
__attribute__((always_inline)) inline void packet_eval_points(const KernelsOf<K>& kern, RT* const* st,
                                                              std::uint32_t act, SlotRange range,
                                                              const simd::PointFilterPacketD& f) {
  const RT& r0 = *st[__builtin_ctz(act)];
  auto& scratch = r0.scratch;
  if (r0.stats) {
    const unsigned nr = static_cast<unsigned>(__builtin_popcount(act));
    r0.stats->nodes_visited += nr;
    r0.stats->points_tested += std::uint64_t{nr} * range.size();
  }
  auto& sel = scratch.sel;
  auto& rays = scratch.sel_rays;
  if (sel.size() < range.size()) sel.resize(range.size());
  if (rays.size() < range.size()) rays.resize(range.size());
  const double* xyz = position_block(r0.pos, range.begin, range.size(), scratch.block);
  const unsigned n = kern.packet_point_filter(xyz, range.size(), f, act, sel.data(), rays.data());
  for (unsigned j = 0; j < n; ++j) {
    const double* p = xyz + 3 * std::size_t{sel[j]};
    const Vec3 pv(p[0], p[1], p[2]);
    for (std::uint32_t m = rays[j]; m; m &= m - 1) {
      RT& r = *st[__builtin_ctz(m)];
      if (!r.done) r.eval_slot(range.begin + sel[j], pv, false);
    }
  }
}

/// The rays of lanes [0, N) whose bound lb[i] is not above bound[i] (RayTraversal::live with
/// bound[i] = worst + tol, as a mask; a NaN bound counts as live, as there). Written lane by lane
/// over the whole packet so that it compiles to vector compares.
template <unsigned N, class K>
__attribute__((always_inline)) inline std::uint32_t lanes_live(const double* lb, const double* bound) {
  if constexpr (N == 16 && requires { K::lanes_not_above16; }) {
    return K::lanes_not_above16(lb, bound);
  } else {
    std::uint32_t m = 0;
    for (unsigned i = 0; i < N; ++i) m |= static_cast<std::uint32_t>(!(lb[i] > bound[i])) << i;
    return m;
  }
}

/// The least v[i] over the lanes i < N of `mask` (+inf for none; any order of the minima: it
/// only orders the children's pushes).
template <unsigned N, class K>
__attribute__((always_inline)) inline double masked_min(const double* v, std::uint32_t mask) {
  if constexpr (N == 16 && requires { K::masked_min16; }) {
    return K::masked_min16(v, mask);
  } else {
    double r = kInf;
    for (unsigned i = 0; i < N; ++i) r = std::min(r, (mask >> i) & 1u ? v[i] : kInf);
    return r;
  }
}

/// The child hits of a packet node: for the nc <= 8 children of `node` and the live rays `act`,
/// cm[c] = the rays whose node test enters child c, lbc[c][i] = ray i's lower bound of it;
/// returns the mask of children entered by any ray. SIMD over the rays when over_rays (the lanes
/// of packet_lanes_over_rays), else each ray's test_children.
/// `bound`: each ray's live() bound (worst + tol; first_hit_packet keeps them per lane).
template <unsigned N, class RT, class K, SpatialIndex I>
__attribute__((always_inline)) inline std::uint32_t packet_test_children(
    const I& index, [[maybe_unused]] const KernelsOf<K>& kern, const RayQuery& q, RT* const* st,
    typename I::Node node, unsigned nc, std::uint32_t act, [[maybe_unused]] bool over_rays,
    [[maybe_unused]] const simd::SlabPacketF& lanes, [[maybe_unused]] const double* bound, std::uint32_t* cm,
    double (*lbc)[N]) {
  std::uint32_t any = 0;
  for (unsigned c = 0; c < nc; ++c) cm[c] = 0;
  if constexpr (FloatChildBoxes<I>) {
    if (over_rays) {
      std::uint32_t hits[8];
      alignas(64) float entry[8 * 16];
      if constexpr (RT::per_box_f)
        kern.packet_child_slab(st[__builtin_ctz(act)]->key_policy.child_boxes_f_of(node), lanes, N, hits, entry);
      else
        kern.packet_child_slab(index.child_boxes_f(node), lanes, N, hits, entry);
      // Every lane's bound (as test_children: the entry raised to t_min) and live() at once; the
      // lanes outside a child's rays hold values nothing reads.
      for (unsigned c = 0; c < nc; ++c) {
        if (!(hits[c] & act)) continue;
        for (unsigned i = 0; i < N; ++i) lbc[c][i] = std::max(static_cast<double>(entry[16 * c + i]), q.t_min);
        cm[c] = hits[c] & act & lanes_live<N, K>(lbc[c], bound);
        any |= static_cast<std::uint32_t>(cm[c] != 0) << c;
      }
      return any;
    }
  }
  double lbs[8];
  for (std::uint32_t m = act; m; m &= m - 1) {
    const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
    for (std::uint32_t h = st[i]->test_children(node, nc, lbs); h; h &= h - 1) {
      const unsigned c = static_cast<unsigned>(__builtin_ctz(h));
      cm[c] |= 1u << i;
      lbc[c][i] = lbs[c];
      any |= 1u << c;
    }
  }
  return any;
}

/// Pushes one entry per child of `node` in `any` (rays cm[c], bounds lbc[c]: every lane copied)
/// onto the stack [0, top) of capacity >= top + 8, far-to-near by the smallest bound of its rays,
/// so that the nearest is popped first; returns the new top.
template <unsigned N, class K, SpatialIndex I>
__attribute__((always_inline)) inline std::size_t push_packet_children(const I& index, typename I::Node node,
                                                                       std::uint32_t any, const std::uint32_t* cm,
                                                                       const double (*lbc)[N],
                                                                       PacketEntry<typename I::Node, N>* stack,
                                                                       std::size_t top) {
  unsigned order[8];
  double key[8];
  unsigned nk = 0;
  for (; any; any &= any - 1) {
    const unsigned c = static_cast<unsigned>(__builtin_ctz(any));
    const double kmin = masked_min<N, K>(lbc[c], cm[c]);
    unsigned j = nk++;
    while (j > 0 && key[j - 1] < kmin) {  // descending by bound
      order[j] = order[j - 1];
      key[j] = key[j - 1];
      --j;
    }
    order[j] = c;
    key[j] = kmin;
  }
  for (unsigned j = 0; j < nk; ++j) {
    PacketEntry<typename I::Node, N>& k = stack[top++];
    k.node = index.child(node, order[j]);
    k.mask = cm[order[j]];
    std::memcpy(k.lb, lbc[order[j]], sizeof k.lb);
  }
  return top;
}

template <unsigned N, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline unsigned first_hit_packet(const I& index, const Ray* rays, unsigned n,
                                                                const RayQuery& q, Candidate* best,
                                                                RayQueryStats* stats, const KeyPolicy* keys) {
  static_assert(N >= 1 && N <= 16);
  using Node = typename I::Node;
  using RT = RayTraversal<true, I, KeyPolicy, K>;
  using Entry = PacketEntry<Node, N>;
  const auto key_of = [keys](unsigned i) -> const KeyPolicy& {
    if constexpr (std::is_same_v<KeyPolicy, OrderKey>) {
      static constexpr OrderKey kKey{};
      return keys ? keys[i] : kKey;
    } else {
      return keys[i];
    }
  };
  thread_local std::vector<Entry> stack;
  // The rays' states in uninitialised storage (an array of std::optional<RT> was zero-filled on
  // every call: 9 KB of memset per 16-ray packet, 11% of a render's instructions under callgrind).
  // (made: the rays whose state was constructed, bit i for st[i].)
  struct States {
    alignas(RT) unsigned char buf[N][sizeof(RT)];
    std::uint32_t made = 0;
    ~States() {
      for (std::uint32_t m = made; m; m &= m - 1) std::launder(reinterpret_cast<RT*>(buf[__builtin_ctz(m)]))->~RT();
    }
  } states;
  RT* st[N];
  Entry root;
  root.node = index.root();
  root.mask = 0;
  const KernelsOf<K> kern = kernels_of<K>();
  // The rays share the thread's scratch, fetched once (a thread_local read per ray costs a guard
  // and, in the per-ISA instances, spills around it: ray_traverse_avx512).
  RayScratch<Node>* const scratch = &ray_scratch<Node>();
  // The root test of every ray at once where the path has the packet kernel (the same test as
  // root_test's ray_box, SIMD over the rays: most of a camera's misses end here).
  std::uint32_t root_in = ~0u;
  bool root_by_packet = false;
  if (has_kernel(kern.packet_ray_box) && root_kernel_applies<K, KeyPolicy>(kern, q)) {
    static_assert(sizeof(Ray) % sizeof(double) == 0);
    const AABB b = index.node_bounds(index.root());
    root_in = kern.packet_ray_box(&b.lo.x, &b.hi.x, &rays[0].origin().x, &rays[0].direction().x,
                                  sizeof(Ray) / sizeof(double), n, q.radius, q.t_min, q.t_max + q.radius);
    root_by_packet = true;
  }
  const RT* prev = nullptr;  // the last ray set up (RayTraversal's sibling)
  for (unsigned i = 0; i < n; ++i) {
    // As ray_traverse: a ray that root_test finds missing is never set up, one that misses the
    // root is never prepared, nor read again.
    if (!((root_in >> i) & 1u)) continue;
    const RootTest rtest = root_by_packet ? RootTest::enter : root_test<K, KeyPolicy>(kern, index, rays[i], q);
    if (rtest == RootTest::miss) continue;
    st[i] = ::new (static_cast<void*>(states.buf[i])) RT(index, rays[i], q, best[i], stats, key_of(i), scratch, prev);
    states.made |= 1u << i;
    prev = st[i];
    if (st[i]->enters_root(rtest, root.lb[i])) {
      st[i]->prepare();
      root.mask |= 1u << i;
    }
  }
  alignas(64) simd::SlabPacketF lanes;
  const bool over_rays = packet_lanes_over_rays<RT, K, I>(kern, st, root.mask, lanes);
  alignas(64) simd::PointFilterPacketD filters;
  const bool leaf_over_rays = root.mask && packet_leaf_over_rays<RT, K>(kern, st, root.mask, filters);
  // Each ray's live() bound (worst + tol: kBest1 is bounded) and the rays that are done (any_hit
  // answered), per lane, so that a popped entry's and a child's live rays are masks of compares.
  alignas(64) double bound[N];
  std::uint32_t done = 0;
  for (unsigned i = 0; i < N; ++i) bound[i] = (root.mask >> i) & 1u ? st[i]->worst + st[i]->tol : kInf;
  // After ray i evaluated points (its bound was `before`): its lanes follow its bound.
  auto follow = [&](unsigned i, double before) __attribute__((always_inline)) {
    const RT& r = *st[i];
    done |= static_cast<std::uint32_t>(r.done) << i;
    if (r.worst == before) return;
    bound[i] = r.worst + r.tol;
    if (leaf_over_rays) r.set_filter_lane(filters, i);
    if constexpr (FloatChildBoxes<I>)
      if (over_rays) set_packet_lane(lanes, r, i);
  };
  alignas(64) double lbc[8][N] = {};  // lbc[c][i]: ray i's bound of child c
  std::uint32_t cm[8];  // cm[c]: the rays that hit child c
  // The node stack: entries [0, top) of the thread's vector, whose size is the capacity (grown
  // before a node's pushes).
  for (unsigned i = 0; i < N; ++i)
    if (!((root.mask >> i) & 1u)) root.lb[i] = 0.0;  // (every lane defined: whole rows are copied)
  if (stack.size() < 64) stack.resize(64);
  std::size_t top = 0;
  if (root.mask) stack[top++] = root;
  while (top > 0) {
    const Entry& e = stack[--top];  // (read before any push overwrites it)
    const Node node = e.node;
    const std::uint32_t act = e.mask & ~done & lanes_live<N, K>(e.lb, bound);
    if (!act) continue;
    if ((act & (act - 1)) == 0) {  // one ray left: diverged, it finishes the subtree alone
      const unsigned i = static_cast<unsigned>(__builtin_ctz(act));
      RT& r = *st[i];
      const double before = r.worst;
      r.traverse_from(node, e.lb[i]);
      follow(i, before);  // (the ray may still be in entries below)
      continue;
    }
    const SlotRange range = index.node_points(node);
    if (range.size() == 0 && !RT::per_node) {
      // No points (the interior nodes of an adaptive octree): nothing for a ray to evaluate, and
      // without per-node radii nothing of it to set for the node (enter_node).
      if (stats) stats->nodes_visited += static_cast<unsigned>(__builtin_popcount(act));
    } else {
      double before[N];
      for (std::uint32_t m = act; m; m &= m - 1) before[__builtin_ctz(m)] = st[__builtin_ctz(m)]->worst;
      if (leaf_over_rays && range.size() >= 4 && packet_leaf_pays<K>(kern, act)) {
        packet_eval_points<RT, K>(kern, st, act, range, filters);
      } else {
        for (std::uint32_t m = act; m; m &= m - 1) {
          RT& r = *st[__builtin_ctz(m)];
          r.enter_node(node);
          r.eval_points(node);
        }
      }
      for (std::uint32_t m = act; m; m &= m - 1) follow(__builtin_ctz(m), before[__builtin_ctz(m)]);
    }
    const unsigned nc = index.child_count(node);
    if (nc == 0) continue;
    if (nc > 8) {  // (no index here has more than 8 children): each ray alone below this node
      for (std::uint32_t m = act & ~done; m; m &= m - 1) {
        RT& r = *st[__builtin_ctz(m)];
        const double was = r.worst;
        for (unsigned c = 0; c < nc; ++c) {
          double lb;
          if (r.test_child(index.child(node, c), lb)) r.traverse_from(index.child(node, c), lb);
        }
        follow(__builtin_ctz(m), was);
      }
      continue;
    }
    if (top + 8 > stack.size()) stack.resize(stack.size() * 2);
    const std::uint32_t any = packet_test_children<N, RT, K>(index, kern, q, st, node, nc, act & ~done, over_rays,
                                                             lanes, bound, cm, lbc);
    top = push_packet_children<N, K>(index, node, any, cm, lbc, stack.data(), top);
  }
  std::uint32_t found = 0;
  for (std::uint32_t m = states.made; m; m &= m - 1)
    if (st[__builtin_ctz(m)]->found) found |= 1u << __builtin_ctz(m);
  return found;
}

/// first_hit_packet with kernel policy K, the 4-, 8- or 16-lane instance by packet size n.
template <class K, SpatialIndex I, class KeyPolicy>
unsigned first_hit_packet_any(const I& index, const Ray* rays, unsigned n,
                                                                    const RayQuery& q, Candidate* best,
                                                                    RayQueryStats* stats, const KeyPolicy* keys) {
  return n <= 4   ? first_hit_packet<4, K>(index, rays, n, q, best, stats, keys)
         : n <= 8 ? first_hit_packet<8, K>(index, rays, n, q, best, stats, keys)
                  : first_hit_packet<kMaxRayPacket, K>(index, rays, n, q, best, stats, keys);
}

#if RAYSCAN_SIMD_X86
/// first_hit_packet compiled for AVX2 + FMA with its kernels inlined (as ray_traverse_avx2), the
/// 16-lane instance for any packet size (one instance per ISA: the packet loop inlines two
/// single-ray loops, and three sizes per ISA tripled the compile time of the renderer; the 4- and
/// 8-lane instances only serve the last rays of a span).
template <SpatialIndex I, class KeyPolicy>
__attribute__((target("avx2,fma"), flatten, noinline)) unsigned first_hit_packet_avx2(
    const I& index, const Ray* rays, unsigned n, const RayQuery& q, Candidate* best, RayQueryStats* stats,
    const KeyPolicy* keys) {
  return first_hit_packet<kMaxRayPacket, simd::Avx2Kernels>(index, rays, n, q, best, stats, keys);
}
/// As first_hit_packet_avx2, for the AVX-512 path (F + VL).
template <SpatialIndex I, class KeyPolicy>
__attribute__((target("avx512f,avx512vl,avx2,fma"), flatten, noinline)) unsigned first_hit_packet_avx512(
    const I& index, const Ray* rays, unsigned n, const RayQuery& q, Candidate* best, RayQueryStats* stats,
    const KeyPolicy* keys) {
  return first_hit_packet<kMaxRayPacket, simd::Avx512Kernels>(index, rays, n, q, best, stats, keys);
}
#endif

/// first_hit_packet_any on SIMD path `path` (simd_path()): where kIsaInstances, the instance
/// compiled for its instruction set, else the one calling its kernels through simd::Kernels.
template <SpatialIndex I, class KeyPolicy>
unsigned first_hit_packet_on(SimdPath path, const I& index, const Ray* rays, unsigned n, const RayQuery& q,
                             Candidate* best, RayQueryStats* stats, const KeyPolicy* keys) {
#if RAYSCAN_SIMD_X86
  if constexpr (kIsaInstances<I, KeyPolicy>) {
    if (path == SimdPath::avx2) return first_hit_packet_avx2(index, rays, n, q, best, stats, keys);
    if (path == SimdPath::avx512) return first_hit_packet_avx512(index, rays, n, q, best, stats, keys);
  }
#endif
  (void)path;
  return first_hit_packet_any<simd::Kernels>(index, rays, n, q, best, stats, keys);
}

/// Runs first_hit_packet over `rays` in blocks of kMaxRayPacket consecutive rays (the 4-, 8- or
/// 16-lane instance by block size; on FloatChildBoxes indexes the instance compiled for the
/// active SIMD path where kIsaInstances, as ray_traverse) and calls emit(b, n, best, found) for each block: rays
/// [b, b + n), bit i of `found` set when ray b + i has its answer in best[i].
/// `keys`: as first_hit_packet's, one per ray of `rays` (nullptr only with OrderKey).
template <SpatialIndex I, class Emit, class KeyPolicy = OrderKey>
void for_each_ray_packet(const I& index, std::span<const Ray> rays, const RayQuery& q, RayQueryStats* stats,
                         Emit&& emit, const KeyPolicy* keys = nullptr) {
  const SimdPath path = simd::active_kernels().path;
  for (std::size_t b = 0; b < rays.size(); b += kMaxRayPacket) {
    const unsigned n = static_cast<unsigned>(std::min(kMaxRayPacket, rays.size() - b));
    const KeyPolicy* k = keys ? keys + b : nullptr;
    Candidate best[kMaxRayPacket];
    const std::uint32_t found = first_hit_packet_on(path, index, rays.data() + b, n, q, best, stats, k);
    emit(b, n, static_cast<const Candidate*>(best), found);
  }
}

}  // namespace rayscan::detail
