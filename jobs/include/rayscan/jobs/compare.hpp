// The compare job: check an image against a reference -- channel picking,
// mask (alpha / point-index AOV), resize, metrics, idiff-style verdict, diff heat map -- as one
// library call. `rayscan compare` and the Python module's rayscan.compare() wrap run_compare().
#pragma once

#include "rayscan/analysis/image_compare.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/jobs/memory_source.hpp"

#include <optional>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The analysis library types this job's options and results are made of.
using analysis::CompareMetrics;
using analysis::CompareOptions;
using analysis::Judgement;
using analysis::Limits;

/// One level (fail or warn) of criteria as given by a user; unset = not given. limits() turns it
/// into Limits with idiff's rule: with no criterion given, fail on any pixel error over 1e-6.
/// Exception (run_compare): when fail criteria are given and no warn criterion, the warn level is
/// off, so a verdict asked for by SSIM or PSNR alone is not turned into a WARNING by idiff's
/// 1e-6 pixel default.
struct Criteria {
  std::optional<double> threshold;  ///< pixel error threshold (idiff -fail / -warn)
  std::optional<double> percent;    ///< % of pixels allowed over the threshold (-failpercent)
  std::optional<double> max_error;  ///< any pixel error above this triggers (-hardfail)
  std::optional<double> min_psnr;   ///< PSNR below this (dB) triggers
  std::optional<double> min_ssim;   ///< SSIM below this triggers
  std::optional<double> max_flip;   ///< mean FLIP above this triggers
  /// The Limits these criteria mean (see above).
  [[nodiscard]] Limits limits() const;
  /// Throws OptionError naming the option (`level` "fail" or "warn", then "_percent", "_psnr", ...)
  /// of a criterion that is NaN or infinite: a NaN limit compares false with every metric, so it
  /// would pass any pair of images.
  void require_finite(const std::string& level) const;
  /// Whether any criterion is given.
  [[nodiscard]] bool given() const {
    return threshold || percent || max_error || min_psnr || min_ssim || max_flip;
  }
};

/// Inputs of run_compare(). An invalid option throws OptionError naming the fields (`flip_ppd`),
/// which the CLI writes as its flags (`--flip-ppd`).
struct CompareJobOptions {
  std::string reference_file, image_file;      ///< files (any format OpenImageIO reads)
  const Image* reference = nullptr;            ///< in-memory reference instead of reference_file
  const Image* image = nullptr;                ///< in-memory image instead of image_file
  std::vector<std::string> channels;           ///< compare these (renderer aliases: depth -> Z, index -> id);
                                               ///< empty = R,G,B, else Y, else non-alpha non-index channels
  bool alpha = false;                          ///< also compare the alpha channel
  bool mask = false;                           ///< ignore reference alpha == 0 and index-AOV misses
  std::string mask_channel = "id";             ///< point-index AOV channel name
  std::string mask_index;                      ///< file holding the point-index AOV (implies mask)
  bool resize = false;                         ///< resample the image to the reference's size
  std::string resize_filter = "lanczos3";      ///< OpenImageIO filter name
  Criteria fail, warn;                         ///< verdict criteria
  double ssim_range = 1.0;                     ///< SSIM dynamic range L
  std::string diff;                            ///< write the error heat map here ("" = no)
  std::optional<double> diff_max;              ///< error mapped to white (default: the max error)
  bool flip = true;                            ///< compute mean LDR-FLIP (flip.hpp) for R,G,B or Y images
  double flip_ppd = 67.02064327658226;         ///< FLIP observer's pixels per degree (flip_pixels_per_degree())
  std::string flip_map;                        ///< write the FLIP error map here (heat ramp over [0, 1]; "" = no)
  /// `cancel` only: checked between the stages and before each block of rows of the error, SSIM,
  /// FLIP and heat-map passes (run_compare then throws Cancelled and writes no map); threads,
  /// progress, log and distributor are unused (TBB's default arena).
  JobControl control;
};

/// Output of run_compare().
struct CompareJobResult {
  /// File names, or the in-memory images' Image::source (kMemorySource when it is empty).
  std::string reference_name, image_name;
  CompareMetrics metrics;                      ///< MAE, RMSE, PSNR, max error, SSIM, pixels over thresholds
  Judgement judgement;                         ///< verdict and reasons
  CompareOptions used;                         ///< thresholds and SSIM parameters used
  /// The limits judged with, fail and warn (Criteria::limits with run_compare's exception): a
  /// level whose `pixel_test` is false has no pixel threshold, whatever `used` holds.
  Limits fail_limits, warn_limits;
  std::vector<std::string> image_channels;     ///< the image's channels compared (metrics.channels: reference's)
  bool masked = false;                         ///< a mask was applied
  std::string mask_sources;                    ///< what the mask came from ("ref.png:A == 0 or r.exr:id miss (-1)")
  std::string resized_from;                    ///< "WxH" when the image was resized, else ""
  std::string resize_filter;                   ///< filter used when resized
  double diff_max = 0.0;                       ///< heat-map range top (when diff was written)
  std::string diff;                            ///< heat map written ("" = none)
  double flip_ppd = 0.0;                       ///< pixels per degree FLIP used (when computed)
  std::string flip_map;                        ///< FLIP map written ("" = none)
};

/// Reads both images, picks channels, builds the mask, resizes if asked, computes the metrics
/// (compare_images) and mean FLIP (flip(); R,G,B or Y channels only: PNG/JPEG/TIFF samples are
/// taken as sRGB-encoded, EXR/HDR ones as linear and encoded first), judges them (judge) and
/// writes the heat map and the FLIP map (PNG, JPEG, TIFF: the map with a legend strip below it,
/// raster_preview.hpp's draw_legend; EXR: the bare map at the images' size), both maps as one
/// OutputTransaction: renamed into place together once both are written, so when either fails
/// neither old file is replaced and no temporary is left. Throws std::invalid_argument
/// for a user error (missing channel, size mismatch without resize, bad mask, SSIM limit on a tiny
/// image; one line), std::runtime_error "<file>: <reason>" for unreadable or unwritable files,
/// rayscan::Cancelled once options.control.cancel is set.
CompareJobResult run_compare(const CompareJobOptions& options);

/// The JSON report printed by `rayscan compare --json` (2-space indent). `over_threshold.fail` and
/// `.warn` are {threshold, pixels, percent} where that level has a pixel test, null where it has
/// none (the text report's "off").
std::string compare_report_json(const CompareJobResult& result);

/// The idiff-style text report printed by `rayscan compare`, ending in PASS, WARNING or FAILURE.
std::string compare_report_text(const CompareJobResult& result);

}  // namespace rayscan::jobs
