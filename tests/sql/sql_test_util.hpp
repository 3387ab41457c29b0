// Shared pieces of the SQL tests: data files, the import through the real CLI, query rays and the
// brute-force oracle (rayscan::ray_query over BruteForceIndex, and plain loops).
#pragma once

#include "../common/run_command.hpp"

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace rayscan::sqltest {

namespace fs = std::filesystem;

/// The real scans of the SQL tests: autzen (tests/data), lone-star (../shared/data/las/derived,
/// skipped when absent) and the PDRF 8 file append-bug (the decompressed LAS from ../shared when
/// present, else the same points from the bundled tests/data/laz/append-bug.laz).
inline std::vector<std::string> scan_names() { return {"autzen", "lone_star", "pdrf8_append_bug"}; }

/// Path of a scan, or "" when it is not available.
inline fs::path scan_path(const std::string& name) {
  fs::path p;
  if (name == "autzen") p = fs::path(RAYSCAN_TEST_DATA) / "las/autzen_trim.las";
  else if (name == "lone_star") p = fs::path(RAYSCAN_SHARED_DATA) / "las/derived/lone-star.las";
  else {
    p = fs::path(RAYSCAN_SHARED_DATA) / "las/derived/append-bug.las";
    if (!fs::exists(p)) p = fs::path(RAYSCAN_TEST_DATA) / "laz/append-bug.laz";
  }
  return fs::exists(p) ? p : fs::path();
}

/// Runs a shell command, returning its exit code.
inline int run(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// The CRS `rayscan info --json` reports for a cloud: the oracle of what an import stores.
struct InfoCrs {
  std::string wkt;  ///< crs.wkt, "" when the file has none
  int epsg = 0;     ///< crs.epsg (the horizontal EPSG code), 0 when none is identified
};
inline InfoCrs info_crs(const fs::path& p) {
  const auto r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " info --json " + rayscan::test::quoted(p), false);
  EXPECT_EQ(r.code, 0) << p;
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  InfoCrs c;
  if (j.is_object() && j.contains("crs")) {
    c.wkt = j["crs"].value("wkt", "");
    c.epsg = j["crs"].value("epsg", 0);
  }
  return c;
}

/// One line of `rayscan db import`'s progress into a log: the phase and its counts.
struct PhaseLine {
  std::string phase;
  std::uint64_t done = 0, total = 0;
};

/// The progress lines of a `db import`'s stderr (not a terminal: one line per phase, and one every
/// few seconds while a long phase runs; such repeats of a phase are merged, keeping the last).
/// Fails the test for a line that is not a progress line.
inline std::vector<PhaseLine> progress_phases(const std::string& err) {
  // "<phase> <pct>%  <done> / <total> points  <rate> M points/s", or "<phase> <done> points" for a
  // phase without a total (the index's "scan").
  static const std::regex line(R"(db import: (\w+) +(?:[0-9.]+%  ([0-9]+) / ([0-9]+)|([0-9]+)) points(?:  [0-9.]+ M points/s)?)");
  std::vector<PhaseLine> out;
  std::istringstream in(err);
  for (std::string l; std::getline(in, l);) {
    std::smatch m;
    if (!std::regex_match(l, m, line)) {
      ADD_FAILURE() << "not a progress line: " << l;
      continue;
    }
    PhaseLine p{m[1], std::stoull(m[2].matched ? m[2].str() : m[4].str()), m[3].matched ? std::stoull(m[3]) : 0};
    if (!out.empty() && out.back().phase == p.phase) out.back() = p;
    else out.push_back(p);
  }
  return out;
}

/// Checks the progress of an import of `points` points: the temporary index's phases (`index`:
/// an import of clouds, not of an index file), each of every point, then insert, index and done,
/// each of every point and each once; no phase of another unit (the index's "spacing").
inline void expect_import_phases(const std::string& err, std::uint64_t points, bool index) {
  const std::vector<PhaseLine> p = progress_phases(err);
  ASSERT_GE(p.size(), 3u) << err;
  std::vector<std::string> tail;
  for (std::size_t i = p.size() - 3; i < p.size(); ++i) tail.push_back(p[i].phase);
  EXPECT_EQ(tail, (std::vector<std::string>{"insert", "index", "done"})) << err;
  static const std::vector<std::string> kIndexPhases{"scan", "read", "sort", "write", "merge", "nodes"};
  for (std::size_t i = 0; i + 3 < p.size(); ++i)
    EXPECT_NE(std::find(kIndexPhases.begin(), kIndexPhases.end(), p[i].phase), kIndexPhases.end()) << err;
  EXPECT_EQ(p.size() > 3, index) << err;
  for (const PhaseLine& l : p) {
    EXPECT_EQ(l.done, points) << l.phase << "\n" << err;
    if (l.phase != "scan") {
      EXPECT_EQ(l.total, points) << l.phase << "\n" << err;
    }
  }
}

/// Query rays of a scan: origins above the cloud, aimed at points of the cloud (so queries hit).
inline std::vector<Ray> query_rays(const PointCloud& c, int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, c.size() - 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const AABB b = c.bounds();
  const Vec3 e = b.extent();
  std::vector<Ray> rays;
  for (int i = 0; i < n; ++i) {
    const Vec3 target = c.positions[pick(rng)];
    const Vec3 o(b.lo.x + u(rng) * e.x, b.lo.y + u(rng) * e.y, b.hi.z + 0.3 * b.max_extent());
    rays.emplace_back(o, target - o);
  }
  return rays;
}

/// A radius of about the point spacing: sqrt(area per point) of the xy footprint.
inline double spacing(const PointCloud& c) {
  const Vec3 e = c.bounds().extent();
  return std::sqrt(std::max(e.x * e.y, 1e-12) / double(c.size()));
}

}  // namespace rayscan::sqltest
