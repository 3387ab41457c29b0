// Cameras: the look-at thin-lens camera of Ray Tracing in One Weekend (sections 11-12) and the
// photogrammetric pinhole with intrinsic matrix K and extrinsic [R|t] (OpenCV convention, Hartley &
// Zisserman, "Multiple View Geometry", 2nd ed., section 6.1), both reduced to one ray generator.
#pragma once

#include "rayscan/ray.hpp"

#include <glm/mat3x3.hpp>

#include <array>
#include <cstdint>

namespace rayscan {

/// Look-at camera description (RTIOW "positionable camera" and "defocus blur").
struct LookAtParams {
  Vec3 position{0.0};           ///< eye, world coordinates
  Vec3 look_at{0.0, 0.0, -1.0}; ///< point the view centre passes through, world coordinates
  Vec3 up{0.0, 0.0, 1.0};       ///< world up (must not be parallel to look_at - position)
  double vfov_deg = 40.0;       ///< vertical field of view, degrees, in (0, 180)
  double aperture = 0.0;        ///< lens diameter, world units (0 = pinhole)
  double focus_distance = 0.0;  ///< distance to the plane in focus, world units (0 = |look_at - position|)
};

/// Photogrammetric pinhole: x_cam = R x_world + t, pixel ~ K x_cam (OpenCV: camera x right, y down,
/// z forward; pixel (0,0) is the centre of the top-left pixel).
struct PinholeParams {
  std::array<std::array<double, 3>, 3> K{};  ///< intrinsics, pixels; K[2] must be (0, 0, 1)
  std::array<std::array<double, 3>, 3> R{};  ///< world-to-camera rotation (orthonormal, det +1)
  Vec3 t{0.0};                               ///< world-to-camera translation, world units
};

/// A camera that maps continuous pixel coordinates to world rays.
///
/// Pixel coordinates follow OpenCV: the centre of pixel (i, j) (column i, row j from the top) is at
/// (i, j); a pixel covers [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]. Internally a pinhole ray has
/// origin C (the centre of projection) and direction M (u, v, 1) with M = R^T K^-1, so look-at and
/// K/[R|t] descriptions of the same pose produce the same rays.
class Camera {
 public:
  /// Look-at camera of `width` x `height` pixels (square pixels, principal point at the image
  /// centre ((width-1)/2, (height-1)/2)). Throws std::invalid_argument for a zero size, vfov outside
  /// (0, 180), coincident position/look_at, up parallel to the view direction, or negative aperture.
  static Camera look_at(const LookAtParams& p, std::uint32_t width, std::uint32_t height);
  /// K/[R|t] camera. Throws std::invalid_argument for a zero size, a singular K or K[2] != (0,0,1),
  /// or an R that is not a rotation (|R^T R - I| > 1e-6 or det < 0).
  static Camera pinhole(const PinholeParams& p, std::uint32_t width, std::uint32_t height);

  /// The ray through continuous pixel coordinates (u, v); lens_u, lens_v in [0,1) pick a point on
  /// the aperture disk (ignored for a pinhole). Direction is unit length (Ray normalises).
  [[nodiscard]] Ray generate_ray(double u, double v, double lens_u = 0.5, double lens_v = 0.5) const;

  /// Image width in pixels.
  [[nodiscard]] std::uint32_t width() const { return width_; }
  /// Image height in pixels.
  [[nodiscard]] std::uint32_t height() const { return height_; }
  /// Centre of projection, world coordinates.
  [[nodiscard]] const Vec3& center() const { return center_; }
  /// Unit viewing direction (camera +z).
  [[nodiscard]] const Vec3& forward() const { return forward_; }
  /// Returns a copy with another image size, scaling the intrinsics so the field of view is kept.
  [[nodiscard]] Camera resized(std::uint32_t width, std::uint32_t height) const;

 private:
  Camera() = default;
  std::uint32_t width_ = 0, height_ = 0;
  Vec3 center_{0.0};
  glm::dmat3 pixel_to_dir_{1.0};  // M = R^T K^-1: (u, v, 1) -> world direction (not unit)
  Vec3 forward_{0.0, 0.0, 1.0};
  Vec3 lens_x_{1.0, 0.0, 0.0}, lens_y_{0.0, 1.0, 0.0};  // aperture basis (unit)
  double lens_radius_ = 0.0, focus_distance_ = 1.0;
};

}  // namespace rayscan
