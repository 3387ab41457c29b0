// Colour: the sRGB transfer function and the one set of colour ramps for scalar values -- point
// albedo from elevation or intensity (renderer), error heat maps (compare), visibility previews.
// Every ramp is a table of sRGB-encoded stops; ramp_linear() interpolates them in linear light
// (for rendering), ramp_display() in the encoded values (for maps written as 8-bit images).
#pragma once

#include <glm/vec3.hpp>

#include <string>
#include <vector>

namespace rayscan {

/// sRGB opto-electronic transfer function (IEC 61966-2-1, section 5.2): linear [0,1] -> encoded
/// [0,1]. Inputs are clamped to [0,1] first.
[[nodiscard]] float linear_to_srgb(float v);
/// Inverse of linear_to_srgb: encoded [0,1] -> linear [0,1] (used for 8/16-bit point colours,
/// which LAS and PCD store sRGB-encoded).
[[nodiscard]] float srgb_to_linear(float v);

/// Named colour ramps over [0, 1].
enum class Ramp {
  viridis,  ///< perceptually uniform blue-green-yellow (van der Walt & Smith, matplotlib; 10 stops)
  terrain,  ///< hypsometric: dark green, light green, tan, brown, white (elevation tints)
  grey,     ///< black to white
  heat      ///< black (0), red (1/3), yellow (2/3), white (1): monotonic in luminance, so it reads
            ///< correctly in greyscale print (error heat maps, visibility previews)
};

/// The ramp names in enum order: "viridis", "terrain", "grey", "heat".
const std::vector<std::string>& ramp_names();

/// Parses a ramp name; throws std::invalid_argument naming the allowed values.
Ramp parse_ramp(const std::string& s);

/// The ramp's linear-light colour at u (clamped to [0,1]; NaN = 0): stops converted to linear
/// light, then interpolated (renderer albedo, scenes/README.md).
[[nodiscard]] glm::vec3 ramp_linear(Ramp ramp, float u);

/// The ramp's display-referred (sRGB-encoded, [0,1]) colour at t (clamped to [0,1]; NaN maps to
/// the first stop): the encoded stops interpolated directly.
[[nodiscard]] glm::vec3 ramp_display(Ramp ramp, double t);

/// A display-referred RGB colour, components in [0, 1] (written as sRGB-encoded bytes).
using Rgb = glm::vec3;

/// The heat ramp (Ramp::heat) at t, display-referred: black 0, red 1/3, yellow 2/3, white 1;
/// t is clamped to [0, 1]; NaN maps to black.
inline Rgb heat_ramp(double t) { return ramp_display(Ramp::heat, t); }

/// One-line description of the heat ramp for a legend, with the data values at its stops for the
/// data range [lo, hi], e.g. "black 0 -> red 0.0333 -> yellow 0.0667 -> white 0.1".
std::string heat_ramp_legend(double lo, double hi);

}  // namespace rayscan
