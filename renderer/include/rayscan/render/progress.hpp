// The progress bar lives in the core library (rayscan/progress.hpp), shared by every job; this
// header keeps the renderer's spelling rayscan::render::Progress.
#pragma once

#include "rayscan/progress.hpp"

namespace rayscan::render {
using rayscan::Progress;
using rayscan::ProgressUnits;
}  // namespace rayscan::render
