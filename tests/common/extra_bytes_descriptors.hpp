// Test helper: the Extra Bytes descriptors of a LAS file read from its own bytes (ASPRS LAS 1.4 R15
// section 2.5.6, table 24), an oracle independent of rayscan's LAS reader.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::test {

/// One Extra Bytes descriptor: its name (bytes 4-35) and description (bytes 160-191), both
/// NUL-padded in the file, and its data type (byte 2).
struct ExtraBytesDescriptor {
  std::string name, description;
  int type = 0;
};

/// The Extra Bytes descriptors of the uncompressed or LAZ file `las` in file order: the header's
/// VLR offset (byte 94) and count (byte 100), then each VLR "LASF_Spec" record 4 (54-byte VLR
/// headers, section 2.5), 192 bytes a descriptor. Empty when the file has none.
inline std::vector<ExtraBytesDescriptor> extra_bytes_descriptors_of(const std::filesystem::path& las) {
  std::ifstream in(las, std::ios::binary);
  const std::string b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto u32 = [&](std::size_t at) { std::uint32_t v = 0; std::memcpy(&v, b.data() + at, 4); return v; };
  const auto u16 = [&](std::size_t at) { std::uint16_t v = 0; std::memcpy(&v, b.data() + at, 2); return v; };
  const auto text = [&](std::size_t at, std::size_t n) {
    return std::string(b.c_str() + at, strnlen(b.c_str() + at, n));
  };
  std::vector<ExtraBytesDescriptor> out;
  std::size_t pos = u16(94);
  for (std::uint32_t i = 0, n = u32(100); i < n; ++i) {
    const std::uint16_t len = u16(pos + 20);
    if (text(pos + 2, 16) == "LASF_Spec" && u16(pos + 18) == 4)
      for (std::size_t k = 0; k + 192 <= len; k += 192) {
        const std::size_t d = pos + 54 + k;
        out.push_back({text(d + 4, 32), text(d + 160, 32), static_cast<unsigned char>(b[d + 2])});
      }
    pos += 54 + len;
  }
  return out;
}

}  // namespace rayscan::test
