// Shared pieces of the SQL tests: data files, the import through the real CLI, query rays and the
// brute-force oracle (rayscan::ray_query over BruteForceIndex, and plain loops).
#pragma once

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <random>
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
