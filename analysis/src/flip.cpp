// LDR-FLIP (rayscan/analysis/flip.hpp), written from Andersson et al. 2020, section 4. Equation
// and table numbers refer to that paper. Colour matrices: IEC 61966-2-1 (sRGB) primaries with the
// D65 white, as tabulated by B. Lindbloom ("RGB/XYZ Matrices"); CIELAB: CIE 15:2004 section 8.2.1.
#include "rayscan/analysis/flip.hpp"

#include "rayscan/base/job.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace rayscan::analysis {

namespace {

using Colour3 = std::array<double, 3>;

// --- colour spaces -------------------------------------------------------------------------

double srgb_to_linear(double c) {  // IEC 61966-2-1, the inverse transfer function
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

Colour3 linear_rgb_to_xyz(const Colour3& c) {
  return {0.4124564 * c[0] + 0.3575761 * c[1] + 0.1804375 * c[2],
          0.2126729 * c[0] + 0.7151522 * c[1] + 0.0721750 * c[2],
          0.0193339 * c[0] + 0.1191920 * c[1] + 0.9503041 * c[2]};
}

Colour3 xyz_to_linear_rgb(const Colour3& x) {
  return {3.2404542 * x[0] - 1.5371385 * x[1] - 0.4985314 * x[2],
          -0.9692660 * x[0] + 1.8760108 * x[1] + 0.0415560 * x[2],
          0.0556434 * x[0] - 0.2040259 * x[1] + 1.0572252 * x[2]};
}

/// The reference white: XYZ of linear RGB (1, 1, 1) (D65).
const Colour3& white() {
  static const Colour3 w = linear_rgb_to_xyz({1.0, 1.0, 1.0});
  return w;
}

/// XYZ -> YyCxCz (paper section 4.1, after Johnson & Fairchild): a linear opponent space.
Colour3 xyz_to_ycxcz(const Colour3& x) {
  const Colour3& w = white();
  const double xr = x[0] / w[0], yr = x[1] / w[1], zr = x[2] / w[2];
  return {116.0 * yr - 16.0, 500.0 * (xr - yr), 200.0 * (yr - zr)};
}

Colour3 ycxcz_to_xyz(const Colour3& c) {
  const Colour3& w = white();
  const double yr = (c[0] + 16.0) / 116.0;
  return {(c[1] / 500.0 + yr) * w[0], yr * w[1], (yr - c[2] / 200.0) * w[2]};
}

/// CIE 1976 L*a*b* of an XYZ colour relative to white() (CIE 15:2004, 8.2.1).
Colour3 xyz_to_lab(const Colour3& x) {
  constexpr double d = 6.0 / 29.0;
  const auto f = [](double t) { return t > d * d * d ? std::cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0; };
  const Colour3& w = white();
  const double fx = f(x[0] / w[0]), fy = f(x[1] / w[1]), fz = f(x[2] / w[2]);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

/// Hunt-adjusted CIELAB (paper eq. 4's input): a and b scaled by 0.01 L.
Colour3 hunt(const Colour3& lab) { return {lab[0], 0.01 * lab[0] * lab[1], 0.01 * lab[0] * lab[2]}; }

/// HyAB distance (Abasi et al. 2020, paper eq. 4): |dL| + Euclidean (a, b) distance.
double hyab(const Colour3& p, const Colour3& q) {
  return std::abs(p[0] - q[0]) + std::hypot(p[1] - q[1], p[2] - q[2]);
}

constexpr double kQc = 0.7, kPc = 0.4, kPt = 0.95, kQf = 0.5;
constexpr double kFeatureWidthDeg = 0.082;  // w in the paper's section 4.2

// --- filters -------------------------------------------------------------------------------

/// A 1-D kernel of odd length 2 r + 1, centre at index r.
using Kernel = std::vector<float>;

/// Convolve each row of plane `src` (w x h) with `k`, clamping at the edges. `cancel` (nullptr =
/// never) is checked before each block of rows (FlipOptions::cancel).
void convolve_rows(const std::vector<float>& src, std::vector<float>& dst, int w, int h, const Kernel& k,
                   const std::atomic<bool>* cancel) {
  const int r = static_cast<int>(k.size() / 2);
  dst.resize(src.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    throw_if_cancelled(cancel);  // out of the body: TBB skips the blocks not started
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const float* s = src.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      float* o = dst.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(w);
      for (int x = 0; x < w; ++x) {
        double acc = 0.0;
        for (int i = -r; i <= r; ++i) acc += static_cast<double>(k[static_cast<std::size_t>(i + r)]) * s[std::clamp(x + i, 0, w - 1)];
        o[x] = static_cast<float>(acc);
      }
    }
  });
}

/// Convolve each column of plane `src` (w x h) with `k`, clamping at the edges; `cancel` as
/// convolve_rows'.
void convolve_cols(const std::vector<float>& src, std::vector<float>& dst, int w, int h, const Kernel& k,
                   const std::atomic<bool>* cancel) {
  const int r = static_cast<int>(k.size() / 2);
  dst.resize(src.size());
  const auto W = static_cast<std::size_t>(w);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    throw_if_cancelled(cancel);
    std::vector<double> acc(W);
    for (int y = rows.begin(); y < rows.end(); ++y) {
      std::fill(acc.begin(), acc.end(), 0.0);
      for (int i = -r; i <= r; ++i) {
        const double kv = k[static_cast<std::size_t>(i + r)];
        const float* s = src.data() + static_cast<std::size_t>(std::clamp(y + i, 0, h - 1)) * W;
        for (std::size_t x = 0; x < W; ++x) acc[x] += kv * s[x];
      }
      float* o = dst.data() + static_cast<std::size_t>(y) * W;
      for (std::size_t x = 0; x < W; ++x) o[x] = static_cast<float>(acc[x]);
    }
  });
}

/// Separable 2-D convolution: rows with kx, then columns with ky; `cancel` as convolve_rows'.
std::vector<float> convolve(const std::vector<float>& src, int w, int h, const Kernel& kx, const Kernel& ky,
                            const std::atomic<bool>* cancel) {
  std::vector<float> tmp, out;
  convolve_rows(src, tmp, w, h, kx, cancel);
  convolve_cols(tmp, out, w, h, ky, cancel);
  return out;
}

/// One channel's contrast sensitivity function as a sum of Gaussians (paper eq. 2-3, Table 1):
/// S(x) = sum_i a_i sqrt(pi / b_i) exp(-pi^2 x^2 / b_i), x in degrees.
struct Csf {
  double a1, b1, a2, b2;
};
constexpr std::array<Csf, 3> kCsf = {{{1.0, 0.0047, 0.0, 1e-5},     // achromatic (Yy)
                                      {1.0, 0.0053, 0.0, 1e-5},     // red-green (Cx)
                                      {34.1, 0.04, 13.5, 0.025}}};  // blue-yellow (Cz)

/// Filter one YyCxCz plane with its CSF: the 2-D kernel sum_i a_i sqrt(pi/b_i) exp(-pi^2 (x^2 +
/// y^2) / b_i) over offsets within `radius` pixels, normalised to unit sum. Each Gaussian term
/// is separable; the terms are filtered apart and added with their share of the 2-D sum.
std::vector<float> csf_filter(const std::vector<float>& plane, int w, int h, const Csf& c, double ppd, int radius,
                              const std::atomic<bool>* cancel) {
  const std::array<std::array<double, 2>, 2> terms = {{{c.a1, c.b1}, {c.a2, c.b2}}};
  std::array<Kernel, 2> k;
  std::array<double, 2> weight{0.0, 0.0};
  double total = 0.0;
  for (std::size_t t = 0; t < 2; ++t) {
    const double a = terms[t][0], b = terms[t][1];
    if (a == 0.0) continue;
    double s = 0.0;
    std::vector<double> g(static_cast<std::size_t>(2 * radius + 1));
    for (int i = -radius; i <= radius; ++i) {
      const double x = i / ppd;  // degrees
      g[static_cast<std::size_t>(i + radius)] = std::exp(-std::numbers::pi * std::numbers::pi * x * x / b);
      s += g[static_cast<std::size_t>(i + radius)];
    }
    k[t].resize(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) k[t][i] = static_cast<float>(g[i] / s);
    weight[t] = a * std::sqrt(std::numbers::pi / b) * s * s;  // this term's 2-D sum
    total += weight[t];
  }
  std::vector<float> out(plane.size(), 0.0f);
  for (std::size_t t = 0; t < 2; ++t) {
    if (weight[t] == 0.0) continue;
    const std::vector<float> f = convolve(plane, w, h, k[t], k[t], cancel);
    const auto share = static_cast<float>(weight[t] / total);
    for (std::size_t p = 0; p < out.size(); ++p) out[p] += share * f[p];
  }
  return out;
}

/// The feature detectors of section 4.2 as separable parts: g = the normalised Gaussian of
/// standard deviation sigma; edge = its first derivative -x g(x), point = its second derivative
/// (x^2 / sigma^2 - 1) g(x), each scaled so its positive weights sum to 1 and its negative
/// weights to -1 (the 2-D kernels edge(x) g(y), point(x) g(y) then have the same property).
struct FeatureKernels {
  Kernel gauss, edge, point;
};

FeatureKernels feature_kernels(double ppd) {
  const double sigma = 0.5 * kFeatureWidthDeg * ppd;
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  const std::size_t n = static_cast<std::size_t>(2 * r + 1);
  std::vector<double> g(n), e(n), p(n);
  double gs = 0.0;
  for (int i = -r; i <= r; ++i) {
    const double x = i, gi = std::exp(-x * x / (2.0 * sigma * sigma));
    g[static_cast<std::size_t>(i + r)] = gi;
    e[static_cast<std::size_t>(i + r)] = -x * gi;
    p[static_cast<std::size_t>(i + r)] = (x * x / (sigma * sigma) - 1.0) * gi;
    gs += gi;
  }
  const auto balance = [](std::vector<double>& v) {
    double pos = 0.0, neg = 0.0;
    for (double x : v) (x > 0 ? pos : neg) += x;
    for (double& x : v) x = x > 0 ? x / pos : (x < 0 ? x / -neg : 0.0);
  };
  balance(e);
  balance(p);
  FeatureKernels k;
  for (std::size_t i = 0; i < n; ++i) {
    k.gauss.push_back(static_cast<float>(g[i] / gs));
    k.edge.push_back(static_cast<float>(e[i]));
    k.point.push_back(static_cast<float>(p[i]));
  }
  return k;
}

/// Magnitudes of the edge and point responses (paper eq. 6-7) of the achromatic plane.
void feature_magnitudes(const std::vector<float>& grey, int w, int h, const FeatureKernels& k,
                        std::vector<float>& edge, std::vector<float>& point, const std::atomic<bool>* cancel) {
  const std::vector<float> ex = convolve(grey, w, h, k.edge, k.gauss, cancel);
  const std::vector<float> ey = convolve(grey, w, h, k.gauss, k.edge, cancel);
  const std::vector<float> px = convolve(grey, w, h, k.point, k.gauss, cancel);
  const std::vector<float> py = convolve(grey, w, h, k.gauss, k.point, cancel);
  edge.resize(grey.size());
  point.resize(grey.size());
  for (std::size_t i = 0; i < grey.size(); ++i) {
    edge[i] = std::hypot(ex[i], ey[i]);
    point[i] = std::hypot(px[i], py[i]);
  }
}

/// Planes of one input image after the colour-space conversions.
struct Planes {
  std::array<std::vector<float>, 3> ycxcz;  ///< YyCxCz, unfiltered
  std::vector<float> grey;                  ///< (Yy + 16) / 116, the feature pipeline's input
};

Planes to_planes(std::span<const float> rgb, std::size_t n, bool linear_input) {
  Planes p;
  for (auto& c : p.ycxcz) c.resize(n);
  p.grey.resize(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      Colour3 c;
      for (std::size_t k = 0; k < 3; ++k) {
        double v = rgb[i * 3 + k];
        v = std::isnan(v) ? 0.0 : std::clamp(v, 0.0, 1.0);
        c[k] = linear_input ? v : srgb_to_linear(v);
      }
      const Colour3 y = xyz_to_ycxcz(linear_rgb_to_xyz(c));
      for (std::size_t k = 0; k < 3; ++k) p.ycxcz[k][i] = static_cast<float>(y[k]);
      p.grey[i] = static_cast<float>((y[0] + 16.0) / 116.0);
    }
  });
  return p;
}

/// Hunt-adjusted CIELAB of a filtered YyCxCz sample (back through linear RGB clamped to [0, 1]).
Colour3 filtered_to_hunt_lab(const Colour3& ycxcz) {
  Colour3 rgb = xyz_to_linear_rgb(ycxcz_to_xyz(ycxcz));
  for (double& v : rgb) v = std::clamp(v, 0.0, 1.0);
  return hunt(xyz_to_lab(linear_rgb_to_xyz(rgb)));
}

}  // namespace

double flip_pixels_per_degree(double distance_m, double resolution_x, double monitor_width_m) {
  if (!(distance_m > 0) || !(resolution_x > 0) || !(monitor_width_m > 0) || !std::isfinite(distance_m) ||
      !std::isfinite(resolution_x) || !std::isfinite(monitor_width_m))
    throw std::invalid_argument("flip_pixels_per_degree: distance, resolution and monitor width must be finite and > 0");
  return distance_m * (resolution_x / monitor_width_m) * std::numbers::pi / 180.0;
}

double flip_max_colour_difference() {
  const Colour3 green = hunt(xyz_to_lab(linear_rgb_to_xyz({0.0, 1.0, 0.0})));
  const Colour3 blue = hunt(xyz_to_lab(linear_rgb_to_xyz({0.0, 0.0, 1.0})));
  return std::pow(hyab(green, blue), kQc);
}

FlipResult flip(std::span<const float> reference, std::span<const float> test, int width, int height,
                const FlipOptions& opts, std::span<const std::uint8_t> ignore) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("flip: image size " + std::to_string(width) + "x" + std::to_string(height) +
                                " (expected at least 1x1)");
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  if (reference.size() != 3 * n || test.size() != 3 * n)
    throw std::invalid_argument("flip: expected " + std::to_string(3 * n) + " RGB samples for " + std::to_string(width) +
                                "x" + std::to_string(height) + ", got " + std::to_string(reference.size()) + " and " +
                                std::to_string(test.size()));
  if (!ignore.empty() && ignore.size() != n)
    throw std::invalid_argument("flip: ignore mask has " + std::to_string(ignore.size()) + " flags, expected " +
                                std::to_string(n));
  const double ppd = opts.pixels_per_degree;
  if (!(ppd > 0) || !std::isfinite(ppd)) throw std::invalid_argument("flip: pixels per degree must be finite and > 0");

  const Planes pr = to_planes(reference, n, opts.linear_input), pt = to_planes(test, n, opts.linear_input);

  // Colour pipeline: CSF filtering in YyCxCz. The filter radius covers 3 standard deviations of
  // the widest Gaussian of Table 1 (b = 0.04): sigma = sqrt(b / (2 pi^2)) degrees.
  const double bmax = 0.04;
  const int radius = static_cast<int>(std::ceil(3.0 * std::sqrt(bmax / (2.0 * std::numbers::pi * std::numbers::pi)) * ppd));
  std::array<std::vector<float>, 3> fr, ft;
  for (std::size_t c = 0; c < 3; ++c) {
    fr[c] = csf_filter(pr.ycxcz[c], width, height, kCsf[c], ppd, radius, opts.cancel);
    ft[c] = csf_filter(pt.ycxcz[c], width, height, kCsf[c], ppd, radius, opts.cancel);
  }

  // Feature pipeline on the unfiltered achromatic planes.
  const FeatureKernels fk = feature_kernels(ppd);
  std::vector<float> er, prr, et, ptt;
  feature_magnitudes(pr.grey, width, height, fk, er, prr, opts.cancel);
  feature_magnitudes(pt.grey, width, height, fk, et, ptt, opts.cancel);

  FlipResult res;
  res.error.resize(n);
  res.colour_error.resize(n);
  res.feature_error.resize(n);
  const double cmax = flip_max_colour_difference();
  const double knee = kPc * cmax;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
    throw_if_cancelled(opts.cancel);
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Colour3 a = filtered_to_hunt_lab({fr[0][i], fr[1][i], fr[2][i]});
      const Colour3 b = filtered_to_hunt_lab({ft[0][i], ft[1][i], ft[2][i]});
      const double d = std::pow(hyab(a, b), kQc);
      const double ec = d < knee ? kPt / knee * d : kPt + (d - knee) / (cmax - knee) * (1.0 - kPt);
      const double df = std::max(std::abs(double(er[i]) - et[i]), std::abs(double(prr[i]) - ptt[i]));
      const double ef = std::pow(df / std::numbers::sqrt2, kQf);
      res.colour_error[i] = static_cast<float>(ec);
      res.feature_error[i] = static_cast<float>(ef);
      res.error[i] = static_cast<float>(std::pow(ec, 1.0 - ef));
    }
  });
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!ignore.empty() && ignore[i]) {
      res.error[i] = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    sum += res.error[i];
    ++res.pixels;
  }
  res.mean = res.pixels ? sum / static_cast<double>(res.pixels) : std::numeric_limits<double>::quiet_NaN();
  return res;
}

}  // namespace rayscan::analysis
