// LAZ/COPC benchmarks (docs/formats.md "LAZ"; figures in bench/README.md):
//   bench_laz decode FILE --threads N   decode every record, print points/s (wall clock)
//   bench_laz encode FILE.las OUT.laz   LAS -> LAZ, print points/s and compression ratio
//   bench_laz copc FILE.copc.laz        time to the first ray query answered from the file
//                                       (CopcIndex: header + hierarchy + touched nodes) vs
//                                       reading the whole file (read_point_cloud)
// bench/laz.sh interleaves these with laz-perf under Node on the same files.
#include "bench_cli.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/translate.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <tbb/global_control.h>

#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_laz: LAZ decode and encode throughput, COPC time to the first ray query"};
  app.require_subcommand(1);
  std::string file, out;
  int threads = 1;
  CLI::App* decode = app.add_subcommand("decode", "decode every record of a LAZ file, points/s");
  decode->add_option("FILE", file, "LAZ file")->required();
  decode->add_option("--threads", threads, "decoding threads")->check(CLI::Range(1, 1024))->capture_default_str();
  CLI::App* encode = app.add_subcommand("encode", "LAS -> LAZ, points/s and compression ratio");
  encode->add_option("IN", file, "LAS file")->required();
  encode->add_option("OUT", out, "LAZ file to write")->required();
  CLI::App* copc = app.add_subcommand("copc", "time to the first ray query answered from a COPC file vs reading it whole");
  copc->add_option("FILE", file, "COPC file")->required();
  rayscan::bench::parse_or_exit(app, argc, argv);
  const std::string mode = decode->parsed() ? "decode" : encode->parsed() ? "encode" : "copc";
  try {
    if (mode == "decode") {
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
      const double t0 = now();
      const std::clock_t c0 = std::clock();
      const rayscan::io::LasRecords r = rayscan::io::read_las_records(file);
      const double dt = now() - t0;
      const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
      std::printf("rayscan decode threads=%d points=%llu wall_s=%.4f cpu_s=%.4f points_per_wall_s=%.0f points_per_cpu_s=%.0f\n",
                  threads, static_cast<unsigned long long>(r.count), dt, cpu, static_cast<double>(r.count) / dt,
                  static_cast<double>(r.count) / cpu);
    } else if (mode == "encode") {
      const double t0 = now();
      const rayscan::io::TranslateResult r = rayscan::io::translate_las(file, out);
      const double dt = now() - t0;
      std::printf("rayscan encode points=%llu seconds=%.4f points_per_s=%.0f ratio=%.2f\n",
                  static_cast<unsigned long long>(r.points), dt, static_cast<double>(r.points) / dt,
                  static_cast<double>(r.in_bytes) / static_cast<double>(r.out_bytes));
    } else if (mode == "copc") {
      const double t0 = now();
      rayscan::io::CopcIndex idx(file);
      const rayscan::AABB cube = idx.node_bounds(idx.root());
      const rayscan::Vec3 c = 0.5 * (cube.lo + cube.hi);
      std::vector<rayscan::RayHit> hits;
      rayscan::RayQuery q;
      q.k = 1;
      q.radius = 0.05;
      rayscan::ray_query(idx, rayscan::Ray(c + rayscan::Vec3(0, 0, cube.hi.z - c.z), rayscan::Vec3(0, 0, -1)), q, hits);
      const double t1 = now();
      const rayscan::PointCloud pc = rayscan::io::read_point_cloud(file);
      const double t2 = now();
      std::printf("copc first_ray_ms=%.2f nodes_decoded=%llu of %zu; whole_read_ms=%.2f points=%zu\n",
                  1e3 * (t1 - t0), static_cast<unsigned long long>(idx.decodes()), idx.node_count(),
                  1e3 * (t2 - t1), pc.size());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_laz: %s\n", e.what());
    return 2;
  }
  return 0;
}
