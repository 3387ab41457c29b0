// SSIM by separable Gaussian filtering of x, y, x^2, y^2 and xy (Wang et al. 2004, eq. (14)-(16)
// with the Gaussian-weighted local statistics of section III-C). Windows holding a masked or
// non-finite sample are found with running counts along the same two passes and left out.
#include "rayscan/analysis/ssim.hpp"

#include "rayscan/base/job.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rayscan::analysis {

std::vector<double> ssim_gaussian_weights(const SsimOptions& opts) {
  if (opts.window < 1 || opts.window % 2 == 0)
    throw std::invalid_argument("SSIM window must be odd and positive, got " +
                                std::to_string(opts.window));
  if (!(opts.sigma > 0.0)) throw std::invalid_argument("SSIM sigma must be positive");
  const int r = opts.window / 2;
  std::vector<double> w(static_cast<std::size_t>(opts.window));
  double sum = 0.0;
  for (int i = -r; i <= r; ++i) {
    w[static_cast<std::size_t>(i + r)] = std::exp(-(i * i) / (2.0 * opts.sigma * opts.sigma));
    sum += w[static_cast<std::size_t>(i + r)];
  }
  for (double& v : w) v /= sum;
  return w;
}

namespace {

/// The reason text for an SSIM without any usable window; counts decide the wording so that it
/// names only the causes actually present.
std::string no_window_reason(std::span<const float> x, std::span<const float> y,
                             std::span<const std::uint8_t> ignore, std::size_t win) {
  bool masked = false, nonfinite = false;
  for (std::size_t p = 0; p < x.size(); ++p) {
    if (!ignore.empty() && ignore[p])
      masked = true;  // a masked pixel's value does not matter, finite or not
    else if (!std::isfinite(x[p]) || !std::isfinite(y[p]))
      nonfinite = true;
  }
  const std::string w = std::to_string(win) + "x" + std::to_string(win);
  const char* what = masked && nonfinite ? "a masked pixel or a non-finite (NaN or Inf) sample"
                     : masked            ? "a masked pixel"
                                         : "a non-finite (NaN or Inf) sample";
  return "every " + w + " SSIM window holds " + what;
}

}  // namespace

SsimResult ssim(std::span<const float> x, std::span<const float> y, int width, int height,
                std::span<const std::uint8_t> ignore, const SsimOptions& opts, const std::atomic<bool>* cancel) {
  const std::vector<double> g = ssim_gaussian_weights(opts);
  if (width < 0 || height < 0) throw std::invalid_argument("ssim: negative image size");
  const std::size_t W = static_cast<std::size_t>(width), H = static_cast<std::size_t>(height);
  if (x.size() != W * H || y.size() != W * H)
    throw std::invalid_argument("ssim: image buffers do not match " + std::to_string(width) + "x" +
                                std::to_string(height));
  if (!ignore.empty() && ignore.size() != W * H)
    throw std::invalid_argument("ssim: ignore mask does not match the image size");
  const std::size_t win = g.size();
  SsimResult res;
  if (W < win || H < win) {
    res.mssim = std::numeric_limits<double>::quiet_NaN();
    res.undefined = "image " + std::to_string(W) + "x" + std::to_string(H) + " is smaller than the " +
                    std::to_string(win) + "x" + std::to_string(win) + " SSIM window";
    return res;
  }
  const std::size_t OW = W - win + 1, OH = H - win + 1;  // "valid" output size
  res.positions = OW * OH;
  const double C1 = (opts.k1 * opts.dynamic_range) * (opts.k1 * opts.dynamic_range);
  const double C2 = (opts.k2 * opts.dynamic_range) * (opts.k2 * opts.dynamic_range);
  const auto bad = [&](std::size_t p) {
    return (!ignore.empty() && ignore[p]) || !std::isfinite(x[p]) || !std::isfinite(y[p]);
  };

  std::vector<double> row_sum(OH, 0.0);
  std::vector<std::size_t> row_count(OH, 0);
  constexpr std::size_t kBlock = 32;  // output rows per task
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, OH, kBlock), [&](const auto& range) {
    throw_if_cancelled(cancel);  // out of the body: TBB skips the blocks not started
    const std::size_t oy0 = range.begin(), oy1 = range.end();
    const std::size_t rows = oy1 - oy0 + win - 1;  // input rows oy0 .. oy1 + win - 2
    // Horizontally filtered statistics of the input rows: mu_x, mu_y, E[x^2], E[y^2], E[xy], and
    // the number of left-out samples under each horizontal span (a running count).
    std::vector<double> hx(rows * OW), hy(rows * OW), hxx(rows * OW), hyy(rows * OW), hxy(rows * OW);
    std::vector<std::size_t> hbad(rows * OW);
    for (std::size_t i = 0; i < rows; ++i) {
      const std::size_t row0 = (oy0 + i) * W;
      const float* xr = x.data() + row0;
      const float* yr = y.data() + row0;
      std::size_t nbad = 0;
      for (std::size_t k = 0; k + 1 < win; ++k) nbad += bad(row0 + k);
      for (std::size_t ox = 0; ox < OW; ++ox) {
        nbad += bad(row0 + ox + win - 1);
        const std::size_t o = i * OW + ox;
        hbad[o] = nbad;
        nbad -= bad(row0 + ox);
        double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
        for (std::size_t k = 0; k < win; ++k) {
          const double a = xr[ox + k], b = yr[ox + k], w = g[k];
          sx += w * a;
          sy += w * b;
          sxx += w * a * a;
          syy += w * b * b;
          sxy += w * a * b;
        }
        hx[o] = sx, hy[o] = sy, hxx[o] = sxx, hyy[o] = syy, hxy[o] = sxy;
      }
    }
    for (std::size_t oy = oy0; oy < oy1; ++oy) {
      double sum = 0.0;
      std::size_t count = 0;
      const std::size_t i0 = oy - oy0;
      for (std::size_t ox = 0; ox < OW; ++ox) {
        double mx = 0, my = 0, exx = 0, eyy = 0, exy = 0;
        std::size_t nbad = 0;
        for (std::size_t k = 0; k < win; ++k) {
          const std::size_t o = (i0 + k) * OW + ox;
          const double w = g[k];
          nbad += hbad[o];
          mx += w * hx[o];
          my += w * hy[o];
          exx += w * hxx[o];
          eyy += w * hyy[o];
          exy += w * hxy[o];
        }
        if (nbad) continue;  // a masked or non-finite sample: the window is left out
        const double vx = exx - mx * mx, vy = eyy - my * my, cxy = exy - mx * my;
        sum += ((2.0 * mx * my + C1) * (2.0 * cxy + C2)) /
               ((mx * mx + my * my + C1) * (vx + vy + C2));
        ++count;
      }
      row_sum[oy] = sum;
      row_count[oy] = count;
    }
  });
  double total = 0.0;
  for (std::size_t oy = 0; oy < OH; ++oy) {  // fixed order: deterministic for any thread count
    total += row_sum[oy];
    res.windows += row_count[oy];
  }
  if (res.windows) {
    res.mssim = total / static_cast<double>(res.windows);
  } else {
    res.mssim = std::numeric_limits<double>::quiet_NaN();
    res.undefined = no_window_reason(x, y, ignore, win);
  }
  return res;
}

}  // namespace rayscan::analysis
