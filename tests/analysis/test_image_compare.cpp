// Comparison metrics against analytic values of constructed perturbations.
#include "rayscan/image/color_ramp.hpp"
#include "rayscan/image/image_file.hpp"
#include "image_test_util.hpp"
#include "rayscan/analysis/image_compare.hpp"
#include "rayscan/analysis/raster_preview.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::analysis;

namespace {

using rayscan::analysis::test::noise_image;
using rayscan::analysis::test::px;

}  // namespace

TEST(CompareImages, IdenticalImagesHaveInfinitePsnrAndUnitSsim) {
  const Image a = noise_image(32, 24, {"R", "G", "B"}, 3, 0.0f, 1.0f);
  const CompareMetrics m = compare_images(a, a);
  EXPECT_EQ(m.rmse, 0.0);
  EXPECT_EQ(m.mae, 0.0);
  EXPECT_TRUE(std::isinf(m.psnr) && m.psnr > 0);
  EXPECT_EQ(m.ssim, 1.0);
  EXPECT_EQ(m.ssim_signal, "luminance");
  EXPECT_EQ(m.over_fail, 0u);
  EXPECT_EQ(judge(m, Limits{}, Limits{}).verdict, Verdict::pass);
}

TEST(CompareImages, KnownPerturbationGivesAnalyticErrors) {
  // Values in [0.25, 0.375) plus d = 0.125 (same binade, so exact) on k samples of one channel: every difference is exactly
  // d in float, so MAE = k d / (N C), RMSE = d sqrt(k / (N C)), PSNR = -20 log10(RMSE).
  const int W = 40, H = 30, C = 3;
  const Image a = noise_image(W, H, {"R", "G", "B"}, 5, 0.25f, 0.375f);
  Image b = a;
  const double d = 0.125;
  int k = 0;
  for (int y = 0; y < H; y += 3)
    for (int x = 0; x < W; x += 2, ++k) px(b, x, y, 1) += float(d);
  px(b, 7, 11, 2) -= 0.25f;  // the single largest error
  const double NC = double(W) * H * C;
  const double sum_abs = k * d + 0.25, sum_sq = k * d * d + 0.0625;
  CompareOptions o;
  o.fail_threshold = 0.2;
  o.warn_threshold = 0.1;
  const CompareMetrics m = compare_images(a, b, {}, o);
  EXPECT_NEAR(m.mae, sum_abs / NC, 1e-15);
  EXPECT_NEAR(m.rmse, std::sqrt(sum_sq / NC), 1e-15);
  EXPECT_NEAR(m.psnr, -20.0 * std::log10(std::sqrt(sum_sq / NC)), 1e-12);
  EXPECT_EQ(m.peak, 1.0);
  EXPECT_EQ(m.max_error, 0.25);
  EXPECT_EQ(m.max_x, 7);
  EXPECT_EQ(m.max_y, 11);
  EXPECT_EQ(m.max_c, 2);
  EXPECT_EQ(m.over_fail, 1u);
  EXPECT_EQ(m.over_warn, std::size_t(k + 1));
  EXPECT_NEAR(m.percent_over_warn(), 100.0 * (k + 1) / (W * H), 1e-12);
  ASSERT_EQ(m.per_channel.size(), 3u);
  EXPECT_EQ(m.per_channel[0].rmse, 0.0);
  EXPECT_NEAR(m.per_channel[1].mae, k * d / (W * H), 1e-15);
  EXPECT_EQ(m.per_channel[2].max_error, 0.25);
  EXPECT_LT(m.ssim, 1.0);
}

TEST(CompareImages, PsnrPeakIsLargestValueForHdr) {
  // idiff/OpenImageIO convention: peak = max(1, largest sample of either image).
  Image a = make_image(12, 12, {"R", "G", "B"}, 2.0f), b = make_image(12, 12, {"R", "G", "B"}, 2.5f);
  const CompareMetrics m = compare_images(a, b);
  EXPECT_EQ(m.peak, 2.5);
  EXPECT_NEAR(m.psnr, 20 * std::log10(2.5 / 0.5), 1e-12);
}

TEST(CompareImages, MaskExcludesPixelsFromEveryMetric) {
  const Image a = noise_image(20, 20, {"Y"}, 9, 0.0f, 1.0f);
  Image b = a;
  std::vector<std::uint8_t> ignore(400, 0);
  for (int x = 0; x < 20; ++x) {  // wreck row 4 but mask it
    px(b, x, 4, 0) += 0.5f;
    ignore[4 * 20 + x] = 1;
  }
  px(b, 3, 9, 0) += 0.25f;
  const CompareMetrics m = compare_images(a, b, ignore);
  EXPECT_EQ(m.pixels_compared, 380u);
  EXPECT_EQ(m.pixels_ignored, 20u);
  EXPECT_NEAR(m.rmse, std::sqrt(0.0625 / 380), 1e-7);
  EXPECT_NEAR(m.max_error, 0.25, 1e-6);
  EXPECT_EQ(m.max_y, 9);
  EXPECT_EQ(m.ssim_signal, "Y");
  const std::vector<float> err = pixel_errors(a, b, ignore);
  EXPECT_TRUE(std::isnan(err[4 * 20 + 5]));
  EXPECT_NEAR(err[9 * 20 + 3], 0.25f, 1e-6);
}

TEST(CompareImages, NonFiniteSamples) {
  Image a = make_image(4, 4, {"Z"}, 1.0f), b = a;
  px(a, 0, 0, 0) = px(b, 0, 0, 0) = std::nanf("");
  px(a, 1, 0, 0) = px(b, 1, 0, 0) = INFINITY;
  CompareMetrics m = compare_images(a, b);
  EXPECT_EQ(m.rmse, 0.0);
  EXPECT_EQ(m.nonfinite_mismatches, 0u);
  px(b, 2, 3, 0) = std::nanf("");
  m = compare_images(a, b);
  EXPECT_EQ(m.nonfinite_mismatches, 1u);
  EXPECT_TRUE(std::isinf(m.max_error));
  EXPECT_EQ(m.max_x, 2);
  EXPECT_EQ(m.max_y, 3);
  EXPECT_EQ(m.rmse, 0.0);  // not summed
  EXPECT_EQ(m.over_fail, 1u);
}

TEST(CompareImages, SizeOrChannelMismatchThrows) {
  const Image a = make_image(8, 8, {"R", "G", "B"}), b = make_image(8, 9, {"R", "G", "B"}),
              c = make_image(8, 8, {"Y"});
  EXPECT_THROW(compare_images(a, b), std::invalid_argument);
  EXPECT_THROW(compare_images(a, c), std::invalid_argument);
  try {
    compare_images(a, b);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("8x9"), std::string::npos) << e.what();
  }
}

TEST(Judge, IdiffStyleCriteria) {
  CompareMetrics m;
  m.pixels_compared = 1000;
  m.fail_threshold = 0.1;
  m.warn_threshold = 0.01;
  m.over_fail = 5;   // 0.5 %
  m.over_warn = 50;  // 5 %
  m.max_error = 0.3;
  m.psnr = 35;
  m.ssim = 0.95;
  Limits fail, warn;
  fail.threshold = 0.1;
  warn.threshold = 0.01;
  EXPECT_EQ(judge(m, fail, warn).verdict, Verdict::fail);  // any pixel over 0.1
  fail.percent = 1.0;
  EXPECT_EQ(judge(m, fail, warn).verdict, Verdict::warn);  // 5 % over 0.01 > 0 %
  warn.percent = 10.0;
  EXPECT_EQ(judge(m, fail, warn).verdict, Verdict::pass);
  fail.min_psnr = 40;
  EXPECT_EQ(judge(m, fail, warn).verdict, Verdict::fail);
  fail.min_psnr = 30;
  fail.max_error = 0.25;
  EXPECT_EQ(judge(m, fail, warn).verdict, Verdict::fail);
  fail.max_error = 0.5;
  warn.min_ssim = 0.96;
  const Judgement j = judge(m, fail, warn);
  EXPECT_EQ(j.verdict, Verdict::warn);
  ASSERT_EQ(j.reasons.size(), 1u);
  EXPECT_NE(j.reasons[0].find("SSIM"), std::string::npos);
  m.ssim = std::nan("");
  EXPECT_THROW(judge(m, fail, warn), std::invalid_argument);
}

TEST(HeatMap, RampStopsAndMaskColour) {
  const Rgb k = heat_ramp(0), r = heat_ramp(1.0 / 3), y = heat_ramp(2.0 / 3), w = heat_ramp(1.5);
  EXPECT_EQ(k.r + k.g + k.b, 0.0f);
  EXPECT_FLOAT_EQ(r.r, 1.0f);
  EXPECT_FLOAT_EQ(r.g, 0.0f);
  EXPECT_FLOAT_EQ(y.g, 1.0f);
  EXPECT_FLOAT_EQ(y.b, 0.0f);
  EXPECT_EQ(w.r + w.g + w.b, 3.0f);
  const std::vector<float> err{0.0f, 0.5f, 1.0f, std::nanf("")};
  const Image h = error_heatmap(err, 2, 2, 1.0);
  EXPECT_EQ(h.at(0, 0, 0), 0.0f);
  EXPECT_EQ(h.at(0, 1, 0) + h.at(0, 1, 1) + h.at(0, 1, 2), 3.0f);
  EXPECT_EQ(h.at(1, 1, 2), 1.0f);
  EXPECT_EQ(h.at(1, 1, 0), 0.0f);
  EXPECT_THROW(error_heatmap(err, 2, 2, 0.0), std::invalid_argument);
}

// The legend drawer draws into a strip it was given and nothing else: it refuses an image that
// is not R,G,B, too narrow or without the rows, and a ramp range that is not finite or reversed.
TEST(Legend, DrawsOnlyIntoItsStripAndRefusesBadInput) {
  Image img = make_image(kLegendMinWidth, 10 + kLegendHeight, {"R", "G", "B"}, 1.0f);
  const std::vector<float> before(img.pixels.begin(), img.pixels.begin() + 10 * kLegendMinWidth * 3);
  const LegendSwatch s{{0.0f, 0.0f, 1.0f}, "masked"};
  const int x = draw_legend(img, 10, "t", std::pair{0.0, 2.0}, std::span(&s, 1));
  EXPECT_EQ(x, kLegendBarX + legend_bar_width(kLegendMinWidth) + 20 + kLegendBarHeight + 12 + 8 * 6);
  EXPECT_TRUE(std::equal(before.begin(), before.end(), img.pixels.begin()));  // rows above the strip untouched
  EXPECT_THROW(draw_legend(img, 11, "t", std::nullopt, {}), std::invalid_argument);  // strip past the bottom
  Image narrow = make_image(kLegendMinWidth - 1, kLegendHeight, {"R", "G", "B"}, 1.0f);
  EXPECT_THROW(draw_legend(narrow, 0, "t", std::nullopt, {}), std::invalid_argument);
  Image grey = make_image(kLegendMinWidth, kLegendHeight, {"Y"}, 1.0f);
  EXPECT_THROW(draw_legend(grey, 0, "t", std::nullopt, {}), std::invalid_argument);
  EXPECT_THROW(draw_legend(img, 10, "t", std::pair{1.0, 0.0}, {}), std::invalid_argument);
  EXPECT_THROW(draw_legend(img, 10, "t", std::pair{0.0, std::nan("")}, {}), std::invalid_argument);
}

TEST(ImageIo, RoundTripResizeAndIndexMisses) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rayscan_analysis_io";
  std::filesystem::create_directories(dir);
  Image a = make_image(16, 8, {"R", "G", "B", "A", "index"}, 0.5f);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) px(a, x, y, 4) = (x + y) % 3 == 0 ? -1.0f : float(y * 16 + x);
  const std::string path = (dir / "rt.exr").string();
  write_image(a, path, PixelFormat::float32);
  for (const auto& de : std::filesystem::directory_iterator(dir))  // no temporary left behind
    EXPECT_EQ(de.path().filename().string().find(".tmp."), std::string::npos) << de.path();
  const Image b = read_image(path);
  ASSERT_EQ(b.channels, a.channels);
  EXPECT_EQ(b.alpha_channel, 3);
  EXPECT_EQ(b.pixels, a.pixels);
  int w = 0, h = 0;
  const std::vector<std::uint8_t> miss = read_index_misses(path, "index", w, h);
  ASSERT_EQ(w, 16);
  ASSERT_EQ(h, 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) EXPECT_EQ(miss[y * 16 + x], (x + y) % 3 == 0);
  EXPECT_THROW(read_index_misses(path, "nope", w, h), std::runtime_error);
  // A constant image stays constant under any normalised resize filter.
  const Image r = resize_image(select_channels(b, {0, 1, 2}), 7, 5, "lanczos3");
  EXPECT_EQ(r.width, 7);
  for (float v : r.pixels) EXPECT_NEAR(v, 0.5f, 1e-6);
  EXPECT_THROW(resize_image(b, 7, 5, "no-such-filter"), std::runtime_error);
  EXPECT_THROW(read_image((dir / "missing.png").string()), std::runtime_error);
  std::filesystem::remove_all(dir);
}
