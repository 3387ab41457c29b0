// The path tracer: Ray Tracing in One Weekend's ray_color loop (sections 9-10) over spheres
// centred on the points, found by the paper's ray query (Algorithm 1, order sphere_hit), with
// next-event estimation of the sun and optional Russian roulette (pbrt-v4 section 13.1.1).
#pragma once

#include "rayscan/ray_query.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/sampler.hpp"
#include "rayscan/render/scene.hpp"
#include "rayscan/render/sky.hpp"
#include "rayscan/render/surfel.hpp"

#include <chrono>
#include <numbers>
#include <span>
#include <vector>

namespace rayscan::render {

/// Everything the integrator reads, independent of the index type. Spans must outlive the
/// integrator. Sphere centres are read from the index itself (index.positions()[RayHit::slot]),
/// so an index file is traced without a copy of its points.
struct IntegratorInputs {
  std::span<const Vec3> centers;    ///< the cloud's positions by original index, world coordinates:
                                    ///< the disc centres of surfel mode (empty: sphere mode only)
  AlbedoSource albedo;              ///< per-point albedo, linear [0,1] (array or rule)
  double radius = 1.0;              ///< sphere radius r, world units (> 0)
  HitMode hit = HitMode::sphere;
  NodeDistance node_distance = NodeDistance::exact;  ///< node pruning bound of the ray query
  std::uint32_t max_depth = 4;      ///< rays per path (camera ray + bounces; shadow rays not
                                    ///< counted), as RTIOW's max_depth: 1 = sun light only
  std::uint32_t rr_depth = 0;       ///< Russian roulette from this depth on; 0 = off
  double ray_offset = 1e-3;         ///< offset of secondary ray origins along n, fraction of r
  Primitive primitive = Primitive::sphere;  ///< spheres of `radius` or the discs of `surfels`
  SurfelView surfels;               ///< per-point discs (Primitive::surfel only; centres = centers)
};

/// Per-thread work counters (summed by the renderer).
struct TraceCounters {
  std::uint64_t queries = 0;         ///< ray queries issued (camera, bounce and shadow rays)
  std::uint64_t nodes_visited = 0;   ///< index nodes whose points were tested
  std::uint64_t points_tested = 0;   ///< point predicates evaluated
  std::int64_t query_ns = 0;         ///< time inside ray_query (only when timing is enabled)
};

/// The first surface a ray meets.
struct SurfaceHit {
  double t = kInf;        ///< ray parameter of the hit (world units along the unit direction)
  PointIndex index = 0;   ///< original index of the point whose sphere was hit
  std::uint32_t slot = 0; ///< its storage slot in the index (sphere mode; surfel mode: 0)
  Vec3 position{0.0};     ///< world position of the hit
  Vec3 normal{0.0};       ///< unit normal (hit - centre) / r, or the disc normal, facing the ray
  double radius = 0.0;    ///< radius of the sphere or disc hit, world units
};

/// Path tracer over one index type (a template so the hot loop has no virtual calls).
template <SpatialIndex I>
class PathTracer {
 public:
  /// `index` must be built over `in.centers`. Throws std::invalid_argument for radius <= 0.
  PathTracer(const I& index, const IntegratorInputs& in, const Sky& sky, bool time_queries = false)
      : index_(index), in_(in), sky_(sky), time_(time_queries) {
    if (!(in.radius > 0.0)) throw std::invalid_argument("render: sphere radius must be > 0");
    if (in.primitive == Primitive::surfel &&
        (in.surfels.normals.size() != in.centers.size() || in.surfels.radii.size() != in.centers.size() ||
         !(in.surfels.max_radius > 0.0)))
      throw std::invalid_argument("render: surfel mode needs a normal and a radius > 0 per point");
    if (in.primitive == Primitive::surfel && in.albedo.by_index.size() != in.centers.size())
      throw std::invalid_argument("render: surfel mode needs the albedo by original point index");
    if (!in.albedo.covers(index.positions().size()))
      throw std::invalid_argument("render: the albedo does not cover the index's points");
    if (in_.primitive == Primitive::surfel && in_.surfels.node_radii.empty()) {
      node_radii_ = surfel_node_radii(index, in_.surfels.radii);
      in_.surfels.node_radii = node_radii_;
    }
    query_.k = 1;
    query_.radius = in.radius;
    query_.t_min = 0.0;
    query_.node_distance = in.node_distance;
    query_.order = in.hit == HitMode::sphere ? RayOrder::sphere_hit : RayOrder::time;
    query_.validate();
    shadow_query_ = query_;
    shadow_query_.any_hit = true;  // a shadow ray only asks whether anything blocks the sun
  }

  PathTracer(const PathTracer&) = delete;  // in_.surfels.node_radii views node_radii_
  PathTracer& operator=(const PathTracer&) = delete;

  /// True when any sphere blocks `ray` at t >= 0 (shadow rays; the core's any_hit mode).
  /// `from`: the surface the ray leaves, whose own discs are ignored (surfel mode).
  bool occluded(const Ray& ray, std::vector<RayHit>& hits, TraceCounters& c,
                const LeavingSurface* from = nullptr) const {
    RayQueryStats st;
    if (in_.primitive == Primitive::surfel) {
      const SurfelHit sh = first_surfel_hit(index_, in_.surfels, ray, 0.0, kInf, from, true, hits, st);
      c.queries += sh.queries;
      c.nodes_visited += st.nodes_visited;
      c.points_tested += st.points_tested;
      return sh.t < kInf;
    }
    ray_query(index_, ray, shadow_query_, hits, &st);
    ++c.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    return !hits.empty();
  }

  /// First hit along `ray` with t >= 0 (see HitMode). `hits` is caller-owned scratch.
  /// `from`: the surface the ray leaves, whose own discs are ignored (surfel mode).
  bool intersect(const Ray& ray, SurfaceHit& h, std::vector<RayHit>& hits, TraceCounters& c,
                 const LeavingSurface* from = nullptr) const {
    RayQueryStats st;
    if (in_.primitive == Primitive::surfel) return intersect_surfel(ray, h, hits, c, from);
    if (time_) {
      const auto t0 = std::chrono::steady_clock::now();
      ray_query(index_, ray, query_, hits, &st);
      c.query_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                        std::chrono::steady_clock::now() - t0).count();
    } else {
      ray_query(index_, ray, query_, hits, &st);
    }
    ++c.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    if (hits.empty()) return false;
    const RayHit& rh = hits.front();
    const double r = in_.radius;
    // sphere_hit: rh.t is already the entry parameter. closest_point: rh.t is t_p of the point
    // with the smallest t within r; enter its sphere (never before the ray origin).
    h.t = in_.hit == HitMode::sphere ? rh.t
                                     : std::max(0.0, sphere_entry(rh.t, rh.distance * rh.distance, r));
    h.index = rh.index;
    h.slot = rh.slot;
    h.position = ray.at(h.t);
    const Vec3 n = h.position - index_.positions()[rh.slot];
    const double len = glm::length(n);
    h.normal = len > 0.0 ? n / len : -ray.direction();
    if (glm::dot(h.normal, ray.direction()) > 0.0) h.normal = -h.normal;
    h.radius = r;
    return true;
  }

  /// First disc hit (see first_surfel_hit); the normal is the disc's, facing the ray.
  bool intersect_surfel(const Ray& ray, SurfaceHit& h, std::vector<RayHit>& hits, TraceCounters& c,
                        const LeavingSurface* from) const {
    RayQueryStats st;
    SurfelHit sh;
    if (time_) {
      const auto t0 = std::chrono::steady_clock::now();
      sh = first_surfel_hit(index_, in_.surfels, ray, 0.0, kInf, from, false, hits, st);
      c.query_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                        std::chrono::steady_clock::now() - t0).count();
    } else {
      sh = first_surfel_hit(index_, in_.surfels, ray, 0.0, kInf, from, false, hits, st);
    }
    c.queries += sh.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    if (!(sh.t < kInf)) return false;
    h.t = sh.t;
    h.index = sh.index;
    h.position = ray.at(sh.t);
    thread_local std::vector<Neighbor> near;
    h.normal = surfel_shading_normal(index_, in_.surfels, sh.index, h.position, near);
    if (glm::dot(h.normal, ray.direction()) > 0.0) h.normal = -h.normal;
    h.radius = in_.surfels.radii[sh.index];
    return true;
  }

  /// Radiance along a camera ray (one path sample). `first`, when non-null, receives the first
  /// hit (or t = inf for a miss).
  Color trace(Ray ray, Sampler& s, std::vector<RayHit>& hits, TraceCounters& c,
              SurfaceHit* first = nullptr) const {
    Color L(0.0f), beta(1.0f);
    const bool surfel = in_.primitive == Primitive::surfel;
    LeavingSurface from;
    for (std::uint32_t depth = 0;; ++depth) {
      SurfaceHit h;
      if (!intersect(ray, h, hits, c, depth > 0 && surfel ? &from : nullptr)) {
        L += beta * sky_.background(ray.direction());
        if (depth == 0) L += sky_.sun_disk(ray.direction());
        if (first && depth == 0) first->t = kInf;
        break;
      }
      if (first && depth == 0) *first = h;
      const Color a = in_.albedo.at(h.index, h.slot);
      const Vec3 origin = h.position + (in_.ray_offset * h.radius) * h.normal;
      from = {h.index, h.position, h.normal, h.radius, surfel ? in_.surfels.thickness_at(h.index) : 0.0};
      const LeavingSurface* leaving = surfel ? &from : nullptr;
      // Next-event estimation of the sun: Lambertian f = a/pi, times E cos(theta).
      if (sky_.has_sun()) {
        const Vec3 l = sky_.sample_sun(s.uniform(), s.uniform());
        const double cos_l = glm::dot(l, h.normal);
        if (cos_l > 0.0) {
          if (!occluded(Ray(origin, l), hits, c, leaving))
            L += beta * a * sky_.sun_irradiance() * float(cos_l / std::numbers::pi);
        }
      }
      if (depth + 1 >= in_.max_depth) break;  // RTIOW max_depth: rays per path
      // Cosine-weighted bounce (Malley's method): the pdf cancels cos/pi, leaving beta *= albedo.
      beta *= a;
      if (in_.rr_depth > 0 && depth + 1 >= in_.rr_depth) {
        const float q = std::min(0.95f, std::max({beta.r, beta.g, beta.b}));
        if (s.uniform() >= q) break;
        beta /= q;
      }
      if (beta == Color(0.0f)) break;
      ray = Ray(origin, cosine_direction(h.normal, s.uniform(), s.uniform()));
    }
    return L;
  }

  /// Cosine-distributed unit direction around unit n (Malley's method over an orthonormal basis
  /// from Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
  static Vec3 cosine_direction(const Vec3& n, double u1, double u2) {
    const double sign = std::copysign(1.0, n.z);
    const double a = -1.0 / (sign + n.z);
    const double b = n.x * n.y * a;
    const Vec3 t(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    const Vec3 bt(b, sign + n.y * n.y * a, -n.y);
    const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
    const double x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0, 1.0 - u1));
    return x * t + y * bt + z * n;
  }

 private:
  const I& index_;
  IntegratorInputs in_;
  std::vector<float> node_radii_;  ///< surfel_node_radii over index_ (surfel mode)
  const Sky& sky_;
  bool time_;
  RayQuery query_;
  RayQuery shadow_query_;
};

}  // namespace rayscan::render
