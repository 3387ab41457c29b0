// Sorting points by Morton code: the one sort behind every Morton-ordered layout (the octree's
// bulk build, the index file's sort runs, a COPC node's local tree). The result is the unique
// (code, index) order a comparison sort of the keys gives, computed as a parallel MSD radix pass
// on the top bits (a histogram pass, then a stable scatter) and an LSD radix sort of each bucket
// on the remaining bits (Knuth, TAOCP vol. 3, section 5.2.5: LSD radix sorting is stable pass
// by pass; the scatter keeps each bucket in index order).
#pragma once

#include "rayscan/octree/morton.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rayscan {

/// A point's Morton code (< 2^63, kMortonBits bits per axis) and its index in the input.
struct MortonKey {
  std::uint64_t code;
  std::uint32_t idx;
  /// (code, idx) order: the order every Morton-sorted layout of rayscan uses.
  friend bool operator<(const MortonKey& a, const MortonKey& b) {
    return a.code < b.code || (a.code == b.code && a.idx < b.idx);
  }
};

/// Sorts keys[0, n) by code, stably, by an LSD radix sort on the 8-bit digits of the codes' low
/// `low_bits` bits (<= 64; the bits above must be equal in all keys). One pass counts every digit;
/// a digit on which all keys agree is skipped. `tmp` holds n keys of scratch. Keys given in idx
/// order come out in (code, idx) order.
void radix_sort_low_bits(MortonKey* keys, std::size_t n, MortonKey* tmp, unsigned low_bits);

namespace detail {
/// Bits of the MSD pass of sort_morton_keys for n keys: about 256 keys per bucket on uniform
/// data, from 1 to 16 bits.
inline unsigned morton_bucket_bits(std::size_t n) {
  return static_cast<unsigned>(std::clamp<int>(static_cast<int>(std::bit_width(n)) - 8, 1, 16));
}
/// Sorts each bucket [start[b], start[b + 1]) of keys (the keys of a bucket share the code's top
/// 63 - low_bits bits) in parallel: std::sort below 64 keys, tbb::parallel_sort above n / 8 (a
/// dense cluster), one 8-bit counting pass and small sorts below 1,024 keys, radix_sort_low_bits
/// otherwise.
void sort_morton_buckets(MortonKey* keys, std::size_t n, const std::vector<std::size_t>& start, unsigned low_bits);
}  // namespace detail

/// Writes {code_of(i), i} for i in [0, n) to out[0, n), sorted by (code, i), in parallel (TBB).
/// code_of(i) must return the same code < 2^63 on every call and be safe to call concurrently:
/// it is called twice per point (histogram and scatter), so no array of codes is held. `out`
/// may be uninitialised memory of n keys.
template <class CodeOf>
void sort_morton_keys(std::size_t n, const CodeOf& code_of, MortonKey* out) {
  if (n == 0) return;
  const unsigned bits = detail::morton_bucket_bits(n), shift = 3 * kMortonBits - bits;
  const std::size_t buckets = std::size_t{1} << bits;
  const std::size_t chunks = std::clamp<std::size_t>((n + 65535) / 65536, 1, 16);
  auto chunk_begin = [&](std::size_t c) { return n * c / chunks; };
  std::vector<std::size_t> hist(chunks * buckets, 0);  // [chunk][bucket], then write cursors
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    std::size_t* h = hist.data() + c * buckets;
    for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i) ++h[code_of(i) >> shift];
  });
  std::vector<std::size_t> start(buckets + 1, 0);
  std::size_t sum = 0;
  for (std::size_t b = 0; b < buckets; ++b) {
    start[b] = sum;
    for (std::size_t c = 0; c < chunks; ++c) {
      const std::size_t v = hist[c * buckets + b];
      hist[c * buckets + b] = sum;
      sum += v;
    }
  }
  start[buckets] = sum;
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    std::size_t* cur = hist.data() + c * buckets;
    for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i) {
      const std::uint64_t code = code_of(i);
      out[cur[code >> shift]++] = MortonKey{code, static_cast<std::uint32_t>(i)};
    }
  });
  detail::sort_morton_buckets(out, n, start, shift);
}

}  // namespace rayscan
