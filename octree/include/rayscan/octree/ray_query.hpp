// The ray query of the paper (Teuscher et al., "Ray Queries On Raw Point Clouds", Algorithm 1 and
// sections 3.1-3.3), written once against the SpatialIndex concept: the public entry points. The
// types are in ray_query_types.hpp. The traversal (RayTraversal, the per-ISA instances, the
// packets) is the library's implementation, in its private headers (octree/src/include:
// detail/ray_query_impl.hpp and the ray_* and simd_kernels* headers beside it); these templates
// are compiled once per index type of the library (Octree, KdTree, BruteForceIndex in
// rayscan::octree, io::MappedIndex and io::CopcIndex in rayscan::site: RAYSCAN_RAY_QUERY_INSTANCES
// below). For another SpatialIndex type, use the generic walks of traverse.hpp (depth_first).
#pragma once

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/kdtree.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query_types.hpp"
#include "rayscan/octree/traverse.hpp"

#include <optional>
#include <span>
#include <vector>

namespace rayscan {

/// Ray query (paper Algorithm 1) over any SpatialIndex; results are appended to `out` (cleared
/// first), sorted by (key, original index) ascending.
///
/// Semantics: a point p with terms (t_p, d) is a candidate when d <= radius, every plane gives
/// dist_plane <= 0, and its t lies in [t_min, t_max], where t = t_p for orders ray/time and
/// t = sphere_entry(t_p, d^2, radius) for sphere_hit. The k smallest candidates by key are kept.
///
/// Pruning (section 3.3): a node is skipped when its minimum distance to the ray segment exceeds
/// the radius (exact distance or eq. 3, see NodeDistance), when its projected time interval (eq. 4,
/// or the slab interval of the box grown by r, which is tighter) misses [t_min, t_max], when a plane
/// has the whole box on its positive side, and, once k candidates are held, when its lower bound on
/// the key exceeds the worst kept key (dynamic k filter: it tightens r for order ray, t_max for
/// orders time and sphere_hit). With k set, the traversal is depth-first with each node's children
/// visited nearest lower bound first, so the k filter tightens early, and every node whose lower
/// bound exceeds the current k-bound is skipped when it is popped (a global best-first heap was
/// measured slower for the k = 1 queries a renderer issues); without k, a plain depth-first stack
/// is used. Bounds carry a rounding allowance (node_test_tolerance: relative to the geometry and
/// to the coordinates' magnitude) so rounding never prunes a qualifying point.
///
/// SIMD: on the active simd_path(), an index with FloatChildBoxes tests all children
/// of a node at once on their float boxes (slabs grown by a margin that covers every float rounding,
/// so no box holding a qualifying point is rejected), and each node's points go through a SIMD
/// filter with widened bounds before the exact scalar test. Both are policies of this one traversal
/// and only filter: every answer is bit-identical to the scalar path (RAYSCAN_SIMD=scalar).
/// With k = 1 the candidates go to a single best candidate instead of the k-heap (same answer;
/// ray_first_hit is that query without a result vector or per-query validation).
///
/// Point-key policy (OrderKey, RefinedKey): with RefinedKey, each candidate's key is the policy's
/// refinement of the order key (k filter, ordering, any_hit acceptance and RayHit::key use it;
/// RayHit::t stays the order's t); its optional early rejection by slot and node bounds are
/// described at RefinedKey.
///
/// Throws std::invalid_argument (from RayQuery::validate) for inconsistent parameters.
/// Thread-safe (per-thread scratch, shared with knn_query: a key policy must not query on its thread).
template <SpatialIndex I, class KeyPolicy = OrderKey>
void ray_query(const I& index, const Ray& ray, const RayQuery& q, std::vector<RayHit>& out,
               RayQueryStats* stats = nullptr, const KeyPolicy& key_policy = {});

/// First hit: the result ray_query(index, ray, q) gives with q.k = 1 (whatever q.k says), without a
/// result vector; nullopt when nothing qualifies. For renderers (cf. Embree's rtcIntersect1).
/// `q` must have been checked with q.validate() (once per batch: this hot path does not validate;
/// an unchecked invalid query gives an unspecified answer, never undefined behaviour).
template <SpatialIndex I>
[[nodiscard]] std::optional<RayHit> ray_first_hit(const I& index, const Ray& ray, const RayQuery& q,
                                                  RayQueryStats* stats = nullptr);

/// Sets the entry-point search for the whole process (default EntryPointSearch::automatic): on an
/// index with an entry grid (Octree and MappedIndex: entry_grid), the first hits of orders time
/// and sphere_hit without planes (ray_first_hit, ray_first_hit_each, ray_query with k = 1) start a
/// ray at the node of the grid cell where it enters and go up only as far as a point outside that
/// cell could still be hit first (Havran's entry-point search), and knn_query starts at the node
/// of q's cell (point_query.hpp). Answers are the same in every setting (with q.any_hit, which
/// qualifying point is returned may differ, as any_hit allows; RayQueryStats differ); for
/// benchmarks and tests that compare them in one process. Thread-safe.
void set_entry_point_search(EntryPointSearch mode);
/// set_entry_point_search(on ? EntryPointSearch::automatic : EntryPointSearch::off).
void set_entry_point_search(bool on);

/// Whether ray_first_hit_each traces its rays two at a time with their traversals interleaved
/// (true) or one by one (false). Off by default (interleaved_pairs_default): measured against
/// single rays in one process (`bench_rays`' `ray_first_hit_each` row, `bench_render --pairs
/// both`), the pairs lose on every CPU family tried with the entry-point search on: Zen 5 (the
/// renderer 0.90x), Zen 4 (0.82-0.84x; the renderer 10-15% slower) and Intel Xeons (0.89-0.96x on a
/// 16-core Sapphire-Rapids class Xeon at 1 to 16 threads, 0.80-1.0x on a 2-core one)
/// (bench/notes/2026-11-28-pairs-by-cpu-family.md, bench/notes/2026-11-28-pairs-off-on-zen-4.md,
/// bench/notes/2026-11-29-pairs-off-on-zen-5.md). Answers are the same either way.
/// Thread-safe.
[[nodiscard]] bool interleaved_pairs();
/// Sets interleaved_pairs() for the whole process (benchmarks compare both in one process).
/// Thread-safe.
void set_interleaved_pairs(bool on);
/// interleaved_pairs()'s default on this CPU: false on every CPU measured (above); a per-family
/// choice (simd::amd_cpu_family) belongs here if a CPU is measured to gain from the pairs.
[[nodiscard]] bool interleaved_pairs_default();

/// First hits of a batch of rays: out[i] = ray_first_hit(index, rays[i], q, stats) for every i,
/// bit for bit. Where interleaved_pairs() (set by a caller; off by default) the rays are traced two
/// at a time, their traversals interleaved node by node (detail::first_hit_pair: two independent
/// chains for the core's idle slots), else one by one. The batch form of ray_first_hit for callers with many rays
/// (ray_query_each, the renderer's wavefronts, bench_rays). `stats` (optional) sums the work
/// counters. As ray_first_hit, `q` must have been validated. Throws std::invalid_argument when
/// out.size() != rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_first_hit_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                        std::span<std::optional<RayHit>> out, RayQueryStats* stats = nullptr);

/// Packet first hit (coherent rays): out[i] = ray_first_hit(index, rays[i], q) for
/// every i, bit for bit, computed for up to kMaxRayPacket rays at a time with one traversal that
/// shares the node stack and visits of the rays (detail::first_hit_packet): meant for coherent
/// rays such as the camera rays of a 2x2 or 4x4 pixel tile (cf. Embree's rtcIntersect4/8/16 and
/// Wald et al., "Interactive Rendering with Coherent Ray Tracing", 2001). Incoherent rays still
/// get the right answers (the packet splits into single rays where it diverges), only slower.
/// Longer spans are answered in packets of kMaxRayPacket consecutive rays. With q.any_hit the
/// answer depends on the visiting order, so each ray runs ray_first_hit alone.
/// `q` must have been checked with q.validate(), as for ray_first_hit. Throws std::invalid_argument
/// when out.size() != rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_first_hit_packet(const I& index, std::span<const Ray> rays, const RayQuery& q,
                          std::span<std::optional<RayHit>> out, RayQueryStats* stats = nullptr);

/// Packet any hit (shadow rays, coherent rays): out[i] = ray_first_hit(index, rays[i],
/// q).has_value() for every i: whether anything qualifies along the ray. With q.any_hit each ray
/// stops at its first candidate in the packet's visiting order and drops out of the packet (cf.
/// Embree's rtcOccluded4/8/16); the answer is the same whatever that order, as pruning is
/// conservative and an any_hit query never tightens the k-bound. Shares detail::first_hit_packet
/// with ray_first_hit_packet. `q` must have been checked with q.validate(). Throws
/// std::invalid_argument when out.size() != rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_any_hit_packet(const I& index, std::span<const Ray> rays, const RayQuery& q, std::span<bool> out,
                        RayQueryStats* stats = nullptr);

/// out[i] = ray_query(index, rays[i], q) for every i, bit for bit: with q.k == 1 through
/// ray_first_hit_each (interleaved pairs where the CPU gains from them, interleaved_pairs(); 16-ray
/// packets of consecutive rays had been 0.88-0.91x of single rays: bench/notes/), other queries
/// ray by ray. The batch form for callers that pass whole
/// ray sets (ray_query_batch: the Python module, `rayscan query`; the renderer traces its camera
/// wavefronts as packets, ray_first_hit_packet). `stats` (optional) sums the work counters.
/// Throws std::invalid_argument for an invalid q (RayQuery::validate) or out.size() !=
/// rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_query_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                    std::span<std::vector<RayHit>> out, RayQueryStats* stats = nullptr);

/// Whether ray_first_hit_packet pays for these rays: they share one origin (bit for bit) and every
/// direction lies within 2 degrees of the first one's: the rays of a pinhole camera's neighbouring
/// pixels or of one observer. Measured (`bench_rays --coherence`, 1e6 / 1e7 uniform points, 16
/// rays sharing an origin, bench/notes/): packets take 0.70 / 0.78x the
/// time of single rays for a 1-degree cone, 0.78 / 0.89x for 2 degrees, 0.90 / 1.00x for 4 and
/// 1.03-1.05x beyond; random rays 2.4-2.5x. (Two rays of an accepted span may lie up to 4 degrees
/// apart, each within 2 of the first.) False for fewer than two rays.
[[nodiscard]] inline bool packet_coherent(std::span<const Ray> rays) {
  if (rays.size() < 2) return false;
  constexpr double kCos2Deg = 0.99939082701909573;  // cos(2 degrees)
  const Vec3& o = rays[0].origin();
  const Vec3& d = rays[0].direction();
  for (const Ray& r : rays.subspan(1))
    if (r.origin() != o || !(glm::dot(r.direction(), d) >= kCos2Deg)) return false;
  return true;
}

/// Convenience overload of ray_query returning a new vector; see ray_query above.
template <SpatialIndex I>
[[nodiscard]] std::vector<RayHit> ray_query(const I& index, const Ray& ray, const RayQuery& q,
                                            RayQueryStats* stats = nullptr) {
  std::vector<RayHit> out;
  ray_query(index, ray, q, out, stats);
  return out;
}

/// Convex "frustum" query (paper section 3.1, "Time Range"): every point with
/// dist_plane(plane.point, plane.normal, p) <= 0 for all planes, as original indices in ascending
/// order. No ray is needed; a depth_first walk (traverse.hpp) whose node test prunes with
/// dist_plane_bounds.
template <SpatialIndex I>
[[nodiscard]] std::vector<PointIndex> frustum_query(const I& index, std::span<const Plane> planes) {
  std::vector<PointIndex> out;
  if (index.empty()) return out;
  for (const Plane& pl : planes) {
    const double len = glm::length(pl.normal);
    if (!(len > 0) || !std::isfinite(len) || !std::isfinite(glm::length(pl.point)))
      throw std::invalid_argument("frustum_query: plane normal must be non-zero and finite");
  }
  const AABB root_box = index.node_bounds(index.root());
  const double tol = 1e-9 * (root_box.max_extent() + glm::length(root_box.center())) + 1e-300;
  const auto pos = index.positions();
  const IdView ids = index.ids();
  using Node = typename I::Node;
  depth_first(
      index,
      [&](Node n) {
        const AABB b = index.node_bounds(n);
        for (const Plane& pl : planes)
          if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) return Enter::no;
        return Enter::yes;
      },
      [&](const NodeVisit<Node>& v) {
        for (std::uint32_t s = v.slots.begin; s < v.slots.end; ++s) {
          bool inside = true;
          for (const Plane& pl : planes)
            if (dist_plane(pl.point, pl.normal, pos[s]) > 0.0) { inside = false; break; }
          if (inside) out.push_back(ids[s]);
        }
      });
  std::sort(out.begin(), out.end());
  return out;
}

/// Declares (KW = `extern template`) or defines (KW = `template`) the ray query's entry points for
/// index type I (plain keys, OrderKey): ray_query, ray_first_hit, ray_first_hit_each,
/// ray_first_hit_packet, ray_any_hit_packet and ray_query_each. Used inside namespace rayscan:
/// the headers of the library's indexes declare them extern (here, any_index.hpp, site's
/// index_file.hpp and copc.hpp) and their libraries define them once
/// (octree/src/query/ray_query.cpp, site/src/query_instances.cpp), where the traversal's
/// definitions are.
#define RAYSCAN_RAY_QUERY_INSTANCES(KW, I)                                                                   \
  KW void ray_query<I, OrderKey>(const I&, const Ray&, const RayQuery&, std::vector<RayHit>&, RayQueryStats*, \
                                 const OrderKey&);                                                          \
  KW std::optional<RayHit> ray_first_hit<I>(const I&, const Ray&, const RayQuery&, RayQueryStats*);         \
  KW void ray_first_hit_each<I>(const I&, std::span<const Ray>, const RayQuery&,                            \
                                std::span<std::optional<RayHit>>, RayQueryStats*);                         \
  KW void ray_first_hit_packet<I>(const I&, std::span<const Ray>, const RayQuery&,                          \
                                  std::span<std::optional<RayHit>>, RayQueryStats*);                        \
  KW void ray_any_hit_packet<I>(const I&, std::span<const Ray>, const RayQuery&, std::span<bool>,          \
                                RayQueryStats*);                                                            \
  KW void ray_query_each<I>(const I&, std::span<const Ray>, const RayQuery&, std::span<std::vector<RayHit>>, \
                            RayQueryStats*);

RAYSCAN_RAY_QUERY_INSTANCES(extern template, Octree)
RAYSCAN_RAY_QUERY_INSTANCES(extern template, KdTree)
RAYSCAN_RAY_QUERY_INSTANCES(extern template, BruteForceIndex)

}  // namespace rayscan
