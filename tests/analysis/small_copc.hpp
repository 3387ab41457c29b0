// A small COPC file for the analyses' in-place tests: the south-west quarter of autzen_trim (tests/data/las,
// trees, houses and open ground; about a quarter of its 110,000 points) written as COPC with small
// nodes (io::write_copc, leaf_points 2000), so that the hierarchy has several levels and dozens of
// nodes, and a chunk of points or an image row reaches only some of them. Written once per test
// process into a temporary folder (removed at exit).
#pragma once

#include "../common/temp_dir.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/site/copc_writer.hpp"

#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace rayscan::analysis::test {

inline const std::filesystem::path& small_copc() {
  namespace fs = std::filesystem;
  static const fs::path path = [] {
    const fs::path dir = ::rayscan::test::process_temp_dir("rayscan_small_copc");
    static const std::string keep = dir.string();
    std::atexit([] { std::filesystem::remove_all(keep); });
    io::FileInfo info;
    const PointCloud all = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las", {}, &info);
    const AABB b = all.bounds();
    const Vec3 mid = b.lo + 0.5 * (b.hi - b.lo);
    PointCloud part;
    for (std::size_t i = 0; i < all.size(); ++i) {
      const Vec3& p = all.positions[i];
      if (p.x > mid.x || p.y > mid.y) continue;
      part.positions.push_back(p);
      if (!all.classification.empty()) part.classification.push_back(all.classification[i]);
    }
    part.crs_wkt = all.crs_wkt;
    const fs::path las = dir / "quarter.las", copc = dir / "quarter.copc.laz";
    io::write_point_cloud(las, part, io::las_grid_of(info));  // the source's integer grid
    io::CopcWriteOptions o;
    o.leaf_points = 2000;
    io::write_copc(las, copc, o);
    return copc;
  }();
  return path;
}

}  // namespace rayscan::analysis::test
