// Colour ramps for scalar maps (error heat maps, visibility previews).
#pragma once

#include <string>

namespace rayscan::analysis {

/// An RGB colour with components in [0, 1] (display-referred, written as sRGB-encoded bytes).
struct Rgb {
  float r = 0, g = 0, b = 0;
};

/// The "heat" (black-body style) ramp: piecewise linear through black (t = 0), red (1/3),
/// yellow (2/3) and white (1). Monotonic in luminance, so it reads correctly in greyscale print.
/// t is clamped to [0, 1]; NaN maps to black.
Rgb heat_ramp(double t);

/// One-line description of heat_ramp for a legend, with the data values at its stops for the
/// data range [lo, hi], e.g. "black 0 -> red 0.0333 -> yellow 0.0667 -> white 0.1".
std::string heat_ramp_legend(double lo, double hi);

}  // namespace rayscan::analysis
