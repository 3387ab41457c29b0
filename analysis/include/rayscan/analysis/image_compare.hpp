// Numerical comparison of a rendered image against a reference (`rayscan compare`): MAE, RMSE,
// PSNR, maximum error, SSIM and the share of pixels over a threshold, plus idiff-style pass/fail.
//
// Definitions (all over the compared channels of the pixels not ignored by the mask; N pixels,
// C channels, e = test - reference per sample):
//   MAE  = sum |e| / (N C)             RMSE = sqrt(sum e^2 / (N C))
//   PSNR = 20 log10(peak / RMSE) dB,   peak = max(1, largest finite sample of either image)
//   (PSNR = +inf when RMSE = 0). These are exactly OpenImageIO's ImageBufAlgo::compare, which
//   `idiff` prints as "Mean error", "RMS error" and "Peak SNR": per sample over all channels, peak
//   1 for normalised images and the largest value for HDR ones.
//   Pixel error = max over the channels of |e| (idiff counts a pixel "over T" when any channel
//   differs by more than T; so do we).
//   SSIM: ssim.hpp on one signal: Rec. ITU-R BT.709 luminance Y = 0.2126 R + 0.7152 G + 0.0722 B
//   of the stored (not linearised) values when R, G, B are compared, otherwise the mean of the
//   compared channels (the channel itself for one channel, e.g. --channel depth); windows holding
//   an ignored pixel or a NaN/Inf sample are left out of the mean.
#pragma once

#include "rayscan/image/image_file.hpp"
#include "rayscan/analysis/ssim.hpp"

#include <atomic>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace rayscan::analysis {

/// Rec. ITU-R BT.709 luma weights used for the SSIM signal of RGB images.
inline constexpr double kLumaR = 0.2126, kLumaG = 0.7152, kLumaB = 0.0722;

/// Per-channel error statistics.
struct ChannelStats {
  std::string name;
  double mae = 0, rmse = 0, max_error = 0;
};

/// Everything `rayscan compare` reports about one image pair.
struct CompareMetrics {
  int width = 0, height = 0;
  std::vector<std::string> channels;   ///< compared channel names (reference's)
  std::size_t pixels_compared = 0;     ///< pixels not ignored by the mask
  std::size_t pixels_ignored = 0;      ///< pixels ignored by the mask
  double mae = 0, rmse = 0;
  double psnr = std::numeric_limits<double>::infinity();  ///< dB; +inf when RMSE = 0
  double peak = 1.0;                   ///< the PSNR peak value
  double max_error = 0;                ///< largest |e| (+inf for a finite/non-finite mismatch)
  int max_x = 0, max_y = 0, max_c = 0; ///< where (pixel coordinates incl. data-window origin)
  float max_ref = 0, max_test = 0;     ///< the two samples there
  std::size_t nonfinite_mismatches = 0;  ///< samples where exactly one side is NaN/Inf or they differ in kind
  std::vector<ChannelStats> per_channel;
  double ssim = 0;                     ///< mean over the usable windows (ssim.hpp); NaN when none
  std::string ssim_undefined;          ///< why ssim is NaN (SsimResult::undefined, or "not computed")
  std::size_t ssim_windows = 0;        ///< SSIM windows averaged
  std::size_t ssim_positions = 0;      ///< SSIM window positions inside the image
  std::string ssim_signal;             ///< "luminance", or the channel(s) averaged
  double flip = std::numeric_limits<double>::quiet_NaN();  ///< mean LDR-FLIP (flip.hpp); NaN when not computed
  std::string flip_signal;             ///< why/how FLIP was computed ("RGB, sRGB-encoded", "Y as grey", or why not)
  double fail_threshold = 0, warn_threshold = 0;  ///< the pixel-error thresholds counted
  std::size_t over_fail = 0, over_warn = 0;       ///< pixels whose error exceeds them
  [[nodiscard]] double percent_over_fail() const { return percent(over_fail); }
  [[nodiscard]] double percent_over_warn() const { return percent(over_warn); }
  [[nodiscard]] double percent(std::size_t n) const {
    return pixels_compared ? 100.0 * static_cast<double>(n) / static_cast<double>(pixels_compared) : 0.0;
  }
};

/// Options of compare_images().
struct CompareOptions {
  double fail_threshold = 1e-6;  ///< count pixels whose error exceeds this (idiff -fail default)
  double warn_threshold = 1e-6;  ///< ... and this (idiff -warn default)
  bool compute_ssim = true;
  SsimOptions ssim;
  /// Checked before each block of rows of the error pass and of SSIM (ssim()'s `cancel`): once
  /// set, compare_images throws rayscan::Cancelled (base/job.hpp); nullptr = never. Not owned.
  const std::atomic<bool>* cancel = nullptr;
};

/// Compare `test` against `reference`: both must have the same size and channel count (channels
/// are matched by position; select them first with select_channels). `ignore` is empty or holds
/// width * height flags, 1 = leave the pixel out of every metric. NaN matches NaN and +/-Inf
/// matches the same infinity; any other non-finite sample counts as an infinite error (not summed
/// into MAE/RMSE, counted in nonfinite_mismatches). Throws std::invalid_argument on a size or
/// channel-count mismatch, naming both sizes, rayscan::Cancelled once opts.cancel is set.
CompareMetrics compare_images(const Image& reference, const Image& test,
                              std::span<const std::uint8_t> ignore = {},
                              const CompareOptions& opts = {});

/// The signal SSIM is computed on (see the file comment), as width * height floats.
/// Sets `name` to "luminance" or the averaged channel names.
std::vector<float> ssim_signal(const Image& img, std::string& name);

/// Per-pixel error max_c |test - reference| (width * height, row major); +inf where a
/// non-finite mismatch occurs, NaN for ignored pixels. Same preconditions as compare_images().
/// `cancel` is checked before each block of rows: once set, pixel_errors throws
/// rayscan::Cancelled (base/job.hpp); nullptr = never. Not owned.
std::vector<float> pixel_errors(const Image& reference, const Image& test,
                                std::span<const std::uint8_t> ignore = {},
                                const std::atomic<bool>* cancel = nullptr);

/// An RGB heat map of `errors` (from pixel_errors) through heat_ramp() over [0, vmax]; errors
/// above vmax are white; ignored (NaN) pixels are blue (0, 0, 1), which the ramp never produces.
/// Throws std::invalid_argument unless vmax > 0 and errors.size() == width * height.
Image error_heatmap(std::span<const float> errors, int width, int height, double vmax);

/// One level (fail or warn) of idiff-style criteria. A level triggers when ANY enabled test
/// does: the pixel test (more than `percent` % of compared pixels have an error above
/// `threshold`), any pixel error above `max_error` (idiff -hardfail), PSNR below `min_psnr`,
/// SSIM below `min_ssim`, mean FLIP above `max_flip`.
struct Limits {
  bool pixel_test = true;
  double threshold = 1e-6;
  double percent = 0.0;
  double max_error = std::numeric_limits<double>::infinity();
  double min_psnr = -std::numeric_limits<double>::infinity();
  double min_ssim = -std::numeric_limits<double>::infinity();
  double max_flip = std::numeric_limits<double>::infinity();  ///< mean FLIP above this triggers
};

/// The outcome of a comparison: no limit triggered, a warn limit triggered, or a fail limit.
enum class Verdict { pass, warn, fail };

/// Outcome of judge(): the verdict and a human-readable reason per triggered test.
struct Judgement {
  Verdict verdict = Verdict::pass;
  std::vector<std::string> reasons;
};

/// Apply fail then warn limits to `m` (whose fail/warn thresholds must be those of the limits'
/// pixel tests). Throws std::invalid_argument when a min_ssim is set but SSIM is undefined
/// (the message gives CompareMetrics::ssim_undefined: image smaller than the window, every window
/// holding a masked or non-finite sample, or not computed), or a max_flip is set but FLIP was not
/// computed (channels other than RGB or Y).
Judgement judge(const CompareMetrics& m, const Limits& fail, const Limits& warn);

/// "pass", "warn" or "fail".
const char* to_string(Verdict v);

}  // namespace rayscan::analysis
