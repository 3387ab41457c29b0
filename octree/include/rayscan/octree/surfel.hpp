// Surfels: oriented discs centred on the points (Pfister et al. 2000, "Surfels: Surface Elements as
// Rendering Primitives"; ray tracing them as in Wald & Seidel 2005, "Interactive Ray Tracing of
// Point-based Models", section 3), found through the paper's ray query: candidates within the
// maximum disc radius of the ray in order of their sphere entry (RayOrder::sphere_hit, a lower
// bound of the disc hit), then the exact ray-disc test in double.
// The queries that run the ray query's traversal or its SIMD kernels (first_surfel_hit,
// first_surfel_hit_packet, covering_discs, cover_candidates) are compiled once per index type of
// the library (RAYSCAN_SURFEL_INSTANCES below; their definitions are in the library's private
// headers, octree/src/include: detail/surfel_impl.hpp); the node tables and the disc tests are
// defined here.
#pragma once

#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/traverse.hpp"

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan {

/// The discs of a cloud, indexed by original point index (spans must outlive the view).
struct SurfelView {
  std::span<const Vec3> centers;       ///< disc centres (the cloud's positions), world coordinates
  std::span<const glm::vec3> normals;  ///< unit disc normals
  std::span<const float> radii;        ///< disc radii, world units (> 0)
  double max_radius = 0.0;             ///< max of radii: the candidate radius of the ray query
  /// Optional, by node of the one index the view is used with (surfel_node_radii over it): the
  /// largest disc radius in each node's subtree, the per-node candidate radius of the ray query.
  /// Empty: max_radius everywhere.
  std::span<const float> node_radii{};
  /// Optional, by original point index: the measured surface thickness at each disc (world units,
  /// SurfelAttributes::thickness), which widens the self-intersection slab (same_surface). Empty: 0.
  std::span<const float> thickness{};
  /// Optional (with node_radii), by node of the same index (surfel_node_boxes over it): the
  /// bounding box of the discs of each node's subtree, the node test of the ray query. Empty: each
  /// node's box grown by its radius.
  std::span<const AABB> node_boxes{};
  /// Optional (with node_boxes, on FloatChildBoxes indexes), by node of the same index
  /// (surfel_node_boxes_f over it): node_boxes in float, 8 floats per node (lo xyz, hi xyz, 2
  /// unused), relative to the index's float_origin() and rounded outwards: the SIMD child test of
  /// the ray query (RefinedKey::child_boxes_f). Empty: each child's box is tested in double.
  std::span<const float> node_boxes_f{};
  /// Optional, by storage slot of the same index (surfel_slot_radii over it): radii[ids[slot]],
  /// so the ray query rejects a point whose disc the ray passes too far from by one contiguous
  /// load (DiscKey::reject) instead of a lookup by original index. Empty: no early rejection.
  std::span<const float> slot_radii{};
  /// Optional (with slot_radii), by storage slot of the same index (surfel_slot_normals over it):
  /// normals[ids[slot]], present only where every disc centre equals (==) the index's position
  /// of its point, so the disc test reads a candidate's centre, normal and radius in storage
  /// order (DiscKey::exact_key: the position the traversal holds, this and slot_radii) instead of
  /// by three lookups by original index. Empty: by original index.
  std::span<const glm::vec3> slot_normals{};
  /// thickness[i], or 0 without thickness.
  [[nodiscard]] double thickness_at(PointIndex i) const { return thickness.empty() ? 0.0 : double(thickness[i]); }
};

/// The largest of `radii` (by original point index) over the points of each node's subtree of
/// `index`, indexed by node (size: largest node handle + 1; unvisited handles hold 0). One pass
/// over the tree (nodes_children_first: each node after its children).
template <SpatialIndex I>
[[nodiscard]] std::vector<float> surfel_node_radii(const I& index, std::span<const float> radii) {
  std::vector<float> out;
  if (index.empty()) return out;
  const auto order = nodes_children_first(index);
  out.assign(static_cast<std::size_t>(*std::max_element(order.begin(), order.end())) + 1, 0.0f);
  const IdView ids = index.ids();
  for (const auto n : order) {
    float m = 0.0f;
    const SlotRange sr = index.node_points(n);
    for (std::uint32_t k = sr.begin; k < sr.end; ++k) m = std::max(m, radii[ids[k]]);
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i) m = std::max(m, out[index.child(n, i)]);
    out[n] = m;
  }
  return out;
}

/// The axis-aligned bounding box of the disc (centre c, normal n, not necessarily unit, radius r):
/// c +- r sqrt(1 - n_a^2 / |n|^2) on axis a (the disc's extent along a), widened by 1e-9 r for
/// rounding. Every point ray_disc_t accepts as a hit lies in it (up to the ray query's tolerance).
[[nodiscard]] inline AABB disc_bounds(const Vec3& c, const Vec3& n, double r) {
  const double len2 = glm::dot(n, n);
  Vec3 e(r * (1.0 + 1e-9));  // a degenerate normal (never hit): the sphere's box
  if (len2 > 0.0)
    for (int a = 0; a < 3; ++a) e[a] = r * (std::sqrt(std::max(0.0, 1.0 - n[a] * n[a] / len2)) + 1e-9);
  return {c - e, c + e};
}

/// The bounding box of the discs of each node's subtree of `index` (disc_bounds of the centres
/// `s.centers`, normals and radii, by original point index), indexed by node like
/// surfel_node_radii (unvisited handles and nodes without discs hold an empty box). For flat
/// surfaces it is much thinner across the surface than the node's box grown by its largest radius.
template <SpatialIndex I>
[[nodiscard]] std::vector<AABB> surfel_node_boxes(const I& index, const SurfelView& s) {
  std::vector<AABB> out;
  if (index.empty()) return out;
  const auto order = nodes_children_first(index);
  out.assign(static_cast<std::size_t>(*std::max_element(order.begin(), order.end())) + 1, AABB{});
  const IdView ids = index.ids();
  for (const auto n : order) {
    AABB b;
    const SlotRange sr = index.node_points(n);
    for (std::uint32_t k = sr.begin; k < sr.end; ++k) {
      const PointIndex id = ids[k];
      const AABB db = disc_bounds(s.centers[id], Vec3(s.normals[id]), s.radii[id]);
      b.lo = glm::min(b.lo, db.lo);
      b.hi = glm::max(b.hi, db.hi);
    }
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i) {
      const AABB& cb = out[index.child(n, i)];
      b.lo = glm::min(b.lo, cb.lo);
      b.hi = glm::max(b.hi, cb.hi);
    }
    out[n] = b;
  }
  return out;
}

/// `radii` (by original point index) in the storage slot order of `index`: out[slot] =
/// radii[index.ids()[slot]] (SurfelView::slot_radii).
template <SpatialIndex I>
[[nodiscard]] std::vector<float> surfel_slot_radii(const I& index, std::span<const float> radii) {
  const IdView ids = index.ids();
  std::vector<float> out(index.positions().size());
  for (std::size_t k = 0; k < out.size(); ++k) out[k] = radii[ids[k]];
  return out;
}

/// `normals` (by original point index) in the storage slot order of `index` (SurfelView::
/// slot_normals): out[slot] = normals[index.ids()[slot]], or empty when some disc centre
/// centers[ids[slot]] is not equal (==) to the index's position of the slot (then the disc test
/// keeps reading by original index).
template <SpatialIndex I>
[[nodiscard]] std::vector<glm::vec3> surfel_slot_normals(const I& index, std::span<const Vec3> centers,
                                                         std::span<const glm::vec3> normals) {
  const IdView ids = index.ids();
  const auto pos = index.positions();
  std::vector<glm::vec3> out(pos.size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    const Vec3 p = pos[k];
    if (!(p == centers[ids[k]])) return {};
    out[k] = normals[ids[k]];
  }
  return out;
}

/// Floats per node of surfel_node_boxes_f (simd::ChildBoxesF::stride: lo xyz, hi xyz, 2 unused).
inline constexpr unsigned kNodeBoxFloats = 8;

/// `boxes` (surfel_node_boxes over `index`) as the float table of SurfelView::node_boxes_f: box n
/// at [kNodeBoxFloats n, + 6), each coordinate relative to index.float_origin() rounded outwards
/// (lo down, hi up), so the float box contains the double one; empty boxes stay empty (+inf lo,
/// -inf hi). Only for indexes whose children are contiguous node handles with float boxes
/// (detail::FloatChildBoxes: Octree, io::MappedIndex); throws std::invalid_argument when a node's
/// children are not contiguous or `boxes` does not cover every node.
template <SpatialIndex I>
  requires detail::FloatChildBoxes<I>
[[nodiscard]] std::vector<float> surfel_node_boxes_f(const I& index, std::span<const AABB> boxes) {
  using Node = typename I::Node;
  // SurfelChildBoxesF reads the rows child(n, 0) + i: every node checked, in depth_first's order.
  depth_first(index, [](Node) { return Enter::yes; }, [&](const NodeVisit<Node>& v) {
    const Node n = v.node;
    if (std::size_t{n} >= boxes.size())
      throw std::invalid_argument("surfel_node_boxes_f: the node boxes do not cover node " + std::to_string(n));
    for (unsigned i = 0, nc = index.child_count(n); i < nc; ++i)
      if (index.child(n, i) != index.child(n, 0) + i)
        throw std::invalid_argument("surfel_node_boxes_f: the children of node " + std::to_string(n) +
                                    " are not contiguous");
  });
  std::vector<float> out(boxes.size() * kNodeBoxFloats, 0.0f);
  const Vec3 o = index.float_origin();
  for (std::size_t n = 0; n < boxes.size(); ++n) {
    float* f = out.data() + n * kNodeBoxFloats;
    for (int a = 0; a < 3; ++a) {
      const bool empty = !(boxes[n].lo[a] <= boxes[n].hi[a]);
      f[a] = empty ? std::numeric_limits<float>::infinity() : detail::round_float_down(boxes[n].lo[a] - o[a]);
      f[3 + a] = empty ? -std::numeric_limits<float>::infinity() : detail::round_float_up(boxes[n].hi[a] - o[a]);
    }
  }
  return out;
}

/// Ray parameter where the ray o + t d (unit d) crosses the disc (centre c, unit normal n, radius
/// r), or kInf when it misses it or the hit lies outside [t_min, t_max]. A ray parallel to the
/// disc plane misses. Double precision throughout (pbrt-v4 section 6.4.2, "Disk Intersection
/// Tests", with the plane at the disc centre).
[[nodiscard]] inline double ray_disc_t(const Vec3& o, const Vec3& d, const Vec3& c, const Vec3& n,
                                       double r, double t_min, double t_max) {
  const double denom = glm::dot(d, n);
  if (std::abs(denom) < 1e-12) return kInf;
  const Vec3 v = c - o;
  const double t = glm::dot(v, n) / denom;
  if (!(t >= t_min && t <= t_max)) return kInf;
  const Vec3 w = t * d - v;  // hit minus centre
  return glm::dot(w, w) <= r * r ? t : kInf;
}

/// The surface a shadow or bounce ray leaves: the discs of that surface near the
/// origin are ignored, so flat lit surfaces do not shadow themselves (no "acne").
struct LeavingSurface {
  PointIndex index = 0;  ///< the disc or sphere that was hit
  Vec3 position{0.0};    ///< hit point, world coordinates
  Vec3 normal{0.0};      ///< unit normal at the hit, facing the side the new ray leaves into
  double radius = 0.0;   ///< radius of the disc or sphere that was hit, world units
  double thickness = 0.0;  ///< measured surface thickness at the disc hit (SurfelView::thickness_at)
};

/// True when candidate disc j (thickness t_j) belongs to the surface `from` lies on: j is the disc
/// left, or its centre lies within the surface's slab around the tangent plane at the origin (half
/// a radius plus T, the larger measured thickness of the two discs: the depth steps of a quantised
/// scan, the noise of a noisy one) and within two disc diameters plus T of it (the offset along the
/// normal counted only beyond T), and either its
/// normal is within 45 degrees of the surface normal or its centre lies strictly within the
/// measured thickness of the surface left (no disc there is resolved as an occluder): the
/// overlapping neighbours of a scanned surface. A wall meeting the floor at a corner has another
/// normal and is kept. With both thicknesses zero (visibility, a noise-free scan) this is exactly
/// the rule without thickness: normal within 45 degrees, |h| <= r / 2, distance <= 2 (r + r_j).
[[nodiscard]] inline bool same_surface(const LeavingSurface& from, PointIndex j, const Vec3& c_j,
                                       const Vec3& n_j, double r_j, double t_j = 0.0) {
  if (j == from.index) return true;
  const Vec3 v = c_j - from.position;
  const double r = std::max(from.radius, r_j);
  const double h = glm::dot(v, from.normal);
  const double T = std::max(from.thickness, t_j);
  if (std::abs(h) > 0.5 * r + T) return false;
  // Distance to the disc left, without the part of the offset along the normal that lies within
  // the measured thickness (the layers of one surface are side by side, not above each other).
  const double lim = 2.0 * (from.radius + r_j) + T;
  if (glm::dot(v, v) - std::min(h * h, T * T) > lim * lim) return false;
  if (std::abs(h) < from.thickness) return true;
  return std::abs(glm::dot(n_j, from.normal)) >= 0.7071;
}

/// Result of first_surfel_hit().
struct SurfelHit {
  double t = kInf;       ///< ray parameter of the hit, kInf for a miss
  PointIndex index = 0;  ///< the disc hit
  std::uint32_t queries = 0;  ///< ray queries issued
};

/// The refined key of a surfel ray query (RefinedKey::key): the exact ray-disc parameter of disc
/// `id` in [t_min, t_max] (ray_disc_t, double), kInf when the ray misses the disc, passes farther
/// than its radius from the centre, or the disc belongs to the surface `from` leaves
/// (same_surface). `o`, `d`: the ray's origin and unit direction, world coordinates.
struct DiscKey {
  const SurfelView* s = nullptr;
  Vec3 o{0.0}, d{0.0};
  double t_min = 0.0, t_max = kInf;
  const LeavingSurface* from = nullptr;
  const float* slot_radii = nullptr;  ///< SurfelView::slot_radii, or null
  const glm::vec3* slot_normals = nullptr;  ///< SurfelView::slot_normals (with slot_radii), or null
  /// True when the point at storage slot `slot` lies farther than its disc's radius from the ray
  /// (d2: squared distance), exactly the first rejection of operator() (same float radius).
  bool reject(std::uint32_t slot, double d2) const {
    if (!slot_radii) return false;
    const double r = slot_radii[slot];
    return d2 > r * r;
  }
  /// The radii reject() tests, by storage slot, for the ray query's SIMD point filter (or null).
  const float* filter_radii() const { return slot_radii; }
  /// The disc normals by storage slot for the SIMD point filter's ray-disc test (RefinedKey's
  /// filter_normals; the refined key is ray_disc_t in [t_min, t_max]), or null.
  const float* filter_normals() const { return slot_normals ? &slot_normals->x : nullptr; }
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "filter_normals: slot normals as packed float triples");
  /// Every finite key is a disc hit t >= t_min (RefinedKey's key_min; the query's own t_min is
  /// 2 R lower, for the sphere keys).
  double key_min() const { return t_min; }
  /// The disc hit parameter of disc `id` (at storage slot `slot`, index position p) alone
  /// (RefinedKey::exact_key): ray_disc_t in [t_min, t_max] unless the disc belongs to the surface
  /// left. With slot_normals, the centre is p (the same value: see SurfelView::slot_normals) and
  /// normal and radius come by slot. A finite one satisfies the query's own predicates up to
  /// rounding (surfel_query: the centre within r <= R of the ray, the sphere key t_p - sqrt(R^2 -
  /// d^2) >= t - r - R >= t_min - 2 R and <= t), so the traversal skips them (RefinedKey).
  double exact_key(std::uint32_t slot, PointIndex id, const Vec3& p) const {
    if (slot_normals) return disc_test(id, p, Vec3(slot_normals[slot]), slot_radii[slot]);
    return disc_test(id, s->centers[id], Vec3(s->normals[id]), s->radii[id]);
  }
  /// RefinedKey::key: the test of exact_key by original index after the cheap rejection of a
  /// centre farther than r from the ray (d2: its squared distance), for the queries that test the
  /// points first (with planes, or of an order other than sphere_hit).
  double operator()(PointIndex id, double, double d2, double) const {
    const double r = s->radii[id];
    if (d2 > r * r) return kInf;  // the ray passes farther than r from the centre: misses the disc
    return disc_test(id, s->centers[id], Vec3(s->normals[id]), r);
  }
  /// ray_disc_t of disc `id` (centre c, unit normal n, radius r) unless it belongs to the surface
  /// left. The disc test first: it rejects most of the surface's own discs near a secondary ray's
  /// origin (behind it, or not under it) for less than same_surface costs.
  double disc_test(PointIndex id, const Vec3& c, const Vec3& n, double r) const {
    const double t = ray_disc_t(o, d, c, n, r, t_min, t_max);
    if (t < kInf && from && same_surface(*from, id, c, n, r, s->thickness_at(id))) return kInf;
    return t;
  }
};

/// DiscKey::slot_normals of a view: SurfelView::slot_normals when it and slot_radii cover the
/// same slots, else null.
[[nodiscard]] inline const glm::vec3* slot_normals_of(const SurfelView& s) {
  return !s.slot_normals.empty() && s.slot_normals.size() == s.slot_radii.size() ? s.slot_normals.data() : nullptr;
}

/// RefinedKey::node_radius_of of a surfel query: SurfelView::node_radii (world units).
struct SurfelNodeRadius {
  const SurfelView* s = nullptr;
  template <class Node>
  double operator()(Node n) const { return double(s->node_radii[n]); }
};

/// RefinedKey::node_box_of of a surfel query: SurfelView::node_boxes (world coordinates).
struct SurfelNodeBox {
  const SurfelView* s = nullptr;
  template <class Node>
  AABB operator()(Node n) const { return s->node_boxes[n]; }
};

/// RefinedKey::child_boxes_f_of of a surfel query: the rows of SurfelView::node_boxes_f of n's
/// children (contiguous node handles on FloatChildBoxes indexes).
template <SpatialIndex I>
struct SurfelChildBoxesF {
  const I* index = nullptr;
  const SurfelView* s = nullptr;
  simd::ChildBoxesF operator()(typename I::Node n) const {
    return {s->node_boxes_f.data() + std::size_t{index->child(n, 0)} * kNodeBoxFloats, kNodeBoxFloats,
            index->child_count(n)};
  }
};

/// The ray query of first_surfel_hit (see there): order sphere_hit, candidate radius R, k = 1.
[[nodiscard]] inline RayQuery surfel_query(const SurfelView& s, double t_min, double t_max, bool any_hit) {
  const double R = s.max_radius;
  RayQuery q;
  q.order = RayOrder::sphere_hit;
  q.radius = R;
  q.k = 1;
  q.any_hit = any_hit;
  // A hit at t >= t_min has t_p >= t_min - r, so its sphere key is >= t_min - 2R.
  q.t_min = t_min - 2.0 * R;
  q.t_max = t_max;
  return q;
}

/// Which node-bound variants of the surfel ray query first_surfel_hit compiles: `any` all of
/// them, chosen at run time by which node tables the SurfelView holds; `best` only the one of the
/// index's full tables (see first_surfel_hit).
enum class SurfelTables { any, best };

/// The first disc hit along `ray` with t in [t_min, t_max] (or, with any_hit, some disc hit in it),
/// ignoring the discs of `from` when given; ties in t go to the smaller index. One ray query: order
/// sphere_hit with the maximum radius R as candidate radius (a disc of radius r <= R around c lies
/// inside the sphere of radius R around c, so its hit is never before that sphere's entry, the
/// key the traversal prunes with), k = 1, and the exact ray-disc test in double as the query's
/// refined key (RefinedKey, DiscKey): the traversal visits nodes nearest entry first and stops once
/// no node can hold a disc hit before the best one. With s.node_radii, each node's box is grown by
/// its own largest disc radius instead of R, and with s.node_boxes (and node_radii) each child is
/// tested against the bounding box of its discs instead, and with s.node_boxes_f (FloatChildBoxes
/// indexes only, else std::invalid_argument) all children of a node at once on their float copies
/// (SIMD). `hits` is caller-owned scratch; `stats` accumulates the query counters.
/// V = SurfelTables::best compiles only the variant of the index's full tables (the path tracer,
/// which builds them all: node_radii and node_boxes, and node_boxes_f on a FloatChildBoxes index)
/// and throws std::invalid_argument when the view lacks one; the default chooses at run time,
/// so its caller compiles all four ray queries (render.cpp: 13 of its 18 surfel traversals).
template <SpatialIndex I, SurfelTables V = SurfelTables::any>
SurfelHit first_surfel_hit(const I& index, const SurfelView& s, const Ray& ray, double t_min,
                           double t_max, const LeavingSurface* from, bool any_hit,
                           std::vector<RayHit>& hits, RayQueryStats& stats);

/// first_surfel_hit for each of n = rays.size() <= kMaxRayPacket coherent rays (a camera tile, or
/// the shadow rays of its hits), out[i] = first_surfel_hit(index, s, rays[i], t_min, t_max,
/// from[i], any_hit, ...) for every i: the same t and index bit for bit (with any_hit: whether a
/// disc was hit; which one depends on the visiting order, as for one ray). `from` is empty (no
/// surface left) or holds one (possibly null) pointer per ray. The rays share one traversal
/// (detail::first_hit_packet with one DiscKey per ray) when the view has all its node tables on a
/// FloatChildBoxes index; otherwise each ray is answered alone (with `hits` as first_surfel_hit's
/// caller-owned scratch, and V as there). Throws std::invalid_argument for inconsistent sizes. Thread-safe
/// (per-thread scratch).
template <SpatialIndex I, SurfelTables V = SurfelTables::any>
void first_surfel_hit_packet(const I& index, const SurfelView& s, std::span<const Ray> rays, double t_min,
                             double t_max, std::span<const LeavingSurface* const> from, bool any_hit,
                             std::span<SurfelHit> out, std::vector<RayHit>& hits, RayQueryStats& stats);

/// sqrt(1 + 1/16): a disc of radius r that covers x in the sense of blended_normal (in-plane
/// distance < r, plane offset <= r/4) has its centre within this factor times r of x.
inline constexpr double kBlendReachFactor = 1.0307764064044151;

/// Distance from a point x within which lie the centres of all discs that can cover x in the
/// sense of blended_normal (in-plane distance < r, plane offset <= r/4): sqrt(1 + 1/16) R.
[[nodiscard]] inline double blend_reach(const SurfelView& s) { return s.max_radius * kBlendReachFactor; }

/// The squared in-plane distance of x from the centre c of a disc (normal n, not necessarily unit
/// in float; radius r, world units) when the disc covers x in the sense of blended_normal (plane
/// offset dot(x - c, n) within r/4, in-plane distance < r), else kInf. The one cover test of
/// blended_normal, covering_discs and covering_discs_among (the same expressions, so they agree
/// bit for bit).
[[nodiscard]] inline double cover_in_plane_d2(const Vec3& c, const Vec3& n, double r, const Vec3& x) {
  const Vec3 v = x - c;
  const double off = glm::dot(v, n);
  if (std::abs(off) > 0.25 * r) return kInf;
  const double d2 = glm::dot(v, v) - off * off;
  return d2 >= r * r ? kInf : d2;
}

namespace surfel_detail {

/// The order of covering discs (covering_discs, cover_hits_among), as knn_query orders: by squared
/// distance d2 (world units squared), then by original index.
[[nodiscard]] inline bool cover_less(double d2_a, PointIndex a, double d2_b, PointIndex b) {
  return d2_a < d2_b || (d2_a == d2_b && a < b);
}

/// The sum of blended_normal (shared with blended_normal_among, so both blend alike bit for bit):
/// add() one covering disc at a time, in order; normal() the result.
struct NormalBlend {
  Vec3 n0{0.0};        ///< the hit disc's unit normal
  PointIndex hit = 0;  ///< the hit disc's original index
  Vec3 sum{0.0};       ///< the weighted normals so far
  bool own = false;    ///< the hit disc itself was added
  /// Adds disc `id` (unit normal n, radius r) when its normal is within 45 degrees of n0 (either
  /// side) and plane_d2() (its cover_in_plane_d2 of the hit point, called only then) is finite.
  template <class PlaneD2>
  void add(PointIndex id, const Vec3& n, double r, PlaneD2&& plane_d2) {
    const double c = glm::dot(n, n0);
    if (std::abs(c) < 0.7071) return;
    const double d2 = plane_d2();
    if (!(d2 < kInf)) return;
    own = own || id == hit;
    sum += (1.0 - d2 / (r * r)) * (c < 0.0 ? -n : n);
  }
  /// The blended normal (unit): sum normalised, or n0 when the hit disc was not added or the
  /// sum vanishes.
  [[nodiscard]] Vec3 normal() const {
    const double len = glm::length(sum);
    return own && len > 0.0 ? sum / len : n0;
  }
};

}  // namespace surfel_detail

/// Shading normal at hit point x of disc `hit`: the normals of the discs among `candidates` (at
/// least every disc that covers x: covering_discs, or every centre within blend_reach of x) that
/// cover x (in-plane distance < r, within r/4 of their plane, normal within 45 degrees) blended
/// with weights 1 - d^2/r^2 in the candidates' order, the normalised splat blending of EWA surface
/// splatting (Zwicker et al. 2001, section 5) that hides the facets of flat discs on curved
/// surfaces. Signs are aligned with the hit disc; returns the hit disc's normal when no other disc
/// covers x.
[[nodiscard]] inline Vec3 blended_normal(const SurfelView& s, std::span<const Neighbor> candidates,
                                         PointIndex hit, const Vec3& x) {
  surfel_detail::NormalBlend b{Vec3(s.normals[hit]), hit};
  for (const Neighbor& h : candidates) {
    const double r = s.radii[h.index];
    b.add(h.index, Vec3(s.normals[h.index]), r, [&] { return cover_in_plane_d2(s.centers[h.index], Vec3(s.normals[h.index]), r, x); });
  }
  return b.normal();
}

namespace surfel_detail {

/// The squared reach of cover_descent for a disc of radius r (world units) and a neighbourhood of
/// delta >= 0: (kBlendReachFactor r (1 + 1e-9) + delta)^2, widened past rounding.
[[nodiscard]] inline double cover_reach2(double r, double delta) {
  const double e = kBlendReachFactor * (1.0 + 1e-9) * r + delta;
  return e * e;
}



}  // namespace surfel_detail

/// The discs that cover point x in the sense of blended_normal (in-plane distance < r_i and plane
/// offset <= r_i / 4, tested with blended_normal's own expressions; such a centre c_i lies within
/// sqrt(1 + 1/16) r_i of x, the bound the descent prunes with), appended to `out` (cleared first;
/// Neighbor::distance = |x - c_i|) sorted by (distance, index) as knn_query sorts, so
/// blended_normal over them equals blended_normal over a radius query of blend_reach around x (the
/// same covering discs in the same order). A descent of `index` that prunes each node by its own
/// subtree's largest disc radius (s.node_radii, from surfel_node_radii over this index;
/// s.max_radius without), the per-node radius bound of first_surfel_hit applied to a point: a ball
/// of the global blend_reach holds ~16x the discs where most radii are near the median and the
/// clamp is 4x it (bench/README.md, "surfel render speed").
template <SpatialIndex I>
void covering_discs(const I& index, const SurfelView& s, const Vec3& x, std::vector<Neighbor>& out);

/// A disc that may cover points near a centre (cover_candidates): its original index, the
/// index's position of it (bit for bit), and the disc's centre, normal and radius as the view
/// holds them (copied, so that testing a candidate reads no per-point array).
struct CoverCandidate {
  PointIndex id = 0;  ///< original point index
  Vec3 p{0.0};        ///< the index's position of the point (world coordinates)
  Vec3 c{0.0};        ///< SurfelView::centers[id] (world coordinates)
  glm::vec3 n{0.0f};  ///< SurfelView::normals[id] (unit)
  float r = 0.0f;     ///< disc radius (world units)
};

/// Every disc that may cover some point within `delta` of a centre x0 (cover_candidates), plus a
/// float copy, relative to x0, of each one's index position and a float bound on its squared
/// reach (structure of arrays), with which cover_hits_among rejects most candidates in a
/// conservative float test before the exact one (bench/notes/).
struct CoverCandidates {
  Vec3 x0{0.0};        ///< centre (world coordinates)
  double delta = 0.0;  ///< reach around x0 (world units)
  std::vector<CoverCandidate> cands;  ///< in no particular order
  /// float(p - x0) per axis and a float bound >= |p - x|^2 whenever the exact cover reach
  /// |p - x|^2 <= cover_reach2(r, 0) holds for some x within delta of x0 (see finish).
  std::vector<float> px, py, pz, lim2;
  /// Fills the float arrays from x0, delta and cands (cover_candidates calls it).
  void finish();
};

/// Every disc that may cover some point within `delta` (world units, >= 0) of x0: a superset of
/// covering_discs(x) for every such x, from which covering_discs_among gives exactly
/// covering_discs(x). `out` is refilled (candidates in no particular order). For a render's
/// camera rays, whose hits for the samples of one pixel lie close together, one descent serves
/// many hits (PathTracer's per-pixel cover cache). Throws std::invalid_argument for delta < 0 or
/// NaN.
template <SpatialIndex I>
void cover_candidates(const I& index, const SurfelView& s, const Vec3& x0, double delta, CoverCandidates& out);

/// A covering disc of x among a CoverCandidates set: |p - x|^2 (squared distance of its index
/// position, as covering_discs), its original index, cover_in_plane_d2 of x and the candidate.
struct CoverHit {
  double d2 = 0.0;                  ///< |p - x|^2 (world units squared)
  PointIndex id = 0;                ///< original point index
  double plane_d2 = 0.0;            ///< cover_in_plane_d2(c, n, r, x)
  const CoverCandidate* cand = nullptr;  ///< the candidate (in the set it came from)
};

/// The discs of `set` (cover_candidates(x0, delta)) that cover x, for |x - x0| <= delta (the
/// caller's precondition, not checked): exactly covering_discs(x), with its tests and expressions
/// (d2 = |p - x|^2 within cover_reach2(r, 0), cover_in_plane_d2), sorted as it sorts, by (d2,
/// id). A float test of |p - x|^2 against CoverCandidates::lim2 (4 candidates at a time on SSE2)
/// rejects first; it never rejects a disc the exact tests keep. Expects `set` filled by
/// cover_candidates (its float arrays from finish(): one entry per candidate). `out` is cleared
/// first; its CoverHit::cand point into `set`.
void cover_hits_among(const CoverCandidates& set, const Vec3& x, std::vector<CoverHit>& out);

/// covering_discs(x) from `set` = cover_candidates(x0, delta) with |x - x0| <= delta (the
/// caller's precondition): the same discs in the same order with the same distances, bit for bit
/// (cover_hits_among into the caller's `scratch`, distances turned into |p - x|). `out` is cleared
/// first.
void covering_discs_among(const CoverCandidates& set, const Vec3& x, std::vector<Neighbor>& out,
                          std::vector<CoverHit>& scratch);

/// blended_normal(s, covering_discs(x), hit, x) for |x - x0| <= delta from `set` =
/// cover_candidates(x0, delta), bit for bit: the covering discs of cover_hits_among, blended in
/// its order with blended_normal's terms, from the candidates' copies of normals and radii. `n0`:
/// the normal of disc `hit` (SurfelView::normals[hit]). `scratch` is caller-owned.
[[nodiscard]] Vec3 blended_normal_among(const CoverCandidates& set, PointIndex hit, const glm::vec3& n0, const Vec3& x,
                                        std::vector<CoverHit>& scratch);

/// blended_normal over covering_discs(x); `scratch` is caller-owned.
template <SpatialIndex I>
[[nodiscard]] Vec3 surfel_shading_normal(const I& index, const SurfelView& s, PointIndex hit,
                                         const Vec3& x, std::vector<Neighbor>& scratch) {
  covering_discs(index, s, x, scratch);
  return blended_normal(s, scratch, hit, x);
}

/// Declares (KW = `extern template`) or defines (KW = `template`) the surfel queries for index type
/// I: first_surfel_hit and first_surfel_hit_packet (both SurfelTables), covering_discs,
/// cover_candidates and the ray query with the disc keys they use (RefinedKey over DiscKey, with
/// the per-node radii and boxes). RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES adds the ray query on the
/// float child boxes (SurfelChildBoxesF) for indexes with detail::FloatChildBoxes. As
/// RAYSCAN_RAY_QUERY_INSTANCES: declared extern by the headers of the library's indexes, defined
/// once by their libraries (octree/src/query/surfel_query.cpp, site/src/surfel_instances.cpp).
#define RAYSCAN_SURFEL_INSTANCES(KW, I)                                                                     \
  KW SurfelHit first_surfel_hit<I, SurfelTables::any>(const I&, const SurfelView&, const Ray&, double, double, \
                                                      const LeavingSurface*, bool, std::vector<RayHit>&,     \
                                                      RayQueryStats&);                                       \
  KW SurfelHit first_surfel_hit<I, SurfelTables::best>(const I&, const SurfelView&, const Ray&, double,       \
                                                       double, const LeavingSurface*, bool,                   \
                                                       std::vector<RayHit>&, RayQueryStats&);                 \
  KW void first_surfel_hit_packet<I, SurfelTables::any>(const I&, const SurfelView&, std::span<const Ray>,    \
                                                        double, double, std::span<const LeavingSurface* const>, \
                                                        bool, std::span<SurfelHit>, std::vector<RayHit>&,     \
                                                        RayQueryStats&);                                      \
  KW void first_surfel_hit_packet<I, SurfelTables::best>(const I&, const SurfelView&, std::span<const Ray>,   \
                                                         double, double, std::span<const LeavingSurface* const>, \
                                                         bool, std::span<SurfelHit>, std::vector<RayHit>&,    \
                                                         RayQueryStats&);                                     \
  KW void covering_discs<I>(const I&, const SurfelView&, const Vec3&, std::vector<Neighbor>&);               \
  KW void cover_candidates<I>(const I&, const SurfelView&, const Vec3&, double, CoverCandidates&);           \
  KW void ray_query<I, RefinedKey<DiscKey>>(const I&, const Ray&, const RayQuery&, std::vector<RayHit>&,     \
                                            RayQueryStats*, const RefinedKey<DiscKey>&);                     \
  KW void ray_query<I, RefinedKey<DiscKey, SurfelNodeRadius>>(const I&, const Ray&, const RayQuery&,         \
                                                              std::vector<RayHit>&, RayQueryStats*,          \
                                                              const RefinedKey<DiscKey, SurfelNodeRadius>&); \
  KW void ray_query<I, RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox>>(                                 \
      const I&, const Ray&, const RayQuery&, std::vector<RayHit>&, RayQueryStats*,                           \
      const RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox>&);
#define RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(KW, I)                                                           \
  KW void ray_query<I, RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox, SurfelChildBoxesF<I>>>(         \
      const I&, const Ray&, const RayQuery&, std::vector<RayHit>&, RayQueryStats*,                           \
      const RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox, SurfelChildBoxesF<I>>&);

RAYSCAN_SURFEL_INSTANCES(extern template, Octree)
RAYSCAN_SURFEL_INSTANCES(extern template, KdTree)
RAYSCAN_SURFEL_INSTANCES(extern template, BruteForceIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(extern template, Octree)

}  // namespace rayscan
