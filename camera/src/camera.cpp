#include "rayscan/camera/camera.hpp"

#include <glm/matrix.hpp>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace rayscan {

namespace {
void check_size(std::uint32_t w, std::uint32_t h) {
  if (w == 0 || h == 0) throw std::invalid_argument("camera: width and height must be > 0");
  if (w > 65536 || h > 65536) throw std::invalid_argument("camera: width and height must be <= 65536");
}
}  // namespace

Camera Camera::look_at(const LookAtParams& p, std::uint32_t width, std::uint32_t height) {
  check_size(width, height);
  if (!is_finite(p.position) || !is_finite(p.look_at) || !is_finite(p.up))
    throw std::invalid_argument("camera: position, look_at and up must be finite");
  if (!(p.vfov_deg > 0.0 && p.vfov_deg < 180.0))
    throw std::invalid_argument("camera: vfov_deg must be in (0, 180)");
  if (!(p.aperture >= 0.0)) throw std::invalid_argument("camera: aperture must be >= 0");
  if (!(p.focus_distance >= 0.0)) throw std::invalid_argument("camera: focus_distance must be >= 0");
  const Vec3 view = p.look_at - p.position;
  const double dist = glm::length(view);
  if (!(dist > 0.0)) throw std::invalid_argument("camera: look_at must differ from position");
  const Vec3 w = view / dist;  // camera +z (forward)
  const Vec3 side = glm::cross(w, p.up);
  const double side_len = glm::length(side);
  if (!(side_len > 1e-9 * glm::length(p.up)))
    throw std::invalid_argument("camera: up must not be parallel to the viewing direction");
  const Vec3 right = side / side_len;          // camera +x
  const Vec3 down = glm::cross(w, right);      // camera +y (OpenCV: y down)
  // Focal length in pixels from the vertical field of view; square pixels.
  const double f = 0.5 * double(height) / std::tan(0.5 * p.vfov_deg * std::numbers::pi / 180.0);
  const double cx = 0.5 * (double(width) - 1.0), cy = 0.5 * (double(height) - 1.0);
  Camera c;
  c.width_ = width;
  c.height_ = height;
  c.center_ = p.position;
  // d = right (u - cx)/f + down (v - cy)/f + w  (= R^T K^-1 (u, v, 1)).
  c.pixel_to_dir_ = glm::dmat3(right / f, down / f, w - right * (cx / f) - down * (cy / f));
  c.forward_ = w;
  c.lens_x_ = right;
  c.lens_y_ = down;
  c.lens_radius_ = 0.5 * p.aperture;
  c.focus_distance_ = p.focus_distance > 0.0 ? p.focus_distance : dist;
  return c;
}

Camera Camera::pinhole(const PinholeParams& p, std::uint32_t width, std::uint32_t height) {
  check_size(width, height);
  glm::dmat3 K, R;  // glm is column-major: m[col][row]
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      K[c][r] = p.K[r][c];
      R[c][r] = p.R[r][c];
      if (!std::isfinite(p.K[r][c]) || !std::isfinite(p.R[r][c]))
        throw std::invalid_argument("camera: K and R must be finite");
    }
  if (!is_finite(p.t)) throw std::invalid_argument("camera: t must be finite");
  if (p.K[2][0] != 0.0 || p.K[2][1] != 0.0 || p.K[2][2] != 1.0)
    throw std::invalid_argument("camera: the last row of K must be (0, 0, 1)");
  if (!(std::abs(glm::determinant(K)) > 0.0)) throw std::invalid_argument("camera: K is singular");
  const glm::dmat3 RtR = glm::transpose(R) * R;
  double err = 0.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) err = std::max(err, std::abs(RtR[c][r] - (r == c ? 1.0 : 0.0)));
  if (err > 1e-6 || glm::determinant(R) < 0.0)
    throw std::invalid_argument("camera: R must be a rotation matrix (orthonormal, det +1)");
  Camera c;
  c.width_ = width;
  c.height_ = height;
  const glm::dmat3 Rt = glm::transpose(R);
  c.center_ = -(Rt * p.t);  // C = -R^T t
  c.pixel_to_dir_ = Rt * glm::inverse(K);
  c.forward_ = glm::normalize(Rt * Vec3(0, 0, 1));
  c.lens_x_ = Rt * Vec3(1, 0, 0);
  c.lens_y_ = Rt * Vec3(0, 1, 0);
  return c;
}

Ray Camera::generate_ray(double u, double v, double lens_u, double lens_v) const {
  if (projection_ != Projection::perspective || distortion_.any()) return generate_special(u, v);
  const Vec3 d = pixel_to_dir_ * Vec3(u, v, 1.0);
  if (lens_radius_ <= 0.0) return Ray(center_, d);
  // Thin lens (RTIOW section 12; pbrt-v4 section 5.2.3): the point at depth focus_distance along
  // the pinhole ray stays sharp; the origin moves on a disk of radius lens_radius (concentric-free
  // polar mapping, r = R sqrt(u)).
  const double t_focus = focus_distance_ / glm::dot(d, forward_);
  const Vec3 focus = center_ + t_focus * d;
  const double rad = lens_radius_ * std::sqrt(lens_u);
  const double phi = 2.0 * std::numbers::pi * lens_v;
  const Vec3 o = center_ + rad * (std::cos(phi) * lens_x_ + std::sin(phi) * lens_y_);
  return Ray(o, focus - o);
}

Camera Camera::pinhole_distorted(const PinholeParams& p, const LensDistortion& k, std::uint32_t width,
                                 std::uint32_t height) {
  Camera c = pinhole(p, width, height);
  glm::dmat3 K, R;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) {
      K[col][r] = p.K[r][col];
      R[col][r] = p.R[r][col];
    }
  c.k_inv_ = glm::inverse(K);
  c.r_t_ = glm::transpose(R);
  c.distortion_ = k;
  return c;
}

Ray Camera::generate_special(double u, double v) const {
  switch (projection_) {
    case Projection::orthographic:
      return Ray(origin00_ + u * step_u_ + v * step_v_, forward_);
    case Projection::equirectangular: {
      // Pixel centres at longitude 2 pi ((u + 0.5) / W - 0.5), latitude pi (0.5 - (v + 0.5) / H).
      const double lon = 2.0 * std::numbers::pi * ((u + 0.5) / double(width_) - 0.5);
      const double lat = std::numbers::pi * (0.5 - (v + 0.5) / double(height_));
      const Vec3 d = std::cos(lat) * (std::cos(lon) * forward_ + std::sin(lon) * right_) + std::sin(lat) * up_;
      return Ray(center_, d);
    }
    case Projection::perspective: break;
  }
  // Distorted pinhole: K^-1 gives distorted normalised coordinates; undistort, then rotate.
  const Vec3 xd = k_inv_ * Vec3(u, v, 1.0);
  const glm::dvec2 x = undistort(distortion_, glm::dvec2(xd.x / xd.z, xd.y / xd.z));
  return Ray(center_, r_t_ * Vec3(x.x, x.y, 1.0));
}

Camera Camera::resized(std::uint32_t width, std::uint32_t height) const {
  check_size(width, height);
  const double sx = double(width) / double(width_), sy = double(height) / double(height_);
  // New pixel coordinates u' = sx (u + 0.5) - 0.5: old (u, v, 1) = A^-1 (u', v', 1).
  glm::dmat3 Ainv(1.0);
  Ainv[0][0] = 1.0 / sx;
  Ainv[1][1] = 1.0 / sy;
  Ainv[2][0] = (0.5 - 0.5 * sx) / sx;
  Ainv[2][1] = (0.5 - 0.5 * sy) / sy;
  Camera c = *this;
  c.width_ = width;
  c.height_ = height;
  c.pixel_to_dir_ = pixel_to_dir_ * Ainv;
  c.k_inv_ = k_inv_ * Ainv;
  // Orthographic: the same plane in the new pixel grid (origin of pixel (0, 0) and steps).
  c.origin00_ = origin00_ + step_u_ * Ainv[2][0] + step_v_ * Ainv[2][1];
  c.step_u_ = step_u_ / sx;
  c.step_v_ = step_v_ / sy;
  return c;
}

}  // namespace rayscan
