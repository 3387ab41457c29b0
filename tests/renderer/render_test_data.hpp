// Shared test data of the renderer tests.
#pragma once

#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/render/scene.hpp"

#include <filesystem>

namespace rayscan::render::test {

/// The bundled autzen subset (tests/renderer/data/autzen_subset.xyz: trees and ground, feet), read
/// once per test process.
inline const PointCloud& subset() {
  static const PointCloud pc =
      io::read_point_cloud(std::filesystem::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz");
  return pc;
}

/// Oblique view of the 60 x 60 ft autzen subset (trees and ground), w x h px, with a sun; 3 spp,
/// max_depth 3, seed 12345.
inline Scene subset_scene(std::uint32_t w, std::uint32_t h) {
  const AABB b = subset().bounds();
  LookAtParams la;
  la.position = b.center() + Vec3(-45.0, -60.0, 50.0);
  la.look_at = b.center();
  la.vfov_deg = 50.0;
  Scene s;
  s.camera = Camera::look_at(la, w, h);
  s.sun.enabled = true;
  s.sun.direction = glm::normalize(Vec3(0.5, -0.3, 0.8));
  s.spp = 3;
  s.max_depth = 3;
  s.seed = 12345;
  return s;
}

}  // namespace rayscan::render::test
