// OpenCV's lens distortion model (OpenCV documentation, "Camera Calibration and 3D Reconstruction",
// calib3d module: radial k1, k2, k3 and tangential p1, p2 on normalised image coordinates; Brown
// 1966 / Conrady 1919), as COLMAP's OPENCV, RADIAL and SIMPLE_RADIAL camera models use it.
#pragma once

#include <glm/vec2.hpp>

namespace rayscan {

/// Distortion coefficients (dimensionless, on normalised coordinates x = X/Z, y = Y/Z).
struct LensDistortion {
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0, k3 = 0.0;
  /// True when any coefficient is non-zero.
  [[nodiscard]] bool any() const { return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0; }
};

/// Distorted normalised coordinates of undistorted (x, y):
/// r^2 = x^2 + y^2, radial = 1 + k1 r^2 + k2 r^4 + k3 r^6,
/// x' = x radial + 2 p1 x y + p2 (r^2 + 2 x^2), y' = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y.
[[nodiscard]] glm::dvec2 distort(const LensDistortion& k, const glm::dvec2& xy);

/// Inverse of distort() by Newton's method with the analytic Jacobian (at most 20 steps, stops at
/// 1e-14): the undistorted normalised coordinates whose distortion is `xy_d`. Within the
/// monotonic range of the model the result satisfies |distort(result) - xy_d| < 1e-12.
[[nodiscard]] glm::dvec2 undistort(const LensDistortion& k, const glm::dvec2& xy_d);

}  // namespace rayscan
