// Per-sample random streams (pbrt-v4 chapter 8 "Sampling and Reconstruction", the independent
// sampler; hashing after pbrt-v4's Hash/MixBits). A stream is a pure function of
// (seed, pixel x, pixel y, sample index), so an image is bit-identical for any thread count and
// any tile order.
#pragma once

#include <cstdint>

namespace rayscan::render {

/// Finaliser of SplitMix64 / MurmurHash3 fmix64: a bijective 64-bit mixing function.
[[nodiscard]] constexpr std::uint64_t mix_bits(std::uint64_t v) {
  v ^= v >> 31;
  v *= 0x7fb5d329728ea185ULL;
  v ^= v >> 27;
  v *= 0x81dadef4bc2dd44dULL;
  v ^= v >> 33;
  return v;
}

/// An independent uniform random stream for one (seed, pixel, sample): SplitMix64 (Steele, Lea &
/// Flood 2014) started from a hash of the three keys. Small value type; copy freely.
class Sampler {
 public:
  /// The stream of sample `sample` of pixel (x, y) for render seed `seed`.
  Sampler(std::uint64_t seed, std::uint32_t x, std::uint32_t y, std::uint32_t sample)
      : state_(mix_bits(mix_bits(seed ^ 0x9e3779b97f4a7c15ULL) ^
                        mix_bits((std::uint64_t(y) << 32 | x) + 0x632be59bd9b4e019ULL) ^
                        mix_bits(std::uint64_t(sample) * 0xd1b54a32d192ed03ULL + 1))) {}

  /// Next 64 random bits.
  std::uint64_t next_u64() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  /// Uniform double in [0, 1) with 53 random bits.
  double uniform() { return double(next_u64() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

}  // namespace rayscan::render
