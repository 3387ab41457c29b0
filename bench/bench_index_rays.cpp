// bench_index_rays SITE.rsi [MORE.rsi ...]: ray-query throughput on memory-mapped index files vs
// the in-memory octree (Octree::build_bulk over the first file's points in original order, same
// layout and capacity: the same tree) on the same rays, interleaved in rounds
// (the first contender rotating), median of the rounds. Every index file is checked to return the
// octree's hits bit for bit (index, t, distance). Queries: the renderer's first hit (sphere_hit,
// k = 1, r = the stored median spacing) on rays from 200 m above the site's box to uniform points
// of the box and on bounce-like rays (from 4 spacings above a stored point, directions uniform
// over the sphere above z = -0.3), kNN to the ray (order ray, k = 8, r = 4 x spacing) on the
// first rays, and kNN of points (k = 8) at stored points moved by up to a spacing (all seeded).
// One thread; the thread's CPU time is reported (on the shared machine wall time mostly measures
// preemption).
// Page cache: the files are read once before the first round (warm). --entry-ab: each file also
// with the entry-point search forced on first hits (EntryPointSearch::always) and without it (off:
// first hits and point kNN from the root), set around its runs. bench/README.md.
#include "bench_cli.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <string>
#include <vector>

using namespace rayscan;

namespace {

double thread_cpu() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

template <class I>
double run(const I& idx, const std::vector<Ray>& rays, const RayQuery& q, std::vector<std::vector<RayHit>>& out) {
  out.resize(rays.size());
  const double t0 = thread_cpu();
  for (std::size_t i = 0; i < rays.size(); ++i) ray_query(idx, rays[i], q, out[i]);
  return thread_cpu() - t0;
}

/// kNN of each point (k = q.k), its neighbours kept as hits (index and distance; t 0, so `same`
/// compares them).
template <class I>
double run_points(const I& idx, const std::vector<Vec3>& points, const RayQuery& q,
                  std::vector<std::vector<RayHit>>& out) {
  out.resize(points.size());
  const double t0 = thread_cpu();
  for (std::size_t i = 0; i < points.size(); ++i) {
    out[i].clear();
    for (const auto& nb : knn(idx, points[i], q.k)) out[i].push_back({nb.index, 0, 0.0, nb.distance, nb.distance});
  }
  return thread_cpu() - t0;
}

bool same(const std::vector<std::vector<RayHit>>& a, const std::vector<std::vector<RayHit>>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].size() != b[i].size()) return false;
    for (std::size_t j = 0; j < a[i].size(); ++j)
      if (a[i][j].index != b[i][j].index || a[i][j].t != b[i][j].t || a[i][j].distance != b[i][j].distance)
        return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_index_rays: ray queries on mapped index files vs the in-memory octree"};
  std::vector<std::string> files;
  std::size_t nrays = 100000;
  int rounds = 5;
  bool entry_ab = false;
  app.add_option("SITE", files, "index files (.rsi) of the same points; the first gives the octree")->required();
  app.add_option("--rays", nrays, "rays per query type")->capture_default_str();
  app.add_option("--rounds", rounds, "interleaved rounds")->capture_default_str()->check(CLI::Range(1, 1000));
  app.add_flag("--entry-ab", entry_ab,
               "each file also with the entry-point search forced on first hits, and without the search");
  rayscan::bench::parse_or_exit(app, argc, argv);
  try {
    std::vector<io::MappedIndex> maps;
    for (const std::string& f : files) maps.push_back(io::MappedIndex::open(f));
    const io::MappedIndex& m0 = maps.front();
    const double t_build = thread_cpu();
    const Octree tree = Octree::build_bulk(m0.to_point_cloud().positions, m0.config());
    std::printf("in-memory octree: %zu points, %zu nodes (%.1f s CPU incl. to_point_cloud)\n", tree.positions().size(),
                tree.node_count(), thread_cpu() - t_build);
    for (std::size_t k = 0; k < maps.size(); ++k)
      std::printf("index %zu: %s, positions %s, %.2f bytes/point\n", k, files[k].c_str(),
                  to_string(maps[k].position_encoding()),
                  static_cast<double>(maps[k].file_bytes()) / static_cast<double>(maps[k].positions().size()));
    volatile double sink = 0;  // warm the page cache: touch every position once
    for (const io::MappedIndex& m : maps)
      for (std::size_t s = 0; s < m.positions().size(); s += 97) sink = sink + m.positions()[s].x;

    const AABB b = m0.bounds();
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto in_box = [&] { return b.lo + Vec3(u(rng), u(rng), u(rng)) * (b.hi - b.lo); };
    std::vector<Ray> rays;
    for (std::size_t i = 0; i < nrays; ++i) {
      const Vec3 t = in_box();
      const Vec3 o(b.lo.x + u(rng) * (b.hi.x - b.lo.x), b.lo.y + u(rng) * (b.hi.y - b.lo.y), b.hi.z + 200.0);
      rays.emplace_back(o, t - o);
    }
    const double sp = m0.median_nn_spacing();
    std::vector<Ray> bounces;
    std::vector<Vec3> points;
    for (std::size_t i = 0; i < nrays; ++i) {
      const Vec3 p = m0.positions()[static_cast<std::size_t>(u(rng) * static_cast<double>(m0.positions().size() - 1))];
      const double z = u(rng) * 1.3 - 0.3, phi = 6.283185307179586 * u(rng), s = std::sqrt(1.0 - z * z);
      bounces.emplace_back(p + Vec3(0.0, 0.0, 4.0 * sp), Vec3(s * std::cos(phi), s * std::sin(phi), z));
      points.push_back(p + sp * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5));
    }
    struct QueryKind {
      const char* name;
      RayQuery q;
      const std::vector<Ray>* rays;  // null: kNN of `points`
    };
    std::vector<QueryKind> kinds(4);
    kinds[0].name = "first hit (sphere_hit, k=1), rays from above";
    kinds[1].name = "first hit (sphere_hit, k=1), bounce-like rays";
    for (int k = 0; k < 2; ++k) {
      kinds[k].q.order = RayOrder::sphere_hit;
      kinds[k].q.k = 1;
      kinds[k].q.radius = sp;
    }
    kinds[0].rays = &rays;
    kinds[1].rays = &bounces;
    kinds[2].name = "kNN to the ray (k=8)";
    kinds[2].q.order = RayOrder::ray;
    kinds[2].q.k = 8;
    kinds[2].q.radius = 4 * sp;
    kinds[2].rays = &rays;
    kinds[3].name = "kNN of points (k=8)";
    kinds[3].q.k = 8;
    kinds[3].q.radius = kInf;  // (no radius: the 8 nearest)
    kinds[3].rays = nullptr;

    // Contender 0: the in-memory octree; 1..F: the files (the default search); with --entry-ab,
    // F+1..2F: the files with the search forced on first hits, 2F+1..3F: without the search.
    const std::size_t nf = maps.size(), nc = 1 + (entry_ab ? 3 : 1) * nf;
    auto mode_of = [&](std::size_t c) {
      return c <= nf ? EntryPointSearch::automatic : c <= 2 * nf ? EntryPointSearch::always : EntryPointSearch::off;
    };
    auto label = [&](std::size_t c) {
      if (c == 0) return std::string("in-memory octree");
      const std::size_t f = (c - 1) % nf;
      const EntryPointSearch e = mode_of(c);
      return files[f] + " (" + to_string(maps[f].position_encoding()) +
             (e == EntryPointSearch::always ? ", entry search always)" : e == EntryPointSearch::off ? ", no entry search)" : ")");
    };
    auto run_on = [&](const auto& idx, const QueryKind& kind, std::vector<std::vector<RayHit>>& out) {
      return kind.rays ? run(idx, *kind.rays, kind.q, out) : run_points(idx, points, kind.q, out);
    };
    auto run_contender = [&](std::size_t c, const QueryKind& kind, std::vector<std::vector<RayHit>>& out) {
      if (c == 0) return run_on(tree, kind, out);
      set_entry_point_search(mode_of(c));
      const double t = run_on(maps[(c - 1) % nf], kind, out);
      set_entry_point_search(EntryPointSearch::automatic);
      return t;
    };
    for (const QueryKind& kind : kinds) {
      std::vector<std::vector<double>> secs(nc);
      std::vector<std::vector<std::vector<RayHit>>> hits(nc);
      bool equal = true;
      for (int r = 0; r < rounds; ++r)
        for (std::size_t j = 0; j < nc; ++j) {
          const std::size_t c = (j + static_cast<std::size_t>(r)) % nc;
          secs[c].push_back(run_contender(c, kind, hits[c]));
          if (c != 0 && !hits[0].empty()) equal = equal && same(hits[c], hits[0]);
        }
      const std::size_t nq = kind.rays ? kind.rays->size() : points.size();
      std::printf("%s, %zu queries, %d rounds, radius %.4g: hits equal to the octree's: %s\n", kind.name, nq, rounds,
                  kind.q.radius, equal ? "yes" : "NO");
      std::vector<double> med(nc);
      for (std::size_t c = 0; c < nc; ++c) {
        std::sort(secs[c].begin(), secs[c].end());
        med[c] = secs[c][secs[c].size() / 2];
      }
      for (std::size_t c = 0; c < nc; ++c)
        std::printf("  %-40s %10.0f queries/s  (median %.3f s CPU; min %.3f, max %.3f)  %.3fx the octree\n",
                    label(c).c_str(),
                    static_cast<double>(nq) / med[c], med[c], secs[c].front(), secs[c].back(), med[0] / med[c]);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_index_rays: %s\n", e.what());
    return 2;
  }
  return 0;
}
