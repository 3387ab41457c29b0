// Fidelity of `rayscan solar` against GRASS GIS r.sun on a real scan: on autzen_trim, the per-cell
// yearly global irradiation of open terrain cells is within 5 % of r.sun's on rayscan's own DSM
// for >= 95 % of them.
//
// The DSM is rayscan's own (`render CLOUD --ortho-map 3 --dsm`, 3 ft cells, NoData where no
// surface was hit). r.sun runs on it with its own terrain shadowing (tests/analysis/rsun_dsm.sh:
// the cells moved unchanged into the same Lambert conic in metres, z x 0.3048, slope and aspect
// from r.slope.aspect). `rayscan solar` runs on the points, clear sky, defaults otherwise (sphere
// shadows, 1 degree sun map, 64 sky rays), and its `--raster --cell 3` (the value of each cell's
// highest point) lies on the DSM's grid (both snap to multiples of the cell; the geotransforms are
// checked equal).
//
// The year is sampled: the 15th of each month, weighted by the month's days (sum of 12 daily
// irradiations x 31, 28, ...), 30 min steps, Linke 3, albedo 0.2 in both programs. On a flat open
// cell at autzen's latitude that sample is +0.07 % off r.sun's full 365-day sum (rsun_daily.sh).
//
// "Open terrain": a cell whose highest point is ground (at most kGroundTolerance above the cell's
// highest class-2 point, or above the lowest point of the cell and its 8 neighbours: no crown, bank
// or railing in it; autzen_trim's class 2 is sparse, most of the field is class 1), whose DSM
// slope (Horn, 3 x 3 valid cells) is below kMaxSlopeDeg and whose DSM horizon (32 azimuths out to
// kHorizonReach) is below kMaxHorizonDeg in every direction. The other cells are reported by kind.
//
// Measured (this code, GRASS 8.2.1): open terrain 7,908 cells, 99.6 % within 5 %, median -0.04 %
// (5-95 %: -1.6 .. +1.5 %); those ground by class 2 alone 3,829 cells, 99.3 %. rayscan's diffuse
// is 1.3 % lower there (its sky view, 0.988 median, scales it; r.sun's diffuse has no sky view),
// the beam agrees to 0.1 %; the 0.4 % of misses lie near the DSM's holes (the river), where
// rayscan's points shade what r.sun sees as open. Ground next to trees (horizon >= 20 degrees):
// 78.9 % within 5 %, median -0.1 %: lower where the crowns also hide sky (diffuse -12 %), higher
// where sun passes through gaps in the crowns (spheres; the DSM's crowns are solid). Crowns, the
// bank and the footbridge (raised > 10 ft): 20 % within 5 %: r.sun tilts each cell by the DSM's
// 3 x 3 slope (a crown's or the bridge's edge is a steep wall facing out), rayscan by the top
// point's own normal. Time per day, one thread, 2 shared cores: r.sun ~0.7-1.0 s for 46,215
// cells, rayscan ~3.1-3.4 s for 110,000 points (with 64 sky-view rays per point); about 70 s in all.
//
// Skipped when `grass` (Debian grass-core) or GDAL's command line tools are not installed.
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
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#ifndef RAYSCAN_SOURCE_DIR
#error "RAYSCAN_SOURCE_DIR (the source tree, for tests/analysis/rsun_dsm.sh and the scene) must be defined"
#endif
#ifndef RAYSCAN_BIN
#error "RAYSCAN_BIN (the rayscan executable) must be defined"
#endif

namespace rayscan::solar_dsm_test {
namespace {

namespace fs = std::filesystem;

constexpr double kCell = 3.0;             // feet (autzen's CRS unit)
constexpr double kGroundTolerance = 1.0;  // feet: the top point at most this far above the ground
constexpr double kMaxSlopeDeg = 15.0;
constexpr double kMaxHorizonDeg = 20.0;
constexpr double kHorizonReach = 100.0;  // feet (30 m)
constexpr double kTolerance = 0.05;
constexpr double kLinke = 3.0, kAlbedo = 0.2;
constexpr int kYear = 2026;
constexpr std::array<int, 12> kMonthDays = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};

using rayscan::test::run_output;

bool installed(const char* program) {
  int status = 0;
  run_output(std::string("command -v ") + program + " >/dev/null 2>&1", status);
  return status == 0;
}

using rayscan::test::quoted;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("rayscan_solar_dsm_" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// A single-band raster read back through GDAL's command line tools: gdalinfo for the grid,
// `gdal_translate -of XYZ` for the values (row-major, top row first); NoData -> NaN.
struct Grid {
  int cols = 0, rows = 0;
  double x0 = 0, y_top = 0, dx = 0, dy = 0;
  std::vector<double> v;
  [[nodiscard]] bool valid(std::size_t k) const { return std::isfinite(v[k]); }
  [[nodiscard]] double at(int c, int r) const { return v[std::size_t(r) * std::size_t(cols) + std::size_t(c)]; }
};

Grid read_grid(const fs::path& file) {
  Grid g;
  int status = 0;
  const std::string info = run_output("gdalinfo " + quoted(file) + " 2>&1", status);
  EXPECT_EQ(status, 0) << info;
  double nodata = std::nan("");
  std::istringstream lines(info);
  std::string line;
  while (std::getline(lines, line)) {
    std::sscanf(line.c_str(), "Size is %d, %d", &g.cols, &g.rows);
    std::sscanf(line.c_str(), "Origin = (%lf,%lf)", &g.x0, &g.y_top);
    std::sscanf(line.c_str(), "Pixel Size = (%lf,%lf)", &g.dx, &g.dy);
    std::sscanf(line.c_str(), "  NoData Value=%lf", &nodata);
  }
  const std::string xyz = run_output("gdal_translate -q -of XYZ " + quoted(file) + " /vsistdout/", status);
  EXPECT_EQ(status, 0) << file;
  g.v.reserve(std::size_t(g.cols) * std::size_t(g.rows));
  const char* p = xyz.c_str();
  char* end = nullptr;
  while (*p) {
    std::strtod(p, &end);  // x
    if (end == p) break;
    std::strtod(end, &end);  // y
    double value = std::strtod(end, &end);
    if (value == nodata || !std::isfinite(value)) value = std::nan("");
    g.v.push_back(value);
    p = end;
    while (*p == '\n' || *p == '\r' || *p == ' ') ++p;
  }
  EXPECT_EQ(g.v.size(), std::size_t(g.cols) * std::size_t(g.rows)) << file;
  return g;
}

bool same_grid(const Grid& a, const Grid& b) {
  return a.cols == b.cols && a.rows == b.rows && a.x0 == b.x0 && a.y_top == b.y_top && a.dx == b.dx &&
         a.dy == b.dy;
}

// Per cell of `grid`: the z of its highest point (first in point order on a tie, as the raster's
// `top`), of its lowest point, and of its highest ground point (class 2), from rayscan's CSV.
struct TopPoints {
  std::vector<double> top_z, low_z, ground_z;
};

TopPoints top_points(const fs::path& csv, const Grid& grid) {
  const std::size_t n = std::size_t(grid.cols) * std::size_t(grid.rows);
  const double inf = std::numeric_limits<double>::infinity();
  TopPoints t{std::vector<double>(n, -inf), std::vector<double>(n, inf), std::vector<double>(n, -inf)};
  std::ifstream in(csv);
  std::string line;
  if (!std::getline(in, line)) {
    ADD_FAILURE() << "no output " << csv;
    return t;
  }
  std::map<std::string, std::size_t> column;
  {
    std::stringstream header(line);
    std::string name;
    for (std::size_t k = 0; std::getline(header, name, ','); ++k) column[name] = k;
  }
  for (const char* name : {"x", "y", "z", "classification"})
    if (!column.count(name)) {
      ADD_FAILURE() << csv << " has no column " << name << ": " << line;
      return t;
    }
  const std::size_t cx = column["x"], cy = column["y"], cz = column["z"], cc = column["classification"];
  const std::size_t last = std::max({cx, cy, cz, cc});
  // GridSpec's cell of (x, y): col = floor(x / c) - x0 / c, row = y_top / c - 1 - floor(y / c).
  const auto c0 = std::llround(grid.x0 / grid.dx), r0 = std::llround(grid.y_top / grid.dx) - 1;
  std::vector<double> f;
  while (std::getline(in, line)) {
    f.clear();
    const char* p = line.c_str();
    char* end = nullptr;
    for (std::size_t k = 0; k <= last; ++k) {
      f.push_back(std::strtod(p, &end));
      p = *end == ',' ? end + 1 : end;
    }
    const long long col = static_cast<long long>(std::floor(f[cx] / grid.dx)) - c0;
    const long long row = r0 - static_cast<long long>(std::floor(f[cy] / grid.dx));
    if (col < 0 || row < 0 || col >= grid.cols || row >= grid.rows) continue;
    const std::size_t k = std::size_t(row) * std::size_t(grid.cols) + std::size_t(col);
    const double z = f[cz];
    t.top_z[k] = std::max(t.top_z[k], z);
    t.low_z[k] = std::min(t.low_z[k], z);
    if (static_cast<int>(f[cc]) == 2) t.ground_z[k] = std::max(t.ground_z[k], z);
  }
  return t;
}

// DSM slope (Horn's 3 x 3 gradient; NaN unless all nine cells are valid), degrees.
std::vector<double> slope_deg(const Grid& d) {
  std::vector<double> s(d.v.size(), std::nan(""));
  const double c = d.dx;
  for (int r = 1; r + 1 < d.rows; ++r)
    for (int q = 1; q + 1 < d.cols; ++q) {
      double z[3][3];
      bool ok = true;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) ok &= std::isfinite(z[i][j] = d.at(q + j - 1, r + i - 1));
      if (!ok) continue;
      const double gx = ((z[0][2] + 2 * z[1][2] + z[2][2]) - (z[0][0] + 2 * z[1][0] + z[2][0])) / (8 * c);
      const double gy = ((z[2][0] + 2 * z[2][1] + z[2][2]) - (z[0][0] + 2 * z[0][1] + z[0][2])) / (8 * c);
      s[std::size_t(r) * std::size_t(d.cols) + std::size_t(q)] = std::atan(std::hypot(gx, gy)) * 180.0 / std::numbers::pi;
    }
  return s;
}

// The DSM's horizon: the largest elevation angle (degrees) of a valid DSM cell seen from each
// valid cell, over 32 azimuths, one cell per step out to `reach` (nearest cell).
std::vector<double> horizon_deg(const Grid& d, double reach) {
  std::vector<double> h(d.v.size(), std::nan(""));
  const int steps = static_cast<int>(reach / d.dx);
  for (int r = 0; r < d.rows; ++r)
    for (int q = 0; q < d.cols; ++q) {
      const double z0 = d.at(q, r);
      if (!std::isfinite(z0)) continue;
      double best = -90.0;
      for (int a = 0; a < 32; ++a) {
        const double az = 2.0 * std::numbers::pi * a / 32.0, ux = std::sin(az), uy = std::cos(az);
        for (int s = 1; s <= steps; ++s) {
          const int qq = q + static_cast<int>(std::lround(ux * s)), rr = r - static_cast<int>(std::lround(uy * s));
          if (qq < 0 || rr < 0 || qq >= d.cols || rr >= d.rows) break;
          const double z = d.at(qq, rr);
          if (std::isfinite(z)) best = std::max(best, std::atan((z - z0) / (s * d.dx)) * 180.0 / std::numbers::pi);
        }
      }
      h[std::size_t(r) * std::size_t(d.cols) + std::size_t(q)] = best;
    }
  return h;
}

struct Agreement {
  std::size_t n = 0;
  double within = 0, median = 0, p5 = 0, p95 = 0;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(std::lround(p * double(v.size() - 1))));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

Agreement agreement(const std::vector<double>& rel) {
  Agreement a;
  a.n = rel.size();
  if (rel.empty()) return a;
  a.within = double(std::count_if(rel.begin(), rel.end(), [](double x) { return std::abs(x) <= kTolerance; })) /
             double(rel.size());
  a.median = percentile(rel, 0.5);
  a.p5 = percentile(rel, 0.05);
  a.p95 = percentile(rel, 0.95);
  return a;
}

void print(const char* what, const Agreement& a) {
  std::printf("  %-44s %6zu cells: %5.1f %% within 5 %%, median %+6.2f %%, 5-95 %% [%+6.2f, %+6.2f] %%\n", what,
              a.n, 100 * a.within, 100 * a.median, 100 * a.p5, 100 * a.p95);
}

TEST(SolarDsmRsun, YearlyGlobalOfOpenTerrainCellsMatchesGrassRsunOnRayscansOwnDsm) {
  if (!installed("grass")) GTEST_SKIP() << "GRASS GIS (`grass`, Debian grass-core) is not installed";
  if (!installed("gdal_translate") || !installed("gdalinfo") || !installed("gdalsrsinfo"))
    GTEST_SKIP() << "GDAL's command line tools (Debian gdal-bin) are not installed";
  ASSERT_TRUE(fs::exists(RAYSCAN_BIN)) << RAYSCAN_BIN;
  const fs::path cloud = fs::path(RAYSCAN_SOURCE_DIR) / "scenes/data/autzen_trim.las";
  ASSERT_TRUE(fs::exists(cloud)) << cloud;
  const auto t_all = std::chrono::steady_clock::now();
  TempDir dir;
  const std::string bin = quoted(RAYSCAN_BIN);
  int status = 0;

  // rayscan's own DSM.
  const fs::path dsm_file = dir.path / "dsm.tif";
  std::string log = run_output(bin + " render -q " + quoted(cloud) + " --ortho-map 3 --dsm " + quoted(dsm_file) +
                                   " --out " + quoted(dir.path / "ortho.tif") + " 2>&1",
                               status);
  ASSERT_EQ(status, 0) << log;
  const Grid dsm = read_grid(dsm_file);
  ASSERT_EQ(dsm.v.size(), std::size_t(dsm.cols) * std::size_t(dsm.rows));
  ASSERT_EQ(dsm.dx, kCell);

  // r.sun on it, the 15th of each month.
  std::string days;
  {
    int day = 0;
    for (int m = 0; m < 12; ++m) {
      days += (m ? " " : "") + std::to_string(day + 15) + ":" + std::to_string(kMonthDays[std::size_t(m)]);
      day += kMonthDays[std::size_t(m)];
    }
  }
  const auto t_rsun = std::chrono::steady_clock::now();
  char args[128];
  std::snprintf(args, sizeof args, " %g %g 0.5 2>&1", kLinke, kAlbedo);
  log = run_output("nice bash " + quoted(fs::path(RAYSCAN_SOURCE_DIR) / "tests/analysis/rsun_dsm.sh") + " " +
                       quoted(dsm_file) + " " + quoted(dir.path / "rsun") + " '" + days + "'" + args,
                   status);
  ASSERT_EQ(status, 0) << log;
  const double rsun_total = seconds_since(t_rsun);
  std::vector<double> rsun_day_seconds;
  long rsun_cells = 0;
  {
    std::istringstream lines(log);
    std::string line;
    while (std::getline(lines, line)) {
      int day = 0, weight = 0;
      double s = 0;
      long valid = 0, all = 0;
      if (std::sscanf(line.c_str(), "RSUN_DAY %d %d %lf", &day, &weight, &s) == 3) rsun_day_seconds.push_back(s);
      if (std::sscanf(line.c_str(), "RSUN_CELLS %ld %ld", &valid, &all) == 2) rsun_cells = valid;
    }
  }
  ASSERT_EQ(rsun_day_seconds.size(), 12u) << log;
  const Grid rsun = read_grid(dir.path / "rsun" / "rsun_global.tif");
  ASSERT_TRUE(same_grid(rsun, dsm)) << "r.sun's raster is not on the DSM's grid";

  // rayscan on the same days (one thread, as r.sun's one process); the January run also writes
  // the points (for the cells' top points and classes).
  std::vector<double> ours(dsm.v.size(), 0.0);
  std::vector<double> rayscan_seconds;
  for (int m = 1; m <= 12; ++m) {
    char date[16], name[32];
    std::snprintf(date, sizeof date, "%04d-%02d-15", kYear, m);
    std::snprintf(name, sizeof name, "rs_%02d.tif", m);
    const fs::path out = dir.path / name;
    std::snprintf(args, sizeof args, " --linke %g --albedo %g", kLinke, kAlbedo);
    const std::string points = m == 1 ? " -o " + quoted(dir.path / "points.csv") : "";
    const auto t0 = std::chrono::steady_clock::now();
    log = run_output("nice " + bin + " solar " + quoted(cloud) + " --start " + date + " --end " + date +
                         " --step 30min" + args + " --raster " + quoted(out) +
                         " --cell 3 --raster-value global --no-preview --threads 1 -q" + points + " 2>&1",
                     status);
    rayscan_seconds.push_back(seconds_since(t0));
    ASSERT_EQ(status, 0) << log;
    const Grid g = read_grid(out);
    ASSERT_TRUE(same_grid(g, dsm)) << name << " is not on the DSM's grid";
    for (std::size_t k = 0; k < ours.size(); ++k) ours[k] += kMonthDays[std::size_t(m - 1)] * g.v[k];  // NaN stays
  }
  const TopPoints top = top_points(dir.path / "points.csv", dsm);
  const std::vector<double> slope = slope_deg(dsm), horizon = horizon_deg(dsm, kHorizonReach);

  // The cells by kind, and the relative difference (rayscan - r.sun) / r.sun on each. A cell's
  // ground: by class (its highest point at most kGroundTolerance above its highest class-2 point)
  // or by height (at most kGroundTolerance above the lowest point of it and its 8 neighbours;
  // autzen_trim's class 2 is sparse: most of the field's points are class 1). Raised: more than
  // 10 ft above the lowest point within 30 ft (crowns, the footbridge; autzen_trim has no building).
  const auto lowest_within = [&](std::size_t k, int reach) {
    const int r = int(k / std::size_t(dsm.cols)), q = int(k % std::size_t(dsm.cols));
    double low = std::numeric_limits<double>::infinity();
    for (int i = std::max(0, r - reach); i <= std::min(dsm.rows - 1, r + reach); ++i)
      for (int j = std::max(0, q - reach); j <= std::min(dsm.cols - 1, q + reach); ++j)
        low = std::min(low, top.low_z[std::size_t(i) * std::size_t(dsm.cols) + std::size_t(j)]);
    return low;
  };
  std::vector<double> all, open, open_class, obstructed, raised, steep;
  for (std::size_t k = 0; k < ours.size(); ++k) {
    if (!std::isfinite(ours[k]) || !std::isfinite(rsun.v[k]) || !(rsun.v[k] > 0.0)) continue;
    const double rel = (ours[k] - rsun.v[k]) / rsun.v[k];
    all.push_back(rel);
    const bool by_class = std::isfinite(top.ground_z[k]) && top.top_z[k] - top.ground_z[k] <= kGroundTolerance;
    const bool by_height = top.top_z[k] - lowest_within(k, 1) <= kGroundTolerance;
    const bool flat = std::isfinite(slope[k]) && slope[k] < kMaxSlopeDeg;
    const bool unobstructed = horizon[k] < kMaxHorizonDeg;
    if ((by_class || by_height) && flat) (unobstructed ? open : obstructed).push_back(rel);
    if (by_class && flat && unobstructed) open_class.push_back(rel);
    if (top.top_z[k] - lowest_within(k, 10) > 10.0) raised.push_back(rel);
    if (!flat) steep.push_back(rel);
  }
  const Agreement a_open = agreement(open), a_open_class = agreement(open_class);
  const double rsun_day = percentile(rsun_day_seconds, 0.5), rayscan_day = percentile(rayscan_seconds, 0.5);
  std::printf("autzen_trim, yearly global irradiation (15th of each month x days, 30 min), rayscan vs r.sun on "
              "rayscan's DSM (%d x %d cells of 3 ft):\n",
              dsm.cols, dsm.rows);
  print("open terrain (ground, slope < 15, horizon < 20)", a_open);
  print("  of which ground by class 2", a_open_class);
  print("ground, slope < 15, horizon >= 20 (obstructed)", agreement(obstructed));
  print("raised > 10 ft (crowns, the footbridge)", agreement(raised));
  print("DSM slope >= 15 or unknown", agreement(steep));
  print("every cell valid in both", agreement(all));
  std::printf("time per day (median of 12, one thread): r.sun %.2f s for %ld cells (%.1f us per cell), rayscan "
              "%.2f s for 110000 points (%.1f us per point); r.sun script %.1f s, in all %.1f s\n",
              rsun_day, rsun_cells, 1e6 * rsun_day / double(std::max(rsun_cells, 1L)), rayscan_day,
              1e6 * rayscan_day / 110000.0, rsun_total, seconds_since(t_all));
  RecordProperty("open_cells", std::to_string(a_open.n));
  RecordProperty("open_within_5pct", std::to_string(a_open.within));
  RecordProperty("open_median_rel", std::to_string(a_open.median));

  EXPECT_GE(a_open.n, 5000u) << "too few open cells for the comparison to mean something";
  EXPECT_GE(a_open.within, 0.95);
  EXPECT_GE(a_open_class.n, 1000u);
  EXPECT_GE(a_open_class.within, 0.95);
  EXPECT_LE(std::abs(a_open.median), 0.01);
}

}  // namespace
}  // namespace rayscan::solar_dsm_test
