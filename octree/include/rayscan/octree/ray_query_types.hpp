// The ray query's public types (paper section 3.1): the order, the query's predicates, a hit,
// the statistics, the projection terms and the sphere entry, and the point-key policies
// (OrderKey, RefinedKey). The queries themselves: ray_query.hpp.
#pragma once

#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray.hpp"
#include "rayscan/octree/simd.hpp"
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

/// Rays per packet of ray_first_hit_packet: at most this many rays share one traversal.
inline constexpr std::size_t kMaxRayPacket = 16;

/// The setting of the entry-point search (set_entry_point_search).
enum class EntryPointSearch {
  off,        ///< every query starts at the root
  automatic,  ///< the default: knn_query always, first hits where the grid is for them
              ///< (EntryGrid::first_hits: a cloud that fills its cube, not a scan of surfaces)
  always,     ///< first hits on every grid too (tests and benchmarks of the search itself)
};

}  // namespace rayscan
