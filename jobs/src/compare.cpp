// The compare job (rayscan/jobs/compare.hpp): what `rayscan compare` and
// rayscan.compare() run. Pass/fail follows OpenImageIO's idiff.
#include "rayscan/jobs/compare.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/image/color_ramp.hpp"
#include "rayscan/analysis/flip.hpp"
#include "rayscan/analysis/raster_preview.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/list_text.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/render/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace rayscan::jobs {

using namespace rayscan::analysis;  // the analysis library's types, which this job speaks in
using namespace rayscan::io;

namespace {

using std::invalid_argument;

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
    if (c != alpha_index(img) && c != index_c) out.push_back(c);
  return out;
}

std::vector<std::string> names_of(const Image& img, const std::vector<int>& idx) {
  std::vector<std::string> n;
  for (int c : idx) n.push_back(img.channels[static_cast<std::size_t>(c)]);
  return n;
}

std::vector<int> pick_channels(const Image& img, const CompareJobOptions& o) {
  std::vector<int> idx;
  if (!o.channels.empty()) {
    for (const std::string& name : o.channels) {
      // The literal name first, then the renderer's EXR name (depth -> Z, index -> id).
      const int c = find_channel(img.channels, name);
      if (c < 0) {
        const std::string_view alias = renderer_channel_alias(name);
        throw invalid_argument(img.source + ": no channel '" + name + "'" +
                               (alias != name ? " (nor its renderer name '" + std::string(alias) + "')" : "") +
                               " (channels: " + join(img.channels) + ")");
      }
      idx.push_back(c);
    }
  } else {
    idx = colour_channels(img, o.mask_channel);
    if (idx.empty())
      throw OptionError({img.source + ": no colour channels (channels: " + join(img.channels) + "); choose some with ",
                         option("channels")});
  }
  if (o.alpha) {
    const int a = alpha_index(img);
    if (a < 0)
      throw OptionError({img.source + ": ", option("alpha"),
                         " given but the image has no alpha channel (channels: " + join(img.channels) + ")"});
    idx.push_back(a);
  }
  return idx;
}

/// Whether a file's samples are scene-referred linear values (float formats) rather than
/// display-encoded sRGB: EXR and Radiance HDR.
bool stored_linear(const std::string& file) {
  const std::string ext = lower_extension(file);
  return ext == ".exr" || ext == ".hdr";
}

/// The RGB samples FLIP takes (sRGB-encoded, interleaved) from an image holding R,G,B or Y
/// (first `colour` channels of `img`, as selected); `linear` values are encoded with the sRGB
/// transfer function (IEC 61966-2-1) first.
std::vector<float> flip_input(const Image& img, int colour, bool linear) {
  std::vector<float> rgb(img.npixels() * 3);
  const auto nc = static_cast<std::size_t>(img.nchannels());
  for (std::size_t p = 0; p < img.npixels(); ++p)
    for (std::size_t k = 0; k < 3; ++k) {
      float v = img.pixels[p * nc + (colour == 3 ? k : 0)];
      if (linear) {
        const double c = std::clamp(static_cast<double>(v), 0.0, 1.0);
        v = static_cast<float>(c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055);
      }
      rgb[p * 3 + k] = v;
    }
  return rgb;
}

std::string size_of(const Image& img) { return std::to_string(img.width) + "x" + std::to_string(img.height); }

nlohmann::ordered_json json_number(double v) {
  if (std::isnan(v)) return nullptr;
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}

std::string g(double v, int prec = 9) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", prec, v);
  return buf;
}

/// What both reports say of FLIP's signal: run_compare's words (the channels FLIP ran on, or why
/// it could not run), or, where it was not asked for (run_compare leaves the signal empty only
/// then), the flag that turned it off, so that neither report shows an empty reason.
std::string flip_signal_text(const CompareMetrics& m) {
  return m.flip_signal.empty() ? "not computed (--no-flip)" : m.flip_signal;
}

/// Writes a heat map (error_heatmap's colours over [0, vmax]; masked pixels blue). An EXR holds
/// the bare map at the images' size in half floats, so that it overlays them pixel for pixel in
/// a compositor or a script; an 8-bit picture (PNG, JPEG, TIFF) is for viewing: the map at its top
/// left, its pixels unchanged, and below it the legend strip (draw_legend, shared with the raster
/// previews) with `title` (the metric and its unit), the ramp's values and, when pixels were
/// masked, the masked colour. `description` goes to the file's ImageDescription.
void write_heat_map(const Image& heat, const std::string& path, const std::string& title, double vmax, bool masked,
                    std::string description) {
  if (lower_extension(path) == ".exr") {
    write_image(heat, path, PixelFormat::half, description);
    return;
  }
  Image pic = make_image(std::max(heat.width, kLegendMinWidth), heat.height + kLegendHeight, {"R", "G", "B"}, 1.0f);
  for (int y = 0; y < heat.height; ++y)
    std::copy_n(heat.pixels.begin() + std::ptrdiff_t(y) * heat.width * 3, std::size_t(heat.width) * 3,
                pic.pixels.begin() + std::ptrdiff_t(y) * pic.width * 3);
  const LegendSwatch masked_swatch{{0.0f, 0.0f, 1.0f}, "masked"};
  draw_legend(pic, heat.height, title, std::pair{0.0, vmax},
              masked ? std::span(&masked_swatch, 1) : std::span<const LegendSwatch>());
  description += "; the map is the top left " + std::to_string(heat.width) + "x" + std::to_string(heat.height) +
                 " pixels, the legend below it";
  write_image(pic, path, PixelFormat::uint8, description);
}

}  // namespace

Limits Criteria::limits() const {
  Limits l;
  const bool any = given();
  // The idiff default (fail on any pixel differing by more than 1e-6) applies when no criterion
  // of this level is given; otherwise only the given criteria apply.
  l.pixel_test = threshold || percent || !any;
  l.threshold = threshold.value_or(1e-6);
  l.percent = percent.value_or(0.0);
  if (max_error) l.max_error = *max_error;
  if (min_psnr) l.min_psnr = *min_psnr;
  if (min_ssim) l.min_ssim = *min_ssim;
  if (max_flip) l.max_flip = *max_flip;
  return l;
}

void Criteria::require_finite(const std::string& level) const {
  for (const auto& [v, name] : {std::pair{&threshold, ""}, std::pair{&percent, "_percent"}, std::pair{&max_error, "_max"},
                                std::pair{&min_psnr, "_psnr"}, std::pair{&min_ssim, "_ssim"}, std::pair{&max_flip, "_flip"}})
    if (*v && !std::isfinite(**v))
      throw OptionError({option(level + name), std::string(": expected a finite number, got ") +
                                                   (std::isnan(**v) ? "nan" : "inf")});
}

CompareJobResult run_compare(const CompareJobOptions& o) {
  // Every front end's limits (the CLI's parser, Python's keywords).
  o.fail.require_finite("fail");
  o.warn.require_finite("warn");
  // The heat maps' paths checked before any work: an image format, a writable place, neither an
  // input (--diff ref.png would replace the reference) nor each other.
  for (const auto& [path, name] : {std::pair{&o.diff, "diff"}, std::pair{&o.flip_map, "flip_map"}})
    if (!path->empty() && !render::is_image_file_name(*path))
      throw OptionError({option(name), " '" + *path + "': " + render::image_file_name_expected()});
  {
    const std::filesystem::path outs[] = {o.diff, o.flip_map};
    const std::filesystem::path ins[] = {o.reference_file, o.image_file, o.mask_index};
    require_outputs(outs, ins);
  }
  CompareJobResult res;
  Image ref = o.reference ? *o.reference : read_image(o.reference_file);
  o.control.check_cancel();
  Image test = o.image ? *o.image : read_image(o.image_file);
  o.control.check_cancel();
  if (ref.source.empty()) ref.source = kMemorySource;  // names in messages for in-memory images
  if (test.source.empty()) test.source = kMemorySource;
  res.reference_name = o.reference ? ref.source : o.reference_file;
  res.image_name = o.image ? test.source : o.image_file;

  const std::vector<int> rc = pick_channels(ref, o), tc = pick_channels(test, o);
  if (rc.size() != tc.size())
    throw OptionError({"channel counts differ: " + res.reference_name + " has " + std::to_string(rc.size()) +
                           " (" + join(names_of(ref, rc)) + "), " + res.image_name + " has " +
                           std::to_string(tc.size()) + " (" + join(names_of(test, tc)) + "); choose channels with ",
                       option("channels")});

  // Mask: reference alpha == 0, or the render's point-index AOV says "miss".
  res.masked = o.mask || !o.mask_index.empty();
  std::vector<std::uint8_t> ignore;
  if (res.masked) {
    std::vector<std::string> mask_sources;
    ignore.assign(ref.npixels(), 0);
    if (const int a = alpha_index(ref); a >= 0) {
      for (std::size_t p = 0; p < ref.npixels(); ++p)
        if (ref.pixels[p * ref.channels.size() + static_cast<std::size_t>(a)] == 0.0f) ignore[p] = 1;
      mask_sources.push_back(res.reference_name + ":" + ref.channels[static_cast<std::size_t>(a)] + " == 0");
    }
    std::string index_file;
    if (!o.mask_index.empty()) index_file = o.mask_index;
    else if (!o.image && find_channel(test.channels, o.mask_channel) >= 0) index_file = o.image_file;
    if (!index_file.empty()) {
      int iw = 0, ih = 0;
      std::vector<std::uint8_t> miss;
      try {
        miss = read_index_misses(index_file, o.mask_channel, iw, ih);
      } catch (const std::runtime_error& e) {
        throw OptionError({option("mask_index"), std::string(": ") + e.what()});
      }
      if (iw != test.width || ih != test.height)
        throw invalid_argument(index_file + ": point-index AOV is " + std::to_string(iw) + "x" + std::to_string(ih) +
                               ", expected the image's " + size_of(test));
      // Nearest-neighbour onto the reference grid (identity when the sizes agree).
      for (int y = 0; y < ref.height; ++y) {
        const int sy = std::min(ih - 1, static_cast<int>((y + 0.5) * ih / ref.height));
        for (int x = 0; x < ref.width; ++x) {
          const int sx = std::min(iw - 1, static_cast<int>((x + 0.5) * iw / ref.width));
          if (miss[static_cast<std::size_t>(sy) * static_cast<std::size_t>(iw) + static_cast<std::size_t>(sx)])
            ignore[static_cast<std::size_t>(y) * static_cast<std::size_t>(ref.width) + static_cast<std::size_t>(x)] = 1;
        }
      }
      const int mc = index_file == o.image_file ? find_channel(test.channels, o.mask_channel) : -1;
      mask_sources.push_back(index_file + ":" +
                             (mc >= 0 ? test.channels[static_cast<std::size_t>(mc)] : o.mask_channel) + " miss (-1)");
    }
    res.mask_sources = join_alternatives(mask_sources);
    if (mask_sources.empty())
      throw OptionError({option("mask"), ": " + res.reference_name + " has no alpha channel and " + res.image_name +
                             " has no '" + o.mask_channel + "' channel (give the point-index AOV with ",
                         option("mask_index"), " FILE.exr)"});
  }

  const Image r = select_channels(ref, rc);
  Image t = select_channels(test, tc);
  if (r.width != t.width || r.height != t.height) {
    if (!o.resize)
      throw OptionError({"image sizes differ: " + res.reference_name + " is " + size_of(r) + ", " + res.image_name +
                             " is " + size_of(t) + " (use ",
                         option("resize"), " to compare at the reference's size)"});
    res.resized_from = size_of(t);
    res.resize_filter = o.resize_filter;
    try {
      t = resize_image(t, r.width, r.height, o.resize_filter);
    } catch (const std::runtime_error& e) {
      throw OptionError({option("resize_filter"), std::string(": ") + e.what()});
    }
  }
  res.image_channels = t.channels;

  const Limits fail = o.fail.limits();
  Limits warn = o.warn.limits();
  if (o.fail.given() && !o.warn.given()) warn.pixel_test = false;  // the warn level is off (Criteria)
  res.used.fail_threshold = fail.threshold;
  res.used.warn_threshold = warn.threshold;
  res.used.ssim.dynamic_range = o.ssim_range;
  res.used.cancel = o.control.cancel;
  o.control.check_cancel();
  res.metrics = compare_images(r, t, ignore, res.used);

  // The heat maps are one output: both written to temporaries, renamed together at the end, so
  // a failure at the second (or a refusal between them) leaves both old files as they were.
  OutputTransaction tx;
  // FLIP on R,G,B (or Y as grey) of the selected channels.
  if (o.flip) {
    const auto& ch = r.channels;
    const int colour = ch.size() >= 3 && ch[0] == "R" && ch[1] == "G" && ch[2] == "B" ? 3
                       : !ch.empty() && ch[0] == "Y"                               ? 1
                                                                                   : 0;
    const bool ref_linear = !o.reference && stored_linear(o.reference_file);
    const bool img_linear = !o.image && stored_linear(o.image_file);
    if (colour == 0) {
      res.metrics.flip_signal = "not computed: FLIP needs R,G,B or Y channels";
    } else {
      if (!(o.flip_ppd > 0) || !std::isfinite(o.flip_ppd))
        throw OptionError({option("flip_ppd"), ": expected a finite number > 0"});
      FlipOptions fo;
      fo.pixels_per_degree = o.flip_ppd;
      fo.cancel = o.control.cancel;
      const FlipResult fr = flip(flip_input(r, colour, ref_linear), flip_input(t, colour, img_linear), r.width,
                                 r.height, fo, ignore);
      res.metrics.flip = fr.mean;
      res.metrics.flip_signal = std::string(colour == 3 ? "R,G,B" : "Y as grey") + "; reference " +
                                (ref_linear ? "linear" : "sRGB") + ", image " + (img_linear ? "linear" : "sRGB");
      res.flip_ppd = o.flip_ppd;
      if (!o.flip_map.empty()) {
        write_heat_map(error_heatmap(fr.error, r.width, r.height, 1.0), o.flip_map, "LDR-FLIP error (0-1, unitless)",
                       1.0, res.masked,
                       "rayscan compare LDR-FLIP error map (Andersson et al. 2020): " + heat_ramp_legend(0.0, 1.0) +
                           "; masked pixels blue");
        res.flip_map = o.flip_map;
      }
    }
    if (colour == 0 && !o.flip_map.empty())
      throw OptionError({option("flip_map"), ": FLIP needs R,G,B or Y channels (compared: " + join(r.channels) + ")"});
  }
  res.judgement = judge(res.metrics, fail, warn);  // std::invalid_argument for an SSIM limit without SSIM
  res.fail_limits = fail;
  res.warn_limits = warn;

  // Heat map of the per-pixel error.
  if (!o.diff.empty()) {
    const std::vector<float> err = pixel_errors(r, t, ignore, o.control.cancel);
    double vmax = 0.0;
    if (o.diff_max) {
      vmax = *o.diff_max;
    } else {
      for (float e : err)
        if (std::isfinite(e)) vmax = std::max(vmax, static_cast<double>(e));
      if (vmax == 0.0) vmax = 1.0;  // identical images: an all-black map over [0, 1]
    }
    write_heat_map(error_heatmap(err, r.width, r.height, vmax), o.diff,
                   "Pixel error |image - reference|, max over channels (image units)", vmax, res.masked,
                   "rayscan compare error heat map: max channel |image - reference| per pixel; " +
                       heat_ramp_legend(0.0, vmax) + "; masked pixels blue");
    res.diff = o.diff;
    res.diff_max = vmax;
  }
  o.control.check_cancel();  // set after the last pass: the maps are not renamed into place either
  tx.commit();
  return res;
}

std::string compare_report_json(const CompareJobResult& res) {
  const CompareMetrics& m = res.metrics;
  const CompareOptions& copt = res.used;
  const std::string cname = m.channels[static_cast<std::size_t>(m.max_c)];
  nlohmann::ordered_json out;
  out["reference"] = res.reference_name;
  out["image"] = res.image_name;
  out["width"] = m.width;
  out["height"] = m.height;
  out["channels"] = m.channels;
  out["image_channels"] = res.image_channels;
  out["pixels_compared"] = m.pixels_compared;
  out["pixels_ignored"] = m.pixels_ignored;
  out["mask"] = res.masked ? nlohmann::ordered_json(res.mask_sources) : nlohmann::ordered_json(nullptr);
  out["resized"] = res.resized_from.empty()
                       ? nlohmann::ordered_json(nullptr)
                       : nlohmann::ordered_json{{"from", res.resized_from}, {"filter", res.resize_filter}};
  out["mae"] = json_number(m.mae);
  out["rmse"] = json_number(m.rmse);
  out["psnr_db"] = json_number(m.psnr);
  out["psnr_peak"] = json_number(m.peak);
  out["max_error"] = {{"value", json_number(m.max_error)}, {"x", m.max_x}, {"y", m.max_y},
                      {"channel", cname}, {"reference", json_number(m.max_ref)}, {"image", json_number(m.max_test)}};
  out["ssim"] = {{"value", json_number(m.ssim)}, {"signal", m.ssim_signal},
                 {"luma_weights", {kLumaR, kLumaG, kLumaB}}, {"window", copt.ssim.window},
                 {"sigma", copt.ssim.sigma}, {"k1", copt.ssim.k1}, {"k2", copt.ssim.k2},
                 {"dynamic_range", copt.ssim.dynamic_range}, {"windows", m.ssim_windows},
                 {"window_positions", m.ssim_positions},
                 {"undefined", m.ssim_undefined.empty() ? nlohmann::ordered_json(nullptr)
                                                        : nlohmann::ordered_json(m.ssim_undefined)}};
  nlohmann::ordered_json pc = nlohmann::ordered_json::array();
  for (const ChannelStats& c : m.per_channel)
    pc.push_back({{"name", c.name}, {"mae", json_number(c.mae)}, {"rmse", json_number(c.rmse)}, {"max_error", json_number(c.max_error)}});
  out["per_channel"] = pc;
  // null where the level has no pixel test, as the text report says "off": a count over a
  // threshold nothing judges would read as a cause of the verdict.
  const auto over = [](const Limits& l, double threshold, std::size_t pixels, double percent) {
    if (!l.pixel_test) return nlohmann::ordered_json(nullptr);
    return nlohmann::ordered_json{{"threshold", threshold}, {"pixels", pixels}, {"percent", percent}};
  };
  out["over_threshold"] = {
      {"fail", over(res.fail_limits, m.fail_threshold, m.over_fail, m.percent_over_fail())},
      {"warn", over(res.warn_limits, m.warn_threshold, m.over_warn, m.percent_over_warn())}};
  out["flip"] = {{"mean", json_number(m.flip)}, {"signal", flip_signal_text(m)},
                 {"pixels_per_degree", res.flip_ppd > 0 ? json_number(res.flip_ppd) : nlohmann::ordered_json(nullptr)},
                 {"map", res.flip_map.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(res.flip_map)}};
  out["nonfinite_mismatches"] = m.nonfinite_mismatches;
  if (!res.diff.empty())
    out["diff"] = {{"path", res.diff}, {"range", {0.0, res.diff_max}}, {"ramp", heat_ramp_legend(0.0, res.diff_max)},
                   {"masked_colour", "blue"}};
  out["verdict"] = to_string(res.judgement.verdict);
  out["reasons"] = res.judgement.reasons;
  return out.dump(2);
}

std::string compare_report_text(const CompareJobResult& res) {
  const CompareMetrics& m = res.metrics;
  const std::string cname = m.channels[static_cast<std::size_t>(m.max_c)];
  std::ostringstream s;
  s << "Comparing \"" << res.reference_name << "\" (reference) and \"" << res.image_name << "\"\n";
  s << "  size            " << m.width << "x" << m.height;
  if (!res.resized_from.empty())
    s << " (image resized from " << res.resized_from << ", " << res.resize_filter << " filter)";
  s << "\n  channels        " << join(m.channels);
  if (join(res.image_channels) != join(m.channels)) s << " vs " << join(res.image_channels);
  s << "\n  pixels          " << m.pixels_compared << " compared";
  if (res.masked) s << ", " << m.pixels_ignored << " masked (" << res.mask_sources << ")";
  s << "\n  MAE             " << g(m.mae) << "\n";
  s << "  RMSE            " << g(m.rmse) << "\n";
  s << "  PSNR            " << (std::isinf(m.psnr) ? std::string("inf") : g(m.psnr)) << " dB (peak " << g(m.peak)
    << ")\n";
  s << "  max error       " << g(m.max_error) << " @ (" << m.max_x << ", " << m.max_y << ", " << cname
    << ")  reference " << g(m.max_ref) << ", image " << g(m.max_test) << "\n";
  s << "  SSIM            " << (std::isnan(m.ssim) ? "n/a (" + m.ssim_undefined + ")" : g(m.ssim)) << " ("
    << m.ssim_signal << (m.ssim_signal == "luminance" ? " 0.2126 R + 0.7152 G + 0.0722 B" : "")
    << "; 11x11 Gaussian sigma 1.5, K1 0.01, K2 0.03, L " << g(res.used.ssim.dynamic_range);
  // A mean over part of the image says so: the left-out windows are not in the value.
  if (m.ssim_windows > 0 && m.ssim_windows < m.ssim_positions)
    s << "; mean of " << m.ssim_windows << " of " << m.ssim_positions
      << " windows, the others hold a masked pixel or a NaN/Inf sample";
  s << ")\n";
  // FLIP ran exactly when run_compare records its pixels per degree; otherwise the line is the
  // reason alone, the JSON's flip.signal.
  if (res.flip_ppd > 0)
    s << "  FLIP            " << (std::isnan(m.flip) ? std::string("n/a") : g(m.flip, 6)) << " (mean LDR-FLIP; "
      << m.flip_signal << "; " << g(res.flip_ppd, 6) << " pixels per degree)\n";
  else
    s << "  FLIP            " << flip_signal_text(m) << "\n";
  if (!res.flip_map.empty())
    s << "  FLIP map        " << res.flip_map << ": " << heat_ramp_legend(0.0, 1.0) << "; masked pixels blue\n";
  if (m.per_channel.size() > 1)
    for (const ChannelStats& c : m.per_channel)
      s << "  channel " << c.name << std::string(c.name.size() < 8 ? 8 - c.name.size() : 0, ' ') << "MAE "
        << g(c.mae, 6) << "  RMSE " << g(c.rmse, 6) << "  max " << g(c.max_error, 6) << "\n";
  if (m.nonfinite_mismatches) s << "  non-finite      " << m.nonfinite_mismatches << " samples NaN/Inf on one side only\n";
  // The pixels over a level's threshold only where that level has a pixel test: a count over a
  // threshold nothing judges would read as the cause of a verdict it cannot have caused.
  const auto over = [&](const Limits& l, std::size_t pixels, double percent, double threshold, const char* level) {
    if (l.pixel_test)
      s << "  " << count_text(pixels, "pixel") << " (" << g(percent, 6) << "%) over " << g(threshold, 6) << " (" << level
        << " threshold)\n";
    else
      s << "  " << level << " threshold  off (no pixel test at this level)\n";
  };
  over(res.fail_limits, m.over_fail, m.percent_over_fail(), m.fail_threshold, "fail");
  over(res.warn_limits, m.over_warn, m.percent_over_warn(), m.warn_threshold, "warn");
  if (!res.diff.empty())
    s << "  diff            " << res.diff << ": per-pixel max channel error, " << heat_ramp_legend(0.0, res.diff_max)
      << " (and above); masked pixels blue\n";
  for (const std::string& why : res.judgement.reasons) s << "  " << why << "\n";
  const Verdict v = res.judgement.verdict;
  s << (v == Verdict::pass ? "PASS" : v == Verdict::warn ? "WARNING" : "FAILURE") << "\n";
  return s.str();
}

}  // namespace rayscan::jobs
