// FLIP, NVIDIA's perceptual difference evaluator for alternating images, in its LDR form:
// P. Andersson, J. Nilsson, T. Akenine-Moeller, M. Oskarsson, K. Astroem, M. D. Fairchild,
// "FLIP: A Difference Evaluator for Alternating Images", Proc. ACM Comput. Graph. Interact. Tech.
// 3(2), 2020 (HPG 2020), section 4. Written from the paper's description:
//   colour pipeline (section 4.1): sRGB -> linear RGB -> XYZ (D65) -> YyCxCz (opponent space of
//     Johnson & Fairchild); each channel convolved with its spatial contrast-sensitivity filter
//     (sum of Gaussians, eq. 2-3, parameters of Table 1) at the observer's pixels per degree;
//     back to linear RGB clamped to [0, 1] -> CIELAB -> Hunt adjustment a,b *= 0.01 L -> HyAB
//     distance |dL| + ||(da, db)|| raised to q_c = 0.7 and mapped to [0, 1] with the knee
//     p_c = 0.4, p_t = 0.95 relative to the green-blue maximum (eq. 4-5);
//   feature pipeline (section 4.2): on the normalised achromatic channel (Yy + 16) / 116 of the
//     unfiltered images, edge (first Gaussian derivative) and point (second derivative) detectors
//     with sigma = 0.5 * 0.082 degrees; feature error = (max(|d|edge||, |d|point||) / sqrt 2)^q_f,
//     q_f = 0.5 (eq. 6-8);
//   combination (eq. 9): FLIP = colour_error ^ (1 - feature_error), per pixel in [0, 1].
// Borders: samples outside the image repeat the edge pixel (clamp to edge).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rayscan::analysis {

/// Pixels per degree of visual angle for a viewer `distance_m` metres from a monitor
/// `monitor_width_m` metres wide showing `resolution_x` pixels across (FLIP paper section 4):
/// ppd = distance * (resolution_x / monitor_width) * pi / 180. The paper's default viewer
/// (0.7 m, 3840 px on 0.7 m) gives 67.02. Throws std::invalid_argument unless all are > 0.
double flip_pixels_per_degree(double distance_m = 0.7, double resolution_x = 3840.0,
                              double monitor_width_m = 0.7);

/// Options of flip().
struct FlipOptions {
  double pixels_per_degree = 67.02064327658226;  ///< flip_pixels_per_degree() of the default viewer
  bool linear_input = false;  ///< inputs are linear RGB (e.g. EXR), not sRGB-encoded (PNG, JPEG)
  /// Checked before each block of rows of every filter pass and of the final per-pixel pass: once
  /// set, flip() throws rayscan::Cancelled (base/job.hpp); nullptr = never. Not owned.
  const std::atomic<bool>* cancel = nullptr;
};

/// Per-pixel FLIP maps and their mean.
struct FlipResult {
  std::vector<float> error;          ///< FLIP per pixel, width * height, row major, in [0, 1]; NaN where ignored
  std::vector<float> colour_error;   ///< the colour pipeline's error (eq. 5) per pixel
  std::vector<float> feature_error;  ///< the feature pipeline's error (eq. 8) per pixel
  double mean = 0.0;                 ///< mean FLIP over the pixels not ignored (NaN when none)
  std::size_t pixels = 0;            ///< pixels averaged
};

/// The colour difference normaliser c_max of eq. 5: the HyAB distance of the Hunt-adjusted CIELAB
/// colours of linear green (0, 1, 0) and blue (0, 0, 1), raised to q_c = 0.7 (about 41.2).
double flip_max_colour_difference();

/// LDR-FLIP of `test` against `reference`, both width * height * 3 interleaved RGB samples
/// (row major, top row first), sRGB-encoded in [0, 1] unless opts.linear_input (values outside
/// [0, 1] are clamped). `ignore` is empty or width * height flags (1 = leave out of the mean;
/// those pixels still take part in the filters). Parallel over rows (TBB); the result does not
/// depend on the thread count. Throws std::invalid_argument for a size mismatch, a non-positive
/// size or pixels_per_degree <= 0, rayscan::Cancelled once opts.cancel is set.
FlipResult flip(std::span<const float> reference, std::span<const float> test, int width, int height,
                const FlipOptions& opts = {}, std::span<const std::uint8_t> ignore = {});

}  // namespace rayscan::analysis
