// bench_figure5: the measuring half of bench/figure5.py (Teuscher et al., section 5.2, Figure 5)
// as one C++ program that links only the octree library, for machines where the Python module
// cannot run (the lent Intel Xeon has no Debian Python; see bench/device_bundle.sh). It runs
// figure5.py's cases (passed in by figure5.py with --case, so the case list lives there alone) on
// N uniform points in the unit cube held in memory (octree-adaptive, make_index's defaults; the
// Python path's rayscan.Octree) with random rays (origins uniform in the cube, directions uniform
// on the sphere), calibrates the ray count as figure5.py does, and prints one line per thread count:
//   row TAB points TAB case TAB threads TAB rays TAB seconds TAB results
// (seconds: the best of --repeats batches of ray_query_batch, the per-ray result vectors
// included, as the Python path's time includes its arrays).
// Usage: bench_figure5 --points N --threads 1,4,16 [--seconds 0.5] [--repeats 3]
//                      --case 'NAME|K|RADIUS|ORDER' ... (K 0: no k; RADIUS inf: none; ORDER ray|time)
#include "bench_cli.hpp"
#include "bench_common.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/batch.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace {

using rayscan::Ray;
using rayscan::RayQuery;
using rayscan::Vec3;

/// One figure5.py case: its name (printed back) and the query it stands for.
struct Case {
  std::string name;
  RayQuery q;
};

/// Parses 'NAME|K|RADIUS|ORDER'; throws std::invalid_argument naming the field that is wrong.
Case parse_case(const std::string& s) {
  std::vector<std::string> f;
  std::stringstream ss(s);
  for (std::string part; std::getline(ss, part, '|');) f.push_back(part);
  if (f.size() != 4) throw std::invalid_argument("--case '" + s + "': expected NAME|K|RADIUS|ORDER");
  Case c{f[0], {}};
  // Whole fields only: "8x" or "" is refused rather than read as 8 or 0.
  std::size_t used = 0;
  unsigned long k = 0;
  try {
    k = std::stoul(f[1], &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != f[1].size() || k > 0xFFFFFFFFul || f[1][0] == '-')
    throw std::invalid_argument("--case '" + s + "': K must be a whole number (0: no limit), got '" + f[1] + "'");
  if (k) c.q.k = static_cast<std::uint32_t>(k);
  if (f[2] == "inf") {
    c.q.radius = rayscan::kInf;
  } else {
    try {
      c.q.radius = std::stod(f[2], &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != f[2].size() || !(c.q.radius > 0.0))
      throw std::invalid_argument("--case '" + s + "': RADIUS must be a positive number or inf, got '" + f[2] + "'");
  }
  if (f[3] == "ray") c.q.order = rayscan::RayOrder::ray;
  else if (f[3] == "time") c.q.order = rayscan::RayOrder::time;
  else throw std::invalid_argument("--case '" + s + "': ORDER must be ray or time");
  c.q.t_min = 0.0;
  c.q.validate();
  return c;
}

/// m rays with origins uniform in the unit cube and directions uniform on the sphere (bench_common's
/// generator: the same stream on every standard library).
std::vector<Ray> random_rays(std::size_t m, std::uint64_t seed) {
  rayscan::bench::Rng rng(seed);
  std::vector<Ray> rays;
  rays.reserve(m);
  for (std::size_t i = 0; i < m; ++i) {
    const Vec3 o = rng.point_in_unit_cube();
    rays.emplace_back(o, rng.unit_vector());
  }
  return rays;
}

/// Seconds for one batch and the number of results it returned.
std::pair<double, std::size_t> timed(const rayscan::AnyIndex& index, const std::vector<Ray>& rays,
                                     const RayQuery& q, int threads) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
  const auto t0 = std::chrono::steady_clock::now();
  const auto res = std::visit([&](const auto& ix) { return rayscan::ray_query_batch(ix, rays, q); }, index);
  const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::size_t hits = 0;
  for (const auto& r : res) hits += r.size();
  return {dt, hits};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Figure 5 of Teuscher et al.: ray query modalities on uniform points (the cases come from figure5.py)"};
  std::size_t n = 1'000'000;
  std::vector<int> threads{1, 2};
  double seconds = 0.5;
  int repeats = 3;
  std::vector<std::string> case_args;
  app.add_option("--points", n, "number of uniform points in the unit cube")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 31))->capture_default_str();
  app.add_option("--threads", threads, "comma-separated thread counts")->delimiter(',')->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--seconds", seconds, "target time per measurement at one thread")->check(CLI::Range(1e-3, 3600.0))
      ->capture_default_str();
  app.add_option("--repeats", repeats, "batches per thread count (the best is kept)")->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--case", case_args, "NAME|K|RADIUS|ORDER")->required();
  rayscan::bench::parse_or_exit(app, argc, argv);
  try {
    std::vector<Case> cases;
    for (const auto& s : case_args) cases.push_back(parse_case(s));
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<Vec3> pts = rayscan::bench::uniform_cube(n, 1);
    const rayscan::AnyIndex index = rayscan::make_index(pts, rayscan::IndexOptions{});
    std::printf("points %zu in memory (octree-adaptive): ready in %.1f s\n", n,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    for (const Case& c : cases) {
      const auto probe = random_rays(256, 5);
      (void)timed(index, probe, c.q, 1);  // warm-up
      const auto [dt, hits] = timed(index, probe, c.q, 1);
      const double per_ray = std::max(dt / 256, 1e-7);
      const double m = std::min({5e5, std::max(256.0, seconds / per_ray), 2e7 / std::max(1.0, hits / 256.0)});
      const auto rays = random_rays(static_cast<std::size_t>(m), 5);
      for (int th : threads) {
        std::pair<double, std::size_t> best{1e300, 0};
        for (int r = 0; r < repeats; ++r) best = std::min(best, timed(index, rays, c.q, th));
        std::printf("row\t%zu\t%s\t%d\t%zu\t%.6f\t%zu\n", n, c.name.c_str(), th, rays.size(), best.first, best.second);
        std::fflush(stdout);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_figure5: %s\n", e.what());
    return 2;
  }
  return 0;
}
