// PNG preview of a Raster: the cells through the heat colour ramp, with a legend; and that
// legend on its own, for the other maps written as pictures (compare's heat maps).
#pragma once

#include "rayscan/analysis/raster.hpp"
#include "rayscan/image/image.hpp"

#include <algorithm>
#include <array>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::analysis {

/// Colour used for no-data (NaN) cells in previews: a mid blue, outside the heat ramp's hues.
inline constexpr float kNoDataRgb[3] = {0.2f, 0.3f, 0.8f};

/// Height in pixels of the legend strip that draw_legend fills below a map.
inline constexpr int kLegendHeight = 70;
/// The narrowest picture whose legend strip holds the bar, its labels and two swatches.
inline constexpr int kLegendMinWidth = 480;
/// Where draw_legend puts the colour bar: from x = kLegendBarX, in rows [top + kLegendBarTop,
/// top + kLegendBarTop + kLegendBarHeight), legend_bar_width(image width) pixels wide; a 1-px
/// black frame around it.
inline constexpr int kLegendBarX = 10, kLegendBarTop = 26, kLegendBarHeight = 14;
/// The colour bar's width in pixels for a picture `width` pixels wide (at most 400).
[[nodiscard]] constexpr int legend_bar_width(int width) { return std::min(width - 2 * kLegendBarX - 200, 400); }

/// A legend entry after the colour bar: a framed square of `rgb` (display RGB in [0, 1]) and
/// its label.
struct LegendSwatch {
  std::array<float, 3> rgb{0.0f, 0.0f, 0.0f};
  std::string label;
};

/// Draws a legend into rows [top, top + kLegendHeight) of `img` (channels R,G,B, display
/// values; those rows already white, as the caller's background): `title` (14-px text), then,
/// when `ramp` = {lo, hi} is given, the heat ramp as a colour bar (column i coloured
/// heat_ramp((i + 0.5) / width), so its ends are the ramp's black and white) with lo, the
/// middle and hi written beneath it, then each swatch with its label. Text is drawn with
/// OpenImageIO's render_text (FreeType, DejaVu Sans); without a font the bar and swatches are
/// drawn unlabelled. Returns the x where a further legend item goes. Throws
/// std::invalid_argument for an image that is not R,G,B, narrower than kLegendMinWidth or
/// without the rows, or a ramp range that is not finite with lo <= hi.
int draw_legend(Image& img, int top, const std::string& title, std::optional<std::pair<double, double>> ramp,
                std::span<const LegendSwatch> swatches);

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
  /// The raster's CRS (WKT, as its GeoTIFF carries it): the legend gives the cell size in the
  /// CRS's linear unit as the GeoTIFF's band unit names it, "world units" without a CRS
  /// (crs_length_unit).
  std::string crs_wkt;
};

/// Writes an 8-bit RGB image (format by extension, normally .png) of `raster`: each cell becomes an
/// s x s block (s = the largest integer with max(cols, rows) s <= 1024, at least 1), north up,
/// coloured by heat_ramp((v - lo) / (hi - lo)) (values outside [lo, hi] clamp; with lo == hi, v
/// <= lo takes the ramp's first colour, as the bar labels that end lo, and v > lo its last), or by `style.categories` when given; no-data cells kNoDataRgb;
/// `style.markers` drawn over the map. Below the map a legend (draw_legend): the title (once), a
/// colour bar with the values at its ends and middle (or one swatch per category), a no-data
/// swatch and the marker's symbol. The legend text is also stored as the file's ImageDescription
/// and returned. Written through write_image (temp file + rename). Throws std::invalid_argument
/// for lo > hi or non-finite bounds, std::runtime_error for I/O failures.
std::string write_raster_preview(const std::filesystem::path& path, const Raster& raster, double lo,
                                 double hi, const std::string& title, const PreviewStyle& style = {});

}  // namespace rayscan::analysis
