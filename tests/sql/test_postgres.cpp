// PostgreSQL side of the SQL extensions: CREATE EXTENSION rayscan on a private server that CTest starts
// (pg_server.sh: initdb in a temporary directory, Unix socket only, unprivileged user) and stops.
// Checked against the core (bit for bit), the brute-force oracle and the SQLite extension's rules.
#include "sql_test_util.hpp"

#include "rayscan/octree/distance.hpp"
#include "rayscan/sql/functions.h"
#include "rayscan/sql/import.hpp"

#include <libpq-fe.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <set>

#include <unistd.h>

namespace rayscan::sqltest {
namespace {

std::string server_dir() {
  std::ifstream f(RAYSCAN_PG_STATE);
  std::string d;
  std::getline(f, d);
  return d;
}

std::string conninfo(const std::string& dbname = "postgres") {
  return "host=" + server_dir() + " port=5432 user=postgres dbname=" + dbname;
}

struct Pg {
  PGconn* c = nullptr;
  explicit Pg(const std::string& dbname = "postgres") {
    c = PQconnectdb(conninfo(dbname).c_str());
    EXPECT_EQ(PQstatus(c), CONNECTION_OK) << PQerrorMessage(c);
    PQsetNoticeProcessor(c, [](void*, const char*) {}, nullptr);
  }
  ~Pg() { PQfinish(c); }
  /// Rows of a query as text cells; fails the test on an error.
  std::vector<std::vector<std::string>> rows(const std::string& sql) {
    PGresult* r = PQexec(c, sql.c_str());
    std::vector<std::vector<std::string>> out;
    const auto st = PQresultStatus(r);
    EXPECT_TRUE(st == PGRES_TUPLES_OK || st == PGRES_COMMAND_OK) << sql << ": " << PQerrorMessage(c);
    for (int i = 0; i < PQntuples(r); ++i) {
      out.emplace_back();
      for (int j = 0; j < PQnfields(r); ++j)
        out.back().push_back(PQgetisnull(r, i, j) ? "NULL" : PQgetvalue(r, i, j));
    }
    PQclear(r);
    return out;
  }
  /// The primary error message of `sql` ("" when it succeeds).
  std::string error_of(const std::string& sql) {
    PGresult* r = PQexec(c, sql.c_str());
    std::string m;
    if (PQresultStatus(r) == PGRES_FATAL_ERROR) {
      const char* p = PQresultErrorField(r, PG_DIAG_MESSAGE_PRIMARY);
      m = p ? p : "?";
    }
    PQclear(r);
    return m;
  }
  /// The SQLSTATE of the error of `sql` ("" when it succeeds).
  std::string sqlstate_of(const std::string& sql) {
    PGresult* r = PQexec(c, sql.c_str());
    std::string m;
    if (PQresultStatus(r) == PGRES_FATAL_ERROR) {
      const char* p = PQresultErrorField(r, PG_DIAG_SQLSTATE);
      m = p ? p : "?";
    }
    PQclear(r);
    return m;
  }
};

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return std::string("'") + b + "'::float8";
}
std::string vec(const Vec3& v) { return num(v.x) + "," + num(v.y) + "," + num(v.z); }
double dbl(const std::string& s) { return std::strtod(s.c_str(), nullptr); }
// The planner's rows of the top node of the plan of sql (EXPLAIN), -1 when it shows none.
double planned_rows(Pg& pg, const std::string& sql) {
  const auto plan = pg.rows("EXPLAIN " + sql);
  const auto at = plan.at(0).at(0).find(" rows=");
  return at == std::string::npos ? -1.0 : std::stod(plan[0][0].substr(at + 6));
}
// ray_dwithin's brute-force oracle: the number of points within r of the ray (o, d).
double points_within(const PointCloud& cloud, const Vec3& o, const Vec3& d, double r) {
  double n = 0;
  for (const Vec3& p : cloud.positions) n += dist_ray(o, d, p) <= r;
  return n;
}

class Postgres : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (server_dir().empty()) return;
    cloud_ = new PointCloud(io::read_point_cloud(scan_path("autzen"), io::ReadOptions{.scalars = false}));
    Pg pg;
    pg.rows("DROP TABLE IF EXISTS autzen, autzen_chunks, autzen_sources");
    imported_ = run(std::string(RAYSCAN_BIN) + " db import '" + scan_path("autzen").string() +
                    "' --postgres '" + conninfo() + "' --table autzen --chunk 512 > /dev/null") == 0;
  }
  static void TearDownTestSuite() {
    delete cloud_;
    cloud_ = nullptr;
  }
  void SetUp() override {
    if (server_dir().empty()) GTEST_SKIP() << "no test server (pg_server.sh could not start PostgreSQL 15)";
    ASSERT_TRUE(imported_);
  }
  static inline PointCloud* cloud_ = nullptr;
  static inline bool imported_ = false;
};

TEST_F(Postgres, ExtensionFunctionsAreImmutableParallelSafeStrict) {
  Pg pg;
  const auto r = pg.rows("SELECT proname, provolatile, proparallel, proisstrict FROM pg_proc WHERE proname IN "
                         "('dist_ray','ray_time','dist_plane','dist_ray_min','dist_ray_max','ray_time_min',"
                         "'ray_time_max','dist_plane_min','dist_plane_max') ORDER BY 1");
  ASSERT_EQ(r.size(), 9u);
  for (const auto& row : r) {
    EXPECT_EQ(row[1], "i") << row[0];
    EXPECT_EQ(row[2], "s") << row[0];
    EXPECT_EQ(row[3], "t") << row[0];
  }
}

TEST_F(Postgres, ImportKeepsExactDoublesAndChunkBoxes) {
  Pg pg;
  const auto r = pg.rows("SELECT point_index, x, y, z FROM autzen WHERE point_index % 101 = 0");
  ASSERT_EQ(r.size(), (cloud_->size() + 100) / 101);
  for (const auto& row : r) {
    const Vec3& p = cloud_->positions[std::stoull(row[0])];
    ASSERT_EQ(Vec3(dbl(row[1]), dbl(row[2]), dbl(row[3])), p);
  }
  // Every point lies in its chunk's box (boxes are exact doubles: no rounding).
  const auto bad = pg.rows("SELECT count(*) FROM autzen p JOIN autzen_chunks c USING (chunk) "
                           "WHERE NOT (rs_box(p.x,p.y,p.z,p.x,p.y,p.z) && ray_within(p.x,p.y,p.z,1,0,0,0)) "
                           "OR NOT (c.box && ray_within(p.x,p.y,p.z,1,0,0,0))");
  EXPECT_EQ(bad[0][0], "0");
  EXPECT_EQ(pg.rows("SELECT count(*) FROM autzen")[0][0], std::to_string(cloud_->size()));
  // The planner statistic of the chunk column is the exact number of distinct chunks (counted here).
  const auto nd = pg.rows("SELECT (SELECT attoptions::text FROM pg_attribute WHERE attrelid = 'autzen'::regclass "
                          "AND attname = 'chunk'), -count(DISTINCT chunk)::float8 / count(*) FROM autzen");
  ASSERT_EQ(nd.size(), 1u);
  const auto eq = nd[0][0].find("n_distinct=");
  ASSERT_NE(eq, std::string::npos) << nd[0][0];
  EXPECT_EQ(dbl(nd[0][0].substr(eq + 11)), dbl(nd[0][1])) << nd[0][0];
}

TEST_F(Postgres, FunctionsEqualTheCoreBitForBit) {
  Pg pg;
  const auto rays = query_rays(*cloud_, 4, 11);
  for (const Ray& ray : rays) {
    const Vec3 o = ray.origin(), d = ray.direction() * 3.0;
    const auto r = pg.rows("SELECT point_index, dist_ray(" + vec(o) + "," + vec(d) + ",x,y,z), ray_time(" + vec(o) + "," +
                           vec(d) + ",x,y,z), dist_plane(" + vec(o) + "," + vec(d) + ",x,y,z) FROM autzen WHERE point_index % 211 = 0");
    ASSERT_FALSE(r.empty());
    for (const auto& row : r) {
      const Vec3& p = cloud_->positions[std::stoull(row[0])];
      ASSERT_EQ(dbl(row[1]), dist_ray(o, d, p));
      ASSERT_EQ(dbl(row[2]), ray_point_terms(o, Ray(o, d).direction(), p).t);
      ASSERT_EQ(dbl(row[3]), dist_plane(o, d, p));
    }
    const AABB box = cloud_->bounds();
    const std::string b = vec(box.lo) + "," + vec(box.hi);
    const auto bb = pg.rows("SELECT dist_ray_min(" + vec(o) + "," + vec(d) + "," + b + "), dist_ray_max(" + vec(o) + "," +
                            vec(d) + "," + b + "), dist_plane_min(" + vec(o) + "," + vec(d) + "," + b + ")");
    // (the core's exact bounds widened by the node test's rounding allowance, as in SQLite)
    const double tol = node_test_tolerance(o, box);
    EXPECT_EQ(dbl(bb[0][0]), std::max(0.0, dist_ray_bounds(o, d, box).lo - tol));
    EXPECT_EQ(dbl(bb[0][1]), dist_ray_bounds(o, d, box).hi + tol);
    EXPECT_EQ(dbl(bb[0][2]), dist_plane_bounds(o, d, box).lo - tol);
  }
}

TEST_F(Postgres, NullInNullOutAndTheSameErrorsAsSqlite) {
  Pg pg;
  const auto n = pg.rows("SELECT dist_ray(NULL,0,0,1,0,0,1,1,1) IS NULL, dist_plane_max(0,0,0,0,0,1,0,0,0,1,1,NULL) IS NULL");
  EXPECT_EQ(n[0][0], "t");
  EXPECT_EQ(n[0][1], "t");
  EXPECT_EQ(pg.error_of("SELECT dist_ray(0,0,0, 0,0,0, 1,2,3)"),
            "dist_ray: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT dist_plane(0,0,0, 0,0,0, 1,2,3)"),
            "dist_plane: normal (nx,ny,nz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT dist_ray(0,0,0, 1,0,0, 'infinity',2,3)"),
            "dist_ray: argument 7 (x) is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT dist_ray(0,0,0, 1,0,0, 'NaN',2,3)"),
            "dist_ray: argument 7 (x) is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT dist_ray_min(0,0,0, 1,0,0, 2,0,0, 1,1,1)"),
            "dist_ray_min: box xmin > xmax; expected min <= max on every axis");
  EXPECT_NE(pg.error_of("SELECT dist_ray(0,0,0, 1,0,0, 1,2)"), "");      // no such function
  EXPECT_NE(pg.error_of("SELECT dist_ray(0,0,0, 1,0,0, 'a',2,3)"), "");  // invalid float8
  EXPECT_EQ(pg.error_of("SELECT ray_within(0,0,0, 1,0,0, -1)"),
            "ray_within: radius r is negative; expected a number >= 0 (NULL: unbounded)");
  EXPECT_EQ(pg.error_of("SELECT '(1,2,3)'::rs_box").rfind("invalid input syntax for type rs_box", 0), 0u);
}

// The pruned form of the paper's query uses the GiST index on chunk boxes (consistent = bounds
// evaluation) and returns exactly the brute-force set; radius and time slab.
TEST_F(Postgres, GistPrunedRadiusAndTimeSlabEqualBruteForce) {
  Pg pg;
  pg.rows("SET enable_seqscan = off");
  const double r = 2.0 * spacing(*cloud_);
  for (const Ray& ray : query_rays(*cloud_, 6, 7)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const double tc = glm::length(cloud_->bounds().center() - o);
    for (int slab = 0; slab < 2; ++slab) {
      const double t0 = slab ? tc - 100 : -kInf, t1 = slab ? tc + 100 : kInf;
      const std::string pred = slab ? "ray_within(" + vec(o) + "," + vec(d) + "," + num(r) + "," + num(t0) + "," + num(t1) + ")"
                                    : "ray_within(" + vec(o) + "," + vec(d) + "," + num(r) + ")";
      const std::string sql =
          "SELECT p.point_index FROM autzen_chunks c JOIN autzen p ON p.chunk = c.chunk WHERE c.box && " + pred +
          " AND dist_ray(" + vec(o) + "," + vec(d) + ",p.x,p.y,p.z) <= " + num(r) +
          (slab ? " AND ray_time(" + vec(o) + "," + vec(d) + ",p.x,p.y,p.z) BETWEEN " + num(t0) + " AND " + num(t1) : "");
      std::set<std::size_t> got, want;
      for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
      RayQuery q;
      q.radius = r;
      q.t_min = t0;
      q.t_max = t1;
      for (const RayHit& h : ray_query(BruteForceIndex(*cloud_), ray, q)) want.insert(h.index);
      EXPECT_EQ(got, want);
      if (!slab) { EXPECT_FALSE(want.empty()); }
      std::string plan;
      for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
      EXPECT_NE(plan.find("autzen_chunks_box"), std::string::npos) << plan;
    }
  }
}

// ORDER BY box <-> ray LIMIT k runs as an index-ordered kNN scan over chunks (GiST distance =
// lower bound of dist_ray); nearest-chunk-first plus the exact point kNN equals the brute force.
TEST_F(Postgres, IndexOrderedKnnEqualsBruteForce) {
  Pg pg;
  pg.rows("SET enable_seqscan = off");
  const double r = 3.0 * spacing(*cloud_);
  for (const Ray& ray : query_rays(*cloud_, 6, 3)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const std::string rw = "ray_within(" + vec(o) + "," + vec(d) + ", NULL)";
    const std::string knn_chunks = "SELECT chunk, box <-> " + rw + " FROM autzen_chunks ORDER BY box <-> " + rw + " LIMIT 5";
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + knn_chunks)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("Index Scan using autzen_chunks_box"), std::string::npos) << plan;
    EXPECT_NE(plan.find("Order By"), std::string::npos) << plan;
    // The 5 chunks come out in increasing lower bound, equal to sorting every chunk's bound.
    const auto got = pg.rows(knn_chunks);
    const auto all = pg.rows("SELECT box <-> " + rw + " FROM autzen_chunks");
    std::vector<double> bounds;
    for (const auto& row : all) bounds.push_back(dbl(row[0]));
    std::sort(bounds.begin(), bounds.end());
    ASSERT_EQ(got.size(), 5u);
    for (int i = 0; i < 5; ++i) EXPECT_EQ(dbl(got[i][1]), bounds[i]);
    // kNN of points to the ray within r, through the index, equals the core on the brute force.
    const std::string kq =
        "SELECT p.point_index, dist_ray(" + vec(o) + "," + vec(d) + ",p.x,p.y,p.z) AS dist FROM autzen_chunks c "
        "JOIN autzen p ON p.chunk = c.chunk WHERE c.box && ray_within(" + vec(o) + "," + vec(d) + "," + num(r) +
        ") AND dist_ray(" + vec(o) + "," + vec(d) + ",p.x,p.y,p.z) <= " + num(r) + " ORDER BY 2, 1 LIMIT 7";
    RayQuery q;
    q.k = 7;
    q.radius = r;
    const auto want = ray_query(BruteForceIndex(*cloud_), ray, q);
    const auto rows = pg.rows(kq);
    ASSERT_EQ(rows.size(), want.size());
    for (std::size_t i = 0; i < rows.size(); ++i) EXPECT_EQ(std::stoull(rows[i][0]), want[i].index) << i;
  }
}

// No hand-written bounds clause: ray_dwithin(rs_box(x,y,z), o, d, r) on the points table alone.
// Its planner support function (SupportRequestIndexCondition) derives the GiST condition
// rs_box(x,y,z) && ray_dwithin_ray(o, d, r) on the points' rs_box_ops index (bounds evaluation on every
// GiST page box); the plan must show that Index Cond, and the rows equal the brute force. The same
// function on the chunk table prunes chunks exactly as dist_ray_min <= r.
TEST_F(Postgres, RayDwithinSupportFunctionUsesTheGistIndex) {
  Pg pg;
  pg.rows("CREATE INDEX IF NOT EXISTS autzen_pt ON autzen USING gist (rs_box(x, y, z))");
  pg.rows("ANALYZE autzen");
  const double r = 2.0 * spacing(*cloud_);
  for (const Ray& ray : query_rays(*cloud_, 4, 5)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const std::string od = vec(o) + "," + vec(d);
    const std::string sql = "SELECT point_index FROM autzen WHERE ray_dwithin(rs_box(x, y, z), " + od + "," + num(r) + ")";
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("autzen_pt"), std::string::npos) << plan;
    EXPECT_NE(plan.find("ray_dwithin_ray("), std::string::npos) << plan;  // the derived Index Cond
    std::set<std::size_t> got, want;
    for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
    for (std::size_t i = 0; i < cloud_->size(); ++i)
      if (dist_ray(o, d, cloud_->positions[i]) <= r) want.insert(i);
    EXPECT_EQ(got, want) << sql << "\n" << plan;
    EXPECT_FALSE(want.empty());
    // Chunk table: index-pruned chunks equal the chunks whose dist_ray_min <= r (sequential scan).
    const std::string cq = "SELECT chunk FROM autzen_chunks WHERE ray_dwithin(box, " + od + "," + num(r) + ") ORDER BY 1";
    plan.clear();
    pg.rows("SET enable_seqscan = off");
    for (const auto& row : pg.rows("EXPLAIN " + cq)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("autzen_chunks_box"), std::string::npos) << plan;
    std::vector<std::string> chunks, oracle;
    for (const auto& row : pg.rows(cq)) chunks.push_back(row[0]);
    pg.rows("RESET enable_seqscan");
    // Oracles: every chunk holding a point within r of the ray (brute force over the cloud) is
    // kept, and none whose exact bounds (the core's dist_ray_bounds, in C++) lie beyond r by more
    // than the rounding allowance.
    std::set<std::string> holding;
    for (const auto& row : pg.rows("SELECT point_index, chunk FROM autzen"))
      if (dist_ray(o, d, cloud_->positions[std::stoull(row[0])]) <= r) holding.insert(row[1]);
    for (const auto& row : pg.rows("SELECT chunk, box FROM autzen_chunks ORDER BY 1")) {
      double v[6];
      ASSERT_EQ(std::sscanf(row[1].c_str(), "(%lf,%lf,%lf,%lf,%lf,%lf)", v, v + 1, v + 2, v + 3, v + 4, v + 5), 6);
      const AABB b{Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5])};
      if (dist_ray_bounds(o, d, b).lo <= r + node_test_tolerance(o, b)) oracle.push_back(row[0]);
    }
    const std::set<std::string> kept(chunks.begin(), chunks.end());
    for (const std::string& c : holding) EXPECT_TRUE(kept.count(c)) << "chunk " << c << " holds a point within r";
    for (const std::string& c : chunks) EXPECT_NE(std::find(oracle.begin(), oracle.end(), c), oracle.end()) << c;
    EXPECT_FALSE(chunks.empty());
  }
  // The radius at the boundary: r = the distance of a chunk's nearest point keeps that chunk
  // (ray_dwithin on its box), which bounds rounded as the exact ones would not guarantee. The
  // first ray is one where the exact bounds exceed that distance (chunk 166 of autzen at chunk
  // size 512).
  std::vector<Ray> boundary_rays = query_rays(*cloud_, 3, 11);
  boundary_rays.insert(boundary_rays.begin(), Ray(Vec3(636671.1536259624, 849606.67960656, 600),
                                                  Vec3(0.22834017597878464, -0.015290736389950065, -1)));
  for (const Ray& ray : boundary_rays) {
    const std::string od = vec(ray.origin()) + "," + vec(ray.direction());
    const auto dropped = pg.rows("WITH m AS (SELECT chunk, min(dist_ray(" + od + ", x, y, z)) AS r FROM autzen GROUP BY chunk) "
                                 "SELECT count(*), sum((NOT ray_dwithin(c.box, " + od + ", m.r))::int) "
                                 "FROM m JOIN autzen_chunks c USING (chunk)");
    EXPECT_GT(std::stoll(dropped[0][0]), 100);
    EXPECT_EQ(dropped[0][1], "0") << od;
  }
  // Index-ordered kNN of points: ORDER BY rs_box(x,y,z) <-> ray LIMIT k walks the points' GiST
  // index by the bounds lower bound (for a point: its dist_ray); the rows equal the brute-force kNN.
  for (const Ray& ray : query_rays(*cloud_, 3, 8)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const std::string sql = "SELECT point_index FROM autzen ORDER BY rs_box(x, y, z) <-> ray_within(" + vec(o) + "," +
                            vec(d) + ", NULL) LIMIT 7";
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("Index Scan using autzen_pt"), std::string::npos) << plan;
    EXPECT_NE(plan.find("Order By"), std::string::npos) << plan;
    RayQuery q;
    q.k = 7;
    std::set<std::size_t> got, want;
    for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
    for (const RayHit& h : ray_query(BruteForceIndex(*cloud_), ray, q)) want.insert(h.index);
    EXPECT_EQ(got, want);
  }
  // A ray from a column of the same table cannot become an index condition: still correct.
  EXPECT_EQ(pg.rows("SELECT count(*) FROM autzen WHERE ray_dwithin(rs_box(x, y, z), x, y, z, 1, 0, 0, 0)")[0][0],
            std::to_string(cloud_->size()));
}

// ray_dwithin's row estimate comes from the sample of boxes ANALYZE keeps (rs_box_analyze), not a
// constant (0.005 of the rows, 550 points or 1 chunk of autzen for every ray): on the points'
// rs_box(x, y, z) index, within 5 standard deviations of the brute-force count for rays that keep
// about 3% and 25% of the points; on the chunk boxes (every chunk sampled) and, with a statistics
// target that samples every point, on the points, the count itself.
TEST_F(Postgres, RayDwithinRowEstimateComesFromTheBoxSample) {
  Pg pg;
  pg.rows("CREATE INDEX IF NOT EXISTS autzen_pt ON autzen USING gist (rs_box(x, y, z))");
  pg.rows("ANALYZE autzen");
  pg.rows("ANALYZE autzen_chunks");
  auto estimate = [&pg](const std::string& sql) { return planned_rows(pg, sql); };
  const Vec3 o(636500, 849200, 600), d(0, 0, -1);  // vertical, through the middle of autzen
  const std::string od = vec(o) + "," + vec(d);
  auto within = [&](double r) { return points_within(*cloud_, o, d, r); };
  auto points_sql = [&](double r) { return "SELECT point_index FROM autzen WHERE ray_dwithin(rs_box(x, y, z), " + od + "," + num(r) + ")"; };
  // At the default target the estimate is the share of a random sample of 30 boxes per unit of
  // the target (RS_BOX_SAMPLE_PER_TARGET), a binomial draw: a bound of 5 of its standard
  // deviations fails about one run in 2 million, where 1.5x of the count was 3 of them at 60 ft
  // (one run in 1,000); the constant's 550 rows lies about 8 and 32 of them away.
  const double n = double(cloud_->size());
  const double sample = 30 * std::stod(pg.rows("SHOW default_statistics_target").at(0).at(0));
  for (const double r : {60.0, 200.0}) {
    const double want = within(r), got = estimate(points_sql(r));
    EXPECT_GT(want, 0.02 * n) << r;
    const double sigma = n * std::sqrt(want / n * (1 - want / n) / sample);
    EXPECT_LT(std::abs(got - want), 5 * sigma) << "r " << r << ": estimated " << got << ", " << want << " points";
    const std::string chunks = "SELECT chunk FROM autzen_chunks WHERE ray_dwithin(box, " + od + "," + num(r) + ")";
    const double kept = double(pg.rows(chunks).size());
    EXPECT_GT(kept, 10) << r;
    EXPECT_EQ(estimate(chunks), kept) << chunks;
  }
  pg.rows("ALTER INDEX autzen_pt ALTER COLUMN 1 SET STATISTICS 10000");  // a sample of 3e6 rows: all
  pg.rows("ANALYZE autzen");
  EXPECT_GT(within(5), 10);
  for (const double r : {5.0, 60.0, 200.0}) EXPECT_EQ(estimate(points_sql(r)), within(r)) << r;
  // A ray whose distance to every point overflows: ray_dwithin refuses each point (rs_eval's
  // error), so the estimate counts none, even within an infinite radius (the planner's 1 row).
  const double far[6] = {1e200, 0, 0, 0, 0, 1};
  std::size_t accepted = 0;
  for (const Vec3& p : cloud_->positions) {
    double a[9] = {far[0], far[1], far[2], far[3], far[4], far[5], p.x, p.y, p.z}, v = 0;
    rs_error_kind kind;
    char err[RS_ERRBUF];
    accepted += rs_eval("ray_dwithin", RS_DIST_RAY, a, &v, &kind, err) == nullptr;
  }
  EXPECT_EQ(accepted, 0u);
  EXPECT_EQ(estimate("SELECT point_index FROM autzen WHERE ray_dwithin(rs_box(x, y, z), 1e200, 0, 0, 0, 0, 1, "
                     "'Infinity')"),
            1.0);
  pg.rows("ALTER INDEX autzen_pt ALTER COLUMN 1 SET STATISTICS -1");
  pg.rows("ANALYZE autzen");
  // Nothing to estimate from (a ray known only when the query runs): the constant.
  EXPECT_EQ(estimate("SELECT point_index FROM autzen WHERE ray_dwithin(rs_box(x, y, z), " + od + ", random())"),
            std::round(0.005 * double(cloud_->size())));
}

// CREATE STATISTICS on the expression rs_box(x, y, z) keeps the same sample without an index
// (docs/sql.md): with a target that samples every point, the estimate is the brute-force count.
TEST_F(Postgres, RayDwithinRowEstimateFromStatisticsWithoutAnIndex) {
  Pg pg;
  pg.rows("DROP TABLE IF EXISTS autzen_unindexed");
  pg.rows("CREATE TABLE autzen_unindexed AS SELECT x, y, z FROM autzen");
  pg.rows("CREATE STATISTICS autzen_unindexed_box ON (rs_box(x, y, z)) FROM autzen_unindexed");
  pg.rows("ALTER STATISTICS autzen_unindexed_box SET STATISTICS 10000");
  pg.rows("ANALYZE autzen_unindexed");
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_indexes WHERE tablename = 'autzen_unindexed'")[0][0], "0");
  const Vec3 o(636500, 849200, 600), d(0, 0, -1);
  for (const double r : {5.0, 60.0}) {
    const double want = points_within(*cloud_, o, d, r);
    EXPECT_GT(want, 10) << r;
    EXPECT_EQ(planned_rows(pg, "SELECT x FROM autzen_unindexed WHERE ray_dwithin(rs_box(x, y, z), " + vec(o) +
                                   "," + vec(d) + "," + num(r) + ")"),
              want)
        << r;
  }
  pg.rows("DROP TABLE autzen_unindexed");
}

// A frustum (four half-spaces around a ray): box && plane_below(...) on the chunk GiST index plus
// dist_plane <= 0 per point equals the brute-force set (as in SQLite).
TEST_F(Postgres, FrustumWithPlanePruningEqualsBruteForce) {
  Pg pg;
  pg.rows("SET enable_seqscan = off");
  for (const Ray& ray : query_rays(*cloud_, 3, 9)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const Vec3 a = glm::normalize(glm::cross(d, std::abs(d.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0)));
    const Vec3 b = glm::cross(d, a);
    const double w = 10 * spacing(*cloud_);
    const std::vector<Plane> planes = {{o + w * a, a}, {o - w * a, -a}, {o + w * b, b}, {o - w * b, -b}};
    std::string sql = "SELECT p.point_index FROM autzen_chunks c JOIN autzen p ON p.chunk = c.chunk WHERE ";
    for (std::size_t i = 0; i < planes.size(); ++i) {
      const std::string pl = vec(planes[i].point) + "," + vec(planes[i].normal);
      sql += std::string(i ? " AND " : "") + "c.box && plane_below(" + pl + ") AND dist_plane(" + pl + ", p.x, p.y, p.z) <= 0";
    }
    std::set<std::size_t> got, want;
    for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
    for (std::size_t i = 0; i < cloud_->size(); ++i) {
      bool in = true;
      for (const Plane& pl : planes) in = in && dist_plane(pl.point, pl.normal, cloud_->positions[i]) <= 0;
      if (in) want.insert(i);
    }
    EXPECT_EQ(got, want);
    EXPECT_FALSE(want.empty());
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("autzen_chunks_box"), std::string::npos) << plan;
  }
  EXPECT_EQ(pg.error_of("SELECT plane_below(0,0,0, 0,0,0)"),
            "plane_below: normal (nx,ny,nz) is zero; expected a non-zero vector");
}

// pgpointcloud: `db import --pcpatch` writes one pcpatch per chunk (double X/Y/Z schema in
// pointcloud_formats) with its rs_box; pgpointcloud's own PC_Explode / PC_Get read back the
// reader's exact doubles and point indices, every box is exactly its patch's min/max, and the
// paper's radius query over patches (ray_dwithin on the box GiST index, then dist_ray on the
// exploded points) equals the brute force.
TEST_F(Postgres, PcpatchImportAndPrunedRadiusQueryEqualBruteForce) {
  Pg pg;
  if (pg.rows("SELECT count(*) FROM pg_available_extensions WHERE name = 'pointcloud'")[0][0] == "0")
    GTEST_SKIP() << "pgpointcloud (postgresql-15-pointcloud) not installed";
  pg.rows("DROP TABLE IF EXISTS autzen_pc, autzen_pc_sources");
  ASSERT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + scan_path("autzen").string() + "' --postgres '" + conninfo() +
                "' --table autzen_pc --chunk 512 --pcpatch > /dev/null"), 0);
  const auto n = pg.rows("SELECT count(*), sum(PC_NumPoints(pa)) FROM autzen_pc");
  EXPECT_EQ(n[0][0], std::to_string((cloud_->size() + 511) / 512));
  EXPECT_EQ(n[0][1], std::to_string(cloud_->size()));
  // Exact doubles and indices through pgpointcloud's own accessors.
  const auto pts = pg.rows("SELECT (PC_Get(pt))[4]::bigint, (PC_Get(pt))[1], (PC_Get(pt))[2], (PC_Get(pt))[3] "
                           "FROM autzen_pc, PC_Explode(pa) pt WHERE chunk % 9 = 0");
  ASSERT_GT(pts.size(), 1000u);
  for (const auto& row : pts)
    ASSERT_EQ(Vec3(dbl(row[1]), dbl(row[2]), dbl(row[3])), cloud_->positions[std::stoull(row[0])]);
  // Each box is exactly the min/max of its patch's points.
  const auto bad = pg.rows("SELECT count(*) FROM autzen_pc c WHERE c.chunk % 4 = 0 AND c.box::text <> (SELECT rs_box(min((PC_Get(pt))[1]), "
                           "min((PC_Get(pt))[2]), min((PC_Get(pt))[3]), max((PC_Get(pt))[1]), max((PC_Get(pt))[2]), "
                           "max((PC_Get(pt))[3]))::text FROM PC_Explode(c.pa) pt)");
  EXPECT_EQ(bad[0][0], "0");
  pg.rows("SET enable_seqscan = off");
  const double r = 2.0 * spacing(*cloud_);
  for (const Ray& ray : query_rays(*cloud_, 4, 13)) {
    const Vec3 o = ray.origin(), d = ray.direction();
    const std::string od = vec(o) + "," + vec(d);
    const std::string sql = "SELECT (PC_Get(pt))[4]::bigint FROM autzen_pc, PC_Explode(pa) pt WHERE ray_dwithin(box, " + od +
                            "," + num(r) + ") AND dist_ray(" + od + ", (PC_Get(pt))[1], (PC_Get(pt))[2], (PC_Get(pt))[3]) <= " +
                            num(r);
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
    EXPECT_NE(plan.find("autzen_pc_box"), std::string::npos) << plan;
    std::set<std::size_t> got, want;
    for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
    for (std::size_t i = 0; i < cloud_->size(); ++i)
      if (dist_ray(o, d, cloud_->positions[i]) <= r) want.insert(i);
    EXPECT_EQ(got, want);
    EXPECT_FALSE(want.empty());
  }
  EXPECT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + scan_path("autzen").string() + "' -o /tmp/x.sqlite --pcpatch 2>/dev/null"), 2);
}

// The functions were loaded from the build tree (tests/sql/pg_server.sh, rayscan_build_tree.sql),
// not from an extension installed into the system's PostgreSQL directories.
TEST_F(Postgres, FunctionsComeFromTheBuildTreeNotASystemInstall) {
  Pg pg;
  const auto r = pg.rows("SELECT DISTINCT probin FROM pg_proc WHERE proname IN ('dist_ray', 'ray_within', 'rs_box_in')");
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0][0], RAYSCAN_PG_MODULE);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_extension WHERE extname = 'rayscan'")[0][0], "0");
}

// The same checks on the other real scans: lone-star (terrestrial, 0.5 M points, y ~ 4.9e6 at a
// 0.25 mm scale; from ../shared) and the PDRF 8 file append-bug (bundled as LAZ). Radius, time slab,
// kNN to the ray, kNN along the ray and a frustum through the chunk GiST index equal the core's ray
// query over the brute-force oracle (same point sets; same order for kNN).
class PostgresScan : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (server_dir().empty()) GTEST_SKIP() << "no test server (pg_server.sh could not start PostgreSQL 15)";
    path_ = scan_path(GetParam());
    if (path_.empty()) GTEST_SKIP() << GetParam() << ": ../shared/data absent";
    cloud_ = io::read_point_cloud(path_, io::ReadOptions{.scalars = false});
    table_ = GetParam();
    Pg pg;
    // One import per server (the server lives for one ctest run, the binary does not change in it).
    if (pg.rows("SELECT to_regclass('" + table_ + "_chunks') IS NULL")[0][0] == "t") {
      ASSERT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + path_.string() + "' --postgres '" + conninfo() +
                    "' --table " + table_ + " --chunk 512 > /dev/null"), 0);
    }
  }
  fs::path path_;
  PointCloud cloud_;
  std::string table_;
};

TEST_P(PostgresScan, ImportAndQueriesEqualBruteForce) {
  Pg pg;
  const auto& pos = cloud_.positions;
  ASSERT_EQ(pg.rows("SELECT count(*) FROM " + table_)[0][0], std::to_string(cloud_.size()));
  for (const auto& row : pg.rows("SELECT point_index, x, y, z FROM " + table_ + " WHERE point_index % 97 = 0"))
    ASSERT_EQ(Vec3(dbl(row[1]), dbl(row[2]), dbl(row[3])), pos[std::stoull(row[0])]);
  pg.rows("SET enable_seqscan = off");
  const BruteForceIndex brute(cloud_);
  const double r = 2.0 * spacing(cloud_);
  const std::string from = " FROM " + table_ + "_chunks c JOIN " + table_ + " p ON p.chunk = c.chunk WHERE ";
  int nonempty = 0;
  for (const Ray& q_ray : query_rays(cloud_, 4, 21)) {
    // The oracle's ray is built from the same direction values the SQL receives.
    const Vec3 o = q_ray.origin(), d = q_ray.direction();
    const Ray ray(o, d);
    const std::string od = vec(o) + "," + vec(d);
    const std::string dr = "dist_ray(" + od + ",p.x,p.y,p.z)", rt = "ray_time(" + od + ",p.x,p.y,p.z)";
    const double tc = glm::length(cloud_.bounds().center() - o);
    struct Case { const char* name; std::size_t k; double r, t0, t1; RayOrder order; };
    const Case cases[] = {
        {"radius", kAllPoints, r, -kInf, kInf, RayOrder::ray},
        {"time slab", kAllPoints, 4 * r, tc - 20 * r, tc + 20 * r, RayOrder::time},
        {"kNN to the ray within 3r", 7, 3 * r, -kInf, kInf, RayOrder::ray},
        {"kNN along the ray within r", 6, r, -kInf, kInf, RayOrder::time},
    };
    for (const Case& c : cases) {
      const bool slab = std::isfinite(c.t0);
      std::string sql = "SELECT p.point_index" + from + "c.box && ray_within(" + od + "," + num(c.r) +
                        (slab ? "," + num(c.t0) + "," + num(c.t1) : "") + ") AND " + dr + " <= " + num(c.r);
      if (slab) sql += " AND " + rt + " BETWEEN " + num(c.t0) + " AND " + num(c.t1);
      const bool knn = c.k != kAllPoints;
      if (knn) sql += " ORDER BY " + (c.order == RayOrder::ray ? dr : rt) + ", p.point_index LIMIT " + std::to_string(c.k);
      RayQuery q;
      q.k = c.k;
      q.radius = c.r;
      q.t_min = c.t0;
      q.t_max = c.t1;
      q.order = c.order;
      const auto want = ray_query(brute, ray, q);
      const auto rows = pg.rows(sql);
      if (knn) {
        ASSERT_EQ(rows.size(), want.size()) << c.name;
        for (std::size_t i = 0; i < rows.size(); ++i) EXPECT_EQ(std::stoull(rows[i][0]), want[i].index) << c.name << " rank " << i;
      } else {
        std::set<std::size_t> got, w;
        for (const auto& row : rows) got.insert(std::stoull(row[0]));
        for (const RayHit& h : want) w.insert(h.index);
        EXPECT_EQ(got, w) << c.name;
      }
      nonempty += !want.empty();
    }
    // Frustum: four half-spaces around the ray, pruned with plane_below on the chunk index.
    const Vec3 a = glm::normalize(glm::cross(d, std::abs(d.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0)));
    const Vec3 b = glm::cross(d, a);
    const double w = 10 * r;
    const std::vector<Plane> planes = {{o + w * a, a}, {o - w * a, -a}, {o + w * b, b}, {o - w * b, -b}};
    std::string sql = "SELECT p.point_index" + from;
    for (std::size_t i = 0; i < planes.size(); ++i) {
      const std::string pl = vec(planes[i].point) + "," + vec(planes[i].normal);
      sql += std::string(i ? " AND " : "") + "c.box && plane_below(" + pl + ") AND dist_plane(" + pl + ", p.x, p.y, p.z) <= 0";
    }
    RayQuery fq;
    fq.planes = planes;
    std::set<std::size_t> got, want;
    for (const auto& row : pg.rows(sql)) got.insert(std::stoull(row[0]));
    for (const RayHit& h : ray_query(brute, ray, fq)) want.insert(h.index);
    EXPECT_EQ(got, want) << "frustum";
    EXPECT_FALSE(want.empty()) << "frustum";
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + sql)) plan += row[0] + "\n";
    EXPECT_NE(plan.find(table_ + "_chunks_box"), std::string::npos) << plan;
  }
  EXPECT_GE(nonempty, 8);  // the rays aim at points of the cloud: most queries have results
}

INSTANTIATE_TEST_SUITE_P(Scans, PostgresScan, ::testing::Values("lone_star", "pdrf8_append_bug"),
                         [](const auto& i) { return i.param; });

// The import streams through the index's external sort: importing an index
// file from `rayscan index` writes the same rows and chunks as importing the cloud (here with a
// 1 MiB sort budget, so many sort runs), and every row is the file's own point.
TEST_F(Postgres, ImportOfAnIndexFileEqualsImportOfTheCloud) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan-pgtest-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string bin = RAYSCAN_BIN, rsi = (dir / "autzen.rsi").string();
  ASSERT_EQ(run(bin + " index '" + scan_path("autzen").string() + "' -o " + rsi + " --attributes id > /dev/null 2>&1"), 0);
  Pg pg;
  pg.rows("DROP TABLE IF EXISTS autzen_rsi, autzen_rsi_chunks, autzen_rsi_sources, autzen_small, "
          "autzen_small_chunks, autzen_small_sources");
  ASSERT_EQ(run(bin + " db import " + rsi + " --postgres '" + conninfo() + "' --table autzen_rsi > /dev/null"), 0);
  ASSERT_EQ(run(bin + " db import '" + scan_path("autzen").string() + "' --postgres '" + conninfo() +
                "' --table autzen_small --memory 1M --temp-dir " + dir.string() + " > /dev/null"), 0);
  fs::remove(rsi);
  EXPECT_TRUE(fs::is_empty(dir)) << "temporary index or sort runs left in " << dir;
  fs::remove_all(dir);
  const std::string q = " ORDER BY chunk, point_index";
  const auto a = pg.rows("SELECT point_index, source, chunk, x, y, z FROM autzen_rsi" + q);
  const auto b = pg.rows("SELECT point_index, source, chunk, x, y, z FROM autzen_small" + q);
  ASSERT_EQ(a.size(), cloud_->size());
  EXPECT_EQ(a, b);
  for (const auto& row : a) ASSERT_EQ(Vec3(dbl(row[3]), dbl(row[4]), dbl(row[5])), cloud_->positions[std::stoull(row[0])]);
  EXPECT_EQ(pg.rows("SELECT box::text, first_row, count FROM autzen_rsi_chunks ORDER BY chunk"),
            pg.rows("SELECT box::text, first_row, count FROM autzen_small_chunks ORDER BY chunk"));
  pg.rows("DROP TABLE autzen_rsi, autzen_rsi_chunks, autzen_rsi_sources, autzen_small, autzen_small_chunks, "
          "autzen_small_sources");
}

/// Runs `cmd` with its stderr in a file; returns the exit code and the stderr text.
std::pair<int, std::string> run_capture(const std::string& cmd) {
  const fs::path err = fs::temp_directory_path() / ("rayscan-pgtest-" + std::to_string(::getpid()) + ".err");
  const int rc = run(cmd + " 2> '" + err.string() + "' > /dev/null");
  std::ifstream f(err);
  std::string text((std::istreambuf_iterator<char>(f)), {});
  fs::remove(err);
  return {rc, text};
}

// A failure inside the transaction (here the last CREATE INDEX, which an event trigger refuses
// after the points and chunks are written) takes everything back: no half table. Its message is
// one line: what failed and PostgreSQL's primary message, not its detail or the statement.
TEST_F(Postgres, FailedImportLeavesNoHalfTable) {
  Pg pg;
  pg.rows("DROP TABLE IF EXISTS half, half_chunks, half_sources");
  pg.rows("CREATE OR REPLACE FUNCTION rs_test_refuse() RETURNS event_trigger LANGUAGE plpgsql AS $$ BEGIN "
          "IF EXISTS (SELECT FROM pg_event_trigger_ddl_commands() WHERE object_identity = 'public.half_chunks_box') THEN "
          "RAISE EXCEPTION 'refused by the test' USING DETAIL = 'a second line'; END IF; END $$");
  pg.rows("CREATE EVENT TRIGGER rs_test_refuse ON ddl_command_end WHEN TAG IN ('CREATE INDEX') "
          "EXECUTE FUNCTION rs_test_refuse()");
  const auto [rc, err] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + scan_path("autzen").string() +
                                     "' --postgres '" + conninfo() + "' --table half -q");
  pg.rows("DROP EVENT TRIGGER rs_test_refuse; DROP FUNCTION rs_test_refuse()");
  EXPECT_EQ(rc, 2);
  EXPECT_EQ(err, "rayscan db: postgres: create public.half_chunks_box: refused by the test\n");
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_class WHERE relname IN ('half', 'half_chunks', 'half_sources')")[0][0], "0");
  EXPECT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + scan_path("autzen").string() + "' --postgres '" +
                conninfo() + "' --table 'Bad-Name' 2>/dev/null"), 2);
}

// An import whose table (or one of its companions, or an index name it uses) exists is refused
// before the points are read (no progress line), with one line naming it and what to do; a server
// that is not there gives libpq's message on one line (its hint joined, no tab).
TEST_F(Postgres, ImportErrorsAreOneLineNamingTheTableAndWhatToDo) {
  Pg pg;
  const std::string bin = RAYSCAN_BIN, cloud = scan_path("autzen").string();
  pg.rows("DROP TABLE IF EXISTS taken, taken2, taken2_sources, taken3, taken3_chunk_idx");
  pg.rows("CREATE TABLE taken (x int); CREATE TABLE taken2_sources (x int); CREATE TABLE taken3_chunk_idx (x int)");
  for (const char* t : {"taken", "taken2", "taken3"}) {
    const auto [rc, err] = run_capture(bin + " db import '" + cloud + "' --postgres '" + conninfo() + "' --table " + t);
    EXPECT_EQ(rc, 2) << t;
    const std::string rel = std::string(t) + (t == std::string("taken2") ? "_sources" : t == std::string("taken3") ? "_chunk_idx" : "");
    EXPECT_EQ(err, "rayscan db: postgres: table public." + rel + " exists: choose another --table or drop it\n");
  }
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_class WHERE relname LIKE 'taken%'")[0][0], "3");
  pg.rows("DROP TABLE taken, taken2_sources, taken3_chunk_idx");
  const auto [rc, err] = run_capture(bin + " db import '" + cloud + "' --postgres 'host=/nonexistent port=5432' --table x");
  EXPECT_EQ(rc, 2);
  EXPECT_EQ(err.rfind("rayscan db: postgres: cannot connect: ", 0), 0u) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_EQ(err.back(), '\n');
  EXPECT_EQ(err.find('\t'), std::string::npos) << err;
  EXPECT_NE(err.find("/nonexistent"), std::string::npos) << err;
}

// Each engine keeps the CRS of the sources as `rayscan info --json` reports it (the oracle): the
// WKT in <table>_sources.crs_wkt (NULL without one), and with --pcpatch the EPSG code as the
// pgpointcloud schema's srid (0 when none is identified), which PDAL's readers.pgpointcloud reads.
// Files: a WKT VLR without an EPSG code (autzen), one with EPSG:2154 (append-bug), GeoKeys of a
// compound CRS (Haystack_Rock: 3645 + vertical 5703), none (simple). The progress of a PostgreSQL
// import ends as SQLite's: insert, index, done, each of every point.
TEST_F(Postgres, ImportStoresTheCrsAsRayscanInfoReportsIt) {
  Pg pg;
  const bool pc = pg.rows("SELECT count(*) FROM pg_available_extensions WHERE name = 'pointcloud'")[0][0] != "0";
  std::set<int> codes;
  for (const char* name : {"las/autzen_trim.las", "las/append-bug.las", "las/Haystack_Rock.las", "las/simple.las"}) {
    const fs::path cloud = fs::path(RAYSCAN_TEST_DATA) / name;
    const InfoCrs want = info_crs(cloud);
    codes.insert(want.epsg);
    pg.rows("DROP TABLE IF EXISTS crs, crs_chunks, crs_sources, crs_pc, crs_pc_sources");
    const auto [rc, err] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud.string() + "' --postgres '" +
                                       conninfo() + "' --table crs");
    ASSERT_EQ(rc, 0) << err;
    expect_import_phases(err, std::stoull(pg.rows("SELECT count(*) FROM crs")[0][0]), true);
    const auto wkt = pg.rows("SELECT coalesce(crs_wkt, 'NULL') FROM crs_sources");
    ASSERT_EQ(wkt.size(), 1u);
    EXPECT_EQ(wkt[0][0], want.wkt.empty() ? "NULL" : want.wkt) << name;
    if (!pc) continue;
    ASSERT_EQ(run(std::string(RAYSCAN_BIN) + " db import '" + cloud.string() + "' --postgres '" + conninfo() +
                  "' --table crs_pc --pcpatch -q > /dev/null"), 0) << name;
    const auto srid = pg.rows("SELECT f.srid, coalesce(s.crs_wkt, 'NULL') FROM pointcloud_formats f, crs_pc_sources s "
                              "WHERE f.pcid = (SELECT DISTINCT PC_PCId(pa) FROM crs_pc)");
    ASSERT_EQ(srid.size(), 1u) << name;
    EXPECT_EQ(srid[0][0], std::to_string(want.epsg)) << name;
    EXPECT_EQ(srid[0][1], want.wkt.empty() ? "NULL" : want.wkt) << name;
  }
  EXPECT_EQ(codes, (std::set<int>{0, 2154, 3645}));  // the files cover a code, a compound CRS and none
  pg.rows("DROP TABLE IF EXISTS crs, crs_chunks, crs_sources, crs_pc, crs_pc_sources");
}

// A search_path without the extension's schema (options=-csearch_path=survey): the import finds
// rs_box where the extension is (pg_extension.extnamespace), or where a build tree's script put it,
// and names it schema-qualified, so the tables land in survey and the functions stay where they
// are. In a database without the extension, CREATE EXTENSION puts it in public, not in the data
// schema. Databases from template0 (no build-tree functions); the server's own postgres database
// has the build tree's functions in public and must get no extension.
TEST_F(Postgres, ImportFindsTheExtensionWhateverTheSearchPath) {
  Pg admin;
  const std::string cloud = scan_path("autzen").string(), n = std::to_string(cloud_->size());
  const bool pc = admin.rows("SELECT count(*) FROM pg_available_extensions WHERE name = 'pointcloud'")[0][0] != "0";
  const std::string rs_box_schemas = "SELECT string_agg(typnamespace::regnamespace::text, ',') FROM pg_type WHERE typname = 'rs_box'";
  for (const bool installed : {true, false}) {
    const std::string dbname = installed ? "rayscan_path_installed" : "rayscan_path_absent";
    admin.rows("DROP DATABASE IF EXISTS " + dbname + " WITH (FORCE)");
    admin.rows("CREATE DATABASE " + dbname + " TEMPLATE template0");
    {
      Pg db(dbname);
      db.rows("CREATE SCHEMA survey");
      if (installed) db.rows("CREATE EXTENSION rayscan");
      const auto [rc, err] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud + "' --postgres '" +
                                         conninfo(dbname) + " options=-csearch_path=survey' --table scan -q");
      ASSERT_EQ(rc, 0) << dbname << ": " << err;
      EXPECT_EQ(db.rows("SELECT count(*) FROM survey.scan")[0][0], n) << dbname;
      EXPECT_EQ(db.rows("SELECT extnamespace::regnamespace::text FROM pg_extension WHERE extname = 'rayscan'"),
                (std::vector<std::vector<std::string>>{{"public"}})) << dbname;
      EXPECT_EQ(db.rows(rs_box_schemas)[0][0], "public") << dbname;
      EXPECT_EQ(db.rows("SELECT atttypid::regtype::text FROM pg_attribute WHERE attrelid = 'survey.scan_chunks'::regclass "
                        "AND attname = 'box'")[0][0], "rs_box") << dbname;
      // The functions through a search path that holds both.
      db.rows("SET search_path = survey, public");
      EXPECT_EQ(db.rows("SELECT sum(count) FROM scan_chunks WHERE ray_dwithin(box, 636500, 849200, 600, 0, 0, -1, 1e6)")[0][0], n);
      if (pc) {
        const auto [rc2, err2] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud + "' --postgres '" +
                                             conninfo(dbname) + " options=-csearch_path=survey' --table scan_pc --pcpatch -q");
        ASSERT_EQ(rc2, 0) << dbname << ": " << err2;
        EXPECT_EQ(db.rows("SELECT extnamespace::regnamespace::text FROM pg_extension WHERE extname = 'pointcloud'")[0][0], "public");
        EXPECT_EQ(db.rows("SELECT sum(PC_NumPoints(pa)) FROM survey.scan_pc")[0][0], n);
      }
    }
    admin.rows("DROP DATABASE " + dbname + " WITH (FORCE)");
  }
  // The build tree's functions in public (pg_server.sh), no extension: found there, none created.
  admin.rows("DROP SCHEMA IF EXISTS survey CASCADE; CREATE SCHEMA survey");
  const auto [rc, err] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud + "' --postgres '" + conninfo() +
                                     " options=-csearch_path=survey' --table scan -q");
  ASSERT_EQ(rc, 0) << err;
  EXPECT_EQ(admin.rows("SELECT count(*) FROM survey.scan")[0][0], n);
  EXPECT_EQ(admin.rows("SELECT count(*) FROM pg_extension WHERE extname = 'rayscan'")[0][0], "0");
  EXPECT_EQ(admin.rows(rs_box_schemas)[0][0], "public");
  admin.rows("DROP SCHEMA survey CASCADE");
}

// `--table pg_class`: an unqualified COPY pg_class would reach the catalog (pg_catalog comes
// first in every search path) while CREATE TABLE makes public.pg_class. Every statement names the
// table with its schema (current_schema(), here also a schema of the connection's own search_path), so the import
// lands there whole and the catalog is untouched.
TEST_F(Postgres, TableNamedLikeACatalogTableLandsInTheCurrentSchema) {
  Pg pg;
  const std::string cloud = scan_path("autzen").string(), n = std::to_string(cloud_->size());
  pg.rows("DROP TABLE IF EXISTS public.pg_class, public.pg_class_chunks, public.pg_class_sources");
  const std::string catalog = "SELECT count(*) FROM pg_catalog.pg_class WHERE relnamespace = 'pg_catalog'::regnamespace";
  const std::string catalog_rows = pg.rows(catalog)[0][0];
  const auto [rc, err] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud + "' --postgres '" +
                                     conninfo() + "' --table pg_class");
  ASSERT_EQ(rc, 0) << err;
  EXPECT_EQ(pg.rows("SELECT count(*) FROM public.pg_class")[0][0], n);
  EXPECT_EQ(pg.rows("SELECT sum(count) FROM public.pg_class_chunks")[0][0], n);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM public.pg_class_sources")[0][0], "1");
  // The catalog's own relations are the same; the new ones (3 tables, 4 indexes) are in public.
  EXPECT_EQ(pg.rows(catalog)[0][0], catalog_rows);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_catalog.pg_class WHERE relnamespace = 'public'::regnamespace AND "
                    "relname LIKE 'pg\\_class%'")[0][0], "7");
  pg.rows("DROP TABLE public.pg_class, public.pg_class_chunks, public.pg_class_sources");
  // Another schema first in the connection's search path: the tables are created there.
  pg.rows("DROP SCHEMA IF EXISTS survey CASCADE; CREATE SCHEMA survey");
  const auto [rc2, err2] = run_capture(std::string(RAYSCAN_BIN) + " db import '" + cloud + "' --postgres '" +
                                       conninfo() + " options=-csearch_path=survey,public' --table scan");
  ASSERT_EQ(rc2, 0) << err2;
  EXPECT_EQ(pg.rows("SELECT count(*) FROM survey.scan")[0][0], n);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM survey.scan_chunks")[0][0],
            pg.rows("SELECT count(DISTINCT chunk) FROM survey.scan")[0][0]);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_class WHERE relname = 'scan' AND relnamespace = 'public'::regnamespace")[0][0], "0");
  pg.rows("DROP SCHEMA survey CASCADE");
}

// A reserved key word as --table (or an attribute) would meet the server's raw syntax error after
// the whole sort; it is refused before anything is read, with one line (exit 2). The server is the
// oracle of the list: its key words of category R and T (pg_get_keywords()) are exactly the ones
// refused, and every system column of a table is a refused column name.
TEST_F(Postgres, ReservedWordsAndSystemColumnsAreRefusedUpFront) {
  const std::string bin = RAYSCAN_BIN, cloud = scan_path("autzen").string();
  const auto [rc, err] = run_capture(bin + " db import '" + cloud + "' --postgres '" + conninfo() + "' --table select");
  EXPECT_EQ(rc, 2);
  EXPECT_EQ(err, "rayscan db: --table 'select': 'select' is a reserved key word of PostgreSQL; expected another name\n");
  const auto [rc2, err2] = run_capture(bin + " db import '" + cloud + "' --postgres '" + conninfo() +
                                       "' --table ok_name --attributes xmin");
  EXPECT_EQ(rc2, 2);
  EXPECT_NE(err2.find("attribute 'xmin': 'xmin' is a system column of PostgreSQL"), std::string::npos) << err2;
  Pg pg;
  EXPECT_EQ(pg.rows("SELECT count(*) FROM pg_class WHERE relname IN ('select', 'ok_name')")[0][0], "0");
  for (const auto& row : pg.rows("SELECT word, catcode FROM pg_get_keywords()")) {
    const bool reserved = row[1] == "R" || row[1] == "T";
    EXPECT_EQ(!sql::reserved_sql_name(row[0], false).empty(), reserved) << row[0] << " (" << row[1] << ")";
  }
  const auto sys = pg.rows("SELECT attname FROM pg_attribute WHERE attrelid = 'autzen'::regclass AND attnum < 0");
  EXPECT_GE(sys.size(), 6u);
  for (const auto& row : sys) EXPECT_NE(sql::reserved_sql_name(row[0], true), "") << row[0];
}

// A box such as rs_box('Infinity',2,3) would fail only later, in ray_dwithin; non-finite
// coordinates are refused where a box is made (both constructors and the text input), naming the coordinate.
TEST_F(Postgres, NonFiniteBoxCoordinatesAreRefusedAtInput) {
  Pg pg;
  EXPECT_EQ(pg.error_of("SELECT rs_box('Infinity',2,3)"), "rs_box: x is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT rs_box(1,'-Infinity',3)"), "rs_box: y is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT rs_box(1,2,'NaN')"), "rs_box: z is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT rs_box(0,0,0, 'Infinity',1,1)"), "rs_box: xmax is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0,1,1,inf)'::rs_box"), "rs_box: zmax is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0,1,1)'::rs_box"),
            "invalid input syntax for type rs_box: expected 6 comma-separated numbers in parentheses");
  EXPECT_EQ(pg.rows("SELECT ray_dwithin(rs_box(1,2,3), 0,0,0, 1,0,0, 3), ray_dwithin(rs_box(1,2,3), 0,0,0, 1,0,0, 3.7)")[0],
            (std::vector<std::string>{"f", "t"}));  // dist_ray = sqrt(13) = 3.606
}

// A denormal direction (0,0,1e-320) is not zero but cannot be normalised (its values would be
// wrong); the core's rule refuses it in every function, with the same text as SQLite.
TEST_F(Postgres, DirectionsThatCannotBeNormalisedAreErrors) {
  Pg pg;
  const std::string tail = " = (0,0,9.99989e-321) cannot be normalised exactly; expected a finite length between "
                           "about 1.5e-154 and 1.3e154";
  EXPECT_EQ(pg.error_of("SELECT dist_ray(0,0,0, 0,0,'1e-320', 1,2,3)"), "dist_ray: direction (dx,dy,dz)" + tail);
  EXPECT_EQ(pg.error_of("SELECT dist_plane(0,0,0, 0,0,'1e-320', 1,2,3)"), "dist_plane: normal (nx,ny,nz)" + tail);
  EXPECT_EQ(pg.error_of("SELECT ray_within(0,0,0, 0,0,'1e-320', 1)"), "ray_within: direction (dx,dy,dz)" + tail);
  EXPECT_EQ(pg.error_of("SELECT plane_below(0,0,0, 0,0,'1e-320')"), "plane_below: normal (nx,ny,nz)" + tail);
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(1,2,3), 0,0,0, 0,0,'1e-320', 1)"), "ray_dwithin: direction (dx,dy,dz)" + tail);
}

// Every error names the SQL function the user called, also where the message comes from the
// shared bounds evaluation (rs_eval_bounds) or a check the function shares with another.
TEST_F(Postgres, ErrorsNameTheFunctionTheUserCalled) {
  Pg pg;
  EXPECT_EQ(pg.error_of("SELECT dist_ray_max(0,0,0, 1,0,0, 0,2,0, 1,1,1)"),
            "dist_ray_max: box ymin > ymax; expected min <= max on every axis");
  EXPECT_EQ(pg.error_of("SELECT ray_time_min(0,0,0, 0,0,0, 0,0,0, 1,1,1)"),
            "ray_time_min: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT dist_plane_max(0,0,0, 0,0,1, 'NaN',0,0, 1,1,1)"),
            "dist_plane_max: argument 7 (xmin) is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT dist_plane_min(0,0,0, 0,0,1, 0,0,0, 1,1,'Infinity')"),
            "dist_plane_min: argument 12 (zmax) is infinite; expected a finite number");
  const std::string overflow = ": the result overflows double precision; expected coordinates and vector components "
                               "of magnitude below about 1e150";
  EXPECT_EQ(pg.error_of("SELECT dist_ray_min(0,0,0, 1,0,0, 0,0,0, 1e300,1,1)"), "dist_ray_min" + overflow);
  // ray_dwithin: a point box is evaluated with dist_ray, a larger box with dist_ray_min; the
  // message is ray_dwithin's either way, and its ray arguments are named as ray_dwithin has them.
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(0,0,0, 1,1,1), 0,0,0, 0,0,0, 1)"),
            "ray_dwithin: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(1,2,3), 0,0,0, 0,0,0, 1)"),
            "ray_dwithin: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(1,2,3), 0,'NaN',0, 1,0,0, 1)"),
            "ray_dwithin: oy is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(0,0,0, 1e300,1,1), 0,0,0, 1,0,0, 1)"), "ray_dwithin" + overflow);
  EXPECT_EQ(pg.error_of("SELECT ray_dwithin(rs_box(0,1e155,0), 0,0,0, 1,0,0, 1)"), "ray_dwithin" + overflow);
  // The text input of rs_ray / rs_plane is the type's, not ray_within's or plane_below's.
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0, 0,0,0, 1,0,1)'::rs_ray"),
            "rs_ray: direction (dx,dy,dz) is zero; expected a non-zero vector");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0, 0,0,0)'::rs_plane"), "rs_plane: normal (nx,ny,nz) is zero; expected a non-zero vector");
  // The bad value named, with the text SQLite's plane_prune gives for it (same text in both engines).
  EXPECT_EQ(pg.error_of("SELECT '(0,0,nan, 0,0,1)'::rs_plane"), "rs_plane: pz is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT plane_below(0,0,'NaN', 0,0,1)"), "plane_below: pz is NaN; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT plane_below(0,0,0, 'Infinity',0,1)"), "plane_below: nx is infinite; expected a finite number");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0, 0,-inf,1)'::rs_plane"), "rs_plane: ny is infinite; expected a finite number");
}

// With the documented GiST index the plan evaluates the index condition (ray_dwithin_ray) before
// ray_dwithin itself; a bad argument fails with ray_dwithin's own message either way: an index
// or bitmap scan, a sequential scan (enable_indexscan, enable_bitmapscan off), and a generic plan
// whose ray is a parameter. A NULL radius gives no row in every plan, as ray_dwithin gives NULL.
TEST_F(Postgres, RayDwithinErrorsAreRayDwithinsWhateverThePlan) {
  Pg pg;
  pg.rows("CREATE INDEX IF NOT EXISTS autzen_pt ON autzen USING gist (rs_box(x, y, z))");
  pg.rows("ANALYZE autzen");
  const std::string q = "SELECT count(*) FROM autzen WHERE ray_dwithin(rs_box(x, y, z), ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"636500,849200,600, 0,0,0, 2)", "ray_dwithin: direction (dx,dy,dz) is zero; expected a non-zero vector"},
      {"636500,849200,600, 0,0,-1, -2)", "ray_dwithin: radius r is negative or NaN; expected a number >= 0"},
      {"636500,849200,600, 0,0,-1, 'NaN')", "ray_dwithin: radius r is negative or NaN; expected a number >= 0"},
      {"636500,'NaN',600, 0,0,-1, 2)", "ray_dwithin: oy is NaN; expected a finite number"},
      {"636500,849200,600, 0,0,'Infinity', 2)", "ray_dwithin: dz is infinite; expected a finite number"},
  };
  for (const bool index : {true, false}) {
    pg.rows(index ? "RESET enable_indexscan; RESET enable_bitmapscan" : "SET enable_indexscan = off; SET enable_bitmapscan = off");
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + q + "636500,849200,600, 0,0,-1, 2)")) plan += row[0] + "\n";
    EXPECT_EQ(plan.find("ray_dwithin_ray(") != std::string::npos, index) << plan;
    EXPECT_EQ(plan.find("Seq Scan") != std::string::npos, !index) << plan;
    for (const auto& [args, message] : cases) EXPECT_EQ(pg.error_of(q + args), message) << args << (index ? " (index)" : "");
    EXPECT_EQ(pg.rows(q + "636500,849200,600, 0,0,-1, NULL)")[0][0], "0");
    // A generic plan: the index condition's ray is computed at run time.
    pg.rows("SET plan_cache_mode = force_generic_plan");
    pg.rows("PREPARE dw(float8, float8) AS " + q + "636500,849200,600, 0,0,$1, $2)");
    EXPECT_EQ(pg.error_of("EXECUTE dw(0, 2)"), cases[0].second);
    EXPECT_EQ(pg.error_of("EXECUTE dw(-1, -2)"), cases[1].second);
    EXPECT_EQ(pg.rows("EXECUTE dw(-1, NULL)")[0][0], "0");
    EXPECT_EQ(pg.rows("EXECUTE dw(-1, 2)")[0][0], pg.rows(q + "636500,849200,600, 0,0,-1, 2)")[0][0]);
    pg.rows("DEALLOCATE dw; RESET plan_cache_mode");
  }
  pg.rows("RESET enable_indexscan; RESET enable_bitmapscan");
}

// The text input and the constructor of rs_box name the axis whose min exceeds its max, as the
// bounds functions do; a number beyond float8's range is refused as float8 refuses it (the
// oracle: the server's own float8 input, SQLSTATE 22003), where strtod made 1e-400 a zero and
// 1e400 an "infinite" coordinate; a subnormal number is kept, as float8 keeps it.
TEST_F(Postgres, BoxInputNamesTheAxisAndRefusesOutOfRangeAsFloat8) {
  Pg pg;
  EXPECT_EQ(pg.error_of("SELECT '(5,2,3,4,5,6)'::rs_box"), "rs_box: xmin > xmax; expected min <= max on every axis");
  EXPECT_EQ(pg.error_of("SELECT rs_box(0,0,0,1,-1,1)"), "rs_box: ymin > ymax; expected min <= max on every axis");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,2,1,1,1)'::rs_box"), "rs_box: zmin > zmax; expected min <= max on every axis");
  for (const char* v : {"1e-400", "1e400", "-1e400"}) {
    const std::string oracle = pg.sqlstate_of(std::string("SELECT '") + v + "'::float8");
    EXPECT_EQ(oracle, "22003") << v;
    EXPECT_EQ(pg.sqlstate_of(std::string("SELECT '(1,2,3,") + v + ",5,6)'::rs_box"), oracle) << v;
    EXPECT_EQ(pg.error_of(std::string("SELECT '(1,2,3,") + v + ",5,6)'::rs_box"),
              std::string("rs_box: xmax \"") + v + "\" is out of range for type double precision");
  }
  EXPECT_EQ(pg.error_of("SELECT '( 1e-400 ,2,3,4,5,6)'::rs_box"),
            "rs_box: xmin \"1e-400\" is out of range for type double precision");
  EXPECT_EQ(pg.sqlstate_of("SELECT '(0,0,0,1,0,0,1e400,0,1)'::rs_ray"), "22003");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0,1,0,0,1e400,0,1)'::rs_ray"), "rs_ray: r \"1e400\" is out of range for type double precision");
  EXPECT_EQ(pg.error_of("SELECT '(0,0,0,0,0,1e-999)'::rs_plane"), "rs_plane: nz \"1e-999\" is out of range for type double precision");
  // Bad syntax is reported as such (invalid_text_representation) even where an earlier number is
  // out of range; a number after a tab is quoted from its first character, on one line.
  EXPECT_EQ(pg.sqlstate_of("SELECT '(1e400,2,3)'::rs_box"), "22P02");
  EXPECT_EQ(pg.error_of("SELECT E'(1,2,3,\\t1e400,5,6)'::rs_box"),
            "rs_box: xmax \"1e400\" is out of range for type double precision");
  EXPECT_EQ(pg.rows("SELECT '(1e-310,2,3,4,5,6)'::rs_box::text, '(' || '1e-310'::float8 || ',2,3,4,5,6)'")[0][0],
            pg.rows("SELECT '(' || '1e-310'::float8 || ',2,3,4,5,6)'")[0][0]);
  EXPECT_EQ(pg.rows("SELECT '(0,0,0,1,0,0,Infinity,-inf,inf)'::rs_ray::text")[0][0], "(0,0,0,1,0,0,Infinity,-Infinity,Infinity)");
}

// rs_box has = with a default B-tree and hash operator class: DISTINCT, GROUP BY, count(DISTINCT),
// UNION, ORDER BY and hash or merge joins on boxes work and agree with the oracle: equal means the
// same six float8 values (-0 = 0), the order is lexicographic on (xmin,ymin,zmin,xmax,ymax,zmax).
TEST_F(Postgres, BoxEqualityServesDistinctGroupByAndJoins) {
  Pg pg;
  pg.rows("DROP TABLE IF EXISTS boxes_eq");
  pg.rows("CREATE TABLE boxes_eq (id int, box rs_box)");
  // Groups: {1,2,3} the unit box (3 with xmin -0), {4,5,6} the point (1,2,3), {7} a box one ulp
  // larger than the unit box in zmax.
  pg.rows("INSERT INTO boxes_eq VALUES (4, rs_box(1,2,3)), (1, rs_box(0,0,0,1,1,1)), (7, rs_box(0,0,0,1,1,1.0000000000000002)), "
          "(2, '(0,0,0,1,1,1)'), (5, rs_box(1,2,3,1,2,3)), (3, rs_box('-0',0,0,1,1,1)), (6, '(1,2,3,1,2,3)')");
  using Rows = std::vector<std::vector<std::string>>;
  EXPECT_EQ(pg.rows("SELECT count(*) FROM (SELECT DISTINCT box FROM boxes_eq) d")[0][0], "3");
  EXPECT_EQ(pg.rows("SELECT count(DISTINCT box) FROM boxes_eq")[0][0], "3");
  EXPECT_EQ(pg.rows("SELECT array_agg(id ORDER BY id)::text FROM boxes_eq GROUP BY box ORDER BY box"),
            (Rows{{"{1,2,3}"}, {"{7}"}, {"{4,5,6}"}}));
  EXPECT_EQ(pg.rows("SELECT string_agg(id::text, ',' ORDER BY box, id) FROM boxes_eq")[0][0], "1,2,3,7,4,5,6");
  EXPECT_EQ(pg.rows("SELECT count(*) FROM (SELECT box FROM boxes_eq UNION SELECT rs_box(1,2,3)) u")[0][0], "3");
  EXPECT_EQ(pg.rows("SELECT rs_box(0,0,0,1,1,1) = rs_box(0,0,0,1,1,1.0000000000000002), rs_box(1,2,3) = '(1,2,3,1,2,3)', "
                    "rs_box(0,0,0,1,1,1) < rs_box(0,0,0,1,1,1.0000000000000002), rs_box(0,0,0,2,2,2) < rs_box(0,0,1,1,1,1)")[0],
            (std::vector<std::string>{"f", "t", "t", "t"}));
  // Both aggregation strategies, and both join strategies: a join pairs every box with every
  // equal one, 3*3 + 3*3 + 1*1 pairs, so the hash of -0 must equal the hash of 0.
  for (const char* off : {"enable_hashagg", "enable_sort"}) {
    pg.rows(std::string("SET ") + off + " = off");
    EXPECT_EQ(pg.rows("SELECT count(*) FROM boxes_eq GROUP BY box ORDER BY 1"), (Rows{{"1"}, {"3"}, {"3"}})) << off;
    pg.rows(std::string("RESET ") + off);
  }
  pg.rows("SET enable_nestloop = off");
  for (const auto& [off, node] : {std::pair{"enable_mergejoin", "Hash Join"}, std::pair{"enable_hashjoin", "Merge Join"}}) {
    pg.rows(std::string("SET ") + off + " = off");
    const std::string join = "SELECT count(*) FROM boxes_eq a JOIN boxes_eq b ON a.box = b.box";
    std::string plan;
    for (const auto& row : pg.rows("EXPLAIN " + join)) plan += row[0] + "\n";
    EXPECT_NE(plan.find(node), std::string::npos) << plan;
    EXPECT_EQ(pg.rows(join)[0][0], "19") << node;
    pg.rows(std::string("RESET ") + off);
  }
  // The import's chunk boxes: as many distinct boxes as distinct exact texts (float8out is
  // shortest-exact, and no chunk coordinate is -0 here).
  EXPECT_EQ(pg.rows("SELECT count(DISTINCT box) = count(DISTINCT box::text), count(DISTINCT box) > 1 FROM autzen_chunks"),
            (Rows{{"t", "t"}}));
  pg.rows("DROP TABLE boxes_eq");
}

/// The bytes `COPY (sql) TO STDOUT (FORMAT binary)` writes (fails the test on an error).
std::string copy_out_binary(Pg& pg, const std::string& sql) {
  PGresult* r = PQexec(pg.c, ("COPY (" + sql + ") TO STDOUT (FORMAT binary)").c_str());
  EXPECT_EQ(PQresultStatus(r), PGRES_COPY_OUT) << PQerrorMessage(pg.c);
  PQclear(r);
  std::string out;
  char* buf = nullptr;
  int n;
  while ((n = PQgetCopyData(pg.c, &buf, 0)) > 0) {
    out.append(buf, std::size_t(n));
    PQfreemem(buf);
  }
  while ((r = PQgetResult(pg.c))) {
    EXPECT_EQ(PQresultStatus(r), PGRES_COMMAND_OK) << PQerrorMessage(pg.c);
    PQclear(r);
  }
  return out;
}

/// Sends `data` with `COPY table FROM STDIN (FORMAT binary)`; the primary error message, "" on
/// success, and its SQLSTATE in *sqlstate when given.
std::string copy_in_binary(Pg& pg, const std::string& table, const std::string& data, std::string* sqlstate = nullptr) {
  PGresult* r = PQexec(pg.c, ("COPY " + table + " FROM STDIN (FORMAT binary)").c_str());
  EXPECT_EQ(PQresultStatus(r), PGRES_COPY_IN) << PQerrorMessage(pg.c);
  PQclear(r);
  EXPECT_EQ(PQputCopyData(pg.c, data.data(), int(data.size())), 1);
  EXPECT_EQ(PQputCopyEnd(pg.c, nullptr), 1);
  std::string m;
  while ((r = PQgetResult(pg.c))) {
    if (PQresultStatus(r) == PGRES_FATAL_ERROR) {
      const char* p = PQresultErrorField(r, PG_DIAG_MESSAGE_PRIMARY);
      m = p ? p : "?";
      if (sqlstate) *sqlstate = PQresultErrorField(r, PG_DIAG_SQLSTATE) ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : "?";
    }
    PQclear(r);
  }
  return m;
}

/// A binary COPY file of one rs_box column (PostgreSQL documentation, COPY, "Binary Format"):
/// the signature, flags and extension length, per row a field count of 1, the field's length
/// and its bytes, then the trailer -1. Each box is written as six IEEE doubles, big-endian.
std::string binary_copy_of_boxes(const std::vector<std::array<double, 6>>& boxes, int field_len = 48) {
  std::string s("PGCOPY\n\377\r\n\0", 11);
  auto be = [&s](std::uint64_t v, int bytes) {
    for (int i = bytes - 1; i >= 0; --i) s.push_back(char((v >> (8 * i)) & 0xff));
  };
  be(0, 4);
  be(0, 4);
  for (const auto& b : boxes) {
    be(1, 2);
    be(std::uint32_t(field_len), 4);
    for (int i = 0; i < field_len / 8; ++i) be(std::bit_cast<std::uint64_t>(b[std::size_t(i)]), 8);
  }
  be(0xffff, 2);
  return s;
}

// Binary I/O of rs_box: COPY ... (FORMAT binary) writes each box as six network-order float8
// (checked against a file built here from the doubles), reads those bytes back into the same
// values, and refuses a corrupt value with an error naming rs_box.
TEST_F(Postgres, BoxBinaryCopyRoundTripsAndRefusesCorruptValues) {
  Pg pg;
  const std::vector<std::array<double, 6>> boxes = {
      {0, 0, 0, 1, 1, 1},
      {-0.0, 1.0 / 3.0, -1e-300, 636500.123456789, 0.5, 1e300},
      {636500, 849200, -2.5, 636500, 849200, -2.5}};
  pg.rows("DROP TABLE IF EXISTS boxes_bin, boxes_bin2");
  pg.rows("CREATE TABLE boxes_bin (id int, box rs_box)");
  pg.rows("CREATE TABLE boxes_bin2 (box rs_box)");
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    std::string v;
    for (double c : boxes[i]) v.append(v.empty() ? "" : ",").append(num(c));
    pg.rows("INSERT INTO boxes_bin VALUES (" + std::to_string(i) + ", rs_box(" + v + "))");
  }
  const std::string want = binary_copy_of_boxes(boxes);
  const std::string out = copy_out_binary(pg, "SELECT box FROM boxes_bin ORDER BY id");
  EXPECT_EQ(out, want);
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", out), "");
  EXPECT_EQ(copy_out_binary(pg, "SELECT box FROM boxes_bin2"), want);
  // -0 keeps its sign through the round trip (the bytes above), and the values equal the text form's.
  EXPECT_EQ(pg.rows("SELECT count(*) FROM boxes_bin a JOIN boxes_bin2 b ON a.box::text = b.box::text")[0][0], "3");
  // The import's chunk boxes round-trip byte for byte too.
  pg.rows("TRUNCATE boxes_bin2");
  const std::string chunks = copy_out_binary(pg, "SELECT box FROM autzen_chunks ORDER BY chunk");
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", chunks), "");
  EXPECT_EQ(copy_out_binary(pg, "SELECT box FROM boxes_bin2"), chunks);
  EXPECT_EQ(pg.rows("SELECT count(*) FROM boxes_bin2")[0][0], pg.rows("SELECT count(*) FROM autzen_chunks")[0][0]);
  // Corrupt values: nothing is stored.
  pg.rows("TRUNCATE boxes_bin2");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", binary_copy_of_boxes({{0, 0, 0, 1, 1, 1}, {nan, 0, 0, 1, 1, 1}})),
            "rs_box: xmin is NaN; expected a finite number");
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", binary_copy_of_boxes({{0, 0, 0, 1, kInf, 1}})),
            "rs_box: ymax is infinite; expected a finite number");
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", binary_copy_of_boxes({{0, 0, 2, 1, 1, 1}})),
            "rs_box: zmin > zmax; expected min <= max on every axis");
  EXPECT_EQ(copy_in_binary(pg, "boxes_bin2", binary_copy_of_boxes({{0, 0, 0, 1, 1, 1}}, 40)),
            "invalid binary value for type rs_box: 40 bytes; expected 48 (six float8 in network byte order)");
  EXPECT_EQ(pg.rows("SELECT count(*) FROM boxes_bin2")[0][0], "0");
  pg.rows("DROP TABLE boxes_bin, boxes_bin2");
}

// Each kind of error has the SQLSTATE the server's own functions and types give the same fault (the
// oracle: the server, on its built-ins): an argument outside the function's domain as
// generate_series' zero step (22023), a result beyond float8 as float8 multiplication's overflow
// (22003), a malformed literal as float8's input (22P02), a number beyond float8's range in a
// literal as float8's input (22003), a binary value of the wrong size as float8's receive (22P03).
TEST_F(Postgres, EachKindOfErrorHasTheServersSqlstate) {
  Pg pg;
  const std::string argument = pg.sqlstate_of("SELECT generate_series(1, 2, 0)");
  const std::string overflow = pg.sqlstate_of("SELECT '1e200'::float8 * '1e200'::float8");
  const std::string syntax = pg.sqlstate_of("SELECT 'x'::float8");
  const std::string range = pg.sqlstate_of("SELECT '1e400'::float8");
  EXPECT_EQ(argument, "22023");
  EXPECT_EQ(overflow, "22003");
  EXPECT_EQ(syntax, "22P02");
  EXPECT_EQ(range, "22003");
  for (const char* sql : {"SELECT dist_ray(0,0,0, 0,0,0, 1,2,3)", "SELECT dist_ray(0,0,0, 1,0,0, 'NaN',2,3)",
                          "SELECT dist_ray(0,0,0, 0,0,'1e-320', 1,2,3)", "SELECT dist_ray_min(0,0,0, 1,0,0, 2,0,0, 1,1,1)",
                          "SELECT ray_within(0,0,0, 1,0,0, -1)", "SELECT ray_within(0,0,0, 1,0,0, 1, 2, 1)",
                          "SELECT plane_below(0,0,'NaN', 0,0,1)", "SELECT rs_box(1,2,'Infinity')",
                          "SELECT rs_box(0,0,2, 1,1,1)", "SELECT '(0,0,0, 0,0,0, 1,0,1)'::rs_ray",
                          "SELECT ray_dwithin(rs_box(1,2,3), 0,0,0, 1,0,0, -1)"})
    EXPECT_EQ(pg.sqlstate_of(sql), argument) << sql;
  for (const char* sql : {"SELECT dist_ray(0,0,0, 1,0,0, 0,1e155,0)", "SELECT dist_ray_min(0,0,0, 1,0,0, 0,0,0, 1e300,1,1)",
                          "SELECT ray_dwithin(rs_box(0,1e155,0), 0,0,0, 1,0,0, 1)",
                          "SELECT ray_dwithin(rs_box(0,0,0, 1e300,1,1), 0,0,0, 1,0,0, 1)"})
    EXPECT_EQ(pg.sqlstate_of(sql), overflow) << sql;
  for (const char* sql : {"SELECT '(1,2,3)'::rs_box", "SELECT 'x'::rs_ray", "SELECT '(1,2'::rs_plane"})
    EXPECT_EQ(pg.sqlstate_of(sql), syntax) << sql;
  for (const char* sql : {"SELECT '(1,2,3,1e400,5,6)'::rs_box", "SELECT '(0,0,0,1,0,0,1e400,0,1)'::rs_ray"})
    EXPECT_EQ(pg.sqlstate_of(sql), range) << sql;
  pg.rows("DROP TABLE IF EXISTS state_bin, state_f8");
  pg.rows("CREATE TABLE state_bin (box rs_box)");
  pg.rows("CREATE TABLE state_f8 (v float8)");
  std::string binary, ours;
  EXPECT_NE(copy_in_binary(pg, "state_f8", binary_copy_of_boxes({{1, 2, 0, 0, 0, 0}}, 16), &binary), "");
  EXPECT_EQ(binary, "22P03");
  EXPECT_NE(copy_in_binary(pg, "state_bin", binary_copy_of_boxes({{0, 0, 0, 1, 1, 1}}, 40), &ours), "");
  EXPECT_EQ(ours, binary);
  pg.rows("DROP TABLE state_bin, state_f8");
}

// Every object the extension creates has a description (COMMENT ON ...), which \dT+, \df+, \do+,
// pgAdmin and QGIS show. The oracle is the catalog: the members CREATE EXTENSION recorded
// (pg_depend, deptype 'e'), so an object a later version adds without a description fails here.
// Each description is one line and names the paper section it follows (or says it is not in the
// paper). A database created at 0.1 and updated (ALTER EXTENSION UPDATE) ends with the same members
// and descriptions as a fresh CREATE EXTENSION. pg_server.sh offers the build tree's extension
// files; the databases come from template0, which lacks the functions it loads into template1.
TEST_F(Postgres, EveryExtensionObjectHasADescription) {
  Pg admin;
  // The server reads its extension files from its private installation tree (the build's files).
  const auto sharedir = admin.rows("SELECT setting FROM pg_config WHERE name = 'SHAREDIR'");
  ASSERT_EQ(sharedir.size(), 1u);
  EXPECT_EQ(sharedir[0][0].rfind(server_dir() + "/", 0), 0u) << sharedir[0][0];
  const auto version = admin.rows("SELECT default_version FROM pg_available_extensions WHERE name = 'rayscan'");
  ASSERT_EQ(version.size(), 1u);
  const std::string members_sql =
      "SELECT c.relname, pg_describe_object(d.classid, d.objid, d.objsubid), "
      "coalesce(obj_description(d.objid, c.relname), '') FROM pg_depend d JOIN pg_class c ON c.oid = d.classid "
      "WHERE d.deptype = 'e' AND d.refclassid = 'pg_extension'::regclass "
      "AND d.refobjid = (SELECT oid FROM pg_extension WHERE extname = 'rayscan') ORDER BY 1, 2";
  const std::array<std::string, 2> dbs{"rayscan_ext_fresh", "rayscan_ext_updated"};
  std::array<std::vector<std::vector<std::string>>, 2> members;
  for (std::size_t i = 0; i < dbs.size(); ++i) {
    admin.rows("DROP DATABASE IF EXISTS " + dbs[i] + " WITH (FORCE)");
    admin.rows("CREATE DATABASE " + dbs[i] + " TEMPLATE template0");
    {
      Pg db(dbs[i]);
      if (i == 0) {
        db.rows("CREATE EXTENSION rayscan");
      } else {
        db.rows("CREATE EXTENSION rayscan VERSION '0.1'");
        db.rows("ALTER EXTENSION rayscan UPDATE");
      }
      EXPECT_EQ(db.rows("SELECT extversion FROM pg_extension WHERE extname = 'rayscan'"), version) << dbs[i];
      members[i] = db.rows(members_sql);
    }
    admin.rows("DROP DATABASE " + dbs[i] + " WITH (FORCE)");
  }
  // Members of every kind the scripts create, so that the check below is not over an empty list.
  std::set<std::string> kinds;
  for (const auto& m : members[0]) kinds.insert(m[0]);
  EXPECT_EQ(kinds, (std::set<std::string>{"pg_opclass", "pg_operator", "pg_opfamily", "pg_proc", "pg_type"}));
  for (const auto& m : members[0]) {
    EXPECT_NE(m[2], "") << m[1] << " has no description (COMMENT ON)";
    EXPECT_EQ(m[2].find('\n'), std::string::npos) << m[1] << ": " << m[2];
    EXPECT_TRUE(m[2].find("section 4.2") != std::string::npos || m[2].find("not in the paper") != std::string::npos)
        << m[1] << ": " << m[2];
  }
  EXPECT_EQ(members[1], members[0]);
}

}  // namespace
}  // namespace rayscan::sqltest
