// Visibility benchmark: line of sight from 10 observers to every point of the
// largest bundled LAS (scenes/data/autzen_trim.las, 110,000 points), reported as points per second
// (a point is done when all observers are tested) and observer-point pairs per second. The
// observers are fixed: 8 at eye height (5.5 ft above the local ground) on a 4 x 2 grid over the
// site and 2 on 100 ft masts, so the run mixes short grazing rays and long rays across the site.
// Optionally the sky view factor (--sky N rays per point) is timed as well.
//
// Usage: bench_visibility [CLOUD] [--threads T] [--repeat R] [--observers M] [--sky N]
//   CLOUD defaults to scenes/data/autzen_trim.las. CPU seconds (user + system of the process) are
//   printed too, because the benchmark machine is shared.
#include "bench_cli.hpp"
#include "rayscan/analysis/observer.hpp"
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/spacing.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

using namespace rayscan;
using namespace rayscan::analysis;

namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  std::string path = RAYSCAN_SCENES_DIR "/data/autzen_trim.las";
  unsigned threads = 0, repeat = 3, nobs = 10, sky = 0;
  CLI::App app{"bench_visibility: line of sight from observers to every point of a cloud, points/s and pairs/s"};
  app.add_option("CLOUD", path, "point cloud")->capture_default_str();
  app.add_option("--threads", threads, "threads (0: all)")->capture_default_str();
  app.add_option("--repeat", repeat, "timed passes")->check(CLI::Range(1u, 1000u))->capture_default_str();
  app.add_option("--observers", nobs, "observers (8 at eye height, then masts)")->check(CLI::Range(1u, 10000u))
      ->capture_default_str();
  app.add_option("--sky", sky, "also time the sky view factor with N rays per point (0: not)")->capture_default_str();
  rayscan::bench::parse_or_exit(app, argc, argv);
  try {
    const PointCloud cloud = io::read_point_cloud(path);
    auto t0 = std::chrono::steady_clock::now();
    const AnyIndex index = make_index(cloud.positions, IndexOptions{});
    const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double radius = median_nn_spacing(index, cloud.positions);
    const AABB b = cloud.bounds();

    // Observers: a 4 x 2 grid at eye height, then masts at 1/3 and 2/3 of the diagonal.
    std::vector<Observer> obs;
    for (unsigned k = 0; k < nobs; ++k) {
      Observer o;
      if (k < 8) {
        const double fx = (double(k % 4) + 0.5) / 4.0, fy = (double(k / 4) + 0.5) / 2.0;
        o.position = Vec3(b.lo.x + fx * (b.hi.x - b.lo.x), b.lo.y + fy * (b.hi.y - b.lo.y), 0.0);
        o.height = 5.5;
      } else {
        const double f = double(k - 7) / 3.0;
        o.position = Vec3(b.lo.x + f * (b.hi.x - b.lo.x), b.lo.y + f * (b.hi.y - b.lo.y), 0.0);
        o.height = 100.0;
      }
      obs.push_back(o);
    }
    place_observers(obs, index, cloud, GroundOptions{25.0 * radius, std::nullopt, std::nullopt});

    VisibilityOptions vo;
    vo.radius = radius;
    vo.tolerance = 2.0 * radius;
    vo.target_height = radius;
    vo.threads = threads;
    std::printf("cloud %s: %zu points, octree-adaptive built in %.3f s, r = %.4g (median NN spacing), "
                "tolerance 2r, target height r, %zu observers\n",
                path.c_str(), cloud.size(), build_s, radius, obs.size());
    double best = 1e300, best_cpu = 0;
    VisibilityResult res;
    for (unsigned rep = 0; rep < repeat; ++rep) {
      const double c0 = cpu_seconds();
      res = compute_visibility(index, cloud.positions, obs, vo);
      const double cpu = cpu_seconds() - c0;
      std::printf("  run %u: %.3f s wall, %.3f s CPU, %u threads\n", rep + 1, res.seconds, cpu, res.threads);
      if (res.seconds < best) {
        best = res.seconds;
        best_cpu = cpu;
      }
    }
    std::uint64_t seen = 0;
    for (auto c : res.count) seen += c > 0;
    std::printf("line of sight (best of %u): %.3f s wall -> %.4g points/s, %.4g observer-point pairs/s; "
                "%.3f s CPU -> %.4g pairs per CPU-second\n",
                repeat, best, double(cloud.size()) / best, double(res.pairs) / best, best_cpu,
                double(res.pairs) / best_cpu);
    std::printf("  %llu ray queries (%.1f %% of pairs inside range/limits), %llu points (%.1f %%) seen by "
                "at least one observer\n",
                static_cast<unsigned long long>(res.queries), 100.0 * double(res.queries) / double(res.pairs),
                static_cast<unsigned long long>(seen), 100.0 * double(seen) / double(cloud.size()));
    for (std::size_t k = 0; k < obs.size(); ++k)
      std::printf("  observer %2zu at (%.1f, %.1f, %.1f): sees %llu points\n", k + 1, obs[k].position.x,
                  obs[k].position.y, obs[k].position.z, static_cast<unsigned long long>(res.per_observer[k]));
    if (sky > 0) {
      SkyViewOptions so;
      so.rays = sky;
      so.radius = radius;
      so.lift = 2.0 * radius;
      so.threads = threads;
      const double c0 = cpu_seconds();
      t0 = std::chrono::steady_clock::now();
      std::uint64_t q = 0;
      const std::vector<double> sv = compute_sky_view(index, cloud.positions, so, &q);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      double mean = 0;
      for (double v : sv) mean += v / double(sv.size());
      std::printf("sky view, %u rays per point: %.3f s wall (%.3f s CPU) -> %.4g points/s, %.4g rays/s; "
                  "mean %.4f\n",
                  sky, s, cpu_seconds() - c0, double(cloud.size()) / s, double(q) / s, mean);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_visibility: %s\n", e.what());
    return 2;
  }
  return 0;
}
