// The index file's checksums recomputed over forged or mutated bytes: the fuzz target for index
// files (tests/fuzz/fuzz_rsi.cpp) does this before it opens an input, so that the structural checks
// behind the CRCs are what gets fuzzed, and the replay of its findings (tests/io/test_bad_input.cpp)
// must do exactly the same to reach the same code. Needs io/src on the include path (bytes.hpp),
// as both have.
#pragma once

#include "bytes.hpp"
#include "rayscan/base/crc32c.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rayscan::test {

/// Recomputes the CRC-32C of every section that lies inside `b` and then the header's
/// (docs/index-format.md, "Header": the 4096-byte header, the section count at byte 20, the 32-byte
/// table entries from byte 128 with offset at +8, size at +16 and CRC at +24, at most 16 of them,
/// the header CRC at byte 120, computed with that field 0). A section reaching past the end of `b`
/// keeps its stored CRC; `b` shorter than the header is left as it is. Never reads outside `b`.
inline void fix_index_crcs(std::vector<std::uint8_t>& b) {
  constexpr std::size_t kHeader = 4096, kSectionCount = 20, kHeaderCrc = 120, kTable = 128, kEntry = 32,
                        kMaxSections = 16;
  using io::detail::load_le, io::detail::store_le;
  if (b.size() < kHeader) return;
  const std::uint32_t sections = load_le<std::uint32_t>(b.data() + kSectionCount);
  for (std::uint32_t i = 0; i < sections && i < kMaxSections; ++i) {
    const std::size_t e = kTable + i * kEntry;
    const auto off = load_le<std::uint64_t>(b.data() + e + 8), size = load_le<std::uint64_t>(b.data() + e + 16);
    if (off <= b.size() && size <= b.size() - off)
      store_le<std::uint32_t>(b, e + 24, io::crc32c(b.data() + off, static_cast<std::size_t>(size)));
  }
  store_le<std::uint32_t>(b, kHeaderCrc, 0);
  store_le<std::uint32_t>(b, kHeaderCrc, io::crc32c(b.data(), kHeader));
}

}  // namespace rayscan::test
