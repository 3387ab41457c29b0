// `rayscan compare REFERENCE IMAGE`: check a render against a reference image (issue 5 section 1).
// Metrics and their definitions: analysis/include/rayscan/analysis/image_compare.hpp. Pass/fail
// follows OpenImageIO's idiff (thresholds -fail/-failpercent/-hardfail/-warn/-warnpercent), with
// exit code 0 = pass (or warning), 1 = fail, 2 = error.
#include "commands.hpp"

#include "rayscan/analysis/color_ramp.hpp"
#include "rayscan/analysis/image.hpp"
#include "rayscan/analysis/image_compare.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <sstream>

namespace rayscan::cli {

namespace {

using namespace rayscan::analysis;

struct CompareCli {
  std::string reference, image;
  std::vector<std::string> channels;
  bool alpha = false, json = false, mask = false, resize = false;
  std::string mask_channel = "id", mask_index, resize_filter = "lanczos3", diff;
  std::optional<double> diff_max;
  std::optional<double> fail_t, fail_pct, fail_max, fail_psnr, fail_ssim;
  std::optional<double> warn_t, warn_pct, warn_max, warn_psnr, warn_ssim;
  double ssim_range = 1.0;
};

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i) s += ',';
    s += v[i];
  }
  return s;
}

int alpha_index(const Image& img) {
  if (img.alpha_channel >= 0) return img.alpha_channel;
  return img.channel_index("A");
}

/// The colour channels compared by default: R,G,B when all three exist, else Y (greyscale), else
/// every channel that is neither alpha nor the point-index AOV (`index_channel`, or its renderer
/// alias).
std::vector<int> colour_channels(const Image& img, const std::string& index_channel) {
  const int index_c = find_channel(img.channels, index_channel);
  const int r = img.channel_index("R"), g = img.channel_index("G"), b = img.channel_index("B");
  if (r >= 0 && g >= 0 && b >= 0) return {r, g, b};
  if (const int y = img.channel_index("Y"); y >= 0) return {y};
  std::vector<int> out;
  for (int c = 0; c < img.nchannels(); ++c)
    if (c != alpha_index(img) && c != index_c)
      out.push_back(c);
  return out;
}

std::vector<std::string> names_of(const Image& img, const std::vector<int>& idx) {
  std::vector<std::string> n;
  for (int c : idx) n.push_back(img.channels[static_cast<std::size_t>(c)]);
  return n;
}

std::vector<int> pick_channels(const Image& img, const CompareCli& o) {
  std::vector<int> idx;
  if (!o.channels.empty()) {
    for (const std::string& name : o.channels) {
      // The literal name first, then the renderer's EXR name (depth -> Z, index -> id).
      const int c = find_channel(img.channels, name);
      if (c < 0) {
        const std::string_view alias = renderer_channel_alias(name);
        throw UsageError(img.source + ": no channel '" + name + "'" +
                         (alias != name ? " (nor its renderer name '" + std::string(alias) + "')" : "") +
                         " (channels: " + join(img.channels) + ")");
      }
      idx.push_back(c);
    }
  } else {
    idx = colour_channels(img, o.mask_channel);
    if (idx.empty())
      throw UsageError(img.source + ": no colour channels (channels: " + join(img.channels) +
                       "); choose some with --channel");
  }
  if (o.alpha) {
    const int a = alpha_index(img);
    if (a < 0)
      throw UsageError(img.source + ": --alpha given but the image has no alpha channel (channels: " +
                       join(img.channels) + ")");
    idx.push_back(a);
  }
  return idx;
}

std::string size_of(const Image& img) {
  return std::to_string(img.width) + "x" + std::to_string(img.height);
}

nlohmann::ordered_json num(double v) {
  if (std::isnan(v)) return nullptr;
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}

std::string g(double v, int prec = 9) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", prec, v);
  return buf;
}

Limits make_limits(const std::optional<double>& t, const std::optional<double>& pct,
                   const std::optional<double>& max, const std::optional<double>& psnr,
                   const std::optional<double>& ssim) {
  Limits l;
  const bool any = t || pct || max || psnr || ssim;
  // The idiff default (fail on any pixel differing by more than 1e-6) applies when no criterion
  // of this level is given; otherwise only the given criteria apply.
  l.pixel_test = t || pct || !any;
  l.threshold = t.value_or(1e-6);
  l.percent = pct.value_or(0.0);
  if (max) l.max_error = *max;
  if (psnr) l.min_psnr = *psnr;
  if (ssim) l.min_ssim = *ssim;
  return l;
}

int run_compare(const CompareCli& o) {
  Image ref = read_image(o.reference);
  Image test = read_image(o.image);

  const std::vector<int> rc = pick_channels(ref, o), tc = pick_channels(test, o);
  if (rc.size() != tc.size())
    throw UsageError("channel counts differ: " + o.reference + " has " + std::to_string(rc.size()) +
                     " (" + join(names_of(ref, rc)) + "), " + o.image + " has " +
                     std::to_string(tc.size()) + " (" + join(names_of(test, tc)) +
                     "); choose channels with --channel");

  // Mask: reference alpha == 0, or the render's point-index AOV says "miss".
  const bool masking = o.mask || !o.mask_index.empty();
  std::vector<std::uint8_t> ignore;
  std::string mask_sources;
  if (masking) {
    ignore.assign(ref.npixels(), 0);
    if (const int a = alpha_index(ref); a >= 0) {
      for (std::size_t p = 0; p < ref.npixels(); ++p)
        if (ref.pixels[p * ref.channels.size() + static_cast<std::size_t>(a)] == 0.0f) ignore[p] = 1;
      mask_sources = o.reference + ":" + ref.channels[static_cast<std::size_t>(a)] + " == 0";
    }
    std::string index_file;
    if (!o.mask_index.empty()) index_file = o.mask_index;
    else if (find_channel(test.channels, o.mask_channel) >= 0) index_file = o.image;
    if (!index_file.empty()) {
      int iw = 0, ih = 0;
      std::vector<std::uint8_t> miss;
      try {
        miss = read_index_misses(index_file, o.mask_channel, iw, ih);
      } catch (const std::runtime_error& e) {
        throw UsageError(std::string("--mask-index: ") + e.what());
      }
      if (iw != test.width || ih != test.height)
        throw UsageError(index_file + ": point-index AOV is " + std::to_string(iw) + "x" +
                         std::to_string(ih) + ", expected the image's " + size_of(test));
      // Nearest-neighbour onto the reference grid (identity when the sizes agree).
      for (int y = 0; y < ref.height; ++y) {
        const int sy = std::min(ih - 1, static_cast<int>((y + 0.5) * ih / ref.height));
        for (int x = 0; x < ref.width; ++x) {
          const int sx = std::min(iw - 1, static_cast<int>((x + 0.5) * iw / ref.width));
          if (miss[static_cast<std::size_t>(sy) * static_cast<std::size_t>(iw) + static_cast<std::size_t>(sx)])
            ignore[static_cast<std::size_t>(y) * static_cast<std::size_t>(ref.width) + static_cast<std::size_t>(x)] = 1;
        }
      }
      if (!mask_sources.empty()) mask_sources += " or ";
      const int mc = index_file == o.image ? find_channel(test.channels, o.mask_channel) : -1;
      mask_sources += index_file + ":" +
                      (mc >= 0 ? test.channels[static_cast<std::size_t>(mc)] : o.mask_channel) +
                      " miss (-1)";
    }
    if (mask_sources.empty())
      throw UsageError("--mask: " + o.reference + " has no alpha channel and " + o.image +
                       " has no '" + o.mask_channel + "' channel (give the point-index AOV with "
                       "--mask-index FILE.exr)");
  }

  Image r = select_channels(ref, rc), t = select_channels(test, tc);
  std::string resized_from;
  if (r.width != t.width || r.height != t.height) {
    if (!o.resize)
      throw UsageError("image sizes differ: " + o.reference + " is " + size_of(r) + ", " + o.image +
                       " is " + size_of(t) + " (use --resize to compare at the reference's size)");
    resized_from = size_of(t);
    try {
      t = resize_image(t, r.width, r.height, o.resize_filter);
    } catch (const std::runtime_error& e) {
      throw UsageError(std::string("--resize-filter: ") + e.what());
    }
  }

  const Limits fail = make_limits(o.fail_t, o.fail_pct, o.fail_max, o.fail_psnr, o.fail_ssim);
  const Limits warn = make_limits(o.warn_t, o.warn_pct, o.warn_max, o.warn_psnr, o.warn_ssim);
  CompareOptions copt;
  copt.fail_threshold = fail.threshold;
  copt.warn_threshold = warn.threshold;
  copt.ssim.dynamic_range = o.ssim_range;
  const CompareMetrics m = compare_images(r, t, ignore, copt);
  Judgement j;
  try {
    j = judge(m, fail, warn);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }

  // Heat map of the per-pixel error.
  double vmax = 0.0;
  if (!o.diff.empty()) {
    const std::vector<float> err = pixel_errors(r, t, ignore);
    if (o.diff_max) {
      vmax = *o.diff_max;
    } else {
      for (float e : err)
        if (std::isfinite(e)) vmax = std::max(vmax, static_cast<double>(e));
      if (vmax == 0.0) vmax = 1.0;  // identical images: an all-black map over [0, 1]
    }
    const Image heat = error_heatmap(err, r.width, r.height, vmax);
    const bool is_float = o.diff.size() >= 4 && o.diff.substr(o.diff.size() - 4) == ".exr";
    write_image(heat, o.diff, is_float ? PixelFormat::half : PixelFormat::uint8,
                "rayscan compare error heat map: max channel |image - reference| per pixel; " +
                    heat_ramp_legend(0.0, vmax) + "; masked pixels blue");
  }

  const std::string cname = m.channels[static_cast<std::size_t>(m.max_c)];
  if (o.json) {
    nlohmann::ordered_json out;
    out["reference"] = o.reference;
    out["image"] = o.image;
    out["width"] = m.width;
    out["height"] = m.height;
    out["channels"] = m.channels;
    out["image_channels"] = t.channels;
    out["pixels_compared"] = m.pixels_compared;
    out["pixels_ignored"] = m.pixels_ignored;
    out["mask"] = masking ? nlohmann::ordered_json(mask_sources) : nlohmann::ordered_json(nullptr);
    out["resized"] = resized_from.empty()
                         ? nlohmann::ordered_json(nullptr)
                         : nlohmann::ordered_json{{"from", resized_from}, {"filter", o.resize_filter}};
    out["mae"] = num(m.mae);
    out["rmse"] = num(m.rmse);
    out["psnr_db"] = num(m.psnr);
    out["psnr_peak"] = num(m.peak);
    out["max_error"] = {{"value", num(m.max_error)}, {"x", m.max_x}, {"y", m.max_y},
                        {"channel", cname}, {"reference", num(m.max_ref)}, {"image", num(m.max_test)}};
    out["ssim"] = {{"value", num(m.ssim)}, {"signal", m.ssim_signal},
                   {"luma_weights", {kLumaR, kLumaG, kLumaB}}, {"window", copt.ssim.window},
                   {"sigma", copt.ssim.sigma}, {"k1", copt.ssim.k1}, {"k2", copt.ssim.k2},
                   {"dynamic_range", copt.ssim.dynamic_range}};
    nlohmann::ordered_json pc = nlohmann::ordered_json::array();
    for (const ChannelStats& c : m.per_channel)
      pc.push_back({{"name", c.name}, {"mae", num(c.mae)}, {"rmse", num(c.rmse)},
                    {"max_error", num(c.max_error)}});
    out["per_channel"] = pc;
    out["over_threshold"] = {
        {"fail", {{"threshold", m.fail_threshold}, {"pixels", m.over_fail}, {"percent", m.percent_over_fail()}}},
        {"warn", {{"threshold", m.warn_threshold}, {"pixels", m.over_warn}, {"percent", m.percent_over_warn()}}}};
    out["nonfinite_mismatches"] = m.nonfinite_mismatches;
    if (!o.diff.empty())
      out["diff"] = {{"path", o.diff}, {"range", {0.0, vmax}}, {"ramp", heat_ramp_legend(0.0, vmax)},
                     {"masked_colour", "blue"}};
    out["verdict"] = to_string(j.verdict);
    out["reasons"] = j.reasons;
    std::cout << out.dump(2) << "\n";
  } else {
    std::ostringstream s;
    s << "Comparing \"" << o.reference << "\" (reference) and \"" << o.image << "\"\n";
    s << "  size            " << m.width << "x" << m.height;
    if (!resized_from.empty()) s << " (image resized from " << resized_from << ", " << o.resize_filter << " filter)";
    s << "\n  channels        " << join(m.channels);
    if (join(t.channels) != join(m.channels)) s << " vs " << join(t.channels);
    s << "\n  pixels          " << m.pixels_compared << " compared";
    if (masking) s << ", " << m.pixels_ignored << " masked (" << mask_sources << ")";
    s << "\n  MAE             " << g(m.mae) << "\n";
    s << "  RMSE            " << g(m.rmse) << "\n";
    s << "  PSNR            " << (std::isinf(m.psnr) ? std::string("inf") : g(m.psnr)) << " dB (peak "
      << g(m.peak) << ")\n";
    s << "  max error       " << g(m.max_error) << " @ (" << m.max_x << ", " << m.max_y << ", "
      << cname << ")  reference " << g(m.max_ref) << ", image " << g(m.max_test) << "\n";
    s << "  SSIM            " << (std::isnan(m.ssim) ? std::string("n/a (image smaller than 11x11)") : g(m.ssim))
      << " (" << m.ssim_signal << (m.ssim_signal == "luminance" ? " 0.2126 R + 0.7152 G + 0.0722 B" : "")
      << "; 11x11 Gaussian sigma 1.5, K1 0.01, K2 0.03, L " << g(copt.ssim.dynamic_range) << ")\n";
    if (m.per_channel.size() > 1)
      for (const ChannelStats& c : m.per_channel)
        s << "  channel " << c.name << std::string(c.name.size() < 8 ? 8 - c.name.size() : 0, ' ')
          << "MAE " << g(c.mae, 6) << "  RMSE " << g(c.rmse, 6) << "  max " << g(c.max_error, 6) << "\n";
    if (m.nonfinite_mismatches)
      s << "  non-finite      " << m.nonfinite_mismatches << " samples NaN/Inf on one side only\n";
    s << "  " << m.over_fail << " pixels (" << g(m.percent_over_fail(), 6) << "%) over " << g(m.fail_threshold, 6)
      << " (fail threshold)\n";
    s << "  " << m.over_warn << " pixels (" << g(m.percent_over_warn(), 6) << "%) over " << g(m.warn_threshold, 6)
      << " (warn threshold)\n";
    if (!o.diff.empty())
      s << "  diff            " << o.diff << ": per-pixel max channel error, " << heat_ramp_legend(0.0, vmax)
        << " (and above); masked pixels blue\n";
    for (const std::string& why : j.reasons) s << "  " << why << "\n";
    s << (j.verdict == Verdict::pass ? "PASS" : j.verdict == Verdict::warn ? "WARNING" : "FAILURE") << "\n";
    std::cout << s.str();
  }
  std::cout.flush();
  return j.verdict == Verdict::fail ? 1 : 0;
}

}  // namespace

Runner add_compare_command(CLI::App& app) {
  auto o = std::make_shared<CompareCli>();
  CLI::App* sub = app.add_subcommand(
      "compare",
      "Compare an image against a reference: MAE, RMSE, PSNR, max error, SSIM, pixels over a "
      "threshold; idiff-style pass/fail. Exit 0 pass (or warning), 1 fail, 2 error.");
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
  sub->add_option("--fail-psnr", o->fail_psnr, "Fail if PSNR is below this many dB (default: off)");
  sub->add_option("--fail-ssim", o->fail_ssim, "Fail if SSIM is below this (default: off)")->check(finite_number(-1.0, 1.0));
  sub->add_option("--warn", o->warn_t, "Pixel error threshold for a warning (default 1e-6)")
      ->check(non_negative());
  sub->add_option("--warn-percent", o->warn_pct, "Warn if more than this % of pixels exceed --warn (default 0)")
      ->check(finite_number(0.0, 100.0));
  sub->add_option("--warn-max", o->warn_max, "Warn if any pixel error exceeds this (default: off)")->check(non_negative());
  sub->add_option("--warn-psnr", o->warn_psnr, "Warn if PSNR is below this many dB (default: off)");
  sub->add_option("--warn-ssim", o->warn_ssim, "Warn if SSIM is below this (default: off)")->check(finite_number(-1.0, 1.0));
  sub->add_option("--ssim-range", o->ssim_range,
                  "Dynamic range L of the SSIM signal (C1 = (0.01 L)^2, C2 = (0.03 L)^2)")
      ->capture_default_str()
      ->check(positive());
  sub->add_option("--diff", o->diff, "Write a heat map of the per-pixel error here (PNG, TIFF, EXR, ...)");
  sub->add_option("--diff-max", o->diff_max, "Error mapped to white in --diff (default: the max error)")
      ->check(positive());
  sub->add_flag("--json", o->json, "Print the report as JSON instead of a table");
  return [o] { return run_compare(*o); };
}

}  // namespace rayscan::cli
