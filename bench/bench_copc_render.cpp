// Time to the first traced tile and total render time for a COPC file
// traced in place (io::CopcIndex: header + hierarchy, nodes decoded as rays reach them) vs the
// same file read whole (io::read_point_cloud) and rendered through the in-memory octree.
//   bench_copc_render inplace|whole FILE.copc.laz [width height spp cache]
// One mode per process (peak RSS is per process); bench/copc_render.sh interleaves the modes.
// Prints one line: mode first_tile_s total_s decodes nodes maxrss_mb cache_peak_mb queries lit_px radius.
#include "bench_cli.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/render.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;

int main(int argc, char** argv) {
  std::string mode;
  std::filesystem::path file;
  unsigned w = 64, h = 48, spp = 1;
  std::size_t cache_mb = 2048;
  CLI::App app{"bench_copc_render: time to the first traced tile and the whole render of a COPC file, in place or read whole"};
  app.add_option("MODE", mode, "inplace (CopcIndex) or whole (read_point_cloud)")->required()
      ->check(CLI::IsMember({"inplace", "whole"}));
  app.add_option("FILE", file, "COPC file")->required();
  app.add_option("WIDTH", w, "image width, pixels")->check(CLI::Range(1u, 1u << 15))->capture_default_str();
  app.add_option("HEIGHT", h, "image height, pixels")->check(CLI::Range(1u, 1u << 15))->capture_default_str();
  app.add_option("SPP", spp, "samples per pixel")->check(CLI::Range(1u, 1u << 16))->capture_default_str();
  app.add_option("CACHE", cache_mb, "decoded-node cache, MiB (inplace)")->check(CLI::Range(std::size_t{1}, std::size_t{1} << 24))
      ->capture_default_str();
  rayscan::bench::parse_or_exit(app, argc, argv);
  const std::size_t cache = cache_mb << 20;
  try {
    const auto t0 = std::chrono::steady_clock::now();
    // The camera: from the COPC header's root cube (no point read), looking at its centre.
    const io::CopcInfo info = io::read_copc_info(file);
    const double e = info.halfsize;
    LookAtParams la;
    la.look_at = info.center - Vec3(0, 0, 0.5 * e);
    la.position = info.center + Vec3(-1.2 * e, -1.6 * e, 1.4 * e);
    RenderJobOptions o;
    o.scene.camera = Camera::look_at(la, w, h);
    o.scene.spp = spp;
    o.scene.max_depth = 2;
    o.scene.seed = 1;
    o.scene.radius = info.spacing / std::ldexp(1.0, std::max(0, info.depth - 1));  // the deepest level's spacing
    o.scene.material.mode = ColorMode::classification;
    o.scene.cloud = file;
    o.write = false;
    o.control.threads = 2;
    o.cache_bytes = cache;
    PointCloud pc;
    double read_s = 0;
    if (mode == "whole") {
      pc = io::read_point_cloud(file, io::ReadOptions{.scalars = false});
      read_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      o.cloud = &pc;
    }
    const RenderJobResult r = run_render(o);
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::size_t hit = 0;
    for (Color c : r.image.beauty) hit += c.r > 0;
    std::printf("%s first_tile_s %.3f total_s %.3f decodes %llu nodes %zu maxrss_mb %.1f cache_peak_mb %.1f "
                "queries %llu lit_px %zu radius %.4g\n",
                mode.c_str(), read_s + r.first_tile_seconds, total, (unsigned long long)r.copc_decodes,
                info.nodes.size(), double(ru.ru_maxrss) / 1024.0, double(r.copc_peak_cache_bytes) / 1048576.0,
                (unsigned long long)r.stats.queries, hit, r.radius.radius);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_copc_render: %s\n", e.what());
    return 2;
  }
  return 0;
}
