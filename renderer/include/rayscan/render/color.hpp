// Linear RGB colour and the classification colours of the renderer's albedo; the sRGB transfer
// and the colour ramps come from the core (rayscan/image/color_ramp.hpp).
#pragma once

#include "rayscan/image/color_ramp.hpp"

#include <glm/vec3.hpp>

#include <cstdint>
#include <string>

namespace rayscan::render {

/// Linear-light RGB (Rec. 709 primaries), single precision. Radiance, albedo and pixel values.
using Color = glm::vec3;

/// The sRGB transfer function and the colour ramps are defined once in the core
/// (rayscan/image/color_ramp.hpp): linear_to_srgb, srgb_to_linear, Ramp, parse_ramp, ramp_linear.
using rayscan::linear_to_srgb;
using rayscan::parse_ramp;
using rayscan::Ramp;
using rayscan::ramp_linear;
using rayscan::srgb_to_linear;

/// Display colour of an ASPRS classification code (LAS 1.4 R15 Table 17: 2 ground, 3-5
/// vegetation, 6 building, 9 water, ...), linear light; unknown codes are mid grey.
[[nodiscard]] Color classification_color(std::uint8_t code);

}  // namespace rayscan::render
