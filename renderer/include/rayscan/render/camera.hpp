// The camera lives in the core library (rayscan/camera.hpp) so that analysis can use it without
// the renderer; this header keeps the renderer's spelling rayscan::render::Camera.
#pragma once

#include "rayscan/camera.hpp"

namespace rayscan::render {
using rayscan::Camera;
using rayscan::EquirectangularParams;
using rayscan::LookAtParams;
using rayscan::OrthographicParams;
using rayscan::PinholeParams;
using rayscan::Projection;
}  // namespace rayscan::render
