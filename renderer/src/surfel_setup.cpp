#include "rayscan/render/surfel_setup.hpp"

namespace rayscan::render {

SurfelAttributes scene_surfels(const Scene& scene, const AnyIndex& index, const PointCloud& cloud) {
  SurfelOptions o = scene.surfel;
  o.orientation.up = scene.up;
  if (scene.surfel_orient_camera && scene.camera) o.orientation.viewpoint = scene.camera->center();
  return estimate_surfels(index, cloud.positions, o, cloud.normals);
}

void use_surfels(RenderSettings& s, const SurfelAttributes& a) {
  s.integrator.primitive = Primitive::surfel;
  s.integrator.surfels = SurfelView{s.integrator.centers, a.normals, a.radii, a.max_radius};
  if (a.median_radius > 0.0) s.integrator.radius = a.median_radius;
}

}  // namespace rayscan::render
