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

// True when some channel of `rgb` exceeds 255 (16-bit colour). Only that matters, so the parallel
// read stops at the first such value (16-bit colour: after a few points; 8-bit: one read of all).
// An index file's 3-byte colours with multiplier 1 are bytes by construction: 8-bit, no read.
bool any_wide_rgb(RgbView rgb) {
  if (rgb.multiplier() == 1) return false;
  std::atomic<bool> any_wide{false};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rgb.size(), 1 << 16), [&](const auto& r) {
    if (any_wide.load(std::memory_order_relaxed)) return;
    std::uint16_t mx = 0;
    for (std::size_t i = r.begin(); i != r.end(); ++i) mx = std::max({mx, rgb[i].r, rgb[i].g, rgb[i].b});
    if (mx > 255) any_wide = true;
  });
  return any_wide.load();
}

// The whole cloud's attributes as a stream of one block.
AlbedoStream one_block(const AlbedoAttributes& a, std::size_t n) {
  AlbedoStream s;
  s.points = n;
  s.rgb = a.rgb.size() == n;
  s.intensity = a.intensity.size() == n;
  s.classification = a.classification.size() == n;
  s.blocks = [a](const std::function<bool(const AlbedoAttributes&)>& each) { each(a); };
  return s;
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
      s.blocks([&](const AlbedoAttributes& a) { return !(wide = any_wide_rgb(a.rgb)); });
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
        if (!v.empty()) lowest_ = *std::min_element(v.begin(), v.end());
        range_ = percentile_range(std::move(v));
      }
      break;
  }
  inv_ = 1.0 / (range_[1] - range_[0]);
}

AlbedoRule::AlbedoRule(const AlbedoAttributes& a, std::size_t n, const MaterialDesc& m, const Vec3& up)
    : AlbedoRule(one_block(a, n), m, up) {}

AlbedoAttributes albedo_attributes(const PointCloud& cloud) {
  return {cloud.positions, std::span<const Rgb16>(cloud.rgb), cloud.intensity, cloud.classification};
}

std::vector<Color> compute_albedo(const PointCloud& cloud, const MaterialDesc& m, const Vec3& up) {
  return compute_albedo(cloud, AlbedoRule(albedo_attributes(cloud), cloud.size(), m, up));
}

std::vector<Color> compute_albedo(const PointCloud& cloud, const AlbedoRule& rule) {
  const AlbedoAttributes a = albedo_attributes(cloud);
  std::vector<Color> albedo(cloud.size());
  for (std::size_t i = 0; i < albedo.size(); ++i) albedo[i] = rule.at(a, i);
  return albedo;
}

}  // namespace rayscan::render
