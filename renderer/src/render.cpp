#include "rayscan/render/render.hpp"

#include "rayscan/point_query.hpp"
#include "rayscan/threads.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <mutex>

namespace rayscan::render {

RenderSettings make_settings(const Scene& scene, std::span<const Vec3> centers,
                             std::span<const Color> albedo, double radius) {
  if (!scene.camera) throw std::invalid_argument("render: the scene has no camera");
  RenderSettings s{*scene.camera, {}, scene.background, scene.sun, scene.up, scene.spp, scene.seed,
                   scene.output.aovs};
  s.integrator.centers = centers;
  s.integrator.albedo = albedo;
  s.integrator.radius = radius;
  s.integrator.hit = scene.hit;
  s.integrator.node_distance = scene.node_distance;
  s.integrator.max_depth = scene.max_depth;
  s.integrator.rr_depth = scene.russian_roulette_depth;
  s.integrator.ray_offset = scene.ray_offset;
  return s;
}

double median_nn_spacing(const io::MappedIndex& index, std::span<const Vec3> positions, std::size_t max_samples) {
  return median_nn_spacing_of(index, positions, max_samples);
}

namespace {

template <class I>
void render_tiles(const I& idx, const RenderSettings& s, Framebuffer& fb, const RenderOptions& opt,
                  RenderStats& stats) {
  const Sky sky(s.background, s.sun, s.up);
  const PathTracer<I> tracer(idx, s.integrator, sky, opt.time_queries);
  const std::uint32_t W = fb.width, H = fb.height, T = std::max(1u, opt.tile_size);
  const std::uint32_t tiles_x = (W + T - 1) / T, tiles_y = (H + T - 1) / T;
  const bool any_aov = !s.aovs.empty();
  const bool want_cost = !fb.cost.empty();
  const Camera& cam = s.camera;
  std::mutex stats_mutex;

  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, tiles_x * tiles_y, 1), [&](const auto& range) {
    std::vector<RayHit> hits;
    hits.reserve(4);
    TraceCounters c;
    for (std::uint32_t tile = range.begin(); tile != range.end(); ++tile) {
      const std::uint64_t q_before = c.queries;
      const std::uint32_t x0 = (tile % tiles_x) * T, y0 = (tile / tiles_x) * T;
      const std::uint32_t x1 = std::min(W, x0 + T), y1 = std::min(H, y0 + T);
      for (std::uint32_t y = y0; y < y1; ++y)
        for (std::uint32_t x = x0; x < x1; ++x) {
          const std::size_t p = std::size_t(y) * W + x;
          const std::uint64_t nodes_before = c.nodes_visited;
          Color sum(0.0f);
          for (std::uint32_t j = 0; j < s.spp; ++j) {
            Sampler smp(s.seed, x, y, j);
            const double u = x + smp.uniform() - 0.5, v = y + smp.uniform() - 0.5;
            const double lu = smp.uniform(), lv = smp.uniform();
            sum += tracer.trace(cam.generate_ray(u, v, lu, lv), smp, hits, c);
          }
          fb.beauty[p] = sum / float(s.spp);
          if (want_cost) fb.cost[p] = float(double(c.nodes_visited - nodes_before) / s.spp);
          if (!any_aov) continue;
          SurfaceHit h;  // the AOV ray (after the cost AOV was taken, so not part of it)
          const bool hit = tracer.intersect(cam.generate_ray(x, y), h, hits, c);
          if (!fb.depth.empty()) fb.depth[p] = hit ? float(h.t) : std::numeric_limits<float>::infinity();
          if (!fb.normal.empty()) fb.normal[p] = hit ? glm::vec3(h.normal) : glm::vec3(0.0f);
          if (!fb.position.empty())
            fb.position[p] = hit ? glm::vec3(h.position - fb.position_origin) : glm::vec3(0.0f);
          if (!fb.index.empty()) fb.index[p] = hit ? h.index : kNoPoint;
          if (!fb.albedo.empty()) fb.albedo[p] = hit ? s.integrator.albedo[h.index] : Color(0.0f);
        }
      if (opt.progress) opt.progress->tile_done(c.queries - q_before);
    }
    std::lock_guard lock(stats_mutex);
    stats.queries += c.queries;
    stats.nodes_visited += c.nodes_visited;
    stats.points_tested += c.points_tested;
    stats.query_seconds += double(c.query_ns) * 1e-9;
  });
}

}  // namespace

namespace {
template <class I>
RenderStats render_image_impl(const I& index, const RenderSettings& s, Framebuffer& fb,
                              const RenderOptions& opt) {
  const std::uint32_t W = s.camera.width(), H = s.camera.height();
  const std::size_t n = std::size_t(W) * H;
  fb = Framebuffer{};
  fb.width = W;
  fb.height = H;
  fb.beauty.assign(n, Color(0.0f));
  fb.position_origin = s.camera.center();
  for (Aov a : s.aovs) switch (a) {
      case Aov::depth: fb.depth.assign(n, 0.0f); break;
      case Aov::normal: fb.normal.assign(n, glm::vec3(0.0f)); break;
      case Aov::position: fb.position.assign(n, glm::vec3(0.0f)); break;
      case Aov::index: fb.index.assign(n, kNoPoint); break;
      case Aov::albedo: fb.albedo.assign(n, Color(0.0f)); break;
      case Aov::cost: fb.cost.assign(n, 0.0f); break;
    }
  const std::size_t npts = index.positions().size();
  if (npts != s.integrator.centers.size() || s.integrator.albedo.size() != s.integrator.centers.size())
    throw std::invalid_argument("render: index, centres and albedo sizes differ");
  if (s.spp == 0) throw std::invalid_argument("render: spp must be >= 1");

  RenderStats stats;
  const unsigned threads = resolve_threads(opt.threads);
  stats.threads = threads;
  tbb::task_arena arena(static_cast<int>(threads));
  const auto t0 = std::chrono::steady_clock::now();
  arena.execute([&] {
    render_tiles(index, s, fb, opt, stats);
  });
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats.primary_rays = std::uint64_t(n) * (s.spp + (s.aovs.empty() ? 0 : 1));
  if (opt.progress) opt.progress->finish();
  return stats;
}

}  // namespace

RenderStats render_image(const AnyIndex& index, const RenderSettings& s, Framebuffer& fb,
                         const RenderOptions& opt) {
  return std::visit([&](const auto& idx) { return render_image_impl(idx, s, fb, opt); }, index);
}

RenderStats render_image(const io::MappedIndex& index, const RenderSettings& s, Framebuffer& fb,
                         const RenderOptions& opt) {
  return render_image_impl(index, s, fb, opt);
}

}  // namespace rayscan::render
