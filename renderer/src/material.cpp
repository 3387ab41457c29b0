#include "rayscan/render/material.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <stdexcept>

namespace rayscan::render {

namespace {
// Values at ranks lo = 2% and hi = 98% of n (nth_element's answer), the default scalar range.
std::array<double, 2> percentile_range(std::vector<double> v) {
  if (v.empty()) return {0.0, 1.0};
  const std::size_t lo = v.size() * 2 / 100, hi = std::min(v.size() - 1, v.size() * 98 / 100);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(lo), v.end());
  const double a = v[lo];
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(hi), v.end());
  const double b = v[hi];
  return {a, b > a ? b : a + 1.0};
}

// The same ranks of n 16-bit values from their histogram.
std::array<double, 2> percentile_range_hist(const std::vector<std::uint64_t>& hist, std::size_t n) {
  if (n == 0) return {0.0, 1.0};
  const std::size_t lo = n * 2 / 100, hi = std::min(n - 1, n * 98 / 100);
  auto value_at = [&](std::size_t rank) {
    std::uint64_t seen = 0;
    for (std::size_t x = 0; x < hist.size(); ++x) {
      seen += hist[x];
      if (seen > rank) return double(x);
    }
    return 65535.0;
  };
  const double a = value_at(lo), b = value_at(hi);
  return {a, b > a ? b : a + 1.0};
}

// The same ranks of 16-bit values from a histogram (one pass, no copy of the values).
std::array<double, 2> percentile_range_u16(std::span<const std::uint16_t> v) {
  std::vector<std::uint64_t> hist(65536, 0);
  for (const std::uint16_t x : v) ++hist[x];
  return percentile_range_hist(hist, v.size());
}

const char* kNoRgb = "material color \"rgb\": the cloud has no RGB colours (use "
                     "\"elevation\", \"intensity\" or a constant [r, g, b])";
}  // namespace

void AlbedoRule::set_rgb_scale(bool wide) {
  const float scale = wide ? 1.0f / 65535.0f : 1.0f / 255.0f;
  lut_.resize(65536);  // 8-bit data only reads [0, 255]
  for (std::size_t i = 0; i < (wide ? lut_.size() : 256); ++i) lut_[i] = srgb_to_linear(float(i) * scale);
}

AlbedoRule::AlbedoRule(const AlbedoStream& s, const MaterialDesc& m, const Vec3& up)
    : material_(m), up_(glm::normalize(up)) {
  switch (m.mode) {
    case ColorMode::constant: break;
    case ColorMode::rgb: {
      if (!s.rgb) throw std::invalid_argument(kNoRgb);
      bool wide = false;
      s.blocks([&](const AlbedoAttributes& a) {
        for (const Rgb16& c : a.rgb)
          if (std::max({c.r, c.g, c.b}) > 255) {
            wide = true;
            return false;
          }
        return true;
      });
      set_rgb_scale(wide);
      break;
    }
    case ColorMode::classification:
      if (!s.classification)
        throw std::invalid_argument("material color \"classification\": the cloud has no classification");
      break;
    case ColorMode::intensity:
      if (!s.intensity) throw std::invalid_argument("material color \"intensity\": the cloud has no intensity");
      if (m.range) {
        range_ = *m.range;
      } else {
        std::vector<std::uint64_t> hist(65536, 0);
        std::size_t n = 0;
        s.blocks([&](const AlbedoAttributes& a) {
          for (const std::uint16_t x : a.intensity) ++hist[x];
          n += a.intensity.size();
          return true;
        });
        range_ = percentile_range_hist(hist, n);
      }
      break;
    case ColorMode::elevation:
      if (m.range) {
        range_ = *m.range;
      } else {
        std::vector<double> v;
        v.reserve(s.points);
        s.blocks([&](const AlbedoAttributes& a) {
          for (const Vec3& p : a.positions) v.push_back(glm::dot(p, up_));
          return true;
        });
        range_ = percentile_range(std::move(v));
      }
      break;
  }
  inv_ = 1.0 / (range_[1] - range_[0]);
}

AlbedoRule::AlbedoRule(const AlbedoAttributes& a, std::size_t n, const MaterialDesc& m, const Vec3& up)
    : material_(m), up_(glm::normalize(up)) {
  switch (m.mode) {
    case ColorMode::constant: break;
    case ColorMode::rgb: {
      if (a.rgb.size() != n) throw std::invalid_argument(kNoRgb);
      // Only whether some channel exceeds 255 matters: stop at the first one that does (16-bit
      // colour: after a few points; 8-bit colour: one parallel read of all of them).
      std::atomic<bool> any_wide{false};
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 16), [&](const auto& r) {
        if (any_wide.load(std::memory_order_relaxed)) return;
        std::uint16_t mx = 0;
        for (std::size_t i = r.begin(); i != r.end(); ++i) mx = std::max({mx, a.rgb[i].r, a.rgb[i].g, a.rgb[i].b});
        if (mx > 255) any_wide = true;
      });
      set_rgb_scale(any_wide.load());
      break;
    }
    case ColorMode::classification:
      if (a.classification.size() != n)
        throw std::invalid_argument("material color \"classification\": the cloud has no classification");
      break;
    case ColorMode::intensity:
      if (a.intensity.size() != n) throw std::invalid_argument("material color \"intensity\": the cloud has no intensity");
      range_ = m.range ? *m.range : percentile_range_u16(a.intensity);
      break;
    case ColorMode::elevation:
      if (!m.range) {
        std::vector<double> v(n);
        for (std::size_t i = 0; i < n; ++i) v[i] = glm::dot(a.positions[i], up_);
        range_ = percentile_range(std::move(v));
      } else {
        range_ = *m.range;
      }
      break;
  }
  inv_ = 1.0 / (range_[1] - range_[0]);
}

AlbedoAttributes albedo_attributes(const PointCloud& cloud) {
  return {cloud.positions, cloud.rgb, cloud.intensity, cloud.classification};
}

std::vector<Color> compute_albedo(const PointCloud& cloud, const MaterialDesc& m, const Vec3& up) {
  const AlbedoAttributes a = albedo_attributes(cloud);
  const AlbedoRule rule(a, cloud.size(), m, up);
  std::vector<Color> albedo(cloud.size());
  for (std::size_t i = 0; i < albedo.size(); ++i) albedo[i] = rule.at(a, i);
  return albedo;
}

}  // namespace rayscan::render
