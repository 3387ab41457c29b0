// The ray-query job and ray files as library calls (rayscan/jobs/query.hpp, rays.hpp); oracle:
// the brute-force index and the bytes written by the test itself.
#include "rayscan/octree/brute_force.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/jobs/info.hpp"
#include "rayscan/jobs/query.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/rays.hpp"

#include "io_test_util.hpp"

#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

using namespace rayscan;
using namespace rayscan::io;
using namespace rayscan::jobs;
using rayscan::test::temp_dir;

namespace {

std::string error_of(const std::filesystem::path& p) {
  try {
    (void)read_rays(p);
  } catch (const std::exception& e) {  // FormatError, or InputFileError (the input policy)
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RayFile, CsvAndF64GiveTheSameRays) {
  const auto dir = temp_dir();
  const double v[2][6] = {{1.5, -2.0, 3.25, 0.0, 0.0, 2.0}, {0.0, 0.0, 0.0, 1.0, 1.0, 0.0}};
  {
    std::ofstream csv(dir / "r.csv");
    csv << "ox, oy, oz, dx, dy, dz\r\n\n1.5,-2,3.25,0,0,2\n +0 ,0,0,1,1,0\n";
    std::ofstream f64(dir / "r.F64", std::ios::binary);
    f64.write(reinterpret_cast<const char*>(v), sizeof v);
  }
  const auto a = read_rays(dir / "r.csv"), b = read_rays(dir / "r.F64");
  ASSERT_EQ(a.size(), 2u);
  ASSERT_EQ(b.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(a[i].origin(), Vec3(v[i][0], v[i][1], v[i][2]));
    EXPECT_EQ(a[i].origin(), b[i].origin());
    EXPECT_EQ(a[i].direction(), b[i].direction());
  }
  EXPECT_DOUBLE_EQ(a[1].direction().x, std::sqrt(0.5));  // unit length
}

TEST(RayFile, ErrorsNameFileAndPlace) {
  const auto dir = temp_dir();
  {
    std::ofstream(dir / "h.csv") << "x,y,z\n";
    std::ofstream(dir / "n.csv") << "ox,oy,oz,dx,dy,dz\n1,2,3,4,5,6\n1,2,3,4,5\n";
    std::ofstream(dir / "z.csv") << "ox,oy,oz,dx,dy,dz\n1,2,3,0,0,0\n";
    std::ofstream(dir / "s.f64", std::ios::binary) << std::string(50, '\0');
  }
  EXPECT_EQ(error_of(dir / "h.csv"), (dir / "h.csv").string() + ": line 1: expected header ox,oy,oz,dx,dy,dz, got 'x,y,z'");
  EXPECT_EQ(error_of(dir / "n.csv"), (dir / "n.csv").string() + ": line 3: expected 6 values, got 5");
  EXPECT_EQ(error_of(dir / "z.csv").rfind((dir / "z.csv").string() + ": line 2: ", 0), 0u);
  EXPECT_EQ(error_of(dir / "s.f64"), (dir / "s.f64").string() + ": byte 48: size 50 is not a multiple of 48 (6 float64 per ray)");
  EXPECT_EQ(error_of(dir / "missing.csv").rfind((dir / "missing.csv").string() + ": cannot open file", 0), 0u);
  EXPECT_NE(error_of(dir).find("not a regular file"), std::string::npos) << error_of(dir);
}

TEST(QueryJob, InMemoryCloudMatchesBruteForce) {
  PointCloud cloud;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int i = 0; i < 3000; ++i) cloud.positions.emplace_back(u(rng), u(rng), u(rng));
  QueryJobOptions o;
  o.cloud = &cloud;
  for (int i = 0; i < 40; ++i) o.rays.emplace_back(Vec3(u(rng), u(rng), -10.0), Vec3(0.1 * u(rng), 0.1 * u(rng), 1.0));
  o.query.k = 4;
  o.query.radius = 0.4;
  o.query.order = RayOrder::sphere_hit;
  o.index.type = "octree-layered";
  o.control.threads = 2;
  const QueryJobResult r = run_query(o);
  ASSERT_EQ(r.hits.size(), o.rays.size());
  EXPECT_TRUE(r.cloud.empty());  // the in-memory cloud is not copied
  const BruteForceIndex brute(cloud.positions);
  std::size_t total = 0;
  for (std::size_t i = 0; i < o.rays.size(); ++i) {
    const auto want = ray_query(brute, o.rays[i], o.query);
    ASSERT_EQ(r.hits[i].size(), want.size()) << "ray " << i;
    for (std::size_t k = 0; k < want.size(); ++k) EXPECT_EQ(r.hits[i][k].index, want[k].index);
    total += want.size();
  }
  EXPECT_GT(total, 20u);

  std::ostringstream csv;
  write_hits_csv(csv, cloud.positions, r.hits);
  std::istringstream in(csv.str());
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "ray,rank,index,x,y,z,t,distance");
  std::size_t rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, total);

  o.query.k = 0;
  o.query.radius = -1.0;
  EXPECT_THROW((void)run_query(o), std::invalid_argument);
}

namespace {

/// The CSV a query job writes through QueryJobOptions::csv.
std::string streamed_csv(QueryJobOptions o) {
  std::string text;
  o.csv = [&](std::string_view s) { text += s; };
  const QueryJobResult r = run_query(o);
  EXPECT_TRUE(r.hits.empty());  // not kept
  return text;
}

/// Checks the CSV `csv` of a query on the LAS records of `las` (hit index = record number): x,
/// y, z have `decimals` decimals each and name the record's own integers on the grid of the
/// header (scale at byte 131, offset at 155: LAS 1.4 table 3), t and distance are `want`'s in the
/// shortest text, and the CSV equals write_hits_csv of the hits kept in memory. Returns the rows.
std::size_t expect_grid_csv(const std::string& csv, const std::filesystem::path& las, std::size_t decimals,
                            const QueryJobResult& want) {
  const std::vector<std::uint8_t> head = rayscan::test::slurp(las);
  Vec3 scale(0.0), offset(0.0);
  for (int k = 0; k < 3; ++k) {
    std::memcpy(&scale[k], head.data() + 131 + 8 * k, 8);
    std::memcpy(&offset[k], head.data() + 155 + 8 * k, 8);
  }
  const LasRecords rec = read_las_records(las);
  std::ostringstream kept;
  write_hits_csv(kept, want);
  EXPECT_EQ(csv, kept.str()) << las;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "ray,rank,index,x,y,z,t,distance");
  std::size_t rows = 0;
  for (std::size_t ray = 0; ray < want.hits.size(); ++ray)
    for (std::size_t rank = 0; rank < want.hits[ray].size(); ++rank, ++rows) {
      if (!std::getline(in, line)) {
        ADD_FAILURE() << las << ": " << rows << " rows only";
        return rows;
      }
      std::istringstream row(line);
      std::string f[8];
      for (std::string& v : f) std::getline(row, v, ',');
      const RayHit& h = want.hits[ray][rank];
      EXPECT_EQ(f[0] + "," + f[1] + "," + f[2], std::to_string(ray) + "," + std::to_string(rank) + "," + std::to_string(h.index));
      for (int k = 0; k < 3; ++k) {
        const std::string& t = f[3 + k];
        if (t.find('.') == std::string::npos) {
          ADD_FAILURE() << "no decimals: " << line;
          continue;
        }
        EXPECT_EQ(t.size() - t.find('.') - 1, decimals) << line;
        std::int32_t q = 0;
        std::memcpy(&q, rec.records.data() + std::size_t{h.index} * rec.record_length + 4 * k, 4);
        EXPECT_EQ(std::llround((std::stod(t) - offset[k]) / scale[k]), q) << line;
      }
      char buf[2][32];
      EXPECT_EQ(f[6], std::string(buf[0], std::to_chars(buf[0], buf[0] + 32, h.t).ptr)) << line;
      EXPECT_EQ(f[7], std::string(buf[1], std::to_chars(buf[1], buf[1] + 32, h.distance).ptr)) << line;
    }
  EXPECT_FALSE(std::getline(in, line)) << line;
  return rows;
}

/// Rays straight down through 40 of `cloud`'s points (every 997th), from 50 units above.
std::vector<Ray> rays_down_through(const PointCloud& cloud) {
  std::vector<Ray> rays;
  for (std::size_t i = 0; i < cloud.size() && rays.size() < 40; i += 997)
    rays.emplace_back(cloud.positions[i] + Vec3(0, 0, 50), Vec3(0, 0, -1));
  return rays;
}

}  // namespace

// The rays of a run: kQueryHitsPerRun (16,384) results by the typical count, within [1, 256], and
// never more rays than fit one MPI message (2^31 - 1 - 4096 bytes, 8 + 32 B a ray) were each to
// return the bound, so that a ray outside the sample cannot make a run's reply pass 2 GiB.
TEST(QueryJob, RunsAreCappedSoThatTheirBoundFitsOneMpiMessage) {
  using rayscan::jobs::detail::query_run_rays;
  EXPECT_EQ(query_run_rays(1, 1), 256u);
  EXPECT_EQ(query_run_rays(64, 64), 256u);
  EXPECT_EQ(query_run_rays(100, 100), 163u);       // 16,384 / 100
  EXPECT_EQ(query_run_rays(20000, 20000), 1u);
  EXPECT_EQ(query_run_rays(1, 1000000), 67u);      // 2,147,479,551 / 32,000,008 = 67.1
  EXPECT_EQ(query_run_rays(1000, 1000000), 16u);   // the typical count binds first
  EXPECT_EQ(query_run_rays(1, 10000000), 6u);      // / 320,000,008 = 6.7
  EXPECT_EQ(query_run_rays(1, 100000000), 1u);     // one ray past 2 GiB: still one ray
  EXPECT_EQ(query_run_rays(0, 0), 256u);
  // Against a search over every run length: the longest whose worst case fits.
  const std::uint64_t max_bytes = 2147483647u - 4096u;
  for (std::uint64_t bound : {std::uint64_t{65}, std::uint64_t{70000}, std::uint64_t{262144}, std::uint64_t{5000000},
                              std::uint64_t{33554367}, std::uint64_t{33554368}, std::uint64_t{67108735},
                              std::uint64_t{67108736}}) {
    std::uint64_t want = 1;
    for (std::uint64_t rays = 1; rays <= 256; ++rays)
      if (rays * (8 + 32 * bound) <= max_bytes) want = rays;
    EXPECT_EQ(query_run_rays(1, bound), want) << "bound " << bound;
  }
}

// A radius query without k: a ray's bound is every point, so the job cuts its runs by the most
// results of a sample of the rays; rays 1 to 3 (outside the sample) run along a dense line and
// return far more than that, so their run is longer. Every ray's answer is brute force's all the
// same, kept or streamed.
TEST(QueryJob, RadiusQueryWithoutKMatchesBruteForceWhateverItsRuns) {
  PointCloud cloud;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int i = 0; i < 4000; ++i) cloud.positions.emplace_back(u(rng), u(rng), u(rng));
  for (int i = 0; i < 3000; ++i) cloud.positions.emplace_back(u(rng), 0.0, 0.0);  // the line
  QueryJobOptions o;
  o.cloud = &cloud;
  for (int i = 0; i < 600; ++i)
    o.rays.push_back(i >= 1 && i <= 3 ? Ray(Vec3(-10.0, 0.01 * i, 0.0), Vec3(1.0, 0.0, 0.0))
                                      : Ray(Vec3(u(rng), u(rng), -10.0), Vec3(0.0, 0.0, 1.0)));
  o.query.radius = 0.3;
  o.control.threads = 2;
  const QueryJobResult r = run_query(o);
  ASSERT_EQ(r.hits.size(), o.rays.size());
  const BruteForceIndex brute(cloud.positions);
  for (std::size_t i = 0; i < o.rays.size(); ++i) {
    const auto want = ray_query(brute, o.rays[i], o.query);
    ASSERT_EQ(r.hits[i].size(), want.size()) << "ray " << i;
    for (std::size_t k = 0; k < want.size(); ++k) EXPECT_EQ(r.hits[i][k].index, want[k].index) << "ray " << i;
  }
  EXPECT_GE(r.hits[2].size(), 3000u);
  std::ostringstream kept;
  write_hits_csv(kept, cloud.positions, r.hits);
  EXPECT_EQ(streamed_csv(o), kept.str());
}

// The query CSV prints the coordinates of a LAS, COPC or index-file source on its LAS grid, with
// the grid's decimals (autzen_trim.las: scale 0.01, 2 decimals: 636191.20, not the reader's double
// 636191.2000000001; lone-star.copc.laz: scale 0.00025 and offset 515384.8225, 5), as the text
// writer and las2txt do; t and distance stay the shortest round-trip text. The CSV streamed while
// the rays are answered equals the one written from the hits kept in memory. Oracle: the files'
// own records and header bytes.
TEST(QueryJob, CsvCoordinatesOfLasCopcAndIndexSourcesHaveTheGridsDecimals) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  QueryJobOptions o;
  o.cloud_file = las;
  o.rays = rays_down_through(io::read_point_cloud(las));
  o.query.k = 3;
  o.query.radius = 1.0;
  o.control.threads = 2;
  EXPECT_GE(expect_grid_csv(streamed_csv(o), las, 2, run_query(o)), 40u);

  // The index file of it, with ids (hit index = record number): positions stored as the LAS
  // integers, so the same grid.
  IndexJobOptions index;
  index.inputs = {las};
  index.output = temp_dir() / "grid_query.rsi";
  index.attributes = "id";
  (void)run_index(index);
  o.cloud_file = index.output;
  EXPECT_GE(expect_grid_csv(streamed_csv(o), las, 2, run_query(o)), 40u);

  RAYSCAN_REQUIRE_FILE(copc, "laz/lone-star.copc.laz");
  o.cloud_file = copc;
  o.rays = rays_down_through(io::read_point_cloud(copc, io::ReadOptions{.scalars = false}));
  o.query.radius = 0.05;
  EXPECT_GE(expect_grid_csv(streamed_csv(o), copc, 5, run_query(o)), 40u);
}

TEST(InfoJob, CountsAndBoundsOfATestFile) {
  InfoJobOptions o;
  o.file = rayscan::test::data_file("las/autzen_trim.las");
  const InfoJobResult r = run_info(o);
  // Oracle: the count and bounds the shared data README gives for the file (scale 0.01).
  EXPECT_EQ(r.info.format, "LAS");
  EXPECT_EQ(r.count, 110000u);
  EXPECT_NEAR(r.bounds.lo.x, 636001.76, 1e-6);
  EXPECT_NEAR(r.bounds.lo.y, 848935.20, 1e-6);
  EXPECT_NEAR(r.bounds.lo.z, 406.26, 1e-6);
  EXPECT_NEAR(r.bounds.hi.x, 637179.22, 1e-6);
  EXPECT_NEAR(r.bounds.hi.y, 849497.90, 1e-6);
  EXPECT_NEAR(r.bounds.hi.z, 520.51, 1e-6);
  ASSERT_FALSE(r.attributes.empty());
  EXPECT_EQ(r.attributes[0].name, "X");
  EXPECT_NEAR(r.attributes[0].lo, 636001.76, 1e-6);
  EXPECT_NE(info_report_text(r).find("points:            110000"), std::string::npos);
  EXPECT_NE(info_report_json(r).find("\"count\": 110000"), std::string::npos);
}

// A COPC file queried in place logs its node decodes with the rays, one ray in the singular.
// Oracle: lone-star.copc.laz's 15 hierarchy nodes (docs/visibility.md) and the job's own decode
// count, a ray down through one of its points (--k 1: one hit).
TEST(QueryJob, CopcLogLineOfOneRayIsSingular) {
  RAYSCAN_REQUIRE_FILE(copc, "laz/lone-star.copc.laz");
  QueryJobOptions o;
  o.cloud_file = copc;
  o.rays = {rays_down_through(io::read_point_cloud(copc, io::ReadOptions{.scalars = false})).front()};
  o.query.k = 1;
  std::vector<std::string> log;
  o.control.log = [&](const std::string& line) { log.push_back(line); };
  const QueryJobResult r = run_query(o);
  ASSERT_EQ(r.hits.size(), 1u);
  EXPECT_EQ(r.hits[0].size(), 1u);
  EXPECT_EQ(r.copc_nodes, 15u);
  ASSERT_EQ(log.size(), 1u);
  const std::string want = "COPC: " + std::to_string(r.copc_decodes) + " of 15 nodes decoded, 1 ray in ";
  EXPECT_EQ(log[0].substr(0, want.size()), want) << log[0];
}
