// `rayscan query` end to end: the CSV it writes equals the library's answer (itself checked against
// brute force), each number the shortest text that reads back as the same double (std::to_chars),
// every index gives the same rows, the summary on standard error counts what was read and written,
// and bad input exits with code 2 and a one-line error naming the file and line or the option.
#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/ray_query.hpp"

#include "../common/run_command.hpp"
#include "../common/sanitizers.hpp"
#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>

#include <sched.h>
#include <sys/wait.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>

using namespace rayscan;
namespace fs = std::filesystem;

namespace {

using RunResult = rayscan::test::CommandResult;

/// Runs `rayscan ARGS`, capturing standard output and error.
RunResult run(const std::string& args) {
  return rayscan::test::run_command(std::string(RAYSCAN_BIN) + " " + args);
}

class QueryCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = rayscan::test::process_temp_dir("rayscan_query_cli");
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> u(0, 1);
    std::ofstream c(dir_ / "cloud.csv");
    c.precision(17);
    c << "x,y,z\n";
    for (int i = 0; i < 2000; ++i) {
      pts_.emplace_back(600000 + u(rng), 5300000 + u(rng), u(rng));
      c << pts_.back().x << ',' << pts_.back().y << ',' << pts_.back().z << '\n';
    }
    std::ofstream r(dir_ / "rays.csv");
    r.precision(17);
    r << "ox,oy,oz,dx,dy,dz\n";
    for (int i = 0; i < 20; ++i) {
      rays_.emplace_back(Vec3(599999, 5300000 + u(rng), u(rng)), Vec3(1, 0, 0));
      r << 599999 << ',' << rays_.back().origin().y << ',' << rays_.back().origin().z << ','
        << 1 << ',' << 0 << ',' << 0 << '\n';
    }
    r.close();
    c.close();
    // Rebuild the rays from the text that was written (what the CLI will parse).
    rays_.clear();
    std::ifstream in(dir_ / "rays.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      double v[6];
      char comma;
      std::istringstream ss(line);
      ss >> v[0] >> comma >> v[1] >> comma >> v[2] >> comma >> v[3] >> comma >> v[4] >> comma >> v[5];
      rays_.emplace_back(Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5]));
    }
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// The shortest text of `v` that reads back as `v` (std::to_chars, the C++ standard's rule).
  static std::string shortest(double v) {
    char buf[32];
    return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
  }

  std::string expected_csv(const RayQuery& q) const { return expected_csv(q, rays_); }

  /// The brute-force rows of `rays`.
  std::string expected_csv(const RayQuery& q, const std::vector<Ray>& rays) const {
    const BruteForceIndex bf(pts_);
    std::ostringstream os;
    os << "ray,rank,index,x,y,z,t,distance\n";
    for (std::size_t r = 0; r < rays.size(); ++r) {
      const auto hits = ray_query(bf, rays[r], q);
      for (std::size_t k = 0; k < hits.size(); ++k) {
        const Vec3& p = pts_[hits[k].index];
        os << r << ',' << k << ',' << hits[k].index << ',' << shortest(p.x) << ',' << shortest(p.y) << ','
           << shortest(p.z) << ',' << shortest(hits[k].t) << ',' << shortest(hits[k].distance) << '\n';
      }
    }
    return os.str();
  }

  static std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  /// Writes `copies` copies of the fixture's 20 rays as `name` (.f64) and returns them.
  std::vector<Ray> write_copies(const std::string& name, int copies) const {
    std::vector<Ray> all;
    std::ofstream f(dir_ / name, std::ios::binary);
    for (int copy = 0; copy < copies; ++copy)
      for (const Ray& r : rays_) {
        const double v[6] = {r.origin().x, r.origin().y, r.origin().z, r.direction().x, r.direction().y,
                             r.direction().z};
        f.write(reinterpret_cast<const char*>(v), sizeof v);
        all.push_back(r);
      }
    return all;
  }

  fs::path dir_;
  std::vector<Vec3> pts_;
  std::vector<Ray> rays_;
};

TEST_F(QueryCli, EveryIndexWritesTheBruteForceRows) {
  RayQuery q;
  q.k = 3;
  q.radius = 0.05;
  q.order = RayOrder::sphere_hit;
  const std::string want = expected_csv(q);
  ASSERT_GT(std::count(want.begin(), want.end(), '\n'), 10);
  for (const char* index : {"octree-adaptive", "octree-layered", "octree-fixed", "kdtree", "brute"}) {
    const fs::path out = dir_ / (std::string(index) + ".csv");
    const RunResult r = run("query --cloud " + (dir_ / "cloud.csv").string() + " --rays " +
                            (dir_ / "rays.csv").string() +
                            " --k 3 --radius 0.05 --order sphere_hit --index " + index +
                            " --out " + out.string());
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(slurp(out), want) << index;
  }
}

TEST_F(QueryCli, BinaryRaysAndTimeRange) {
  // The same rays as headerless little-endian float64 (.f64).
  std::ofstream f(dir_ / "rays.f64", std::ios::binary);
  for (const Ray& r : rays_) {
    const double v[6] = {r.origin().x, r.origin().y, r.origin().z, r.direction().x, r.direction().y,
                         r.direction().z};
    f.write(reinterpret_cast<const char*>(v), sizeof v);
  }
  f.close();
  RayQuery q;
  q.t_min = 0.25;
  q.t_max = 0.5;
  q.radius = 0.03;
  q.order = RayOrder::time;
  // Standard output alone (the progress and summary lines go to standard error).
  const RunResult r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " query --cloud " +
                                                     (dir_ / "cloud.csv").string() + " --rays " +
                                                     (dir_ / "rays.f64").string() +
                                                     " --t-min 0.25 --t-max 0.5 --radius 0.03 --order time",
                                                 false);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out, expected_csv(q));
}

// The report on standard error: a progress line over the blocks of 256 rays (a pipe: the line of
// the last block) and a summary whose counts are the rays file's and the CSV's, with the threads
// used (--threads above the cores: the cores this process may use, its CPU affinity); standard
// output keeps the CSV alone, and -q silences standard error. Oracles: the 600 rays written here
// (30 copies of the fixture's 20: 3 blocks), their brute-force rows, sched_getaffinity.
TEST_F(QueryCli, SummaryLineCountsTheRaysFileAndTheRowsWritten) {
  {
    std::ofstream f(dir_ / "rays600.f64", std::ios::binary);
    for (int copy = 0; copy < 30; ++copy)
      for (const Ray& r : rays_) {
        const double v[6] = {r.origin().x, r.origin().y, r.origin().z, r.direction().x, r.direction().y,
                             r.direction().z};
        f.write(reinterpret_cast<const char*>(v), sizeof v);
      }
  }
  RayQuery q;
  q.k = 2;
  q.radius = 0.05;
  const std::string one = expected_csv(q);  // the 20 rays' rows, after the header line
  const long rows20 = std::count(one.begin(), one.end(), '\n') - 1;
  ASSERT_GT(rows20, 10);
  const long rows = 30 * rows20;
  const std::string base = std::string(RAYSCAN_BIN) + " query --cloud " + (dir_ / "cloud.csv").string() +
                           " --rays " + (dir_ / "rays600.f64").string() + " --k 2 --radius 0.05";
  const fs::path err = dir_ / "err.txt", out = dir_ / "hits.csv";
  // Standard error into a file, standard output captured: the summary is the last line.
  auto run_split = [&](const std::string& args) {
    return rayscan::test::run_command("(" + base + args + " 2>'" + err.string() + "')", false);
  };
  const std::regex summary(R"(rayscan query: (\d+) rays, (\d+) results written to (.*); (\d+) threads?, )"
                           R"(\d+\.\d\d s in all \(\d+\.\d\d s querying, \d+ rays/s\)\n$)");
  std::smatch m;

  RunResult r = run_split(" --threads 1 --out '" + out.string() + "'");
  ASSERT_EQ(r.code, 0) << slurp(err);
  EXPECT_EQ(r.out, "");
  std::string e = slurp(err);
  ASSERT_TRUE(std::regex_search(e, m, summary)) << e;
  EXPECT_EQ(m[1], "600");
  const std::string csv = slurp(out);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n') - 1, rows);
  EXPECT_EQ(m[2], std::to_string(rows));
  EXPECT_EQ(m[3], "'" + out.string() + "'");
  EXPECT_EQ(m[4], "1");
  EXPECT_NE(e.find("\nprogress: 3/3 ray blocks 100.0%"), std::string::npos) << e;

  r = run_split(" --threads 1024");
  ASSERT_EQ(r.code, 0) << slurp(err);
  EXPECT_EQ(r.out, csv);  // standard output: the same CSV, nothing else
  e = slurp(err);
  ASSERT_TRUE(std::regex_search(e, m, summary)) << e;
  EXPECT_EQ(m[1], "600");
  EXPECT_EQ(m[2], std::to_string(rows));
  EXPECT_EQ(m[3], "standard output");
  cpu_set_t cpus;
  ASSERT_EQ(::sched_getaffinity(0, sizeof cpus, &cpus), 0);
  EXPECT_EQ(m[4], std::to_string(CPU_COUNT(&cpus)));

  r = run_split(" -q");
  ASSERT_EQ(r.code, 0) << slurp(err);
  EXPECT_EQ(r.out, csv);
  EXPECT_EQ(slurp(err), "");

  // Standard output that takes no byte (/dev/full: a full disk): the write error ends the report,
  // not a summary of rows that were never written.
  if (fs::exists("/dev/full")) {
    r = rayscan::test::run_command("(" + base + " > /dev/full 2>'" + err.string() + "')", false);
    EXPECT_EQ(r.code, 2);
    e = slurp(err);
    EXPECT_EQ(e.find(" written to "), std::string::npos) << e;
    EXPECT_EQ(e.substr(e.rfind("rayscan query: ")).rfind("rayscan query: standard output: write failed", 0), 0u) << e;
  }
}

// One point, one ray: every count on standard error in the singular ("1 point", "1 ray", "1
// result", "1 thread"), never "1 rays". Oracle: the counts of the two files written here and --k 1
// (with no radius the one ray's nearest point is always a hit: one row).
TEST_F(QueryCli, OneRayIsSingularInTheLogAndTheSummary) {
  std::ofstream(dir_ / "one_point.csv") << "x,y,z\n600000.5,5300000.5,0.5\n";
  std::ofstream(dir_ / "one_ray.csv") << "ox,oy,oz,dx,dy,dz\n599999,5300000.5,0.5,1,0,0\n";
  const fs::path err = dir_ / "err.txt", out = dir_ / "one.csv";
  const RunResult r = rayscan::test::run_command(
      "(" + std::string(RAYSCAN_BIN) + " query --cloud '" + (dir_ / "one_point.csv").string() + "' --rays '" +
          (dir_ / "one_ray.csv").string() + "' --k 1 --threads 1 --out '" + out.string() + "' 2>'" + err.string() + "')",
      false);
  ASSERT_EQ(r.code, 0) << slurp(err);
  EXPECT_EQ(slurp(out), "ray,rank,index,x,y,z,t,distance\n0,0,0,600000.5,5300000.5,0.5,1.5,0\n");
  const std::string e = slurp(err);
  EXPECT_TRUE(std::regex_search(e, std::regex(R"(^rayscan query: read 1 point and 1 ray in \d+\.\d\d s\n)"))) << e;
  EXPECT_TRUE(std::regex_search(e, std::regex("\nrayscan query: 1 ray, 1 result written to '" + out.string() +
                                              R"('; 1 thread, \d+\.\d\d s in all \(\d+\.\d\d s querying, \d+ rays/s\)\n$)")))
      << e;
  // No count of one in the plural anywhere (a rate such as "9601 rays/s" is a unit, not a count).
  EXPECT_FALSE(std::regex_search(e, std::regex(R"((^|[^0-9.])1 (ray|point|result|thread)s($|[^/]))"))) << e;
}

// The rows are written as the rays are answered, run by run: a run is a whole block of 256 rays
// when each ray returns few results, fewer rays when each may return many (no --k: up to the
// cloud's 2000 points, so runs of 8 rays here), and one thread writes them in ray order. Oracle:
// the brute-force rows of the 600 rays (2 whole blocks and a short one), for 1 and 3 threads.
TEST_F(QueryCli, RunsOfRaysAreWrittenInRayOrderForAnyThreadCount) {
  const std::vector<Ray> rays = write_copies("rays600.f64", 30);
  RayQuery q;
  q.radius = 0.05;
  q.order = RayOrder::time;
  const std::string want = expected_csv(q, rays);
  ASSERT_GT(std::count(want.begin(), want.end(), '\n'), 600);
  for (const char* threads : {"1", "3"}) {
    const RunResult r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " query -q --cloud " +
                                                       (dir_ / "cloud.csv").string() + " --rays " +
                                                       (dir_ / "rays600.f64").string() +
                                                       " --radius 0.05 --order time --threads " + threads,
                                                   false);
    ASSERT_EQ(r.code, 0);
    EXPECT_EQ(r.out, want) << threads << " threads";
  }
}

// Memory holds the runs of rays in flight, not the whole answer: 2000 rays x --all over the 2000
// points are 4 million rows (160 MB of hits held at once if they were collected before writing),
// and the query completes within an address-space limit (ulimit -v) 40 MiB above what the same
// rays with --k 1 need. Oracle: the row count on standard output, 2000 x 2000 + the header.
// (MALLOC_ARENA_MAX=1: every thread allocates from one heap, so the limit does not also catch
// the 64 MiB address ranges glibc reserves for each thread's own heap, which vary by run.)
TEST_F(QueryCli, AllResultsOfManyRaysStreamWithinAMemoryLimit) {
  if (rayscan::test::kSanitized) GTEST_SKIP() << "a sanitizer reserves its shadow memory beyond any ulimit -v";
  write_copies("rays2000.f64", 100);
  const auto rows_within = [&](long kib, const std::string& bound) {
    const RunResult r = rayscan::test::run_command(
        "MALLOC_ARENA_MAX=1 sh -c 'ulimit -v " + std::to_string(kib) + " && exec " + RAYSCAN_BIN + " query -q --cloud " +
            (dir_ / "cloud.csv").string() + " --rays " + (dir_ / "rays2000.f64").string() + " --threads 2 " + bound +
            "' 2>/dev/null | wc -l",
        false);
    return std::stol(r.out);
  };
  // The least limit (to 4 MiB) in which the small query completes: the program, its libraries and
  // the threads' stacks.
  long lo = 16 << 10, hi = 4 << 20;
  ASSERT_EQ(rows_within(hi, "--k 1"), 2001);
  while (hi - lo > (4 << 10)) {
    const long mid = (lo + hi) / 2;
    (rows_within(mid, "--k 1") == 2001 ? hi : lo) = mid;
  }
  EXPECT_EQ(rows_within(hi + (40 << 10), "--all"), 2000L * 2000 + 1);
}

TEST_F(QueryCli, BadInputExitsTwoWithOneLineError) {
  const std::string cloud = (dir_ / "cloud.csv").string();
  const std::string rays = (dir_ / "rays.csv").string();
  {
    std::ofstream bad(dir_ / "bad_rays.csv");
    bad << "ox,oy,oz,dx,dy,dz\n0,0,0,1,0,0\n0,0,zero,1,0,0\n";
  }
  RunResult r = run("query --cloud " + cloud + " --rays " + (dir_ / "bad_rays.csv").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("bad_rays.csv: line 3"), std::string::npos) << r.out;
  {
    std::ofstream bad(dir_ / "zero_dir.csv");
    bad << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,0\n";
  }
  r = run("query --cloud " + cloud + " --rays " + (dir_ / "zero_dir.csv").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("zero_dir.csv: line 2"), std::string::npos) << r.out;
  // The library's checks name the options, with plain numbers.
  r = run("query --cloud " + cloud + " --rays " + rays + " --t-min 2 --t-max 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: ray query: --t-min 2 must not exceed --t-max 1\n");
  r = run("query --cloud " + cloud + " --rays " + rays + " --radius -1.5");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: ray query: --radius must be >= 0, got -1.5\n");
  // --k is a whole number >= 1 (0 would return no hits; 1.5 is not a count).
  for (const char* k : {"0", "1.5"}) {
    r = run("query --cloud " + cloud + " --rays " + rays + " --k " + k);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.out, std::string("rayscan query: --k: expected an integer >= 1, got '") + k + "' (see --help)\n");
  }
  // --capacity with an index that has none is refused, not ignored.
  for (const char* index : {"octree-fixed", "brute"}) {
    r = run("query --cloud " + cloud + " --rays " + rays + " --k 1 --capacity 8 --index " + index);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.out, std::string("rayscan query: --capacity applies to --index octree-adaptive, octree-layered and "
                                 "kdtree only (got --index ") + index + ")\n");
  }
  // --insertion is a way to build an octree: refused with the other indexes (check_applicable).
  r = run("query --cloud " + cloud + " --rays " + rays + " --k 1 --insertion --index kdtree");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: --insertion applies to --index octree-adaptive, octree-layered and octree-fixed "
                   "only (got --index kdtree)\n");
  r = run("query --cloud " + cloud + " --rays " + rays + " --k 1 --index rtree");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("rtree"), std::string::npos) << r.out;
  r = run("query --cloud " + (dir_ / "missing.csv").string() + " --rays " + rays + " --k 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("missing.csv"), std::string::npos) << r.out;
  r = run("query --cloud " + cloud + " --rays " + rays + " --order sphere_hit");
  EXPECT_EQ(r.code, 2);  // sphere_hit needs --radius
  r = run("query --cloud " + cloud + " --rays " + rays + " --k -1");
  EXPECT_EQ(r.code, 2);
  r = run("query --cloud " + cloud + " --rays " + rays + " --index kdtree --depth 3");
  EXPECT_EQ(r.code, 2);  // --depth belongs to octree-fixed
  EXPECT_NE(r.out.find("--depth"), std::string::npos) << r.out;
  // A failed run leaves no output file behind.
  r = run("query --cloud " + cloud + " --rays " + (dir_ / "bad_rays.csv").string() + " --out " +
          (dir_ / "never.csv").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir_ / "never.csv"));
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(QueryCliHelp, ListsEveryOptionWithDefaults) {
  const RunResult r = run("query --help");
  EXPECT_EQ(r.code, 0);
  for (const char* opt : {"--cloud", "--rays", "--k", "--radius", "--t-min", "--t-max", "--order",
                          "--index", "--capacity", "--depth", "--insertion", "--out", "--quiet"})
    EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
}

}  // namespace
