// Morton (z-order) codes and Warren & Salmon node keys (Warren & Salmon, "A parallel hashed
// oct-tree N-body algorithm", SC 1993, section 3: "key = 1 followed by the interleaved bits").
#pragma once

#include <cstdint>

namespace rayscan {

/// Bits per axis of a Morton code: 21, so that three axes fit in 63 bits and the Warren & Salmon
/// sentinel bit fits in 64.
inline constexpr unsigned kMortonBits = 21;

/// Spread the low 21 bits of v so that bit i moves to bit 3i ("part1by2").
[[nodiscard]] constexpr std::uint64_t morton_spread(std::uint64_t v) {
  v &= 0x1FFFFF;
  v = (v | (v << 32)) & 0x1F00000000FFFFull;
  v = (v | (v << 16)) & 0x1F0000FF0000FFull;
  v = (v | (v << 8)) & 0x100F00F00F00F00Full;
  v = (v | (v << 4)) & 0x10C30C30C30C30C3ull;
  v = (v | (v << 2)) & 0x1249249249249249ull;
  return v;
}

/// Inverse of morton_spread: gather every third bit.
[[nodiscard]] constexpr std::uint64_t morton_compact(std::uint64_t v) {
  v &= 0x1249249249249249ull;
  v = (v ^ (v >> 2)) & 0x10C30C30C30C30C3ull;
  v = (v ^ (v >> 4)) & 0x100F00F00F00F00Full;
  v = (v ^ (v >> 8)) & 0x1F0000FF0000FFull;
  v = (v ^ (v >> 16)) & 0x1F00000000FFFFull;
  v = (v ^ (v >> 32)) & 0x1FFFFF;
  return v;
}

/// 3-D Morton code of integer cell coordinates (each < 2^21): bit 3i is x's bit i, 3i+1 y's,
/// 3i+2 z's. Child octant digit = (x_bit | y_bit << 1 | z_bit << 2).
[[nodiscard]] constexpr std::uint64_t morton_encode(std::uint32_t x, std::uint32_t y,
                                                    std::uint32_t z) {
  return morton_spread(x) | (morton_spread(y) << 1) | (morton_spread(z) << 2);
}

/// An octree node id: depth plus the Morton code of the node's cell at that depth, packed as in
/// Warren & Salmon: a sentinel 1 bit above 3*depth bits of Morton code. The root is 1.
class OctreeNodeId {
 public:
  /// Node at `depth` (0..21) whose cell has Morton code `morton` (< 8^depth).
  constexpr OctreeNodeId(unsigned depth, std::uint64_t morton)
      : bits_((std::uint64_t{1} << (3 * depth)) | morton) {}
  /// The root node (depth 0).
  static constexpr OctreeNodeId root() { return OctreeNodeId(0, 0); }
  /// Depth: position of the sentinel bit / 3.
  [[nodiscard]] constexpr unsigned depth() const {
    return static_cast<unsigned>((63 - __builtin_clzll(bits_)) / 3);
  }
  /// The Morton code at this node's depth (the bits below the sentinel).
  [[nodiscard]] constexpr std::uint64_t morton() const {
    return bits_ & ~(std::uint64_t{1} << (3 * depth()));
  }
  /// The child in octant o (0..7).
  [[nodiscard]] constexpr OctreeNodeId child(unsigned octant) const {
    return OctreeNodeId::from_bits((bits_ << 3) | octant);
  }
  /// The parent (root's parent is undefined).
  [[nodiscard]] constexpr OctreeNodeId parent() const { return from_bits(bits_ >> 3); }
  /// The packed 64-bit key.
  [[nodiscard]] constexpr std::uint64_t bits() const { return bits_; }
  /// Rebuild from a packed key (must have a sentinel bit).
  static constexpr OctreeNodeId from_bits(std::uint64_t b) {
    OctreeNodeId id(0, 0);
    id.bits_ = b;
    return id;
  }
  friend constexpr bool operator==(OctreeNodeId, OctreeNodeId) = default;

 private:
  std::uint64_t bits_;
};

}  // namespace rayscan
