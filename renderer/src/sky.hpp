// Environment lighting: the sky gradient of Ray Tracing in One Weekend (section 4.2) or a constant
// background, plus an optional sun disk sampled by shadow rays (next-event estimation, pbrt-v4
// section 13.4 / "Ray Tracing: The Next Week" lights chapter).
#pragma once

#include "rayscan/render/color.hpp"
#include "rayscan/render/scene.hpp"

#include <cmath>
#include <numbers>

namespace rayscan::render {

/// The sky as seen by escaping rays, and the sun as a small cone light.
class Sky {
 public:
  /// `up` is the world up used by the gradient; must be unit length.
  Sky(const BackgroundDesc& bg, const SunDesc& sun, const Vec3& up)
      : bg_(bg), sun_(sun), up_(up) {
    const double half = 0.5 * sun.angular_diameter_deg * std::numbers::pi / 180.0;
    cos_half_ = std::cos(half);
    const double solid_angle = 2.0 * std::numbers::pi * (1.0 - cos_half_);
    sun_e_ = sun.color * sun.irradiance;
    sun_l_ = solid_angle > 0.0 ? sun_e_ / float(solid_angle) : Color(0.0f);
    // Orthonormal frame around the sun direction for cone sampling.
    const Vec3 w = sun.direction;
    const Vec3 a = std::abs(w.x) > 0.9 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
    su_ = glm::normalize(glm::cross(a, w));
    sv_ = glm::cross(w, su_);
  }

  /// Background radiance along unit direction d (sun excluded). Gradient: lerp(horizon, zenith, a)
  /// with a = (d.up + 1) / 2, as RTIOW's "blended value".
  [[nodiscard]] Color background(const Vec3& d) const {
    if (!bg_.gradient) return bg_.color * bg_.intensity;
    const float a = static_cast<float>(0.5 * (glm::dot(d, up_) + 1.0));
    return ((1.0f - a) * bg_.horizon + a * bg_.zenith) * bg_.intensity;
  }
  /// Radiance of the sun disk along d (0 outside the disk or for a zero-size sun): E / solid angle.
  [[nodiscard]] Color sun_disk(const Vec3& d) const {
    if (!sun_.enabled || glm::dot(d, sun_.direction) < cos_half_) return Color(0.0f);
    return sun_l_;
  }
  /// True when a sun is present.
  [[nodiscard]] bool has_sun() const { return sun_.enabled && sun_.irradiance > 0.0f; }
  /// A direction towards the sun, uniform over its cone (u1, u2 uniform in [0,1)).
  [[nodiscard]] Vec3 sample_sun(double u1, double u2) const {
    const double cos_t = 1.0 - u1 * (1.0 - cos_half_);
    const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
    const double phi = 2.0 * std::numbers::pi * u2;
    return sin_t * std::cos(phi) * su_ + sin_t * std::sin(phi) * sv_ + cos_t * sun_.direction;
  }
  /// Sun irradiance on a surface facing it (colour x irradiance).
  [[nodiscard]] const Color& sun_irradiance() const { return sun_e_; }

 private:
  BackgroundDesc bg_;
  SunDesc sun_;
  Vec3 up_;
  double cos_half_ = 1.0;
  Color sun_e_{0.0f}, sun_l_{0.0f};
  Vec3 su_{1, 0, 0}, sv_{0, 1, 0};
};

}  // namespace rayscan::render
