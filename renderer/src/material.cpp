#include "rayscan/render/material.hpp"

#include <algorithm>
#include <stdexcept>

namespace rayscan::render {

namespace {
std::array<double, 2> percentile_range(std::vector<double> v) {
  if (v.empty()) return {0.0, 1.0};
  const std::size_t lo = v.size() * 2 / 100, hi = std::min(v.size() - 1, v.size() * 98 / 100);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(lo), v.end());
  const double a = v[lo];
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(hi), v.end());
  const double b = v[hi];
  return {a, b > a ? b : a + 1.0};
}
}  // namespace

std::vector<Color> compute_albedo(const PointCloud& cloud, const MaterialDesc& m, const Vec3& up) {
  const std::size_t n = cloud.size();
  std::vector<Color> albedo(n, m.constant);
  switch (m.mode) {
    case ColorMode::constant: break;
    case ColorMode::rgb: {
      if (cloud.rgb.size() != n)
        throw std::invalid_argument("material color \"rgb\": the cloud has no RGB colours (use "
                                    "\"elevation\", \"intensity\" or a constant [r, g, b])");
      std::uint16_t mx = 0;
      for (const Rgb16& c : cloud.rgb) mx = std::max({mx, c.r, c.g, c.b});
      const float scale = mx <= 255 ? 1.0f / 255.0f : 1.0f / 65535.0f;
      // Decode through a table: 65536 entries at most, shared by all points.
      std::vector<float> lut(mx <= 255 ? 256 : 65536);
      for (std::size_t i = 0; i < lut.size(); ++i) lut[i] = srgb_to_linear(float(i) * scale);
      for (std::size_t i = 0; i < n; ++i)
        albedo[i] = {lut[cloud.rgb[i].r], lut[cloud.rgb[i].g], lut[cloud.rgb[i].b]};
      break;
    }
    case ColorMode::classification:
      if (cloud.classification.size() != n)
        throw std::invalid_argument("material color \"classification\": the cloud has no classification");
      for (std::size_t i = 0; i < n; ++i) albedo[i] = classification_color(cloud.classification[i]);
      break;
    case ColorMode::intensity:
    case ColorMode::elevation: {
      std::vector<double> v(n);
      if (m.mode == ColorMode::intensity) {
        if (cloud.intensity.size() != n)
          throw std::invalid_argument("material color \"intensity\": the cloud has no intensity");
        for (std::size_t i = 0; i < n; ++i) v[i] = cloud.intensity[i];
      } else {
        const Vec3 u = glm::normalize(up);
        for (std::size_t i = 0; i < n; ++i) v[i] = glm::dot(cloud.positions[i], u);
      }
      const auto range = m.range ? *m.range : percentile_range(v);
      const double inv = 1.0 / (range[1] - range[0]);
      for (std::size_t i = 0; i < n; ++i)
        albedo[i] = ramp_linear(m.ramp, static_cast<float>((v[i] - range[0]) * inv));
      break;
    }
  }
  for (Color& c : albedo) c = glm::clamp(c * m.albedo_scale, Color(0.0f), Color(1.0f));
  return albedo;
}

}  // namespace rayscan::render
