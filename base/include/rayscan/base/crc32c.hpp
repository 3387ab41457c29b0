// CRC-32C (Castagnoli): the checksum of the index file's header and sections (docs/index-format.md).
#pragma once

#include <cstddef>
#include <cstdint>

namespace rayscan::io {

/// CRC-32C of `n` bytes at `data` continuing from `crc` (0 to start; pass the previous result to
/// checksum a byte stream in pieces). Polynomial 0x1EDC6F41 (reflected 0x82F63B78), initial value
/// and final xor 0xFFFFFFFF, as in iSCSI (RFC 3720 section 12.1 and appendix B.4): crc32c of the
/// ASCII "123456789" is 0xE3069283. Uses the SSE4.2 `crc32` instruction when the CPU has it
/// (runtime check once; Intel SDM vol. 2A "CRC32"), else a portable slicing-by-8 table; both give
/// the same value. No alignment requirement on `data`.
[[nodiscard]] std::uint32_t crc32c(const void* data, std::size_t n, std::uint32_t crc = 0);

/// The portable table implementation of crc32c() (same result; exposed for tests).
[[nodiscard]] std::uint32_t crc32c_portable(const void* data, std::size_t n, std::uint32_t crc = 0);

/// crc32c(A || B) from crc32c(A), crc32c(B) and |B| bytes, without the bytes (zlib's
/// crc32_combine method: a GF(2) matrix for "append |B| zero bytes", applied to crc(A)). Lets
/// pieces of a stream that become final out of order be checksummed as they do. The operator of
/// the last |B| is kept per thread (runs of equal lengths cost one matrix product each).
[[nodiscard]] std::uint32_t crc32c_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::size_t len_b);

/// True when crc32c() uses the SSE4.2 instruction on this CPU.
[[nodiscard]] bool crc32c_is_hardware();

}  // namespace rayscan::io
