// Point positions by storage slot as the SpatialIndex concept exposes them: either a span of
// float64 triples (the in-memory Octree, KdTree, BruteForce, CopcIndex: zero cost) or a
// PositionView that decodes a compact encoding on access (the index file's LAS int32 grid or
// float32 positions, docs/index-format.md "Positions"). Query templates read positions only
// through `pos[slot]`, `pos.size()` and position_block(), so both work unchanged.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <span>
#include <vector>

namespace rayscan {

/// One coordinate of a LAS point record: `X * scale + offset` in double (ASPRS LAS 1.4 R15 section
/// 2.4, "X, Y and Z scale factors" / "offsets"). The ONE expression every LAS/LAZ/COPC reader and
/// the index file's int32 grid decode with, so decoded values are bit-identical to the reader's.
/// That holds only while the multiply and the add round separately: GCC and Clang fuse them into
/// an FMA in C++ by default (-std=c++20 included) wherever the target has one (aarch64,
/// -march=native). So -ffp-contract=off is a usage requirement of rayscan::octree (its CMake
/// target): every target that includes this header compiles without contraction.
[[nodiscard]] inline double las_coordinate(std::int32_t v, double scale, double offset) {
  return static_cast<double>(v) * scale + offset;
}

/// How an index stores its positions (docs/index-format.md, "Positions"): the header's encoding id.
enum class PositionEncoding : std::uint32_t {
  float64 = 0,    ///< 24 bytes: float64 x, y, z (any source)
  float32 = 1,    ///< 12 bytes: float32 x, y, z (every coordinate is exactly a float)
  las_int32 = 2,  ///< 12 bytes: int32 X, Y, Z decoded by las_coordinate with the header's scale/offset
};

/// "float64", "float32" or "las_int32" (rayscan info, docs/index-format.md).
[[nodiscard]] constexpr const char* to_string(PositionEncoding e) {
  return e == PositionEncoding::float64 ? "float64" : e == PositionEncoding::float32 ? "float32" : "las_int32";
}

/// Bytes per point of an encoding.
[[nodiscard]] constexpr std::size_t position_bytes(PositionEncoding e) {
  return e == PositionEncoding::float64 ? 24 : 12;
}

/// Read-only view of N positions in one of the encodings, indexed by slot: `view[s]` returns the
/// decoded Vec3 by value (bit-identical to what the source's reader produced). `data()` is the
/// float64 array when the encoding is float64 (used in place), else null. Does not own the bytes.
class PositionView {
 public:
  PositionView() = default;
  /// float64 positions used in place (implicit: a span of Vec3 is a float64 view).
  PositionView(std::span<const Vec3> p) : f64_(p.data()), n_(p.size()) {}  // NOLINT(google-explicit-constructor)
  PositionView(const std::vector<Vec3>& p) : f64_(p.data()), n_(p.size()) {}  // NOLINT(google-explicit-constructor)
  /// `bytes`: N x position_bytes(enc) bytes, 4-byte aligned; `scale`/`offset`: the LAS grid
  /// (las_int32 only).
  PositionView(PositionEncoding enc, const void* bytes, std::size_t n, Vec3 scale = Vec3(1.0), Vec3 offset = Vec3(0.0))
      : enc_(enc), n_(n), scale_(scale), offset_(offset) {
    if (enc == PositionEncoding::float64) f64_ = static_cast<const Vec3*>(bytes);
    else raw_ = bytes;
  }

  [[nodiscard]] std::size_t size() const { return n_; }
  [[nodiscard]] bool empty() const { return n_ == 0; }
  [[nodiscard]] PositionEncoding encoding() const { return enc_; }
  [[nodiscard]] const Vec3* data() const { return f64_; }
  [[nodiscard]] const Vec3& scale() const { return scale_; }
  [[nodiscard]] const Vec3& offset() const { return offset_; }

  /// The position of slot s < size().
  [[nodiscard]] Vec3 operator[](std::size_t s) const {
    if (f64_ != nullptr) return f64_[s];
    if (enc_ == PositionEncoding::las_int32) {
      std::int32_t v[3];
      std::memcpy(v, static_cast<const std::uint8_t*>(raw_) + 12 * s, 12);
      return {las_coordinate(v[0], scale_.x, offset_.x), las_coordinate(v[1], scale_.y, offset_.y),
              las_coordinate(v[2], scale_.z, offset_.z)};
    }
    float f[3];
    std::memcpy(f, static_cast<const std::uint8_t*>(raw_) + 12 * s, 12);
    return {static_cast<double>(f[0]), static_cast<double>(f[1]), static_cast<double>(f[2])};
  }
  /// Decodes slots [b, b + n) into out[0, n).
  void decode(std::size_t b, std::size_t n, Vec3* out) const {
    if (f64_ != nullptr) {
      std::memcpy(static_cast<void*>(out), f64_ + b, n * sizeof(Vec3));
      return;
    }
    const auto* src = static_cast<const std::uint8_t*>(raw_) + 12 * b;
    // One branch per block, a tight loop per point. The grid constants live in locals (out may
    // alias *this as far as the compiler knows) and each coordinate is loaded on its own: a
    // 12-byte memcpy into a stack array was compiled to two stores and a 16-byte reload per point
    // (a store-forwarding stall; profiled, bench/README.md).
    if (enc_ == PositionEncoding::las_int32) {
      const double sx = scale_.x, sy = scale_.y, sz = scale_.z;
      const double ox = offset_.x, oy = offset_.y, oz = offset_.z;
      for (std::size_t i = 0; i < n; ++i, src += 12) {
        std::int32_t x, y, z;
        std::memcpy(&x, src, 4);
        std::memcpy(&y, src + 4, 4);
        std::memcpy(&z, src + 8, 4);
        out[i] = Vec3(las_coordinate(x, sx, ox), las_coordinate(y, sy, oy), las_coordinate(z, sz, oz));
      }
      return;
    }
    for (std::size_t i = 0; i < n; ++i, src += 12) {
      float x, y, z;
      std::memcpy(&x, src, 4);
      std::memcpy(&y, src + 4, 4);
      std::memcpy(&z, src + 8, 4);
      out[i] = Vec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
    }
  }

  /// Random-access iterator yielding Vec3 by value (for std algorithms and vector::assign).
  class iterator {
   public:
    using iterator_category = std::random_access_iterator_tag;
    using value_type = Vec3;
    using difference_type = std::ptrdiff_t;
    using reference = Vec3;
    using pointer = void;
    iterator() = default;
    iterator(const PositionView* v, std::size_t i) : v_(v), i_(i) {}
    Vec3 operator*() const { return (*v_)[i_]; }
    Vec3 operator[](difference_type k) const { return (*v_)[i_ + static_cast<std::size_t>(k)]; }
    iterator& operator++() { ++i_; return *this; }
    iterator operator++(int) { iterator t = *this; ++i_; return t; }
    iterator& operator--() { --i_; return *this; }
    iterator operator--(int) { iterator t = *this; --i_; return t; }
    iterator& operator+=(difference_type k) { i_ += static_cast<std::size_t>(k); return *this; }
    iterator& operator-=(difference_type k) { i_ -= static_cast<std::size_t>(k); return *this; }
    friend iterator operator+(iterator a, difference_type k) { return a += k; }
    friend iterator operator+(difference_type k, iterator a) { return a += k; }
    friend iterator operator-(iterator a, difference_type k) { return a -= k; }
    friend difference_type operator-(const iterator& a, const iterator& b) {
      return static_cast<difference_type>(a.i_) - static_cast<difference_type>(b.i_);
    }
    friend bool operator==(const iterator& a, const iterator& b) { return a.i_ == b.i_; }
    friend auto operator<=>(const iterator& a, const iterator& b) { return a.i_ <=> b.i_; }

   private:
    const PositionView* v_ = nullptr;
    std::size_t i_ = 0;
  };
  [[nodiscard]] iterator begin() const { return {this, 0}; }
  [[nodiscard]] iterator end() const { return {this, n_}; }

 private:
  const Vec3* f64_ = nullptr;  // float64 encoding: the array itself
  const void* raw_ = nullptr;  // float32 / las_int32: 12 bytes per point
  PositionEncoding enc_ = PositionEncoding::float64;
  std::size_t n_ = 0;
  Vec3 scale_{1.0}, offset_{0.0};
};

/// What an index's positions() returns: `p[slot]` a Vec3 (by value or reference), `p.size()`.
/// std::span<const Vec3> and PositionView both model it.
template <class P>
concept PositionRange = requires(const P& p, std::size_t s) {
  { p[s] } -> std::convertible_to<Vec3>;
  { p.size() } -> std::convertible_to<std::size_t>;
};

/// Positions [b, b + n) as contiguous float64 x, y, z triples (the SIMD point filters' input):
/// the array itself for a span (zero cost), else decoded into a per-thread buffer that stays valid
/// until the next position_block call on the same thread (the three-argument form, which decodes
/// through the four-argument one).
/// With `buf`: decoded into the caller's buffer (grown to n as needed; the result stays valid
/// until buf changes), for a caller that holds per-thread scratch already (the ray query), so the
/// hot loop reaches no thread_local. A span or float64 view returns the array itself.
inline const double* position_block(std::span<const Vec3> p, std::uint32_t b, std::uint32_t /*n*/,
                                    std::vector<Vec3>& /*buf*/) {
  return &p[b].x;
}
inline const double* position_block(const PositionView& p, std::uint32_t b, std::uint32_t n, std::vector<Vec3>& buf) {
  if (p.data() != nullptr) return &p.data()[b].x;
  if (buf.size() < n || buf.empty()) buf.resize(n > 0 ? n : 1);
  p.decode(b, n, buf.data());
  return &buf[0].x;
}
inline const double* position_block(std::span<const Vec3> p, std::uint32_t b, std::uint32_t /*n*/) { return &p[b].x; }
inline const double* position_block(const PositionView& p, std::uint32_t b, std::uint32_t n) {
  if (p.data() != nullptr) return &p.data()[b].x;
  // (The attribute does not keep this buffer out of a module's static TLS block: a module with any
  // initial-exec access needs its whole block there. The Python module uses the default model;
  // python/CMakeLists.txt says why.)
  __attribute__((tls_model("global-dynamic"))) thread_local std::vector<Vec3> buf;
  return position_block(p, b, n, buf);
}

}  // namespace rayscan
