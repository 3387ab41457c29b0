// `rayscan compare REFERENCE IMAGE`: check a render against a reference image.
// Metrics and their definitions: analysis/include/rayscan/analysis/image_compare.hpp. Pass/fail
// follows OpenImageIO's idiff (thresholds -fail/-failpercent/-hardfail/-warn/-warnpercent), with
// exit code 0 = pass (or warning), 1 = fail, 2 = error. The job is jobs::run_compare
// (rayscan/jobs/compare.hpp); this file parses options and prints.
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/jobs/compare.hpp"
#include "rayscan/render/scene.hpp"

#include <iostream>
#include <memory>
#include <optional>

namespace rayscan::cli {

namespace {

using namespace rayscan::analysis;
using namespace rayscan::jobs;

struct CompareCli {
  std::string reference, image;
  std::vector<std::string> channels;
  bool alpha = false, json = false, mask = false, resize = false;
  std::string mask_channel = "id", mask_index, resize_filter = "lanczos3", diff;
  std::optional<double> diff_max;
  std::optional<double> fail_t, fail_pct, fail_max, fail_psnr, fail_ssim, fail_flip;
  std::optional<double> warn_t, warn_pct, warn_max, warn_psnr, warn_ssim, warn_flip;
  double ssim_range = 1.0;
  bool no_flip = false;
  std::string flip_map;
  std::optional<double> flip_ppd;
};

int run_compare(const CompareCli& o) {
  CompareJobOptions job;
  job.reference_file = o.reference;
  job.image_file = o.image;
  job.channels = o.channels;
  job.alpha = o.alpha;
  job.mask = o.mask;
  job.mask_channel = o.mask_channel;
  job.mask_index = o.mask_index;
  job.resize = o.resize;
  job.resize_filter = o.resize_filter;
  job.fail = {o.fail_t, o.fail_pct, o.fail_max, o.fail_psnr, o.fail_ssim, o.fail_flip};
  job.warn = {o.warn_t, o.warn_pct, o.warn_max, o.warn_psnr, o.warn_ssim, o.warn_flip};
  job.flip = !o.no_flip;
  if (o.no_flip && (!o.flip_map.empty() || o.fail_flip || o.warn_flip))
    throw UsageError("--no-flip: cannot be combined with --flip-map, --fail-flip or --warn-flip");
  job.flip_map = o.flip_map;
  if (o.flip_ppd) job.flip_ppd = *o.flip_ppd;
  job.ssim_range = o.ssim_range;
  job.diff = o.diff;
  job.diff_max = o.diff_max;
  const CompareJobResult r = run_compare(job);
  std::cout << (o.json ? compare_report_json(r) + "\n" : compare_report_text(r));
  std::cout.flush();
  return r.judgement.verdict == Verdict::fail ? 1 : 0;
}

}  // namespace

Runner add_compare_command(CLI::App& app) {
  auto o = std::make_shared<CompareCli>();
  // The heat maps' accepted extensions, from the list the job checks them against.
  std::string map_exts;
  for (const std::string& e : render::image_extensions()) map_exts += (map_exts.empty() ? "" : " ") + e;
  CLI::App* sub = app.add_subcommand(
      "compare",
      "Compare an image against a reference: MAE, RMSE, PSNR, max error, SSIM, mean LDR-FLIP, "
      "pixels over a threshold; idiff-style pass/fail. Exit 0 pass (or warning), 1 fail, 2 error.");
  sub->add_option("reference", o->reference, "Reference image (any format OpenImageIO reads)")->required();
  sub->add_option("image", o->image, "Image to check (e.g. a render)")->required();
  sub->add_option("--channel", o->channels,
                  "Compare these channels by name (repeat or comma-separate, e.g. --channel depth) "
                  "instead of the colour channels (R,G,B, or Y). A name the file lacks is looked "
                  "up under the renderer's EXR name: depth -> Z, index -> id")
      ->delimiter(',');
  sub->add_flag("--alpha", o->alpha, "Also compare the alpha channel");
  sub->add_flag("--mask", o->mask,
                "Ignore pixels where the reference's alpha is 0 or the image's point-index AOV "
                "channel (--mask-channel) is a miss (-1; 0xFFFFFFFF in the renderer's uint32 'id')");
  sub->add_option("--mask-channel", o->mask_channel, "Name of the point-index AOV channel ('index' also finds the renderer's 'id')")
      ->capture_default_str();
  sub->add_option("--mask-index", o->mask_index,
                  "Read the point-index AOV from this file (implies --mask)");
  sub->add_flag("--resize", o->resize, "Resample the image to the reference's size if they differ");
  sub->add_option("--resize-filter", o->resize_filter,
                  "OpenImageIO filter for --resize (lanczos3, blackman-harris, box, triangle, "
                  "gaussian, mitchell, ...)")
      ->capture_default_str();
  sub->add_option("--fail", o->fail_t, "Pixel error threshold for failure (default 1e-6)")
      ->check(non_negative());
  sub->add_option("--fail-percent", o->fail_pct, "Fail if more than this % of pixels exceed --fail (default 0)")
      ->check(finite_number(0.0, 100.0));
  sub->add_option("--fail-max", o->fail_max, "Fail if any pixel error exceeds this (idiff -hardfail; default: off)")
      ->check(non_negative());
  sub->add_option("--fail-psnr", o->fail_psnr, "Fail if PSNR is below this many dB (default: off)")
      ->check(any_finite());
  sub->add_option("--fail-ssim", o->fail_ssim, "Fail if SSIM is below this (default: off)")->check(finite_number(-1.0, 1.0));
  sub->add_option("--warn", o->warn_t,
                  "Pixel error threshold for a warning (default 1e-6; the warning level is off when fail "
                  "criteria are given and no --warn* option is)")
      ->check(non_negative());
  sub->add_option("--warn-percent", o->warn_pct, "Warn if more than this % of pixels exceed --warn (default 0)")
      ->check(finite_number(0.0, 100.0));
  sub->add_option("--warn-max", o->warn_max, "Warn if any pixel error exceeds this (default: off)")->check(non_negative());
  sub->add_option("--warn-psnr", o->warn_psnr, "Warn if PSNR is below this many dB (default: off)")
      ->check(any_finite());
  sub->add_option("--warn-ssim", o->warn_ssim, "Warn if SSIM is below this (default: off)")->check(finite_number(-1.0, 1.0));
  sub->add_option("--ssim-range", o->ssim_range,
                  "Dynamic range L of the SSIM signal (C1 = (0.01 L)^2, C2 = (0.03 L)^2)")
      ->capture_default_str()
      ->check(positive());
  sub->add_option("--diff", o->diff, "Write a heat map of the per-pixel error here (" + map_exts + ")");
  sub->add_option("--diff-max", o->diff_max, "Error mapped to white in --diff (default: the max error)")
      ->check(positive());
  sub->add_option("--fail-flip", o->fail_flip, "Fail if the mean LDR-FLIP exceeds this (default: off)")
      ->check(finite_number(0.0, 1.0));
  sub->add_option("--warn-flip", o->warn_flip, "Warn if the mean LDR-FLIP exceeds this (default: off)")
      ->check(finite_number(0.0, 1.0));
  sub->add_option("--flip-map", o->flip_map,
                  "Write the per-pixel LDR-FLIP error map (NVIDIA FLIP, Andersson et al. 2020) here as a heat "
                  "map over [0, 1] (" + map_exts + ")");
  sub->add_option("--flip-ppd", o->flip_ppd,
                  "FLIP observer's pixels per degree (default 67.02: 0.7 m from a 0.7 m wide 3840-pixel monitor)")
      ->check(positive());
  sub->add_flag("--no-flip", o->no_flip, "Skip the FLIP computation");
  sub->add_flag("--json", o->json, "Print the report as JSON instead of a table");
  return [o] {
    require_single_process("rayscan compare");
    return run_compare(*o);
  };
}

}  // namespace rayscan::cli
