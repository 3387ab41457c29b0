#include "rayscan/render/render.hpp"

#include "integrator.hpp"

#include "rayscan/render/color.hpp"

#include "rayscan/octree/point_query.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/base/threads.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <type_traits>

namespace rayscan::render {

RenderSettings make_settings(const Scene& scene, std::span<const Vec3> centers,
                             std::span<const Color> albedo, double radius) {
  if (!scene.camera) throw std::invalid_argument("render: the scene has no camera");
  RenderSettings s{*scene.camera, {}, scene.background, scene.sun, scene.up, scene.spp, scene.seed,
                   scene.output.aovs};
  s.integrator.centers = centers;
  s.integrator.albedo.by_index = albedo;
  s.integrator.radius = radius;
  s.integrator.hit = scene.hit;
  s.integrator.node_distance = scene.node_distance;
  s.integrator.max_depth = scene.max_depth;
  s.integrator.rr_depth = scene.russian_roulette_depth;
  s.integrator.ray_offset = scene.ray_offset;
  return s;
}

namespace {

// The strata of n points of a pixel (stratified_pixel_point's rows and columns), laid out once for
// a render's RenderSettings::albedo_samples rather than for every ray; point() gives the same
// points, bit for bit. n >= 1, and point's j < n, are the caller's to check.
class PixelStrata {
 public:
  explicit PixelStrata(std::uint32_t n) : n_(n) {
    rows_ = std::uint32_t(std::sqrt(double(n)));
    while (std::uint64_t(rows_) * rows_ > n) --rows_;
    while (std::uint64_t(rows_ + 1) * (rows_ + 1) <= n) ++rows_;
    q_ = n / rows_;
    narrow_ = rows_ - n % rows_;
  }
  [[nodiscard]] std::uint32_t size() const { return n_; }
  // Point j at the jitter (ju, jv) within its stratum.
  [[nodiscard]] PixelSample point(std::uint32_t j, double ju, double jv) const {
    std::uint32_t row, col, cols;
    if (j < narrow_ * q_) {
      row = j / q_, col = j % q_, cols = q_;
    } else {
      const std::uint32_t k = j - narrow_ * q_;
      row = narrow_ + k / (q_ + 1), col = k % (q_ + 1), cols = q_ + 1;
    }
    return {(col + ju) / cols - 0.5, (row + jv) / rows_ - 0.5, 1.0 / (double(rows_) * cols)};
  }

 private:
  std::uint32_t n_, rows_, q_, narrow_;  // rows_ rows: the first narrow_ of q_ strata, then of q_ + 1
};

}  // namespace

PixelSample stratified_pixel_point(std::uint32_t j, std::uint32_t n, double ju, double jv) {
  if (n == 0 || j >= n)
    throw std::invalid_argument("stratified_pixel_point: point " + std::to_string(j) + " of " + std::to_string(n));
  return PixelStrata(n).point(j, ju, jv);
}

namespace {

// The sample index of albedo ray j's stream, Sampler(seed, x, y, kAlbedoStream + j): apart from
// the beauty's samples 0 .. spp - 1 (a scene's spp is at most 2^20), so the albedo's jitter does not repeat the
// beauty's camera rays.
constexpr std::uint32_t kAlbedoStream = 1u << 31;

// What a pixel block holds open on its index while it is traced: on a COPC file the cache scope
// (the nodes the block reaches stay decoded; its end trims the cache to the budget), nothing
// elsewhere.
struct NoScope {};
template <class I>
auto block_scope(const I& idx) {
  if constexpr (std::is_same_v<I, io::CopcIndex>) return std::make_unique<io::CopcIndex::QueryScope>(idx);
  else return NoScope{};
}

// Tiles [first, last) of the T x T tile grid (row-major tile order).
template <class I>
void render_tiles(const I& idx, const RenderSettings& s, Framebuffer& fb, const RenderOptions& opt,
                  RenderStats& stats, std::uint32_t first, std::uint32_t last,
                  std::chrono::steady_clock::time_point t0, std::atomic<bool>& first_done) {
  const Sky sky(s.background, s.sun, s.up);
  const PathTracer<I> tracer(idx, s.integrator, sky, opt.time_queries);
  const std::uint32_t W = fb.width, H = fb.height, T = std::max(1u, opt.tile_size);
  const std::uint32_t tiles_x = (W + T - 1) / T;
  const bool any_aov = !s.aovs.empty();
  const bool want_cost = !fb.cost.empty();
  const Camera& cam = s.camera;
  // Packets of camera rays: not for the cost AOV (node visits are counted per packet,
  // not per pixel). On COPC in place too: a packet decodes a node when its first ray reaches it,
  // as a single ray does, and the answers are the single rays'.
  const bool packets = opt.packets && !want_cost;
  constexpr std::uint32_t kBlock = 4;  // 4x4 pixels = kMaxRayPacket rays
  // The camera ray of pixel (x, y) for sampler stream smp: pixel jitter (u, v), then the lens
  // sample, in this order on every path (the image depends on it).
  auto camera_ray = [&](std::uint32_t x, std::uint32_t y, Sampler& smp) {
    const double u = x + smp.uniform() - 0.5, v = y + smp.uniform() - 0.5;
    const double lu = smp.uniform(), lv = smp.uniform();
    return cam.generate_ray(u, v, lu, lv);
  };
  static_assert(kBlock * kBlock == kMaxRayPacket);
  // The albedo AOV of pixel (x, y) over s.albedo_samples stratified rays: the stratum-area-weighted
  // mean of the hits' albedos, averaged sRGB-encoded (RenderSettings::albedo_samples says why),
  // and in `coverage` the summed area of the strata whose ray hit (Framebuffer::coverage).
  // Hits of one colour give it back as it is, not through the round trip to sRGB and back.
  // The strata are laid out once here (render_image_impl checked albedo_samples >= 1).
  const PixelStrata strata(s.albedo_samples);
  auto mean_albedo = [&](std::uint32_t x, std::uint32_t y, std::vector<RayHit>& hits, TraceCounters& c,
                         float& coverage) {
    double sum[3] = {0.0, 0.0, 0.0}, area = 0.0;
    Color first(0.0f);
    bool one_colour = true;
    for (std::uint32_t j = 0; j < strata.size(); ++j) {
      Sampler smp(s.seed, x, y, kAlbedoStream + j);
      const double ju = smp.uniform(), jv = smp.uniform();
      const PixelSample ps = strata.point(j, ju, jv);
      SurfaceHit h;
      if (!tracer.intersect(cam.generate_ray(x + ps.dx, y + ps.dy), h, hits, c)) continue;
      const Color a = s.integrator.albedo.at(h.index, h.slot);
      if (area == 0.0) first = a;
      one_colour = one_colour && a == first;
      for (int k = 0; k < 3; ++k) sum[k] += ps.area * double(linear_to_srgb(a[k]));
      area += ps.area;
    }
    coverage = float(std::min(area, 1.0));
    if (area == 0.0 || one_colour) return first;
    Color m;
    for (int k = 0; k < 3; ++k) m[k] = srgb_to_linear(float(sum[k] / area));
    return m;
  };
  std::mutex stats_mutex;

  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(first, last, 1), [&](const auto& range) {
    std::vector<RayHit> hits;
    hits.reserve(4);
    TraceCounters c;
    std::vector<Ray> rays;  // one packet's camera rays (Ray has no default constructor)
    rays.reserve(kMaxRayPacket);
    std::vector<Sampler> smps;
    smps.reserve(kMaxRayPacket);
    for (std::uint32_t tile = range.begin(); tile != range.end(); ++tile) {
      // Thrown out of the parallel loop: TBB skips the ranges not started and rethrows it here.
      throw_if_cancelled(opt.cancel);
      const std::uint64_t q_before = c.queries;
      const std::uint32_t x0 = (tile % tiles_x) * T, y0 = (tile / tiles_x) * T;
      const std::uint32_t x1 = std::min(W, x0 + T), y1 = std::min(H, y0 + T);
      // 4x4 pixel blocks, each traced within one scope: on COPC the nodes it decodes are held
      // only while its 16 pixels are traced, so what the threads in flight hold beyond the cache
      // budget is what a block's rays reach, not a whole tile's.
      for (std::uint32_t by = y0; by < y1; by += kBlock)
        for (std::uint32_t bx = x0; bx < x1; bx += kBlock) {
          [[maybe_unused]] const auto scope = block_scope(idx);
          const std::uint32_t bw = std::min(kBlock, x1 - bx), bh = std::min(kBlock, y1 - by);
          if (packets) {
            // Sample j of the block's pixels (row-major) as one packet; each pixel keeps its own
            // stream Sampler(seed, x, y, j) and sums its samples in the order j = 0, 1, ...
            const std::size_t n = std::size_t(bw) * bh;
            Color sum[kMaxRayPacket], L[kMaxRayPacket];
            std::fill(sum, sum + n, Color(0.0f));
            for (std::uint32_t j = 0; j < s.spp; ++j) {
              rays.clear();
              smps.clear();
              for (std::uint32_t y = by; y < by + bh; ++y)
                for (std::uint32_t x = bx; x < bx + bw; ++x) {
                  rays.push_back(camera_ray(x, y, smps.emplace_back(s.seed, x, y, j)));
                }
              tracer.trace_packet(rays, smps, std::span(L, n), hits, c);
              for (std::size_t i = 0; i < n; ++i) sum[i] += L[i];
            }
            for (std::uint32_t k = 0; k < n; ++k)
              fb.beauty[std::size_t(by + k / bw) * W + bx + k % bw] = sum[k] / float(s.spp);
          }
          for (std::uint32_t y = by; y < by + bh; ++y)
            for (std::uint32_t x = bx; x < bx + bw; ++x) {
              const std::size_t p = std::size_t(y) * W + x;
              if (!packets) {
                const std::uint64_t nodes_before = c.nodes_visited;
                Color sum(0.0f);
                for (std::uint32_t j = 0; j < s.spp; ++j) {
                  Sampler smp(s.seed, x, y, j);
                  sum += tracer.trace(camera_ray(x, y, smp), smp, hits, c);
                }
                fb.beauty[p] = sum / float(s.spp);
                if (want_cost) fb.cost[p] = float(double(c.nodes_visited - nodes_before) / s.spp);
              }
              if (!any_aov) continue;
              SurfaceHit h;  // the AOV ray (after the cost AOV was taken, so not part of it)
              const bool hit = tracer.intersect(cam.generate_ray(x, y), h, hits, c);
              if (!fb.depth.empty()) fb.depth[p] = hit ? float(h.t) : std::numeric_limits<float>::infinity();
              if (!fb.normal.empty()) fb.normal[p] = hit ? glm::vec3(h.normal) : glm::vec3(0.0f);
              if (!fb.position.empty())
                fb.position[p] = hit ? glm::vec3(h.position - fb.position_origin) : glm::vec3(0.0f);
              if (!fb.index.empty()) fb.index[p] = hit ? h.index : kNoPoint;
              if (!fb.albedo.empty()) {
                if (s.albedo_samples > 1) {
                  fb.albedo[p] = mean_albedo(x, y, hits, c, fb.coverage[p]);
                } else {
                  fb.albedo[p] = hit ? s.integrator.albedo.at(h.index, h.slot) : Color(0.0f);
                  fb.coverage[p] = hit ? 1.0f : 0.0f;
                }
              }
            }
        }
      if (opt.progress) opt.progress->tile_done(c.queries - q_before);
      if (!first_done.load(std::memory_order_relaxed) && !first_done.exchange(true))
        stats.first_tile_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    std::lock_guard lock(stats_mutex);
    stats.queries += c.queries;
    stats.nodes_visited += c.nodes_visited;
    stats.points_tested += c.points_tested;
    stats.query_seconds += double(c.query_ns) * 1e-9;
  });
}

// Calls f(channel bytes span) for every channel vector of fb that is in use, in a fixed order.
template <class F>
void for_each_channel(Framebuffer& fb, F&& f) {
  f(std::as_writable_bytes(std::span(fb.beauty)), sizeof(Color));
  f(std::as_writable_bytes(std::span(fb.depth)), sizeof(float));
  f(std::as_writable_bytes(std::span(fb.normal)), sizeof(glm::vec3));
  f(std::as_writable_bytes(std::span(fb.position)), sizeof(glm::vec3));
  f(std::as_writable_bytes(std::span(fb.index)), sizeof(std::uint32_t));
  f(std::as_writable_bytes(std::span(fb.albedo)), sizeof(Color));
  f(std::as_writable_bytes(std::span(fb.cost)), sizeof(float));
  f(std::as_writable_bytes(std::span(fb.coverage)), sizeof(float));
}

// The pixel rectangle of tile t (row-major tiles of T x T pixels, cut at the image edge).
struct TileRect {
  std::uint32_t x0, y0, x1, y1;  // pixels [x0, x1) x [y0, y1)
};

TileRect tile_rect(const Framebuffer& fb, std::uint32_t T, std::uint64_t t) {
  const std::uint32_t tiles_x = (fb.width + T - 1) / T;
  const std::uint32_t x0 = std::uint32_t(t % tiles_x) * T, y0 = std::uint32_t(t / tiles_x) * T;
  return {x0, y0, std::min(fb.width, x0 + T), std::min(fb.height, y0 + T)};
}

}  // namespace

std::vector<std::byte> pack_tiles(Framebuffer& fb, unsigned tile_size, std::uint64_t first, std::uint64_t count) {
  std::vector<std::byte> out;
  const std::uint32_t T = std::max(1u, tile_size);
  for (std::uint64_t t = first; t < first + count; ++t) {
    const TileRect r = tile_rect(fb, T, t);
    for_each_channel(fb, [&](std::span<std::byte> ch, std::size_t px) {
      if (ch.empty()) return;
      for (std::uint32_t y = r.y0; y < r.y1; ++y) {
        const std::size_t a = (std::size_t(y) * fb.width + r.x0) * px, b = (std::size_t(y) * fb.width + r.x1) * px;
        out.insert(out.end(), ch.begin() + a, ch.begin() + b);
      }
    });
  }
  return out;
}

void unpack_tiles(Framebuffer& fb, unsigned tile_size, std::uint64_t first, std::uint64_t count,
                  std::span<const std::byte> bytes) {
  const std::uint32_t T = std::max(1u, tile_size);
  std::size_t off = 0;
  for (std::uint64_t t = first; t < first + count; ++t) {
    const TileRect r = tile_rect(fb, T, t);
    for_each_channel(fb, [&](std::span<std::byte> ch, std::size_t px) {
      if (ch.empty()) return;
      for (std::uint32_t y = r.y0; y < r.y1; ++y) {
        const std::size_t a = (std::size_t(y) * fb.width + r.x0) * px;
        read_bytes(bytes, off, ch.subspan(a, std::size_t(r.x1 - r.x0) * px));
      }
    });
  }
  if (off != bytes.size())
    throw std::runtime_error("render: tile message of " + std::to_string(bytes.size()) + " bytes, expected " +
                             std::to_string(off));
}

Framebuffer empty_framebuffer(const Camera& camera, std::span<const Aov> aovs) {
  const std::uint32_t W = camera.width(), H = camera.height();
  const std::size_t n = std::size_t(W) * H;
  Framebuffer fb;
  fb.width = W;
  fb.height = H;
  fb.beauty.assign(n, Color(0.0f));
  fb.position_origin = camera.center();
  for (Aov a : aovs) switch (a) {
      case Aov::depth: fb.depth.assign(n, 0.0f); break;
      case Aov::normal: fb.normal.assign(n, glm::vec3(0.0f)); break;
      case Aov::position: fb.position.assign(n, glm::vec3(0.0f)); break;
      case Aov::index: fb.index.assign(n, kNoPoint); break;
      case Aov::albedo:
        fb.albedo.assign(n, Color(0.0f));
        fb.coverage.assign(n, 0.0f);
        break;
      case Aov::cost: fb.cost.assign(n, 0.0f); break;
    }
  return fb;
}

namespace {
template <class I>
RenderStats render_image_impl(const I& index, const RenderSettings& s, Framebuffer& fb, const RenderOptions& opt) {
  const std::uint32_t W = s.camera.width(), H = s.camera.height();
  const std::size_t n = std::size_t(W) * H;
  fb = empty_framebuffer(s.camera, s.aovs);
  const std::size_t npts = index.positions().size();
  if ((!s.integrator.centers.empty() && npts != s.integrator.centers.size()) || !s.integrator.albedo.covers(npts))
    throw std::invalid_argument("render: index, centres and albedo sizes differ");
  if (s.spp == 0) throw std::invalid_argument("render: spp must be >= 1");
  if (s.albedo_samples == 0 || s.albedo_samples > (1u << 20))
    throw std::invalid_argument("render: albedo_samples must be in [1, 1048576], got " + std::to_string(s.albedo_samples));

  RenderStats stats;
  const unsigned threads = resolve_threads(opt.threads);
  stats.threads = threads;
  tbb::task_arena arena(static_cast<int>(threads));
  const auto t0 = std::chrono::steady_clock::now();
  std::atomic<bool> first_done{false};
  const std::uint32_t T = std::max(1u, opt.tile_size);
  const std::uint32_t tiles = ((W + T - 1) / T) * ((H + T - 1) / T);
  WorkDistributor* dist = opt.distributor;
  if (!dist || dist->size() <= 1) {
    arena.execute([&] { render_tiles(index, s, fb, opt, stats, 0, tiles, t0, first_done); });
  } else {
    // Tiles handed out by the distributor (rayscan::mpi's work queue); the root gathers them.
    WorkStage stage;
    stage.items = tiles;
    stage.batch = threads;
    stage.compute = [&](std::uint64_t first, std::uint64_t count) {
      arena.execute([&] {
        render_tiles(index, s, fb, opt, stats, std::uint32_t(first), std::uint32_t(first + count), t0, first_done);
      });
    };
    stage.pack = [&](std::uint64_t first, std::uint64_t count) { return pack_tiles(fb, T, first, count); };
    stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
      unpack_tiles(fb, T, first, count, bytes);
      if (opt.progress)
        for (std::uint64_t k = 0; k < count; ++k) opt.progress->tile_done(0);
    };
    dist->run(stage);
    std::uint64_t totals[3] = {stats.queries, stats.nodes_visited, stats.points_tested};
    dist->sum_to_root(totals);
    stats.queries = totals[0];
    stats.nodes_visited = totals[1];
    stats.points_tested = totals[2];
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool albedo_rays = s.albedo_samples > 1 && !fb.albedo.empty();
  stats.primary_rays = std::uint64_t(n) * (s.spp + (s.aovs.empty() ? 0 : 1) + (albedo_rays ? s.albedo_samples : 0));
  if (opt.progress) opt.progress->finish();
  return stats;
}

}  // namespace

RenderStats render_image(const Site& site, const RenderSettings& s, Framebuffer& fb, const RenderOptions& opt) {
  return site.visit([&](auto& index) {
    if constexpr (is_copc_index<decltype(index)>) {
      if (s.integrator.primitive != Primitive::sphere)
        throw std::invalid_argument("render: a COPC file is traced in place in sphere mode only");
      return render_image_impl(index, s, fb, opt);  // each 4x4 pixel block a CopcIndex::QueryScope
    } else {
      return render_image_impl(index, s, fb, opt);
    }
  });
}

}  // namespace rayscan::render
