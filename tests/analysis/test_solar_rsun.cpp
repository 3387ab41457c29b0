// Fidelity of `rayscan solar` against GRASS GIS r.sun: on an open horizontal plane and a 30 degree
// south-facing plane of synthetic points, daily and yearly global irradiation equal r.sun's on the
// equivalent flat/tilted DEM (same day, Linke, albedo, location) within 2 %. The test writes the two planes as .xyz clouds, runs the real `rayscan solar` on
// them (clear sky, exact per-step shadow rays) and reads the per-point fields back from its CSV
// output; r.sun runs in its daily mode on one-row flat/tilted rasters through
// tests/analysis/rsun_daily.sh (skipped when `grass` is not installed).
#include "../common/run_command.hpp"
#include "run_command.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#ifndef RAYSCAN_SOURCE_DIR
#error "RAYSCAN_SOURCE_DIR (the source tree, for tests/analysis/rsun_daily.sh) must be defined"
#endif
#ifndef RAYSCAN_BIN
#error "RAYSCAN_BIN (the rayscan executable) must be defined"
#endif

namespace rayscan::solar_rsun_test {
namespace {

namespace fs = std::filesystem;

// The site and the sky, the same for both programs.
constexpr double kLatitude = 46.5;  // the Swiss plateau: sun up to 67 deg, down to 20 deg at noon
constexpr double kLongitude = 7.5;
constexpr double kLinke = 3.0;
constexpr double kAlbedo = 0.2;
constexpr double kSlopeDeg = 30.0;
constexpr int kYear = 2026;  // not a leap year: day numbers 1..365 as r.sun's
constexpr double kTolerance = 0.02;
// The planes: kHalf metres either side of the origin, kSpacing apart; the points compared lie
// within kCentre of the origin (horizontally), far from the edges.
constexpr double kHalf = 15.0, kSpacing = 0.5, kCentre = 4.0;

using rayscan::test::run_output;

bool grass_installed() {
  int status = 0;
  run_output("command -v grass >/dev/null 2>&1", status);
  return status == 0;
}

using rayscan::test::quoted;

// Daily (or summed) irradiation on one surface, Wh/m^2.
struct Irradiation {
  double beam = 0.0, diffuse = 0.0, reflected = 0.0, global = 0.0;
  Irradiation& operator+=(const Irradiation& o) {
    beam += o.beam, diffuse += o.diffuse, reflected += o.reflected, global += o.global;
    return *this;
  }
};

// A temporary folder, removed at the end of the test.
struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("rayscan_solar_rsun_" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// A plane of points in a local metric frame (x east, y north, z up): horizontal, or rising to
// the north at kSlopeDeg (so it faces south).
fs::path write_plane(const fs::path& dir, bool tilted) {
  const fs::path file = dir / (tilted ? "tilted.xyz" : "flat.xyz");
  std::ofstream out(file);
  const double rise = tilted ? std::tan(kSlopeDeg * std::numbers::pi / 180.0) : 0.0;
  const int n = static_cast<int>(std::lround(2.0 * kHalf / kSpacing));
  char line[96];
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double x = -kHalf + i * kSpacing, y = -kHalf + j * kSpacing;
      std::snprintf(line, sizeof line, "%.4f %.4f %.6f\n", x, y, y * rise);
      out << line;
    }
  return file;
}

// "2026-MM-DD" of day number `day` (1 = January 1).
std::string date_of(int day) {
  using namespace std::chrono;
  const year_month_day ymd(sys_days(year(kYear) / January / 1) + days(day - 1));
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04d-%02u-%02u", int(ymd.year()), unsigned(ymd.month()),
                unsigned(ymd.day()));
  return buf;
}

// Runs `rayscan solar` on `cloud` from the start of day `first` to the end of day `last` (local
// mean solar time), clear sky, one shadow ray per time step and no sky map (the planes are open),
// and returns the mean of the centre points' solar_* fields, Wh/m^2.
Irradiation rayscan_solar(const fs::path& cloud, const fs::path& dir, const std::string& first,
                          const std::string& last, const std::string& step, const std::string& tag) {
  const fs::path out = dir / (tag + ".csv");
  char args[512];
  std::snprintf(args, sizeof args,
                " --lat %g --lon %g --start %s --end %s --step %s --linke %g --albedo %g"
                " --sky-rays 0 --sector 0 --elevation 0 -q -o ",
                kLatitude, kLongitude, first.c_str(), last.c_str(), step.c_str(), kLinke, kAlbedo);
  int status = 0;
  const std::string log = run_output(
      quoted(RAYSCAN_BIN) + " solar " + quoted(cloud) + args + quoted(out) + " 2>&1", status);
  EXPECT_EQ(status, 0) << log;
  Irradiation mean;
  std::ifstream in(out);
  std::string line;
  if (!std::getline(in, line)) {
    ADD_FAILURE() << "no output " << out << ": " << log;
    return mean;
  }
  std::map<std::string, std::size_t> column;
  {
    std::stringstream header(line);
    std::string name;
    for (std::size_t k = 0; std::getline(header, name, ','); ++k) column[name] = k;
  }
  for (const char* name : {"x", "y", "solar_global", "solar_beam", "solar_diffuse", "solar_reflected"})
    if (!column.count(name)) {
      ADD_FAILURE() << out << " has no column " << name << ": " << line;
      return mean;
    }
  std::size_t n = 0;
  std::vector<double> v;
  while (std::getline(in, line)) {
    v.clear();
    std::stringstream row(line);
    std::string cell;
    while (std::getline(row, cell, ',')) v.push_back(std::stod(cell));
    if (std::abs(v.at(column["x"])) > kCentre || std::abs(v.at(column["y"])) > kCentre) continue;
    mean += {v.at(column["solar_beam"]), v.at(column["solar_diffuse"]),
             v.at(column["solar_reflected"]), v.at(column["solar_global"])};
    ++n;
  }
  EXPECT_GT(n, 100u) << out;
  const double scale = n ? 1000.0 / double(n) : 0.0;  // kWh/m^2 -> Wh/m^2, mean
  return {mean.beam * scale, mean.diffuse * scale, mean.reflected * scale, mean.global * scale};
}

// r.sun's daily irradiation for every day of the year, [day][flat = 0, tilted = 1], Wh/m^2.
std::map<int, std::array<Irradiation, 2>> rsun_year(std::string& log) {
  char args[256];
  std::snprintf(args, sizeof args, " %g %g all %g %g %g 180 0.25 0 2>&1", kLatitude, kLongitude, kLinke,
                kAlbedo, kSlopeDeg);
  int status = 0;
  log = run_output("bash " + quoted(fs::path(RAYSCAN_SOURCE_DIR) / "tests/analysis/rsun_daily.sh") + args, status);
  EXPECT_EQ(status, 0) << log;
  std::map<int, std::array<Irradiation, 2>> days;
  std::istringstream lines(log);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream f(line);
    std::string tag, surface;
    int day = 0;
    Irradiation r;
    if (!(f >> tag >> day >> surface >> r.beam >> r.diffuse >> r.reflected >> r.global) || tag != "RSUN")
      continue;
    days[day][surface == "tilted" ? 1 : 0] = r;
  }
  return days;
}

// Relative difference, with 1 % of the global irradiation as the floor of the scale (a reflected
// 0 against 1e-9 is no miss).
double rel_diff(double ours, double rsun, double global) {
  return (ours - rsun) / std::max(std::abs(rsun), 0.01 * std::abs(global));
}

// Compares all four components within kTolerance, prints them, returns the worst |difference|.
double compare(const char* what, const Irradiation& ours, const Irradiation& rsun) {
  const std::array<double, 4> d = {rel_diff(ours.beam, rsun.beam, rsun.global),
                                   rel_diff(ours.diffuse, rsun.diffuse, rsun.global),
                                   rel_diff(ours.reflected, rsun.reflected, rsun.global),
                                   rel_diff(ours.global, rsun.global, rsun.global)};
  std::printf("%-22s global %9.1f vs r.sun %9.1f Wh/m2: %+6.2f %% | beam %+6.2f %% diffuse %+6.2f %% "
              "reflected %+6.2f %%\n",
              what, ours.global, rsun.global, 100 * d[3], 100 * d[0], 100 * d[1], 100 * d[2]);
  const char* names[] = {"beam", "diffuse", "reflected", "global"};
  double worst = 0.0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    EXPECT_LE(std::abs(d[k]), kTolerance) << what << ": " << names[k] << " differs by " << 100 * d[k]
                                          << " % (ours " << (&ours.beam)[k] << ", r.sun "
                                          << (&rsun.beam)[k] << " Wh/m2)";
    worst = std::max(worst, std::abs(d[k]));
  }
  return worst;
}

// Days 15, 80, 172, 266, 355 (mid-January, the equinoxes, the solstices) and the whole of 2026,
// flat and 30 degrees south-facing, at 46.5 N 7.5 E, sea level, Linke 3, albedo 0.2: rayscan
// with 15 min steps per day and 1 h steps over the year, r.sun with its 0.25 h step.
TEST(SolarRsun, DailyAndYearlyIrradiationOfOpenPlanesMatchGrassRsun) {
  if (!grass_installed()) GTEST_SKIP() << "GRASS GIS (`grass`, Debian grass-core) is not installed";
  ASSERT_TRUE(fs::exists(RAYSCAN_BIN)) << RAYSCAN_BIN;
  const auto t0 = std::chrono::steady_clock::now();
  TempDir dir;
  const std::array<fs::path, 2> clouds = {write_plane(dir.path, false), write_plane(dir.path, true)};
  const char* surface[] = {"flat", "tilted 30 S"};

  std::string log;
  const auto rsun = rsun_year(log);
  ASSERT_EQ(rsun.size(), 365u) << log;
  const double rsun_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  double worst_day = 0.0;
  for (int day : {15, 80, 172, 266, 355})
    for (int s = 0; s < 2; ++s) {
      const std::string date = date_of(day);
      const Irradiation ours =
          rayscan_solar(clouds[s], dir.path, date, date, "15min", "day" + std::to_string(day) + "_" + std::to_string(s));
      char what[64];
      std::snprintf(what, sizeof what, "day %3d %s (%s)", day, surface[s], date.c_str());
      worst_day = std::max(worst_day, compare(what, ours, rsun.at(day)[s]));
    }

  double worst_year = 0.0;
  for (int s = 0; s < 2; ++s) {
    Irradiation year;
    for (const auto& [day, r] : rsun) year += r[s];
    const Irradiation ours = rayscan_solar(clouds[s], dir.path, date_of(1), date_of(365), "1h",
                                           "year_" + std::to_string(s));
    char what[64];
    std::snprintf(what, sizeof what, "year %d %s", kYear, surface[s]);
    worst_year = std::max(worst_year, compare(what, ours, year));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("worst |difference|: days %.2f %%, year %.2f %%; r.sun %.1f s, in all %.1f s\n",
              100 * worst_day, 100 * worst_year, rsun_seconds, seconds);
  RecordProperty("max_rel_daily", std::to_string(worst_day));
  RecordProperty("max_rel_yearly", std::to_string(worst_year));
}

}  // namespace
}  // namespace rayscan::solar_rsun_test
