// Shared test data of the renderer tests.
#pragma once

#include "rayscan/io/point_io.hpp"
#include "rayscan/point_cloud.hpp"

#include <filesystem>

namespace rayscan::render::test {

/// The bundled autzen subset (tests/render/data/autzen_subset.xyz: trees and ground, feet), read
/// once per test process.
inline const PointCloud& subset() {
  static const PointCloud pc =
      io::read_point_cloud(std::filesystem::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz");
  return pc;
}

}  // namespace rayscan::render::test
