#include "rayscan/render/surfel_setup.hpp"

#include <utility>

namespace rayscan::render {

namespace {
/// The scene's surfel options with its up axis and, when asked, the camera centre as viewpoint.
SurfelOptions surfel_options(const Scene& scene) {
  SurfelOptions o = scene.surfel;
  o.orientation.up = scene.up;
  if (scene.surfel_orient_camera && scene.camera) o.orientation.viewpoint = scene.camera->center();
  return o;
}
}  // namespace

SurfelAttributes scene_surfels(const Scene& scene, const Site& site, const PointCloud& cloud,
                               decltype(SurfelOptions::progress) progress) {
  SurfelOptions o = surfel_options(scene);
  o.progress = std::move(progress);
  return estimate_surfels(site, cloud.positions, o, cloud.normals);
}

void use_surfels(RenderSettings& s, const SurfelAttributes& a) {
  s.integrator.primitive = Primitive::surfel;
  s.integrator.surfels = SurfelView{s.integrator.centers, a.normals, a.radii, a.max_radius, {}, a.thickness};
  if (a.median_radius > 0.0) s.integrator.radius = a.median_radius;
}

}  // namespace rayscan::render
