// Linear RGB colour, the sRGB transfer function and the colour ramps used to turn scalar point
// attributes (elevation, intensity) into albedo.
#pragma once

#include <glm/vec3.hpp>

#include <cstdint>
#include <string>

namespace rayscan::render {

/// Linear-light RGB (Rec. 709 primaries), single precision. Radiance, albedo and pixel values.
using Color = glm::vec3;

/// sRGB opto-electronic transfer function (IEC 61966-2-1, section 5.2): linear [0,1] -> encoded
/// [0,1]. Inputs are clamped to [0,1] first.
[[nodiscard]] float linear_to_srgb(float v);
/// Inverse of linear_to_srgb: encoded [0,1] -> linear [0,1] (used for 8/16-bit point colours,
/// which LAS and PCD store sRGB-encoded).
[[nodiscard]] float srgb_to_linear(float v);

/// Named colour ramps for scalar attributes. Each is a piecewise-linear ramp over [0,1] with the
/// stops listed in scenes/README.md, interpolated in linear light.
enum class Ramp {
  viridis,  ///< perceptually uniform blue-green-yellow (van der Walt & Smith, matplotlib; 9 stops)
  terrain,  ///< hypsometric: dark green, light green, tan, brown, white (elevation tints)
  grey      ///< black to white
};

/// Parses "viridis" | "terrain" | "grey"; throws std::invalid_argument naming the allowed values.
Ramp parse_ramp(const std::string& s);

/// The ramp's linear-light colour at u (clamped to [0,1]).
[[nodiscard]] Color eval_ramp(Ramp ramp, float u);

/// Display colour of an ASPRS classification code (LAS 1.4 R15 Table 17: 2 ground, 3-5
/// vegetation, 6 building, 9 water, ...), linear light; unknown codes are mid grey.
[[nodiscard]] Color classification_color(std::uint8_t code);

}  // namespace rayscan::render
