// SQLite side of the SQL extensions: the loadable extension rayscan_sqlite.so on databases written by the
// real `rayscan db import`, checked against the core (bit for bit) and the brute-force oracle.
#include "sql_test_util.hpp"

#include "../common/crs_wkt.hpp"

#include "rayscan/octree/distance.hpp"
#include "rayscan/sql/functions.h"
#include "rayscan/sql/import.hpp"

#include <sqlite3.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <tuple>

namespace rayscan::sqltest {
namespace {

struct Db {
  sqlite3* db = nullptr;
  explicit Db(const fs::path& p, bool load = true) {
    EXPECT_EQ(sqlite3_open_v2(p.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK);
    if (!load) return;
    sqlite3_enable_load_extension(db, 1);
    char* err = nullptr;
    EXPECT_EQ(sqlite3_load_extension(db, RAYSCAN_SQLITE_EXT, nullptr, &err), SQLITE_OK) << (err ? err : "");
    sqlite3_free(err);
  }
  ~Db() { sqlite3_close(db); }
  Db(const Db&) = delete;
};

struct Stmt {
  sqlite3_stmt* s = nullptr;
  Stmt(sqlite3* db, const std::string& sql) {
    EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &s, nullptr), SQLITE_OK) << sql << ": " << sqlite3_errmsg(db);
  }
  ~Stmt() { sqlite3_finalize(s); }
  Stmt& bind(int i, double v) { sqlite3_bind_double(s, i, v); return *this; }
  bool step() { return sqlite3_step(s) == SQLITE_ROW; }
  double d(int i) { return sqlite3_column_double(s, i); }
  long long i64(int i) { return sqlite3_column_int64(s, i); }
};

/// The error message of running `sql` (empty when it succeeds).
std::string error_of(sqlite3* db, const std::string& sql) {
  sqlite3_stmt* s = nullptr;
  std::string msg;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &s, nullptr) != SQLITE_OK) return sqlite3_errmsg(db);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {}
  if (rc != SQLITE_DONE) msg = sqlite3_errmsg(db);
  sqlite3_finalize(s);
  return msg;
}

/// One imported scan, shared by the tests of a file.
struct Site {
  PointCloud cloud;
  fs::path db;
  double r = 0;
  std::vector<Ray> rays;
};

const fs::path& tmpdir() {
  static const fs::path d = [] {
    fs::path p = fs::temp_directory_path() / ("rayscan-sqltest-" + std::to_string(::getpid()));
    fs::create_directories(p);
    return p;
  }();
  return d;
}

/// Removes this process's scratch directory after the tests.
struct ScratchCleanup : ::testing::Environment {
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(fs::temp_directory_path() / ("rayscan-sqltest-" + std::to_string(::getpid())), ec);
  }
};
[[maybe_unused]] const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

Site* site(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Site>> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second.get();
  const fs::path p = scan_path(name);
  if (p.empty()) return nullptr;
  auto s = std::make_unique<Site>();
  s->cloud = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  // Imported once per build of `rayscan` (CTest runs every test in its own process); a newer
  // binary re-imports. Concurrent imports are safe: each writes a temporary and renames it.
  s->db = fs::path(RAYSCAN_SQL_TEST_CACHE) / (name + ".sqlite");
  fs::create_directories(s->db.parent_path());
  std::error_code ec;
  const bool fresh = fs::exists(s->db) && fs::last_write_time(s->db, ec) > fs::last_write_time(RAYSCAN_BIN) &&
                     fs::last_write_time(s->db, ec) > fs::last_write_time(p);
  // A chunk of 512 points gives hundreds of chunks even on the small files.
  if (!fresh) {
    EXPECT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + p.string() + "' -o '" + s->db.string() +
                  "' --chunk 512 > /dev/null"), 0);
  }
  s->r = 2.0 * spacing(s->cloud);
  // The oracle's rays are built from the same direction values the SQL receives (Ray normalises
  // once, as `rayscan query` does for a rays file).
  for (const Ray& r : query_rays(s->cloud, 12, 7)) s->rays.emplace_back(r.origin(), r.direction());
  return (cache[name] = std::move(s)).get();
}

class SqliteScan : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    s_ = site(GetParam());
    if (!s_) GTEST_SKIP() << GetParam() << ": ../shared/data absent";
  }
  Site* s_ = nullptr;
};

TEST_P(SqliteScan, ImportKeepsEveryPointExactlyWithConservativeChunkBoxes) {
  Db db(s_->db);
  const auto& pos = s_->cloud.positions;
  std::vector<int> seen(pos.size(), 0);
  // Every point appears once with the reader's exact doubles, inside its chunk's float32 box.
  Stmt st(db.db, "SELECT p.point_index, p.x, p.y, p.z, c.min_x, c.max_x, c.min_y, c.max_y, c.min_z, c.max_z "
                 "FROM points p JOIN chunks c ON c.id = p.chunk");
  std::size_t n = 0;
  while (st.step()) {
    const long long i = st.i64(0);
    ASSERT_GE(i, 0);
    ASSERT_LT(i, (long long)pos.size());
    ++seen[i];
    const Vec3 p(st.d(1), st.d(2), st.d(3));
    ASSERT_EQ(p, pos[i]) << "point " << i;
    ASSERT_TRUE(st.d(4) <= p.x && p.x <= st.d(5) && st.d(6) <= p.y && p.y <= st.d(7) &&
                st.d(8) <= p.z && p.z <= st.d(9)) << "point " << i << " outside its chunk box";
    ++n;
  }
  EXPECT_EQ(n, pos.size());
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), (long)pos.size());
  // Rows of a chunk are the R*Tree's [first_row, first_row + count).
  Stmt c(db.db, "SELECT count(*) FROM chunks c JOIN points p ON p.chunk = c.id "
                "WHERE p.rowid < c.first_row OR p.rowid >= c.first_row + c.count");
  ASSERT_TRUE(c.step());
  EXPECT_EQ(c.i64(0), 0);
}

TEST_P(SqliteScan, FunctionsEqualTheCoreBitForBit) {
  Db db(s_->db);
  for (const Ray& ray : s_->rays) {
    const Vec3 o = ray.origin(), d = ray.direction() * 3.0;  // a non-unit direction
    Stmt st(db.db, "SELECT point_index, dist_ray(?1,?2,?3,?4,?5,?6,x,y,z), ray_time(?1,?2,?3,?4,?5,?6,x,y,z), "
                   "dist_plane(?1,?2,?3,?4,?5,?6,x,y,z) FROM points WHERE rowid % 97 = 0");
    for (int i = 0; i < 3; ++i) st.bind(i + 1, o[i]).bind(i + 4, d[i]);
    int n = 0;
    while (st.step()) {
      const Vec3& p = s_->cloud.positions[st.i64(0)];
      ASSERT_EQ(st.d(1), dist_ray(o, d, p));
      ASSERT_EQ(st.d(2), ray_point_terms(o, Ray(o, d).direction(), p).t);
      ASSERT_EQ(st.d(3), dist_plane(o, d, p));
      ++n;
    }
    EXPECT_GT(n, 0);
    // Bounds evaluation over every chunk box: the core's exact bounds widened by at most the node
    // test's rounding allowance, and holding every value dist_ray returns for the chunk's points.
    Stmt b(db.db, "SELECT min_x,min_y,min_z,max_x,max_y,max_z, "
                  "dist_ray_min(?1,?2,?3,?4,?5,?6,min_x,min_y,min_z,max_x,max_y,max_z), "
                  "dist_ray_max(?1,?2,?3,?4,?5,?6,min_x,min_y,min_z,max_x,max_y,max_z), "
                  "dist_plane_min(?1,?2,?3,?4,?5,?6,min_x,min_y,min_z,max_x,max_y,max_z), "
                  "dist_plane_max(?1,?2,?3,?4,?5,?6,min_x,min_y,min_z,max_x,max_y,max_z), "
                  "(SELECT min(dist_ray(?1,?2,?3,?4,?5,?6,x,y,z)) FROM points WHERE rowid >= first_row AND rowid < first_row + count), "
                  "(SELECT max(dist_ray(?1,?2,?3,?4,?5,?6,x,y,z)) FROM points WHERE rowid >= first_row AND rowid < first_row + count) "
                  "FROM chunks WHERE id % 7 = 0");
    for (int i = 0; i < 3; ++i) b.bind(i + 1, o[i]).bind(i + 4, d[i]);
    while (b.step()) {
      const AABB box{Vec3(b.d(0), b.d(1), b.d(2)), Vec3(b.d(3), b.d(4), b.d(5))};
      const Interval dr = dist_ray_bounds(o, d, box), dp = dist_plane_bounds(o, d, box);
      const double tol = node_test_tolerance(o, box);
      ASSERT_EQ(b.d(6), std::max(0.0, dr.lo - tol));
      ASSERT_EQ(b.d(7), dr.hi + tol);
      ASSERT_EQ(b.d(8), dp.lo - tol);
      ASSERT_EQ(b.d(9), dp.hi + tol);
      EXPECT_LE(b.d(6), b.d(10));
      EXPECT_GE(b.d(7), b.d(11));
    }
  }
}

// The paper's query `WHERE dist_ray(...) <= r` in the documented pruned form touches only chunks
// whose bounds admit the predicate and returns exactly the brute-force set.
TEST_P(SqliteScan, PaperQueryWithPruningCallbackEqualsBruteForce) {
  Db db(s_->db);
  Stmt total(db.db, "SELECT count(*) FROM chunks");
  ASSERT_TRUE(total.step());
  const long long chunks = total.i64(0);
  long long touched_sum = 0;
  for (const Ray& ray : s_->rays) {
    const Vec3 o = ray.origin(), d = ray.direction();
    Stmt q(db.db, "SELECT p.point_index FROM chunks c JOIN points p "
                  "ON p.rowid >= c.first_row AND p.rowid < c.first_row + c.count "
                  "WHERE c.id MATCH ray_prune(?1,?2,?3,?4,?5,?6,?7) AND dist_ray(?1,?2,?3,?4,?5,?6,p.x,p.y,p.z) <= ?7");
    for (int i = 0; i < 3; ++i) q.bind(i + 1, o[i]).bind(i + 4, d[i]);
    q.bind(7, s_->r);
    std::set<long long> got;
    while (q.step()) got.insert(q.i64(0));
    std::set<long long> want;
    for (std::size_t i = 0; i < s_->cloud.size(); ++i)
      if (dist_ray(o, d, s_->cloud.positions[i]) <= s_->r) want.insert((long long)i);
    EXPECT_EQ(got, want);
    EXPECT_FALSE(want.empty());
    // Chunks the callback admits = chunks whose stored box passes the bounds test; they include
    // every chunk holding a result.
    Stmt m(db.db, "SELECT id, min_x,min_y,min_z,max_x,max_y,max_z FROM chunks WHERE id MATCH ray_prune(?1,?2,?3,?4,?5,?6,?7)");
    for (int i = 0; i < 3; ++i) m.bind(i + 1, o[i]).bind(i + 4, d[i]);
    m.bind(7, s_->r);
    std::set<long long> admitted;
    while (m.step()) admitted.insert(m.i64(0));
    Stmt all(db.db, "SELECT id, min_x,min_y,min_z,max_x,max_y,max_z FROM chunks");
    std::set<long long> expect_admitted;
    while (all.step()) {
      const double box[6] = {all.d(1), all.d(2), all.d(3), all.d(4), all.d(5), all.d(6)};
      const double o3[3] = {o.x, o.y, o.z}, d3[3] = {d.x, d.y, d.z};
      double score;
      if (rs_ray_box_test(o3, d3, s_->r, -kInf, kInf, 0, box, &score) != RS_NOT_WITHIN)
        expect_admitted.insert(all.i64(0));
    }
    EXPECT_EQ(admitted, expect_admitted);
    Stmt hit(db.db, "SELECT DISTINCT chunk FROM points WHERE dist_ray(?1,?2,?3,?4,?5,?6,x,y,z) <= ?7");
    for (int i = 0; i < 3; ++i) hit.bind(i + 1, o[i]).bind(i + 4, d[i]);
    hit.bind(7, s_->r);
    while (hit.step()) EXPECT_TRUE(admitted.count(hit.i64(0))) << "chunk " << hit.i64(0) << " wrongly pruned";
    touched_sum += (long long)admitted.size();
  }
  // Pruning is real: far fewer chunks than the whole site on average.
  EXPECT_LT(touched_sum, chunks * (long long)s_->rays.size() * 3 / 4);
}

// ray_query (radius, time slab, kNN to and along the ray) equals the core ray query over the
// brute-force oracle and over the octree `rayscan query` uses: same points, same order, same bits.
TEST_P(SqliteScan, RayQueryEqualsCoreAndBruteForce) {
  Db db(s_->db);
  const BruteForceIndex brute(s_->cloud);
  const Octree octree = Octree::build_bulk(s_->cloud.positions);
  struct Case { const char* name; long long k; double r, t0, t1; const char* ord; };
  for (const Ray& ray : s_->rays) {
    const double t_hit = glm::length(s_->cloud.bounds().center() - ray.origin());
    const Case cases[] = {
        {"radius", -1, s_->r, -kInf, kInf, "ray"},
        {"time slab", -1, 4 * s_->r, t_hit - 20 * s_->r, t_hit + 20 * s_->r, "time"},
        {"kNN to the ray", 10, kInf, -kInf, kInf, "ray"},
        {"kNN to the ray within r", 5, s_->r, -kInf, kInf, "ray"},
        {"kNN along the ray", 8, s_->r, -kInf, kInf, "time"},
    };
    for (const Case& c : cases) {
      RayQuery q;
      if (c.k >= 0) q.k = (std::size_t)c.k;
      q.radius = c.r;
      q.t_min = c.t0;
      q.t_max = c.t1;
      q.order = std::string(c.ord) == "time" ? RayOrder::time : RayOrder::ray;
      const Ray same(ray.origin(), ray.direction());  // what ray_query(...) builds from its arguments
      const auto want = ray_query(brute, same, q);
      const auto oct = ray_query(octree, same, q);
      ASSERT_EQ(want.size(), oct.size());
      Stmt st(db.db, "SELECT point_index, t, distance, rank FROM ray_query(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10,?11)");
      const Vec3 o = ray.origin(), d = ray.direction();
      for (int i = 0; i < 3; ++i) st.bind(i + 1, o[i]).bind(i + 4, d[i]);
      if (c.k >= 0) sqlite3_bind_int64(st.s, 7, c.k);
      if (std::isfinite(c.r)) st.bind(8, c.r);
      if (std::isfinite(c.t0)) st.bind(9, c.t0).bind(10, c.t1);
      sqlite3_bind_text(st.s, 11, c.ord, -1, SQLITE_STATIC);
      std::size_t i = 0;
      while (st.step()) {
        ASSERT_LT(i, want.size()) << c.name;
        EXPECT_EQ(st.i64(0), (long long)want[i].index) << c.name << " rank " << i;
        EXPECT_EQ(st.i64(0), (long long)oct[i].index) << c.name << " rank " << i;
        EXPECT_EQ(st.d(1), want[i].t) << c.name;
        EXPECT_EQ(st.d(2), want[i].distance) << c.name;
        EXPECT_EQ(st.i64(3), (long long)i);
        ++i;
      }
      EXPECT_EQ(i, want.size()) << c.name;
      if (c.k > 0 && !std::isfinite(c.r)) { EXPECT_EQ(want.size(), (std::size_t)c.k) << c.name; }
      if (c.k > 0) { EXPECT_LE(want.size(), (std::size_t)c.k) << c.name; }
    }
  }
  // The dynamic k filter visits few chunks for kNN.
  Stmt st(db.db, "SELECT count(*) FROM ray_query(?1,?2,?3,?4,?5,?6, 1)");
  const Vec3 o = s_->rays[0].origin(), d = s_->rays[0].direction();
  for (int i = 0; i < 3; ++i) st.bind(i + 1, o[i]).bind(i + 4, d[i]);
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.i64(0), 1);
  Stmt stats(db.db, "SELECT json_extract(rayscan_stats(), '$.chunks_visited'), json_extract(rayscan_stats(), '$.chunks_total')");
  ASSERT_TRUE(stats.step());
  EXPECT_LT(stats.i64(0), stats.i64(1));
}

// A frustum (four planes around a ray): plane_prune on the R*Tree plus dist_plane <= 0 per point
// equals the brute-force set.
TEST_P(SqliteScan, FrustumWithPlanePruningEqualsBruteForce) {
  Db db(s_->db);
  const Ray& ray = s_->rays[0];
  const Vec3 o = ray.origin(), d = ray.direction();
  const Vec3 a = glm::normalize(glm::cross(d, std::abs(d.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0)));
  const Vec3 b = glm::cross(d, a);
  const double w = 10 * s_->r;
  const std::vector<Plane> planes = {{o + w * a, a}, {o - w * a, -a}, {o + w * b, b}, {o - w * b, -b}};
  std::string sql = "SELECT p.point_index FROM chunks c JOIN points p ON p.chunk = c.id WHERE ";
  for (std::size_t i = 0; i < planes.size(); ++i) {
    const Plane& pl = planes[i];
    char buf[512];
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", pl.point.x, pl.point.y,
                  pl.point.z, pl.normal.x, pl.normal.y, pl.normal.z);
    sql += std::string(i ? " AND " : "") + "c.id MATCH plane_prune(" + buf + ") AND dist_plane(" + buf + ", p.x, p.y, p.z) <= 0";
  }
  Stmt st(db.db, sql);
  std::set<long long> got, want;
  while (st.step()) got.insert(st.i64(0));
  for (std::size_t i = 0; i < s_->cloud.size(); ++i) {
    bool in = true;
    for (const Plane& pl : planes) in = in && dist_plane(pl.point, pl.normal, s_->cloud.positions[i]) <= 0;
    if (in) want.insert((long long)i);
  }
  EXPECT_EQ(got, want);
  EXPECT_FALSE(want.empty());
}

/// A double as SQL text that reads back as the same double.
std::string sql_number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

/// The first n values of v.
std::vector<double> head_values(std::vector<double> v, std::size_t n) {
  if (v.size() > n) v.resize(n);
  return v;
}

/// The chunks the connection's last ray_query read (rayscan_stats()).
long long chunks_visited(sqlite3* db) {
  Stmt st(db, "SELECT json_extract(rayscan_stats(), '$.chunks_visited')");
  EXPECT_TRUE(st.step());
  return st.i64(0);
}

/// A row of ray_query as the LIMIT test reads it.
struct LimitRow {
  long long point_index;
  double x, z, t, distance;
  bool operator==(const LimitRow& o) const {
    return point_index == o.point_index && x == o.x && z == o.z && t == o.t && distance == o.distance;
  }
};

// A query's LIMIT (+ OFFSET) bounds the hits ray_query keeps, as its k does, where nothing can
// drop or reorder rows after it: its rows are the first rows of the unlimited query and of the
// brute-force oracle, and LIMIT 10 reads the chunks k = 10 reads (fewer than the unlimited query).
// Where a condition or another order comes after it (WHERE on a column, ORDER BY another column,
// DESC, an expression, an ord only known when the statement runs), SQLite's rows are still the
// oracle's: the limit then must not cut the hits.
TEST_P(SqliteScan, LimitBoundsTheHitsKeptAndKeepsTheUnlimitedQuerysFirstRows) {
  Db db(s_->db);
  const BruteForceIndex brute(s_->cloud);
  const auto rows_of = [&](const std::string& sql, const char* ord_param = nullptr) {
    Stmt st(db.db, "SELECT point_index, x, z, t, distance FROM " + sql);
    if (ord_param) sqlite3_bind_text(st.s, 1, ord_param, -1, SQLITE_STATIC);
    std::vector<LimitRow> out;
    while (st.step()) out.push_back({st.i64(0), st.d(1), st.d(2), st.d(3), st.d(4)});
    return out;
  };
  const auto column = [](const std::vector<LimitRow>& rows, double LimitRow::*c) {
    std::vector<double> v;
    for (const LimitRow& r : rows) v.push_back(r.*c);
    return v;
  };
  const auto sorted = [](std::vector<double> v, bool descending = false) {
    std::sort(v.begin(), v.end());
    if (descending) std::reverse(v.begin(), v.end());
    return v;
  };
  const auto head = [](std::vector<LimitRow> v, std::size_t skip, std::size_t n) {
    v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(std::min(skip, v.size())));
    if (v.size() > n) v.resize(n);
    return v;
  };
  for (std::size_t ri = 0; ri < 3; ++ri) {
    const Ray& ray = s_->rays[ri];
    const Vec3 o = ray.origin(), d = ray.direction();
    std::string ray_args;
    for (int i = 0; i < 6; ++i) ray_args += (i ? "," : "") + sql_number(i < 3 ? o[i] : d[i - 3]);
    const double r = 20 * s_->r;
    for (const std::string ord : {"ray", "time"}) {
      RayQuery q;
      q.radius = r;
      q.order = ord == "time" ? RayOrder::time : RayOrder::ray;
      std::vector<LimitRow> want;
      for (const RayHit& h : ray_query(brute, Ray(o, d), q)) {
        const Vec3& p = s_->cloud.positions[h.index];
        want.push_back({(long long)h.index, p.x, p.z, h.t, h.distance});
      }
      ASSERT_GT(want.size(), 20u) << ord;
      const std::string call = "ray_query(" + ray_args + ", NULL, " + sql_number(r) + ", NULL, NULL, '" + ord + "')";
      const std::string key = ord == "time" ? "t" : "distance";
      const std::vector<LimitRow> all = rows_of(call);
      const long long unlimited_chunks = chunks_visited(db.db);
      ASSERT_EQ(all, want) << ord;
      // Pushed: no order, the rows' own order (rank, or key, source, point_index), with OFFSET.
      EXPECT_EQ(rows_of(call + " LIMIT 7"), head(want, 0, 7)) << ord;
      if (ord == "ray") {
        EXPECT_LT(chunks_visited(db.db), unlimited_chunks);  // nearest chunk first: it stops early
      } else {
        EXPECT_LE(chunks_visited(db.db), unlimited_chunks);
      }
      EXPECT_EQ(rows_of(call + " LIMIT 7 OFFSET 5"), head(want, 5, 7)) << ord;
      EXPECT_EQ(rows_of(call + " ORDER BY rank LIMIT 7"), head(want, 0, 7)) << ord;
      EXPECT_EQ(rows_of(call + " ORDER BY " + key + " LIMIT 7"), head(want, 0, 7)) << ord;
      // The order consumed (SQLite does not sort all rows after): the chunks LIMIT alone reads.
      if (ord == "ray") EXPECT_LT(chunks_visited(db.db), unlimited_chunks) << ord;
      EXPECT_EQ(rows_of(call + " ORDER BY " + key + ", source, point_index LIMIT 7 OFFSET 3"), head(want, 3, 7)) << ord;
      EXPECT_EQ(rows_of(call + " LIMIT -1"), want) << ord;
      EXPECT_TRUE(rows_of(call + " LIMIT 0").empty()) << ord;
      // Not pushed: the rows SQLite keeps are the oracle's.
      const double z_mid = sorted(column(want, &LimitRow::z))[want.size() / 2];
      std::vector<LimitRow> above;
      for (const LimitRow& w : want)
        if (w.z > z_mid) above.push_back(w);
      EXPECT_EQ(rows_of(call + " WHERE z > " + sql_number(z_mid) + " LIMIT 7"), head(above, 0, 7)) << ord;
      EXPECT_EQ(column(rows_of(call + " ORDER BY x LIMIT 7"), &LimitRow::x),
                head_values(sorted(column(want, &LimitRow::x)), 7)) << ord;
      EXPECT_EQ(column(rows_of(call + " ORDER BY x * 1 LIMIT 7"), &LimitRow::x),
                head_values(sorted(column(want, &LimitRow::x)), 7)) << ord;
      EXPECT_EQ(column(rows_of(call + " ORDER BY " + key + " DESC LIMIT 7"), key == "t" ? &LimitRow::t : &LimitRow::distance),
                head_values(sorted(column(want, key == "t" ? &LimitRow::t : &LimitRow::distance), true), 7)) << ord;
      const std::string other = ord == "time" ? "distance" : "t";
      EXPECT_EQ(column(rows_of(call + " ORDER BY " + other + " LIMIT 7"), other == "t" ? &LimitRow::t : &LimitRow::distance),
                head_values(sorted(column(want, other == "t" ? &LimitRow::t : &LimitRow::distance)), 7)) << ord;
      // ord as a parameter: unknown when the plan is made, so ORDER BY distance is SQLite's sort.
      const std::string param_call = "ray_query(" + ray_args + ", NULL, " + sql_number(r) + ", NULL, NULL, ?1)";
      EXPECT_EQ(column(rows_of(param_call + " ORDER BY distance LIMIT 7", ord.c_str()), &LimitRow::distance),
                head_values(sorted(column(want, &LimitRow::distance)), 7)) << ord;
    }
    // Unbounded radius: LIMIT 10 is k = 10, chunk for chunk.
    const std::string knn = "ray_query(" + ray_args + ")";
    const std::vector<LimitRow> limited = rows_of(knn + " LIMIT 10");
    const long long limited_chunks = chunks_visited(db.db);
    EXPECT_EQ(limited, rows_of("ray_query(" + ray_args + ", 10)"));
    EXPECT_EQ(limited_chunks, chunks_visited(db.db));
    Stmt total(db.db, "SELECT count(*) FROM chunks");
    ASSERT_TRUE(total.step());
    EXPECT_LT(limited_chunks, total.i64(0));
    // With k, the smaller bound: LIMIT 3 of k = 10 is the first 3 of k = 10's rows.
    EXPECT_EQ(rows_of("ray_query(" + ray_args + ", 10) LIMIT 3"), head(limited, 0, 3));
  }
}

INSTANTIATE_TEST_SUITE_P(Scans, SqliteScan, ::testing::ValuesIn(scan_names()),
                         [](const auto& i) { return i.param; });

// Bounds evaluation on one-point boxes: dist_ray_min <= dist_ray <= dist_ray_max (and the same for
// dist_plane) for every autzen point, the scalar functions' own values as the oracle. The core's
// exact bounds in double exceed dist_ray by rounding for about half these points, so a pruning
// clause on them could drop a point that qualifies.
TEST(SqliteFunctions, BoundsHoldTheScalarValueOfEveryPointOfTheBox) {
  Db db(site("autzen")->db);
  Stmt st(db.db, "SELECT count(*), "
                 "sum(dist_ray_min(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) > dist_ray(?1,?2,?3,?4,?5,?6,x,y,z)), "
                 "sum(dist_ray_max(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) < dist_ray(?1,?2,?3,?4,?5,?6,x,y,z)), "
                 "sum(dist_plane_min(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) > dist_plane(?1,?2,?3,?4,?5,?6,x,y,z)), "
                 "sum(dist_plane_max(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) < dist_plane(?1,?2,?3,?4,?5,?6,x,y,z)), "
                 "sum(ray_time_min(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) > ray_time(?1,?2,?3,?4,?5,?6,x,y,z)), "
                 "sum(ray_time_max(?1,?2,?3,?4,?5,?6,x,y,z,x,y,z) < ray_time(?1,?2,?3,?4,?5,?6,x,y,z)) FROM points");
  const double ray[6] = {636500, 849200, 600, 0.3, 0.2, -1};
  for (int i = 0; i < 6; ++i) st.bind(i + 1, ray[i]);
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.i64(0), 110000);
  for (int c = 1; c <= 6; ++c) EXPECT_EQ(st.i64(c), 0) << "column " << c;
}

// Finite inputs whose squares overflow: an error, not Infinity or NaN passed off as a distance.
TEST(SqliteFunctions, OverflowingDistancesAreErrors) {
  Db db(site("autzen")->db);
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 1,0,0, 0,1e155,0)"),
            "dist_ray: the result overflows double precision; expected coordinates and vector components of "
            "magnitude below about 1e150");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(-1e308,0,0, 1,0,0, 1e308,0,0)"),
            "dist_ray: the result overflows double precision; expected coordinates and vector components of "
            "magnitude below about 1e150");
  Stmt ok(db.db, "SELECT dist_ray(0,0,0, 1,0,0, 0,1e140,0)");
  ASSERT_TRUE(ok.step());
  EXPECT_DOUBLE_EQ(ok.d(0), 1e140);
}

// The bounds functions share one evaluation (rs_eval_bounds); each error names the function called.
TEST(SqliteFunctions, BoundsErrorsNameTheFunctionTheUserCalled) {
  Db db(site("autzen")->db);
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray_max(0,0,0, 1,0,0, 0,2,0, 1,1,1)"),
            "dist_ray_max: box ymin > ymax; expected min <= max on every axis");
  EXPECT_EQ(error_of(db.db, "SELECT ray_time_min(0,0,0, 0,0,0, 0,0,0, 1,1,1)"),
            "ray_time_min: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(error_of(db.db, "SELECT ray_time_max(0,0,0, 1,0,0, 0,0,0, 1,1,1)"), "");
  EXPECT_EQ(error_of(db.db, "SELECT dist_plane_max(0,0,0, 0,0,1, 0,0,0, 1,1,9e999)"),
            "dist_plane_max: argument 12 (zmax) is infinite; expected a finite number");
  EXPECT_EQ(error_of(db.db, "SELECT dist_plane_min(0,0,0, 0,0,0, 0,0,0, 1,1,1)"),
            "dist_plane_min: normal (nx,ny,nz) is zero; expected a non-zero vector");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray_min(0,0,0, 1,0,0, 0,0,0, 1e300,1,1)"),
            "dist_ray_min: the result overflows double precision; expected coordinates and vector components of "
            "magnitude below about 1e150");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray_max(0,0,0, 1,0,0, 0,0,0, 1,'a',1)"),
            "dist_ray_max: argument 11 has type text; expected a number");
}

TEST(SqliteFunctions, NullInNullOutAndClearErrors) {
  Db db(site("autzen")->db);
  Stmt n(db.db, "SELECT dist_ray(NULL,0,0,1,0,0,1,1,1) IS NULL, ray_time(0,0,0,1,0,0,1,1,NULL) IS NULL, "
                "dist_plane_min(0,0,0,0,0,1,NULL,0,0,1,1,1) IS NULL, "
                "(SELECT count(*) FROM ray_query(NULL,0,0,1,0,0))");
  ASSERT_TRUE(n.step());
  EXPECT_EQ(n.i64(0), 1);
  EXPECT_EQ(n.i64(1), 1);
  EXPECT_EQ(n.i64(2), 1);
  EXPECT_EQ(n.i64(3), 0);
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 0,0,0, 1,2,3)"),
            "dist_ray: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(error_of(db.db, "SELECT dist_plane(0,0,0, 0,0,0, 1,2,3)"),
            "dist_plane: normal (nx,ny,nz) is zero; expected a non-zero vector");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 1,0,0, 9e999,2,3)"),
            "dist_ray: argument 7 (x) is infinite; expected a finite number");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 1,0,0, 'a',2,3)"),
            "dist_ray: argument 7 has type text; expected a number");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 1,0,0, 1,2)"), "wrong number of arguments to function dist_ray()");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray_min(0,0,0, 1,0,0, 2,0,0, 1,1,1)"),
            "dist_ray_min: box xmin > xmax; expected min <= max on every axis");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, -1)"),
            "ray_query: k must be an integer >= 0 (NULL: all points)");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, 1, -2)"),
            "ray_query: radius r is negative; expected a number >= 0 (NULL: unbounded)");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, 1, 1, 5, 2)"),
            "ray_query: t_min/t_max (5, 2): expected t_min <= t_max, not NaN");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, 1, 1, 0, 2, 'x')"),
            "ray_query: ord must be 'ray' (kNN to the ray) or 'time' (kNN along the ray)");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 0,0,0)"),
            "ray_query: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_NE(error_of(db.db, "SELECT * FROM ray_query(0,0,0)"), "");
  EXPECT_NE(error_of(db.db, "SELECT id FROM chunks WHERE id MATCH ray_prune(0,0,0, 0,0,0, 1)"), "");
  EXPECT_NE(error_of(db.db, "SELECT id FROM chunks WHERE id MATCH ray_prune(0,0,0, 1,0,0)"), "");
}

// is_sql_identifier: known answers, and every name of the list that it accepts SQLite takes
// unquoted as a column name (the database as the oracle of the accepting side).
TEST(SqlImport, IdentifiersAreRegularAsciiNamesWithinTheLength) {
  const std::string l63(63, 'a'), l64(64, 'a');
  struct Case {
    std::string s;
    std::size_t max_len;
    bool upper, want;
  };
  const std::vector<Case> cases = {
      {"gps_time", 63, true, true},  {"_x1", 63, true, true},     {"GpsTime", 63, true, true},
      {"GpsTime", 63, false, false}, {"site_2", 50, false, true}, {"", 63, true, false},
      {"1abc", 63, true, false},     {"a b", 63, true, false},    {"a-b", 63, true, false},
      {"a;drop", 63, true, false},   {"caf\xc3\xa9", 63, true, false}, {l63, 63, true, true},
      {l64, 63, true, false},        {l63, 50, false, false},     {"\"q\"", 63, true, false}};
  Db db(":memory:", false);
  for (const Case& c : cases) {
    EXPECT_EQ(sql::is_sql_identifier(c.s, c.max_len, c.upper), c.want) << "'" << c.s << "'";
    if (c.want) {
      const std::string table = "t_" + std::to_string(&c - cases.data());
      EXPECT_EQ(error_of(db.db, "CREATE TEMP TABLE " + table + "(" + c.s + " INTEGER)"), "") << c.s;
    }
  }
}

// check_attribute_names: the columns an import would create (the built-ins, then red, green, blue
// for rgb, else the name) must differ other than by case. SQLite is the oracle: it refuses a table
// with two such columns ("duplicate column name") exactly when the check throws.
TEST(SqlImport, AttributeColumnsEqualButForCaseAreRejectedAsTheDatabaseWould) {
  const std::vector<std::vector<std::string>> cases = {
      {"intensity", "classification", "gps_time", "rgb", "GpsTime"},
      {"red"},
      {"Red", "green", "Blue"},
      {"rgb", "RGB"},
      {"y"},
      {"chunk"},
      {"intensity", "intensity"},
      {"GpsTime", "gpstime"},
      {"X"},
      {"z"},
      {"Point_Index"},
      {"rgb", "Red"},
      {"rgb", "rgb"},
      {"blue"},
      {"Chunk_2", "chunk_2"},
      {"source_id", "SOURCE"}};
  Db db(":memory:", false);
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const std::vector<std::string>& names = cases[k];
    std::string ddl = "CREATE TEMP TABLE cols_" + std::to_string(k) + "(point_index, source, chunk, x, y, z";
    for (const std::string& n : names) ddl += n == "rgb" ? ", red, green, blue" : ", " + n;
    ddl += ")";
    const bool db_accepts = error_of(db.db, ddl).empty();
    bool check_accepts = true;
    std::string message;
    try {
      sql::check_attribute_names(names);
    } catch (const std::invalid_argument& e) {
      check_accepts = false;
      message = e.what();
    }
    EXPECT_EQ(check_accepts, db_accepts) << ddl;
    if (!check_accepts) {  // one line naming the attribute that collides
      EXPECT_NE(message.find("attribute '"), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }
  // pgpointcloud's PointIndex dimension is built in only for --pcpatch.
  EXPECT_NO_THROW(sql::check_attribute_names({"pointindex"}));
  EXPECT_THROW(sql::check_attribute_names({"pointindex"}, true), std::invalid_argument);
  EXPECT_THROW(sql::check_attribute_names({"PointIndex"}, true), std::invalid_argument);
}

TEST(SqliteFunctions, DatabaseWithoutChunkIndexIsAnError) {
  const fs::path p = tmpdir() / "plain.sqlite";
  fs::remove(p);
  sqlite3* raw;
  ASSERT_EQ(sqlite3_open(p.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw, "CREATE TABLE points(point_index, source, chunk, x, y, z)", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(raw);
  Db db(p);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, 3)").rfind(
                "ray_query: the database has no chunk index (R*Tree 'chunks')", 0), 0u)
      << error_of(db.db, "SELECT * FROM ray_query(0,0,0, 1,0,0, 3)");
}

// ray_query reads each chunk from its packed BLOB (chunk_points); a database without that table
// (an older import) is read row by row with the same answers, and a BLOB of the wrong size (a
// corrupted file) is an SQL error naming the chunk, not a read past the BLOB. The connection
// closes cleanly although ray_query keeps prepared statements (finalized in xDisconnect).
TEST(SqliteFunctions, PackedChunksEqualRowsAndBadBlobsAreErrors) {
  const fs::path src = site("autzen")->db, p = tmpdir() / "rows.sqlite";
  fs::copy_file(src, p, fs::copy_options::overwrite_existing);
  const Site& s = *site("autzen");
  auto answers = [&](sqlite3* db) {
    std::vector<std::vector<long long>> out;
    for (const Ray& ray : s.rays) {
      for (const char* q : {"SELECT point_index FROM ray_query(?1,?2,?3,?4,?5,?6, 8, NULL, NULL, NULL, 'ray')",
                            "SELECT point_index FROM ray_query(?1,?2,?3,?4,?5,?6, 6, ?7, NULL, NULL, 'time')",
                            "SELECT point_index FROM ray_query(?1,?2,?3,?4,?5,?6, NULL, ?7)"}) {
        Stmt st(db, q);
        for (int i = 0; i < 3; ++i) st.bind(i + 1, ray.origin()[i]).bind(i + 4, ray.direction()[i]);
        st.bind(7, s.r);
        out.emplace_back();
        while (st.step()) out.back().push_back(st.i64(0));
      }
    }
    return out;
  };
  std::vector<std::vector<long long>> packed;
  {
    Db db(src);
    packed = answers(db.db);
  }
  {
    Db db(p);
    ASSERT_EQ(sqlite3_exec(db.db, "DROP TABLE chunk_points", nullptr, nullptr, nullptr), SQLITE_OK);
  }
  {
    Db db(p);
    EXPECT_EQ(answers(db.db), packed);
    ASSERT_EQ(sqlite3_close(db.db), SQLITE_OK);  // cached statements do not keep it busy
    db.db = nullptr;
  }
  fs::copy_file(src, p, fs::copy_options::overwrite_existing);
  Db db(p);
  ASSERT_EQ(sqlite3_exec(db.db, "UPDATE chunk_points SET data = x'0011'", nullptr, nullptr, nullptr), SQLITE_OK);
  const Ray& ray = s.rays[0];
  char sql[512];
  std::snprintf(sql, sizeof sql, "SELECT * FROM ray_query(%.17g,%.17g,%.17g,%.17g,%.17g,%.17g, 3)", ray.origin().x,
                ray.origin().y, ray.origin().z, ray.direction().x, ray.direction().y, ray.direction().z);
  const std::string e = error_of(db.db, sql);
  EXPECT_EQ(e.rfind("ray_query: reading table 'chunk_points': chunk ", 0), 0u) << e;
  EXPECT_NE(e.find("has 2 bytes; expected"), std::string::npos) << e;
}

TEST(SqliteFunctions, CorruptedDatabaseGivesAnErrorNotACrash) {
  const fs::path src = site("autzen")->db, p = tmpdir() / "corrupt.sqlite";
  fs::copy_file(src, p, fs::copy_options::overwrite_existing);
  {  // overwrite pages in the middle of the file (R*Tree and points b-tree pages)
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    const auto size = fs::file_size(p);
    for (std::uintmax_t off = 8192; off < size; off += 8192 * 7) {
      f.seekp((std::streamoff)off + 100);
      const std::string junk(3000, '\xA5');
      f.write(junk.data(), (std::streamsize)junk.size());
    }
  }
  Db db(p);
  const std::string e1 = error_of(db.db, "SELECT * FROM ray_query(636500,849000,600, 0,0,-1, 5)");
  const std::string e2 = error_of(db.db, "SELECT count(*) FROM chunks WHERE id MATCH ray_prune(636500,849000,600, 0,0,-1, 3)");
  const std::string e3 = error_of(db.db, "SELECT sum(dist_ray(0,0,0,1,0,0,x,y,z)) FROM points");
  EXPECT_TRUE(!e1.empty() || !e2.empty() || !e3.empty()) << "corruption went unnoticed";
}

TEST(SqliteImportCli, BadInputExitsTwoWithOneLineAndLeavesNoFile) {
  const fs::path out = tmpdir() / "bad.sqlite";
  const std::string bin = RAYSCAN_BIN;
  EXPECT_EQ(run(bin + " db import /nonexistent.las -o " + out.string() + " 2>/dev/null"), 2);
  EXPECT_EQ(run(bin + " db import " + scan_path("autzen").string() + " -o " + out.string() + " --chunk 0 2>/dev/null"), 2);
  EXPECT_EQ(run(bin + " db import " + scan_path("autzen").string() + " -o " + out.string() +
                " --attributes nir 2>/dev/null"), 2);
  EXPECT_EQ(run(bin + " db import " + scan_path("autzen").string() + " -o " + out.string() +
                " --attributes intensity,intensity 2>/dev/null"), 2);  // one column twice: refused by the import, before the database sees it
  EXPECT_EQ(run(bin + " db import " + scan_path("autzen").string() + " 2>/dev/null"), 2);
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(tmpdir()))
    EXPECT_EQ(e.path().filename().string().find(".bad.sqlite.tmp"), std::string::npos);
  // Attributes are stored as asked.
  const fs::path good = tmpdir() / "attrs.sqlite";
  ASSERT_EQ(run(bin + " db import " + scan_path("autzen").string() + " -o " + good.string() +
                " --attributes intensity,classification,gps_time,rgb > /dev/null"), 0);
  const PointCloud c = io::read_point_cloud(scan_path("autzen"));
  Db db(good, false);
  Stmt st(db.db, "SELECT point_index, intensity, classification, gps_time, red, green, blue FROM points WHERE rowid % 101 = 0");
  int n = 0;
  while (st.step()) {
    const auto i = (std::size_t)st.i64(0);
    EXPECT_EQ(st.i64(1), c.intensity[i]);
    EXPECT_EQ(st.i64(2), c.classification[i]);
    EXPECT_EQ(st.d(3), c.gps_time[i]);
    EXPECT_EQ(st.i64(4), c.rgb[i].r);
    EXPECT_EQ(st.i64(6), c.rgb[i].b);
    ++n;
  }
  EXPECT_GT(n, 100);
  // Without --chunk: chunks of the documented default size (the last one partial).
  Stmt ch(db.db, "SELECT count(*), max(count), min(count) FROM chunks");
  ASSERT_TRUE(ch.step());
  const long long per = sql::ImportOptions::kDefaultChunkSize;
  EXPECT_EQ(ch.i64(0), ((long long)c.size() + per - 1) / per);
  EXPECT_EQ(ch.i64(1), per);
  EXPECT_EQ(ch.i64(2), (long long)c.size() - (ch.i64(0) - 1) * per);
}

// The import streams the input: it orders the points with the index's external sort.
// With a 1 MiB budget (many sort runs) it writes the same rows as an import of an index file built
// by `rayscan index`, every row carries the reader's exact point and colour (the file's own values,
// read here with read_point_cloud), and nothing is left in the temporary folder.
TEST(SqliteImportCli, StreamingImportEqualsIndexFileImportAndLeavesNoTemporaries) {
  const std::string bin = RAYSCAN_BIN, cloud = scan_path("autzen").string();
  const fs::path tmp = tmpdir() / "stream-tmp", a = tmpdir() / "stream.sqlite", b = tmpdir() / "from-rsi.sqlite",
                 rsi = tmpdir() / "autzen.rsi";
  fs::create_directories(tmp);
  ASSERT_EQ(run(bin + " db import " + cloud + " -o " + a.string() + " --attributes rgb --memory 1M --temp-dir " +
                tmp.string() + " > /dev/null"), 0);
  EXPECT_TRUE(fs::is_empty(tmp)) << "temporary index or sort runs left in " << tmp;
  ASSERT_EQ(run(bin + " index " + cloud + " -o " + rsi.string() + " --attributes id,rgb > /dev/null 2>&1"), 0);
  ASSERT_EQ(run(bin + " db import " + rsi.string() + " -o " + b.string() + " --attributes rgb > /dev/null"), 0);
  // An attribute the index file does not store is a one-line error, exit 2.
  EXPECT_EQ(run(bin + " db import " + rsi.string() + " -o " + (tmpdir() / "x.sqlite").string() +
                " --attributes intensity 2>/dev/null"), 2);

  const PointCloud c = io::read_point_cloud(cloud);
  Db da(a, false), db(b, false);
  const std::string q = "SELECT rowid, point_index, source, chunk, x, y, z, red, green, blue FROM points ORDER BY rowid";
  Stmt sa(da.db, q), sb(db.db, q);
  std::vector<int> seen(c.size(), 0);
  std::size_t n = 0;
  while (sa.step()) {
    ASSERT_TRUE(sb.step());
    for (int col = 0; col < 10; ++col) ASSERT_EQ(sa.d(col), sb.d(col)) << "row " << n << " column " << col;
    const auto i = static_cast<std::size_t>(sa.i64(1));
    ASSERT_LT(i, c.size());
    ++seen[i];
    EXPECT_EQ(Vec3(sa.d(4), sa.d(5), sa.d(6)), c.positions[i]);
    EXPECT_EQ(sa.i64(7), c.rgb[i].r);
    EXPECT_EQ(sa.i64(9), c.rgb[i].b);
    ++n;
  }
  EXPECT_FALSE(sb.step());
  EXPECT_EQ(n, c.size());
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(c.size()));
  // The sources table names the cloud as given (the index file's import names the indexed file).
  Stmt src(da.db, "SELECT path, point_count FROM sources");
  ASSERT_TRUE(src.step());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(sqlite3_column_text(src.s, 0))), cloud);
  EXPECT_EQ(src.i64(1), static_cast<long long>(c.size()));
}


/// The text of a file (a command's captured stderr).
std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  return std::string(std::istreambuf_iterator<char>(f), {});
}


// The sources table keeps each file's CRS as WKT, as `rayscan info --json` reports it (the
// oracle): a WKT VLR (autzen, append-bug), GeoKeys of a compound CRS (Haystack_Rock) and no CRS
// (simple.las: NULL).
TEST(SqliteImportCli, SourcesKeepTheCrsAsRayscanInfoReportsIt) {
  const std::string bin = RAYSCAN_BIN;
  int with_crs = 0;
  for (const char* name : {"las/autzen_trim.las", "las/append-bug.las", "las/Haystack_Rock.las", "las/simple.las"}) {
    const fs::path cloud = fs::path(RAYSCAN_TEST_DATA) / name, out = tmpdir() / "crs.sqlite";
    const InfoCrs want = info_crs(cloud);
    with_crs += !want.wkt.empty();
    ASSERT_EQ(run(bin + " db import '" + cloud.string() + "' -o " + out.string() + " -q > /dev/null"), 0) << name;
    Db db(out, false);
    Stmt st(db.db, "SELECT crs_wkt FROM sources");
    ASSERT_TRUE(st.step()) << name;
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(st.s, 0));
    if (want.wkt.empty()) EXPECT_EQ(sqlite3_column_type(st.s, 0), SQLITE_NULL) << name;
    else EXPECT_EQ(std::string(text ? text : ""), want.wkt) << name;
  }
  EXPECT_EQ(with_crs, 3);
}

// The progress on stderr (a log, not a terminal): the temporary index's phases, then insert, index
// and done, each of the file's points (the reader's count, the oracle), done last; no phase in
// another unit (the index's "spacing": 1 of 1). An index file's import has only the last three.
TEST(SqliteImportCli, ProgressPhasesCountPointsAndEndWithDone) {
  const std::string bin = RAYSCAN_BIN, cloud = scan_path("autzen").string();
  const fs::path out = tmpdir() / "progress.sqlite", err = tmpdir() / "progress.err", rsi = tmpdir() / "progress.rsi";
  const std::uint64_t n = io::read_point_cloud(cloud, io::ReadOptions{.scalars = false}).size();
  ASSERT_EQ(run(bin + " db import '" + cloud + "' -o " + out.string() + " > /dev/null 2> " + err.string()), 0);
  expect_import_phases(slurp(err), n, true);
  ASSERT_EQ(run(bin + " index '" + cloud + "' -o " + rsi.string() + " --attributes id -q > /dev/null"), 0);
  ASSERT_EQ(run(bin + " db import " + rsi.string() + " -o " + out.string() + " > /dev/null 2> " + err.string()), 0);
  expect_import_phases(slurp(err), n, false);
}

// A direction whose squared length leaves the normal doubles (0,0,1e-320: |d|^2 underflows to 0;
// 1e300: it overflows) cannot be normalised, and every answer from it would be wrong (ray_query:
// far points first, dist_ray NULL, dist_plane inf). Every function refuses it through the core's rule with a one-line message; a direction
// just inside the range answers exactly as its unit multiple (the oracle: the same query with the
// unit direction).
TEST(SqliteFunctions, DirectionsThatCannotBeNormalisedAreErrorsNotWrongAnswers) {
  Db db(site("autzen")->db);
  const std::string tiny = "direction (dx,dy,dz) = (0,0,9.99989e-321) cannot be normalised exactly; expected "
                           "a finite length between about 1.5e-154 and 1.3e154";
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 0,0,1e-320, 1,2,3)"), "dist_ray: " + tiny);
  EXPECT_EQ(error_of(db.db, "SELECT ray_time(0,0,0, 0,0,1e-320, 1,2,3)"), "ray_time: " + tiny);
  EXPECT_EQ(error_of(db.db, "SELECT dist_plane(0,0,0, 0,0,1e-320, 1,2,3)"),
            "dist_plane: normal (nx,ny,nz) = (0,0,9.99989e-321) cannot be normalised exactly; expected a "
            "finite length between about 1.5e-154 and 1.3e154");
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray_min(0,0,0, 0,0,1e-320, 0,0,0,1,1,1)"), "dist_ray_min: " + tiny);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849000,600, 0,0,1e-320, 5)"), "ray_query: " + tiny);
  EXPECT_EQ(error_of(db.db, "SELECT dist_ray(0,0,0, 1e300,1e300,1, 1,2,3)"),
            "dist_ray: direction (dx,dy,dz) = (1e+300,1e+300,1) cannot be normalised exactly; expected a "
            "finite length between about 1.5e-154 and 1.3e154");
  // Just inside the range: the same rows, distances and times as the unit direction.
  const Site& s = *site("autzen");
  const Ray& ray = s.rays[0];
  auto rows = [&](double scale) {
    Stmt st(db.db, "SELECT point_index, distance, t FROM ray_query(?1,?2,?3,?4,?5,?6, 20)");
    for (int i = 0; i < 3; ++i) st.bind(i + 1, ray.origin()[i]).bind(i + 4, ray.direction()[i] * scale);
    std::vector<std::tuple<long long, double, double>> out;
    while (st.step()) out.emplace_back(st.i64(0), st.d(1), st.d(2));
    return out;
  };
  const auto unit = rows(1.0);
  ASSERT_EQ(unit.size(), 20u);
  const auto small = rows(1e-150);
  ASSERT_EQ(small.size(), unit.size());
  for (std::size_t i = 0; i < unit.size(); ++i) {
    EXPECT_EQ(std::get<0>(small[i]), std::get<0>(unit[i])) << "rank " << i;
    EXPECT_NEAR(std::get<1>(small[i]), std::get<1>(unit[i]), 1e-9) << "rank " << i;
  }
}

// ray_query's positional arguments fill its hidden columns in order; with five the sixth (dz) is
// absent, and taking it as 0 would return every point. Each missing ray argument is named.
TEST(SqliteFunctions, RayQueryWithTooFewArgumentsNamesTheMissingOne) {
  Db db(site("autzen")->db);
  const std::string tail = " is missing; expected ray_query(ox,oy,oz, dx,dy,dz [, k, r, t_min, t_max, ord])";
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849000,600, 0,-1)"), "ray_query: argument dz" + tail);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849000,600, 0)"), "ray_query: argument dy" + tail);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849000,600)"), "ray_query: argument dx" + tail);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query()"), "ray_query: argument ox" + tail);
  // NULL in, no rows, but only for a call with its six ray arguments.
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(3, NULL, 'ray')"), "ray_query: argument dx" + tail);
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849000,600, 0,-1,0, 3, '2')"),
            "ray_query: argument r has type text; expected a number");
}

// ray_prune / plane_prune are R*Tree callbacks, whose API returns only an error code ("SQL logic
// error"): the reason is rayscan_error()'s. A text radius is an error, not its numeric value.
TEST(SqliteFunctions, PruneCallbackErrorsKeepTheirReason) {
  Db db(site("autzen")->db);
  const auto reason = [&](const std::string& sql) {
    EXPECT_NE(error_of(db.db, sql), "") << sql;
    Stmt st(db.db, "SELECT rayscan_error()");
    EXPECT_TRUE(st.step());
    const auto* t = sqlite3_column_text(st.s, 0);
    return t ? std::string(reinterpret_cast<const char*>(t)) : std::string("(null)");
  };
  {
    Stmt st(db.db, "SELECT rayscan_error() IS NULL");
    ASSERT_TRUE(st.step());
    EXPECT_EQ(st.i64(0), 1);  // no failure yet
  }
  const std::string m = "SELECT id FROM chunks WHERE id MATCH ";
  EXPECT_EQ(reason(m + "ray_prune(0,0,0, 0,0,0, 1)"), "ray_prune: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(reason(m + "ray_prune(0,0,0, 1,0,0)"), "ray_prune: 6 arguments; expected ox,oy,oz, dx,dy,dz, r [, t_min, t_max]");
  EXPECT_EQ(reason(m + "ray_prune(0,0,0, 1,0,0, '1')"), "ray_prune: argument r is text; expected a number");
  EXPECT_EQ(reason(m + "ray_prune(0,0,0, 1,0,0, 1, 5, 2)"), "ray_prune: t_min/t_max (5, 2): expected t_min <= t_max, not NaN");
  EXPECT_EQ(reason(m + "ray_prune(0,NULL,0, 1,0,0, 1)"), "ray_prune: argument oy is NULL; expected a number");
  EXPECT_EQ(reason(m + "ray_prune(0,0,0, 0,0,1e-320, 1)").rfind("ray_prune: direction (dx,dy,dz) = (0,0,", 0), 0u);
  EXPECT_EQ(reason(m + "plane_prune(0,0,0, 0,0,0)"), "plane_prune: normal (nx,ny,nz) is zero; expected a non-zero vector");
  EXPECT_EQ(reason(m + "plane_prune(0,0,0, 0,0,x'01')"), "plane_prune: argument nz is a blob; expected a number");
  // NULL r, t_min, t_max keep their defaults (unbounded), as documented.
  EXPECT_EQ(error_of(db.db, m + "ray_prune(636500,849000,600, 0,0,-1, NULL, NULL, NULL)"), "");
}

// rayscan_error() explains the last MATCH whose arguments were checked: a later MATCH (or a
// ray_query, which runs one) that passes clears it, so an unrelated later error is not explained
// by an old reason. The bad value of a plane is named, as PostgreSQL's plane_below names it.
TEST(SqliteFunctions, PruneErrorIsClearedByALaterMatchThatPasses) {
  Db db(site("autzen")->db);
  const auto error = [&] {
    Stmt st(db.db, "SELECT rayscan_error()");
    EXPECT_TRUE(st.step());
    const auto* t = sqlite3_column_text(st.s, 0);
    return t ? std::string(reinterpret_cast<const char*>(t)) : std::string("(null)");
  };
  const std::string m = "SELECT id FROM chunks WHERE id MATCH ";
  EXPECT_NE(error_of(db.db, m + "plane_prune(0,0,0, 1e999,0,1)"), "");
  EXPECT_EQ(error(), "plane_prune: nx is infinite; expected a finite number");
  EXPECT_EQ(error_of(db.db, m + "plane_prune(636300,849000,0, 1,0,0)"), "");
  EXPECT_EQ(error(), "(null)");
  EXPECT_NE(error_of(db.db, m + "ray_prune(0,0,0, 0,0,0, 1)"), "");
  EXPECT_EQ(error(), "ray_prune: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849200,600, 0,0,-1, 3)"), "");
  EXPECT_EQ(error(), "(null)");
}

// ray_query's arguments are its hidden columns, and a range is no value to run with (and on an
// argument not given, whose column reads NULL, would silently match nothing), so a condition other
// than = on one is an error naming the argument. The same argument given with = is an argument like
// a positional one (the oracle: the positional call's rows).
TEST(SqliteFunctions, OtherConditionsOnRayQueryArgumentsAreErrors) {
  Db db(site("autzen")->db);
  const std::string ray = "ox = 636500 AND oy = 849200 AND oz = 600 AND dx = 0 AND dy = 0 AND dz = -1";
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query WHERE " + ray + " AND r < 2"),
            "ray_query: r must be given as an argument (or r = value); expected no other condition on it");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849200,600, 0,0,-1, 5) WHERE k > 3"),
            "ray_query: k must be given as an argument (or k = value); expected no other condition on it");
  EXPECT_EQ(error_of(db.db, "SELECT * FROM ray_query(636500,849200,600, 0,0,-1, 5) WHERE ord LIKE 'r%'"),
            "ray_query: ord must be given as an argument (or ord = value); expected no other condition on it");
  Stmt named(db.db, "SELECT count(*), sum(point_index) FROM ray_query WHERE " + ray + " AND r = 2");
  Stmt positional(db.db, "SELECT count(*), sum(point_index) FROM ray_query(636500,849200,600, 0,0,-1, NULL, 2)");
  ASSERT_TRUE(named.step());
  ASSERT_TRUE(positional.step());
  EXPECT_GT(positional.i64(0), 0);
  EXPECT_EQ(named.i64(0), positional.i64(0));
  EXPECT_EQ(named.i64(1), positional.i64(1));
}

// ray_query's hidden columns read, in every row, its arguments as given, value and type (the
// oracle: the arguments written in the query), as SQLite's own table-valued functions
// (generate_series) return theirs; one not given reads NULL, which ray_query takes as its default.
// So whether given positionally or as `column = value`, and with a LIMIT that bounds the hits kept,
// where k still reads as given.
TEST(SqliteFunctions, RayQueryHiddenColumnsReadTheArgumentsGiven) {
  Db db(site("autzen")->db);
  const std::string cols = "ox, oy, oz, dx, dy, dz, k, r, t_min, t_max, ord";
  // Each row's hidden columns as "type:value" (sqlite3_column_type, then the text SQLite gives it).
  const auto hidden = [&](const std::string& sql) {
    std::vector<std::string> rows;
    Stmt st(db.db, sql);
    int rc;
    while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) {
      std::string row;
      for (int i = 0; i < sqlite3_column_count(st.s); ++i) {
        const int t = sqlite3_column_type(st.s, i);
        const auto* v = sqlite3_column_text(st.s, i);
        row += std::string(i ? " " : "") + (t == SQLITE_INTEGER ? "int:" : t == SQLITE_FLOAT ? "real:" : t == SQLITE_TEXT ? "text:" : "null:") +
               (v ? reinterpret_cast<const char*>(v) : "");
      }
      rows.push_back(row);
    }
    EXPECT_EQ(rc, SQLITE_DONE) << sql << ": " << sqlite3_errmsg(db.db);
    return rows;
  };
  const auto given = [](const std::string& row, std::size_t n) { return std::vector<std::string>(n, row); };
  auto rows = hidden("SELECT " + cols + " FROM ray_query(636500, 849200.5, 600, 0, 0, -1, 5, 20.25, NULL, 1000, 'time')");
  EXPECT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows, given("int:636500 real:849200.5 int:600 int:0 int:0 int:-1 int:5 real:20.25 null: int:1000 text:time", 5));
  rows = hidden("SELECT " + cols + " FROM ray_query WHERE ox = 636500 AND oy = 849200 AND oz = 600.5 AND dx = 0 AND "
                "dy = 0 AND dz = -1 AND r = 2");
  EXPECT_GT(rows.size(), 0u);
  EXPECT_EQ(rows, given("int:636500 int:849200 real:600.5 int:0 int:0 int:-1 null: int:2 null: null: null:", rows.size()));
  rows = hidden("SELECT k, r FROM ray_query(636500, 849200, 600, 0, 0, -1, 10, NULL) LIMIT 3");
  EXPECT_EQ(rows, given("int:10 null:", 3));
  rows = hidden("SELECT k FROM ray_query(636500, 849200, 600, 0, 0, -1) LIMIT 2");
  EXPECT_EQ(rows, given("null:", 2));
}

// A cloud in a geographic CRS (lon/lat degrees beside heights in metres) or a geocentric one (z
// not up) imports, but the SQL functions' distances would mix units or axes: one warning line per
// such CRS names the first file with it and the CRS (the oracle: the CRS the file was written
// with, GDAL's name of it and its EPSG code where rayscan identifies one), on stderr even with -q.
// A projected cloud gets none.
TEST(SqliteImportCli, GeographicOrGeocentricCrsIsWarnedAbout) {
  const std::string bin = RAYSCAN_BIN;
  const auto cloud_in = [&](const std::string& name, const std::string& epsg, Vec3 origin, double step) {
    PointCloud pc;
    for (int i = 0; i < 400; ++i) pc.positions.push_back(origin + Vec3(step * (i % 20), step * (i / 20), 10.0 + i % 7));
    pc.crs_wkt = rayscan::test::crs_wkt(epsg);
    const fs::path p = tmpdir() / name;
    io::write_point_cloud(p, pc);
    return p;
  };
  const fs::path lonlat = cloud_in("lonlat.las", "EPSG:4326", Vec3(-123.07, 44.05, 0), 1e-5);
  const fs::path lonlat2 = cloud_in("lonlat2.las", "EPSG:4326", Vec3(-123.06, 44.05, 0), 1e-5);
  const fs::path ecef = cloud_in("ecef.las", "EPSG:4978", Vec3(-2.5e6, -3.8e6, 4.5e6), 0.5);
  const fs::path utm = cloud_in("utm.las", "EPSG:32610", Vec3(500000, 4877000, 0), 0.5);
  const fs::path out = tmpdir() / "crs-warning.sqlite", err = tmpdir() / "crs-warning.err";
  const std::string tail = ": the cloud's CRS is geographic or geocentric: the SQL functions' distances, radii and "
                           "times need a projected CRS (x east, y north, z up); reproject the cloud";
  const auto warnings = [&](const std::string& inputs) {
    EXPECT_EQ(run(bin + " db import " + inputs + " -o " + out.string() + " -q > /dev/null 2> " + err.string()), 0) << inputs;
    std::vector<std::string> lines;
    std::istringstream in(slurp(err));
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    return lines;
  };
  std::vector<std::string> w = warnings(lonlat.string());
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind("rayscan db: warning: " + lonlat.string() + " (WGS 84, EPSG:4326)" + tail, 0), 0u) << w[0];
  // Two files in one CRS: one line, naming the first.
  w = warnings(lonlat.string() + " " + lonlat2.string());
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind("rayscan db: warning: " + lonlat.string() + " (WGS 84, EPSG:4326)" + tail, 0), 0u) << w[0];
  w = warnings(ecef.string());
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind("rayscan db: warning: " + ecef.string() + " (WGS 84, EPSG:4978)" + tail, 0), 0u) << w[0];
  EXPECT_TRUE(warnings(utm.string()).empty());
}

// An attribute named like a column the engine reserves (a PLY property "rowid") would be SQLite's
// row id, its values lost. The import refuses such names, before reading, with one line
// (exit 2). SQLite is the oracle of its reserved names: each is selectable from a table that has
// no such column.
TEST(SqliteImportCli, AttributeNamedLikeAReservedColumnIsRefused) {
  const fs::path ply = tmpdir() / "rowid.ply", out = tmpdir() / "rowid.sqlite", err = tmpdir() / "rowid.err";
  {
    std::ofstream f(ply);
    f << "ply\nformat ascii 1.0\nelement vertex 2000\nproperty float x\nproperty float y\nproperty float z\n"
         "property float rowid\nend_header\n";
    for (int i = 0; i < 2000; ++i) f << i % 50 << ' ' << i / 50 << " 0 " << i * 0.5 << '\n';
  }
  const std::string bin = RAYSCAN_BIN;
  for (const std::string attr : {"rowid", "ROWID", "oid", "_rowid_", "ctid", "xmin", "tableoid"}) {
    EXPECT_EQ(run(bin + " db import " + ply.string() + " -o " + out.string() + " --attributes " + attr + " 2> " +
                  err.string()), 2) << attr;
    const std::string e = slurp(err);
    EXPECT_NE(e.find("attribute '" + attr + "': '"), std::string::npos) << e;
    EXPECT_NE(e.find("reserved column names: rowid, oid, _rowid_, tableoid, xmin, cmin, xmax, cmax, ctid"),
              std::string::npos) << e;
    EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
    EXPECT_FALSE(fs::exists(out));
  }
  // The same values under a free name are stored whole.
  {
    std::ifstream in(ply);
    std::string text((std::istreambuf_iterator<char>(in)), {});
    text.replace(text.find("property float rowid"), 20, "property float row_value");
    std::ofstream(ply) << text;
  }
  ASSERT_EQ(run(bin + " db import " + ply.string() + " -o " + out.string() + " --attributes row_value > /dev/null"), 0);
  Db db(out, false);
  Stmt st(db.db, "SELECT count(DISTINCT row_value), sum(row_value = point_index * 0.5) FROM points");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.i64(0), 2000);
  EXPECT_EQ(st.i64(1), 2000);
  ASSERT_EQ(sqlite3_exec(db.db, "CREATE TEMP TABLE plain(a)", nullptr, nullptr, nullptr), SQLITE_OK);
  for (const char* name : {"rowid", "oid", "_rowid_"}) {
    EXPECT_EQ(error_of(db.db, std::string("SELECT ") + name + " FROM plain"), "") << name;
    EXPECT_NE(sql::reserved_sql_name(name, true), "") << name;
    EXPECT_EQ(sql::reserved_sql_name(name, false), "") << name;  // a table may be so named
  }
  EXPECT_NE(error_of(db.db, "SELECT row_value FROM plain"), "");  // (the oracle can say no)
}


// A database error is one line naming the import's step and SQLite's own message, never the SQL
// text: the output file may grow to no more than 200 blocks (ulimit -f, SIGXFSZ ignored so that
// the write fails with EFBIG instead of killing the process), so writing the database fails. The
// oracle of the message's end is SQLite's text of the codes a failed write gives (sqlite3_errstr);
// the index file is imported as it is (no sort, whose runs the limit would stop first).
TEST(SqliteImportCli, DatabaseErrorsNameTheStepNotTheSql) {
  const std::string bin = RAYSCAN_BIN;
  const fs::path dir = tmpdir() / "full", rsi = dir / "a.rsi", out = dir / "full.sqlite";
  fs::create_directories(dir);
  ASSERT_EQ(run(bin + " index " + scan_path("autzen").string() + " -o " + rsi.string() + " --attributes id -q > /dev/null"), 0);
  const auto r = rayscan::test::run_command("ulimit -f 200 && trap '' XFSZ && " + bin + " db import " + rsi.string() +
                                            " -o " + out.string() + " -q");
  EXPECT_EQ(r.code, 2) << r.out;
  const std::regex line("rayscan db: " + out.string() +
                        ": sqlite: (insert into (points|chunks|chunk_points)|create index points_source_index|commit): (.*)\n");
  std::smatch m;
  ASSERT_TRUE(std::regex_match(r.out, m, line)) << r.out;
  EXPECT_TRUE(m[3] == sqlite3_errstr(SQLITE_IOERR) || m[3] == sqlite3_errstr(SQLITE_FULL)) << r.out;
  for (const char* keyword : {"INSERT", "CREATE", "COMMIT", "VALUES", "PRAGMA"})
    EXPECT_EQ(r.out.find(keyword), std::string::npos) << r.out;
  // Nothing is left but the index file: no database, no temporary file.
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path(), rsi);
}

}  // namespace
}  // namespace rayscan::sqltest
