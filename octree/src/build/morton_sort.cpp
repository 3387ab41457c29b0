#include "rayscan/octree/morton_sort.hpp"

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

namespace {
// Sorts a[0, m) (m < 2^32; the bits of the codes above `low_bits` equal, a in index order within
// equal codes) by one stable counting pass on the top 8 of the low bits into tmp, then each of the
// 256 sub-buckets by insertion sort (<= 16 keys, about 1 per sub-bucket on uniform data) or
// std::sort, and back into a. For the bulk build's buckets of ~150 keys an LSD pass per 8-bit
// digit (6 at 1e7 points) cost a 16 KiB count table and 6 scatters each: 10% of the build under
// perf (bench/notes/).
void msd8_sort(MortonKey* a, std::size_t m, MortonKey* tmp, unsigned low_bits) {
  const unsigned sh = low_bits > 8 ? low_bits - 8 : 0;
  std::array<std::uint32_t, 257> c{};
  for (std::size_t i = 0; i < m; ++i) ++c[((a[i].code >> sh) & 0xFF) + 1];
  for (unsigned k = 0; k < 256; ++k) c[k + 1] += c[k];
  std::array<std::uint32_t, 256> cur;
  std::copy(c.begin(), c.begin() + 256, cur.begin());
  for (std::size_t i = 0; i < m; ++i) tmp[cur[(a[i].code >> sh) & 0xFF]++] = a[i];
  for (unsigned k = 0; k < 256; ++k) {
    MortonKey* b = tmp + c[k];
    const std::size_t s = c[k + 1] - c[k];
    if (s < 2) continue;
    if (s <= 16) {
      for (std::size_t i = 1; i < s; ++i) {
        const MortonKey v = b[i];
        std::size_t j = i;
        for (; j > 0 && v < b[j - 1]; --j) b[j] = b[j - 1];
        b[j] = v;
      }
    } else {
      std::sort(b, b + s);
    }
  }
  std::copy(tmp, tmp + m, a);
}
}  // namespace

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
      } else if (m < 1024) {
        if (tmp.size() < m) tmp.resize(m);
        msd8_sort(b, m, tmp.data(), low_bits);
      } else {
        if (tmp.size() < m) tmp.resize(m);
        radix_sort_low_bits(b, m, tmp.data(), low_bits);
      }
    }
  });
}

}  // namespace detail
}  // namespace rayscan
