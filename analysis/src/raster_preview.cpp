#include "rayscan/analysis/raster_preview.hpp"

#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/image/color_ramp.hpp"
#include "rayscan/image/image_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rayscan::analysis {

namespace {

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

}  // namespace

int draw_legend(Image& img, int top, const std::string& title, std::optional<std::pair<double, double>> ramp,
                std::span<const LegendSwatch> swatches) {
  const int W = img.width;
  if (img.channels != std::vector<std::string>{"R", "G", "B"} || img.pixels.size() != img.npixels() * 3)
    throw std::invalid_argument("draw_legend: expected a complete R,G,B image");
  if (W < kLegendMinWidth || top < 0 || top + kLegendHeight > img.height)
    throw std::invalid_argument("draw_legend: a " + std::to_string(W) + "x" + std::to_string(img.height) +
                                " image has no " + std::to_string(kLegendMinWidth) + "x" + std::to_string(kLegendHeight) +
                                " legend strip at row " + std::to_string(top));
  if (ramp && (!std::isfinite(ramp->first) || !std::isfinite(ramp->second) || ramp->first > ramp->second))
    throw std::invalid_argument("draw_legend: the ramp's range must be finite with lo <= hi");
  const float black[3] = {0.0f, 0.0f, 0.0f};
  auto put = [&](int x, int y, const float* c) {
    if (x < 0 || y < 0 || x >= W || y >= img.height) return;
    std::copy(c, c + 3, img.pixels.begin() + (std::ptrdiff_t(y) * W + x) * 3);
  };
  const int bar_x = kLegendBarX, bar_y = top + kLegendBarTop, bar_h = kLegendBarHeight;
  auto frame = [&](int x0, int y0, int w, int h) {
    for (int x = x0 - 1; x <= x0 + w; ++x) put(x, y0 - 1, black), put(x, y0 + h, black);
    for (int y = y0 - 1; y <= y0 + h; ++y) put(x0 - 1, y, black), put(x0 + w, y, black);
  };
  const bool labels = render_text(img, kLegendBarX, top + 18, title, 14, black);
  int x = bar_x;
  if (ramp) {
    const auto [lo, hi] = *ramp;
    const int bar_w = legend_bar_width(W);
    for (int i = 0; i < bar_w; ++i) {
      const Rgb c = heat_ramp((i + 0.5) / bar_w);
      const float col[3] = {c.r, c.g, c.b};
      for (int y = 0; y < bar_h; ++y) put(bar_x + i, bar_y + y, col);
    }
    frame(bar_x, bar_y, bar_w, bar_h);
    if (labels) {
      const int ty = bar_y + bar_h + 16;
      render_text(img, bar_x, ty, fmt(lo), 12, black);
      render_text(img, bar_x + bar_w / 2, ty, fmt(lo + (hi - lo) / 2), 12, black, TextAlign::center);
      render_text(img, bar_x + bar_w, ty, fmt(hi), 12, black, TextAlign::right);
    }
    x = bar_x + bar_w + 20;
  }
  for (const LegendSwatch& s : swatches) {
    for (int y = 0; y < bar_h; ++y)
      for (int dx = 0; dx < bar_h; ++dx) put(x + dx, bar_y + y, s.rgb.data());
    frame(x, bar_y, bar_h, bar_h);
    if (labels) render_text(img, x + bar_h + 4, bar_y + bar_h - 2, s.label, 12, black);
    x += bar_h + 12 + 8 * int(s.label.size());
  }
  return x;
}

std::string write_raster_preview(const std::filesystem::path& path, const Raster& raster, double lo,
                                 double hi, const std::string& title, const PreviewStyle& style) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi)
    throw std::invalid_argument(path.string() + ": preview range must be finite with lo <= hi");
  const GridSpec& g = raster.grid;
  if (g.cols == 0 || g.rows == 0 || raster.values.size() != std::size_t(g.cols) * g.rows)
    throw std::invalid_argument(path.string() + ": raster size does not match its grid");
  const int s = std::max(1, int(1024 / std::max(g.cols, g.rows)));
  const int map_w = int(g.cols) * s, map_h = int(g.rows) * s;
  const int W = std::max(map_w, kLegendMinWidth), H = map_h + kLegendHeight;

  Image img = make_image(W, H, {"R", "G", "B"}, 1.0f);  // white
  const float black[3] = {0.0f, 0.0f, 0.0f};
  auto put = [&](int x, int y, const float* c) {
    if (x < 0 || y < 0 || x >= W || y >= H) return;
    std::copy(c, c + 3, img.pixels.begin() + (std::ptrdiff_t(y) * W + x) * 3);
  };
  auto ramp = [&](double t) {
    const Rgb c = heat_ramp(t);
    return std::array<float, 3>{c.r, c.g, c.b};
  };
  const double span = hi - lo;
  const bool categorical = !style.categories.empty();
  const std::array<float, 3> no_data{kNoDataRgb[0], kNoDataRgb[1], kNoDataRgb[2]};
  for (std::uint32_t r = 0; r < g.rows; ++r)
    for (std::uint32_t c = 0; c < g.cols; ++c) {
      const float v = raster.values[std::size_t(r) * g.cols + c];
      std::array<float, 3> col = no_data;
      if (categorical) {
        for (const PreviewCategory& k : style.categories)
          if (v == k.value) col = k.rgb;
      } else if (!std::isnan(v)) {
        // With lo == hi (a constant map: all zero in a polar night) the bar's labels all read lo,
        // whose colour is the bar's first: a value at lo is drawn in it, one above in the last.
        col = ramp(span > 0 ? (double(v) - lo) / span : double(v) > lo ? 1.0 : 0.0);
      }
      for (int dy = 0; dy < s; ++dy)
        for (int dx = 0; dx < s; ++dx) put(int(c) * s + dx, int(r) * s + dy, col.data());
    }
  // Markers: a white disc in a black ring, radius 5 px (or the cell's size), at each point.
  const int mr = std::max(5, s);
  auto marker = [&](int cx, int cy) {
    for (int dy = -mr; dy <= mr; ++dy)
      for (int dx = -mr; dx <= mr; ++dx) {
        const int d2 = dx * dx + dy * dy;
        if (d2 <= (mr - 2) * (mr - 2))
          put(cx + dx, cy + dy, std::array<float, 3>{1.0f, 1.0f, 1.0f}.data());
        else if (d2 <= mr * mr)
          put(cx + dx, cy + dy, black);
      }
  };
  for (const Vec3& m : style.markers) {
    const double col = (m.x - g.x0) / g.cell, row = (g.y_top - m.y) / g.cell;
    if (col >= 0 && row >= 0 && col < g.cols && row < g.rows) marker(int(col * s), int(row * s));
  }

  // Legend: the title, the colour bar (or one swatch per category), the no-data swatch and the
  // marker.
  std::vector<LegendSwatch> swatches;
  std::string legend = title + ": ";
  for (const PreviewCategory& k : style.categories) {
    swatches.push_back({k.rgb, k.label});
    legend += k.label + " (" + fmt(k.value) + "), ";
  }
  if (!categorical) legend += heat_ramp_legend(lo, hi) + "; ";
  swatches.push_back({no_data, "no data"});
  legend += "no data: blue";
  const int x = draw_legend(img, map_h, title, categorical ? std::nullopt : std::optional(std::pair{lo, hi}), swatches);
  if (!style.markers.empty()) {
    const int bar_y = map_h + kLegendBarTop, bar_h = kLegendBarHeight;
    marker(x + mr, bar_y + bar_h / 2);
    render_text(img, x + 2 * mr + 4, bar_y + bar_h - 2, style.marker_label, 12, black);  // false: no font
    legend += "; " + style.marker_label + ": white disc";
  }
  legend += "; " + std::to_string(s) + " px per cell of " + fmt(g.cell) + " " + crs_length_unit(style.crs_wkt);
  write_image(img, path.string(), PixelFormat::uint8, legend);
  return legend;
}

}  // namespace rayscan::analysis
