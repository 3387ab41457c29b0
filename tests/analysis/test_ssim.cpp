// SSIM against the paper's formula evaluated directly (Wang et al. 2004, eq. (13)-(16) with the
// Gaussian-weighted statistics of section III-C), window by window, and against closed forms.
#include "rayscan/analysis/ssim.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

using namespace rayscan;
using namespace rayscan::analysis;

namespace {

/// Straightforward reference: for every window fully inside the image, the 11x11 Gaussian weights
/// w(i, j) = exp(-(i^2 + j^2) / (2 sigma^2)) normalised over the window (computed here in 2-D, not
/// separably), two-pass weighted mean / variance / covariance, then eq. (13). A window is skipped
/// when any of its 121 pixels is flagged in `ignore` or NaN/Inf in x or y, checked one by one.
/// `count` receives the number of windows averaged.
double reference_ssim(const std::vector<float>& x, const std::vector<float>& y, int W, int H,
                      const std::vector<std::uint8_t>& ignore = {}, int* count_out = nullptr) {
  const int r = 5;
  const double sigma = 1.5, C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
  double wsum = 0;
  std::vector<double> w(121);
  for (int j = -r; j <= r; ++j)
    for (int i = -r; i <= r; ++i) wsum += w[(j + r) * 11 + i + r] = std::exp(-(i * i + j * j) / (2 * sigma * sigma));
  for (double& v : w) v /= wsum;
  double total = 0;
  int count = 0;
  for (int cy = r; cy < H - r; ++cy)
    for (int cx = r; cx < W - r; ++cx) {
      bool usable = true;
      for (int j = -r; j <= r; ++j)
        for (int i = -r; i <= r; ++i) {
          const int p = (cy + j) * W + cx + i;
          if ((!ignore.empty() && ignore[p]) || std::isnan(x[p]) || std::isinf(x[p]) || std::isnan(y[p]) ||
              std::isinf(y[p]))
            usable = false;
        }
      if (!usable) continue;
      double mx = 0, my = 0;
      for (int j = -r; j <= r; ++j)
        for (int i = -r; i <= r; ++i) {
          mx += w[(j + r) * 11 + i + r] * x[(cy + j) * W + cx + i];
          my += w[(j + r) * 11 + i + r] * y[(cy + j) * W + cx + i];
        }
      double vx = 0, vy = 0, cxy = 0;
      for (int j = -r; j <= r; ++j)
        for (int i = -r; i <= r; ++i) {
          const double wt = w[(j + r) * 11 + i + r];
          const double dx = x[(cy + j) * W + cx + i] - mx, dy = y[(cy + j) * W + cx + i] - my;
          vx += wt * dx * dx;
          vy += wt * dy * dy;
          cxy += wt * dx * dy;
        }
      total += (2 * mx * my + C1) * (2 * cxy + C2) / ((mx * mx + my * my + C1) * (vx + vy + C2));
      ++count;
    }
  if (count_out) *count_out = count;
  return total / count;
}

std::vector<float> noise(int n, unsigned seed, float lo, float hi) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(lo, hi);
  std::vector<float> v(static_cast<std::size_t>(n));
  for (float& f : v) f = d(rng);
  return v;
}

}  // namespace

TEST(Ssim, GaussianWeightsArePaperWindow) {
  const std::vector<double> g = ssim_gaussian_weights({});
  ASSERT_EQ(g.size(), 11u);
  double s = 0;
  for (double v : g) s += v;
  EXPECT_NEAR(s, 1.0, 1e-15);
  EXPECT_NEAR(g[5] / g[6], std::exp(1.0 / (2 * 1.5 * 1.5)), 1e-12);
  SsimOptions even;
  even.window = 10;
  EXPECT_THROW(ssim_gaussian_weights(even), std::invalid_argument);
}

TEST(Ssim, IdenticalImagesGiveExactlyOne) {
  const int W = 40, H = 30;
  const std::vector<float> x = noise(W * H, 1, 0.0f, 1.0f);
  const SsimResult r = ssim(x, x, W, H);
  EXPECT_EQ(r.mssim, 1.0);
  EXPECT_EQ(r.windows, std::size_t(30 * 20));
}

TEST(Ssim, ConstantImagesMatchClosedForm) {
  // Constant a vs constant b: sigma terms vanish, SSIM = (2ab + C1) / (a^2 + b^2 + C1).
  const int W = 16, H = 12;
  const double a = 0.25, b = 0.75, C1 = 1e-4;
  const std::vector<float> x(W * H, float(a)), y(W * H, float(b));
  EXPECT_NEAR(ssim(x, y, W, H).mssim, (2 * a * b + C1) / (a * a + b * b + C1), 1e-12);
}

TEST(Ssim, MatchesDirectWindowedReference) {
  const int W = 57, H = 43;
  const std::vector<float> x = noise(W * H, 7, 0.0f, 1.0f);
  std::vector<float> y = x;
  std::mt19937 rng(8);
  std::normal_distribution<float> n(0.0f, 0.1f);
  for (float& v : y) v += n(rng);
  const double ours = ssim(x, y, W, H).mssim;
  EXPECT_NEAR(ours, reference_ssim(x, y, W, H), 1e-10);
  EXPECT_GT(ours, 0.1);
  EXPECT_LT(ours, 0.99);
  // Anti-correlated structure gives a negative SSIM.
  std::vector<float> z(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) z[i] = 1.0f - x[i];
  EXPECT_NEAR(ssim(x, z, W, H).mssim, reference_ssim(x, z, W, H), 1e-10);
  EXPECT_LT(ssim(x, z, W, H).mssim, 0.0);
}

TEST(Ssim, WindowsWithMaskedOrNonFiniteSamplesAreLeftOut) {
  const int W = 40, H = 30;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<float> x = noise(W * H, 21, 0.0f, 1.0f);
  std::vector<float> y = x;
  std::mt19937 rng(22);
  std::normal_distribution<float> n(0.0f, 0.05f);
  for (float& v : y) v += n(rng);
  // Left quarter masked; a NaN in both images at (25, 8) (NaN matches NaN), +Inf in y only at
  // (33, 22), -Inf in both at (14, 26).
  std::vector<std::uint8_t> ignore(W * H, 0);
  for (int yy = 0; yy < H; ++yy)
    for (int xx = 0; xx < 10; ++xx) ignore[yy * W + xx] = 1;
  std::vector<float> xs = x, ys = y;
  xs[8 * W + 25] = ys[8 * W + 25] = nan;
  ys[22 * W + 33] = inf;
  xs[26 * W + 14] = ys[26 * W + 14] = -inf;
  int count = 0;
  const double expected = reference_ssim(xs, ys, W, H, ignore, &count);
  ASSERT_GT(count, 100);  // the case keeps windows to average
  const SsimResult r = ssim(xs, ys, W, H, ignore);
  EXPECT_NEAR(r.mssim, expected, 1e-10);
  EXPECT_EQ(r.windows, std::size_t(count));
  EXPECT_EQ(r.positions, std::size_t(30 * 20));
  EXPECT_TRUE(r.undefined.empty()) << r.undefined;
  // The masked pixels' values do not matter: anything there (even NaN) gives the same result.
  std::vector<float> ym = ys;
  for (int yy = 0; yy < H; ++yy)
    for (int xx = 0; xx < 10; ++xx) ym[yy * W + xx] = (xx + yy) % 2 ? nan : 1000.0f;
  EXPECT_EQ(ssim(xs, ym, W, H, ignore).mssim, r.mssim);
}

TEST(Ssim, PairDifferingOnlyInMaskedHalfIsIdentical) {
  // Unmasked right half equal; the masked left half differs: SSIM is exactly 1, as MAE is 0.
  const int W = 40, H = 30;
  const std::vector<float> x = noise(W * H, 31, 0.0f, 1.0f);
  std::vector<float> y = x;
  std::vector<std::uint8_t> ignore(W * H, 0);
  for (int yy = 0; yy < H; ++yy)
    for (int xx = 0; xx < W / 2; ++xx) {
      ignore[yy * W + xx] = 1;
      y[yy * W + xx] = 1.0f - x[yy * W + xx];
    }
  const SsimResult r = ssim(x, y, W, H, ignore);
  EXPECT_EQ(r.mssim, 1.0);
  EXPECT_EQ(r.windows, std::size_t((W / 2 - 10) * (H - 10)));  // windows whose left edge is x >= 20
}

TEST(Ssim, SmallerThanWindowIsUndefined) {
  const std::vector<float> x(10 * 20, 0.5f);
  const SsimResult r = ssim(x, x, 10, 20);
  EXPECT_TRUE(std::isnan(r.mssim));
  EXPECT_EQ(r.undefined, "image 10x20 is smaller than the 11x11 SSIM window");
  EXPECT_THROW(ssim(x, x, 11, 20), std::invalid_argument);
}

TEST(Ssim, NoUsableWindowSaysWhy) {
  // 15x15: 25 window positions, each holding the centre pixel (7, 7).
  const int W = 15, H = 15, c = 7 * W + 7;
  const std::vector<float> x = noise(W * H, 41, 0.0f, 1.0f);
  std::vector<float> y = x;
  y[c] = std::numeric_limits<float>::infinity();
  SsimResult r = ssim(x, y, W, H);
  EXPECT_TRUE(std::isnan(r.mssim));
  EXPECT_EQ(r.windows, 0u);
  EXPECT_EQ(r.positions, 25u);
  EXPECT_EQ(r.undefined, "every 11x11 SSIM window holds a non-finite (NaN or Inf) sample");
  std::vector<std::uint8_t> ignore(W * H, 0);
  ignore[c] = 1;
  r = ssim(x, y, W, H, ignore);  // the Inf is masked: the mask is the cause
  EXPECT_EQ(r.undefined, "every 11x11 SSIM window holds a masked pixel");
  ignore[c] = 0;
  ignore[0] = 1;  // in the top-left window only
  r = ssim(x, y, W, H, ignore);
  EXPECT_EQ(r.undefined, "every 11x11 SSIM window holds a masked pixel or a non-finite (NaN or Inf) sample");
  // Without the Inf the other 24 windows are used.
  r = ssim(x, x, W, H, ignore);
  EXPECT_EQ(r.mssim, 1.0);
  EXPECT_EQ(r.windows, 24u);
}
