// The CLI's spelling of the index, translate and db import jobs' option errors: the messages the
// command line printed before these jobs moved into the library, byte for byte.
#include <gtest/gtest.h>

#include "../common/run_command.hpp"
#include "jobs_test_util.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using rayscan::test::data_file;
using rayscan::test::run_command;
using rayscan::test::quoted;
using rayscan::test::rayscan_cli;
using rayscan::test::temp_dir;

TEST(JobCli, IndexErrorsAsBefore) {
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string idx = (temp_dir() / "x.idx").string();
  auto r = rayscan_cli("index -q " + las + " -o '" + idx + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: " + idx + ": the index file name must end in .rsi (or .copc.laz for a COPC file)\n");
  const std::string rsi = (temp_dir() / "x.rsi").string();
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --memory 10Q");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: --memory: size '10Q': expected a positive number with an optional K, M, G or T suffix\n");
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --attributes colour");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out,
            "rayscan index: --attributes 'colour': expected rgb, intensity, classification, gps_time, id, all or none\n");
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --layout layered");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: --layout: expected adaptive or fixed, got 'layered' (see --help)\n");
}

// Options the chosen layout does not use are refused, not ignored (as query refuses --depth
// without --index octree-fixed); an input given twice, however spelled, is refused; the octree's
// own checks name the option. Each is one line and exit code 2, and no index is written.
TEST(JobCli, IndexRefusesOptionsItsLayoutIgnoresAndDuplicateInputs) {
  const std::filesystem::path las = data_file("las/point-color.las");
  const std::filesystem::path rsi = temp_dir() / "refused.rsi";
  const std::string base = "index -q " + quoted(las) + " -o " + quoted(rsi) + " ";
  const std::pair<std::string, std::string> cases[] = {
      {"--depth 3", "--depth applies to --layout fixed only (got --layout adaptive)"},
      {"--layout fixed --capacity 8", "--capacity applies to --layout adaptive only (got --layout fixed)"},
      {"--layout fixed --max-depth 8", "--max-depth applies to --layout adaptive only (got --layout fixed)"},
      {"--capacity 0", "--capacity: expected an integer in [1, 4294967295], got '0' (see --help)"},
      {"--capacity 1.5", "--capacity: expected an integer in [1, 4294967295], got '1.5' (see --help)"},
  };
  for (const auto& [args, message] : cases) {
    const auto r = rayscan_cli(base + args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_EQ(r.out, "rayscan index: " + message + "\n") << args;
    EXPECT_FALSE(std::filesystem::exists(rsi)) << args;
  }
  const std::filesystem::path copc = temp_dir() / "refused.copc.laz";
  auto r = rayscan_cli("index -q " + quoted(las) + " -o " + quoted(copc) + " --capacity 8");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: --capacity applies to an index file (.rsi), not to a COPC output (.copc.laz)\n");
  // The same file twice: by the same name and by another spelling of it.
  const std::filesystem::path again = las.parent_path() / "." / las.filename();
  r = rayscan_cli("index -q " + quoted(las) + " " + quoted(again) + " -o " + quoted(rsi));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: " + again.string() + ": the same file as input 1 ('" + las.string() +
                       "'): give each input file once\n");
  EXPECT_FALSE(std::filesystem::exists(rsi));
  // The fixed layout takes --depth.
  r = rayscan_cli(base + "--layout fixed --depth 3");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("depth 3"), std::string::npos) << r.out;
}

TEST(JobCli, DbImportErrorsAsBefore) {
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string out = quoted(temp_dir() / "x.sqlite");
  auto r = rayscan_cli("db import " + las);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: give exactly one of -o FILE.sqlite and --postgres CONNINFO\n");
  r = rayscan_cli("db import " + las + " -o " + out + " --memory 10Q");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --memory: size '10Q': expected a positive number with an optional K, M, G or T suffix\n");
  r = rayscan_cli("db import " + las + " -o " + out + " --pcpatch");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --pcpatch needs --postgres CONNINFO\n");
}

// Every command that writes one output file names it with -o or --out (index also --output), as
// its help says: `render CLOUD -o IMG.png` and `index CLOUD --out SITE.rsi` write their files.
TEST(JobCli, EveryCommandThatWritesAFileTakesDashOAndDashDashOut) {
  for (const char* command : {"render", "query", "index", "visibility", "solar", "db import"}) {
    const auto help = rayscan_cli(std::string(command) + " --help");
    ASSERT_EQ(help.code, 0) << command;
    EXPECT_NE(help.out.find("  -o,--out"), std::string::npos) << command << ":\n" << help.out;
  }
  const std::filesystem::path las = data_file("las/autzen_trim.las");
  const std::filesystem::path dir = temp_dir() / "dash_o";
  std::filesystem::create_directories(dir);
  auto r = rayscan_cli("render " + quoted(las) + " -q --spp 1 --width 40 -o " + quoted(dir / "q.png"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "q.png"));
  for (const char* flag : {"-o", "--out", "--output"}) {
    const std::filesystem::path rsi = dir / (std::string("i") + std::to_string(std::string(flag).size()) + ".rsi");
    r = rayscan_cli("index -q " + quoted(las) + " " + flag + " " + quoted(rsi));
    EXPECT_EQ(r.code, 0) << flag << ": " << r.out;
    EXPECT_TRUE(std::filesystem::is_regular_file(rsi)) << flag;
  }
  std::filesystem::remove_all(dir);
}

// An index file works wherever a point cloud path is accepted: `render a.rsi` is the quick look of
// its points (it was read as a scene: "invalid JSON"), and a scene whose "cloud" is the index and
// which has no camera gets the overview camera (it was "unknown point cloud extension"). Oracle:
// the quick look of the LAS file the index was built from, whose camera (from the same exact
// bounds) and material must be the same.
TEST(JobCli, IndexFileIsAcceptedWhereverACloudIs) {
  const std::filesystem::path las = data_file("las/autzen_trim.las");
  const std::filesystem::path dir = temp_dir() / "render_rsi";
  std::filesystem::create_directories(dir);
  const std::filesystem::path rsi = dir / "a.rsi";
  ASSERT_EQ(rayscan_cli("index -q " + quoted(las) + " -o " + quoted(rsi) + " --attributes rgb").code, 0);
  const auto from_las = rayscan_cli("render " + quoted(las) + " --print-scene");
  const auto from_rsi = rayscan_cli("render " + quoted(rsi) + " --print-scene");
  ASSERT_EQ(from_las.code, 0) << from_las.out;
  ASSERT_EQ(from_rsi.code, 0) << from_rsi.out;
  const auto a = nlohmann::json::parse(from_las.out), b = nlohmann::json::parse(from_rsi.out);
  // The overview camera frames a sample of the points chosen by their coordinates alone, the same
  // from the LAS file's order and the index's Morton order: the same camera, to the bit.
  EXPECT_EQ(a["camera"], b["camera"]);
  EXPECT_EQ(a["up"], b["up"]);
  EXPECT_EQ(a["material"], b["material"]);
  EXPECT_EQ(b["cloud"], rsi.lexically_normal().string());
  {
    std::ofstream s(dir / "scene.json");
    s << nlohmann::json{{"cloud", "a.rsi"}, {"output", {{"image", "r.png"}}}}.dump();
  }
  const auto scene = rayscan_cli("render " + quoted(dir / "scene.json") + " --print-scene");
  ASSERT_EQ(scene.code, 0) << scene.out;
  EXPECT_EQ(nlohmann::json::parse(scene.out)["camera"], b["camera"]);
  const auto r = rayscan_cli("render " + quoted(rsi) + " -q --spp 1 --width 60 --out " + quoted(dir / "q.png"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "q.png"));
  std::filesystem::remove_all(dir);
}

// `rayscan version --json`: the project's version (CMake's, the oracle), the commit of the checkout
// it was built from (a commit of the checkout, by git, when the tests run in one), the SIMD line of
// `--version`, and each library's version; `--version` carries the same version.
TEST(JobCli, VersionReportsTheProjectVersionCommitAndLibraries) {
  const auto r = rayscan_cli("version --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["version"], RAYSCAN_PROJECT_VERSION);
  // The reported commit is one of this checkout's (git's own answer; HEAD may have moved on since
  // the build, so its existence is checked, not equality with HEAD).
  const auto git = run_command("git -C " + quoted(RAYSCAN_SOURCE_DIR) + " rev-parse --short=12 HEAD", false);
  if (git.code == 0 && git.out.size() > 1) {
    const std::string commit = j["git_commit"].get<std::string>().substr(0, 12);
    EXPECT_EQ(run_command("git -C " + quoted(RAYSCAN_SOURCE_DIR) + " cat-file -e " + commit + "^{commit}", false).code, 0)
        << r.out;
  }
  for (const char* lib : {"tbb", "gdal", "sqlite", "nlohmann_json"})
    EXPECT_FALSE(j["libraries"][lib].get<std::string>().empty()) << lib;
  const auto v = rayscan_cli("--version");
  EXPECT_EQ(v.code, 0);
  EXPECT_EQ(v.out.rfind(std::string("rayscan ") + RAYSCAN_PROJECT_VERSION + ", ", 0), 0u) << v.out;
  EXPECT_NE(v.out.find(j["simd"].get<std::string>()), std::string::npos) << v.out;
}

// `rayscan index` with standard error in a log file (not a terminal): plain progress lines, no
// carriage return (the status line redrawn with \r made one 35 KB line of a 2e8-point build's
// log), each line a complete "index: <phase> ..." line, and the summary on standard output. A
// phase's line is written when it ends, at 100% of the points it processed (the points of the
// file: 110000), once per phase; a phase the build skips ("scan": the header gives the grid) has
// none.
TEST(JobCli, IndexProgressIntoALogFileIsOneLinePerPhaseAtItsEnd) {
  const std::filesystem::path dir = temp_dir() / "index_phases";
  std::filesystem::create_directories(dir);
  const std::filesystem::path log = dir / "err.log";
  std::string cmd = "(";
  cmd.append(quoted(RAYSCAN_BIN)).append(" index ").append(quoted(data_file("las/autzen_trim.las")));
  cmd.append(" -o ").append(quoted(dir / "a.rsi")).append(" --memory 1M 2> ").append(quoted(log)).append(")");
  const auto r = run_command(cmd, false);
  ASSERT_EQ(r.code, 0) << r.out;
  std::istringstream lines(rayscan::test::file_bytes(log));
  std::vector<std::string> phases;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string command, phase, percent;
    words >> command >> phase >> percent;
    EXPECT_EQ(command, "index:") << line;
    EXPECT_EQ(percent, "100.0%") << line;
    if (phase != "spacing") {
      EXPECT_NE(line.find("  110000 / 110000 points"), std::string::npos) << line;
    }
    phases.push_back(phase);
  }
  // Each phase once, in the build's order (a several-run build: read, merge, then the nodes when
  // they are not built during the merge, spacing, done); never "scan".
  ASSERT_GE(phases.size(), 4u);
  EXPECT_EQ(phases.front(), "read");
  EXPECT_EQ(phases[1], "merge");
  EXPECT_EQ(phases.back(), "done");
  for (std::size_t i = 0; i < phases.size(); ++i)
    for (std::size_t j = i + 1; j < phases.size(); ++j) EXPECT_NE(phases[i], phases[j]);
  EXPECT_EQ(std::count(phases.begin(), phases.end(), "scan"), 0);
  std::filesystem::remove_all(dir);
}

TEST(JobCli, IndexProgressIntoALogFileIsPlainLines) {
  const std::filesystem::path dir = temp_dir() / "index_log";
  std::filesystem::create_directories(dir);
  const std::filesystem::path log = dir / "err.log";
  // In a subshell, so that run_command's own redirection of standard error applies outside it.
  std::string cmd = "(";
  cmd.append(quoted(RAYSCAN_BIN)).append(" index ").append(quoted(data_file("las/autzen_trim.las")));
  cmd.append(" -o ").append(quoted(dir / "a.rsi")).append(" 2> ").append(quoted(log)).append(")");
  const auto r = run_command(cmd, false);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("110000 points"), std::string::npos) << r.out;
  const std::string text = rayscan::test::file_bytes(log);
  EXPECT_FALSE(text.empty());  // the build reports at least once
  EXPECT_EQ(text.find('\r'), std::string::npos) << text;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) EXPECT_EQ(line.rfind("index: ", 0), 0u) << line;
  std::filesystem::remove_all(dir);
}

// The other long jobs report the same way into a log file: `translate` LAS -> LAZ ("translate:
// encode ... 100.0%"), `db import` (the temporary index's phases, then "insert"), `render` and
// `visibility` (Progress: "progress: N/N ... done in"): plain lines, never a carriage return, the
// last one at 100%; the surfel estimate of both counts the cloud's 110000 points ("surfels").
TEST(JobCli, TranslateDbImportRenderAndVisibilityProgressIntoALogFileIsPlainLines) {
  const std::filesystem::path dir = temp_dir() / "jobs_log";
  std::filesystem::create_directories(dir);
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::filesystem::path log = dir / "err.log";
  auto logged = [&](const std::string& args) {
    std::string cmd = "(";  // appended, not concatenated: GCC 12's -Wrestrict false positive on operator+
    cmd.append(quoted(RAYSCAN_BIN)).append(" ").append(args).append(" 2> ").append(quoted(log)).append(")");
    const auto r = run_command(cmd, false);
    EXPECT_EQ(r.code, 0) << args << "\n" << r.out;
    const std::string text = rayscan::test::file_bytes(log);
    EXPECT_EQ(text.find('\r'), std::string::npos) << text;
    return text;
  };
  const std::string tr = logged("translate " + las + " " + quoted(dir / "a.laz"));
  EXPECT_NE(tr.find("translate: encode  100.0%  110000 / 110000 points"), std::string::npos) << tr;
  const std::string db = logged("db import " + las + " -o " + quoted(dir / "a.sqlite"));
  EXPECT_NE(db.find("db import: read"), std::string::npos) << db;
  EXPECT_NE(db.find("db import: insert  100.0%  110000 / 110000 points"), std::string::npos) << db;
  const std::string render = logged("render " + las + " --width 60 --spp 1 --out " + quoted(dir / "a.png"));
  EXPECT_NE(render.find("progress: "), std::string::npos) << render;
  EXPECT_NE(render.find(" 100.0%"), std::string::npos) << render;
  EXPECT_NE(render.find("done in"), std::string::npos) << render;
  const std::string surfels = "progress: 110000/110000 points (surfels) 100.0%";
  EXPECT_NE(render.find(surfels), std::string::npos) << render;
  const std::string vis = logged("visibility " + las + " --observer 636226.5,849106.5 --height 6 -o " + quoted(dir / "v.las"));
  EXPECT_NE(vis.find("progress: "), std::string::npos) << vis;
  EXPECT_NE(vis.find("done in"), std::string::npos) << vis;
  EXPECT_NE(vis.find(surfels), std::string::npos) << vis;
  // -q: nothing on standard error.
  EXPECT_EQ(logged("translate -q " + las + " " + quoted(dir / "b.laz")), "");
  std::filesystem::remove_all(dir);
}

// `query --out` writes CSV, so a name promising another format is refused before the queries
// (it received CSV text); a .csv name and standard output work. Oracle: the file's bytes.
// On a terminal (a pseudo-terminal from Python's pty module) the phases' status line is redrawn
// with \r; a phase's report at its start says it runs instead of "0.0%": db import's "index" (the
// SQL indexes and the commit, which report nothing until they end) reads "index  running, 110000
// points" (the points of the file), and no report shows 0.0%. The last report is "done" at 100%.
TEST(JobCli, DbImportOnATerminalSaysAPhaseRunsInsteadOfZeroPercent) {
  const std::filesystem::path dir = temp_dir() / "db_import_tty";
  std::filesystem::create_directories(dir);
  {
    // Runs argv[1:] on a pseudo-terminal and prints what it wrote; exit 77 without a pty.
    std::ofstream py(dir / "on_pty.py");
    py << "import os, pty, sys\n"
          "try:\n    pid, fd = pty.fork()\nexcept OSError:\n    sys.exit(77)\n"
          "if pid == 0:\n    os.execv(sys.argv[1], sys.argv[1:])\n"
          "out = b''\nwhile True:\n    try:\n        d = os.read(fd, 65536)\n    except OSError:\n        break\n"
          "    if not d:\n        break\n    out += d\n"
          "_, st = os.waitpid(pid, 0)\nsys.stdout.buffer.write(out)\nsys.exit(os.waitstatus_to_exitcode(st))\n";
  }
  const auto r = run_command("python3 " + quoted(dir / "on_pty.py") + " " + quoted(RAYSCAN_BIN) + " db import " +
                             quoted(data_file("las/autzen_trim.las")) + " -o " + quoted(dir / "a.sqlite"));
  if (r.code == 77) GTEST_SKIP() << "no pseudo-terminal";
  ASSERT_EQ(r.code, 0) << r.out;
  std::vector<std::string> draws;  // the status line's drawings (a terminal turns \n into \r\n)
  std::istringstream parts(r.out);
  for (std::string part; std::getline(parts, part, '\r');)
    if (part.rfind("db import: ", 0) == 0) draws.push_back(part);
  ASSERT_FALSE(draws.empty()) << r.out;
  EXPECT_NE(std::find_if(draws.begin(), draws.end(),
                         [](const std::string& d) { return d.rfind("db import: index  running, 110000 points", 0) == 0; }),
            draws.end())
      << r.out;
  for (const std::string& d : draws) EXPECT_EQ(d.find(" 0.0%"), std::string::npos) << d;
  EXPECT_EQ(draws.back().rfind("db import: done    100.0%  110000 / 110000 points  ", 0), 0u) << draws.back();
  std::filesystem::remove_all(dir);
}

// A quick look of a LAS file: `render` reads the points once, for the automatic camera and the
// render; the read is logged ("read 110000 points from <file> in T s", the file's point count)
// and counted in the time to the first traced tile: its set-up time is at least T.
TEST(JobCli, QuickLookLogsItsReadAndCountsItInTheTimeToTheFirstTile) {
  const std::filesystem::path dir = temp_dir() / "quick_look_read";
  std::filesystem::create_directories(dir);
  const std::string las = data_file("las/autzen_trim.las").string();
  const auto r = rayscan_cli("render " + quoted(std::filesystem::path(las)) + " --spp 1 --width 60 -o " + quoted(dir / "q.png"));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string read = "rayscan render: read 110000 points from " + las + " in ";
  const std::size_t at = r.out.find(read);
  ASSERT_NE(at, std::string::npos) << r.out;
  const double read_s = std::stod(r.out.substr(at + read.size()));
  const std::string first = " s after the start (";
  const std::size_t f = r.out.find(first);
  ASSERT_NE(f, std::string::npos) << r.out;
  const double setup_s = std::stod(r.out.substr(f + first.size()));
  EXPECT_GE(setup_s, read_s) << r.out;
  std::filesystem::remove_all(dir);
}

TEST(JobCli, QueryOutputMustBeCsv) {
  const std::filesystem::path dir = temp_dir() / "query_out";
  std::filesystem::create_directories(dir);
  {
    std::ofstream r(dir / "rays.csv");
    r << "ox,oy,oz,dx,dy,dz\n636500,849200,1000,0,0,-1\n";
  }
  const std::string base = "query --cloud " + quoted(data_file("las/autzen_trim.las")) + " --rays " +
                           quoted(dir / "rays.csv") + " --radius 5 --out ";
  const auto bad = rayscan_cli(base + quoted(dir / "hits.las"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.out.find("hits.las': expected a file name ending in .csv"), std::string::npos) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "hits.las"));
  const auto ok = rayscan_cli(base + quoted(dir / "hits.csv"));
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_EQ(rayscan::test::file_bytes(dir / "hits.csv").rfind("ray,", 0), 0u);
  std::filesystem::remove_all(dir);
}

// The quick look of a cloud without --out writes <stem>.png in the working directory and says so
// ("wrote ..."); a COPC file's stem drops ".copc". Before, it failed: "/output/image: not set".
TEST(JobCli, QuickLookWithoutOutWritesStemPngHere) {
  const std::filesystem::path dir = temp_dir() / "quick_look_cwd";
  std::filesystem::create_directories(dir);
  for (const auto& [file, png] : {std::pair<std::string, std::string>{"las/autzen_trim.las", "autzen_trim.png"},
                                  {"laz/lone-star.copc.laz", "lone-star.png"}}) {
    const auto r = run_command("cd " + quoted(dir) + " && " + quoted(RAYSCAN_BIN) + " render " + quoted(data_file(file)) +
                               " -q --spp 1 --width 60");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("wrote " + png), std::string::npos) << r.out;
    EXPECT_EQ(rayscan::test::file_bytes(dir / png).substr(1, 3), "PNG") << png;
  }
  std::filesystem::remove_all(dir);
}

TEST(JobCli, SolarIntegrationStepIsAtMostAnHour) {
  // Each step is sampled at its middle: a day-long step would sample solar noon only and give
  // about three times the day's irradiation with 24 sun hours, so steps past 1h are refused.
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::string out = (temp_dir() / "sun.las").string();
  auto r = rayscan_cli("solar -q " + las + " --start 2026-06-21 --end 2026-06-21 --step 1d -o '" + out + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan solar: --step '1d': the sun is sampled once per step, at its middle, so a step longer than "
                   "1h misweights the day; expected at most 1h (e.g. 15min, 30min, 1h)\n");
  EXPECT_FALSE(std::filesystem::exists(out));
  r = rayscan_cli("solar -q " + las + " --day 2026-06-21 --every 0 -o '" + out + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan solar: --every '0': expected a duration of at least 1 min, e.g. 30min, 1h or 1d\n");
}

TEST(JobCli, SolarPositionReadsADateAloneAsItsLocalMidnight) {
  // As the periods of `rayscan solar` do: midnight in --utc-offset hours east of UTC (-7: 07:00Z),
  // else in local mean solar time (longitude / 15 to the minute = -8:12: 08:12:00Z), and the sun's day is
  // that date (sunrise 2026-06-21, not the evening before's UTC date).
  auto r = rayscan_cli("solar position --lat 44.05 --lon -123.07 --time 2026-06-21 --utc-offset -7 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["time"], "2026-06-21T00:00:00-07:00");  // stated at --utc-offset
  EXPECT_EQ(j["sunrise"].get<std::string>().substr(0, 10), "2026-06-21");
  r = rayscan_cli("solar position --lat 44.05 --lon -123.07 --time 2026-06-21 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["time"], "2026-06-21T08:12:00Z");  // 123.07 / 15 h = 8 h 12 min 16.8 s, to the minute
  EXPECT_EQ(j["sunrise"].get<std::string>().substr(0, 10), "2026-06-21");
}

TEST(JobCli, SolarPositionReadsATimeWithoutAnOffsetAtUtcOffset) {
  // 12:00 at --utc-offset 2 is 10:00Z: the same sun to the last digit, stated as local time with
  // its offset; a time naming its offset ('Z') is read as written whatever --utc-offset says, and
  // without --utc-offset a time without an offset is UTC.
  const auto sun = [](const std::string& args) {
    const auto r = rayscan_cli("solar position --lat 48 --lon 11 --json " + args);
    EXPECT_EQ(r.code, 0) << args << ": " << r.out;
    return nlohmann::json::parse(r.out);
  };
  const nlohmann::json local = sun("--time 2026-06-21T12:00 --utc-offset 2");
  const nlohmann::json zulu = sun("--time 2026-06-21T10:00Z");
  const nlohmann::json zulu_offset = sun("--time 2026-06-21T10:00Z --utc-offset 2");
  const nlohmann::json noon = sun("--time 2026-06-21T12:00");
  EXPECT_EQ(local["time"], "2026-06-21T12:00:00+02:00");
  EXPECT_EQ(zulu["time"], "2026-06-21T10:00:00Z");
  EXPECT_EQ(zulu_offset["time"], "2026-06-21T12:00:00+02:00");
  EXPECT_EQ(noon["time"], "2026-06-21T12:00:00Z");
  for (const char* k : {"zenith", "azimuth", "julian_day"}) {
    EXPECT_EQ(local[k].get<double>(), zulu[k].get<double>()) << k;
    EXPECT_EQ(zulu_offset[k].get<double>(), zulu[k].get<double>()) << k;
  }
  EXPECT_NEAR(noon["julian_day"].get<double>() - zulu["julian_day"].get<double>(), 2.0 / 24.0, 1e-8);  // 2 h later
  const auto text = rayscan_cli("solar position --lat 48 --lon 11 --time 2026-06-21T12:00 --utc-offset 2");
  EXPECT_EQ(text.out.substr(0, text.out.find('\n')), "time      2026-06-21T12:00:00+02:00");
}

TEST(JobCli, SolarSiteHeightWithLatitudeAndLongitudeIsTheCentresZInMetres) {
  // autzen: z 406.26 .. 520.51 international feet (its README), so the centre is 463.385 ft =
  // 141.2397 m, with --lat/--lon given as without them.
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const std::string out = (temp_dir() / "sunlatlon.las").string();
  auto r = rayscan_cli("solar -q " + las + " --at 2026-06-21T20:00Z --lat 44.0507 --lon -123.0712 --sky-rays 0 -o '" +
                       out + "' --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_NEAR(j["site"]["elevation_m"].get<double>(), 463.385 * 0.3048, 1e-6) << r.out;
}

// Solar's result fields keep their units outside LAS: `--json` gives each reported field's unit
// and description, and PLY and PCD outputs describe every result field in a header comment with
// the description the LAS Extra Bytes descriptor holds. sun_hours states WMO's sunshine threshold
// (docs/solar.md: a direct normal irradiance of at least 120 W/m²). Oracle: the JSON parsed and
// the written files' own header lines and bytes, the units as docs/solar.md tabulates them.
TEST(JobCli, SolarFieldsCarryTheirUnitsIntoJsonPlyAndPcd) {
  const std::string las = quoted(data_file("las/simple.las"));
  const std::string site = " --lat 44 --lon -123 --sky-rays 0 --json -o '";
  const auto ply = temp_dir() / "sun_units.ply", pcd = temp_dir() / "sun_units.pcd";
  auto r = rayscan_cli("solar -q " + las + " --start 2026-06-21 --end 2026-06-21" + site + ply.string() + "'");
  ASSERT_EQ(r.code, 0) << r.out;
  nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_EQ(j["fields"]["solar_global"]["unit"], "kWh/m2") << r.out;
  EXPECT_EQ(j["fields"]["solar_global"]["description"], "global irradiation, kWh/m2");
  EXPECT_EQ(j["fields"]["sun_hours"]["unit"], "h");
  EXPECT_EQ(j["fields"]["sun_hours"]["description"], "sun hours, DNI >= 120 W/m2, h");
  // The LAS Extra Bytes descriptor's 32-byte description, NUL-padded, in the file's own bytes.
  const auto las_out = temp_dir() / "sun_units.las";
  r = rayscan_cli("solar -q " + las + " --start 2026-06-21 --end 2026-06-21" + site + las_out.string() + "'");
  ASSERT_EQ(r.code, 0) << r.out;
  {
    std::ifstream in(las_out, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(bytes.find(std::string("sun hours, DNI >= 120 W/m2, h\0", 30)), std::string::npos);
  }
  std::filesystem::remove(las_out);
  r = rayscan_cli("solar -q " + las + " --at 2026-06-21T20:00Z" + site + pcd.string() + "'");
  ASSERT_EQ(r.code, 0) << r.out;
  j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_EQ(j["fields"]["in_shadow"]["unit"], "1");

  const auto header = [](const std::filesystem::path& p, const std::string& last) {
    std::ifstream in(p, std::ios::binary);
    std::vector<std::string> lines;
    for (std::string l; std::getline(in, l) && l.rfind(last, 0) != 0;) lines.push_back(l);
    return lines;
  };
  const auto has = [](const std::vector<std::string>& h, const std::string& l) {
    return std::find(h.begin(), h.end(), l) != h.end();
  };
  const std::vector<std::string> ph = header(ply, "end_header");
  EXPECT_TRUE(has(ph, "comment field scalar_solar_global: global irradiation, kWh/m2"));
  EXPECT_TRUE(has(ph, "comment field scalar_solar_beam: beam irradiation, kWh/m2"));
  EXPECT_TRUE(has(ph, "comment field scalar_sun_hours: sun hours, DNI >= 120 W/m2, h"));
  EXPECT_TRUE(has(ph, "property double scalar_solar_global"));
  const std::vector<std::string> dh = header(pcd, "DATA");
  EXPECT_TRUE(has(dh, "# field irradiance_global: global irradiance, W/m2"));
  EXPECT_TRUE(has(dh, "# field in_shadow: 1 shadow (or night), 0 sun"));
  // Fields of the source cloud (simple.las: return_number, ...) have no description, so no comment.
  EXPECT_FALSE(std::any_of(dh.begin(), dh.end(), [](const std::string& l) { return l.rfind("# field return_number", 0) == 0; }));
  // The readers still read both files.
  r = rayscan_cli("info " + quoted(ply));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("comment field scalar_solar_global: global irradiation, kWh/m2"), std::string::npos) << r.out;
  r = rayscan_cli("info " + quoted(pcd));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("# field in_shadow: 1 shadow (or night), 0 sun"), std::string::npos) << r.out;
  std::filesystem::remove(ply);
  std::filesystem::remove(pcd);
}

TEST(JobCli, QueryWithoutABoundIsRefusedUnlessAllIsAsked) {
  // Without --k or a finite --radius each ray returns every point: refused, --all asks for it
  // (the Python module's allow_all=True). 2 rays x 110,000 points.
  const auto dir = temp_dir() / "query_all";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "rays.csv") << "ox,oy,oz,dx,dy,dz\n636500,849200,1000,0,0,-1\n636600,849300,1000,0,0,-1\n";
  const std::string base = "query --cloud " + quoted(data_file("las/autzen_trim.las")) + " --rays " + quoted(dir / "rays.csv");
  auto r = rayscan_cli(base + " --out " + quoted(dir / "hits.csv"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan query: neither --k nor a finite --radius: every ray would return every point; give --k, "
                   "--radius, or --all to ask for all of them\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "hits.csv"));
  r = rayscan_cli(base + " --all --out " + quoted(dir / "hits.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream f(dir / "hits.csv");
  std::size_t rows = 0;
  for (std::string line; std::getline(f, line);) ++rows;
  EXPECT_EQ(rows, 1u + 2u * 110000u);  // the header, then every point for each ray
}

TEST(JobCli, OptionLimitsAreCheckedWhereTheyAreParsed) {
  // Each refused in one line before any work: a zero or tiny ortho-map cell (the message names the
  // cell count in a few digits), a leaf depth of 0, solar position's time zone past 18 h, and a
  // solar run with nothing to write.
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const auto out = temp_dir() / "limits";
  std::filesystem::create_directories(out);
  auto r = rayscan_cli("render " + las + " --ortho-map 0 -o " + quoted(out / "o.tif"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: --ortho-map: expected a finite number > 0, got '0' (see --help)\n");
  r = rayscan_cli("render -q " + las + " --ortho-map 1e-300 -o " + quoted(out / "o.tif"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("gives 1.17746e+303 x 5.627e+302 cells (limit 400000000); use a cell of at least"), std::string::npos)
      << r.out;
  r = rayscan_cli("index -q " + las + " -o " + quoted(out / "x.rsi") + " --max-depth 0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: --max-depth: expected an integer in [1, 21], got '0' (see --help)\n");
  r = rayscan_cli("solar position --lat 44 --lon -123 --time 2026-06-21 --utc-offset 99");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan solar: --utc-offset: expected a finite number in [-18, 18], got '99' (see --help)\n");
  r = rayscan_cli("solar " + las + " --at 2026-06-21T20:00Z");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan solar: nothing to write: give -o OUT (the cloud with the result fields), --raster MAP.tif, "
                   "or --json\n");
  EXPECT_TRUE(std::filesystem::is_empty(out));
}

TEST(JobCli, JobMessagesSpellTheFlags) {
  // The jobs name their options by field (test_jobs.cpp); the command line writes each as its flag,
  // --day included.
  const std::string las = quoted(data_file("las/autzen_trim.las"));
  const auto out = temp_dir() / "job_messages";
  std::filesystem::create_directories(out);
  auto r = rayscan_cli("visibility " + las + " -o " + quoted(out / "v.las"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan visibility: nothing to compute: give observers (--observers or --observer), a sky "
                   "view (--sky-view > 0) or a camera (--from-camera)\n");
  r = rayscan_cli("solar " + las + " --start 2026-06-21 -o " + quoted(out / "s.las"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan solar: give a period (--start and --end) or an instant (--at), or a day of shadows "
                   "(--day)\n");
  EXPECT_TRUE(std::filesystem::is_empty(out));
}

TEST(JobCli, OutputNamesSayTheirFormat) {
  // A SQLite database named .las, a LAS file named .laz, and a --table that a SQLite import would
  // drop: refused before any work, nothing written.
  const std::string las = quoted(data_file("las/point-color.las"));
  const auto dir = temp_dir() / "names";
  std::filesystem::create_directories(dir);
  auto r = rayscan_cli("db import " + las + " -o " + quoted(dir / "x.las"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: -o '" + (dir / "x.las").string() +
                       "': expected a file name ending in .sqlite, .sqlite3 or .db (a SQLite database)\n");
  r = rayscan_cli("db import " + las + " -o " + quoted(dir / "x.sqlite") + " --table t");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --table names the PostgreSQL table (with --postgres); a SQLite import (-o) writes the "
                   "tables points and chunks\n");
  r = rayscan_cli("translate " + las + " " + quoted(dir / "t.laz") + " --format las");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --format las: OUT '" + (dir / "t.laz").string() +
                       "' names another format (.laz); give a .las name, or --format auto\n");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}
