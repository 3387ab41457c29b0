// `rayscan compare` end to end: exit codes, errors, heat map, mask, and agreement with
// OpenImageIO's `idiff` (the reference tool) on the same files.
#include "rayscan/image/image_file.hpp"
#include "image_test_util.hpp"

#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"

#include "rayscan/analysis/raster_preview.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/mount.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <sys/wait.h>

using namespace rayscan;
using namespace rayscan::analysis;
namespace fs = std::filesystem;

namespace {

using RunResult = rayscan::test::CommandResult;

/// Run a shell command, capturing stdout (and stderr when `merge`).
RunResult run(const std::string& cmd, bool merge = false) {
  return rayscan::test::run_command(cmd, merge);
}

std::string q(const fs::path& p) {
  std::string s(1, '\'');
  s += p.string();
  s += '\'';
  return s;
}

RunResult compare(const fs::path& a, const fs::path& b, const std::string& opts = "", bool merge = false) {
  return run(std::string(RAYSCAN_BIN) + " compare " + q(a) + " " + q(b) + " " + opts, merge);
}

nlohmann::json compare_json(const fs::path& a, const fs::path& b, const std::string& opts = "") {
  const RunResult r = compare(a, b, "--json " + opts);
  EXPECT_TRUE(r.code == 0 || r.code == 1) << r.out;
  return nlohmann::json::parse(r.out);
}

using rayscan::analysis::test::noise_image;
using rayscan::analysis::test::px;

/// Value of "<label> = <number>" in idiff's report.
double idiff_value(const std::string& out, const std::string& label) {
  const std::regex re(label + R"(\s*=\s*([-+0-9.eEinfa]+))");
  std::smatch m;
  if (!std::regex_search(out, m, re)) {
    ADD_FAILURE() << "no '" << label << "' in idiff output:\n" << out;
    return std::nan("");
  }
  return std::stod(m[1].str());
}

/// idiff prints with std::cout's default 6 significant digits: half a unit in the 6th digit.
double printed_tolerance(double v) {
  if (v == 0.0) return 1e-12;
  return 0.5 * std::pow(10.0, std::floor(std::log10(std::fabs(v))) - 5) * (1 + 1e-9);
}

}  // namespace

// The fixture outside the anonymous namespace: its TEST_F classes have external linkage (GCC's
// -Wsubobject-linkage in a unity batch).
class CompareCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rayscan_compare_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path write(const std::string& name, const Image& img, PixelFormat f = PixelFormat::float32) {
    const fs::path p = dir_ / name;
    write_image(img, p.string(), f);
    return p;
  }
  fs::path dir_;
};

TEST_F(CompareCli, IdenticalImagesPassWithInfinitePsnr) {
  const fs::path a = write("a.png", noise_image(48, 32, {"R", "G", "B"}, 1, 0, 1), PixelFormat::uint8);
  const RunResult r = compare(a, a);
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("PASS"), std::string::npos) << r.out;
  const nlohmann::json j = compare_json(a, a);
  EXPECT_EQ(j["psnr_db"], "inf");
  EXPECT_EQ(j["rmse"].get<double>(), 0.0);
  EXPECT_EQ(j["ssim"]["value"].get<double>(), 1.0);
  EXPECT_EQ(j["verdict"], "pass");
}

TEST_F(CompareCli, ExitCodesFollowThresholds) {
  const Image a = noise_image(40, 30, {"R", "G", "B"}, 2, 0.25f, 0.375f);
  Image b = a;
  for (int x = 0; x < 40; ++x) px(b, x, 10, 0) += 0.125f;  // 40 of 1200 pixels (3.33 %) off by 0.125
  const fs::path pa = write("a.exr", a), pb = write("b.exr", b);
  EXPECT_EQ(compare(pa, pb).code, 1);                                     // idiff default: any pixel > 1e-6
  EXPECT_EQ(compare(pa, pb, "--fail 0.2").code, 0);
  EXPECT_EQ(compare(pa, pb, "--fail 0.1 --fail-percent 5").code, 0);
  EXPECT_EQ(compare(pa, pb, "--fail 0.1 --fail-percent 3").code, 1);
  EXPECT_EQ(compare(pa, pb, "--fail-max 0.1").code, 1);
  // RMSE = 0.125 sqrt(40 / 3600) exactly (values in [0.25, 0.375) + 0.125 are exact in float)
  const double psnr = -20 * std::log10(0.125 * std::sqrt(40.0 / 3600.0));
  EXPECT_EQ(compare(pa, pb, "--fail-psnr " + std::to_string(psnr - 0.01)).code, 0);
  EXPECT_EQ(compare(pa, pb, "--fail-psnr " + std::to_string(psnr + 0.01)).code, 1);
  EXPECT_EQ(compare(pa, pb, "--fail-ssim 0.999999").code, 1);
  EXPECT_EQ(compare(pa, pb, "--fail-ssim 0.5").code, 0);
  // Fail criteria without warn criteria: the verdict is theirs alone (idiff's 1e-6 pixel default
  // applies to the warn level only when no criterion at all is given).
  const RunResult ssim_only = compare(pa, pb, "--fail-ssim 0.5");
  EXPECT_NE(ssim_only.out.find("PASS"), std::string::npos) << ssim_only.out;
  EXPECT_EQ(ssim_only.out.find("WARNING"), std::string::npos) << ssim_only.out;
  const RunResult w = compare(pa, pb, "--fail 0.2 --warn 0.1");
  EXPECT_EQ(w.code, 0);
  EXPECT_NE(w.out.find("WARNING"), std::string::npos) << w.out;
  const nlohmann::json j = compare_json(pa, pb, "--fail 0.2");
  EXPECT_NEAR(j["psnr_db"].get<double>(), psnr, 1e-9);
  EXPECT_EQ(j["over_threshold"]["fail"]["pixels"].get<int>(), 0);
  EXPECT_TRUE(j["over_threshold"]["warn"].is_null()) << j.dump();  // fail criteria alone: the warn level is off
  const nlohmann::json jw = compare_json(pa, pb, "--fail 0.2 --warn 0.1");
  EXPECT_EQ(jw["over_threshold"]["warn"]["pixels"].get<int>(), 40);
  EXPECT_EQ(jw["over_threshold"]["warn"]["threshold"].get<double>(), 0.1);
  EXPECT_EQ(j["max_error"]["channel"], "R");
  EXPECT_EQ(j["max_error"]["y"].get<int>(), 10);
  // Errors: exit 2 with a one-line message naming the file.
  const RunResult missing = compare(pa, dir_ / "nope.png", "", true);
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.out.find("nope.png"), std::string::npos) << missing.out;
  EXPECT_EQ(compare(pa, pb, "--fail -1").code, 2);
  EXPECT_EQ(compare(pa, pb, "--fail-ssim 0.5 --channel nosuch").code, 2);
}

TEST_F(CompareCli, SizeMismatchIsAnErrorUnlessResized) {
  const fs::path a = write("a.exr", make_image(40, 30, {"R", "G", "B"}, 0.5f));
  const fs::path b = write("b.exr", make_image(20, 15, {"R", "G", "B"}, 0.5f));
  const RunResult r = compare(a, b, "", true);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("sizes differ"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("40x30"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("20x15"), std::string::npos) << r.out;
  // The library names the option by its field (`resize`); the command line prints its flag.
  EXPECT_NE(r.out.find("(use --resize to compare"), std::string::npos) << r.out;
  // A constant image resized is the same constant: identical within float rounding.
  const nlohmann::json j = compare_json(a, b, "--resize --fail 1e-5");
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_EQ(j["resized"]["from"], "20x15");
  EXPECT_EQ(j["resized"]["filter"], "lanczos3");
  EXPECT_EQ(j["width"].get<int>(), 40);
  // Channel counts differ: RGB against greyscale.
  const fs::path g = write("g.exr", make_image(40, 30, {"Y"}, 0.5f));
  const RunResult c = compare(a, g, "", true);
  EXPECT_EQ(c.code, 2);
  EXPECT_NE(c.out.find("channel counts differ"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("choose channels with --channel"), std::string::npos) << c.out;  // field `channels`
}

TEST_F(CompareCli, AgreesWithIdiff) {
  if (run("command -v idiff").code != 0) GTEST_SKIP() << "idiff (openimageio-tools) not installed";
  struct Case {
    std::string name, opts;
    Image a, b;
    PixelFormat fmt;
  };
  std::vector<Case> cases;
  {  // 8-bit RGB PNGs: a random image and a noisy copy
    Image a = noise_image(64, 48, {"R", "G", "B"}, 21, 0, 1), b = a;
    std::mt19937 rng(22);
    std::normal_distribution<float> n(0.0f, 0.05f);
    for (float& v : b.pixels) v = std::clamp(v + n(rng), 0.0f, 1.0f);
    cases.push_back({"png", "", a, b, PixelFormat::uint8});
  }
  {  // HDR float RGBA EXRs (values up to 2: PSNR peak above 1), alpha included as idiff does
    Image a = noise_image(37, 29, {"R", "G", "B", "A"}, 31, 0, 2), b = a;
    std::mt19937 rng(32);
    std::normal_distribution<float> n(0.0f, 0.2f);
    for (float& v : b.pixels) v += n(rng);
    cases.push_back({"exr", "--alpha", a, b, PixelFormat::float32});
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string ext = c.fmt == PixelFormat::uint8 ? ".png" : ".exr";
    const fs::path pa = write("a" + ext, c.a, c.fmt), pb = write("b" + ext, c.b, c.fmt);
    const RunResult id = run("idiff -v " + q(pa) + " " + q(pb));
    ASSERT_EQ(id.code, 2) << id.out;  // idiff: 2 = FAILURE (pixels differ)
    const nlohmann::json j = compare_json(pa, pb, c.opts);
    const double rms = idiff_value(id.out, "RMS error"), mean = idiff_value(id.out, "Mean error"),
                 psnr = idiff_value(id.out, "Peak SNR"), maxe = idiff_value(id.out, "Max error");
    EXPECT_NEAR(j["rmse"].get<double>(), rms, 1e-6) << id.out;
    EXPECT_NEAR(j["mae"].get<double>(), mean, 1e-6) << id.out;
    // idiff prints 6 significant digits, so PSNR (tens of dB) can only be checked to that.
    EXPECT_NEAR(j["psnr_db"].get<double>(), psnr, std::max(1e-6, printed_tolerance(psnr))) << id.out;
    // Tighter: PSNR recomputed from idiff's printed RMSE with our peak (max(1, largest finite
    // sample)). The printed RMSE is known to +-h (half a unit in its 6th digit), which bounds the
    // PSNR to +-20 log10(1 + h / RMSE) dB: ~1e-5 dB here, not 1e-6 (that would need >= 8
    // significant digits, and idiff 2.4 has no option to print more). See analysis/README.md.
    const double h = printed_tolerance(rms);
    const double psnr_from_rms = 20.0 * std::log10(j["psnr_peak"].get<double>() / rms);
    const double psnr_tol = 20.0 * std::log10(1.0 + h / (rms - h)) + 1e-12;
    EXPECT_LT(psnr_tol, printed_tolerance(psnr));  // really tighter than the printed PSNR
    EXPECT_NEAR(j["psnr_db"].get<double>(), psnr_from_rms, std::max(1e-6, psnr_tol)) << id.out;
    // idiff's own peak, implied by its printed PSNR and RMSE, agrees with ours to that precision.
    const double idiff_peak = rms * std::pow(10.0, psnr / 20.0);
    EXPECT_NEAR(idiff_peak, j["psnr_peak"].get<double>(),
                j["psnr_peak"].get<double>() * (h / (rms - h) + std::log(10.0) / 20.0 * printed_tolerance(psnr)) * 1.01)
        << id.out;
    EXPECT_NEAR(j["max_error"]["value"].get<double>(), maxe, std::max(1e-6, printed_tolerance(maxe)));
    std::smatch at;
    const std::string out = id.out;
    ASSERT_TRUE(std::regex_search(out, at, std::regex(R"(@ \((\d+), (\d+), (\w+)\))"))) << id.out;
    EXPECT_EQ(j["max_error"]["x"].get<int>(), std::stoi(at[1].str()));
    EXPECT_EQ(j["max_error"]["y"].get<int>(), std::stoi(at[2].str()));
    EXPECT_EQ(j["max_error"]["channel"], at[3].str());
    if (c.name == "exr") {
      EXPECT_GT(j["psnr_peak"].get<double>(), 1.0);
    }
  }
}

namespace {

/// Checks the legend strip of a heat-map picture whose map is map_w x map_h: the picture is
/// max(map_w, kLegendMinWidth) wide and kLegendHeight rows taller, white beside the map, and the
/// colour bar (raster_preview.hpp's layout) follows the heat ramp as published -- black 0, red
/// 1/3, yellow 2/3, white 1, linear in the encoded values between the stops -- column by column
/// from black to white, framed in black; a blue "masked" swatch after it only when `masked`.
void expect_legend(const Image& h, int map_w, int map_h, bool masked) {
  ASSERT_EQ(h.nchannels(), 3);
  ASSERT_EQ(h.width, std::max(map_w, kLegendMinWidth));
  ASSERT_EQ(h.height, map_h + kLegendHeight);
  for (int y = 0; y < map_h; ++y)
    for (int x = map_w; x < h.width; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(h.at(x, y, c), 1.0f) << x << "," << y;
  const int top = map_h + kLegendBarTop, bar_w = legend_bar_width(h.width);
  for (int i = 0; i < bar_w; ++i) {
    const double t = (i + 0.5) / bar_w;
    const double want[3] = {std::min(1.0, 3 * t), std::clamp(3 * t - 1, 0.0, 1.0), std::clamp(3 * t - 2, 0.0, 1.0)};
    for (int y = top; y < top + kLegendBarHeight; ++y)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(h.at(kLegendBarX + i, y, c), want[c], 0.5 / 255 + 1e-6) << i << "," << y;
  }
  EXPECT_LT(h.at(kLegendBarX, top, 0), 2.0f / 255);                // black end
  EXPECT_GT(h.at(kLegendBarX + bar_w - 1, top, 2), 253.0f / 255);  // white end
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(h.at(kLegendBarX - 1, top, c), 0.0f);     // frame, left
    EXPECT_EQ(h.at(kLegendBarX + bar_w, top, c), 0.0f);  // frame, right
    EXPECT_EQ(h.at(kLegendBarX, top - 1, c), 0.0f);     // frame, top
  }
  // The swatch's inside, after the bar and its 20-px gap (its frame included).
  const int sx = kLegendBarX + bar_w + 20 + kLegendBarHeight / 2, sy = top + kLegendBarHeight / 2;
  EXPECT_EQ(h.at(sx, sy, 0), masked ? 0.0f : 1.0f);
  EXPECT_EQ(h.at(sx, sy, 1), masked ? 0.0f : 1.0f);
  EXPECT_EQ(h.at(sx, sy, 2), 1.0f);
}

}  // namespace

TEST_F(CompareCli, DiffHeatMapAndLegend) {
  Image a = make_image(30, 20, {"R", "G", "B"}, 0.5f), b = a;
  px(b, 4, 5, 1) = 0.75f;   // max error 0.25 -> white
  px(b, 10, 3, 0) = 0.5f + 0.25f / 3.0f;  // a third of the max -> red
  const fs::path pa = write("a.exr", a), pb = write("b.exr", b), diff = dir_ / "diff.png";
  const RunResult r = compare(pa, pb, "--diff " + q(diff));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("white 0.25"), std::string::npos) << r.out;
  const Image h = read_image(diff.string());
  expect_legend(h, 30, 20, false);
  EXPECT_EQ(h.at(4, 5, 0) + h.at(4, 5, 1) + h.at(4, 5, 2), 3.0f);
  EXPECT_NEAR(h.at(10, 3, 0), 1.0f, 1.0f / 255);
  EXPECT_NEAR(h.at(10, 3, 1), 0.0f, 1.0f / 255);
  EXPECT_EQ(h.at(0, 0, 0) + h.at(0, 0, 1) + h.at(0, 0, 2), 0.0f);
  // An EXR map is the bare map at the images' size (for overlays), and the picture's map area
  // holds its pixels unchanged; a TIFF is the same picture as the PNG.
  const fs::path exr = dir_ / "diff.exr", tif = dir_ / "diff.tif";
  ASSERT_EQ(compare(pa, pb, "--diff " + q(exr)).code, 1);
  ASSERT_EQ(compare(pa, pb, "--diff " + q(tif)).code, 1);
  const Image e = read_image(exr.string()), t = read_image(tif.string());
  ASSERT_EQ(e.width, 30);
  ASSERT_EQ(e.height, 20);
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(h.at(x, y, c), e.at(x, y, c), 1.0 / 255) << x << "," << y;
  EXPECT_EQ(t.pixels, h.pixels);
  for (const auto& f : fs::directory_iterator(dir_))
    EXPECT_EQ(f.path().string().find(".tmp."), std::string::npos) << f.path();
  // An unwritable destination is an error and leaves nothing behind.
  EXPECT_EQ(compare(pa, pb, "--diff " + q(dir_ / "no_dir" / "d.png")).code, 2);
}

// The FLIP map as a picture: its legend over [0, 1], the masked swatch when pixels are masked
// (reference alpha 0), masked pixels blue in the map.
TEST_F(CompareCli, FlipMapLegendAndMaskedSwatch) {
  Image a = noise_image(500, 12, {"R", "G", "B", "A"}, 7, 0, 1), b = a;
  for (int y = 0; y < 12; ++y)
    for (int x = 0; x < 500; ++x) px(a, x, y, 3) = px(b, x, y, 3) = 1.0f;
  px(a, 3, 4, 3) = 0.0f;  // masked
  px(b, 9, 9, 0) = 1.0f - px(b, 9, 9, 0);
  const fs::path pa = write("a.png", a, PixelFormat::uint8), pb = write("b.png", b, PixelFormat::uint8);
  const fs::path f1 = dir_ / "f1.png", f2 = dir_ / "f2.png";
  ASSERT_EQ(compare(pa, pb, "--flip-map " + q(f1)).code, 1);
  ASSERT_EQ(compare(pa, pb, "--mask --flip-map " + q(f2)).code, 1);
  const Image m1 = read_image(f1.string()), m2 = read_image(f2.string());
  expect_legend(m1, 500, 12, false);
  expect_legend(m2, 500, 12, true);
  EXPECT_EQ(m2.at(3, 4, 0) + m2.at(3, 4, 1), 0.0f);
  EXPECT_EQ(m2.at(3, 4, 2), 1.0f);
}

// A heat map into a directory that takes no files (a read-only tmpfs mounted by the test as root,
// a 0555 folder otherwise): exit 2 with one line naming the output, and nothing written there.
TEST_F(CompareCli, HeatMapIntoReadOnlyDirectoryFails) {
  const fs::path pa = write("a.png", noise_image(16, 16, {"R", "G", "B"}, 1, 0, 1), PixelFormat::uint8);
  const fs::path pb = write("b.png", noise_image(16, 16, {"R", "G", "B"}, 2, 0, 1), PixelFormat::uint8);
  const fs::path ro = dir_ / "ro";
  fs::create_directories(ro);
  bool mounted = false;
  if (::geteuid() == 0) {
    mounted = ::mount("tmpfs", ro.c_str(), "tmpfs", MS_RDONLY, "size=64k") == 0;
    if (!mounted) GTEST_SKIP() << "cannot mount a read-only tmpfs as root; skipped";
  } else {
    fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
  }
  for (const char* opt : {"--diff", "--flip-map"}) {
    const fs::path out = ro / "d.tif";
    const RunResult r = compare(pa, pb, std::string(opt) + " " + q(out), true);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_EQ(r.out.rfind("rayscan compare: " + out.string() + ": ", 0), 0u) << r.out;
  }
  EXPECT_TRUE(fs::is_empty(ro));
  if (mounted) ::umount2(ro.c_str(), MNT_DETACH);
  else fs::permissions(ro, fs::perms::owner_all);
}

TEST_F(CompareCli, MaskIgnoresMissesAndTransparentReference) {
  // Render with a point-index AOV: -1 (miss) exactly where it disagrees with the reference.
  Image ref = noise_image(32, 24, {"R", "G", "B"}, 41, 0, 1);
  Image render = make_image(32, 24, {"R", "G", "B", "id"});  // the renderer's channel name
  int misses = 0;
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      const bool miss = (x * 7 + y * 3) % 5 == 0;
      misses += miss;
      for (int c = 0; c < 3; ++c) px(render, x, y, c) = miss ? 0.0f : px(ref, x, y, c);
      px(render, x, y, 3) = miss ? -1.0f : float(y * 32 + x);
    }
  const fs::path pr = write("ref.exr", ref), pi = write("render.exr", render);
  EXPECT_EQ(compare(pr, pi).code, 1);
  const nlohmann::json j = compare_json(pr, pi, "--mask");
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_EQ(j["pixels_ignored"].get<int>(), misses);
  EXPECT_EQ(j["psnr_db"], "inf");
  // The same AOV as a separate file.
  Image index_only = select_channels(render, {3});
  const fs::path pidx = write("index.exr", index_only);
  const fs::path prgb = write("render_rgb.exr", select_channels(render, {0, 1, 2}));
  EXPECT_EQ(compare_json(pr, prgb, "--mask-index " + q(pidx))["pixels_ignored"].get<int>(), misses);
  EXPECT_EQ(compare(pr, prgb, "--mask").code, 2);  // no alpha, no index channel: error
  // `--mask-channel index` finds the renderer's `id` (alias); a literal `index` channel wins.
  EXPECT_EQ(compare_json(pr, pi, "--mask --mask-channel index")["pixels_ignored"].get<int>(), misses);
  Image renamed = render;
  renamed.channels[3] = "index";
  const fs::path pn = write("render_index.exr", renamed);
  EXPECT_EQ(compare(pr, pn, "--mask").code, 2);  // default `id` is absent
  EXPECT_EQ(compare_json(pr, pn, "--mask --mask-channel index")["pixels_ignored"].get<int>(), misses);
  // Reference alpha = 0 where the render is wrong.
  Image ref_a = make_image(32, 24, {"R", "G", "B", "A"}, 1.0f);
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      for (int c = 0; c < 3; ++c) px(ref_a, x, y, c) = px(ref, x, y, c);
      if ((x * 7 + y * 3) % 5 == 0) px(ref_a, x, y, 3) = 0.0f;
    }
  const fs::path pa = write("ref_alpha.exr", ref_a);
  const nlohmann::json ja = compare_json(pa, prgb, "--mask");
  EXPECT_EQ(ja["verdict"], "pass");
  EXPECT_EQ(ja["pixels_ignored"].get<int>(), misses);
  EXPECT_EQ(ja["mask"], pa.string() + ":A == 0");
  // Both sources: a pixel either one marks is ignored, and the record names both.
  const nlohmann::json jb = compare_json(pa, pi, "--mask");
  EXPECT_EQ(jb["pixels_ignored"].get<int>(), misses);
  EXPECT_EQ(jb["mask"], pa.string() + ":A == 0 or " + pi.string() + ":id miss (-1)");
}

TEST_F(CompareCli, ChannelByName) {
  Image a = noise_image(20, 20, {"R", "G", "B", "depth"}, 51, 1, 10), b = a;
  for (int x = 0; x < 20; ++x) px(b, x, 0, 3) += 0.5f;  // 20 of 400 depth samples off by 0.5
  const fs::path pa = write("a.exr", a), pb = write("b.exr", b);
  const nlohmann::json j = compare_json(pa, pb, "--channel depth");
  ASSERT_EQ(j["channels"].size(), 1u);
  EXPECT_EQ(j["channels"][0], "depth");
  EXPECT_NEAR(j["rmse"].get<double>(), 0.5 * std::sqrt(20.0 / 400.0), 2e-6);
  EXPECT_EQ(j["ssim"]["signal"], "depth");
  EXPECT_EQ(compare_json(pa, pb)["rmse"].get<double>(), 0.0);  // colour channels untouched
}

TEST_F(CompareCli, SsimLeavesOutMaskedAndNonFiniteWindows) {
  // Windows (11x11) holding a masked pixel or a NaN/Inf sample are left out of the mean; the
  // expected counts are the window positions that do not cover the pixels concerned.
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  {  // A float TIFF pair, equal, with a NaN at the same interior pixel (25, 20) of both.
    Image a = noise_image(50, 40, {"Y"}, 61, 0, 1);
    px(a, 25, 20, 0) = nan;
    const fs::path pa = write("nan_a.tif", a), pb = write("nan_b.tif", a);
    const nlohmann::json j = compare_json(pa, pb);
    EXPECT_EQ(j["ssim"]["value"].get<double>(), 1.0) << j.dump();
    EXPECT_EQ(j["ssim"]["windows"].get<int>(), 40 * 30 - 11 * 11);
    EXPECT_EQ(j["ssim"]["window_positions"].get<int>(), 40 * 30);
    EXPECT_TRUE(j["ssim"]["undefined"].is_null()) << j.dump();
    const RunResult r = compare(pa, pb, "--fail-ssim 0.5");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("; mean of 1079 of 1200 windows, the others hold a masked pixel or a NaN/Inf sample)"),
              std::string::npos) << r.out;
  }
  {  // An RGB pair differing only in the left half, which the index AOV masks: SSIM 1, as MAE 0.
    Image ref = noise_image(40, 30, {"R", "G", "B"}, 62, 0, 1);
    Image img = ref;
    Image idx = make_image(40, 30, {"id"});
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) {
        px(idx, x, y, 0) = x < 20 ? -1.0f : float(y * 40 + x);
        if (x < 20)
          for (int c = 0; c < 3; ++c) px(img, x, y, c) = 1.0f - px(ref, x, y, c);
      }
    const fs::path pr = write("m_ref.png", ref, PixelFormat::uint8), pi = write("m_img.png", img, PixelFormat::uint8);
    const fs::path pidx = write("m_idx.exr", idx);
    const nlohmann::json j = compare_json(pr, pi, "--mask-index " + q(pidx));
    EXPECT_EQ(j["mae"].get<double>(), 0.0);
    EXPECT_EQ(j["ssim"]["value"].get<double>(), 1.0) << j.dump();
    EXPECT_EQ(j["ssim"]["windows"].get<int>(), 10 * 20);  // windows whose left column is x >= 20
  }
  {  // Too small: the reason says so, in the report, the JSON and the --fail-ssim error.
    const Image a = noise_image(8, 8, {"R", "G", "B"}, 63, 0, 1);
    const fs::path pa = write("small.exr", a);
    const RunResult r = compare(pa, pa);
    EXPECT_NE(r.out.find("SSIM            n/a (image 8x8 is smaller than the 11x11 SSIM window) ("), std::string::npos)
        << r.out;
    const nlohmann::json j = compare_json(pa, pa);
    EXPECT_TRUE(j["ssim"]["value"].is_null()) << j.dump();
    EXPECT_EQ(j["ssim"]["undefined"], "image 8x8 is smaller than the 11x11 SSIM window");
    const RunResult f = compare(pa, pa, "--fail-ssim 0.5", true);
    EXPECT_EQ(f.code, 2) << f.out;
    EXPECT_EQ(f.out, "rayscan compare: SSIM criterion given but SSIM is undefined (image 8x8 is smaller than "
                     "the 11x11 SSIM window)\n");
  }
  {  // Every window holds the +Inf depth of a miss at the centre of a 15x15 pair.
    Image a = noise_image(15, 15, {"depth"}, 64, 1, 10);
    px(a, 7, 7, 0) = inf;
    const fs::path pa = write("inf_a.exr", a), pb = write("inf_b.exr", a);
    const std::string why = "every 11x11 SSIM window holds a non-finite (NaN or Inf) sample";
    const RunResult r = compare(pa, pb, "--channel depth");
    EXPECT_EQ(r.code, 0) << r.out;  // Inf matches the same Inf
    EXPECT_NE(r.out.find("SSIM            n/a (" + why + ") ("), std::string::npos) << r.out;
    const RunResult f = compare(pa, pb, "--channel depth --fail-ssim 0.99", true);
    EXPECT_EQ(f.code, 2) << f.out;
    EXPECT_EQ(f.out, "rayscan compare: SSIM criterion given but SSIM is undefined (" + why + ")\n");
  }
}

// FLIP not computed: the report's line gives the reason, the same words as --json's flip.signal,
// with no mean (null) and no pixels per degree, whether FLIP was turned off or cannot run.
TEST_F(CompareCli, FlipNotComputedGivesItsReasonInReportAndJson) {
  const Image a = noise_image(24, 16, {"R", "G", "B"}, 71, 0, 1), b = noise_image(24, 16, {"R", "G", "B"}, 72, 0, 1);
  const fs::path pa = write("a.png", a, PixelFormat::uint8), pb = write("b.png", b, PixelFormat::uint8);
  const Image d = noise_image(24, 16, {"depth"}, 73, 1, 10);
  const fs::path pd = write("d.exr", d);
  const std::pair<std::string, std::string> cases[] = {
      {q(pa) + " " + q(pb) + " --no-flip", "not computed (--no-flip)"},
      {q(pd) + " " + q(pd), "not computed: FLIP needs R,G,B or Y channels"}};
  for (const auto& [args, reason] : cases) {
    const RunResult r = run(std::string(RAYSCAN_BIN) + " compare " + args);
    EXPECT_TRUE(r.code == 0 || r.code == 1) << r.out;
    EXPECT_NE(r.out.find("\n  FLIP            " + reason + "\n"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("LDR-FLIP"), std::string::npos) << r.out;
    const RunResult rj = run(std::string(RAYSCAN_BIN) + " compare --json " + args);
    const nlohmann::json j = nlohmann::json::parse(rj.out)["flip"];
    EXPECT_TRUE(j["mean"].is_null()) << j.dump();
    EXPECT_EQ(j["signal"], reason);
    EXPECT_TRUE(j["pixels_per_degree"].is_null()) << j.dump();
  }
}

TEST_F(CompareCli, UnsignedIndexAovMissIsAllOnes) {
  // A uint32 index channel stores a miss as 0xFFFFFFFF (the bits of int32 -1). oiiotool writes a
  // checker of 0 and 1.0, which OpenImageIO converts to 0 and 0xFFFFFFFF.
  if (run("command -v oiiotool").code != 0) GTEST_SKIP() << "oiiotool (openimageio-tools) not installed";
  const fs::path idx = dir_ / "idx.exr";
  ASSERT_EQ(run("oiiotool --pattern checker:width=1:height=1:color1=0:color2=1 6x4 1 --chnames index "
                "-d uint32 -o " + q(idx)).code, 0);
  int w = 0, h = 0;
  const std::vector<std::uint8_t> miss = read_index_misses(idx.string(), "index", w, h);
  ASSERT_EQ(w, 6);
  ASSERT_EQ(h, 4);
  // OIIO's checker starts with color1 at the origin.
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x) EXPECT_EQ(miss[y * 6 + x], (x + y) % 2 == 1) << x << "," << y;
  const fs::path a = write("a.exr", make_image(6, 4, {"R", "G", "B"}, 0.5f));
  EXPECT_EQ(compare_json(a, a, "--mask-index " + q(idx))["pixels_ignored"].get<int>(), 12);
}

// End to end on real renders: `rayscan render --aov depth --aov index` names the channels `Z` and
// `id` (renderer/src/image_output.cpp); `--channel depth`, `--channel index` and `--mask` must find
// them. Two renders of the same scene with different seeds: the AOVs describe the ray through the
// pixel centre, so they agree exactly while the 1-spp beauty differs.
TEST_F(CompareCli, RealRenderDepthAndIndexAovs) {
  {  // a 41 x 41 grid of points on z = 0 spanning [-1, 1]^2, seen obliquely: sky around it
    std::FILE* f = std::fopen((dir_ / "plane.xyz").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("x y z\n", f);
    for (int i = 0; i <= 40; ++i)
      for (int k = 0; k <= 40; ++k) std::fprintf(f, "%.3f %.3f 0\n", -1.0 + 0.05 * i, -1.0 + 0.05 * k);
    std::fclose(f);
    f = std::fopen((dir_ / "scene.json").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs(R"({"cloud": "plane.xyz", "radius": 0.04, "spp": 1, "material": {"color": [0.6, 0.5, 0.4]},
                  "camera": {"position": [0, -3, 2], "look_at": [0, 0, 0], "vfov_deg": 50,
                             "width": 48, "height": 32}})", f);
    std::fclose(f);
  }
  const std::string scene = q(dir_ / "scene.json");
  for (const char* seed : {"1", "2"}) {
    const fs::path out = dir_ / (std::string("r") + seed + ".exr");
    const RunResult r = run(std::string(RAYSCAN_BIN) + " render " + scene + " --seed " + seed +
                                " --aov depth --aov index --threads 1 --out " + q(out), true);
    ASSERT_EQ(r.code, 0) << r.out;
  }
  const fs::path a = dir_ / "r1.exr", b = dir_ / "r2.exr";
  const Image ia = read_image(a.string());
  ASSERT_EQ(ia.width, 48);
  ASSERT_EQ(ia.height, 32);
  const int z = ia.channel_index("Z");
  ASSERT_GE(z, 0) << "the renderer's depth channel is no longer named Z";
  ASSERT_GE(ia.channel_index("id"), 0) << "the renderer's index channel is no longer named id";
  ASSERT_LT(ia.channel_index("depth"), 0);
  int misses = 0;  // independent of the index AOV: the depth AOV is +inf where the ray missed
  for (int y = 0; y < ia.height; ++y)
    for (int x = 0; x < ia.width; ++x) misses += std::isinf(ia.at(x, y, z)) ? 1 : 0;
  ASSERT_GT(misses, 0);
  ASSERT_LT(misses, 48 * 32);

  // --channel depth resolves to Z: identical depth, exit 0.
  const RunResult rd = compare(a, b, "--channel depth");
  EXPECT_EQ(rd.code, 0) << rd.out;
  EXPECT_NE(rd.out.find("channels        Z"), std::string::npos) << rd.out;
  EXPECT_NE(rd.out.find("PASS"), std::string::npos) << rd.out;
  const nlohmann::json jd = compare_json(a, b, "--channel depth");
  EXPECT_EQ(jd["channels"], nlohmann::json::array({"Z"}));
  EXPECT_EQ(jd["rmse"].get<double>(), 0.0);
  EXPECT_EQ(jd["pixels_compared"].get<int>(), 48 * 32);
  EXPECT_EQ(jd["nonfinite_mismatches"].get<int>(), 0);
  // SSIM of the depth: the windows free of a miss's +inf, counted here from the file's own samples;
  // the depth is identical, so their mean is exactly 1.
  int clear_windows = 0;
  for (int oy = 0; oy + 11 <= ia.height; ++oy)
    for (int ox = 0; ox + 11 <= ia.width; ++ox) {
      bool clear = true;
      for (int y = oy; y < oy + 11; ++y)
        for (int x = ox; x < ox + 11; ++x) clear = clear && std::isfinite(ia.at(x, y, z));
      clear_windows += clear;
    }
  ASSERT_GT(clear_windows, 0);
  EXPECT_EQ(jd["ssim"]["windows"].get<int>(), clear_windows) << jd.dump();
  EXPECT_EQ(jd["ssim"]["value"].get<double>(), 1.0) << jd.dump();
  EXPECT_EQ(compare(a, b, "--channel depth --mask --fail-ssim 0.99").code, 0);
  // --channel index resolves to id.
  EXPECT_EQ(compare_json(a, b, "--channel index")["channels"], nlohmann::json::array({"id"}));

  // --mask uses the default `id` channel: exactly the pixels whose depth is inf are ignored.
  const RunResult rm = compare(a, b, "--mask --channel depth");
  EXPECT_EQ(rm.code, 0) << rm.out;
  EXPECT_NE(rm.out.find(std::to_string(misses) + " masked ("), std::string::npos) << rm.out;
  EXPECT_NE(rm.out.find(b.string() + ":id miss"), std::string::npos) << rm.out;
  const nlohmann::json jm = compare_json(a, b, "--mask");
  EXPECT_EQ(jm["pixels_ignored"].get<int>(), misses);
  EXPECT_EQ(jm["pixels_compared"].get<int>(), 48 * 32 - misses);
  EXPECT_EQ(jm["channels"], nlohmann::json::array({"R", "G", "B"}));
  EXPECT_TRUE(std::isfinite(jm["rmse"].get<double>()));
  EXPECT_GT(jm["rmse"].get<double>(), 0.0);  // 1-spp beauty with different seeds differs
  // A misspelt channel names the alias too.
  const RunResult bad = compare(a, b, "--channel dpeth", true);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.out.find("no channel 'dpeth'"), std::string::npos) << bad.out;
}

TEST_F(CompareCli, HeatMapsNeverReplaceAnInputNorEachOther) {
  // Checked before the images are read: --diff over the reference must not replace it with the
  // heat map, two maps at one path must not share one temporary file, and an unknown extension
  // must not be found after the first map is written. The reference's bytes are the oracle.
  const fs::path pa = write("a.png", noise_image(24, 16, {"R", "G", "B"}, 1, 0, 1), PixelFormat::uint8);
  const fs::path pb = write("b.png", noise_image(24, 16, {"R", "G", "B"}, 2, 0, 1), PixelFormat::uint8);
  const auto bytes = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  const std::string before = bytes(pa);
  RunResult r = compare(pa, pb, "--no-flip --diff " + q(pa), true);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan compare: " + pa.string() + ": is the same file as the input '" + pa.string() +
                       "' (write the output to another path)\n");
  EXPECT_EQ(bytes(pa), before);
  const fs::path d = dir_ / "d.png";
  r = compare(pa, pb, "--diff " + q(d) + " --flip-map " + q(dir_ / "." / "d.png"), true);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("is also the command's output"), std::string::npos) << r.out;
  r = compare(pa, pb, "--flip-map " + q(d) + " --diff " + q(dir_ / "d.xyz"), true);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan compare: --diff '" + (dir_ / "d.xyz").string() +
                       "': expected a file name ending in .png, .jpg, .jpeg, .tif, .tiff or .exr\n");
  EXPECT_FALSE(fs::exists(d));
  r = compare(pa, pb, "--fail-psnr nan", true);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan compare: --fail-psnr: expected a finite number, got 'nan' (see --help)\n");
}

// The two maps are one output: written to temporaries and renamed together, so a failure after
// the FLIP map (written first) leaves both old files and no temporary. A file-size limit
// (RLIMIT_FSIZE, SIGXFSZ ignored, so the write fails with EFBIG) between the two files' sizes
// fails the heat map's write; an SSIM limit on images too small for SSIM fails the verdict, which
// comes between the maps. Oracle: the sizes of the same comparison without a limit (the FLIP map
// of a faint noise is a nearly black PNG; the heat map spreads it over the whole ramp in half
// floats), the old files' own bytes and the folder's listing.
TEST_F(CompareCli, HeatMapsAreWrittenAllOrNothing) {
  const fs::path pa = write("a.exr", make_image(128, 128, {"R", "G", "B"}, 0.5f));
  const fs::path pb = write("b.exr", noise_image(128, 128, {"R", "G", "B"}, 3, 0.49f, 0.51f));
  const auto maps = [&](const std::string& limit, const fs::path& folder) {
    return run("(trap '' XFSZ; " + limit + q(RAYSCAN_BIN) + " compare " + q(pa) + " " + q(pb) + " --flip-map " +
                   q(folder / "f.png") + " --diff " + q(folder / "d.exr") + " 2>&1 >/dev/null)");
  };
  const fs::path free = dir_ / "free", capped = dir_ / "capped";
  fs::create_directories(free);
  ASSERT_EQ(maps("", free).code, 1);  // the images differ: FAILURE (the report goes to /dev/null)
  const std::uintmax_t flip_size = fs::file_size(free / "f.png"), diff_size = fs::file_size(free / "d.exr");
  ASSERT_LT(2 * flip_size, diff_size);
  fs::create_directories(capped);
  const auto bytes = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  std::ofstream(capped / "f.png") << "old flip map";
  std::ofstream(capped / "d.exr") << "old heat map";
  const RunResult r = maps("prlimit --fsize=" + std::to_string((flip_size + diff_size) / 2) + " ", capped);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("rayscan compare: " + (capped / "d.exr").string() + ": ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("File too large"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  const std::set<std::string> old_files{"d.exr", "f.png"};
  EXPECT_EQ(rayscan::test::entry_names(capped), old_files);
  EXPECT_TRUE(bytes(capped / "f.png") == "old flip map") << fs::file_size(capped / "f.png") << " bytes";
  EXPECT_TRUE(bytes(capped / "d.exr") == "old heat map") << fs::file_size(capped / "d.exr") << " bytes";

  // 8 x 8 pixels: no 11 x 11 SSIM window fits, so an SSIM limit cannot be judged.
  const fs::path sa = write("sa.exr", make_image(8, 8, {"R", "G", "B"}, 0.5f));
  const fs::path sb = write("sb.exr", noise_image(8, 8, {"R", "G", "B"}, 3, 0.4f, 0.6f));
  const RunResult s = compare(sa, sb, "--fail-ssim 0.9 --flip-map " + q(capped / "f.png") + " --diff " +
                                          q(capped / "d.exr"), true);
  EXPECT_EQ(s.code, 2) << s.out;
  EXPECT_NE(s.out.find("SSIM"), std::string::npos) << s.out;
  EXPECT_EQ(rayscan::test::entry_names(capped), old_files);
  EXPECT_TRUE(bytes(capped / "f.png") == "old flip map") << fs::file_size(capped / "f.png") << " bytes";
  EXPECT_TRUE(bytes(capped / "d.exr") == "old heat map") << fs::file_size(capped / "d.exr") << " bytes";
}
