// Orthographic cameras (pbrt-v4 section 5.2.1 "Orthographic Camera"): parallel rays whose origins
// lie on the image plane; a top-down grid of them is a true orthophoto.
#include "rayscan/camera/camera.hpp"

#include <cmath>
#include <stdexcept>

namespace rayscan {


Camera Camera::orthographic_grid(const Vec3& origin00, const Vec3& step_u, const Vec3& step_v,
                                 const Vec3& direction, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide)
    throw std::invalid_argument("camera: width and height must be in [1, 65536]");
  if (!is_finite(origin00) || !is_finite(step_u) || !is_finite(step_v) || !is_finite(direction) ||
      glm::length(step_u) == 0.0 || glm::length(step_v) == 0.0 || glm::length(direction) == 0.0)
    throw std::invalid_argument("camera: orthographic origin, steps and direction must be finite and non-zero");
  Camera c;
  c.projection_ = Projection::orthographic;
  c.width_ = width;
  c.height_ = height;
  c.origin00_ = origin00;
  c.step_u_ = step_u;
  c.step_v_ = step_v;
  c.forward_ = glm::normalize(direction);
  c.center_ = origin00 + step_u * (0.5 * (double(width) - 1.0)) + step_v * (0.5 * (double(height) - 1.0));
  c.desc_.model = CameraModel::orthographic_grid;
  return c;
}

Camera Camera::orthographic(const OrthographicParams& p, std::uint32_t width, std::uint32_t height) {
  if (!is_finite(p.position) || !is_finite(p.look_at) || !is_finite(p.up))
    throw std::invalid_argument("camera: position, look_at and up must be finite");
  if (!(p.view_height > 0.0) || !std::isfinite(p.view_height))
    throw std::invalid_argument("camera: view_height must be a finite number > 0");
  const Vec3 view = p.look_at - p.position;
  if (!(glm::length(view) > 0.0)) throw std::invalid_argument("camera: look_at must differ from position");
  const Vec3 w = glm::normalize(view);
  const Vec3 side = glm::cross(w, p.up);
  if (!(glm::length(side) > 1e-9 * glm::length(p.up)))
    throw std::invalid_argument("camera: up must not be parallel to the viewing direction");
  const Vec3 right = glm::normalize(side);
  const Vec3 down = glm::cross(w, right);
  if (width == 0 || height == 0) throw std::invalid_argument("camera: width and height must be > 0");
  const double px = p.view_height / double(height);  // square pixels, world units
  const Vec3 o00 = p.position - right * (px * 0.5 * (double(width) - 1.0)) - down * (px * 0.5 * (double(height) - 1.0));
  Camera c = orthographic_grid(o00, right * px, down * px, w, width, height);
  c.desc_.model = CameraModel::orthographic;
  c.desc_.orthographic = p;
  return c;
}

}  // namespace rayscan
