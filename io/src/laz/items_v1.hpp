// Internal: LASzip item decoders of version 1 (LASzip 1.x, before 2.0), used by the pointwise
// (compressor 1) and pointwise-chunked (compressor 2) streams: POINT10 (item type 6, 20 bytes),
// GPSTIME11 (7, 8 bytes), RGB12 (8, 6 bytes), BYTE (0, n extra bytes). As in version 2, all items
// of a record share one arithmetic decoder and the first record of a stream (or chunk) is stored
// raw and seeds every item's "last" state.
// Format reference (read, not copied): LASzip src/lasreaditemcompressed_v1.cpp (one class per
// item), src/lasreadpoint.cpp (LASreadPoint::setup picks the v1 readers by item version for any
// compressor; read() seeds them with the raw first record). docs/formats.md "LAZ" section 2.
//
// Arithmetic coder and integer compressor: version 1 items use LASzip's one ArithmeticDecoder and
// one IntegerCompressor class exactly as version 2 does (same symbol/bit models, same corrector
// coding with 8 modelled high bits, no `range` argument), so arithmetic_decoder.hpp serves both.
// What differs is only how the items use them: other (bits, contexts) per field, x/y predicted
// from the median of the last 3 differences (not 5, not per return context), coordinates coded
// before the changed-values mask, scan angle, RGB and extra bytes coded as 8-bit integers
// (IntegerCompressor(8, ...)) instead of byte differences through 256-symbol models, and a
// simpler GPS-time coder with one sequence and multipliers 0..509.
#pragma once

#include "laz/arithmetic_decoder.hpp"
#include "laz/items_v2.hpp"  // LazyModels, wrap_add

#include <cstdint>
#include <cstring>
#include <vector>

namespace rayscan::io::laz {

/// Median of three values (the value is unique even with ties).
inline std::int32_t median3(const std::int32_t d[3]) {
  const std::int32_t lo = d[0] < d[1] ? d[0] : d[1], hi = d[0] < d[1] ? d[1] : d[0];
  const std::int32_t m = hi < d[2] ? hi : d[2];
  return lo < m ? m : lo;
}

/// POINT10 v1 (LASzip lasreaditemcompressed_v1.cpp, LASreadItemCompressed_POINT10_v1): x and y
/// as corrections to the median of their last three differences, z to the last z, with the
/// corrector bit lengths of x (and y) as contexts of the next coordinate; then a 6-bit mask of
/// which other fields changed (32 intensity, 16 return/flag byte, 8 classification, 4 scan
/// angle, 2 user data, 1 point source id). Unlike v2 the intensity is not reset by the first
/// record. Decodes 20-byte records; never fails (garbage in, garbage out).
class Point10V1 {
 public:
  void init(const std::uint8_t* first) { std::memcpy(last_, first, 20); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    std::int32_t x, y, z;
    std::memcpy(&x, last_, 4);
    std::memcpy(&y, last_ + 4, 4);
    std::memcpy(&z, last_ + 8, 4);
    const std::int32_t dx = ic_dx_.decompress(dec, median3(last_dx_));
    x = static_cast<std::int32_t>(static_cast<std::uint32_t>(x) + static_cast<std::uint32_t>(dx));
    std::uint32_t k = ic_dx_.k();
    const std::int32_t dy = ic_dy_.decompress(dec, median3(last_dy_), k < 19 ? k : 19);
    y = static_cast<std::int32_t>(static_cast<std::uint32_t>(y) + static_cast<std::uint32_t>(dy));
    k = (k + ic_dy_.k()) / 2;
    z = ic_z_.decompress(dec, z, k < 19 ? k : 19);
    std::memcpy(last_, &x, 4);
    std::memcpy(last_ + 4, &y, 4);
    std::memcpy(last_ + 8, &z, 4);
    const std::uint32_t changed = dec.decode_symbol(m_changed_);
    if (changed & 32) {
      std::uint16_t v;
      std::memcpy(&v, last_ + 12, 2);
      v = static_cast<std::uint16_t>(ic_intensity_.decompress(dec, v));
      std::memcpy(last_ + 12, &v, 2);
    }
    if (changed & 16) last_[14] = static_cast<std::uint8_t>(dec.decode_symbol(m_bit_byte_[last_[14]]));
    if (changed & 8) last_[15] = static_cast<std::uint8_t>(dec.decode_symbol(m_class_[last_[15]]));
    if (changed & 4) last_[16] = static_cast<std::uint8_t>(ic_scan_angle_.decompress(dec, last_[16], k < 3));
    if (changed & 2) last_[17] = static_cast<std::uint8_t>(dec.decode_symbol(m_user_data_[last_[17]]));
    if (changed & 1) {
      std::uint16_t v;
      std::memcpy(&v, last_ + 18, 2);
      v = static_cast<std::uint16_t>(ic_psid_.decompress(dec, v));
      std::memcpy(last_ + 18, &v, 2);
    }
    last_dx_[slot_] = dx;
    last_dy_[slot_] = dy;
    slot_ = slot_ == 2 ? 0 : slot_ + 1;
    std::memcpy(out, last_, 20);
  }

 private:
  std::uint8_t last_[20] = {};
  std::int32_t last_dx_[3] = {}, last_dy_[3] = {};
  std::uint32_t slot_ = 0;  // the oldest of the three differences
  IntegerDecompressor ic_dx_{32, 1}, ic_dy_{32, 20}, ic_z_{32, 20};
  IntegerDecompressor ic_intensity_{16, 1}, ic_scan_angle_{8, 2}, ic_psid_{16, 1};
  SymbolModel m_changed_{64};
  LazyModels<256, 256> m_bit_byte_, m_class_, m_user_data_;
};

/// GPSTIME11 v1 (LASzip lasreaditemcompressed_v1.cpp, LASreadItemCompressed_GPSTIME11_v1): one
/// sequence of 64-bit times. After a zero difference a 3-symbol model says unchanged / new 32-bit
/// difference / full 64-bit time; otherwise a 512-symbol multiplier m of the last difference:
/// 0 = a quarter of it, 1 = the same (replacing it), 2..509 = m times it (contexts by size of m),
/// 510 = full time, 511 = unchanged. Four extreme predictions (0 or 509) in a row replace the
/// last difference. Decodes 8-byte records; never fails.
class GpsTime11V1 {
 public:
  static constexpr int kMultiMax = 512;  ///< LASZIP_GPSTIME_MULTIMAX

  void init(const std::uint8_t* first) { std::memcpy(&last_time_, first, 8); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    if (last_diff_ == 0) {
      const std::uint32_t s = dec.decode_symbol(m_0diff_);
      if (s == 1) {
        last_diff_ = ic_.decompress(dec, 0, 0);
        last_time_ = wrap_add(last_time_, last_diff_);
      } else if (s == 2) {
        last_time_ = read_int64(dec);
      }
    } else {
      const int m = static_cast<int>(dec.decode_symbol(m_multi_));
      if (m < kMultiMax - 2) {
        std::int32_t d;
        if (m == 1) {
          d = ic_.decompress(dec, last_diff_, 1);
          last_diff_ = d;
          extreme_ = 0;
        } else if (m == 0) {
          d = ic_.decompress(dec, last_diff_ / 4, 2);
          extreme(d);
        } else {
          d = ic_.decompress(dec, times(m, last_diff_), m < 10 ? 3 : m < 50 ? 4 : 5);
          if (m == kMultiMax - 3) extreme(d);
        }
        last_time_ = wrap_add(last_time_, d);
      } else if (m == kMultiMax - 2) {
        last_time_ = read_int64(dec);
      }
    }
    std::memcpy(out, &last_time_, 8);
  }

 private:
  static std::int32_t times(int a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
  }
  /// ArithmeticDecoder::readInt64: the low 32 bits first.
  static std::int64_t read_int64(ArithmeticDecoder& dec) {
    const std::uint64_t lo = dec.read_int();
    const std::uint64_t hi = dec.read_int();
    return static_cast<std::int64_t>((hi << 32) | lo);
  }
  void extreme(std::int32_t d) {
    if (++extreme_ > 3) {
      last_diff_ = d;
      extreme_ = 0;
    }
  }

  std::int64_t last_time_ = 0;
  std::int32_t last_diff_ = 0, extreme_ = 0;
  SymbolModel m_multi_{kMultiMax}, m_0diff_{3};
  IntegerDecompressor ic_{32, 6};
};

/// RGB12 v1 (LASzip lasreaditemcompressed_v1.cpp, LASreadItemCompressed_RGB12_v1): a 6-bit mask
/// of which of the six colour bytes (R low, R high, G low, ...) changed, each changed byte an
/// 8-bit integer predicted by the same byte of the last record (context = byte index).
/// Decodes 6-byte records; never fails.
class Rgb12V1 {
 public:
  void init(const std::uint8_t* first) { std::memcpy(last_, first, 6); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    const std::uint32_t used = dec.decode_symbol(m_used_);
    for (std::uint32_t b = 0; b < 6; ++b)
      if (used & (1u << b)) last_[b] = static_cast<std::uint8_t>(ic_.decompress(dec, last_[b], b));
    std::memcpy(out, last_, 6);
  }

 private:
  std::uint8_t last_[6] = {};  // little-endian R, G, B: byte b is bit b of the mask
  SymbolModel m_used_{64};
  IntegerDecompressor ic_{8, 6};
};

/// BYTE v1 (LASzip lasreaditemcompressed_v1.cpp, LASreadItemCompressed_BYTE_v1): every extra
/// byte, every record, as an 8-bit integer predicted by the last record's byte (one context per
/// byte: `n` contexts, n = the item size, 1..65535). Decodes n-byte records; never fails.
class ByteV1 {
 public:
  explicit ByteV1(std::size_t n) : last_(n), ic_(8, static_cast<std::uint32_t>(n)) {}
  void init(const std::uint8_t* first) { std::memcpy(last_.data(), first, last_.size()); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    for (std::size_t i = 0; i < last_.size(); ++i)
      last_[i] = static_cast<std::uint8_t>(ic_.decompress(dec, last_[i], static_cast<std::uint32_t>(i)));
    std::memcpy(out, last_.data(), last_.size());
  }

 private:
  std::vector<std::uint8_t> last_;
  IntegerDecompressor ic_;
};

}  // namespace rayscan::io::laz
