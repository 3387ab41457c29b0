// RgbView: per-point 16-bit colours read either in place (an array of Rgb16) or decoded from
// 8-bit channels times a multiplier (the index file's 3-byte rgb8 section, docs/index-format.md
// "Colour").
#pragma once

#include "rayscan/octree/point_cloud.hpp"

#include <cstddef>
#include <cstdint>
#include <span>

namespace rayscan {

/// The colours of N points by slot, read only through `operator[](slot)` (an Rgb16 by value),
/// `size()` and `empty()`. Either a span of Rgb16 (16 bits per channel as the readers deliver
/// them; implicitly constructible, so in-memory clouds pass their `rgb` vector) or N x 3 bytes
/// (r, g, b) with a multiplier m in {1, 256, 257}: channel value = byte * m, which is exact for
/// colours that were stored so (the index build checks every value; `IndexBuildStats`). Does not
/// own the data (the span or the bytes must outlive the view); cheap to copy.
class RgbView {
 public:
  /// No colour (size 0).
  constexpr RgbView() = default;
  /// 16-bit colours in place.
  constexpr RgbView(std::span<const Rgb16> wide) : wide_(wide.data()), size_(wide.size()) {}  // NOLINT(implicit)
  /// `n` 3-byte colours at `narrow` (r, g, b per point), decoded as byte * `multiplier`
  /// (1, 256 or 257; not checked here: the index file's open() validates it).
  constexpr RgbView(const std::uint8_t* narrow, std::size_t n, std::uint32_t multiplier)
      : narrow_(narrow), size_(n), mul_(multiplier) {}
  /// The colour of slot `slot` (< size(); unchecked), bit-identical to what was stored.
  [[nodiscard]] constexpr Rgb16 operator[](std::size_t slot) const {
    if (narrow_ == nullptr) return wide_[slot];
    const std::uint8_t* p = narrow_ + 3 * slot;
    return {static_cast<std::uint16_t>(p[0] * mul_), static_cast<std::uint16_t>(p[1] * mul_),
            static_cast<std::uint16_t>(p[2] * mul_)};
  }
  /// Number of colours.
  [[nodiscard]] constexpr std::size_t size() const { return size_; }
  /// True when there is no colour.
  [[nodiscard]] constexpr bool empty() const { return size_ == 0; }
  /// The multiplier of the 3-byte form (1, 256 or 257), 0 for 16-bit colours in place.
  [[nodiscard]] constexpr std::uint32_t multiplier() const { return narrow_ ? mul_ : 0u; }
  /// Bytes per colour as stored: 3 (8-bit form) or 6 (Rgb16); 0 when empty.
  [[nodiscard]] constexpr std::size_t bytes_per_point() const { return size_ == 0 ? 0 : narrow_ ? 3 : 6; }

 private:
  const Rgb16* wide_ = nullptr;
  const std::uint8_t* narrow_ = nullptr;
  std::size_t size_ = 0;
  std::uint32_t mul_ = 0;
};

}  // namespace rayscan
