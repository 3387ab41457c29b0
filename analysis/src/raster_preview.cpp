#include "rayscan/analysis/raster_preview.hpp"

#include "rayscan/image/color_ramp.hpp"
#include "rayscan/image/image_file.hpp"

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

std::string write_raster_preview(const std::filesystem::path& path, const Raster& raster, double lo,
                                 double hi, const std::string& title) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi)
    throw std::invalid_argument(path.string() + ": preview range must be finite with lo <= hi");
  const GridSpec& g = raster.grid;
  if (g.cols == 0 || g.rows == 0 || raster.values.size() != std::size_t(g.cols) * g.rows)
    throw std::invalid_argument(path.string() + ": raster size does not match its grid");
  const int s = std::max(1, int(1024 / std::max(g.cols, g.rows)));
  const int map_w = int(g.cols) * s, map_h = int(g.rows) * s;
  const int legend_h = 70, margin = 10;
  const int W = std::max(map_w, 420), H = map_h + legend_h;

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
  for (std::uint32_t r = 0; r < g.rows; ++r)
    for (std::uint32_t c = 0; c < g.cols; ++c) {
      const float v = raster.values[std::size_t(r) * g.cols + c];
      std::array<float, 3> col;
      if (std::isnan(v))
        col = {kNoDataRgb[0], kNoDataRgb[1], kNoDataRgb[2]};
      else
        col = ramp(span > 0 ? (double(v) - lo) / span : 0.5);
      for (int dy = 0; dy < s; ++dy)
        for (int dx = 0; dx < s; ++dx) put(int(c) * s + dx, int(r) * s + dy, col.data());
    }

  // Legend: title, colour bar with a 1-px black frame, end and middle values, no-data swatch.
  const int bar_x = margin, bar_y = map_h + 26, bar_w = std::min(W - 2 * margin - 90, 400), bar_h = 14;
  for (int x = 0; x < bar_w; ++x) {
    const auto col = ramp((x + 0.5) / bar_w);
    for (int y = 0; y < bar_h; ++y) put(bar_x + x, bar_y + y, col.data());
  }
  for (int x = bar_x - 1; x <= bar_x + bar_w; ++x) {
    put(x, bar_y - 1, black);
    put(x, bar_y + bar_h, black);
  }
  for (int y = bar_y - 1; y <= bar_y + bar_h; ++y) {
    put(bar_x - 1, y, black);
    put(bar_x + bar_w, y, black);
  }
  const int sw_x = bar_x + bar_w + 20;
  for (int y = 0; y < bar_h; ++y)
    for (int x = 0; x < bar_h; ++x) put(sw_x + x, bar_y + y, kNoDataRgb);

  const bool labels = render_text(img, margin, map_h + 18, title, 14, black);
  if (labels) {
    const int ty = bar_y + bar_h + 16;
    render_text(img, bar_x, ty, fmt(lo), 12, black);
    render_text(img, bar_x + bar_w / 2, ty, fmt(lo + span / 2), 12, black, TextAlign::center);
    render_text(img, bar_x + bar_w, ty, fmt(hi), 12, black, TextAlign::right);
    render_text(img, sw_x + bar_h + 4, bar_y + bar_h - 2, "no data", 12, black);
  }

  const std::string legend = title + ": " + heat_ramp_legend(lo, hi) + "; no data: blue; " +
                             std::to_string(s) + " px per cell of " + fmt(g.cell) + " world units";
  write_image(img, path.string(), PixelFormat::uint8, legend);
  return legend;
}

}  // namespace rayscan::analysis
