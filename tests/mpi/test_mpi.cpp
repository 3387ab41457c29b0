// `mpirun -n N rayscan ...` end to end: images, per-point fields and query hits are
// the same bytes as a single-process run (the oracle: the file written by one process), for 2
// and 3 ranks and 1 or 2 threads; a rank that cannot open the index or dies ends the job with an
// error and no output. Loopback only: the shared-memory transport (btl self,vader), no network.
#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>
#include <string>

namespace fs = std::filesystem;

namespace {

using rayscan::test::run_command;
using rayscan::test::CommandResult;

const std::string kBin = RAYSCAN_BIN;

// mpirun on this machine only: shared memory between the ranks, no binding (so a rank may use
// more than one core), oversubscription allowed (3 ranks on 2 cores), root allowed in CI
// containers. `root_computes` = false forces every item through the messages (rank 0 serves only).
std::string mpirun(int n, bool root_computes = true) {
  std::string c = std::string(RAYSCAN_MPIEXEC) + " -n " + std::to_string(n) +
                  " --oversubscribe --bind-to none --mca btl self,vader --mca btl_vader_single_copy_mechanism none"
                  " -x RAYSCAN_MPI_TIMEOUT=60";
  if (::geteuid() == 0) c += " --allow-run-as-root";
  if (!root_computes) c += " -x RAYSCAN_MPI_ROOT_COMPUTES=0";
  return c + " ";
}

// Number of lines of `out` equal to `line`. mpirun forwards the ranks' stderr and prints its own
// MPI_ABORT banner; the two may interleave in either order, so the tests look for the line, once.
int lines_equal(const std::string& out, const std::string& line) {
  int n = 0;
  std::size_t a = 0;
  while (a < out.size()) {
    std::size_t b = out.find('\n', a);
    if (b == std::string::npos) b = out.size();
    n += out.compare(a, b - a, line) == 0;
    a = b + 1;
  }
  return n;
}

std::string bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// Byte-compares two files (both must exist and be non-empty).
void expect_same_file(const fs::path& a, const fs::path& b) {
  ASSERT_TRUE(fs::exists(a)) << a;
  ASSERT_TRUE(fs::exists(b)) << b;
  const std::string x = bytes(a), y = bytes(b);
  EXPECT_FALSE(x.empty()) << a;
  EXPECT_TRUE(x == y) << a << " and " << b << " differ (" << x.size() << " vs " << y.size() << " bytes)";
}

// The traffic line of a run under 2 ranks, "mpi: 2 ranks, M messages, B bytes (R bytes of results),
// ...": M and R (a worker's request and assignment per batch, and one more of each to start and end).
struct Traffic {
  unsigned long long messages = 0, result_bytes = 0;
};
Traffic traffic_of_two_ranks(const std::string& out) {
  Traffic t;
  unsigned long long total = 0;
  const std::size_t at = out.find("mpi: 2 ranks, ");
  EXPECT_NE(at, std::string::npos) << out;
  if (at != std::string::npos) {
    EXPECT_EQ(std::sscanf(out.c_str() + at, "mpi: 2 ranks, %llu messages, %llu bytes (%llu bytes", &t.messages, &total,
                          &t.result_bytes),
              3)
        << out;
  }
  return t;
}

class Mpi : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = rayscan::test::fresh_temp_dir("rayscan_mpi_" +
                                         std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::copy_file(fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las", dir_ / "autzen.las");
    // A 64 x 40 view of the autzen scene's overview camera, 2 spp (tiles of 16: 12 tiles).
    std::ofstream(dir_ / "scene.json") << R"({"cloud": "autzen.las", "radius": "auto", "material": {"color": "rgb"},
      "spp": 2, "seed": 7, "max_depth": 2, "output": {"image": "out.png"},
      "camera": {"width": 64, "height": 40, "position": [636300.0, 848450.0, 1050.0],
                 "look_at": [636600.0, 849230.0, 420.0], "vfov_deg": 42}})";
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Runs a command line in the test folder.
  CommandResult run(const std::string& cmd) const { return run_command("cd " + dir_.string() + " && " + cmd); }
  // Runs the rayscan command line `args` in one process (--out one.las), under 2 ranks with rank 0
  // computing nothing (two.las) and under 3 ranks (three.las), and expects the same bytes.
  void expect_same_las_on_any_ranks(const std::string& args) const {
    ASSERT_EQ(run(kBin + args + " --out one.las").code, 0);
    CommandResult r = run(mpirun(2, false) + kBin + args + " --out two.las");
    ASSERT_EQ(r.code, 0) << r.out;
    r = run(mpirun(3) + kBin + args + " --out three.las");
    ASSERT_EQ(r.code, 0) << r.out;
    expect_same_file(dir_ / "one.las", dir_ / "two.las");
    expect_same_file(dir_ / "one.las", dir_ / "three.las");
  }
  fs::path dir_;
};

TEST_F(Mpi, RenderImageAndAovsAreTheSameBytesForAnyRankAndThreadCount) {
  const std::string args = " render -q scene.json --aov depth --aov index --aov cost --aov normal";
  CommandResult r = run(kBin + args + " --out one.png");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(mpirun(2, false) + kBin + args + " --threads 1 --out two.png");  // every tile by rank 1
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(mpirun(3) + kBin + args + " --threads 2 --out three.png");
  ASSERT_EQ(r.code, 0) << r.out;
  expect_same_file(dir_ / "one.png", dir_ / "two.png");
  expect_same_file(dir_ / "one.aovs.exr", dir_ / "two.aovs.exr");
  expect_same_file(dir_ / "one.png", dir_ / "three.png");
  expect_same_file(dir_ / "one.aovs.exr", dir_ / "three.aovs.exr");
  // Only rank 0 writes: one line per file on stdout, no stray temporaries.
  EXPECT_EQ(r.out, "wrote three.png\nwrote three.aovs.exr\n");
}

TEST_F(Mpi, RenderReportsTheTrafficAndTheWorkersShare) {
  const CommandResult r = run(mpirun(2, false) + kBin + " render scene.json --threads 1 --out two.png");
  ASSERT_EQ(r.code, 0) << r.out;
  // 64 x 40 px beauty = 12 bytes per pixel of results, all from rank 1; rank 0 rendered none.
  EXPECT_NE(r.out.find("mpi: 2 ranks"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(30720 bytes of results), rank 0 computed 0 items"), std::string::npos) << r.out;
}

TEST_F(Mpi, FramesFromAnIndexFileAreTheSameBytesWholeFramesOrTiles) {
  ASSERT_EQ(run(kBin + " index -q autzen.las -o site.rsi --attributes rgb").code, 0);
  std::ofstream(dir_ / "scene_rsi.json") << R"({"cloud": "site.rsi", "radius": 1.5, "material": {"color": "rgb"},
      "spp": 1, "seed": 3, "max_depth": 2, "output": {"image": "f.png"},
      "camera": {"width": 8, "height": 8, "position": [636300, 848450, 1050], "look_at": [636600, 849230, 420]}})";
  std::ofstream(dir_ / "cams.json") << R"([
      {"width": 40, "height": 24, "position": [636300, 848450, 1050], "look_at": [636600, 849230, 420]},
      {"width": 40, "height": 24, "position": [636400, 848450, 1000], "look_at": [636600, 849230, 420]},
      {"width": 40, "height": 24, "position": [636500, 848450, 950], "look_at": [636600, 849230, 420]},
      {"width": 40, "height": 24, "position": [636600, 848450, 900], "look_at": [636600, 849230, 420]}])";
  const std::string args = " render -q scene_rsi.json --frames cams.json --aov index";
  ASSERT_EQ(run(kBin + args + " --out one.png").code, 0);
  // 4 frames > 3 ranks: whole frames are the work items; 4 frames on 4 ranks: tiles per frame.
  CommandResult r = run(mpirun(3, false) + kBin + args + " --threads 1 --out three.png");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(mpirun(4, false) + kBin + args + " --threads 1 --out four.png");
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 0; f < 4; ++f) {
    const std::string k = "_000" + std::to_string(f);
    expect_same_file(dir_ / ("one" + k + ".png"), dir_ / ("three" + k + ".png"));
    expect_same_file(dir_ / ("one" + k + ".aovs.exr"), dir_ / ("three" + k + ".aovs.exr"));
    expect_same_file(dir_ / ("one" + k + ".png"), dir_ / ("four" + k + ".png"));
  }
}

TEST_F(Mpi, VisibilityFieldsAreTheSameBytes) {
  // 1438 points of autzen (3 chunks of 512 points), so the runs stay short.
  fs::copy_file(fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz", dir_ / "subset.xyz");
  std::ofstream(dir_ / "cam.json") << R"({"width": 48, "height": 32, "position": [636540, 849150, 480],
      "look_at": [636590, 849216, 420]})";
  const std::string args =
      " visibility -q subset.xyz --observer 636580,849200 --observer 636600,849230 --height 2 --distance"
      " --sky-view 16 --from-camera cam.json --threads 1";
  expect_same_las_on_any_ranks(args);
  // Per-observer counts are summed over the ranks: the printed summary is the same too.
  EXPECT_EQ(run(kBin + args + " --out one.las | head -2").out, run(mpirun(2, false) + kBin + args + " --out two.las | head -2").out);
}

TEST_F(Mpi, SolarFieldsAndShadowFramesAreTheSameBytes) {
  // 1438 points of autzen (3 chunks of 512 points); the site's latitude and longitude given, as
  // the text file has no CRS.
  fs::copy_file(fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz", dir_ / "subset.xyz");
  const std::string site = " solar -q subset.xyz --lat 44.05 --lon -123.07 --radius 1.5 --threads 1";
  const std::string period = site + " --start 2026-06-01 --end 2026-06-03 --sector 5 --sky-rays 16 --monthly";
  expect_same_las_on_any_ranks(period);
  // A day's shadow frames and the per-point sun and shadow hours.
  const std::string day = site + " --day 2026-06-21 --every 3h --cell 4";
  ASSERT_EQ(run(kBin + day + " --out d1.las --raster d1.tif").code, 0);
  const CommandResult r = run(mpirun(2, false) + kBin + day + " --out d2.las --raster d2.tif");
  ASSERT_EQ(r.code, 0) << r.out;
  expect_same_file(dir_ / "d1.las", dir_ / "d2.las");
  int frames = 0;
  for (const auto& e : fs::directory_iterator(dir_)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("d1_", 0) != 0 || e.path().extension() != ".tif") continue;
    ++frames;
    expect_same_file(e.path(), dir_ / ("d2_" + name.substr(3)));
  }
  EXPECT_GE(frames, 4);
}

TEST_F(Mpi, QueryHitsAreTheSameBytes) {
  ASSERT_EQ(run(kBin + " index -q autzen.las -o site.rsi").code, 0);
  {
    std::ofstream rays(dir_ / "rays.csv");
    rays << "ox,oy,oz,dx,dy,dz\n";
    for (int i = 0; i < 700; ++i)  // a grid of slanted rays from above the site: 3 blocks of 256
      rays << 636010 + (i % 35) * 33 << ',' << 848940 + (i / 35) * 27 << ",600," << (i % 7 - 3) * 0.05 << ','
           << (i % 5 - 2) * 0.05 << ",-1\n";
  }
  const std::string args = " query --cloud site.rsi --rays rays.csv --k 2 --radius 1.5 --order sphere_hit --threads 1";
  ASSERT_EQ(run(kBin + args + " --out one.csv").code, 0);
  const CommandResult r = run(mpirun(3, false) + kBin + args + " --out three.csv");
  ASSERT_EQ(r.code, 0) << r.out;
  expect_same_file(dir_ / "one.csv", dir_ / "three.csv");
  EXPECT_GT(bytes(dir_ / "one.csv").size(), 20000u);  // hits were found (not just a header)
  // Batches of 2 blocks (--threads 2): a worker's batch of blocks 2.. (rays 512..699, the last
  // block short) is held from its own first ray, not from ray 0.
  std::string batches = args;
  batches.replace(batches.find("--threads 1"), 11, "--threads 2");
  const CommandResult two = run(mpirun(3, false) + kBin + batches + " --out batches.csv");
  ASSERT_EQ(two.code, 0) << two.out;
  expect_same_file(dir_ / "one.csv", dir_ / "batches.csv");
}

TEST_F(Mpi, QueryOfACopcFileIsTheSameBytes) {
  // A COPC file is not shared out over the ranks: rank 0 answers every ray, the others nothing.
  ASSERT_EQ(run(kBin + " translate -q autzen.las site.copc.laz").code, 0);
  {
    std::ofstream rays(dir_ / "rays.csv");
    rays << "ox,oy,oz,dx,dy,dz\n";
    for (int i = 0; i < 300; ++i)
      rays << 636010 + (i % 20) * 50 << ',' << 848940 + (i / 20) * 40 << ",600,0.05,-0.05,-1\n";
  }
  const std::string args = " query --cloud site.copc.laz --rays rays.csv --k 2 --radius 1.5 --order sphere_hit --threads 1";
  ASSERT_EQ(run(kBin + args + " --out one.csv").code, 0);
  const CommandResult r = run(mpirun(2) + kBin + args + " --out two.csv");
  ASSERT_EQ(r.code, 0) << r.out;
  expect_same_file(dir_ / "one.csv", dir_ / "two.csv");
  EXPECT_GT(bytes(dir_ / "one.csv").size(), 5000u);  // hits were found (not just a header)
}

TEST_F(Mpi, QueryAllSendsRunsOfAboutSixteenThousandResultsAndTheSameBytes) {
  // --all on 1438 points: every ray returns every point. A reply per block of 256 rays would carry
  // 256 x 1438 hits (11.8 MB; past ~262,000 points more than MPI's 2 GiB message); the queue's
  // item is instead the run of about 16,384 results by the bound (docs/mpi.md): 11 rays of 1438.
  fs::copy_file(fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz", dir_ / "subset.xyz");
  std::uint64_t points = 0;
  {
    std::ifstream in(dir_ / "subset.xyz");
    for (std::string line; std::getline(in, line);) points += !line.empty();
    --points;  // the header "x y z"
  }
  const std::uint64_t rays = 300;  // a block of 256 and a short one of 44
  {
    std::ofstream out(dir_ / "rays.csv");
    out << "ox,oy,oz,dx,dy,dz\n";
    for (std::uint64_t i = 0; i < rays; ++i) out << 636560 + i % 20 * 3 << ',' << 849200 + i / 20 * 3 << ",600,0,0,-1\n";
  }
  const std::string args = " query --cloud subset.xyz --rays rays.csv --all";
  ASSERT_EQ(run(kBin + args + " -q --out one.csv").code, 0);
  // Rank 0 computes nothing and rank 1 asks for one run at a time: every run is one reply.
  const CommandResult two = run(mpirun(2, false) + kBin + args + " --threads 1 --out two.csv");
  ASSERT_EQ(two.code, 0) << two.out;
  expect_same_file(dir_ / "one.csv", dir_ / "two.csv");
  // The oracle of the rows: every point on every ray, and the header.
  const std::string csv = bytes(dir_ / "one.csv");
  EXPECT_EQ(std::uint64_t(std::count(csv.begin(), csv.end(), '\n')), rays * points + 1);
  // A request and an assignment per run; the results: per ray its count (8 B) and its hits (32 B).
  const auto [messages, results] = traffic_of_two_ranks(two.out);
  EXPECT_EQ(results, rays * 8 + rays * points * 32);
  const unsigned long long runs = messages / 2 - 1;
  const std::uint64_t rays_per_run = 16384 / points;  // 11
  EXPECT_GE(runs, (rays + rays_per_run - 1) / rays_per_run) << two.out;  // not 2 blocks: at most 11 rays a reply
  EXPECT_LE(results / runs, rays_per_run * (8 + points * 32)) << two.out;
  // Batches of 2 runs over 3 ranks (the root computing none).
  const CommandResult three = run(mpirun(3, false) + kBin + args + " -q --threads 2 --out three.csv");
  ASSERT_EQ(three.code, 0) << three.out;
  expect_same_file(dir_ / "one.csv", dir_ / "three.csv");
}

TEST_F(Mpi, QueryByRadiusSendsWholeBlocksOfRaysAndTheSameBytes) {
  // A 120 x 120 grid of points 1 apart on z = 0. Without --k a ray's bound is every point (14,400:
  // runs of one ray); with --radius 2.5 a vertical ray returns the ~20 points of a disc, as the
  // query's sample of rays shows, so a run is a whole block of 256 rays. Rays 1 to 3 (not among the
  // 64 sampled, rays j x 700 / 64) lie in the plane and return 5 rows of points each: more than the
  // sample's most, so their block's run is longer; its answers are the same.
  {
    std::ofstream out(dir_ / "grid.xyz");
    out << "x y z\n";
    for (int y = 0; y < 120; ++y)
      for (int x = 0; x < 120; ++x) out << x << ' ' << y << " 0\n";
  }
  const std::uint64_t rays = 700;  // blocks of 256, 256 and 188
  const double radius = 2.5;
  std::uint64_t expected_rows = 0;  // the oracle: the grid points within the radius of each ray, by brute force
  {
    std::ofstream out(dir_ / "rays.csv");
    out << "ox,oy,oz,dx,dy,dz\n";
    for (std::uint64_t i = 0; i < rays; ++i) {
      // Origins in sixteenths (exact in binary and in the CSV's 6 digits, so that the squared
      // distances below are exact, as the query's are).
      const bool flat = i >= 1 && i <= 3;
      const double ox = flat ? -10.0 : 5.125 + double(i % 35) * 3.0625;
      const double oy = flat ? 30.0 * double(i) + 0.25 : 5.375 + double(i / 35) * 5.25;
      out << ox << ',' << oy << (flat ? ",0,1,0,0\n" : ",10,0,0,-1\n");
      for (int y = 0; y < 120; ++y)
        for (int x = 0; x < 120; ++x) {
          // Distance to the ray's line: across it in the plane (flat: along x) or to the vertical
          // through (ox, oy).
          const double dx = flat ? 0.0 : x - ox, dy = y - oy;
          expected_rows += dx * dx + dy * dy <= radius * radius;
        }
    }
  }
  const std::string args = " query --cloud grid.xyz --rays rays.csv --radius 2.5";
  ASSERT_EQ(run(kBin + args + " -q --out one.csv").code, 0);
  const std::string csv = bytes(dir_ / "one.csv");
  EXPECT_EQ(std::uint64_t(std::count(csv.begin(), csv.end(), '\n')), expected_rows + 1);
  EXPECT_GT(expected_rows, 3 * 5 * 120u);
  // Rank 0 computes nothing and rank 1 asks for one run at a time: a reply per block, not per ray.
  const CommandResult two = run(mpirun(2, false) + kBin + args + " --threads 1 --out two.csv");
  ASSERT_EQ(two.code, 0) << two.out;
  expect_same_file(dir_ / "one.csv", dir_ / "two.csv");
  const auto [messages, results] = traffic_of_two_ranks(two.out);
  EXPECT_EQ(messages / 2 - 1, (rays + 255) / 256) << two.out;
  EXPECT_EQ(results, rays * 8 + expected_rows * 32) << two.out;
  // Batches of 2 runs over 3 ranks (the root computing none).
  const CommandResult three = run(mpirun(3, false) + kBin + args + " -q --threads 2 --out three.csv");
  ASSERT_EQ(three.code, 0) << three.out;
  expect_same_file(dir_ / "one.csv", dir_ / "three.csv");
}

TEST_F(Mpi, ARankThatCannotOpenTheIndexEndsTheJobWithOneLineAndNoOutput) {
  // Two "nodes": rank 1's folder lacks the index file (a shared file system not mounted there).
  ASSERT_EQ(run(kBin + " index -q autzen.las -o site.rsi").code, 0);
  fs::create_directories(dir_ / "a");
  fs::create_directories(dir_ / "b");
  fs::rename(dir_ / "site.rsi", dir_ / "a" / "site.rsi");
  for (const char* d : {"a", "b"})
    std::ofstream(dir_ / d / "s.json") << R"({"cloud": "site.rsi", "radius": 1.5, "spp": 1, "material": {"color": [0.5, 0.5, 0.5]},
        "camera": {"width": 32, "height": 24, "position": [636300, 848450, 1050], "look_at": [636600, 849230, 420]}})";
  const fs::path out = dir_ / "never.png";
  std::string m = mpirun(1);  // MPMD: -n 1 ... : -n 1 ...
  const std::string cmd = m + "-wdir " + (dir_ / "a").string() + " " + kBin + " render -q s.json --out " + out.string() +
                          " : -n 1 -wdir " + (dir_ / "b").string() + " " + kBin + " render -q s.json --out " + out.string();
  const CommandResult r = run(cmd);
  EXPECT_EQ(r.code, 2) << r.out;
  // The scene's relative cloud path is resolved against the scene file's folder (rank 1's "b").
  EXPECT_EQ(lines_equal(r.out, "rayscan render: " + (dir_ / "b" / "site.rsi").string() +
                                   ": cannot open file: No such file or directory (rank 1 of 2)"),
            1)
      << r.out;
  EXPECT_EQ(r.out.find("rayscan render:"), r.out.rfind("rayscan render:")) << r.out;  // one line of ours
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(dir_)) EXPECT_EQ(e.path().filename().string().find(".never"), std::string::npos);
}

TEST_F(Mpi, AnAbortedJobLeavesNoFileInTheOutputFolder) {
  // Two "nodes" again, rank 1's folder without the cloud. Rank 0 opens the query's CSV output (its
  // temporary, ".hits.csv.tmp.<pid>") before the rays are shared out; rank 1's fail message then
  // ends the job by MPI_Abort, which skips the unwinding that removes the temporary, so the abort
  // path itself must remove it. The oracle: the output folder, empty before, is empty after.
  fs::create_directories(dir_ / "a");
  fs::create_directories(dir_ / "b");
  fs::create_directories(dir_ / "out");
  fs::rename(dir_ / "autzen.las", dir_ / "a" / "autzen.las");
  for (const char* d : {"a", "b"}) {
    std::ofstream rays(dir_ / d / "rays.csv");
    rays << "ox,oy,oz,dx,dy,dz\n";
    for (int i = 0; i < 300; ++i) rays << 636010 + (i % 20) * 50 << ',' << 848940 + (i / 20) * 40 << ",600,0,0,-1\n";
  }
  const fs::path out = dir_ / "out" / "hits.csv";
  const std::string args = " query -q --cloud autzen.las --rays rays.csv --k 1 --radius 1.5 --out " + out.string();
  const std::string cmd = mpirun(1) + "-wdir " + (dir_ / "a").string() + " " + kBin + args + " : -n 1 -wdir " +
                          (dir_ / "b").string() + " " + kBin + args;
  const CommandResult r = run(cmd);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_equal(r.out, "rayscan query: autzen.las: cannot open file: No such file or directory (rank 1 of 2)"), 1)
      << r.out;
  EXPECT_EQ(r.out.find("rayscan query:"), r.out.rfind("rayscan query:")) << r.out;  // one line of ours
  for (const auto& e : fs::directory_iterator(dir_ / "out")) ADD_FAILURE() << "left behind: " << e.path();
}

TEST_F(Mpi, ARankThatDiesEndsTheJobWithoutOutputAndWithoutHanging) {
  const fs::path out = dir_ / "never.png";
  const CommandResult r = run(mpirun(1) + kBin + " render -q scene.json --out " + out.string() + " : -n 1 sh -c 'kill -9 $$'");
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(Mpi, ASilentRankEndsTheJobAfterTheTimeout) {
  // Rank 1 is a hung rank: the same job at 65536 samples per pixel, stopped (SIGSTOP, by GNU
  // timeout, which continues and ends it when mpirun ends the job) one second in, whatever the
  // machine's speed, long before it could have rendered its tiles; rank 0 (a dedicated master
  // here) waits RAYSCAN_MPI_TIMEOUT = 2 s for the results.
  const fs::path out = dir_ / "never.png";
  std::string m = mpirun(1, false);
  m.replace(m.find("RAYSCAN_MPI_TIMEOUT=60"), 22, "RAYSCAN_MPI_TIMEOUT=2");
  const CommandResult r = run(m + kBin + " render -q scene.json --out " + out.string() + " : -n 1 timeout -s STOP 1 " +
                              kBin + " render -q scene.json --spp 65536 --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_equal(r.out, "rayscan render: rank 1 of 2 sent nothing for 2 s while owing work-queue results "
                                "(dead, hung, or slower than RAYSCAN_MPI_TIMEOUT)"),
            1)
      << r.out;
  EXPECT_FALSE(fs::exists(out));
}

// Help, version and usage errors: every rank parses the same command line, but only rank 0 prints,
// once, exactly what a single process prints; every rank ends with the same code (no MPI_Abort).
// The oracle is the same binary run alone.
TEST_F(Mpi, HelpAndUsageErrorsArePrintedOnceByRankZero) {
  // (Each mpirun start costs seconds on a loaded machine: one launch per case.)
  for (const auto& [args, n] : {std::pair<std::string, int>{" --help", 3}, {" render --help", 2}}) {
    const CommandResult one = rayscan::test::run_command(kBin + args, false);
    ASSERT_EQ(one.code, 0) << args;
    ASSERT_FALSE(one.out.empty()) << args;
    const CommandResult r = rayscan::test::run_command(mpirun(n) + kBin + args);  // stdout + stderr
    EXPECT_EQ(r.code, 0) << args << " -n " << n << "\n" << r.out;
    EXPECT_EQ(r.out, one.out) << args << " -n " << n;
  }
  const std::string bad = " render scene.json --no-such-option";
  const CommandResult one = run(kBin + bad);
  ASSERT_EQ(one.code, 2);
  ASSERT_EQ(std::count(one.out.begin(), one.out.end(), '\n'), 1) << one.out;
  const std::string line = one.out.substr(0, one.out.size() - 1);
  EXPECT_EQ(line.rfind("rayscan render: ", 0), 0u) << line;
  {
    const CommandResult r = run(mpirun(3) + kBin + bad);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(lines_equal(r.out, line), 1) << r.out;
    EXPECT_EQ(r.out.find("rayscan"), r.out.rfind("rayscan render:")) << r.out;  // nothing else of ours
    EXPECT_EQ(r.out.find("MPI_ABORT"), std::string::npos) << r.out;           // a clean end, not an abort
  }
  // Different arguments per rank (MPMD): rank 1's usage error ends the job; rank 0 prints it.
  const CommandResult r = run(mpirun(1) + kBin + " render -q scene.json --out never.png : -n 1 " + kBin + bad);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_equal(r.out, line + " (rank 1 of 2)"), 1) << r.out;
  EXPECT_FALSE(fs::exists(dir_ / "never.png"));
}

TEST_F(Mpi, CommandsThatCannotBeDistributedAreRefused) {
  const CommandResult r = run(mpirun(2) + kBin + " info autzen.las");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_equal(r.out, "rayscan info: runs in one process; only render, visibility, solar and query run under "
                                "mpirun -n 2 (run 'rayscan info' without mpirun or with -n 1)"),
            1)
      << r.out;
}

}  // namespace
