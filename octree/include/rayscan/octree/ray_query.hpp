// The ray query of the paper (Teuscher et al., "Ray Queries On Raw Point Clouds", Algorithm 1 and
// sections 3.1-3.3), written once against the SpatialIndex concept.
#pragma once

#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray.hpp"
#include "rayscan/octree/simd.hpp"
#include "rayscan/octree/simd_kernels.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace rayscan {

/// "k not set" (Algorithm 1: k <- inf): return every point that satisfies the other predicates.
inline constexpr std::size_t kAllPoints = std::numeric_limits<std::size_t>::max();

/// The measure a ray query orders (and k-limits) its results by (paper section 3.1).
enum class RayOrder {
  ray,        ///< orthogonal distance to the ray line, eq. 1 ("kNN to the ray")
  time,       ///< t_p of the projection on the ray, eq. 2 with n = d ("kNN along the ray")
  sphere_hit  ///< entry parameter t_p - sqrt(r^2 - d^2) into the sphere of radius r around the
              ///< point: the exact first hit a renderer needs. Requires a finite radius.
};

/// Which node-to-ray minimum distance prunes nodes (paper section 3.3, "Ray Minimum Distance").
enum class NodeDistance {
  exact,  ///< exact box-to-segment distance (segment_box_distance2); tightest pruning
  eq3     ///< the paper's conservative eq. 3 (centre distance minus half diagonal); cheaper, weaker
};

/// A half-space constraint {p : dist_plane(point, normal, p) <= 0} (paper eq. 2/6). A list of them
/// is a convex "frustum" query; the time interval is the special case of two planes with normals
/// -d and +d.
struct Plane {
  Vec3 point;   ///< a point on the plane (world coordinates)
  Vec3 normal;  ///< outward normal (need not be unit); points with positive distance are rejected
};

/// Parameters of a ray query (paper Algorithm 1). Every parameter is optional; the set ones form a
/// logical conjunction (section 3.1).
struct RayQuery {
  std::size_t k = kAllPoints;  ///< at most k results, the k smallest by `order` (kAllPoints = unset)
  double radius = kInf;        ///< keep points with orthogonal distance <= radius (world units)
  double t_min = -kInf;        ///< keep results whose t >= t_min (t: see RayHit::t)
  double t_max = kInf;         ///< keep results whose t <= t_max
  RayOrder order = RayOrder::ray;           ///< ordering measure, see RayOrder
  std::span<const Plane> planes{};          ///< extra half-space constraints (not owned)
  NodeDistance node_distance = NodeDistance::exact;  ///< node pruning bound, see NodeDistance
  /// Occlusion mode: stop at the first candidate the traversal meets and return it alone (it
  /// satisfies every predicate but need not have the smallest key). For shadow rays and
  /// line-of-sight tests that only ask "is anything there?" (cf. Embree's rtcOccluded1).
  bool any_hit = false;

  /// Throws std::invalid_argument when t_min > t_max, a value is NaN, radius < 0, or order is
  /// sphere_hit without a finite radius, or a plane normal is zero or non-finite.
  void validate() const;
};

/// One result of a ray query.
struct RayHit {
  PointIndex index;    ///< the point's index in the caller's original cloud
  std::uint32_t slot;  ///< its slot in the queried index's storage order: index.positions()[slot]
                       ///< is the point and index.ids()[slot] == index (so a caller reads the
                       ///< point or slot-ordered attributes without an id -> slot table)
  double t;          ///< ray parameter: t_p of the projection (orders ray, time) or the sphere
                     ///< entry parameter (order sphere_hit); world units along the unit direction
  double distance;   ///< orthogonal distance of the point to the ray line (eq. 1), not squared
  double key;        ///< the ordering measure: distance (ray) or t (time, sphere_hit)
};

/// Work counters of one query: the "query cost" a renderer shows as an AOV.
/// (The counts depend on the SIMD path, not the answers: the float child tests and the first hit's
/// root kernel (detail::root_test) are conservative, so they may let in a node the exact double
/// test would prune.)
struct RayQueryStats {
  std::uint64_t nodes_visited = 0;  ///< nodes whose points were evaluated
  std::uint64_t points_tested = 0;  ///< point predicates evaluated
};

/// Projection terms of point p on a ray (o, unit d): t_p = d.(p - o) (eq. 2 with n = d) and the
/// squared orthogonal distance |(p - o) - t_p d|^2 (eq. 1 squared). Every index and the tests use
/// this one function, so their per-point values agree to the bit.
struct RayPointTerms {
  double t;   ///< t_p
  double d2;  ///< squared orthogonal distance
};
[[nodiscard]] inline RayPointTerms ray_point_terms(const Vec3& o, const Vec3& d, const Vec3& p) {
  const Vec3 v = p - o;
  const double t = glm::dot(v, d);
  const Vec3 w = v - t * d;
  return {t, glm::dot(w, w)};
}

/// Entry parameter of the ray into the sphere of radius r around a point with terms (t, d2), for
/// d2 <= r^2: t - sqrt(r^2 - d2) (the near root of the ray/sphere quadratic, written in the
/// numerically stable projected form; cf. pbrt-v4 section 6.2.2 and RTIOW section 6).
[[nodiscard]] inline double sphere_entry(double t, double d2, double r) {
  return t - std::sqrt(std::max(0.0, r * r - d2));
}

namespace detail {

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

/// Reusable per-thread scratch so that a query allocates nothing once warm.
template <class Node>
struct RayScratch {
  // The node stack: entries [0, top) (traverse_from); the vector only grows, so that a push
  // needs no capacity test of its own (one per node, for all of its children).
  std::vector<NodeEntry<Node>> nodes;
  std::size_t top = 0;
  std::vector<Candidate> cands;
  std::vector<std::uint32_t> sel;  // survivors of the SIMD point filter (local slot offsets)
  std::vector<Vec3> block;         // a leaf's positions decoded for the filter (compact encodings)
};

/// An index that exposes its children's float boxes for the SIMD child test (simd.hpp): the optional
/// extension of SpatialIndex (Octree, io::MappedIndex, io::CopcIndex; others: the scalar node test).
template <class I>
concept FloatChildBoxes = requires(const I& idx, typename I::Node n) {
  { idx.child_boxes_f(n) } -> std::convertible_to<simd::ChildBoxesF>;
  { idx.float_origin() } -> std::convertible_to<Vec3>;
  { idx.float_extent() } -> std::convertible_to<double>;
};

/// Rounds x to float towards -inf (down) or +inf (up): infinities are kept, finite values past
/// the float range go to -inf / FLT_MAX (down) and -FLT_MAX / +inf (up), NaN stays NaN.
/// Branch-free: the nearest float, stepped one unit in its IEEE bits (the magnitude up or down by
/// the sign bit) when it lies on the wrong side of x (a branch on that mispredicted about once per
/// camera hit: bench/notes/). A nonzero x's nearest float keeps x's sign,
/// so a +0 only ever steps up to denorm_min and a -0 only down to -denorm_min: the bit step holds.
inline float round_float_down(double x) {
  const float f = static_cast<float>(x);
  const std::uint32_t b = std::bit_cast<std::uint32_t>(f);
  const std::uint32_t wrong = 0u - static_cast<std::uint32_t>(static_cast<double>(f) > x);  // all ones or 0
  return std::bit_cast<float>(b + (wrong & (((b >> 31) << 1) - 1u)));  // negative: +1, else -1
}
inline float round_float_up(double x) {
  const float f = static_cast<float>(x);
  const std::uint32_t b = std::bit_cast<std::uint32_t>(f);
  const std::uint32_t wrong = 0u - static_cast<std::uint32_t>(static_cast<double>(f) < x);
  return std::bit_cast<float>(b + (wrong & (1u - ((b >> 31) << 1))));  // negative: -1, else +1
}

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

}  // namespace detail

/// The default point-key policy of ray_query: a candidate's key is the order's measure.
struct OrderKey {
  static constexpr bool refines = false;
  static constexpr bool node_radius = false;
  static constexpr bool node_box = false;
  static constexpr bool child_boxes_f = false;
};

/// "No per-node radius" (the query radius bounds every node): see RefinedKey.
struct NoNodeRadius {};
/// "No per-node geometry box" (each node's box grown by its radius): see RefinedKey.
struct NoNodeBox {};
/// "No float copy of the per-node geometry boxes" (scalar child test of node_box): see RefinedKey.
struct NoChildBoxesF {};

/// A point-key policy refines the key of each candidate that passed the query's predicates:
/// `key(id, t_p, d2, base)` receives the point's original index, its projection terms and its
/// order key `base`, and returns a key >= base (kInf rejects the point). Because the refined key
/// is never below the base key, every node lower bound of the traversal stays a lower bound, so
/// the k smallest refined keys are found exactly. Used for geometry inside the query radius whose
/// exact hit is known per point: the oriented discs of surfel rendering (the refined key is the
/// disc hit parameter, >= the entry into the sphere of radius `radius` that contains the disc).
///
/// Optionally (orders time and sphere_hit only) the policy bounds, per node, how far the geometry
/// of the points of the node's subtree reaches: `node_radius(n)` (world units) is >= the distance
/// from every point p of n's subtree to the ray point at p's finite refined key. The traversal then
/// grows each node's box by its own bound instead of the query radius (a tube as thin as the local
/// geometry; cf. the per-node radius bounds of a BVH over spheres of varying radii), which keeps
/// every node lower bound a lower bound of the refined keys inside it, so the answer is unchanged.
///
/// Optionally too (with node_radius), `node_box(n)` (AABB, world coordinates) holds the ray point
/// at the finite refined key of every point of n's subtree, whatever the ray: the bounding box of
/// the geometry itself (e.g. of oriented discs, thin across a flat surface where the radius pad is
/// not). The exact node test of a child is then the slab test of that box, without pad, whose entry
/// is the child's lower bound (still a lower bound of the refined keys); the radius bounds the SIMD
/// prefilter of the children and the points (cf. a BVH over the primitives' own bounds).
///
/// The key functor may also have a member `bool reject(std::uint32_t slot, double d2)`: a cheap
/// test by storage slot and squared ray distance, called before the order key is computed, that
/// returns true only for points whose refined key would be kInf (e.g. a per-slot copy of each
/// disc's radius: d2 > r^2). With a member `const float* filter_radii()` returning the same radii by
/// storage slot (one float per slot of the index, world units; or null), the SIMD point filter
/// applies that test too (simd::PointFilterD::radii), so the rejected points never reach the
/// scalar loop (nor reject() again). These radii must bound each point's whole geometry (a ball of
/// radius r around it: a finite refined key is >= t_p - r), so that with key_min below the filter
/// also drops the points whose t_p lies more than their own radius before it.
///
/// The key functor may also have a member `double exact_key(std::uint32_t slot, PointIndex id,
/// const Vec3& p)`: the refined key of point `id` (at storage slot `slot`, p its position in the
/// index, bit for bit) decided from the point alone (an exact geometric test, e.g. the ray-disc test),
/// finite only where the query's own predicates hold too, up to rounding (the point within
/// `radius` of the ray, its sphere key in [t_min, t_max] and <= the refined key: true of a disc
/// of radius <= `radius` around the point whose hit lies in [t_min + 2 radius, t_max], as
/// DiscKey's). Queries of order sphere_hit without planes then call it instead of key() and skip
/// those predicates and the projection terms, which they compute only for the points they keep
/// (RayHit::t, distance). Only the node lower bounds need to stay below the refined keys, so a
/// point that a predicate would have dropped by a rounding (a disc hit at its rim) is answered by
/// its exact key, as a brute-force loop over the exact test answers it.
///
/// With filter_radii and key_min (below), a member `const float* filter_normals()` (3 floats per
/// storage slot, a unit normal; or null) declares the refined key a ray-disc hit: finite only
/// where the ray crosses the plane through the point with that normal at some t in [key_min(),
/// the query's t_max] within the point's radius of it, and then equal to that t. The SIMD point
/// filter then drops the points whose disc the ray provably misses in [key_min(), min(t_max, the
/// k-bound)] (simd::PointFilterD::normals), so they never reach the exact test.
///
/// With node_box, the key functor may also have a member `double key_min()`: a lower bound of every
/// finite refined key (e.g. the t_min of a disc test, where the query's t_min lies far below it so
/// that the base keys pass). The geometry boxes are then cut at it (a box behind it holds no hit),
/// and the SIMD point filter at it less the query radius, which therefore must bound the reach of
/// each point's geometry (as the sphere keys of order sphere_hit already assume).
///
/// Optionally too (with node_box, on FloatChildBoxes indexes), `child_boxes_f(n)`
/// (simd::ChildBoxesF) gives the node_box of each of n's children in float, relative to the
/// index's float_origin() and rounded outwards (each float box contains the double one): the
/// children are then tested all at once by the SIMD slab kernel on these boxes, without pad, and
/// its result is final (no scalar re-test, no per-node float constants: the slabs are the ray's
/// own, set once per ray and when its t_far shrinks). The entry the kernel returns is a lower bound
/// of the double box's entry, so every node lower bound stays a lower bound.
template <class F, class G = NoNodeRadius, class B = NoNodeBox, class C = NoChildBoxesF>
struct RefinedKey {
  static constexpr bool refines = true;
  static constexpr bool node_radius = !std::is_same_v<G, NoNodeRadius>;
  static constexpr bool node_box = !std::is_same_v<B, NoNodeBox>;
  static constexpr bool child_boxes_f = !std::is_same_v<C, NoChildBoxesF>;
  static_assert(node_radius || !node_box, "RefinedKey: a per-node box needs the per-node radius");
  static_assert(node_box || !child_boxes_f, "RefinedKey: float child boxes need the per-node box");
  F key;              ///< double(PointIndex id, double t_p, double d2, double base)
  G node_radius_of{};  ///< double(Node n): the bound above (NoNodeRadius: none)
  B node_box_of{};     ///< AABB(Node n): the box above (NoNodeBox: none)
  C child_boxes_f_of{};  ///< simd::ChildBoxesF(Node n): the float boxes above (NoChildBoxesF: none)
};

namespace detail {

/// The one traversal of the ray query (see ray_query for the semantics), as the per-ray state and
/// its policies: the node test (test_node, and test_children: all children of a node at once, SIMD
/// on FloatChildBoxes indexes), the leaf work (eval_points: SIMD filter + exact double test) and
/// the candidate sink (push_candidate with the dynamic k filter), plus the depth-first loop
/// (traverse_from, in steps of one node: step). ray_traverse runs the loop from the root for one
/// ray; first_hit_pair steps two rays' loops in turn; the packet first hit (first_hit_packet)
/// drives several of these states down one shared stack and hands a subtree to traverse_from when
/// the packet diverges, so all use the same node test and leaf work.
///
/// Candidates go to the per-thread k-heap (scratch.cands) or, with kBest1 (k = 1: the first hit of
/// a renderer), to `best` alone: no heap and no vector (a compile-time policy, not a copy).
/// Expects a validated query, a non-empty index and k >= 1. `key_policy`: OrderKey or RefinedKey.
/// `K`: the kernel policy, simd::Kernels (the active path's table, called through pointers) or a
/// compile-time policy of simd_kernels.hpp for the instances compiled per ISA (ray_traverse).
/// prepare() clears the per-thread scratch (one traversal per thread and scratch at a time; the
/// states of one packet are all prepared before any of them traverses; the two rays of
/// first_hit_pair use two scratches).
/// What the first-hit traversals' root test found (root_test).
enum class RootTest {
  miss,   ///< the ray misses the root: nothing to set up or traverse
  enter,  ///< the ray may enter (RayTraversal::enters_root: without its own root test where it can)
  exact,  ///< no kernel test applies: the traversal's own node test decides at the root
};

template <bool kBest1, SpatialIndex I, class KeyPolicy = OrderKey, class K = simd::Kernels>
struct RayTraversal {
  using Node = typename I::Node;
  static constexpr bool per_node = KeyPolicy::node_radius;
  static constexpr bool per_box = KeyPolicy::node_box;
  // The per-node geometry boxes in float: the SIMD child test on them is final (RefinedKey).
  static constexpr bool per_box_f = KeyPolicy::child_boxes_f && detail::FloatChildBoxes<I>;

  const I& index;
  const RayQuery& q;
  Candidate& best;
  RayQueryStats* stats;
  const KeyPolicy& key_policy;
  Vec3 o, d, inv_d;
  std::remove_cvref_t<decltype(std::declval<const I&>().positions())> pos;
  IdView ids;
  bool bounded;
  bool found = false;  // kBest1: best holds a candidate
  bool sphere, ray_order, exact, has_planes;
  bool done = false;  // any_hit: a candidate was found
  double radius, r2;
  AABB root_box;
  double dist_center;  // |o - centre of the root box|
  double tol;
  // Current bounds, tightened by the dynamic k filter (Algorithm 1, step 2).
  double worst = kInf;  // worst kept key once k candidates are held
  double pad;           // node distance bound: r, tightened to the k-bound for order ray
  Vec3 o_plus, o_minus;  // slab planes of the box grown by pad
  double t_lo, t_hi;
  // Geometry boxes (RefinedKey::node_box): the least ray parameter a hit inside one can have: t_lo,
  // raised to the key functor's key_min() when it has one (the query's own t_lo may lie far below).
  static constexpr bool key_floor_known = per_box && requires(const KeyPolicy& kp) { kp.key.key_min(); };
  double box_t_lo;
  RayScratch<Node>& scratch;
  KernelsOf<K> kern;
  double slack_t = 0, slack_d2 = 0;
  simd::PointFilterD pf;
  simd::SlabRayF sr{};
  simd::SlabRayF sr_box{};  // per_box_f: the ray's slabs for the float geometry boxes (no pad)
  bool simd_children = false;
  Vec3 o_rel{0.0};
  double mag = 0;
  bool slab_is_final = false;  // children whose SIMD slab result is final (else it only prefilters)
  bool child_keys = false;     // traverse_from's child step on child order keys (child_slab_keys)
  bool prepared = false;       // prepare() ran
  bool radii_filter = false;   // the SIMD point filter applies the key functor's per-slot radii
  bool normals_filter = false;  // ... and its per-slot disc normals (filter_normals)

  /// `scratch_`: the per-thread scratch to use (node stack, survivors), by default ray_scratch<Node>().
  RayTraversal(const I& index_, const Ray& ray, const RayQuery& q_, Candidate& best_, RayQueryStats* stats_,
               const KeyPolicy& key_policy_, RayScratch<Node>* scratch_ = nullptr)
      : index(index_), q(q_), best(best_), stats(stats_), key_policy(key_policy_), o(ray.origin()),
        d(ray.direction()), inv_d(1.0 / d), pos(index_.positions()), ids(index_.ids()),
        bounded(kBest1 || q_.k != kAllPoints), sphere(q_.order == RayOrder::sphere_hit),
        ray_order(q_.order == RayOrder::ray), exact(q_.node_distance == NodeDistance::exact),
        has_planes(!q_.planes.empty()), radius(q_.radius), r2(q_.radius * q_.radius),
        root_box(index_.node_bounds(index_.root())), scratch(scratch_ ? *scratch_ : detail::ray_scratch<Node>()),
        kern(kernels_of<K>()) {
    if (per_node && ray_order)
      throw std::invalid_argument("ray query: per-node radii need order time or sphere_hit");
    dist_center = glm::length(o - root_box.center());
    tol = node_test_tolerance(o, root_box, dist_center);  // (distance.hpp: with the coordinates' magnitude)
    pad = radius;
    o_plus = o + (pad + tol);
    o_minus = o - (pad + tol);
    t_lo = q.t_min - tol;
    t_hi = (sphere ? q.t_max + radius : q.t_max) + tol;  // sphere keys satisfy t_p <= key + r
    box_t_lo = t_lo;
    if constexpr (key_floor_known) box_t_lo = std::max(t_lo, key_policy.key.key_min() - tol);
    // The rest of the set-up (prepare) waits for the root test: a ray that the traversal's own
    // root test rejects pays only this much (bench/notes/); on the paths
    // with a root kernel most misses never get here (detail::root_test). A per-node radius sets
    // the root's own pad first, which the root test needs.
    if constexpr (per_node) prepare();
  }
  RayTraversal(const RayTraversal&) = delete;
  RayTraversal& operator=(const RayTraversal&) = delete;

  /// The set-up the traversal needs past the root test: clears the per-thread scratch and computes
  /// the SIMD constants (point filter bounds, float slabs). Idempotent; called by ray_traverse once
  /// the root passed, and for every ray of a packet that passed it, before any of them traverses.
  void prepare() {
    if (prepared) return;
    prepared = true;
    scratch.top = 0;
    scratch.cands.clear();

    // SIMD policies (simd.hpp). Point filter: bounds widened by far more than the difference
    // between the SIMD (possibly fused) and the scalar evaluation of t_p and d^2 (a few ulps of
    // |p - o| and |p - o|^2; |p - o| <= vmax for every point in the root box).
    const double vmax = dist_center + 0.5 * glm::length(root_box.hi - root_box.lo);
    slack_t = 1e-12 * vmax + 1e-300;
    slack_d2 = 1e-12 * vmax * vmax + 1e-300;
    pf = simd::PointFilterD{{o.x, o.y, o.z}, {d.x, d.y, d.z}, 0, 0, 0, nullptr, slack_d2};
    // Child test: float slabs relative to the index's float origin; rays with a direction
    // component whose float reciprocal is not finite keep the scalar node test.
    if constexpr (detail::FloatChildBoxes<I>) {
      if (has_kernel(kern.child_slab)) {
        o_rel = o - index.float_origin();
        const float fx = static_cast<float>(inv_d.x), fy = static_cast<float>(inv_d.y),
                    fz = static_cast<float>(inv_d.z);
        simd_children = std::isfinite(fx) && std::isfinite(fy) && std::isfinite(fz);
        sr.inv_d[0] = fx, sr.inv_d[1] = fy, sr.inv_d[2] = fz;
        sr_box.inv_d[0] = fx, sr_box.inv_d[1] = fy, sr_box.inv_d[2] = fz;
        mag = std::max({std::abs(o_rel.x), std::abs(o_rel.y), std::abs(o_rel.z)}) + index.float_extent();
      }
    }
    // Child entries are raised to t_min (no key lies below it), rounded down once per ray.
    sr.lb_floor = sr_box.lb_floor = round_float_down(q.t_min);
    if constexpr (per_node) set_node_pad(index.root());
    if constexpr (requires { key_policy.key.filter_radii(); }) radii_filter = key_policy.key.filter_radii() != nullptr;
    if constexpr (key_floor_known && requires { key_policy.key.filter_normals(); }) {
      normals_filter = radii_filter && key_policy.key.filter_normals() != nullptr;
      pf.disc_slack = 0x1p-36 * vmax + tol;
    }
    update_simd();
    slab_is_final = !ray_order && !has_planes && (!per_node || per_box_f);
    if constexpr (detail::FloatChildBoxes<I>)  // (pad is the query radius here: per node only with per_box_f)
      child_keys = has_kernel(kern.child_slab_keys) && bounded && slab_is_final && simd_children && (per_box_f || pad < kInf);
  }

  /// Per-node state on entering node n (with per-node radii): the pad and the point filter's
  /// distance bound become n's own; the float child slabs too, unless the children are tested on
  /// their float geometry boxes (per_box_f), whose slabs do not depend on the node.
  /// With per-slot radii in the point filter (radii_filter) and float geometry boxes, nothing: the
  /// pad stays the root's (the filter's distance bound in update_simd, valid for every point; each
  /// point's own radius is below it), and nothing else reads it (test_child leaves it alone).
  __attribute__((always_inline)) void enter_node([[maybe_unused]] Node n) {
    if constexpr (per_node) {
      if constexpr (per_box_f) {
        if (radii_filter) return;
        set_node_pad(n);
        pf.d2_max = pad * pad + slack_d2;
      } else {
        set_node_pad(n);
        update_simd();
      }
    }
  }

  /// Refreshes the per-ray SIMD constants after the pad changed (per-node radii, or the dynamic k
  /// filter of order ray), and at the start.
  void update_simd() {
    pf.d2_max = (ray_order ? std::min(r2, worst * worst * (1.0 + 1e-12)) : per_node ? pad * pad : r2) + slack_d2;
    // A point whose geometry (within radius of it) holds a hit has t_p >= the key floor less the
    // radius (without a floor, box_t_lo = t_lo and this is t_lo); with per-slot radii in the
    // filter, each point's own: t_p >= the floor less its radius.
    pf.t_lo = std::max(t_lo, box_t_lo - radius) - slack_t;
    pf.t_lo_own = box_t_lo - slack_t;
    // Disc hits (filter_normals): t in [key_min, t_max], and a refined key above the k-bound fails.
    pf.disc_t_lo = box_t_lo;
    if constexpr (per_box_f) {
      if (has_kernel(kern.child_slab)) {
        // As below with pad 0, the magnitudes including the geometry's reach past the float
        // cell (at most the query radius).
        const double margin = 0x1p-20 * (mag + radius) + tol;
        for (int a = 0; a < 3; ++a) {
          sr_box.o_plus[a] = static_cast<float>(o_rel[a] + margin);
          sr_box.o_minus[a] = static_cast<float>(o_rel[a] - margin);
        }
        sr_box.t_lo = round_float_down(box_t_lo);
      }
    } else if constexpr (detail::FloatChildBoxes<I>) {
      if (has_kernel(kern.child_slab) && pad < kInf) {
        // Position-space margin: float rounding of the slab origins and of box - origin
        // differences (each <= 2^-24 of the magnitudes involved); 2^-20 of their sum covers both.
        // The margin is 16x the rounding of o_plus / o_minus to float, so plain casts stay
        // outside the grown box; t_lo / t_hi are rounded outwards (round_float_down / round_float_up).
        const double margin = 0x1p-20 * (mag + pad) + tol;
        for (int a = 0; a < 3; ++a) {
          sr.o_plus[a] = static_cast<float>(o_rel[a] + (pad + margin));
          sr.o_minus[a] = static_cast<float>(o_rel[a] - (pad + margin));
        }
        sr.t_lo = round_float_down(t_lo);
      }
    }
    update_t_hi();
  }

  /// The SIMD constants that depend on t_hi and the k-bound alone: all that the dynamic k filter
  /// of orders time and sphere_hit moves (push_candidate), so a new best hit costs only these.
  /// The child test's enter_max is live()'s bound rounded up (order ray bounds a distance: none).
  void update_t_hi() {
    pf.t_hi = t_hi + slack_t;
    pf.disc_t_hi = std::min(q.t_max, worst);
    sr.t_hi = sr_box.t_hi = round_float_up(t_hi);
    if (bounded && !ray_order) sr.enter_max = sr_box.enter_max = round_float_up(worst + tol);
  }

  /// Per-node radius policy: pad becomes the node's own bound (never above the query radius).
  void set_node_pad([[maybe_unused]] Node n) {
    if constexpr (per_node) {
      pad = std::min(radius, static_cast<double>(key_policy.node_radius_of(n)));
      o_plus = o + (pad + tol);
      o_minus = o - (pad + tol);
    }
  }

  /// True when a node with key lower bound lb can still hold a better result (k filter).
  [[nodiscard]] bool live(double lb) const { return !(bounded && lb > worst + tol); }

  /// Whether the ray enters the root, after detail::root_test found `root` (enter or exact): the
  /// node test of the root (lb0 its bound), unless the root kernel's test stands for it (enter,
  /// and none of the conditions it does not test: planes, order ray's distance, a per-node
  /// radius below the query's; lb0 = -inf: no bound).
  [[nodiscard]] bool enters_root(RootTest root, double& lb0) {
    lb0 = -kInf;
    if (root == RootTest::enter && !has_planes && !ray_order && !per_node) return true;
    return test_node(root_box, lb0);
  }

  /// Node test (section 3.3): false prunes the node; otherwise lb receives a lower bound of the key
  /// of any result inside it.
  __attribute__((always_inline)) bool test_node(const AABB& b, double& lb) {
    Interval iv;
    if (pad < kInf) {
      // Slab test of the box grown by pad: every qualifying point projects inside iv.
      iv = slab_interval_grown(o_plus, o_minus, inv_d, b, t_lo, t_hi);
      if (iv.empty()) return false;
    } else {
      iv = dist_plane_bounds(o, d, b);  // projected time interval, eq. 4 via eq. 2
      iv.lo = std::max(iv.lo, t_lo);
      iv.hi = std::min(iv.hi, t_hi);
      if (iv.empty()) return false;
    }
    if (has_planes)
      for (const Plane& pl : q.planes)
        if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) return false;
    if (ray_order) {
      // Minimum distance of the box to the ray segment (section 3.3): a cheap separating-axis
      // bound (or eq. 3) first, the exact distance only for boxes large against the bound.
      double dmin = exact ? node_ray_distance_sat(o, d, b) : node_ray_distance_eq3(o, d, b);
      if (dmin > pad + tol) return false;
      if (exact && b.max_extent() > 8.0 * std::min(pad, dmin + 1e-300)) {
        dmin = std::sqrt(segment_box_distance2(o, d, iv.lo, iv.hi, b));
        if (dmin > pad + tol) return false;
      }
      lb = dmin;
    } else {
      // For orders time and sphere_hit the slab of the box grown by r bounds the distance in the
      // L-infinity sense; refining it with the exact distance was measured to prune < 2% more
      // nodes at a 25% higher cost, so it is not done.
      lb = std::max(iv.lo, q.t_min);
    }
    return live(lb);
  }

  /// Node test of child c: test_node of its box (grown by its own radius with per-node radii), or,
  /// with per-node geometry boxes, the slab test of c's box without pad.
  /// With per-node geometry boxes the pad is neither read nor changed (it is the bound of the node
  /// whose points are tested, or the root's: see enter_node).
  __attribute__((always_inline)) bool test_child(Node c, double& lb) {
    if constexpr (per_box) {
      const AABB b = key_policy.node_box_of(c);
      const Interval iv = slab_interval_grown(o + tol, o - tol, inv_d, b, box_t_lo, t_hi);
      if (iv.empty()) return false;
      if (has_planes)
        for (const Plane& pl : q.planes)
          if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) return false;
      lb = std::max(iv.lo, q.t_min);
      return live(lb);
    } else {
      if constexpr (per_node) set_node_pad(c);
      return test_node(index.node_bounds(c), lb);
    }
  }

  /// Node test of the nc <= 8 children of n at once: bit i of the result is set when child i
  /// passes, and lb[i] then holds its lower bound. SIMD policy on FloatChildBoxes indexes (all
  /// children on their float boxes, or on the key policy's float geometry boxes; the result is
  /// final for orders time / sphere_hit without planes, and with per-node radii only on the
  /// geometry boxes, else it prefilters the exact test), the scalar test otherwise.
  __attribute__((always_inline)) unsigned test_children(Node n, unsigned nc, double* lb) {
    unsigned out = 0;
    if constexpr (detail::FloatChildBoxes<I>) {
      // The float boxes: the policy's geometry boxes with the ray's own slabs (per_box_f), else
      // the index's child boxes with the slabs grown by pad.
      if (simd_children && (per_box_f || pad < kInf)) {
        float entry[8];
        unsigned m;
        if constexpr (per_box_f)
          m = kern.child_slab(key_policy.child_boxes_f_of(n), sr_box, entry);
        else
          m = kern.child_slab(index.child_boxes_f(n), sr, entry);
        while (m) {
          const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
          m &= m - 1;
          if (slab_is_final) {
            lb[i] = entry[i];  // (>= t_min rounded down, and live: the kernel tested enter_max)
          } else if (!test_child(index.child(n, i), lb[i])) {
            continue;
          }
          out |= 1u << i;
        }
        return out;
      }
    }
    for (unsigned i = 0; i < nc; ++i)
      if (test_child(index.child(n, i), lb[i])) out |= 1u << i;
    return out;
  }

  __attribute__((always_inline)) void push_candidate(const detail::Candidate& c) {
    if constexpr (kBest1) {
      if (found && !detail::cand_less(c, best)) return;
      best = c;
      found = true;
      if (q.any_hit) {
        done = true;
        return;
      }
    } else if (q.any_hit) {
      scratch.cands.push_back(c);
      done = true;
      return;
    }
    if constexpr (!kBest1) {
      auto& cands = scratch.cands;
      if (!bounded) {
        cands.push_back(c);
        return;
      }
      if (cands.size() < q.k) {
        cands.push_back(c);
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
      } else if (detail::cand_less(c, cands.front())) {
        std::pop_heap(cands.begin(), cands.end(), detail::cand_less);
        cands.back() = c;
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
      } else {
        return;
      }
      if (cands.size() != q.k) return;
    }
    {  // dynamic k filter: tighten r (order ray) or t_max
      worst = kBest1 ? best.key : scratch.cands.front().key;
      if (ray_order) {
        pad = std::min(radius, worst);
        o_plus = o + (pad + tol);
        o_minus = o - (pad + tol);
        update_simd();
      } else {
        t_hi = (sphere ? std::min(q.t_max, worst) + radius : std::min(q.t_max, worst)) + tol;
        update_t_hi();
      }
    }
  }

  /// Leaf work: the points stored at node n (every node of a layered octree holds some).
  __attribute__((always_inline)) void eval_points(Node n) {
    const SlotRange range = index.node_points(n);
    if (stats) {
      ++stats->nodes_visited;
      stats->points_tested += range.size();
    }
    // p: the position of slot s (pos[s], bit for bit: from the SIMD filter's decoded block, so a
    // compact encoding is decoded once per leaf, not again per survivor).
    // radius_filtered: the point passed the SIMD filter with the policy's per-slot radii, which
    // already made reject()'s test (up to the filter's slack; the key functor decides exactly).
    auto eval_slot = [&](std::uint32_t s, const Vec3& p, bool radius_filtered) __attribute__((always_inline)) {
      if constexpr (KeyPolicy::refines && requires { key_policy.key.exact_key(s, PointIndex{}, p); }) {
        // A key that decides alone (RefinedKey, exact_key): no projection terms, sphere key or
        // base-key tests before it; the terms only for a point it keeps (RayHit::t, distance).
        if (!has_planes && sphere) {
          const PointIndex id = ids[s];
          const double key = key_policy.key.exact_key(s, id, p);
          if (!(key <= worst) || !(key < kInf)) return;
          const RayPointTerms pt = ray_point_terms(o, d, p);
          push_candidate({key, id, s, sphere ? sphere_entry(pt.t, pt.d2, radius) : pt.t, pt.d2});
          return;
        }
      }
      const RayPointTerms pt = ray_point_terms(o, d, p);
      if (pt.d2 > r2) return;
      if constexpr (KeyPolicy::refines) {
        // The policy's early rejection by storage slot (RefinedKey), before any per-point work.
        if constexpr (requires { key_policy.key.reject(s, pt.d2); })
          if (!radius_filtered && key_policy.key.reject(s, pt.d2)) return;
      }
      const double t = sphere ? sphere_entry(pt.t, pt.d2, radius) : pt.t;
      if (t < q.t_min || t > q.t_max) return;
      if (has_planes) {
        bool inside = true;
        for (const Plane& pl : q.planes)
          if (dist_plane(pl.point, pl.normal, p) > 0.0) { inside = false; break; }
        if (!inside) return;
      }
      double key = ray_order ? std::sqrt(pt.d2) : t;
      if (key > worst) return;
      if constexpr (KeyPolicy::refines) {
        key = key_policy.key(ids[s], pt.t, pt.d2, key);
        if (!(key <= worst) || !(key < kInf)) return;
      }
      push_candidate({key, ids[s], s, t, pt.d2});
    };
    if (has_kernel(kern.point_filter) && range.size() >= 4) {
      // SIMD filter, then the exact test on the survivors only (in slot order, as below).
      auto& sel = scratch.sel;
      if (sel.size() < range.size()) sel.resize(range.size());
      const double* xyz = position_block(pos, range.begin, range.size(), scratch.block);
      // The policy's per-slot radii (RefinedKey): its early rejection inside the SIMD filter.
      if constexpr (requires { key_policy.key.filter_radii(); })
        if (radii_filter) pf.radii = key_policy.key.filter_radii() + range.begin;
      if constexpr (requires { key_policy.key.filter_normals(); })
        if (normals_filter) pf.normals = key_policy.key.filter_normals() + 3 * std::size_t{range.begin};
      const unsigned m = kern.point_filter(xyz, range.size(), pf, sel.data());
      for (unsigned j = 0; j < m; ++j) {
        const double* p = xyz + 3 * std::size_t{sel[j]};
        eval_slot(range.begin + sel[j], Vec3(p[0], p[1], p[2]), radii_filter);
        if (done) return;
      }
      return;
    }
    for (std::uint32_t s = range.begin; s < range.end; ++s) {
      eval_slot(s, pos[s], false);
      if (done) return;
    }
  }

  /// The depth-first loop over the subtree of `start` (which passed the node test with bound lb0,
  /// or, for the root, enters_root with lb0 = -inf).
  /// With k set: the children of each node pushed far-to-near (so the nearest is expanded first
  /// and the k filter tightens early), skipping any popped node whose lower bound exceeds the
  /// current k-bound; the nearest child is expanded right away instead of being pushed and popped
  /// (the store and reload of its entry and its live() branch sat on the loop's critical path:
  /// first hits 5-10% faster, bench/notes/). Without k: plain
  /// depth-first. Uses the per-thread node stack above its current top, and leaves it as it found
  /// it.
  ///
  /// The child step, when the children's SIMD slab result is final and k is set (child_keys): the
  /// kernel writes each passing child's entry as a child order key (simd.hpp, child_key) and
  /// reduces the least in registers. The next node comes straight from the mask (one child) or
  /// from that key (more), never through a store and reload (the loop is latency-bound: the chain
  /// from one node to the next is its time); the farther of two children is pushed after one
  /// compare (one or two children: 63% of the octree's nodes on the camera rays of bench_rays),
  /// three or more are sorted by a network on the 8 keys and, on indexes with ContiguousChildren32,
  /// written to the stack by the same kernel (sort_push_keys8: no reload of each sorted key and no
  /// loop whose trip count mispredicts; camera hits ~3% faster; else sort_keys8 and a loop).
  /// Otherwise the children are tested by test_children and sorted by insertion. (bench/notes/:
  /// -17% instructions per camera hit; a network for two children as well was slower.)
  ///
  /// The loop is written as steps of one node over a Cursor (begin_at, step, end), so that
  /// first_hit_pair can interleave two rays' traversals node by node; traverse_from runs one.
  void traverse_from(Node start, double lb0) {
    Cursor c = begin_at(start, lb0);
    while (step(c)) {
    }
    end(c);
  }

  /// One ray's place in the loop between two nodes: `e` is the next node when `next`, else the
  /// stack entries [base, top) hold what is left (the per-thread stack of this traversal's
  /// scratch, its storage and size held here rather than reloaded from the vector: the pushes'
  /// stores could not then make the compiler reload the vector's pointers; refreshed where it grows).
  struct Cursor {
    detail::NodeEntry<Node> e;
    bool next;
    std::size_t base, top, cap;
    detail::NodeEntry<Node>* stack;
  };

  /// The cursor at the subtree of `start` (which passed the node test with bound lb0, or
  /// enters_root), over the stack above its current top.
  [[nodiscard]] Cursor begin_at(Node start, double lb0) {
    const std::size_t base = scratch.top;
    return {{lb0, start}, live(lb0), base, base, scratch.nodes.size(), scratch.nodes.data()};
  }

  /// Leaves the stack as begin_at found it (after the last step).
  void end(const Cursor& c) { scratch.top = c.base; }

  /// One node of the loop (traverse_from): pops the next live node unless c holds one, evaluates
  /// its points and steps to its children. Returns false once the ray is done (nothing left, or an
  /// any_hit query found its hit); then call end(c).
  __attribute__((always_inline)) bool step(Cursor& c) {
    auto& nodes = scratch.nodes;
    auto& e = c.e;
    auto& next = c.next;
    auto& top = c.top;
    auto& cap = c.cap;
    auto& stack = c.stack;
    const std::size_t base = c.base;
    detail::NodeEntry<Node> kids[8];
    if (!next) {
      if (top == base) return false;
      e = stack[--top];
      if (!live(e.lb)) return true;
    }
    next = false;
    // Per-node radii: the node's subtree bound for its own points' SIMD filter and (without
    // float geometry boxes) its children's SIMD slab prefilter (test_children); with per-slot
    // radii in the filter and float geometry boxes, nothing (see enter_node).
    enter_node(e.node);
    eval_points(e.node);
    if (done) return false;
    const unsigned nc = index.child_count(e.node);
    if (nc == 0) return true;  // a leaf: no child test (nor an indirect SIMD call)
    // Room for every child (the one capacity test of the node's pushes).
    if (const std::size_t room = nc > 8 ? nc : 8; top + room > cap) [[unlikely]] {
      nodes.resize(cap + room + 64);
      stack = nodes.data();
      cap = nodes.size();
    }
    if (nc > 8) {  // (no index here has more than 8 children; kept general)
      for (unsigned i = 0; i < nc; ++i) {
        const Node ch = index.child(e.node, i);
        double lb;
        if (test_child(ch, lb)) stack[top++] = {lb, ch};
      }
      return true;
    }
    if constexpr (detail::FloatChildBoxes<I>) {
      if (child_keys) {
        alignas(32) std::uint32_t keys[8];
        std::uint32_t near;  // the least key: the next node (its bound is not needed)
        unsigned m;
        if constexpr (per_box_f)
          m = kern.child_slab_keys(key_policy.child_boxes_f_of(e.node), sr_box, keys, near);
        else
          m = kern.child_slab_keys(index.child_boxes_f(e.node), sr, keys, near);
        if (m == 0) return true;
        if ((m & (m - 1)) == 0) {  // one: straight from the mask
          e.node = index.child(e.node, static_cast<unsigned>(__builtin_ctz(m)));
          next = true;
          return true;
        }
        top = detail::push_farther_children(index, kern, e.node, m, keys, stack, top);
        e.node = index.child(e.node, simd::child_key_index(near));
        next = true;
        return true;
      }
    }
    double lb[8];
    unsigned m = test_children(e.node, nc, lb);
    if (!bounded) {
      for (; m; m &= m - 1) {
        const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
        stack[top++] = {lb[i], index.child(e.node, i)};
      }
      return true;
    }
    unsigned nk = 0;
    for (; m; m &= m - 1) {
      // Insertion sort into kids[] by descending lb (at most 8 children).
      const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
      unsigned j = nk++;
      while (j > 0 && kids[j - 1].lb < lb[i]) {
        kids[j] = kids[j - 1];
        --j;
      }
      kids[j] = {lb[i], index.child(e.node, i)};
    }
    if (nk == 0) return true;
    // The nearest child next, without a trip through the stack (it passed live() just now).
    for (unsigned j = 0; j + 1 < nk; ++j) stack[top++] = kids[j];
    e = kids[nk - 1];
    next = true;
    return true;
  }
};

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
template <class K, class KeyPolicy, SpatialIndex I>
__attribute__((always_inline)) inline RootTest root_test(const KernelsOf<K>& kern, const I& index, const Ray& ray,
                                                         const RayQuery& q) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));  // (the kernel reads 3 doubles from &v.x)
  if (!has_kernel(kern.ray_box) || !(q.radius < kInf)) return RootTest::exact;
  // (Per-node radii with order ray: the traversal's constructor refuses the query, for every ray.)
  if constexpr (KeyPolicy::node_radius)
    if (q.order == RayOrder::ray) return RootTest::exact;
  const AABB b = index.node_bounds(index.root());
  // t_max + radius bounds the traversal's t_hi for every order (sphere keys: t_p <= key + r).
  return kern.ray_box(&b.lo.x, &b.hi.x, &ray.origin().x, &ray.direction().x, q.radius, q.t_min, q.t_max + q.radius)
             ? RootTest::enter
             : RootTest::miss;
}

/// The traversal of one ray with kernel policy K after root_test found `root` (enter or exact),
/// from the root. Returns true when `best` was set (kBest1 only).
template <bool kBest1, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline bool ray_traverse_from_root(RootTest root, const I& index, const Ray& ray,
                                                                  const RayQuery& q, Candidate& best,
                                                                  RayQueryStats* stats, const KeyPolicy& key_policy) {
  RayTraversal<kBest1, I, KeyPolicy, K> rt(index, ray, q, best, stats, key_policy);
  double lb0;
  if (!rt.enters_root(root, lb0)) {  // missed the root: no further set-up
    if constexpr (!kBest1) rt.scratch.cands.clear();  // (ray_query reads them)
    return false;
  }
  rt.prepare();
  rt.traverse_from(index.root(), lb0);
  return rt.found;
}

/// The ray query for one ray with kernel policy K: the traversal above from the root, the first
/// hit's after root_test. Returns true when `best` was set (kBest1 only).
template <bool kBest1, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline bool ray_traverse_with(const I& index, const Ray& ray, const RayQuery& q,
                                                             Candidate& best, RayQueryStats* stats,
                                                             const KeyPolicy& key_policy) {
  RootTest root = RootTest::exact;
  if constexpr (kBest1) {
    root = root_test<K, KeyPolicy>(kernels_of<K>(), index, ray, q);
    if (root == RootTest::miss) return false;
  }
  return ray_traverse_from_root<kBest1, K>(root, index, ray, q, best, stats, key_policy);
}

/// ray_traverse_with with the table kernels (simd::Kernels: the active path's kernels through
/// function pointers), as one out-of-line function: the instance every path without a per-ISA one
/// runs (SSE2 and scalar, k > 1, refined keys, indexes without float child boxes). Its OrderKey
/// instances are compiled once, in the libraries of the indexes (RAYSCAN_BASE_INSTANCES), instead of
/// in every translation unit that queries (CI build time, bench/notes/).
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
template <bool kBest1, SpatialIndex I, class KeyPolicy>
__attribute__((target("avx2,fma"), flatten, noinline)) bool ray_traverse_avx2(
    const I& index, const Ray& ray, const RayQuery& q, Candidate& best, RayQueryStats* stats,
    const KeyPolicy& key_policy) {
  return ray_traverse_with<kBest1, simd::Avx2Kernels>(index, ray, q, best, stats, key_policy);
}
/// As ray_traverse_avx2, for the AVX-512 path (F + VL).
template <bool kBest1, SpatialIndex I, class KeyPolicy>
__attribute__((target("avx512f,avx512vl,avx2,fma"), flatten, noinline)) bool ray_traverse_avx512(
    const I& index, const Ray& ray, const RayQuery& q, Candidate& best, RayQueryStats* stats,
    const KeyPolicy& key_policy) {
  return ray_traverse_with<kBest1, simd::Avx512Kernels>(index, ray, q, best, stats, key_policy);
}
#endif

/// Whether the traversal of index I with key policy KeyPolicy has instances compiled per ISA
/// (ray_traverse_avx2 / _avx512 with kBest1, first_hit_packet_avx2 / _avx512 and, with OrderKey,
/// first_hit_pair_avx2 / _avx512): the first hit
/// (k = 1, the renderer's and visibility's query) of the plain ray query (OrderKey)
/// on indexes with float child boxes. Queries with k > 1 and the refined keys of surfel rendering
/// keep the table instance: each per-ISA instance is the whole traversal inlined once more, and
/// instancing every combination made the build 1.75x slower (bench/notes/). The octree's
/// instances are compiled once, in the library (extern templates at the end of this header).
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
      case SimdPath::avx2: return ray_traverse_avx2<kBest1>(index, ray, q, best, stats, key_policy);
      case SimdPath::avx512: return ray_traverse_avx512<kBest1>(index, ray, q, best, stats, key_policy);
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
  Traversal r0(index, rays[0], q, best[0], stats, key_policy);
  Traversal r1(index, rays[1], q, best[1], stats, key_policy, &ray_scratch<typename I::Node, 1>());
  double lb0, lb1;
  bool a0 = r0.enters_root(root0, lb0);  // (a ray that misses the root: no further set-up)
  bool a1 = r1.enters_root(root1, lb1);
  typename Traversal::Cursor c0{}, c1{};
  if (a0) {
    r0.prepare();
    c0 = r0.begin_at(index.root(), lb0);
  }
  if (a1) {
    r1.prepare();
    c1 = r1.begin_at(index.root(), lb1);
  }
  const bool s0 = a0, s1 = a1;
  while (a0 && a1) {
    a0 = r0.step(c0);
    a1 = r1.step(c1);
  }
  while (a0) a0 = r0.step(c0);
  while (a1) a1 = r1.step(c1);
  if (s0) r0.end(c0);
  if (s1) r1.end(c1);
  return (r0.found ? 1u : 0u) | (r1.found ? 2u : 0u);
}

/// first_hit_pair_with with the table kernels (the instance of paths and indexes without per-ISA
/// ones; compiled once per core index, RAYSCAN_BASE_INSTANCES).
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

}  // namespace detail

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
               RayQueryStats* stats = nullptr, const KeyPolicy& key_policy = {}) {
  q.validate();
  out.clear();
  if (index.empty() || q.k == 0) return;
  detail::Candidate best;
  if (q.k == 1) {  // first hit: the single-candidate policy (same answer as the k-heap)
    if (detail::ray_traverse<true>(index, ray, q, best, stats, key_policy))
      out.push_back(detail::to_ray_hit(best));
    return;
  }
  detail::ray_traverse<false>(index, ray, q, best, stats, key_policy);
  auto& cands = detail::ray_scratch<typename I::Node>().cands;
  std::sort(cands.begin(), cands.end(), detail::cand_less);
  out.reserve(cands.size());
  for (const detail::Candidate& c : cands) out.push_back(detail::to_ray_hit(c));
}

/// First hit: the result ray_query(index, ray, q) gives with q.k = 1 (whatever q.k says), without a
/// result vector; nullopt when nothing qualifies. For renderers (cf. Embree's rtcIntersect1).
/// `q` must have been checked with q.validate() (once per batch: this hot path does not validate;
/// an unchecked invalid query gives an unspecified answer, never undefined behaviour).
template <SpatialIndex I>
[[nodiscard]] std::optional<RayHit> ray_first_hit(const I& index, const Ray& ray, const RayQuery& q,
                                                  RayQueryStats* stats = nullptr) {
  if (index.empty()) return std::nullopt;
  detail::Candidate best;
  if (!detail::ray_traverse<true>(index, ray, q, best, stats)) return std::nullopt;
  return detail::to_ray_hit(best);
}

/// First hits of a batch of rays: out[i] = ray_first_hit(index, rays[i], q, stats) for every i,
/// bit for bit, with the rays traced two at a time, their traversals interleaved node by node
/// (detail::first_hit_pair: the single ray's loop is latency-bound, and two independent chains
/// fill the core's idle slots; the 1e6 camera rays of bench_rays 1.06-1.09x the single calls,
/// bench/notes/). The batch form of ray_first_hit for callers with many rays
/// (ray_query_each, the renderer's wavefronts, bench_rays). `stats` (optional) sums the work
/// counters. As ray_first_hit, `q` must have been validated. Throws std::invalid_argument when
/// out.size() != rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_first_hit_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                        std::span<std::optional<RayHit>> out, RayQueryStats* stats = nullptr) {
  detail::require_one_result_per_ray("ray_first_hit_each", out.size(), rays.size());
  if (index.empty()) {
    std::fill(out.begin(), out.end(), std::nullopt);
    return;
  }
  std::size_t i = 0;
  for (; i + 2 <= rays.size(); i += 2) {
    detail::Candidate best[2];
    const unsigned found = detail::first_hit_pair(index, rays.data() + i, q, best, stats);
    for (unsigned j = 0; j < 2; ++j)
      out[i + j] = detail::hit_of(found, best, j);
  }
  if (i < rays.size()) out[i] = ray_first_hit(index, rays[i], q, stats);
}

/// Rays per packet of ray_first_hit_packet: at most this many rays share one traversal.
inline constexpr std::size_t kMaxRayPacket = 16;

namespace detail {

/// The packet first hit of up to N <= 16 rays (kBest1 policy, OrderKey). One traversal state per
/// ray (RayTraversal above: its node test, leaf work and candidate sink), driven down one shared
/// node stack: a node is visited when any of the rays of its entry's mask still has it live, each
/// live ray evaluates the node's points and tests the node's children with its own node test, and
/// a child is pushed once with the mask of the rays that hit it (and each one's lower bound), so
/// rays whose t_far (the k-bound) is beaten drop out of the subtrees behind their hit. When a
/// node is left with a single live ray the packet has diverged there and that ray finishes the
/// subtree alone (RayTraversal::traverse_from, the single-ray loop itself).
///
/// Why a loop of its own rather than a policy of traverse_from: the stack entries carry a ray
/// mask and a bound per ray, and the child order is chosen for the packet; everything a node or a
/// point is tested with is the single-ray code. Each ray's answer is the exact minimum (key, id)
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
template <unsigned N, class K, SpatialIndex I, class KeyPolicy>
__attribute__((always_inline)) inline unsigned first_hit_packet(const I& index, const Ray* rays, unsigned n,
                                                                const RayQuery& q, Candidate* best,
                                                                RayQueryStats* stats, const KeyPolicy* keys) {
  static_assert(N >= 1 && N <= 16);
  using Node = typename I::Node;
  using RT = RayTraversal<true, I, KeyPolicy, K>;
  const auto key_of = [keys](unsigned i) -> const KeyPolicy& {
    if constexpr (std::is_same_v<KeyPolicy, OrderKey>) {
      static constexpr OrderKey kKey{};
      return keys ? keys[i] : kKey;
    } else {
      return keys[i];
    }
  };
  struct Entry {
    Node node;
    std::uint32_t mask;  // rays for which the node passed the node test
    double lb[N];        // each one's lower bound (valid where mask has the bit)
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
  for (unsigned i = 0; i < n; ++i) {
    // As ray_traverse: a ray that root_test finds missing is never set up, one that misses the
    // root is never prepared, nor read again.
    const RootTest rtest = root_test<K, KeyPolicy>(kern, index, rays[i], q);
    if (rtest == RootTest::miss) continue;
    st[i] = ::new (static_cast<void*>(states.buf[i])) RT(index, rays[i], q, best[i], stats, key_of(i));
    states.made |= 1u << i;
    if (st[i]->enters_root(rtest, root.lb[i])) {
      st[i]->prepare();
      root.mask |= 1u << i;
    }
  }
  stack.clear();
  if (root.mask) stack.push_back(root);
  // Child test policy: SIMD over the rays (packet_child_slab: one lane per ray, each child box
  // broadcast) when every ray's slab result is final (orders time / sphere_hit, no planes) and
  // float-testable; else each ray's own test_children (SIMD over the children).
  [[maybe_unused]] bool over_rays = false;
  [[maybe_unused]] alignas(64) simd::SlabPacketF lanes;
  [[maybe_unused]] auto set_lane = [&](unsigned i) {
    const simd::SlabRayF& r = RT::per_box_f ? st[i]->sr_box : st[i]->sr;
    for (int a = 0; a < 3; ++a) {
      lanes.o_plus[a][i] = r.o_plus[a];
      lanes.o_minus[a][i] = r.o_minus[a];
      lanes.inv_d[a][i] = r.inv_d[a];
    }
    lanes.t_lo[i] = r.t_lo;
    lanes.t_hi[i] = r.t_hi;
  };
  if constexpr (FloatChildBoxes<I>) {
    // (Only the prepared rays, those in root.mask, count and get a lane; no other ray is ever in a
    // stack entry's mask.)
    over_rays = has_kernel(kern.packet_child_slab);
    for (std::uint32_t m = root.mask; m; m &= m - 1) {
      const RT& r = *st[__builtin_ctz(m)];
      over_rays = over_rays && r.slab_is_final && r.simd_children && r.pad < kInf;
    }
    if (over_rays) {
      for (unsigned i = 0; i < 16; ++i) {  // unused lanes: a ray that hits nothing (t_lo > t_hi)
        for (int a = 0; a < 3; ++a) lanes.o_plus[a][i] = lanes.o_minus[a][i] = lanes.inv_d[a][i] = 0.0f;
        lanes.t_lo[i] = 1.0f;
        lanes.t_hi[i] = 0.0f;
      }
      for (std::uint32_t m = root.mask; m; m &= m - 1) set_lane(static_cast<unsigned>(__builtin_ctz(m)));
    }
  }
  Entry kids[8];
  double lbs[8];
  double lbc[8][N];     // lbc[c][i]: ray i's bound of child c
  std::uint32_t cm[8];  // cm[c]: the rays that hit child c
  while (!stack.empty()) {
    const Entry e = stack.back();
    stack.pop_back();
    std::uint32_t act = 0;
    for (std::uint32_t m = e.mask; m; m &= m - 1) {
      const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
      if (!st[i]->done && st[i]->live(e.lb[i])) act |= 1u << i;  // (done: any_hit answered)
    }
    if (!act) continue;
    if ((act & (act - 1)) == 0) {  // one ray left: diverged, it finishes the subtree alone
      const unsigned i = static_cast<unsigned>(__builtin_ctz(act));
      st[i]->traverse_from(e.node, e.lb[i]);
      continue;
    }
    for (std::uint32_t m = act; m; m &= m - 1) {
      RT& r = *st[__builtin_ctz(m)];
      const double before = r.worst;
      r.enter_node(e.node);
      r.eval_points(e.node);
      if constexpr (FloatChildBoxes<I>)
        if (over_rays && r.worst != before) set_lane(static_cast<unsigned>(__builtin_ctz(m)));
    }
    const unsigned nc = index.child_count(e.node);
    if (nc == 0) continue;
    if (nc > 8) {  // (no index here has more than 8 children): each ray alone below this node
      for (std::uint32_t m = act; m; m &= m - 1) {
        RT& r = *st[__builtin_ctz(m)];
        for (unsigned c = 0; c < nc; ++c) {
          double lb;
          if (r.test_child(index.child(e.node, c), lb)) r.traverse_from(index.child(e.node, c), lb);
        }
      }
      continue;
    }
    std::uint32_t any = 0;
    for (unsigned c = 0; c < nc; ++c) cm[c] = 0;
    bool tested = false;
    if constexpr (FloatChildBoxes<I>) {
      if (over_rays) {
        std::uint32_t hits[8];
        alignas(64) float entry[8 * 16];
        if constexpr (RT::per_box_f)
          kern.packet_child_slab(st[__builtin_ctz(act)]->key_policy.child_boxes_f_of(e.node), lanes, N, hits, entry);
        else
          kern.packet_child_slab(index.child_boxes_f(e.node), lanes, N, hits, entry);
        for (unsigned c = 0; c < nc; ++c)
          for (std::uint32_t m = hits[c] & act; m; m &= m - 1) {
            const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
            const double lb = std::max(static_cast<double>(entry[16 * c + i]), q.t_min);  // as test_children
            if (!st[i]->live(lb)) continue;
            cm[c] |= 1u << i;
            lbc[c][i] = lb;
            any |= 1u << c;
          }
        tested = true;
      }
    }
    if (!tested)
      for (std::uint32_t m = act; m; m &= m - 1) {
        const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
        for (std::uint32_t h = st[i]->test_children(e.node, nc, lbs); h; h &= h - 1) {
          const unsigned c = static_cast<unsigned>(__builtin_ctz(h));
          cm[c] |= 1u << i;
          lbc[c][i] = lbs[c];
          any |= 1u << c;
        }
      }
    // One entry per child hit by any ray, pushed far-to-near by the smallest bound of its rays.
    unsigned nk = 0;
    double key[8];
    for (; any; any &= any - 1) {
      const unsigned c = static_cast<unsigned>(__builtin_ctz(any));
      Entry k;
      k.node = index.child(e.node, c);
      k.mask = cm[c];
      double kmin = kInf;
      for (std::uint32_t m = cm[c]; m; m &= m - 1) {
        const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
        k.lb[i] = lbc[c][i];
        kmin = std::min(kmin, lbc[c][i]);
      }
      unsigned j = nk++;
      while (j > 0 && key[j - 1] < kmin) {
        kids[j] = kids[j - 1];
        key[j] = key[j - 1];
        --j;
      }
      kids[j] = k;
      key[j] = kmin;
    }
    for (unsigned j = 0; j < nk; ++j) stack.push_back(kids[j]);
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

}  // namespace detail

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
                          std::span<std::optional<RayHit>> out, RayQueryStats* stats = nullptr) {
  detail::require_one_result_per_ray("ray_first_hit_packet", out.size(), rays.size());
  if (index.empty() || q.any_hit) {
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = ray_first_hit(index, rays[i], q, stats);
    return;
  }
  detail::for_each_ray_packet(index, rays, q, stats,
                              [&](std::size_t b, unsigned n, const detail::Candidate* best, std::uint32_t found) {
                                for (unsigned i = 0; i < n; ++i)
                                  out[b + i] = detail::hit_of(found, best, i);
                              });
}

/// Packet any hit (shadow rays, coherent rays): out[i] = ray_first_hit(index, rays[i],
/// q).has_value() for every i: whether anything qualifies along the ray. With q.any_hit each ray
/// stops at its first candidate in the packet's visiting order and drops out of the packet (cf.
/// Embree's rtcOccluded4/8/16); the answer is the same whatever that order, as pruning is
/// conservative and an any_hit query never tightens the k-bound. Shares detail::first_hit_packet
/// with ray_first_hit_packet. `q` must have been checked with q.validate(). Throws
/// std::invalid_argument when out.size() != rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_any_hit_packet(const I& index, std::span<const Ray> rays, const RayQuery& q, std::span<bool> out,
                        RayQueryStats* stats = nullptr) {
  detail::require_one_result_per_ray("ray_any_hit_packet", out.size(), rays.size());
  if (index.empty()) {
    std::fill(out.begin(), out.end(), false);
    return;
  }
  detail::for_each_ray_packet(index, rays, q, stats,
                              [&](std::size_t b, unsigned n, const detail::Candidate*, std::uint32_t found) {
                                for (unsigned i = 0; i < n; ++i) out[b + i] = (found >> i) & 1u;
                              });
}

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

/// out[i] = ray_query(index, rays[i], q) for every i, bit for bit: with q.k == 1, the rays are
/// traced two at a time with their traversals interleaved (ray_first_hit_each; the 1e6 camera
/// rays of bench_rays 1.04-1.11x Embree's rtcIntersect1, where 16-ray packets of consecutive rays
/// had been 0.88-0.91x of single rays: bench/notes/), other queries
/// ray by ray. The batch form for callers that pass whole
/// ray sets (ray_query_batch: the Python module, `rayscan query`; the renderer traces its camera
/// wavefronts as packets, ray_first_hit_packet). `stats` (optional) sums the work counters.
/// Throws std::invalid_argument for an invalid q (RayQuery::validate) or out.size() !=
/// rays.size(). Thread-safe (per-thread scratch).
template <SpatialIndex I>
void ray_query_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                    std::span<std::vector<RayHit>> out, RayQueryStats* stats = nullptr) {
  q.validate();
  detail::require_one_result_per_ray("ray_query_each", out.size(), rays.size());
  if (q.k != 1) {
    for (std::size_t i = 0; i < rays.size(); ++i) ray_query(index, rays[i], q, out[i], stats);
    return;
  }
  constexpr std::size_t kChunk = 64;  // (a multiple of 2: every pair stays a pair)
  std::optional<RayHit> hit[kChunk];
  for (std::size_t i = 0; i < rays.size(); i += kChunk) {
    const std::size_t n = std::min(kChunk, rays.size() - i);
    ray_first_hit_each(index, rays.subspan(i, n), q, std::span<std::optional<RayHit>>(hit, n), stats);
    for (std::size_t j = 0; j < n; ++j) {
      out[i + j].clear();
      if (hit[j]) out[i + j].push_back(*hit[j]);
    }
  }
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
/// order. No ray is needed; nodes are pruned with dist_plane_bounds.
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
  std::vector<typename I::Node> stack{index.root()};
  while (!stack.empty()) {
    const auto n = stack.back();
    stack.pop_back();
    const AABB b = index.node_bounds(n);
    bool pruned = false;
    for (const Plane& pl : planes)
      if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) { pruned = true; break; }
    if (pruned) continue;
    const SlotRange sr = index.node_points(n);
    for (std::uint32_t s = sr.begin; s < sr.end; ++s) {
      bool inside = true;
      for (const Plane& pl : planes)
        if (dist_plane(pl.point, pl.normal, pos[s]) > 0.0) { inside = false; break; }
      if (inside) out.push_back(ids[s]);
    }
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i) stack.push_back(index.child(n, i));
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// Declares (KW = `extern template`) or defines (KW = `template`) the plain ray query's instances
/// with the table kernels for index type I: ray_traverse_base (k = 1 and k > 1),
/// first_hit_packet_any with OrderKey and first_hit_pair_base. Used inside namespace rayscan::detail, as
/// RAYSCAN_FIRST_HIT_ISA_INSTANCES below: the headers of the indexes declare them extern and their
/// libraries define them once (octree/src/query/ray_query.cpp, site/src/query_instances.cpp).
#define RAYSCAN_BASE_INSTANCES(KW, I)                                                                        \
  KW bool ray_traverse_base<true, I, OrderKey>(const I&, const Ray&, const RayQuery&, Candidate&,           \
                                               RayQueryStats*, const OrderKey&);                           \
  KW bool ray_traverse_base<false, I, OrderKey>(const I&, const Ray&, const RayQuery&, Candidate&,          \
                                                RayQueryStats*, const OrderKey&);                          \
  KW unsigned first_hit_packet_any<simd::Kernels, I, OrderKey>(const I&, const Ray*, unsigned,              \
                                                               const RayQuery&, Candidate*, RayQueryStats*, \
                                                               const OrderKey*);                           \
  KW unsigned first_hit_pair_base<I>(const I&, const Ray*, const RayQuery&, Candidate*, RayQueryStats*);

namespace detail {
RAYSCAN_BASE_INSTANCES(extern template, Octree)
}  // namespace detail

#if RAYSCAN_SIMD_X86
/// Declares (KW = `extern template`) or defines (KW = `template`) the first-hit instances compiled
/// per ISA of index type I (kIsaInstances): ray_traverse_avx2 / _avx512, first_hit_packet_avx2 /
/// _avx512 with OrderKey and first_hit_pair_avx2 / _avx512. Used inside namespace rayscan::detail: the headers of the indexes declare
/// them extern and their libraries define them once (octree/src/query/ray_query.cpp,
/// site/src/query_instances.cpp), instead of every caller's translation unit compiling them.
#define RAYSCAN_FIRST_HIT_ISA_INSTANCES(KW, I)                                                              \
  KW bool ray_traverse_avx2<true, I, OrderKey>(const I&, const Ray&, const RayQuery&, Candidate&,          \
                                               RayQueryStats*, const OrderKey&);                          \
  KW bool ray_traverse_avx512<true, I, OrderKey>(const I&, const Ray&, const RayQuery&, Candidate&,        \
                                                 RayQueryStats*, const OrderKey&);                        \
  KW unsigned first_hit_packet_avx2<I, OrderKey>(const I&, const Ray*, unsigned, const RayQuery&,          \
                                                 Candidate*, RayQueryStats*, const OrderKey*);            \
  KW unsigned first_hit_packet_avx512<I, OrderKey>(const I&, const Ray*, unsigned, const RayQuery&,        \
                                                   Candidate*, RayQueryStats*, const OrderKey*);           \
  KW unsigned first_hit_pair_avx2<I>(const I&, const Ray*, const RayQuery&, Candidate*, RayQueryStats*);     \
  KW unsigned first_hit_pair_avx512<I>(const I&, const Ray*, const RayQuery&, Candidate*, RayQueryStats*);

namespace detail {
RAYSCAN_FIRST_HIT_ISA_INSTANCES(extern template, Octree)
}  // namespace detail
#endif

}  // namespace rayscan
