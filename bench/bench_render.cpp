// Render benchmark: the paper's workload shape, 600x400 pixels at 50 spp,
// on the bundled Autzen scan and on a ~10 million point scene made by tiling it. Reports the time,
// ray queries per second (total and per thread) and the cost split between the ray query and the
// rest (camera, shading, sampling), measured by timing every ray_query call.
//
// Usage: bench_render [SCENE.json] [--tiles N] [--spp S] [--threads T] [--no-timing]
//                     [--packets on|off|both] [--entry-search on|off|both] [--pairs on|off|both]
//                     [--rounds R]
//   default scene: scenes/autzen_overview.json; --tiles N renders an N x N tiling of the cloud
//   (N = 9 gives 8.9 million points for autzen_trim), seen by a camera scaled to cover it.
//   --packets: camera and shadow rays of 4x4 pixel blocks as ray packets (on, the
//   default), single rays (off), or both, alternating in each of R rounds (default 1) of the same
//   process, with the two images compared byte by byte and queries/s per thread by wall clock and
//   by process CPU time (the fair figure on a loaded machine) for each render. --entry-search: the
//   entry-point search (rayscan::set_entry_point_search) on (EntryPointSearch::automatic, the
//   default: kNN, and first hits where the grid is for them), off, or both, the same way (each combination with --packets once per round; every image must equal the
//   first byte for byte). --pairs: the bounce and shadow rays' ray_first_hit_each in interleaved
//   pairs (rayscan::set_interleaved_pairs) on, off, or both, likewise; by default this CPU's
//   default (rayscan::interleaved_pairs_default: on for Zen 5).
#include "bench_cli.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/render/render.hpp"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

using namespace rayscan;
using namespace rayscan::render;

int main(int argc, char** argv) {
  std::string scene_path = RAYSCAN_SCENES_DIR "/autzen_overview.json";
  int tiles = 1;
  unsigned spp = 50, threads = 0;
  bool timing = true;
  std::string packets = "on", entry = "on", pairs = interleaved_pairs_default() ? "on" : "off";
  int rounds = 1;
  CLI::App app{"bench_render: rayscan render of a scene, ray queries per second and thread, the ray query's share"};
  const auto modes = CLI::IsMember({"on", "off", "both"});
  app.add_option("SCENE", scene_path, "scene file (.json)")->capture_default_str();
  app.add_option("--tiles", tiles, "render an N x N tiling of the cloud (the camera pulled back to cover it)")
      ->check(CLI::Range(1, 64))->capture_default_str();
  app.add_option("--spp", spp, "samples per pixel")->check(CLI::Range(1u, 1u << 20))->capture_default_str();
  app.add_option("--threads", threads, "threads (0: all)")->capture_default_str();
  bool no_timing = false;
  app.add_flag("--no-timing", no_timing, "do not time each ray query (no cost split)");
  app.add_option("--packets", packets, "camera and shadow rays of 4x4 pixel blocks as packets")->check(modes)->capture_default_str();
  app.add_option("--entry-search", entry, "the first hits' entry-point search")->check(modes)->capture_default_str();
  app.add_option("--pairs", pairs, "bounce and shadow rays in interleaved pairs (default: this CPU's)")
      ->check(modes)->capture_default_str();
  app.add_option("--rounds", rounds, "rounds, each running every combination once")->check(CLI::Range(1, 1000))
      ->capture_default_str();
  rayscan::bench::parse_or_exit(app, argc, argv);
  timing = !no_timing;
  try {
    Scene scene = load_scene(scene_path);
    scene.spp = spp;
    PointCloud cloud = io::read_point_cloud(scene.cloud);
    std::vector<Color> albedo = compute_albedo(cloud, scene.material, scene.up);
    const AABB b = cloud.bounds();
    if (tiles > 1) {
      // Tile the cloud tiles x tiles times in x and y, mirrored so neighbouring tiles join.
      const std::size_t n = cloud.size();
      std::vector<Vec3> pos;
      std::vector<Color> alb;
      pos.reserve(n * tiles * tiles);
      alb.reserve(n * tiles * tiles);
      const Vec3 e = b.extent();
      for (int ty = 0; ty < tiles; ++ty)
        for (int tx = 0; tx < tiles; ++tx)
          for (std::size_t i = 0; i < n; ++i) {
            Vec3 p = cloud.positions[i];
            if (tx % 2) p.x = b.lo.x + b.hi.x - p.x;
            if (ty % 2) p.y = b.lo.y + b.hi.y - p.y;
            pos.push_back(p + Vec3(tx * e.x, ty * e.y, 0.0));
            alb.push_back(albedo[i]);
          }
      cloud.positions = std::move(pos);
      albedo = std::move(alb);
      // Camera: same direction, pulled back so the tiled site fills the view.
      const Vec3 c0 = b.center();
      const Vec3 c1 = c0 + Vec3((tiles - 1) * e.x / 2, (tiles - 1) * e.y / 2, 0.0);
      const Vec3 eye = scene.camera->center();
      LookAtParams la;
      la.look_at = c1;
      la.position = c1 + (eye - c0) * double(tiles);
      la.vfov_deg = 42.0;
      scene.camera = Camera::look_at(la, scene.camera->width(), scene.camera->height());
    }
    auto t0 = std::chrono::steady_clock::now();
    const AnyIndex index = make_index(cloud.positions, scene.index);
    const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double radius = choose_radius(index, cloud.positions, scene.radius, scene.auto_radius_factor).radius;
    const RenderSettings settings = make_settings(scene, cloud.positions, albedo, radius);
    std::printf("scene %s, tiles %dx%d: %zu points, %s build %.2f s, radius %.4g\n", scene_path.c_str(),
                tiles, tiles, cloud.size(), scene.index.type.c_str(), build_s, radius);
    auto cpu_now = [] {
      timespec ts{};
      clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
      return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
    };
    struct Mode {
      bool packets, entry_search, pairs;
    };
    std::vector<Mode> modes;
    auto chosen = [](const std::string& v, bool on) { return v == "both" || (v == "on") == on; };
    for (const bool es : {false, true})
      for (const bool pr : {false, true})
        for (const bool pk : {false, true})
          if (chosen(entry, es) && chosen(pairs, pr) && chosen(packets, pk)) modes.push_back({pk, es, pr});
    std::vector<Color> first_image;
    for (int round = 0; round < rounds; ++round)
      for (const auto& [pk, es, pr] : modes) {
        set_entry_point_search(es);
        set_interleaved_pairs(pr);
        RenderOptions opt;
        opt.threads = threads;
        opt.time_queries = timing;
        opt.packets = pk;
        Framebuffer fb;
        const double c0 = cpu_now();
        const RenderStats st = render_image(index, settings, fb, opt);
        const double cpu = cpu_now() - c0;
        const double qps = double(st.queries) / st.seconds;
        std::printf("round %d, packets %s, entry-point search %s, pairs %s: %ux%u px, %u spp, %u threads: %.2f s, "
                    "%llu primary rays, %llu ray queries\n",
                    round + 1, pk ? "on" : "off", es ? "on" : "off", pr ? "on" : "off", fb.width, fb.height, scene.spp, st.threads, st.seconds,
                    (unsigned long long)st.primary_rays, (unsigned long long)st.queries);
        std::printf("  ray queries/s: %.3g total, %.3g per thread (wall); %.3g per CPU-second; "
                    "nodes visited/query %.1f, points tested/query %.1f\n",
                    qps, qps / st.threads, double(st.queries) / cpu, double(st.nodes_visited) / double(st.queries),
                    double(st.points_tested) / double(st.queries));
        if (timing) {
          const double busy = st.seconds * st.threads;
          std::printf("  cost split (thread time): ray query %.1f%%, rest (camera, shading, sampling, "
                      "timer overhead) %.1f%%\n",
                      100.0 * st.query_seconds / busy, 100.0 * (1.0 - st.query_seconds / busy));
        }
        if (first_image.empty()) first_image = fb.beauty;
        if (first_image.size() != fb.beauty.size() ||
            std::memcmp(first_image.data(), fb.beauty.data(), fb.beauty.size() * sizeof(Color)) != 0) {
          std::fprintf(stderr, "bench_render: round %d: the image differs from the first render\n", round + 1);
          return 1;
        }
      }
    if (modes.size() > 1 || rounds > 1) std::printf("images identical byte for byte (every render)\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_render: %s\n", e.what());
    return 2;
  }
  return 0;
}
