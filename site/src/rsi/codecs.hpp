// The exact compact encodings an index build chooses during its read pass and applies while it
// writes the sorted sections: the positions (float64, float32 or the LAS int32 grid) and the
// colour (the 3-byte rgb8 section with its multiplier, or 6 bytes), and what the read pass learns
// from each block of points. docs/index-format.md, "Exactness (positions, version 3)", "Colour
// (version 4)" and "Build (external memory)" 1.
#pragma once

#include "rayscan/site/index_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

namespace rayscan::io::rsi {

/// The positions encoding a build writes: decided by the read pass (every point checked to decode
/// bit-identically), then applied by encode() to the sorted positions (docs/index-format.md,
/// "Positions").
struct PositionCodec {
  PositionEncoding enc = PositionEncoding::float64;
  Vec3 scale{1.0}, offset{0.0};
  Vec3 inv_scale{1.0};  ///< 1 / scale (grid_int)
  // Read pass state: still possible for every point seen so far.
  bool grid_ok = true, f32_ok = true;
  bool grid_set = false;

  static bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
  /// The int32 grid value of coordinate v on axis a, or false when v is not exactly one.
  bool grid_value(double v, int a, std::int32_t& out) const {
    const double k = std::nearbyint((v - offset[a]) / scale[a]);
    if (!(k >= -2147483648.0 && k <= 2147483647.0)) return false;
    out = static_cast<std::int32_t>(k);
    return same_bits(las_coordinate(out, scale[a], offset[a]), v);
  }
  /// grid_value() mostly without its division: q = (v - offset) * (1 / scale) differs from
  /// grid_value's quotient by less than 2e-6 while |q| <= 2^31 (a few ulps relative), so when q
  /// lies within 0.25 of an integer k both round to k and the round trip decides; otherwise
  /// grid_value does.
  bool grid_fast(double v, int a, std::int32_t& out) const {
    const double q = (v - offset[a]) * inv_scale[a], k = std::nearbyint(q);
    if (std::abs(q - k) <= 0.25 && k >= -2147483648.0 && k <= 2147483647.0) {
      out = static_cast<std::int32_t>(k);
      return same_bits(las_coordinate(out, scale[a], offset[a]), v);
    }
    return grid_value(v, a, out);
  }
  /// grid_value's int32 for a coordinate v known to have one (the read pass checked it).
  [[nodiscard]] std::int32_t grid_int(double v, int a) const {
    std::int32_t out = 0;
    (void)grid_fast(v, a, out);
    return out;
  }
  /// A new source: its integer grid (PointReader::integer_grid) must be the first source's.
  void source(const std::optional<std::pair<Vec3, Vec3>>& g) {
    if (!g) grid_ok = false;
    else if (!grid_set) scale = g->first, offset = g->second, inv_scale = 1.0 / scale, grid_set = true;
    else if (!(g->first == scale && g->second == offset)) grid_ok = false;
  }
  /// True when every coordinate of p is exactly an int32 value of the grid (las_int32 encodes it).
  [[nodiscard]] bool on_grid(const Vec3& p) const {
    std::int32_t k;
    return grid_fast(p[0], 0, k) && grid_fast(p[1], 1, k) && grid_fast(p[2], 2, k);
  }
  /// True when every coordinate of p is exactly a float (float32 encodes it).
  static bool is_f32(const Vec3& p) {
    for (int a = 0; a < 3; ++a) {
      const double v = p[a];  // (a double beyond the float range is not converted: UB)
      if (!(std::abs(v) <= static_cast<double>(std::numeric_limits<float>::max()) &&
            same_bits(static_cast<double>(static_cast<float>(v)), v)))
        return false;
    }
    return true;
  }
  /// Chooses the most compact exact encoding once every point was checked (float64 unless `compact`).
  void decide(bool compact) {
    enc = !compact                ? PositionEncoding::float64
          : grid_ok && grid_set ? PositionEncoding::las_int32
          : f32_ok            ? PositionEncoding::float32
                              : PositionEncoding::float64;
  }
  [[nodiscard]] std::size_t bytes() const { return position_bytes(enc); }
  /// Encodes the n float64 triples at `src` (any alignment) into out (n * bytes() bytes).
  void encode(const void* src, std::size_t n, std::uint8_t* out) const {
    if (enc == PositionEncoding::float64) {
      std::memcpy(out, src, n * sizeof(Vec3));
      return;
    }
    for (std::size_t i = 0; i < n; ++i) {
      double p[3];
      std::memcpy(p, static_cast<const std::uint8_t*>(src) + 24 * i, 24);
      if (enc == PositionEncoding::las_int32) {
        std::int32_t v[3];
        for (int a = 0; a < 3; ++a) v[a] = grid_int(p[a], a);  // checked by the read pass
        std::memcpy(out + 12 * i, v, 12);
      } else {
        const float f[3] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
        std::memcpy(out + 12 * i, f, 12);
      }
    }
  }
};

/// The colour encoding a build writes (docs/index-format.md "Colour"): the read pass checks every
/// delivered rgb value v (uint16) against v = b * m with b <= 255 for each multiplier m in
/// {1, 256, 257} (8-bit colour stored raw, in the high byte, or scaled by 257); decide() picks the
/// first that held for every value (rgb8 section, 3 bytes per point, decoded as b * m, so
/// bit-identical), else 0 (the 6-byte rgb section as read).
struct RgbCodec {
  std::uint32_t bad1 = 0, bad256 = 0, bad257 = 0;  ///< non-zero: some value is not b * m
  std::uint32_t mul = 0;                           ///< decided: 1, 256, 257, or 0 (16-bit section)
  /// The factor from the values read to the values stored: 257 when LAS tiles read as stored
  /// (ReadOptions::stored_colour) all hold 8-bit colour, which their readers would have scaled.
  std::uint16_t fix = 1;
  /// Bits of each candidate multiplier that n colours rule out (bit 0: 1, bit 1: 256, bit 2: 257).
  static std::uint32_t ruled_out(const Rgb16* c, std::size_t n) {
    std::uint32_t a = 0, h = 0, q = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (const std::uint32_t v : {std::uint32_t{c[i].r}, std::uint32_t{c[i].g}, std::uint32_t{c[i].b}}) {
        a |= v > 255u;
        h |= v & 255u;
        q |= (v % 257u) != 0u;
      }
    return (a != 0 ? 1u : 0u) | (h != 0 ? 2u : 0u) | (q != 0 ? 4u : 0u);
  }
  /// Records the multipliers ruled out (ruled_out()'s bits).
  void rule_out(std::uint32_t bits) { bad1 |= bits & 1u, bad256 |= bits & 2u, bad257 |= bits & 4u; }
  [[nodiscard]] bool undecided() const { return !(bad1 && bad256 && bad257); }
  /// Picks the multiplier (compact false: always the 16-bit section).
  void decide(bool compact) {
    mul = !compact ? 0u : !bad1 ? 1u : !bad256 ? 256u : !bad257 ? 257u : 0u;
  }
  /// The readers' colour rule (docs/formats.md) from the largest stored value of each LAS input
  /// read as stored: all zero drops the colour, <= 255 means 8-bit colour scaled by 257. When
  /// every file holds 8-bit colour the values stored are the values read x 257 (fix), which are
  /// all b x 257: multiplier 257. When every file holds 16-bit colour the values read are final.
  /// Otherwise (files differ, or one is all zero) no one rule gives the readers' values: returns
  /// false, and the build reads the files again with each reader's own rule.
  /// Files without points (`points[f] == 0`) have no colour to decide (their readers decide none).
  [[nodiscard]] bool stored_scale(const std::vector<std::uint16_t>& file_max, const std::vector<std::uint64_t>& points) {
    bool eight = true, sixteen = true;
    for (std::size_t f = 0; f < file_max.size(); ++f) {
      if (points[f] == 0) continue;
      eight = eight && file_max[f] > 0 && file_max[f] <= 255;
      sixteen = sixteen && file_max[f] > 255;
    }
    if (eight) fix = 257, bad1 = bad256 = 1, bad257 = 0;
    else if (!sixteen) return false;
    return true;
  }
  /// Encodes n colours (as read) to 3 bytes each: c x fix / mul (mul != 0; every value was
  /// checked to be b * mul). Without a division in the usual cases (a per-record `div` was 7% of
  /// the merge): fix == mul is c itself, 256 a shift, and v / 257 == (v * 0xFF01) >> 24 for
  /// every v < 2^16 (checked exhaustively).
  void encode(const Rgb16* c, std::size_t n, std::uint8_t* out) const {
    auto each = [&](auto op) {
      for (std::size_t i = 0; i < n; ++i) {
        out[3 * i] = static_cast<std::uint8_t>(op(c[i].r));
        out[3 * i + 1] = static_cast<std::uint8_t>(op(c[i].g));
        out[3 * i + 2] = static_cast<std::uint8_t>(op(c[i].b));
      }
    };
    const std::uint32_t f = fix, m = mul;
    if (f == m) each([](std::uint32_t v) { return v; });
    else if (f == 1 && m == 256) each([](std::uint32_t v) { return v >> 8; });
    else if (f == 1 && m == 257) each([](std::uint32_t v) { return (v * 0xFF01u) >> 24; });
    else each([f, m](std::uint32_t v) { return v * f / m; });
  }
  /// The 16-bit values stored for n colours as read (x fix).
  void widen(const Rgb16* c, std::size_t n, Rgb16* out) const {
    for (std::size_t i = 0; i < n; ++i)
      out[i] = Rgb16{static_cast<std::uint16_t>(c[i].r * fix), static_cast<std::uint16_t>(c[i].g * fix),
                     static_cast<std::uint16_t>(c[i].b * fix)};
  }
};

/// What the read pass learns from a block of points besides the points themselves: their bounds,
/// whether the positions encodings are still possible (PositionCodec) and the colour
/// multipliers ruled out (RgbCodec::ruled_out). Joined over the parallel blocks of a chunk.
struct BlockScan {
  AABB box;
  bool grid = true, f32 = true;
  std::uint32_t rgb_out = 0;
  std::uint16_t rgb_max = 0;  ///< the largest colour channel value (when asked)
  void join(const BlockScan& o) {
    box.expand(o.box);
    grid = grid && o.grid, f32 = f32 && o.f32;
    rgb_out |= o.rgb_out;
    rgb_max = std::max(rgb_max, o.rgb_max);
  }
};

}  // namespace rayscan::io::rsi
