// Colour ramps for scalar maps (error heat maps, visibility previews): the core's ramps
// (rayscan/color_ramp.hpp) under the names analysis code uses.
#pragma once

#include "rayscan/color_ramp.hpp"

namespace rayscan::analysis {

/// A display-referred RGB colour, components in [0, 1] (written as sRGB-encoded bytes).
using Rgb = glm::vec3;

/// The heat ramp (Ramp::heat) at t, display-referred: black 0, red 1/3, yellow 2/3, white 1;
/// t is clamped to [0, 1]; NaN maps to black.
inline Rgb heat_ramp(double t) { return ramp_display(Ramp::heat, t); }

using rayscan::heat_ramp_legend;

}  // namespace rayscan::analysis
