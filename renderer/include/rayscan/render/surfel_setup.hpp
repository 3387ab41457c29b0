// Surfel mode for a loaded scene: per-point normals and radii for the
// scene's cloud and the switch of the render settings to oriented discs.
#pragma once

#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"

namespace rayscan::render {

/// Normals (the file's when the cloud has them, else PCA over the scene's k_normal neighbours) and
/// spacing radii for `cloud`, oriented as the scene's "surfel"/"orient" says (default: towards the
/// camera centre; "up": along the scene's up). `index` must be built over cloud.positions.
/// Throws std::invalid_argument (from estimate_surfels) for a cloud of fewer than 2 points.
SurfelAttributes scene_surfels(const Scene& scene, const AnyIndex& index, const PointCloud& cloud);
/// The same over a mapped index file (`cloud` = MappedIndex::to_point_cloud()): identical
/// attributes to the in-memory overload for the same points (estimate_surfels_over).
SurfelAttributes scene_surfels(const Scene& scene, const io::MappedIndex& index, const PointCloud& cloud);

/// Switch `settings` to Primitive::surfel over `attrs` (which must outlive the render). The
/// integrator's sphere radius becomes the median disc radius (it only scales the ray offset).
void use_surfels(RenderSettings& settings, const SurfelAttributes& attrs);

}  // namespace rayscan::render
