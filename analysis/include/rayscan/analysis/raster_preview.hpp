// PNG preview of a Raster: the cells through the heat colour ramp, with a legend.
#pragma once

#include "rayscan/analysis/raster.hpp"

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace rayscan::analysis {

/// Colour used for no-data (NaN) cells in previews: a mid blue, outside the heat ramp's hues.
inline constexpr float kNoDataRgb[3] = {0.2f, 0.3f, 0.8f};

/// Writes an 8-bit RGB image (format by extension, normally .png) of `raster`: each cell becomes an
/// s x s block (s = the largest integer with max(cols, rows) s <= 1024, at least 1), north up,
/// coloured by heat_ramp((v - lo) / (hi - lo)) (values outside [lo, hi] clamp; lo == hi maps to
/// the ramp's middle), or by `style.categories` when given; no-data cells kNoDataRgb;
/// `style.markers` drawn over the map. Below the map a legend: the title (once), a colour bar with
/// the values at its ends and middle (or one swatch per category), a no-data swatch and the
/// marker's symbol. Labels are drawn with
/// OpenImageIO's render_text (FreeType, DejaVu Sans); when no font is available the bar is drawn
/// without labels. The legend text is also stored as the file's ImageDescription and returned.
/// Written through write_image (temp file + rename). Throws std::invalid_argument for lo > hi or
/// non-finite bounds, std::runtime_error for I/O failures.
/// A class of a categorical preview: cells whose value equals `value` get colour `rgb` (linear
/// RGB in [0, 1]) and the legend names them `label`.
struct PreviewCategory {
  float value = 0.0f;
  std::string label;
  std::array<float, 3> rgb{0.0f, 0.0f, 0.0f};
};

/// Optional parts of a preview.
struct PreviewStyle {
  /// Non-empty: a categorical map (e.g. a binary viewshed: visible / not visible) with one legend
  /// swatch per class instead of the heat ramp; a value matching no class is drawn as no data.
  std::vector<PreviewCategory> categories;
  /// Points to mark on the map (world XY, e.g. the observers): a white disc with a black ring
  /// over the cell, and "observer" in the legend.
  std::vector<Vec3> markers;
  std::string marker_label = "observer";
};

std::string write_raster_preview(const std::filesystem::path& path, const Raster& raster, double lo,
                                 double hi, const std::string& title, const PreviewStyle& style = {});

}  // namespace rayscan::analysis
