// Image comparison metrics; definitions in image_compare.hpp (OpenImageIO ImageBufAlgo::compare
// for MAE/RMSE/PSNR, Wang et al. 2004 for SSIM).
#include "rayscan/analysis/image_compare.hpp"

#include "rayscan/base/job.hpp"
#include "rayscan/image/color_ramp.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rayscan::analysis {

namespace {

std::string size_str(const Image& img) {
  return std::to_string(img.width) + "x" + std::to_string(img.height) + " with " +
         std::to_string(img.nchannels()) + " channel(s)";
}

void check_pair(const Image& ref, const Image& test, std::span<const std::uint8_t> ignore) {
  if (ref.width != test.width || ref.height != test.height || ref.nchannels() != test.nchannels())
    throw std::invalid_argument("image sizes differ: reference " + size_str(ref) + ", test " +
                                size_str(test));
  if (ref.nchannels() == 0) throw std::invalid_argument("no channels to compare");
  if (!ignore.empty() && ignore.size() != ref.npixels())
    throw std::invalid_argument("mask has " + std::to_string(ignore.size()) + " pixels, image has " +
                                std::to_string(ref.npixels()));
}

/// Per-row partial sums, combined in row order so results do not depend on the thread count.
struct RowAcc {
  std::vector<double> abs, sq;  // per channel
  double max_err = -1.0;
  int max_x = 0, max_c = 0;
  float max_ref = 0, max_test = 0;
  double peak = 1.0;
  std::size_t compared = 0, nonfinite = 0, over_fail = 0, over_warn = 0;
  std::vector<double> ch_max;
};

}  // namespace

CompareMetrics compare_images(const Image& ref, const Image& test,
                              std::span<const std::uint8_t> ignore, const CompareOptions& opts) {
  check_pair(ref, test, ignore);
  const std::size_t W = static_cast<std::size_t>(ref.width), H = static_cast<std::size_t>(ref.height);
  const std::size_t C = static_cast<std::size_t>(ref.nchannels());
  std::vector<RowAcc> rows(H);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H), [&](const auto& range) {
    throw_if_cancelled(opts.cancel);  // out of the body: TBB skips the blocks not started
    for (std::size_t y = range.begin(); y < range.end(); ++y) {
      RowAcc& a = rows[y];
      a.abs.assign(C, 0.0);
      a.sq.assign(C, 0.0);
      a.ch_max.assign(C, 0.0);
      for (std::size_t x = 0; x < W; ++x) {
        const std::size_t p = y * W + x;
        if (!ignore.empty() && ignore[p]) continue;
        ++a.compared;
        double pix_err = 0.0;
        for (std::size_t c = 0; c < C; ++c) {
          const float r = ref.pixels[p * C + c], t = test.pixels[p * C + c];
          double e;
          if (std::isfinite(r) && std::isfinite(t)) {
            e = std::fabs(static_cast<double>(t) - static_cast<double>(r));
            a.abs[c] += e;
            a.sq[c] += e * e;
            a.peak = std::max({a.peak, static_cast<double>(r), static_cast<double>(t)});
          } else if ((std::isnan(r) && std::isnan(t)) || (std::isinf(r) && r == t)) {
            e = 0.0;  // NaN matches NaN, Inf matches the same Inf (as idiff)
          } else {
            e = std::numeric_limits<double>::infinity();
            ++a.nonfinite;
          }
          a.ch_max[c] = std::max(a.ch_max[c], e);
          if (e > a.max_err) {
            a.max_err = e;
            a.max_x = static_cast<int>(x);
            a.max_c = static_cast<int>(c);
            a.max_ref = r;
            a.max_test = t;
          }
          pix_err = std::max(pix_err, e);
        }
        a.over_fail += pix_err > opts.fail_threshold;
        a.over_warn += pix_err > opts.warn_threshold;
      }
    }
  });

  CompareMetrics m;
  m.width = ref.width;
  m.height = ref.height;
  m.channels = ref.channels;
  m.fail_threshold = opts.fail_threshold;
  m.warn_threshold = opts.warn_threshold;
  std::vector<double> abs(C, 0.0), sq(C, 0.0), ch_max(C, 0.0);
  double best = -1.0;
  for (std::size_t y = 0; y < H; ++y) {
    const RowAcc& a = rows[y];
    m.pixels_compared += a.compared;
    m.nonfinite_mismatches += a.nonfinite;
    m.over_fail += a.over_fail;
    m.over_warn += a.over_warn;
    m.peak = std::max(m.peak, a.peak);
    for (std::size_t c = 0; c < C; ++c) {
      abs[c] += a.abs[c];
      sq[c] += a.sq[c];
      ch_max[c] = std::max(ch_max[c], a.ch_max[c]);
    }
    if (a.max_err > best) {  // first occurrence in scanline order wins
      best = a.max_err;
      m.max_x = a.max_x + ref.x0;
      m.max_y = static_cast<int>(y) + ref.y0;
      m.max_c = a.max_c;
      m.max_ref = a.max_ref;
      m.max_test = a.max_test;
    }
  }
  m.pixels_ignored = ref.npixels() - m.pixels_compared;
  m.max_error = std::max(best, 0.0);
  double tabs = 0.0, tsq = 0.0;
  const double n = static_cast<double>(m.pixels_compared);
  for (std::size_t c = 0; c < C; ++c) {
    tabs += abs[c];
    tsq += sq[c];
    m.per_channel.push_back({ref.channels[c], n > 0 ? abs[c] / n : 0.0,
                             n > 0 ? std::sqrt(sq[c] / n) : 0.0, ch_max[c]});
  }
  const double nv = n * static_cast<double>(C);
  m.mae = nv > 0 ? tabs / nv : 0.0;
  m.rmse = nv > 0 ? std::sqrt(tsq / nv) : 0.0;
  m.psnr = m.rmse > 0 ? 20.0 * std::log10(m.peak / m.rmse) : std::numeric_limits<double>::infinity();

  if (opts.compute_ssim) {
    std::string name;
    const std::vector<float> sx = ssim_signal(ref, name);
    const std::vector<float> sy = ssim_signal(test, name);
    m.ssim_signal = name;
    const SsimResult s = ssim(sx, sy, ref.width, ref.height, ignore, opts.ssim, opts.cancel);
    m.ssim = s.mssim;
    m.ssim_undefined = s.undefined;
    m.ssim_windows = s.windows;
    m.ssim_positions = s.positions;
  } else {
    m.ssim = std::numeric_limits<double>::quiet_NaN();
    m.ssim_undefined = "not computed";
  }
  return m;
}

std::vector<float> ssim_signal(const Image& img, std::string& name) {
  const int r = img.channel_index("R"), g = img.channel_index("G"), b = img.channel_index("B");
  const std::size_t n = img.npixels(), C = img.channels.size();
  std::vector<float> out(n);
  if (r >= 0 && g >= 0 && b >= 0) {
    name = "luminance";
    for (std::size_t p = 0; p < n; ++p)
      out[p] = static_cast<float>(kLumaR * img.pixels[p * C + static_cast<std::size_t>(r)] +
                                  kLumaG * img.pixels[p * C + static_cast<std::size_t>(g)] +
                                  kLumaB * img.pixels[p * C + static_cast<std::size_t>(b)]);
    return out;
  }
  name.clear();
  for (std::size_t c = 0; c < C; ++c) {
    if (c) name += ',';
    name += img.channels[c];
  }
  if (C > 1) name = "mean(" + name + ")";
  for (std::size_t p = 0; p < n; ++p) {
    double s = 0.0;
    for (std::size_t c = 0; c < C; ++c) s += img.pixels[p * C + c];
    out[p] = static_cast<float>(s / static_cast<double>(C));
  }
  return out;
}

std::vector<float> pixel_errors(const Image& ref, const Image& test,
                                std::span<const std::uint8_t> ignore, const std::atomic<bool>* cancel) {
  check_pair(ref, test, ignore);
  const std::size_t n = ref.npixels(), C = static_cast<std::size_t>(ref.nchannels());
  const std::size_t block = 32 * static_cast<std::size_t>(ref.width);  // pixels between checks: 32 rows
  std::vector<float> err(n);
  for (std::size_t p = 0; p < n; ++p) {
    if (p % block == 0) throw_if_cancelled(cancel);
    if (!ignore.empty() && ignore[p]) {
      err[p] = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    float e = 0.0f;
    for (std::size_t c = 0; c < C; ++c) {
      const float r = ref.pixels[p * C + c], t = test.pixels[p * C + c];
      if (std::isfinite(r) && std::isfinite(t))
        e = std::max(e, static_cast<float>(std::fabs(static_cast<double>(t) - r)));
      else if (!((std::isnan(r) && std::isnan(t)) || (std::isinf(r) && r == t)))
        e = std::numeric_limits<float>::infinity();
    }
    err[p] = e;
  }
  return err;
}

Image error_heatmap(std::span<const float> errors, int width, int height, double vmax) {
  if (!(vmax > 0.0) || !std::isfinite(vmax))
    throw std::invalid_argument("heat map range maximum must be positive and finite");
  Image img = make_image(width, height, {"R", "G", "B"});
  if (errors.size() != img.npixels())
    throw std::invalid_argument("heat map: error buffer does not match the image size");
  for (std::size_t p = 0; p < errors.size(); ++p) {
    const Rgb c = std::isnan(errors[p]) ? Rgb(0.0f, 0.0f, 1.0f) : heat_ramp(errors[p] / vmax);
    img.pixels[3 * p] = c.r;
    img.pixels[3 * p + 1] = c.g;
    img.pixels[3 * p + 2] = c.b;
  }
  return img;
}

namespace {

std::string fmt(const char* f, double a, double b) {
  char buf[160];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

bool triggered(const CompareMetrics& m, const Limits& l, double over_percent,
               std::vector<std::string>& reasons) {
  const std::size_t before = reasons.size();
  if (l.pixel_test && over_percent > l.percent)
    reasons.push_back(fmt("%.6g%% of pixels have error > %.6g", over_percent, l.threshold) +
                      fmt(" (allowed %.6g%%)", l.percent, 0));
  if (m.max_error > l.max_error)
    reasons.push_back(fmt("max error %.6g > %.6g", m.max_error, l.max_error));
  if (m.psnr < l.min_psnr) reasons.push_back(fmt("PSNR %.6g dB < %.6g dB", m.psnr, l.min_psnr));
  if (l.min_ssim > -std::numeric_limits<double>::infinity()) {
    if (std::isnan(m.ssim))
      throw std::invalid_argument("SSIM criterion given but SSIM is undefined (" +
                                  (m.ssim_undefined.empty() ? std::string("not computed") : m.ssim_undefined) +
                                  ")");
    if (m.ssim < l.min_ssim) reasons.push_back(fmt("SSIM %.6g < %.6g", m.ssim, l.min_ssim));
  }
  if (l.max_flip < std::numeric_limits<double>::infinity()) {
    if (std::isnan(m.flip))
      throw std::invalid_argument("FLIP criterion given but FLIP is undefined (" + m.flip_signal + ")");
    if (m.flip > l.max_flip) reasons.push_back(fmt("mean FLIP %.6g > %.6g", m.flip, l.max_flip));
  }
  return reasons.size() > before;
}

}  // namespace

Judgement judge(const CompareMetrics& m, const Limits& fail, const Limits& warn) {
  if (fail.pixel_test && fail.threshold != m.fail_threshold)
    throw std::invalid_argument("judge: fail threshold differs from the one the metrics counted");
  if (warn.pixel_test && warn.threshold != m.warn_threshold)
    throw std::invalid_argument("judge: warn threshold differs from the one the metrics counted");
  Judgement j;
  if (triggered(m, fail, m.percent_over_fail(), j.reasons)) {
    j.verdict = Verdict::fail;
    return j;
  }
  if (triggered(m, warn, m.percent_over_warn(), j.reasons)) j.verdict = Verdict::warn;
  return j;
}

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::pass: return "pass";
    case Verdict::warn: return "warn";
    case Verdict::fail: return "fail";
  }
  return "?";
}

}  // namespace rayscan::analysis
