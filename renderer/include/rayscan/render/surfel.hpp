// Surfels: oriented discs centred on the points (Pfister et al. 2000, "Surfels: Surface Elements as
// Rendering Primitives"; ray tracing them as in Wald & Seidel 2005, "Interactive Ray Tracing of
// Point-based Models", section 3), found through the paper's ray query: candidates within the
// maximum disc radius of the ray in order of their sphere entry (RayOrder::sphere_hit, a lower
// bound of the disc hit), then the exact ray-disc test in double.
#pragma once

#include "rayscan/ray_query.hpp"

#include <glm/vec3.hpp>

#include <algorithm>
#include <span>
#include <vector>

namespace rayscan::render {

/// The geometry each point stands for (issue 16, section 1).
enum class Primitive {
  sphere,  ///< the paper's model: a sphere of one global radius, shaded with the sphere normal
  surfel   ///< an oriented disc with a per-point normal and radius
};

/// The discs of a cloud, indexed by original point index (spans must outlive the view).
struct SurfelView {
  std::span<const Vec3> centers;       ///< disc centres (the cloud's positions), world coordinates
  std::span<const glm::vec3> normals;  ///< unit disc normals
  std::span<const float> radii;        ///< disc radii, world units (> 0)
  double max_radius = 0.0;             ///< max of radii: the candidate radius of the ray query
};

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

/// The surface a shadow or bounce ray leaves (issue 16, 1.4): the discs of that surface near the
/// origin are ignored, so flat lit surfaces do not shadow themselves (no "acne").
struct LeavingSurface {
  PointIndex index = 0;  ///< the disc or sphere that was hit
  Vec3 position{0.0};    ///< hit point, world coordinates
  Vec3 normal{0.0};      ///< unit normal at the hit, facing the side the new ray leaves into
  double radius = 0.0;   ///< radius of the disc or sphere that was hit, world units
};

/// True when candidate disc j belongs to the surface `from` lies on: j is the disc left, or its
/// normal is within 45 degrees of the surface normal and its centre lies within half a radius of
/// the tangent plane at the origin and within two disc diameters of it (the overlapping
/// neighbours of a scanned surface; a wall meeting the floor at a corner has another normal and
/// is kept).
[[nodiscard]] inline bool same_surface(const LeavingSurface& from, PointIndex j, const Vec3& c_j,
                                       const Vec3& n_j, double r_j) {
  if (j == from.index) return true;
  if (std::abs(glm::dot(n_j, from.normal)) < 0.7071) return false;
  const Vec3 v = c_j - from.position;
  const double r = std::max(from.radius, r_j);
  const double h = glm::dot(v, from.normal);
  if (std::abs(h) > 0.5 * r) return false;
  const double lim = 2.0 * (from.radius + r_j);
  return glm::dot(v, v) <= lim * lim;
}

/// Result of first_surfel_hit().
struct SurfelHit {
  double t = kInf;       ///< ray parameter of the hit, kInf for a miss
  PointIndex index = 0;  ///< the disc hit
  std::uint32_t queries = 0;  ///< ray queries issued
};

/// The first disc hit along `ray` with t in [t_min, t_max] (or, with any_hit, some disc hit in it),
/// ignoring the discs of `from` when given. Candidates come from ray_query with order sphere_hit
/// and the maximum radius R: a disc of radius r <= R around c lies inside the sphere of radius R
/// around c, so its hit is never before that sphere's entry key. The search alternates a k = 1
/// probe (the next key a, as the sphere renderer's query) with a query of every candidate whose key
/// lies in the window [a, a + 2R], tested exactly in key order; it stops once the best hit is not
/// after the window's end. `hits` is caller-owned scratch (on return it holds the last window's
/// candidates, used by blended_normal); `stats` accumulates the query counters.
template <SpatialIndex I>
SurfelHit first_surfel_hit(const I& index, const SurfelView& s, const Ray& ray, double t_min,
                           double t_max, const LeavingSurface* from, bool any_hit,
                           std::vector<RayHit>& hits, RayQueryStats& stats) {
  SurfelHit best;
  const double R = s.max_radius;
  const double W = 2.0 * R;
  RayQuery probe;
  probe.order = RayOrder::sphere_hit;
  probe.radius = R;
  probe.k = 1;
  // A hit at t >= t_min has t_p >= t_min - r, so its sphere key is >= t_min - 2R.
  probe.t_min = t_min - 2.0 * R;
  probe.t_max = t_max;
  RayQuery window = probe;
  window.k = kAllPoints;
  const Vec3& o = ray.origin();
  const Vec3& d = ray.direction();
  // Ids already tested whose key equals the last window's end (ties across windows).
  thread_local std::vector<PointIndex> tied;
  tied.clear();
  double done_to = -kInf;  // keys <= done_to were tested (except ties not in `tied`)
  for (;;) {
    RayQueryStats st;
    ray_query(index, ray, probe, hits, &st);
    ++best.queries;
    if (hits.empty()) break;
    const double a = hits.front().key;
    if (a > best.t) break;
    window.t_min = a;
    window.t_max = std::min(t_max, a + W);
    ray_query(index, ray, window, hits, &st);
    ++best.queries;
    stats.nodes_visited += st.nodes_visited;
    stats.points_tested += st.points_tested;
    for (const RayHit& h : hits) {
      if (h.key > best.t) break;
      if (h.key == done_to && std::find(tied.begin(), tied.end(), h.index) != tied.end()) continue;
      const Vec3& c = s.centers[h.index];
      const double r = s.radii[h.index];
      const Vec3 n(s.normals[h.index]);
      if (from && same_surface(*from, h.index, c, n, r)) continue;
      const double t = ray_disc_t(o, d, c, n, r, t_min, std::min(t_max, best.t));
      if (t < best.t || (t == best.t && t < kInf && h.index < best.index)) {
        best.t = t;
        best.index = h.index;
        if (any_hit) return best;
      }
    }
    const double end = window.t_max;
    if (best.t <= end || end >= t_max) break;
    tied.clear();
    for (const RayHit& h : hits)
      if (h.key == end) tied.push_back(h.index);
    done_to = end;
    probe.t_min = end;
  }
  return best;
}

/// Shading normal at hit point x of disc `hit`: the normals of the discs among `candidates` (the
/// last batch of first_surfel_hit) that cover x (in-plane distance < r, within r/4 of their
/// plane, normal within 45 degrees) blended with weights 1 - d^2/r^2, the normalised splat blending
/// of EWA surface splatting (Zwicker et al. 2001, section 5) that hides the facets of flat discs
/// on curved surfaces. Signs are aligned with the hit disc; returns the hit disc's normal when no
/// other disc covers x.
[[nodiscard]] inline Vec3 blended_normal(const SurfelView& s, std::span<const RayHit> candidates,
                                         PointIndex hit, const Vec3& x) {
  const Vec3 n0(s.normals[hit]);
  Vec3 sum(0.0);
  bool own = false;
  for (const RayHit& h : candidates) {
    const Vec3 n(s.normals[h.index]);
    const double c = glm::dot(n, n0);
    if (std::abs(c) < 0.7071) continue;
    const Vec3 v = x - s.centers[h.index];
    const double r = s.radii[h.index];
    const double off = glm::dot(v, n);
    if (std::abs(off) > 0.25 * r) continue;
    const double d2 = glm::dot(v, v) - off * off;
    if (d2 >= r * r) continue;
    own = own || h.index == hit;
    sum += (1.0 - d2 / (r * r)) * (c < 0.0 ? -n : n);
  }
  const double len = glm::length(sum);
  return own && len > 0.0 ? sum / len : n0;
}

}  // namespace rayscan::render
