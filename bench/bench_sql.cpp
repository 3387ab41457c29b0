// bench_sql: ray queries through SQL against the in-memory octree, in one
// interleaved run. Per camera ray: radius query (r = point spacing) and kNN to the ray (k = 10) on
//   octree    rayscan::ray_query over Octree::build_bulk (what `rayscan query` runs);
//   sqlite    ray_query(...) of rayscan_sqlite.so (R*Tree pruning callback + dynamic k filter);
//   baseline  optional (--baseline-ext): the same ray_query through another build of the extension
//             (e.g. the one before an optimisation) on a second connection, interleaved per ray;
//   full      SELECT ... FROM points WHERE dist_ray(...) <= r: no pruning (first --full-rays rays);
//   postgres  chunk GiST (&& ray_within) join + dist_ray <= r, and kNN with ORDER BY ... LIMIT k
//             inside radius 3r; ray_dwithin(rs_box(x,y,z), ...) on the points' own GiST index
//             (the planner-support form; the bench creates <table>_pt) (only with --postgres).
// Prints time per query and chunks touched / total, and counts result mismatches vs the octree.
#include "bench_cli.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/sql/import.hpp"

#include <libpq-fe.h>
#include <sqlite3.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <unistd.h>
#include <cstdio>
#include <iostream>
#include <optional>
#include <random>
#include <string>

using namespace rayscan;
using Clock = std::chrono::steady_clock;

static double secs(Clock::time_point a) { return std::chrono::duration<double>(Clock::now() - a).count(); }
// Thread CPU time (s): on the shared 2-core machine wall time mostly measures preemption by other
// processes; the CPU time of this thread is what the query costs (SQLite and the octree run in
// this thread; PostgreSQL runs in its server, so only its wall time is reported).
static double thread_cpu() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}
struct Tick {
  Clock::time_point wall = Clock::now();
  double cpu = thread_cpu();
};

int main(int argc, char** argv) {
  CLI::App app{"bench_sql: SQL ray queries (SQLite, PostgreSQL, full scan) vs the in-memory octree"};
  std::string cloud_path = RAYSCAN_DEFAULT_CLOUD, db_path, conninfo, table = "points";
  int nrays = 1000, full_rays = 20, k = 10;
  std::string baseline_ext, only, pragma, index_path;
  bool point_gist = true;
  app.add_option("--cloud", cloud_path, "Point cloud (the one imported)")->capture_default_str();
  app.add_option("--sqlite", db_path, "SQLite database from `rayscan db import` of --cloud "
                                      "(default: imported here into a temporary file, default chunk size)");
  app.add_option("--postgres", conninfo, "libpq conninfo of a database imported with --postgres");
  app.add_option("--table", table, "PostgreSQL table");
  app.add_option("--rays", nrays, "Camera rays");
  app.add_option("--full-rays", full_rays, "Rays for the unpruned full scan (slow)");
  app.add_option("--baseline-ext", baseline_ext, "Another rayscan_sqlite.so to run interleaved (before/after)");
  app.add_option("--pragma", pragma, "PRAGMA statements run on every SQLite connection first, e.g. "
                                     "\"mmap_size=1073741824\" (SQLite's memory-mapped I/O)");
  app.add_option("--index", index_path, "Use this index file (rayscan index of --cloud, mapped) as the "
                                        "octree instead of reading --cloud and building it in memory "
                                        "(the same tree and results; for sites larger than memory)");
  app.add_flag("!--no-point-gist", point_gist, "PostgreSQL: skip ray_dwithin on the points' own GiST "
                                               "index (building it on 1e8+ rows takes hours)");
  app.add_option("--only", only, "Run only the radius or only the kNN queries (for profiling one case)")
      ->check(CLI::IsMember({"radius", "knn"}));
  rayscan::bench::parse_or_exit(app, argc, argv);
  try {

    // The octree: built in memory from the cloud, or the mapped index file of the same cloud.
    PointCloud cloud;
    std::optional<Octree> mem;
    std::optional<io::MappedIndex> mapped;
    PositionView positions;
    AABB b;
    std::string label;
    if (index_path.empty()) {
      cloud = io::read_point_cloud(cloud_path, io::ReadOptions{.scalars = false});
      mem.emplace(Octree::build_bulk(cloud.positions));
      positions = cloud.positions;
      b = cloud.bounds();
      label = cloud_path + " (octree built in memory)";
    } else {
      mapped.emplace(io::MappedIndex::open(index_path));
      positions = mapped->positions();
      b = mapped->bounds();
      label = cloud_path + " (octree: mapped index file " + index_path + ")";
    }
    auto octree_query = [&](const Ray& ray, const RayQuery& q, std::vector<RayHit>& out) {
      if (mapped) ray_query(*mapped, ray, q, out);
      else ray_query(*mem, ray, q, out);
    };
    const std::size_t npoints = positions.size();
    const Vec3 e = b.extent();
    const double r = std::sqrt(std::max(e.x * e.y, 1e-12) / double(npoints));
    std::mt19937_64 rng(42);
    std::uniform_int_distribution<std::size_t> pick(0, npoints - 1);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Ray> rays;
    for (int i = 0; i < nrays; ++i) {
      const Vec3 o(b.lo.x + u(rng) * e.x, b.lo.y + u(rng) * e.y, b.hi.z + 0.3 * b.max_extent());
      const Ray tmp(o, positions[pick(rng)] - o);
      rays.emplace_back(tmp.origin(), tmp.direction());
    }

    std::filesystem::path tmp_db;
    if (db_path.empty()) {
      tmp_db = std::filesystem::temp_directory_path() / ("bench_sql." + std::to_string(::getpid()) + ".sqlite");
      const auto t0 = Tick();
      sql::import_sqlite({cloud_path}, tmp_db, {});
      std::printf("imported %s into SQLite in %.2f s\n", cloud_path.c_str(), secs(t0.wall));
      db_path = tmp_db.string();
    }
    sqlite3* db;
    if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) return 2;
    sqlite3_enable_load_extension(db, 1);
    char* err = nullptr;
    if (sqlite3_load_extension(db, RAYSCAN_SQLITE_EXT, nullptr, &err) != SQLITE_OK) {
      std::cerr << err << "\n";
      return 2;
    }
    auto apply_pragma = [&](sqlite3* c) {
      if (pragma.empty()) return true;
      char* e = nullptr;
      if (sqlite3_exec(c, ("PRAGMA " + pragma).c_str(), nullptr, nullptr, &e) == SQLITE_OK) return true;
      std::cerr << "PRAGMA " << pragma << ": " << (e ? e : "?") << "\n";
      sqlite3_free(e);
      return false;
    };
    if (!apply_pragma(db)) return 2;
    sqlite3* db_base = nullptr;
    sqlite3_stmt *q_base = nullptr, *stats_base = nullptr;
    if (!baseline_ext.empty()) {
      if (sqlite3_open_v2(db_path.c_str(), &db_base, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) return 2;
      if (!apply_pragma(db_base)) return 2;
      sqlite3_enable_load_extension(db_base, 1);
      if (sqlite3_load_extension(db_base, baseline_ext.c_str(), "sqlite3_extension_init", &err) != SQLITE_OK) {
        std::cerr << err << "\n";
        return 2;
      }
      sqlite3_prepare_v2(db_base, "SELECT point_index FROM ray_query(?1,?2,?3,?4,?5,?6,?7,?8,NULL,NULL,'ray')", -1, &q_base, nullptr);
      sqlite3_prepare_v2(db_base, "SELECT json_extract(s,'$.chunks_visited'), json_extract(s,'$.chunks_total') FROM (SELECT rayscan_stats() AS s)", -1, &stats_base, nullptr);
    }
    sqlite3_stmt *q_sql, *stats, *full;
    sqlite3_prepare_v2(db, "SELECT point_index FROM ray_query(?1,?2,?3,?4,?5,?6,?7,?8,NULL,NULL,'ray')", -1, &q_sql, nullptr);
    sqlite3_prepare_v2(db, "SELECT json_extract(s,'$.chunks_visited'), json_extract(s,'$.chunks_total') FROM (SELECT rayscan_stats() AS s)", -1, &stats, nullptr);
    sqlite3_prepare_v2(db, "SELECT count(*) FROM points WHERE dist_ray(?1,?2,?3,?4,?5,?6,x,y,z) <= ?7", -1, &full, nullptr);

    PGconn* pg = nullptr;
    if (!conninfo.empty()) {
      pg = PQconnectdb(conninfo.c_str());
      if (PQstatus(pg) != CONNECTION_OK) {
        std::cerr << PQerrorMessage(pg);
        return 2;
      }
      PQclear(PQexec(pg, "SET max_parallel_workers_per_gather = 0"));
      // The points' own GiST index for ray_dwithin(rs_box(x,y,z), ...) (the support-function form).
      if (point_gist) {
        PGresult* ix = PQexec(pg, ("CREATE INDEX IF NOT EXISTS " + table + "_pt ON " + table + " USING gist (rs_box(x, y, z))").c_str());
        if (PQresultStatus(ix) != PGRES_COMMAND_OK) std::cerr << PQerrorMessage(pg);
        PQclear(ix);
      }
      PQclear(PQexec(pg, ("ANALYZE " + table).c_str()));
    }
    auto pg_count = [&](const std::string& sql) {
      PGresult* res = PQexec(pg, sql.c_str());
      const int n = PQresultStatus(res) == PGRES_TUPLES_OK ? PQntuples(res) : -1;
      PQclear(res);
      return n;
    };
    auto num = [](double v) { char s[40]; std::snprintf(s, sizeof s, "%.17g", v); return std::string(s); };

    struct Acc {
      double t = 0, cpu = 0;
      long long n = 0, visited = 0, total = 0, mismatch = 0;
      void add(const Tick& t0) { t += secs(t0.wall); cpu += thread_cpu() - t0.cpu; ++n; }
    };
    Acc oct_r, oct_k, sq_r, sq_k, full_r, pg_r, pg_k, base_r, base_k, pg_w;
    std::vector<RayHit> hits;
    for (int i = 0; i < nrays; ++i) {
      const Ray& ray = rays[i];
      const Vec3 o = ray.origin(), d = ray.direction();
      RayQuery qr; qr.radius = r;
      RayQuery qk; qk.k = k;
      Tick t0;
      octree_query(Ray(o, d), qr, hits);
      oct_r.add(t0);
      const std::size_t want_r = hits.size();
      t0 = Tick();
      octree_query(Ray(o, d), qk, hits);
      oct_k.add(t0);
      const std::size_t want_k = hits.size();
      for (int mode = 0; mode < 4; ++mode) {
        const bool base = mode >= 2;
        if (base && !q_base) break;
        if ((only == "radius" && (mode & 1)) || (only == "knn" && !(mode & 1))) continue;
        Acc& a = base ? (mode & 1 ? base_k : base_r) : (mode & 1 ? sq_k : sq_r);
        sqlite3_stmt* q = base ? q_base : q_sql;
        sqlite3_stmt* qs = base ? stats_base : stats;
        t0 = Tick();
        for (int j = 0; j < 3; ++j) sqlite3_bind_double(q, j + 1, o[j]), sqlite3_bind_double(q, j + 4, d[j]);
        if (mode & 1) { sqlite3_bind_int(q, 7, k); sqlite3_bind_null(q, 8); }
        else { sqlite3_bind_null(q, 7); sqlite3_bind_double(q, 8, r); }
        std::size_t n = 0;
        while (sqlite3_step(q) == SQLITE_ROW) ++n;
        sqlite3_reset(q);
        a.add(t0);
        if (n != (mode & 1 ? want_k : want_r)) ++a.mismatch;
        sqlite3_step(qs);
        a.visited += sqlite3_column_int64(qs, 0);
        a.total += sqlite3_column_int64(qs, 1);
        sqlite3_reset(qs);
      }
      if (i < full_rays) {
        t0 = Tick();
        for (int j = 0; j < 3; ++j) sqlite3_bind_double(full, j + 1, o[j]), sqlite3_bind_double(full, j + 4, d[j]);
        sqlite3_bind_double(full, 7, r);
        sqlite3_step(full);
        const auto n = (std::size_t)sqlite3_column_int64(full, 0);
        sqlite3_reset(full);
        full_r.add(t0);
        if (n != want_r) ++full_r.mismatch;
      }
      if (pg) {
        const std::string od = num(o.x) + "," + num(o.y) + "," + num(o.z) + "," + num(d.x) + "," + num(d.y) + "," + num(d.z);
        t0 = Tick();
        const int n = pg_count("SELECT p.point_index FROM " + table + "_chunks c JOIN " + table + " p ON p.chunk = c.chunk "
                               "WHERE c.box && ray_within(" + od + "," + num(r) + ") AND dist_ray(" + od + ",p.x,p.y,p.z) <= " + num(r));
        pg_r.add(t0);
        if (n != (int)want_r) ++pg_r.mismatch;
        if (point_gist) {
        t0 = Tick();
        const int w = pg_count("SELECT point_index FROM " + table + " WHERE ray_dwithin(rs_box(x, y, z), " + od + "," + num(r) + ")");
        pg_w.add(t0);
        if (w != (int)want_r) ++pg_w.mismatch;
        }
        t0 = Tick();
        const int m = pg_count("SELECT p.point_index FROM " + table + "_chunks c JOIN " + table + " p ON p.chunk = c.chunk "
                               "WHERE c.box && ray_within(" + od + "," + num(3 * r) + ") AND dist_ray(" + od + ",p.x,p.y,p.z) <= " +
                               num(3 * r) + " ORDER BY dist_ray(" + od + ",p.x,p.y,p.z), 1 LIMIT " + std::to_string(k));
        pg_k.add(t0);
        RayQuery q3; q3.k = k; q3.radius = 3 * r;
        octree_query(Ray(o, d), q3, hits);
        if (m != (int)hits.size()) ++pg_k.mismatch;
      }
    }
    std::printf("cloud %s: %zu points, r = %.4g (point spacing), k = %d, %d rays\n", label.c_str(), npoints, r, k, nrays);
    std::printf("%-28s %10s %10s %10s %10s %14s %9s\n", "engine / query", "wall us/q", "x octree", "cpu us/q",
                "x octree", "chunks touched", "mismatch");
    auto row = [&](const char* name, const Acc& a, const Acc& ref, bool cpu = true) {
      if (!a.n) return;
      const double us = 1e6 * a.t / a.n, cu = 1e6 * a.cpu / a.n;
      char ch[32] = "-", c1[32] = "-", c2[32] = "-";
      if (a.total) std::snprintf(ch, sizeof ch, "%.3f%%", 100.0 * a.visited / a.total);
      if (cpu) {
        std::snprintf(c1, sizeof c1, "%.1f", cu);
        std::snprintf(c2, sizeof c2, "%.1f", cu / (1e6 * ref.cpu / ref.n));
      }
      std::printf("%-28s %10.1f %10.1f %10s %10s %14s %9lld\n", name, us, us / (1e6 * ref.t / ref.n), c1, c2, ch,
                  a.mismatch);
    };
    row("octree radius", oct_r, oct_r);
    row("sqlite ray_query radius", sq_r, oct_r);
    row("sqlite baseline radius", base_r, oct_r);
    row("sqlite full scan radius", full_r, oct_r);
    row("postgres gist radius", pg_r, oct_r, false);
    row("postgres ray_dwithin radius", pg_w, oct_r, false);
    row("octree kNN (k)", oct_k, oct_k);
    row("sqlite ray_query kNN", sq_k, oct_k);
    row("sqlite baseline kNN", base_k, oct_k);
    row("postgres gist kNN in 3r", pg_k, oct_k, false);
    sqlite3_finalize(q_sql); sqlite3_finalize(stats); sqlite3_finalize(full);
    sqlite3_close(db);
    sqlite3_finalize(q_base); sqlite3_finalize(stats_base);
    if (db_base) sqlite3_close(db_base);
    if (pg) PQfinish(pg);
    if (!tmp_db.empty()) std::filesystem::remove(tmp_db);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_sql: %s\n", e.what());
    return 2;
  }
  return 0;
}
