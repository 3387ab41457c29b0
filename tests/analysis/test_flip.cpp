// LDR-FLIP (rayscan/analysis/flip.hpp). No reference implementation of FLIP is packaged for Debian
// 12 (nor reachable offline), so the oracles are:
//  - uniform colour pairs: CSF filtering leaves a constant image unchanged and the feature
//    detectors answer 0, so FLIP is the paper's colour mapping (eq. 4-5) of the HyAB distance of
//    the Hunt-adjusted CIELAB colours. Those are taken here from published CIELAB values of the
//    sRGB primaries (D65; e.g. B. Lindbloom's calculator / EasyRGB tables), not from our code;
//  - a hand-computed feature case: a vertical black-to-grey step, where the edge detector, whose
//    negative weights sum to -1, answers exactly the luminance jump next to the step;
//  - properties the paper states: 0 for identical images, in [0, 1], symmetric, growing with noise.
#include "rayscan/analysis/flip.hpp"
#include "rayscan/jobs/compare.hpp"

#include "image_test_util.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

using namespace rayscan;
using namespace rayscan::analysis;
using namespace rayscan::jobs;

namespace {

using Lab = std::array<double, 3>;
// Published CIELAB (D65, 2 degree observer) of sRGB colours.
constexpr Lab kBlackLab{0.0, 0.0, 0.0}, kWhiteLab{100.0, 0.0, 0.0};
constexpr Lab kRedLab{53.2408, 80.0925, 67.2032}, kGreenLab{87.7347, -86.1827, 83.1793},
    kBlueLab{32.3026, 79.1967, -107.8637};

/// Paper eq. 4-5 from CIELAB values: Hunt adjustment, HyAB, ^0.7, knee mapping.
double colour_flip(const Lab& p, const Lab& q) {
  const auto hunt = [](const Lab& c) { return Lab{c[0], 0.01 * c[0] * c[1], 0.01 * c[0] * c[2]}; };
  const auto hyab = [](const Lab& a, const Lab& b) { return std::abs(a[0] - b[0]) + std::hypot(a[1] - b[1], a[2] - b[2]); };
  const double cmax = std::pow(hyab(hunt(kGreenLab), hunt(kBlueLab)), 0.7);
  const double d = std::pow(hyab(hunt(p), hunt(q)), 0.7);
  const double pc = 0.4, pt = 0.95;
  return d < pc * cmax ? pt / (pc * cmax) * d : pt + (d - pc * cmax) / (cmax - pc * cmax) * (1 - pt);
}

std::vector<float> uniform(int w, int h, float r, float g, float b) {
  std::vector<float> v(static_cast<std::size_t>(w * h) * 3);
  for (std::size_t i = 0; i < v.size(); i += 3) {
    v[i] = r;
    v[i + 1] = g;
    v[i + 2] = b;
  }
  return v;
}

}  // namespace

TEST(Flip, PixelsPerDegreeOfThePapersViewer) {
  // 0.7 m from a 0.7 m wide 4K monitor: 3840 pixels span 2 atan(0.5) = 53.13 degrees, and ppd is
  // the paper's small-angle form d (r / w) pi / 180.
  EXPECT_NEAR(flip_pixels_per_degree(), 67.0206, 1e-4);
  EXPECT_NEAR(flip_pixels_per_degree(), FlipOptions{}.pixels_per_degree, 1e-9);
  EXPECT_THROW(flip_pixels_per_degree(0.0), std::invalid_argument);
}

TEST(Flip, MaxColourDifferenceMatchesPublishedLab) {
  const auto hunt = [](const Lab& c) { return Lab{c[0], 0.01 * c[0] * c[1], 0.01 * c[0] * c[2]}; };
  const Lab g = hunt(kGreenLab), b = hunt(kBlueLab);
  const double expected = std::pow(std::abs(g[0] - b[0]) + std::hypot(g[1] - b[1], g[2] - b[2]), 0.7);
  EXPECT_NEAR(flip_max_colour_difference(), expected, 1e-3 * expected);
}

TEST(Flip, UniformColourPairsFollowTheColourMapping) {
  const int w = 24, h = 16;
  struct Case {
    std::array<float, 3> a, b;
    Lab la, lb;
  };
  const Case cases[] = {{{0, 0, 0}, {1, 1, 1}, kBlackLab, kWhiteLab},
                        {{1, 0, 0}, {0, 1, 0}, kRedLab, kGreenLab},
                        {{0, 1, 0}, {0, 0, 1}, kGreenLab, kBlueLab},
                        {{1, 1, 1}, {0, 0, 1}, kWhiteLab, kBlueLab},
                        {{0, 0, 0}, {1, 0, 0}, kBlackLab, kRedLab}};
  for (const Case& c : cases) {
    const FlipResult r = flip(uniform(w, h, c.a[0], c.a[1], c.a[2]), uniform(w, h, c.b[0], c.b[1], c.b[2]), w, h);
    const double expected = colour_flip(c.la, c.lb);
    EXPECT_NEAR(r.mean, expected, 2e-4) << c.a[0] << c.a[1] << c.a[2] << " vs " << c.b[0] << c.b[1] << c.b[2];
    for (std::size_t i = 0; i < r.error.size(); ++i) ASSERT_NEAR(r.error[i], expected, 2e-4);
    for (float f : r.feature_error) ASSERT_LT(f, 2e-3);  // constant images: no features
  }
  // Green vs blue is the normaliser: exactly 1 by construction of eq. 5.
  EXPECT_NEAR(colour_flip(kGreenLab, kBlueLab), 1.0, 1e-12);
  // Black vs white: 100^0.7 = 25.1 lies above the knee 0.4 c_max, just under 1.
  EXPECT_GT(colour_flip(kBlackLab, kWhiteLab), 0.95);
  EXPECT_LT(colour_flip(kBlackLab, kWhiteLab), 1.0);
}

TEST(Flip, EdgeDetectorAnswersTheLuminanceJumpAtAStep) {
  // Reference: black | white step; test: black | grey of linear luminance 0.5. Next to the step
  // the edge response is the jump (the detector's weights on one side sum to -1), the point
  // response is smaller, so the feature error there is (0.5 / sqrt 2)^0.5.
  const int w = 64, h = 8, step = 32;
  const float grey = static_cast<float>(1.055 * std::pow(0.5, 1.0 / 2.4) - 0.055);  // sRGB of linear 0.5
  std::vector<float> ref = uniform(w, h, 0, 0, 0), test = uniform(w, h, 0, 0, 0);
  for (int y = 0; y < h; ++y)
    for (int x = step; x < w; ++x)
      for (int k = 0; k < 3; ++k) {
        ref[static_cast<std::size_t>((y * w + x) * 3 + k)] = 1.0f;
        test[static_cast<std::size_t>((y * w + x) * 3 + k)] = grey;
      }
  const FlipResult r = flip(ref, test, w, h);
  const double expected = std::sqrt(0.5 / std::sqrt(2.0));
  for (int y = 0; y < h; ++y) {
    EXPECT_NEAR(r.feature_error[static_cast<std::size_t>(y * w + step)], expected, 2e-4);
    EXPECT_NEAR(r.feature_error[static_cast<std::size_t>(y * w + step - 1)], expected, 2e-4);
  }
  // Far from the step (beyond both filters' reach) the dark sides agree exactly and the bright
  // sides differ only in colour.
  EXPECT_EQ(r.error[4], 0.0f);
  EXPECT_LT(r.feature_error[static_cast<std::size_t>(w - 2)], 1e-3);
  // FLIP combines the pipelines as colour ^ (1 - feature): a feature difference raises the error.
  const std::size_t at = static_cast<std::size_t>(step);
  EXPECT_NEAR(r.error[at], std::pow(r.colour_error[at], 1.0 - r.feature_error[at]), 1e-6);
  EXPECT_GT(r.error[at], r.colour_error[at]);
}

TEST(Flip, IdenticalImagesScoreZeroAndTheMetricIsSymmetricAndBounded) {
  const Image a = rayscan::analysis::test::noise_image(40, 30, {"R", "G", "B"}, 7, 0, 1);
  const Image b = rayscan::analysis::test::noise_image(40, 30, {"R", "G", "B"}, 8, 0, 1);
  const FlipResult same = flip(a.pixels, a.pixels, 40, 30);
  EXPECT_EQ(same.mean, 0.0);
  for (float e : same.error) ASSERT_EQ(e, 0.0f);
  const FlipResult ab = flip(a.pixels, b.pixels, 40, 30), ba = flip(b.pixels, a.pixels, 40, 30);
  EXPECT_NEAR(ab.mean, ba.mean, 1e-6);
  EXPECT_GT(ab.mean, 0.1);
  for (float e : ab.error) {
    ASSERT_GE(e, 0.0f);
    ASSERT_LE(e, 1.0f);
  }
}

TEST(Flip, GrowsWithNoise) {
  // A smooth gradient image plus the same Gaussian noise pattern at growing amplitudes.
  const int w = 64, h = 48;
  std::vector<float> ref(static_cast<std::size_t>(w * h) * 3), noise(ref.size());
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < 3; ++k) {
        const std::size_t i = static_cast<std::size_t>((y * w + x) * 3 + k);
        ref[i] = 0.2f + 0.6f * static_cast<float>(x + k * y) / static_cast<float>(w + 2 * h);
        noise[i] = n(rng);
      }
  double previous = 0.0;
  for (float sigma : {0.01f, 0.03f, 0.1f, 0.3f}) {
    std::vector<float> test(ref.size());
    for (std::size_t i = 0; i < ref.size(); ++i) test[i] = std::clamp(ref[i] + sigma * noise[i], 0.0f, 1.0f);
    const double m = flip(ref, test, w, h).mean;
    EXPECT_GT(m, previous) << "sigma " << sigma;
    previous = m;
  }
}

TEST(Flip, MaskedPixelsLeaveTheMeanAndBadInputThrows) {
  const int w = 20, h = 10;
  std::vector<float> a = uniform(w, h, 0.5f, 0.5f, 0.5f), b = a;
  std::vector<std::uint8_t> ignore(static_cast<std::size_t>(w * h), 0);
  for (int x = 0; x < w; ++x) ignore[static_cast<std::size_t>(x)] = 1;  // top row
  const FlipResult r = flip(a, b, w, h, {}, ignore);
  EXPECT_EQ(r.pixels, static_cast<std::size_t>(w * (h - 1)));
  EXPECT_TRUE(std::isnan(r.error[0]));
  EXPECT_THROW(flip(a, std::vector<float>(3), w, h), std::invalid_argument);
  EXPECT_THROW(flip(a, b, 0, h), std::invalid_argument);
  FlipOptions bad;
  bad.pixels_per_degree = 0;
  EXPECT_THROW(flip(a, b, w, h, bad), std::invalid_argument);
}

TEST(Flip, CompareJobReportsMeanFlipAndJudgesIt) {
  const Image a = rayscan::analysis::test::noise_image(32, 24, {"R", "G", "B"}, 1, 0, 1);
  Image b = a;
  for (float& f : b.pixels) f = 1.0f - f;
  CompareJobOptions o;
  o.reference = &a;
  o.image = &b;
  o.fail.max_flip = 0.05;
  const CompareJobResult r = run_compare(o);
  EXPECT_NEAR(r.metrics.flip, flip(a.pixels, b.pixels, 32, 24).mean, 1e-12);
  EXPECT_EQ(r.judgement.verdict, Verdict::fail);
  o.image = &a;
  EXPECT_EQ(run_compare(o).metrics.flip, 0.0);
  // A depth channel has no FLIP; a FLIP criterion on it is a user error.
  const Image z = rayscan::analysis::test::noise_image(8, 8, {"Z"}, 1, 0, 1);
  o.reference = &z;
  o.image = &z;
  EXPECT_THROW(run_compare(o), std::invalid_argument);
}
