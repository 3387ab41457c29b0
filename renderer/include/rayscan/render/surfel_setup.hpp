// Surfel mode for a loaded scene: per-point normals and radii for the
// scene's cloud and the switch of the render settings to oriented discs.
#pragma once

#include "rayscan/octree/normals.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"

namespace rayscan::render {

/// Normals (the file's when the cloud has them, else PCA over the scene's k_normal neighbours) and
/// spacing radii for `cloud`, the site's points in original order (for an index file:
/// MappedIndex::to_point_cloud()), oriented as the scene's "surfel"/"orient" says (default: towards
/// the camera centre; "up": along the scene's up). The same attributes for any storage of the same
/// points (estimate_surfels_over). Throws std::invalid_argument (from estimate_surfels) for a cloud
/// of fewer than 2 points, and for a COPC site in place (surfels read the file into memory).
/// `progress`: the estimate's progress reports (SurfelOptions::progress), none when empty.
SurfelAttributes scene_surfels(const Scene& scene, const Site& site, const PointCloud& cloud,
                               decltype(SurfelOptions::progress) progress = {});

/// Switch `settings` to Primitive::surfel over `attrs` (which must outlive the render). The
/// integrator's sphere radius becomes the median disc radius (it only scales the ray offset).
void use_surfels(RenderSettings& settings, const SurfelAttributes& attrs);

}  // namespace rayscan::render
