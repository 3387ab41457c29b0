// Per-point albedo of the Lambertian material (Ray Tracing in One Weekend, section 10.3), from
// the point's colour or a scalar attribute through a colour ramp.
#pragma once

#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/position_view.hpp"
#include "rayscan/octree/rgb_view.hpp"
#include "rayscan/render/color.hpp"
#include "rayscan/render/scene.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <vector>

namespace rayscan::render {

/// A cloud's attributes as the albedo rule reads them, all indexed alike (by original point index
/// for a PointCloud, by storage slot for an index file). Spans the material does not use may be
/// empty.
struct AlbedoAttributes {
  PositionView positions;  ///< world coordinates (elevation); an index file's may be decoded on access
  RgbView rgb;  ///< 16-bit colours (a span, or an index file's 3-byte colours decoded on access)
  std::span<const std::uint16_t> intensity;
  std::span<const std::uint8_t> classification;
};

/// A cloud's attributes delivered block by block (e.g. node by node from a COPC file, in bounded
/// memory) for the whole-cloud statistics of AlbedoRule: `blocks` calls its argument once per
/// block (spans of equal length; attributes the material does not use may be empty) and stops
/// when it returns false. `rgb`, `intensity`, `classification`: whether the cloud has them.
struct AlbedoStream {
  std::size_t points = 0;
  bool rgb = false, intensity = false, classification = false;
  std::function<void(const std::function<bool(const AlbedoAttributes&)>&)> blocks;
};

/// The material's albedo rule for one cloud: the whole-cloud statistics resolved once (8-bit
/// colour detection, the percentile range), then applied to one point at a time, so a renderer
/// can shade from the stored attributes without a per-point albedo array.
///  - rgb: the point's 16-bit colour, sRGB-decoded. 8-bit data stored in 16-bit fields (max <= 255,
///    as in many LAS files) is detected and scaled by 1/255 instead of 1/65535.
///  - intensity / elevation (coordinate along `up`): mapped through material.ramp, from
///    material.range or else the 2nd..98th percentile of the values.
///  - classification: classification_color().
///  - constant: material.constant.
/// Every albedo is multiplied by material.albedo_scale and clamped to [0,1].
class AlbedoRule {
 public:
  AlbedoRule() = default;
  /// Resolves the statistics over `a` (`n` points). Cost: rgb scans colours until one exceeds 255
  /// (all of them for 8-bit data); intensity without a range one pass (65536-bin histogram);
  /// elevation without a range one pass and a copy of the n coordinates (nth_element); other
  /// modes O(1). Throws std::invalid_argument when the mode needs an attribute `a` lacks (naming it).
  AlbedoRule(const AlbedoAttributes& a, std::size_t n, const MaterialDesc& material, const Vec3& up);
  /// The same statistics from a stream of blocks (one pass, stopped early by the rgb test), equal
  /// to the constructor above over the concatenated blocks (which is this one over one block). Memory: intensity a 65536-bin
  /// histogram, elevation without a range a copy of the n coordinates. Same errors.
  AlbedoRule(const AlbedoStream& s, const MaterialDesc& material, const Vec3& up);

  /// Albedo of point i of the attributes the rule is applied to (linear RGB in [0,1]).
  [[nodiscard]] Color at(const AlbedoAttributes& a, std::size_t i) const {
    Color c = material_.constant;
    switch (material_.mode) {
      case ColorMode::constant: break;
      case ColorMode::rgb: c = {lut_[a.rgb[i].r], lut_[a.rgb[i].g], lut_[a.rgb[i].b]}; break;
      case ColorMode::classification: c = classification_color(a.classification[i]); break;
      case ColorMode::intensity: c = scalar(a.intensity[i]); break;
      case ColorMode::elevation: c = scalar(glm::dot(a.positions[i], up_)); break;
    }
    return glm::clamp(c * material_.albedo_scale, Color(0.0f), Color(1.0f));
  }

  /// The scalar values at the ramp's ends (intensity, or elevation along `up` in the coordinates'
  /// unit): material.range, else the 2nd and 98th percentile of the cloud's values ([1] = [0] + 1
  /// when those are equal). A value at or below [0] gets the ramp's first colour, at or above [1]
  /// its last. {0, 1} for the other modes, which use no range.
  [[nodiscard]] const std::array<double, 2>& range() const { return range_; }
  /// Elevation without material.range: the lowest of the cloud's heights along `up` (the values
  /// range() takes its percentiles of), so that a log can give the ends as heights above the
  /// lowest point, which do not depend on where the coordinates' origin lies. NaN otherwise.
  [[nodiscard]] double lowest() const { return lowest_; }

 private:
  void set_rgb_scale(bool wide);
  [[nodiscard]] Color scalar(double v) const {
    return ramp_linear(material_.ramp, static_cast<float>((v - range_[0]) * inv_));
  }
  MaterialDesc material_;
  Vec3 up_{0.0, 0.0, 1.0};
  std::vector<float> lut_;  ///< rgb: 16-bit channel value -> linear
  std::array<double, 2> range_{0.0, 1.0};
  double lowest_ = std::numeric_limits<double>::quiet_NaN();
  double inv_ = 1.0;
};

/// Where the integrator takes a hit point's albedo from: a precomputed array by original point
/// index (`by_index`, e.g. compute_albedo of an in-memory cloud) or, when that is empty, `rule`
/// applied to slot-ordered attributes (`by_slot`: an index file's stored points, read at shading
/// time; no per-point array). The two give the same colour for the same point.
struct AlbedoSource {
  std::span<const Color> by_index;
  const AlbedoRule* rule = nullptr;  ///< must outlive the render (when by_index is empty)
  AlbedoAttributes by_slot;
  std::size_t slots = 0;             ///< points behind by_slot

  /// Albedo of the point with original index `index` stored at `slot` of the queried index.
  [[nodiscard]] Color at(PointIndex index, std::uint32_t slot) const {
    return by_index.empty() ? rule->at(by_slot, slot) : by_index[index];
  }
  /// True when the source covers an index of `n` points.
  [[nodiscard]] bool covers(std::size_t n) const {
    return by_index.empty() ? rule != nullptr && slots == n : by_index.size() == n;
  }
};

/// Albedo of every point (linear RGB in [0,1], indexed like cloud.positions): AlbedoRule over the
/// cloud, applied to each point. Throws std::invalid_argument when the mode needs an attribute
/// the cloud lacks (naming it).
std::vector<Color> compute_albedo(const PointCloud& cloud, const MaterialDesc& material, const Vec3& up);

/// Albedo of every point of `cloud` by a rule already resolved over that same cloud (e.g. one
/// kept for its range()): equal to compute_albedo with the rule's material and up, without the
/// statistics' second pass.
std::vector<Color> compute_albedo(const PointCloud& cloud, const AlbedoRule& rule);

/// The cloud's attributes in original order (spans into `cloud`).
[[nodiscard]] AlbedoAttributes albedo_attributes(const PointCloud& cloud);

}  // namespace rayscan::render
