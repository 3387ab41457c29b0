// PNG preview of a Raster: the cells through the heat colour ramp, with a legend.
#pragma once

#include "rayscan/analysis/raster.hpp"

#include <filesystem>
#include <string>

namespace rayscan::analysis {

/// Colour used for no-data (NaN) cells in previews: a mid blue, outside the heat ramp's hues.
inline constexpr float kNoDataRgb[3] = {0.2f, 0.3f, 0.8f};

/// Writes an 8-bit RGB image (format by extension, normally .png) of `raster`: each cell becomes an
/// s x s block (s = the largest integer with max(cols, rows) s <= 1024, at least 1), north up,
/// coloured by heat_ramp((v - lo) / (hi - lo)) (values outside [lo, hi] clamp; lo == hi maps to
/// the ramp's middle), no-data cells kNoDataRgb. Below the map a legend: the title, a colour bar
/// with the values at its ends and middle, and a no-data swatch. Labels are drawn with
/// OpenImageIO's render_text (FreeType, DejaVu Sans); when no font is available the bar is drawn
/// without labels. The legend text is also stored as the file's ImageDescription and returned.
/// Written through write_image (temp file + rename). Throws std::invalid_argument for lo > hi or
/// non-finite bounds, std::runtime_error for I/O failures.
std::string write_raster_preview(const std::filesystem::path& path, const Raster& raster, double lo,
                                 double hi, const std::string& title);

}  // namespace rayscan::analysis
