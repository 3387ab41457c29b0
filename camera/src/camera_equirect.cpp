// Equirectangular (latitude-longitude) panoramas: the 360 x 180 degree view of a scanner station
// (pbrt-v4 section 5.3 "Spherical Camera", equirectangular mapping).
#include "rayscan/camera/camera.hpp"

#include <cmath>
#include <stdexcept>

namespace rayscan {

Camera Camera::equirectangular(const EquirectangularParams& p, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide)
    throw std::invalid_argument("camera: width and height must be in [1, 65536]");
  if (!is_finite(p.position) || !is_finite(p.look_at) || !is_finite(p.up) || glm::length(p.up) == 0.0)
    throw std::invalid_argument("camera: position, look_at and up must be finite, up non-zero");
  const Vec3 forward = p.look_at - p.position;
  const Vec3 up = glm::normalize(p.up);
  const Vec3 horiz = forward - glm::dot(forward, up) * up;
  if (!(glm::length(horiz) > 1e-9 * glm::length(forward)))
    throw std::invalid_argument("camera: look_at - position must not be parallel to up");
  Camera c;
  c.projection_ = Projection::equirectangular;
  c.width_ = width;
  c.height_ = height;
  c.center_ = p.position;
  c.forward_ = glm::normalize(horiz);
  c.up_ = up;
  c.right_ = glm::cross(c.forward_, up);
  c.desc_.model = CameraModel::equirectangular;
  c.desc_.equirectangular = p;
  return c;
}

}  // namespace rayscan
