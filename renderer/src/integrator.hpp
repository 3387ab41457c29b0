// The path tracer: Ray Tracing in One Weekend's ray_color loop (sections 9-10) over spheres
// centred on the points, found by the paper's ray query (Algorithm 1, order sphere_hit), with
// next-event estimation of the sun and optional Russian roulette (pbrt-v4 section 13.1.1).
#pragma once

#include "rayscan/octree/ray_query.hpp"
#include "rayscan/render/material.hpp"
#include "sampler.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"
#include "sky.hpp"
#include "rayscan/octree/surfel.hpp"

#include <atomic>
#include <chrono>
#include <memory>
#include <new>
#include <numbers>
#include <optional>
#include <span>
#include <type_traits>
#include <vector>

namespace rayscan::render {


/// The candidate discs of one pixel's camera hits in surfel mode (PathTracer::trace_packet): every
/// disc that may cover a point within `delta` of `x0` (cover_candidates), so the shading normal of
/// each later sample of that pixel whose hit lies within delta is found among them
/// (blended_normal_among: the same normal, bit for bit) instead of by a descent from the root.
struct CoverCache {
  std::uint64_t owner = 0;  ///< the PathTracer that filled it (0: empty)
  CoverCandidates cands;    ///< cover_candidates(its x0, the tracer's delta)
};

namespace surfel_detail {
/// Unique ids of PathTracers of every index type (a CoverCache filled by one is never used by
/// another).
inline std::atomic<std::uint64_t> next_path_tracer_id{1};
}  // namespace surfel_detail

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
    if (in_.primitive == Primitive::surfel && in_.surfels.node_boxes.empty()) {
      node_boxes_ = surfel_node_boxes(index, in_.surfels);
      in_.surfels.node_boxes = node_boxes_;
    }
    if (in_.primitive == Primitive::surfel && in_.surfels.slot_radii.empty()) {
      slot_radii_ = surfel_slot_radii(index, in_.surfels.radii);
      in_.surfels.slot_radii = slot_radii_;
    }
    if (in_.primitive == Primitive::surfel && in_.surfels.slot_normals.empty()) {
      slot_normals_ = surfel_slot_normals(index, in_.surfels.centers, in_.surfels.normals);
      in_.surfels.slot_normals = slot_normals_;
    }
    if constexpr (detail::FloatChildBoxes<I>) {
      if (in_.primitive == Primitive::surfel && in_.surfels.node_boxes_f.empty()) {
        node_boxes_f_ = surfel_node_boxes_f(index, in_.surfels.node_boxes);
        in_.surfels.node_boxes_f = node_boxes_f_;
      }
    }
    // The cover caches' reach: 2 x the median disc radius (surfel mode's in.radius); 0.7, 1 and
    // 1.5 x were measured with a cache per lane, 1.5, 2 and 3 x with the lanes' caches shared
    // (bench/notes/).
    cover_delta_ = 2.0 * in.radius;
    query_.k = 1;
    query_.radius = in.radius;
    query_.t_min = 0.0;
    query_.node_distance = in.node_distance;
    query_.order = in.hit == HitMode::sphere ? RayOrder::sphere_hit : RayOrder::time;
    query_.validate();
    shadow_query_ = query_;
    shadow_query_.any_hit = true;  // a shadow ray only asks whether anything blocks the sun
  }

  PathTracer(const PathTracer&) = delete;  // in_.surfels' node tables view the members below
  PathTracer& operator=(const PathTracer&) = delete;

  /// True when any sphere blocks `ray` at t >= 0 (shadow rays; the core's any_hit mode).
  /// `from`: the surface the ray leaves, whose own discs are ignored (surfel mode).
  bool occluded(const Ray& ray, std::vector<RayHit>& hits, TraceCounters& c,
                const LeavingSurface* from = nullptr) const {
    RayQueryStats st;
    if (in_.primitive == Primitive::surfel) {
      SurfelHit sh;
      timed(c, [&] { sh = first_surfel_hit<I, SurfelTables::best>(index_, in_.surfels, ray, 0.0, kInf, from, true, hits, st); });
      c.queries += sh.queries;
      c.nodes_visited += st.nodes_visited;
      c.points_tested += st.points_tested;
      return sh.t < kInf;
    }
    bool blocked;
    timed(c, [&] { blocked = ray_first_hit(index_, ray, shadow_query_, &st).has_value(); });
    ++c.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    return blocked;
  }

  /// First hit along `ray` with t >= 0 (see HitMode). `hits` is caller-owned scratch.
  /// `from`: the surface the ray leaves, whose own discs are ignored (surfel mode).
  bool intersect(const Ray& ray, SurfaceHit& h, std::vector<RayHit>& hits, TraceCounters& c,
                 const LeavingSurface* from = nullptr) const {
    RayQueryStats st;
    if (in_.primitive == Primitive::surfel) return intersect_surfel(ray, h, hits, c, from);
    std::optional<RayHit> rh;
    timed(c, [&] { rh = ray_first_hit(index_, ray, query_, &st); });
    ++c.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    if (!rh) return false;
    surface_at(ray, *rh, h);
    return true;
  }

  /// The sphere-mode surface of the first hit `rh` of `ray` (ray_first_hit's answer for query_).
  void surface_at(const Ray& ray, const RayHit& rh, SurfaceHit& h) const {
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
  }

  /// First disc hit (see first_surfel_hit); the normal is the disc's, facing the ray.
  bool intersect_surfel(const Ray& ray, SurfaceHit& h, std::vector<RayHit>& hits, TraceCounters& c,
                        const LeavingSurface* from) const {
    RayQueryStats st;
    SurfelHit sh;
    timed(c, [&] { sh = first_surfel_hit<I, SurfelTables::best>(index_, in_.surfels, ray, 0.0, kInf, from, false, hits, st); });
    c.queries += sh.queries;
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    if (!(sh.t < kInf)) return false;
    surfel_surface_at(ray, sh, h);
    return true;
  }

  /// Per-thread scratch of the shading normals (one thread_local object for both paths).
  struct NormalScratch {
    std::vector<Neighbor> near;      ///< covering_discs of a hit without a cover cache
    std::vector<CoverHit> covering;  ///< cover_hits_among of a hit with one
  };
  static NormalScratch& normal_scratch() {
    thread_local NormalScratch s;
    return s;
  }

  /// The surfel-mode surface of the disc hit `sh` (first_surfel_hit's answer, t < inf) of `ray`:
  /// the hit point, the blended shading normal facing the ray, the disc's radius. With `caches`
  /// (the per-lane cover caches of a camera packet; `own`: the lane of this ray's pixel), the
  /// covering discs come from the candidates of the first cache, own lane first, whose centre lies
  /// within cover_delta_ of the hit (any such cache gives exactly the descent's discs), else the
  /// own lane's cache is refilled around the hit: the same normal, bit for bit, from whichever.
  void surfel_surface_at(const Ray& ray, const SurfelHit& sh, SurfaceHit& h, std::span<CoverCache> caches = {},
                         std::size_t own = 0) const {
    h.t = sh.t;
    h.index = sh.index;
    h.position = ray.at(sh.t);
    if (!caches.empty()) {
      // |x - x0|^2 <= 0.998 delta^2, i.e. within 0.999 delta: |x - x0| <= delta despite rounding.
      const auto serves = [&](const CoverCache& c) {
        const Vec3 v = h.position - c.cands.x0;
        return c.owner == id_ && glm::dot(v, v) <= 0.998 * cover_delta_ * cover_delta_;
      };
      const CoverCache* use = serves(caches[own]) ? &caches[own] : nullptr;
      // A neighbouring pixel's cache often reaches this hit too (its samples land within a few
      // pixel footprints): one test per lane instead of a descent (bench/notes/).
      for (std::size_t k = 0; !use && k < caches.size(); ++k)
        if (k != own && serves(caches[k])) use = &caches[k];
      if (!use) {
        cover_candidates(index_, in_.surfels, h.position, cover_delta_, caches[own].cands);
        caches[own].owner = id_;
        use = &caches[own];
      }
      h.normal = blended_normal_among(use->cands, sh.index, in_.surfels.normals[sh.index], h.position,
                                      normal_scratch().covering);
    } else {
      h.normal = surfel_shading_normal(index_, in_.surfels, sh.index, h.position, normal_scratch().near);
    }
    if (glm::dot(h.normal, ray.direction()) > 0.0) h.normal = -h.normal;
    h.radius = in_.surfels.radii[sh.index];
  }

  /// The state of one path between the stages of a path vertex (see trace): the ray to trace
  /// next, the radiance so far and the throughput, and, after hit_vertex, the vertex's albedo,
  /// secondary-ray origin and pending shadow ray towards the sun.
  struct Path {
    Ray ray;
    Color L{0.0f}, beta{1.0f};
    std::uint32_t depth = 0;   ///< rays of the path traced so far, minus one (0 = camera ray)
    LeavingSurface from;       ///< the surface of the current vertex
    Color a{0.0f};             ///< albedo at the current vertex
    Vec3 origin{0.0};          ///< origin of the vertex's secondary rays (offset along n)
    Ray shadow;                ///< shadow ray towards the sun (when shadow_pending)
    double cos_l = 0.0;        ///< cos(theta) of the sun direction at the vertex
    bool shadow_pending = false;
    explicit Path(const Ray& r) : ray(r), shadow(r) {}
  };

  /// Radiance along a camera ray (one path sample). `first`, when non-null, receives the first
  /// hit (or t = inf for a miss).
  Color trace(Ray ray, Sampler& s, std::vector<RayHit>& hits, TraceCounters& c,
              SurfaceHit* first = nullptr) const {
    Path p(ray);
    continue_path(p, s, hits, c, first);
    return p.L;
  }

  /// Radiance of n = rays.size() <= kMaxRayPacket coherent camera rays (one sample of each pixel
  /// of a small pixel tile, sampler streams `s`), bit-identical to trace() on each ray with its
  /// own stream. The n paths advance together, one vertex at a time (a
  /// small wavefront): the camera rays go through ray_first_hit_packet, the shadow rays of their
  /// hits, which all point at the sun from within the block's footprint, through
  /// ray_any_hit_packet, the bounce rays, which are incoherent (in packets they measured no
  /// faster: bench/README.md) and their shadow rays, through ray_first_hit_each (two at a time,
  /// interleaved, on CPUs that gain from it: interleaved_pairs()); then each path scatters.
  /// Every stage consumes a path's sampler stream in the order trace() does and adds to its L in
  /// the same order, and the packet and pair answers are ray_first_hit's, so nothing depends on
  /// which paths share a packet.
  /// Surfel mode likewise, with first_surfel_hit_packet for the camera rays and for their shadow
  /// rays (each leaving its own surface), bit-identical to first_surfel_hit on each ray, and the
  /// bounce rays and their shadow rays one by one; the
  /// shading normals of the camera hits come from the per-lane CoverCaches (the same normals as
  /// trace()'s descent, bit for bit).
  void trace_packet(std::span<const Ray> rays, std::span<Sampler> s, std::span<Color> out,
                    std::vector<RayHit>& hits, TraceCounters& c) const {
    const std::size_t n = rays.size();
    if (n > kMaxRayPacket || s.size() != n || out.size() != n)
      throw std::invalid_argument("render: a ray packet holds at most 16 rays with one sampler and output each");
    const bool surfel = in_.primitive == Primitive::surfel;
    // The paths in uninitialised storage (an array of std::optional<Path> was zero-filled on every
    // call, ~4 KB of rep stos per packet); Path is trivially destructible.
    static_assert(std::is_trivially_destructible_v<Path>);
    alignas(Path) unsigned char path_buf[kMaxRayPacket][sizeof(Path)];
    Path* p[kMaxRayPacket];
    std::uint32_t live = 0;  // paths still going
    for (std::size_t i = 0; i < n; ++i) {
      p[i] = ::new (static_cast<void*>(path_buf[i])) Path(rays[i]);
      live |= 1u << i;
    }
    thread_local std::vector<Ray> wave;  // the packet's rays (Ray has no default constructor)
    RayQueryStats st;
    for (bool camera = true; live; camera = false) {
      // The first hits of the live paths' rays.
      std::uint8_t lane[kMaxRayPacket];
      std::size_t m = 0;
      wave.clear();
      for (std::size_t i = 0; i < n; ++i)
        if ((live >> i) & 1u) {
          lane[m++] = static_cast<std::uint8_t>(i);
          wave.push_back(p[i]->ray);
        }
      // Each lane's vertex right after its query (one SurfaceHit at a time: an array of them was
      // zero-filled per stage).
      std::uint32_t shadowed = 0;
      const auto vertex = [&](std::size_t j, bool hit, const SurfaceHit& h) {
        Path& q = *p[lane[j]];
        if (!hit_vertex(q, hit, h, s[lane[j]], nullptr)) live &= ~(1u << lane[j]);
        else if (q.shadow_pending) shadowed |= 1u << lane[j];
      };
      if (surfel && camera) {
        // The camera rays as one packet (each ray's answer is the one-ray query's).
        SurfelHit sh[kMaxRayPacket];
        timed(c, [&] {
          first_surfel_hit_packet<I, SurfelTables::best>(index_, in_.surfels, std::span<const Ray>(wave), 0.0, kInf, {},
                                                         false, std::span(sh, m), hits, st);
        });
        // One cover cache per pixel of the packet (the caller traces the samples of one pixel
        // block in turn), each also serving the other lanes' hits within its reach: a pointer's
        // worth of static TLS, the caches on the heap.
        thread_local std::unique_ptr<CoverCache[]> covers;
        if (!covers) covers = std::make_unique<CoverCache[]>(kMaxRayPacket);
        for (std::size_t j = 0; j < m; ++j) {
          SurfaceHit h;
          if (sh[j].t < kInf) {
            // The cache pays when the samples of a pixel land within its reach: judged by the
            // hit of the neighbouring pixel in the row (lane j ^ 1), about one footprint away.
            // Farther (a distant view), each sample would refill it: the plain descent instead.
            const std::size_t nb = j ^ 1u;
            bool cached = true;
            if (nb < m && sh[nb].t < kInf) {
              const Vec3 v = wave[j].at(sh[j].t) - wave[nb].at(sh[nb].t);
              cached = glm::dot(v, v) <= 4.0 * cover_delta_ * cover_delta_;
            }
            surfel_surface_at(wave[j], sh[j], h,
                              cached ? std::span<CoverCache>(covers.get(), kMaxRayPacket) : std::span<CoverCache>{},
                              lane[j]);
          }
          vertex(j, sh[j].t < kInf, h);
        }
        c.queries += m;
      } else if (surfel) {
        // Surfel bounce rays, one by one (incoherent), each leaving its vertex's surface (as trace()).
        for (std::size_t j = 0; j < m; ++j) {
          SurfaceHit h;
          const bool hit = intersect(wave[j], h, hits, c, &p[lane[j]]->from);
          vertex(j, hit, h);
        }
      } else {
        // The camera rays as one packet; the bounce rays, which are incoherent, through
        // ray_first_hit_each. Each answer is the one-ray query's (as trace()'s intersect).
        std::optional<RayHit> rh[kMaxRayPacket];
        timed(c, [&] {
          if (camera)
            ray_first_hit_packet(index_, std::span<const Ray>(wave), query_, std::span(rh, m), &st);
          else
            ray_first_hit_each(index_, std::span<const Ray>(wave), query_, std::span(rh, m), &st);
        });
        for (std::size_t j = 0; j < m; ++j) {
          SurfaceHit h;
          if (rh[j]) surface_at(wave[j], *rh[j], h);
          vertex(j, rh[j].has_value(), h);
        }
        c.queries += m;
      }
      // The shadow rays of the hits (all towards the sun): a packet for the camera rays' hits,
      // whose origins lie within the block's footprint; after a bounce (the origins are
      // scattered: in packets they measured slower, bench/README.md) through ray_first_hit_each,
      // or one by one in surfel mode.
      if (shadowed && !camera && surfel) {
        for (std::size_t i = 0; i < n; ++i)
          if (((shadowed >> i) & 1u) && !occluded(p[i]->shadow, hits, c, &p[i]->from)) add_sun(*p[i]);
      } else if (shadowed) {
        std::size_t ns = 0;
        wave.clear();
        const LeavingSurface* from[kMaxRayPacket];
        for (std::size_t i = 0; i < n; ++i)
          if ((shadowed >> i) & 1u) {
            from[ns] = &p[i]->from;
            lane[ns++] = static_cast<std::uint8_t>(i);
            wave.push_back(p[i]->shadow);
          }
        bool blocked[kMaxRayPacket];
        if (surfel) {
          SurfelHit sh[kMaxRayPacket];
          timed(c, [&] {
            first_surfel_hit_packet<I, SurfelTables::best>(index_, in_.surfels, std::span<const Ray>(wave), 0.0, kInf,
                                                           std::span<const LeavingSurface* const>(from, ns), true,
                                                           std::span(sh, ns), hits, st);
          });
          for (std::size_t j = 0; j < ns; ++j) blocked[j] = sh[j].t < kInf;
        } else if (camera) {
          timed(c, [&] { ray_any_hit_packet(index_, std::span<const Ray>(wave), shadow_query_, std::span(blocked, ns), &st); });
        } else {
          std::optional<RayHit> rh[kMaxRayPacket];
          timed(c, [&] { ray_first_hit_each(index_, std::span<const Ray>(wave), shadow_query_, std::span(rh, ns), &st); });
          for (std::size_t j = 0; j < ns; ++j) blocked[j] = rh[j].has_value();
        }
        c.queries += ns;
        for (std::size_t j = 0; j < ns; ++j)
          if (!blocked[j]) add_sun(*p[lane[j]]);
      }
      for (std::size_t i = 0; i < n; ++i)
        if (((live >> i) & 1u) && !scatter(*p[i], s[i])) live &= ~(1u << i);
    }
    c.nodes_visited += st.nodes_visited;
    c.points_tested += st.points_tested;
    for (std::size_t i = 0; i < n; ++i) out[i] = p[i]->L;
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
  /// Runs the ray query `query()` and, when timing (RenderOptions::time_queries: bench_render's
  /// cost split), adds its time to c.query_ns: every query of a path (camera, bounce and shadow
  /// rays, single or in packets) goes through here, so the split covers them all.
  template <class F>
  __attribute__((always_inline)) void timed(TraceCounters& c, F&& query) const {
    if (!time_) {
      query();
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    query();
    c.query_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
  }

  /// The path loop of trace() from p.ray at p.depth: intersect, hit_vertex, the shadow ray, scatter.
  void continue_path(Path& p, Sampler& s, std::vector<RayHit>& hits, TraceCounters& c, SurfaceHit* first) const {
    const bool surfel = in_.primitive == Primitive::surfel;
    for (;;) {
      SurfaceHit h;
      const bool hit = intersect(p.ray, h, hits, c, p.depth > 0 && surfel ? &p.from : nullptr);
      if (!hit_vertex(p, hit, h, s, first)) break;
      if (p.shadow_pending && !occluded(p.shadow, hits, c, surfel ? &p.from : nullptr)) add_sun(p);
      if (!scatter(p, s)) break;
    }
  }

  /// A path vertex after the ray query of p.ray: a miss adds the sky (and the sun disk, seen
  /// directly by a camera ray) and ends the path (false); a hit sets the vertex (albedo, origin,
  /// leaving surface) and samples the sun (next-event estimation: 2 samples of `s` when there is
  /// a sun), leaving the shadow ray pending when the sun is above the surface.
  bool hit_vertex(Path& p, bool hit, const SurfaceHit& h, Sampler& s, SurfaceHit* first) const {
    p.shadow_pending = false;
    if (!hit) {
      p.L += p.beta * sky_.background(p.ray.direction());
      if (p.depth == 0) p.L += sky_.sun_disk(p.ray.direction());
      if (first && p.depth == 0) first->t = kInf;
      return false;
    }
    if (first && p.depth == 0) *first = h;
    p.a = in_.albedo.at(h.index, h.slot);
    p.origin = h.position + (in_.ray_offset * h.radius) * h.normal;
    p.from = {h.index, h.position, h.normal, h.radius,
              in_.primitive == Primitive::surfel ? in_.surfels.thickness_at(h.index) : 0.0};
    // Next-event estimation of the sun: Lambertian f = a/pi, times E cos(theta).
    if (sky_.has_sun()) {
      const Vec3 l = sky_.sample_sun(s.uniform(), s.uniform());
      p.cos_l = glm::dot(l, h.normal);
      if (p.cos_l > 0.0) {
        p.shadow = Ray(p.origin, l);
        p.shadow_pending = true;
      }
    }
    return true;
  }

  /// The sun's contribution at the vertex whose shadow ray was not blocked.
  void add_sun(Path& p) const { p.L += p.beta * p.a * sky_.sun_irradiance() * float(p.cos_l / std::numbers::pi); }

  /// The bounce after a vertex: false ends the path (max_depth, Russian roulette, zero
  /// throughput); else p.ray becomes the cosine-weighted bounce ray and p.depth grows by one.
  bool scatter(Path& p, Sampler& s) const {
    if (p.depth + 1 >= in_.max_depth) return false;  // RTIOW max_depth: rays per path
    // Cosine-weighted bounce (Malley's method): the pdf cancels cos/pi, leaving beta *= albedo.
    p.beta *= p.a;
    if (in_.rr_depth > 0 && p.depth + 1 >= in_.rr_depth) {
      const float q = std::min(0.95f, std::max({p.beta.r, p.beta.g, p.beta.b}));
      if (s.uniform() >= q) return false;
      p.beta /= q;
    }
    if (p.beta == Color(0.0f)) return false;
    p.ray = Ray(p.origin, cosine_direction(p.from.normal, s.uniform(), s.uniform()));
    ++p.depth;
    return true;
  }

  const I& index_;
  IntegratorInputs in_;
  std::vector<float> node_radii_;  ///< surfel_node_radii over index_ (surfel mode)
  std::vector<AABB> node_boxes_;   ///< surfel_node_boxes over index_ (surfel mode)
  std::vector<float> slot_radii_;    ///< surfel_slot_radii over index_ (surfel mode)
  std::vector<glm::vec3> slot_normals_;  ///< surfel_slot_normals over index_ (surfel mode; may be empty)
  std::vector<float> node_boxes_f_;  ///< surfel_node_boxes_f of node_boxes_ (surfel mode, FloatChildBoxes)
  const Sky& sky_;
  bool time_;
  std::uint64_t id_ = surfel_detail::next_path_tracer_id.fetch_add(1);  ///< owner id of the CoverCaches it fills
  double cover_delta_ = 0.0;  ///< CoverCache reach, world units
  RayQuery query_;
  RayQuery shadow_query_;
};

}  // namespace rayscan::render
