// Structural similarity (SSIM): Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image
// Quality Assessment: From Error Visibility to Structural Similarity", IEEE Trans. Image
// Processing 13(4), 2004 -- eq. (13) evaluated with the paper's section III-C settings.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace rayscan::analysis {

/// SSIM parameters; the defaults are the paper's (section III-C): an 11x11 circular-symmetric
/// Gaussian window with standard deviation 1.5 pixels, normalised to unit sum; K1 = 0.01,
/// K2 = 0.03; C1 = (K1 L)^2, C2 = (K2 L)^2 with L the dynamic range of the values (1 for
/// normalised images).
struct SsimOptions {
  int window = 11;             ///< window side in pixels (odd, >= 1)
  double sigma = 1.5;          ///< Gaussian standard deviation in pixels
  double k1 = 0.01;
  double k2 = 0.03;
  double dynamic_range = 1.0;  ///< L
};

/// Result of ssim(): the mean SSIM (MSSIM, paper eq. (17)) over the windows used.
struct SsimResult {
  double mssim = 0.0;         ///< NaN when no window was used (see `undefined`)
  std::size_t windows = 0;    ///< number of windows averaged
  std::size_t positions = 0;  ///< window positions inside the image ((W - 10) x (H - 10) for 11x11)
  /// Why mssim is NaN, one line: the image is smaller than the window, or every window holds a
  /// masked pixel or a non-finite sample. Empty when mssim is defined.
  std::string undefined;
};

/// The normalised 1-D Gaussian weights of length opts.window (the 2-D window is their outer
/// product). Throws std::invalid_argument for an even or non-positive window or sigma <= 0.
std::vector<double> ssim_gaussian_weights(const SsimOptions& opts);

/// Mean SSIM of two single-channel images x and y of width * height samples (row major).
/// As in the authors' reference implementation, only windows lying entirely inside the image are
/// used ("valid" filtering, (width - 10) x (height - 10) positions for the default window).
/// A window is left out of the mean when any of its samples is flagged in `ignore` (empty, or
/// width * height flags) or is NaN or infinite in x or y: the paper's local statistics are
/// defined only over finite samples, and a masked pixel must not change the SSIM of its unmasked
/// neighbours. The result is the mean over the remaining windows (MSSIM over the valid windows),
/// NaN with the reason in `undefined` when none remains. Parallel over rows (TBB); the result
/// does not depend on the thread count. `cancel` is checked before each block of 32 output rows:
/// once set, ssim throws rayscan::Cancelled (base/job.hpp); nullptr = never. Not owned.
/// Throws std::invalid_argument when the sizes do not match.
SsimResult ssim(std::span<const float> x, std::span<const float> y, int width, int height,
                std::span<const std::uint8_t> ignore = {}, const SsimOptions& opts = {},
                const std::atomic<bool>* cancel = nullptr);

}  // namespace rayscan::analysis
