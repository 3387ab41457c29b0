// python_batch_peer: the C++ side of bench/bench_python.py. Builds the same index over the same
// points as the Python benchmark and times rayscan::ray_query_batch (rayscan/octree/batch.hpp, TBB, all
// cores) on the same rays, so the Python module's overhead (array conversion, GIL release, CSR
// flattening) is the only difference. Not a bench_* program: bench/run.sh runs it through
// bench_python.py, which passes the files.
//
// Usage: python_batch_peer CLOUD.f64 RAYS.f64 K RADIUS ORDER CAPACITY REPS
//   CLOUD.f64: N x 3 little-endian float64; RAYS.f64: M x 6 (ox oy oz dx dy dz); K < 0 = all;
//   ORDER ray|time|sphere_hit; t_min = 0. Prints "ms <wall ms> <process CPU ms>" per rep (after one
//   warm-up batch) and "check <hits> <sum of indices> <sum of t>" of the last batch.
#include "rayscan/octree/batch.hpp"
#include "rayscan/octree/octree.hpp"

#include <chrono>
#include <ctime>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace {

std::vector<double> read_f64(const char* path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw std::runtime_error(std::string(path) + ": cannot open");
  const auto size = static_cast<std::size_t>(in.tellg());
  std::vector<double> v(size / 8);
  in.seekg(0);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(v.size() * 8));
  return v;
}

}  // namespace

int main(int argc, char** argv) try {
  using namespace rayscan;
  if (argc != 8) {
    std::fprintf(stderr, "usage: %s CLOUD.f64 RAYS.f64 K RADIUS ORDER CAPACITY REPS\n", argv[0]);
    return 2;
  }
  const std::vector<double> c = read_f64(argv[1]), r = read_f64(argv[2]);
  std::vector<Vec3> pts(c.size() / 3);
  for (std::size_t i = 0; i < pts.size(); ++i) pts[i] = Vec3(c[3 * i], c[3 * i + 1], c[3 * i + 2]);
  std::vector<Ray> rays;
  rays.reserve(r.size() / 6);
  for (std::size_t i = 0; i + 5 < r.size(); i += 6)
    rays.emplace_back(Vec3(r[i], r[i + 1], r[i + 2]), Vec3(r[i + 3], r[i + 4], r[i + 5]));
  RayQuery q;
  const long long k = std::stoll(argv[3]);
  if (k >= 0) q.k = static_cast<std::size_t>(k);
  q.radius = std::stod(argv[4]);
  const std::string order = argv[5];
  q.order = order == "time" ? RayOrder::time : order == "sphere_hit" ? RayOrder::sphere_hit : RayOrder::ray;
  q.t_min = 0.0;
  OctreeConfig cfg;
  cfg.capacity = static_cast<std::uint32_t>(std::stoul(argv[6]));
  const Octree tree = Octree::build_bulk(pts, cfg);
  const int reps = std::stoi(argv[7]);
  std::vector<std::vector<RayHit>> res = ray_query_batch(tree, rays, q);  // warm-up
  for (int i = 0; i < reps; ++i) {
    const std::clock_t c0 = std::clock();  // process CPU time, all threads
    const auto t0 = std::chrono::steady_clock::now();
    res = ray_query_batch(tree, rays, q);
    const auto t1 = std::chrono::steady_clock::now();
    const std::clock_t c1 = std::clock();
    std::printf("ms %.3f %.3f\n", std::chrono::duration<double, std::milli>(t1 - t0).count(),
                1e3 * static_cast<double>(c1 - c0) / CLOCKS_PER_SEC);
  }
  std::size_t hits = 0;
  double sum_idx = 0, sum_t = 0;
  for (const auto& v : res)
    for (const RayHit& h : v) {
      ++hits;
      sum_idx += h.index;
      sum_t += h.t;
    }
  std::printf("check %zu %.17g %.17g\n", hits, sum_idx, sum_t);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "python_batch_peer: %s\n", e.what());
  return 2;
}
