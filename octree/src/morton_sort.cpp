#include "rayscan/morton_sort.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_sort.h>

#include <array>

namespace rayscan {

void radix_sort_low_bits(MortonKey* a, std::size_t n, MortonKey* tmp, unsigned low_bits) {
  if (n < 2) return;
  const unsigned digits = std::min(8u, (low_bits + 7) / 8);
  std::array<std::array<std::size_t, 256>, 8> count{};
  for (std::size_t i = 0; i < n; ++i)
    for (unsigned d = 0; d < digits; ++d) ++count[d][(a[i].code >> (8 * d)) & 0xFF];
  MortonKey* src = a;
  MortonKey* dst = tmp;
  for (unsigned d = 0; d < digits; ++d) {
    std::array<std::size_t, 256>& c = count[d];
    if (c[(src[0].code >> (8 * d)) & 0xFF] == n) continue;  // every key has this digit
    std::size_t sum = 0;
    for (std::size_t& v : c) {
      const std::size_t k = v;
      v = sum;
      sum += k;
    }
    for (std::size_t i = 0; i < n; ++i) dst[c[(src[i].code >> (8 * d)) & 0xFF]++] = src[i];
    std::swap(src, dst);
  }
  if (src != a) std::copy(src, src + n, a);
}

namespace detail {

void sort_morton_buckets(MortonKey* keys, std::size_t n, const std::vector<std::size_t>& start, unsigned low_bits) {
  const std::size_t buckets = start.size() - 1;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, buckets, 16), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<MortonKey> tmp;
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      MortonKey* b = keys + start[k];
      const std::size_t m = start[k + 1] - start[k];
      if (m < 2) continue;
      if (m > n / 8) {
        tbb::parallel_sort(b, b + m);
      } else if (m < 64) {
        std::sort(b, b + m);
      } else {
        if (tmp.size() < m) tmp.resize(m);
        radix_sort_low_bits(b, m, tmp.data(), low_bits);
      }
    }
  });
}

}  // namespace detail
}  // namespace rayscan
