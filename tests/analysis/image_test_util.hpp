// Test helpers shared by the image-comparison tests: synthetic images with fixed seeds.
#pragma once

#include "rayscan/image/image_file.hpp"

#include <random>
#include <string>
#include <vector>

namespace rayscan::analysis::test {

/// A W x H image with the given channels, every sample uniform in [lo, hi) from an mt19937(seed).
inline Image noise_image(int W, int H, std::vector<std::string> ch, unsigned seed, float lo,
                         float hi) {
  Image img = make_image(W, H, std::move(ch));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(lo, hi);
  for (float& f : img.pixels) f = d(rng);
  return img;
}

/// Sample c of pixel (x, y) (interleaved, row-major).
inline float& px(Image& img, int x, int y, int c) {
  return img.pixels[(static_cast<std::size_t>(y) * img.width + x) * img.channels.size() + c];
}

}  // namespace rayscan::analysis::test
