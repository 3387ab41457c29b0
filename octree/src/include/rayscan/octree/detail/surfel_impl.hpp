// The definitions of the surfel queries that run the ray query's traversal or its SIMD kernels
// (surfel.hpp declares them, with their documentation): first_surfel_hit, first_surfel_hit_packet
// (the ray query with the disc keys of RefinedKey), covering_discs and cover_candidates (the cover
// descent). Private to the library: included by the translation units that compile the instances
// for the library's index types (octree/src/query/surfel_query.cpp, site/src/surfel_instances.cpp)
// and by the tests. Needs -ffp-contract=off (rayscan_octree_impl's compile option).
#pragma once

#include "rayscan/octree/detail/point_query_impl.hpp"
#include "rayscan/octree/detail/ray_query_impl.hpp"
#include "rayscan/octree/surfel.hpp"

namespace rayscan {

namespace surfel_detail {

/// The descent of covering_discs and cover_candidates: calls f(id, p, d2, r) for every point p
/// of `index` (id its original index, d2 = |p - x|^2, r its disc radius: s.slot_radii[slot], else
/// s.radii[id]) whose disc (radius r_i) may cover some point
/// within `delta` of x: |p - x| <= sqrt(1 + 1/16) r_i + delta, widened past rounding (a superset:
/// the callers test each one exactly). Prunes each node by its own subtree's largest disc radius
/// (s.node_radii; s.max_radius without) on the SIMD child bound (child_dist2) and the distance
/// filter (point_filter with d = 0), as knn_query: a depth_first walk (traverse.hpp) with that
/// node test, its leaf callback the point test. Uses the ray query's per-thread filter scratch.
template <SpatialIndex I, class F>
void cover_descent(const I& index, const SurfelView& s, const Vec3& x, double delta, F&& f) {
  using Node = typename I::Node;
  if (index.empty()) return;
  const auto reach2 = [&](double r) { return cover_reach2(r, delta); };
  const auto node_reach2 = [&](Node n) {
    return reach2(s.node_radii.empty() ? s.max_radius : double(s.node_radii[n]));
  };
  const auto pos = index.positions();
  const IdView ids = index.ids();
  // The filter's survivors and decoded positions: the ray query's per-thread scratch (free
  // between queries; no new thread_local, whose static TLS the Python module cannot spare).
  auto& scratch = rayscan::detail::ray_scratch<Node>();
  // SIMD policies as in knn_query: each child's MINDIST^2 lower bound on its float box
  // (child_dist2), each node's points through the distance filter (point_filter with d = 0); both
  // conservative, every survivor tested exactly below.
  const simd::Kernels& kern = simd::active_kernels();
  const AABB root_box = index.node_bounds(index.root());
  const double vmax = glm::length(x - root_box.center()) + 0.5 * glm::length(root_box.hi - root_box.lo);
  simd::PointFilterD pf{{x.x, x.y, x.z}, {0.0, 0.0, 0.0}, 0.0, -kInf, kInf};  // d = 0: |p - x|^2
  const double slack_d2 = 1e-12 * vmax * vmax + 1e-300;
  [[maybe_unused]] const rayscan::detail::FloatQueryPoint xf = rayscan::detail::float_query_point(index, x);
  // The node test: a node's box within its subtree's reach of x (all children at once on their
  // float boxes where the index has them).
  struct ReachTest {
    const I& index;
    const Vec3& x;
    const decltype(node_reach2)& reach_of;  // node_reach2
    const simd::Kernels& kern;
    const rayscan::detail::FloatQueryPoint& xf;
    Enter operator()(Node n) const {
      return distance2_point_box(x, index.node_bounds(n)) <= reach_of(n) ? Enter::yes : Enter::no;
    }
    bool children([[maybe_unused]] Node n, [[maybe_unused]] unsigned nc, [[maybe_unused]] std::uint32_t& mask) const {
      if constexpr (rayscan::detail::FloatChildBoxes<I>) {
        if (xf.usable && kern.child_dist2 && nc <= 8) {
          float lb2[8];
          kern.child_dist2(index.child_boxes_f(n), xf.q, xf.margin, lb2);
          for (unsigned i = 0; i < nc; ++i)
            mask |= std::uint32_t{double(lb2[i]) <= reach_of(index.child(n, i))} << i;
          return true;
        }
      }
      return false;
    }
  };
  depth_first(index, ReachTest{index, x, node_reach2, kern, xf}, [&](const NodeVisit<Node>& v) {
    const double n_reach2 = node_reach2(v.node);
    const SlotRange sr = v.slots;
    const auto test = [&](std::uint32_t k, const Vec3& p) __attribute__((always_inline)) {
      const Vec3 d = p - x;
      const double d2 = glm::dot(d, d);
      if (d2 > n_reach2) return;
      const PointIndex id = ids[k];
      const float r = s.slot_radii.empty() ? s.radii[id] : s.slot_radii[k];
      if (d2 > reach2(r)) return;
      f(id, p, d2, r);
    };
    if (kern.point_filter && sr.size() >= 4) {
      if (scratch.sel.size() < sr.size()) scratch.sel.resize(sr.size());
      const double* xyz = position_block(pos, sr.begin, sr.size(), scratch.block);
      pf.d2_max = n_reach2 + slack_d2;
      const unsigned m = kern.point_filter(xyz, sr.size(), pf, scratch.sel.data());
      for (unsigned j = 0; j < m; ++j) {
        const double* p = xyz + 3 * std::size_t{scratch.sel[j]};
        test(sr.begin + scratch.sel[j], Vec3(p[0], p[1], p[2]));
      }
    } else {
      for (std::uint32_t k = sr.begin; k < sr.end; ++k) test(k, pos[k]);
    }
  });
}

/// Sorts covering discs by (squared distance, index) as knn_query does and turns the squared
/// distances into distances.
inline void finish_covering(std::vector<Neighbor>& out) {
  std::sort(out.begin(), out.end(),
            [](const Neighbor& a, const Neighbor& b) { return cover_less(a.distance, a.index, b.distance, b.index); });
  for (Neighbor& nb : out) nb.distance = std::sqrt(nb.distance);
}

}  // namespace surfel_detail

template <SpatialIndex I, SurfelTables V>
SurfelHit first_surfel_hit(const I& index, const SurfelView& s, const Ray& ray, double t_min,
                           double t_max, const LeavingSurface* from, bool any_hit,
                           std::vector<RayHit>& hits, RayQueryStats& stats) {
  SurfelHit best;
  const RayQuery q = surfel_query(s, t_min, t_max, any_hit);
  const DiscKey disc_t{&s, ray.origin(), ray.direction(), t_min, t_max, from,
                       s.slot_radii.empty() ? nullptr : s.slot_radii.data(), slot_normals_of(s)};
  constexpr bool kFloatBoxes = detail::FloatChildBoxes<I>;
  // Every node table of the index: the float child boxes where the index has them.
  const auto query_full_tables = [&] {
    if constexpr (kFloatBoxes)
      ray_query(index, ray, q, hits, &stats,
                RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox, SurfelChildBoxesF<I>>{
                    disc_t, {&s}, {&s}, {&index, &s}});
    else
      ray_query(index, ray, q, hits, &stats, RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox>{disc_t, {&s}, {&s}});
  };
  if constexpr (V == SurfelTables::best) {
    // (An empty index has no node and no table; ray_query answers it without reading one.)
    if (!index.empty() && (s.node_radii.empty() || s.node_boxes.empty() || (kFloatBoxes && s.node_boxes_f.empty())))
      throw std::invalid_argument("first_surfel_hit: SurfelTables::best needs the view's node tables");
    query_full_tables();
  } else if (s.node_radii.empty()) {
    ray_query(index, ray, q, hits, &stats, RefinedKey<DiscKey>{disc_t, {}});
  } else if (s.node_boxes.empty()) {
    // Per-node bounds: a disc hit lies within the disc's radius of its centre, and in its box.
    ray_query(index, ray, q, hits, &stats, RefinedKey<DiscKey, SurfelNodeRadius>{disc_t, {&s}});
  } else if (!kFloatBoxes && !s.node_boxes_f.empty()) {
    throw std::invalid_argument("first_surfel_hit: float node boxes on an index without float child boxes");
  } else if (kFloatBoxes && s.node_boxes_f.empty()) {
    ray_query(index, ray, q, hits, &stats, RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox>{disc_t, {&s}, {&s}});
  } else {
    query_full_tables();
  }
  best.queries = 1;
  if (!hits.empty()) {
    best.t = hits.front().key;
    best.index = hits.front().index;
  }
  return best;
}

template <SpatialIndex I, SurfelTables V>
void first_surfel_hit_packet(const I& index, const SurfelView& s, std::span<const Ray> rays, double t_min,
                             double t_max, std::span<const LeavingSurface* const> from, bool any_hit,
                             std::span<SurfelHit> out, std::vector<RayHit>& hits, RayQueryStats& stats) {
  const std::size_t n = rays.size();
  if (n > kMaxRayPacket || out.size() != n || (!from.empty() && from.size() != n))
    throw std::invalid_argument("first_surfel_hit_packet: at most 16 rays, with one result (and surface) each");
  const auto from_of = [&](std::size_t i) { return from.empty() ? nullptr : from[i]; };
  bool packet = !index.empty() && !s.node_radii.empty() && !s.node_boxes.empty() && !s.node_boxes_f.empty();
  if constexpr (detail::FloatChildBoxes<I>) {
    if (packet) {
      using Key = RefinedKey<DiscKey, SurfelNodeRadius, SurfelNodeBox, SurfelChildBoxesF<I>>;
      const RayQuery q = surfel_query(s, t_min, t_max, any_hit);
      // Each key set field by field in place: assigning a built temporary cost 5.8% of a camera-ray
      // render (perf: store-forwarding stalls of the 128-byte copies; bench/notes/).
      static_assert(sizeof(DiscKey) == 96 && sizeof(Key) == 128,
                    "first_surfel_hit_packet sets every field of DiscKey and of its node policies: update it");
      Key keys[kMaxRayPacket];
      const float* slot_radii = s.slot_radii.empty() ? nullptr : s.slot_radii.data();
      const glm::vec3* slot_normals = slot_normals_of(s);
      for (std::size_t i = 0; i < n; ++i) {
        DiscKey& k = keys[i].key;
        k.s = &s;
        k.o = rays[i].origin();
        k.d = rays[i].direction();
        k.t_min = t_min;
        k.t_max = t_max;
        k.from = from_of(i);
        k.slot_radii = slot_radii;
        k.slot_normals = slot_normals;
        keys[i].node_radius_of.s = &s;
        keys[i].node_box_of.s = &s;
        keys[i].child_boxes_f_of.index = &index;
        keys[i].child_boxes_f_of.s = &s;
      }
      detail::for_each_ray_packet(
          index, rays, q, &stats,
          [&](std::size_t b, unsigned m, const detail::Candidate* best, std::uint32_t found) {
            for (unsigned i = 0; i < m; ++i)
              out[b + i] = (found >> i) & 1u ? SurfelHit{best[i].key, best[i].id, 1} : SurfelHit{kInf, 0, 1};
          },
          static_cast<const Key*>(keys));
      return;
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    out[i] = first_surfel_hit<I, V>(index, s, rays[i], t_min, t_max, from_of(i), any_hit, hits, stats);
}

template <SpatialIndex I>
void covering_discs(const I& index, const SurfelView& s, const Vec3& x, std::vector<Neighbor>& out) {
  out.clear();
  surfel_detail::cover_descent(index, s, x, 0.0, [&](PointIndex id, const Vec3&, double d2, float r) {
    if (cover_in_plane_d2(s.centers[id], Vec3(s.normals[id]), r, x) < kInf) out.push_back({id, d2});  // squared until sorted
  });
  surfel_detail::finish_covering(out);
}

template <SpatialIndex I>
void cover_candidates(const I& index, const SurfelView& s, const Vec3& x0, double delta, CoverCandidates& out) {
  if (!(delta >= 0.0)) throw std::invalid_argument("cover_candidates: delta must be >= 0");
  out.x0 = x0;
  out.delta = delta;
  out.cands.clear();
  surfel_detail::cover_descent(index, s, x0, delta, [&](PointIndex id, const Vec3& p, double, float r) {
    out.cands.push_back({id, p, s.centers[id], s.normals[id], r});
  });
  out.finish();
}

}  // namespace rayscan
