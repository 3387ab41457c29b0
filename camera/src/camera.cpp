#include "rayscan/camera/camera.hpp"

#include "rayscan/base/option_error.hpp"

#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

namespace rayscan {

namespace {
void check_size(std::uint32_t w, std::uint32_t h) {
  if (w == 0 || h == 0) throw std::invalid_argument("camera: width and height must be > 0");
  if (w > kMaxImageSide || h > kMaxImageSide) throw std::invalid_argument("camera: width and height must be <= " + std::to_string(kMaxImageSide));
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
  c.desc_.model = CameraModel::look_at;
  c.desc_.look_at = p;
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
  c.desc_.model = CameraModel::pinhole;
  c.desc_.pinhole = p;
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
  c.desc_.distortion = k;
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

ImageSize fit_image_size(ImageSize current, std::optional<std::uint32_t> width, std::optional<std::uint32_t> height) {
  if (!width && !height) return current;
  // In double, then checked: a 1x65536 camera with a width of 65536 asks for a height of 2^32,
  // which must be an error, not a wrapped 32-bit integer.
  const double w = width ? double(*width) : std::round(double(current.width) * *height / current.height);
  const double h = height ? double(*height) : std::round(double(current.height) * *width / current.width);
  for (const auto& [v, name] : {std::pair{w, "width"}, std::pair{h, "height"}})
    if (!(v >= 1.0 && v <= double(kMaxImageSide)))
      throw OptionError({"the camera's aspect ratio " + std::to_string(current.width) + ":" +
                             std::to_string(current.height) + " gives an image " + name + " of " +
                             std::to_string(static_cast<long long>(std::min(v, 1e18))) +
                             " pixels, expected 1 to 65536; give both ",
                         option("width"), " and ", option("height")});
  return {static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h)};
}

Camera Camera::resized(std::optional<std::uint32_t> width, std::optional<std::uint32_t> height) const {
  const ImageSize s = fit_image_size({width_, height_}, width, height);
  return resized(s.width, s.height);
}

Camera Camera::resized(std::uint32_t width, std::uint32_t height) const {
  check_size(width, height);
  switch (desc_.model) {
    case CameraModel::look_at: return look_at(desc_.look_at, width, height);
    case CameraModel::orthographic: return orthographic(desc_.orthographic, width, height);
    case CameraModel::equirectangular: return equirectangular(desc_.equirectangular, width, height);
    case CameraModel::pinhole: {
      // New pixel coordinates u' = sx (u + 0.5) - 0.5 (pixel edges stay on the same rays):
      // K' = A K with A = [[sx, 0, (sx - 1) / 2], [0, sy, (sy - 1) / 2], [0, 0, 1]].
      const double sx = double(width) / double(width_), sy = double(height) / double(height_);
      PinholeParams p = desc_.pinhole;
      for (int c = 0; c < 3; ++c) {
        p.K[0][c] = sx * p.K[0][c] + 0.5 * (sx - 1.0) * p.K[2][c];
        p.K[1][c] = sy * p.K[1][c] + 0.5 * (sy - 1.0) * p.K[2][c];
      }
      return desc_.distortion.any() ? pinhole_distorted(p, desc_.distortion, width, height) : pinhole(p, width, height);
    }
    case CameraModel::orthographic_grid: break;
  }
  // A grid keeps the covered plane: the origin of pixel (0, 0) and the steps in the new grid.
  const double sx = double(width) / double(width_), sy = double(height) / double(height_);
  const Vec3 su = step_u_ / sx, sv = step_v_ / sy;
  const Vec3 o00 = origin00_ + step_u_ * ((0.5 - 0.5 * sx) / sx) + step_v_ * ((0.5 - 0.5 * sy) / sy);
  return orthographic_grid(o00, su, sv, forward_, width, height);
}

}  // namespace rayscan
