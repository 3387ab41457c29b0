#include "rayscan/octree/point_cloud.hpp"

#include <stdexcept>

namespace rayscan {

AABB bounds_of(std::span<const Vec3> points) {
  AABB b;
  for (const Vec3& p : points) b.expand(p);
  return b;
}

AABB PointCloud::bounds() const { return bounds_of(positions); }

const ScalarField* PointCloud::scalar(const std::string& name) const {
  for (const ScalarField& f : scalars)
    if (f.name == name) return &f;
  return nullptr;
}

namespace {
template <class V>
void check_len(const V& v, std::size_t n, const char* what) {
  if (!v.empty() && v.size() != n)
    throw std::invalid_argument(std::string("PointCloud: attribute '") + what + "' has " +
                                std::to_string(v.size()) + " values for " + std::to_string(n) +
                                " points");
}
}  // namespace

void PointCloud::validate() const {
  const std::size_t n = positions.size();
  check_len(rgb, n, "rgb");
  check_len(intensity, n, "intensity");
  check_len(classification, n, "classification");
  check_len(gps_time, n, "gps_time");
  check_len(normals, n, "normals");
  for (const ScalarField& f : scalars) check_len(f.values, n, f.name.c_str());
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw std::invalid_argument("PointCloud: point " + std::to_string(i) +
                                  " has a non-finite coordinate");
  }
}

}  // namespace rayscan
