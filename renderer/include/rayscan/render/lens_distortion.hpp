// Lens distortion lives in the core library (rayscan/lens_distortion.hpp) with the Camera; this
// header keeps the renderer's spelling rayscan::render::LensDistortion.
#pragma once

#include "rayscan/lens_distortion.hpp"

namespace rayscan::render {
using rayscan::distort;
using rayscan::LensDistortion;
using rayscan::undistort;
}  // namespace rayscan::render
