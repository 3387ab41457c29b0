#include "rayscan/render/surfel_setup.hpp"

#include <stdexcept>

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

SurfelAttributes scene_surfels(const Scene& scene, const Site& site, const PointCloud& cloud) {
  switch (site.storage()) {
    case SiteStorage::memory:  // the library's instances over AnyIndex (normals.cpp)
      return estimate_surfels(*site.memory_index(), cloud.positions, surfel_options(scene), cloud.normals);
    case SiteStorage::index_file:
      return estimate_surfels_over(*site.index_file(), cloud.positions, surfel_options(scene), cloud.normals);
    case SiteStorage::copc: break;
  }
  throw std::invalid_argument("surfels: a COPC file queried in place is not supported; read it into memory");
}

void use_surfels(RenderSettings& s, const SurfelAttributes& a) {
  s.integrator.primitive = Primitive::surfel;
  s.integrator.surfels = SurfelView{s.integrator.centers, a.normals, a.radii, a.max_radius, {}, a.thickness};
  if (a.median_radius > 0.0) s.integrator.radius = a.median_radius;
}

}  // namespace rayscan::render
