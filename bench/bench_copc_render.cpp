// Time to the first traced tile and total render time for a COPC file
// traced in place (io::CopcIndex: header + hierarchy, nodes decoded as rays reach them) vs the
// same file read whole (io::read_point_cloud) and rendered through the in-memory octree.
//   bench_copc_render inplace|whole FILE.copc.laz [width height spp cache]
// One mode per process (peak RSS is per process); bench/copc_render.sh interleaves the modes.
// Prints one line: mode first_tile_s total_s decodes nodes maxrss_mb cache_peak_mb queries lit_px radius.
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
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_copc_render inplace|whole FILE.copc.laz [width height spp cache_mb]\n");
    return 2;
  }
  const std::string mode = argv[1];
  const std::filesystem::path file = argv[2];
  const unsigned w = argc > 3 ? unsigned(std::atoi(argv[3])) : 64, h = argc > 4 ? unsigned(std::atoi(argv[4])) : 48;
  const unsigned spp = argc > 5 ? unsigned(std::atoi(argv[5])) : 1;
  const std::size_t cache = (argc > 6 ? std::size_t(std::atoll(argv[6])) : 2048) << 20;
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
  } else if (mode != "inplace") {
    std::fprintf(stderr, "mode must be inplace or whole\n");
    return 2;
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
  return 0;
}
