// CRC-32C: SSE4.2 instruction with runtime dispatch, portable slicing-by-8 fallback.
// Reference: RFC 3720 (iSCSI) section 12.1 / appendix B.4 for the polynomial and check value;
// Intel SDM vol. 2A "CRC32 - Accumulate CRC32 Value" for the instruction (it computes exactly the
// reflected CRC-32C update without the initial/final inversion); slicing-by-8 after Kounavis &
// Berry, "A Systematic Approach to Building High Performance Software-Based CRC Generators" (2005).
#include "rayscan/base/crc32c.hpp"

#include <array>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <nmmintrin.h>
#define RAYSCAN_CRC32C_X86 1
#endif

namespace rayscan::io {

namespace {

constexpr std::uint32_t kPoly = 0x82F63B78u;  // reflected 0x1EDC6F41

using Tables = std::array<std::array<std::uint32_t, 256>, 8>;

constexpr Tables make_tables() {
  Tables t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? (c >> 1) ^ kPoly : c >> 1;
    t[0][i] = c;
  }
  for (std::size_t s = 1; s < 8; ++s)
    for (std::uint32_t i = 0; i < 256; ++i) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFFu];
  return t;
}
constexpr Tables kTables = make_tables();

std::uint32_t update_portable(std::uint32_t c, const unsigned char* p, std::size_t n) {
  while (n >= 8) {
    std::uint32_t lo, hi;  // little-endian words (the format is little-endian; static_assert below)
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    lo ^= c;
    c = kTables[7][lo & 0xFFu] ^ kTables[6][(lo >> 8) & 0xFFu] ^ kTables[5][(lo >> 16) & 0xFFu] ^
        kTables[4][lo >> 24] ^ kTables[3][hi & 0xFFu] ^ kTables[2][(hi >> 8) & 0xFFu] ^
        kTables[1][(hi >> 16) & 0xFFu] ^ kTables[0][hi >> 24];
    p += 8;
    n -= 8;
  }
  while (n-- > 0) c = (c >> 8) ^ kTables[0][(c ^ *p++) & 0xFFu];
  return c;
}

/// x^(8 len) mod P applied to a raw register: the CRC register after `len` zero bytes.
/// Computed with a 32x32 GF(2) matrix squared log(len) times (zlib's crc32_combine method).
std::uint32_t gf2_times(const std::array<std::uint32_t, 32>& m, std::uint32_t v) {
  std::uint32_t s = 0;
  for (int i = 0; v != 0; ++i, v >>= 1)
    if (v & 1u) s ^= m[static_cast<std::size_t>(i)];
  return s;
}
std::array<std::uint32_t, 32> gf2_square(const std::array<std::uint32_t, 32>& m) {
  std::array<std::uint32_t, 32> r{};
  for (std::size_t i = 0; i < 32; ++i) r[i] = gf2_times(m, m[i]);
  return r;
}
/// The operator "append `bytes` zero bytes" on a raw CRC register, as a matrix.
std::array<std::uint32_t, 32> zeros_operator(std::size_t bytes) {
  std::array<std::uint32_t, 32> odd{};  // one zero bit
  odd[0] = kPoly;
  for (std::size_t i = 1; i < 32; ++i) odd[i] = 1u << (i - 1);
  std::array<std::uint32_t, 32> op{};  // identity
  for (std::size_t i = 0; i < 32; ++i) op[i] = 1u << i;
  std::array<std::uint32_t, 32> sq = gf2_square(gf2_square(gf2_square(odd)));  // one zero byte
  for (std::size_t b = bytes; b != 0; b >>= 1) {
    if (b & 1u) {
      std::array<std::uint32_t, 32> r{};
      for (std::size_t i = 0; i < 32; ++i) r[i] = gf2_times(sq, op[i]);
      op = r;
    }
    sq = gf2_square(sq);
  }
  return op;
}

#ifdef RAYSCAN_CRC32C_X86
// Three independent streams over thirds of each 24 KiB block hide the instruction's 3-cycle
// latency; the partial CRCs are combined by shifting through zero bytes with the table method
// (crc(A || B) = shift(crc(A), |B|) xor crc(B) for the raw, non-inverted register).
__attribute__((target("sse4.2"))) std::uint32_t update_hw_1(std::uint32_t c, const unsigned char* p, std::size_t n) {
  std::uint64_t c64 = c;
  while (n >= 8) {
    std::uint64_t v;
    std::memcpy(&v, p, 8);
    c64 = _mm_crc32_u64(c64, v);
    p += 8;
    n -= 8;
  }
  c = static_cast<std::uint32_t>(c64);
  while (n-- > 0) c = _mm_crc32_u8(c, *p++);
  return c;
}

constexpr std::size_t kLane = 8192;  // bytes per stream per block

__attribute__((target("sse4.2"))) std::uint32_t update_hw(std::uint32_t c, const unsigned char* p, std::size_t n) {
  static const std::array<std::uint32_t, 32> shift = zeros_operator(kLane);  // thread-safe init
  while (n >= 3 * kLane) {
    std::uint64_t a = c, b = 0, d = 0;
    const unsigned char* q = p;
    for (std::size_t i = 0; i < kLane; i += 8) {
      std::uint64_t va, vb, vd;
      std::memcpy(&va, q + i, 8);
      std::memcpy(&vb, q + kLane + i, 8);
      std::memcpy(&vd, q + 2 * kLane + i, 8);
      a = _mm_crc32_u64(a, va);
      b = _mm_crc32_u64(b, vb);
      d = _mm_crc32_u64(d, vd);
    }
    // crc(A||B||D) = shift(shift(a) ^ b) ^ d on raw registers.
    c = gf2_times(shift, gf2_times(shift, static_cast<std::uint32_t>(a)) ^ static_cast<std::uint32_t>(b)) ^
        static_cast<std::uint32_t>(d);
    p += 3 * kLane;
    n -= 3 * kLane;
  }
  return update_hw_1(c, p, n);
}

bool detect_hw() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("sse4.2");
}
#endif

}  // namespace

std::uint32_t crc32c_portable(const void* data, std::size_t n, std::uint32_t crc) {
  return ~update_portable(~crc, static_cast<const unsigned char*>(data), n);
}

bool crc32c_is_hardware() {
#ifdef RAYSCAN_CRC32C_X86
  static const bool hw = detect_hw();
  return hw;
#else
  return false;
#endif
}

std::uint32_t crc32c(const void* data, std::size_t n, std::uint32_t crc) {
  const auto* p = static_cast<const unsigned char*>(data);
#ifdef RAYSCAN_CRC32C_X86
  if (crc32c_is_hardware()) return ~update_hw(~crc, p, n);
#endif
  return ~update_portable(~crc, p, n);
}

std::uint32_t crc32c_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::size_t len_b) {
  // crc(A || B) = shift(crc(A), |B|) xor crc(B): the inversions at both ends cancel (zlib's
  // crc32_combine). The operator of the last length is kept per thread: callers combine runs of
  // one length (the index build's pages), so it is computed once per run.
  thread_local std::size_t last_len = 0;
  thread_local std::array<std::uint32_t, 32> last_op{};
  if (len_b != last_len || last_len == 0) {
    last_op = zeros_operator(len_b);
    last_len = len_b;
  }
  return gf2_times(last_op, crc_a) ^ crc_b;
}

}  // namespace rayscan::io
