// Internal: bounds-checked access to a file's bytes and the one-line error format of all readers.
#pragma once

#include "rayscan/base/coordinate_bound.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/io/point_io.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <new>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include <sys/mman.h>

namespace rayscan::io::detail {

/// Throws FormatError "<name>: byte <offset>: <what>", control bytes escaped (one_line): a quoted
/// token of a binary file could hold a NUL, which would end the message (what() is a C string).
[[noreturn]] inline void fail_at(const std::string& name, std::uint64_t offset,
                                 const std::string& what) {
  throw FormatError(one_line(name + ": byte " + std::to_string(offset) + ": " + what));
}
/// Throws FormatError "<name>: line <line>: <what>", escaped as fail_at's.
[[noreturn]] inline void fail_line(const std::string& name, std::uint64_t line,
                                   const std::string& what) {
  throw FormatError(one_line(name + ": line " + std::to_string(line) + ": " + what));
}

/// Whether x, y and z all lie within +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp), the
/// bound every point reader and writer holds a world coordinate to: one compare per axis, false
/// for NaN and infinities too, so a reader's loop tests each point once and sorts out the rare
/// failure afterwards.
[[nodiscard]] inline bool within_coordinate_bound(double x, double y, double z) {
  return std::abs(x) <= kMaxCoordinate && std::abs(y) <= kMaxCoordinate && std::abs(z) <= kMaxCoordinate;
}

/// The refusal of point `index` (0-based, in file order) whose `axis` (0 X, 1 Y, 2 Z) coordinate
/// `v` lies beyond +-kMaxCoordinate, as it follows the reader's "file: byte B: " or "file: line L: "
/// (or a writer's "file: "): "point N: X coordinate is V (<source>; expected within +-1e+09, the
/// coordinate bound in world units)", "overflows to infinity" for an infinite V; `source` says how
/// the file gives V (a LAS record's integer, scale and offset) and is left out when empty.
[[nodiscard]] inline std::string beyond_coordinate_bound(std::uint64_t index, int axis, double v,
                                                         const std::string& source = {}) {
  return "point " + std::to_string(index) + ": " + "XYZ"[axis] + " coordinate " +
         (std::isinf(v) ? std::string("overflows to infinity") : "is " + shortest_text(v)) + " (" +
         (source.empty() ? source : source + "; ") + coordinate_bound_expected() + ")";
}

/// beyond_coordinate_bound for the first axis of (x, y, z) beyond the bound (finite or infinite;
/// the caller has sorted out NaN by its own rule); Z when none is (not reached by a caller that
/// found within_coordinate_bound false for finite values).
[[nodiscard]] inline std::string beyond_coordinate_bound(std::uint64_t index, double x, double y, double z) {
  const int axis = !(std::abs(x) <= kMaxCoordinate) ? 0 : !(std::abs(y) <= kMaxCoordinate) ? 1 : 2;
  return beyond_coordinate_bound(index, axis, axis == 0 ? x : axis == 1 ? y : z);
}

/// The bytes of one input file plus its name (for errors). `release(upto)` tells the source that
/// bytes before `upto` will not be read again (a memory map then drops those pages from the
/// process's resident set, keeping peak memory bounded on multi-GB files).
struct Input {
  std::span<const std::uint8_t> bytes;
  std::string name;
  std::function<void(std::uint64_t)> release;

  [[nodiscard]] std::uint64_t size() const { return bytes.size(); }
  /// Throws unless [off, off + n) lies inside the file; `what` names the field being read.
  void need(std::uint64_t off, std::uint64_t n, std::string_view what) const {
    if (off > bytes.size() || n > bytes.size() - off)
      fail_at(name, off,
              "file ends (size " + std::to_string(bytes.size()) + ") inside " + std::string(what) +
                  " (needs " + std::to_string(n) + " bytes)");
  }
  void done(std::uint64_t upto) const {
    if (release) release(upto);
  }
};

/// Unaligned little-endian load (the host is little-endian; checked at compile time).
template <class T>
inline T load_le(const std::uint8_t* p) {
  static_assert(std::endian::native == std::endian::little);
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

/// Unaligned big-endian load.
template <class T>
inline T load_be(const std::uint8_t* p) {
  std::uint8_t tmp[sizeof(T)];
  for (std::size_t i = 0; i < sizeof(T); ++i) tmp[i] = p[sizeof(T) - 1 - i];
  T v;
  std::memcpy(&v, tmp, sizeof(T));
  return v;
}

/// Appends v's little-endian bytes to b (the counterpart of load_le, for the writers).
template <class T>
inline void append_le(std::vector<std::uint8_t>& b, T v) {
  static_assert(std::endian::native == std::endian::little && std::is_trivially_copyable_v<T>);
  const std::size_t at = b.size();
  b.resize(at + sizeof(T));
  std::memcpy(b.data() + at, &v, sizeof(T));
}

/// Overwrites b[at, at + sizeof(T)) (inside b) with v's little-endian bytes.
template <class T>
inline void store_le(std::vector<std::uint8_t>& b, std::size_t at, T v) {
  static_assert(std::endian::native == std::endian::little && std::is_trivially_copyable_v<T>);
  std::memcpy(b.data() + at, &v, sizeof(T));
}

/// Appends s as a fixed-width character field of n bytes, NUL-padded (cut at n): the counterpart
/// of fixed_string.
inline void append_fixed(std::vector<std::uint8_t>& b, std::string_view s, std::size_t n) {
  const std::size_t at = b.size();
  b.resize(at + n, 0);
  std::memcpy(b.data() + at, s.data(), std::min(n, s.size()));
}

/// Appends the header of a VLR (LAS 1.4 R15 section 2.5: 54 bytes, record length 16 bit) or, with
/// `extended`, of an EVLR (section 2.7: 60 bytes, 64 bit): reserved 0, user id (16 bytes), record
/// id, the payload's length, description (32 bytes). The caller appends the payload. Throws
/// std::length_error when a VLR's payload exceeds 65,535 bytes.
inline void append_vlr_header(std::vector<std::uint8_t>& b, std::string_view user, std::uint16_t record,
                              std::uint64_t length, std::string_view description, bool extended) {
  append_le<std::uint16_t>(b, 0);
  append_fixed(b, user, 16);
  append_le<std::uint16_t>(b, record);
  if (extended) {
    append_le<std::uint64_t>(b, length);
  } else {
    if (length > 65535) throw std::length_error("VLR payload of " + std::to_string(length) + " bytes (at most 65,535)");
    append_le<std::uint16_t>(b, static_cast<std::uint16_t>(length));
  }
  append_fixed(b, description, 32);
}

/// A fixed-width, NUL-padded character field as a string (trailing NULs and spaces removed).
inline std::string fixed_string(const std::uint8_t* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  std::string s(reinterpret_cast<const char*>(p), len);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
  return s;
}

/// Normalise raw colour channel values to 16 bit (0..65535), the rule of docs/formats.md:
/// `max_value` is the largest value the file holds over all three channels and `is_float`
/// whether the source type is floating point. Returns the multiplier to apply and describes the
/// choice in `note` ("" when values are used as they are).
inline double colour_scale(double max_value, bool is_float, std::string& note) {
  if (is_float && max_value <= 1.0) {
    note = "floating-point colour in 0..1: scaled by 65535";
    return 65535.0;
  }
  if (max_value <= 255.0) {
    note = "colour values <= 255 (8 bit): scaled by 257 to 16 bit";
    return 257.0;
  }
  if (max_value <= 65535.0) return 1.0;
  note = "colour values up to " + std::to_string(max_value) + ": scaled to 0..65535";
  return 65535.0 / max_value;
}

/// `v` rounded and clamped to [0, hi]; NaN gives 0 (values from text files may be anything).
inline double clamp_round(double v, double hi) {
  if (!(v > 0)) return 0;  // also NaN
  if (v >= hi) return hi;
  return std::nearbyint(v);
}
inline std::uint16_t to_u16(double v) { return static_cast<std::uint16_t>(clamp_round(v, 65535.0)); }
inline std::uint8_t to_u8(double v) { return static_cast<std::uint8_t>(clamp_round(v, 255.0)); }

/// `v` as float without undefined behaviour: finite values beyond the float range are clamped to
/// +-FLT_MAX (NaN and infinities convert as they are).
inline float to_f32(double v) {
  constexpr double kMax = 3.4028234663852886e38;
  if (v > kMax && v != HUGE_VAL) return static_cast<float>(kMax);
  if (v < -kMax && v != -HUGE_VAL) return static_cast<float>(-kMax);
  return static_cast<float>(v);
}

/// v.reserve(n), asking the kernel for transparent huge pages on the reserved storage (madvise
/// MADV_HUGEPAGE): a 10-million-point cloud then takes a few hundred page faults instead of
/// ~100,000, which is most of the system time of a large read (on a paravirtualised VM each 4 KiB
/// fault costs microseconds). A no-op where THP is disabled; the advice covers the whole 2 MiB
/// pages inside the storage.
template <class T>
void reserve_huge(std::vector<T>& v, std::size_t n) {
  v.reserve(n);
  constexpr std::uintptr_t kHuge = 2u << 20;
  const auto b = reinterpret_cast<std::uintptr_t>(v.data());
  const std::uintptr_t lo = (b + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t hi = (b + v.capacity() * sizeof(T)) & ~(kHuge - 1);
  if (hi > lo) ::madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
}

/// v.resize(n) on storage reserved by reserve_huge().
template <class T>
void resize_huge(std::vector<T>& v, std::size_t n) {
  reserve_huge(v, n);
  v.resize(n);
}

/// Alignment of O_DIRECT transfers (offsets, lengths, buffers; a multiple of every logical block
/// size in use), and n rounded up to it.
inline constexpr std::size_t kDirectAlign = 4096;
constexpr std::size_t round_up_direct(std::size_t n) { return (n + kDirectAlign - 1) / kDirectAlign * kDirectAlign; }

/// A fixed-size array of trivially copyable T in an anonymous mapping of its own (page-aligned): no zero-fill
/// pass (the kernel supplies zero pages on first touch) and transparent huge pages advised
/// (MADV_HUGEPAGE), for the multi-gigabyte buffers of the index build. Throws std::bad_alloc when
/// the mapping fails. Move-only.
template <class T>
class HugeArray {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  HugeArray() = default;
  explicit HugeArray(std::size_t n) : n_(n) {
    if (n == 0) return;
    if (n > SIZE_MAX / sizeof(T)) throw std::bad_alloc();
    void* q = ::mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (q == MAP_FAILED) throw std::bad_alloc();
    (void)::madvise(q, n * sizeof(T), MADV_HUGEPAGE);
    p_ = static_cast<T*>(q);
  }
  HugeArray(HugeArray&& o) noexcept : p_(std::exchange(o.p_, nullptr)), n_(std::exchange(o.n_, 0)) {}
  HugeArray& operator=(HugeArray&& o) noexcept {
    if (this != &o) {
      release();
      p_ = std::exchange(o.p_, nullptr);
      n_ = std::exchange(o.n_, 0);
    }
    return *this;
  }
  HugeArray(const HugeArray&) = delete;
  HugeArray& operator=(const HugeArray&) = delete;
  ~HugeArray() { release(); }
  [[nodiscard]] T* data() { return p_; }
  [[nodiscard]] const T* data() const { return p_; }
  [[nodiscard]] std::size_t size() const { return n_; }
  T& operator[](std::size_t i) { return p_[i]; }
  const T& operator[](std::size_t i) const { return p_[i]; }

 private:
  void release() {
    if (p_ != nullptr) ::munmap(p_, n_ * sizeof(T));
    p_ = nullptr;
    n_ = 0;
  }
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

}  // namespace rayscan::io::detail
