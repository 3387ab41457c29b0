// Internal: LASzip item decoders of version 2 (pointwise and pointwise-chunked compressors;
// version 1: items_v1.hpp):
// POINT10 (item type 6, 20 bytes), GPSTIME11 (7, 8 bytes), RGB12 (8, 6 bytes), BYTE (0, n extra
// bytes). All items of a record share one arithmetic decoder; the first record of a chunk is
// stored raw and seeds every item's "last" state. Format reference (read, not copied): LASzip
// src/lasreaditemcompressed_v2.cpp and src/laszip_common_v2.hpp (streaming median, return-number
// context tables); laz-perf cpp/lazperf/detail/field_point10.hpp, field_gpstime.hpp,
// field_rgb.hpp, field_byte.hpp. docs/formats.md "LAZ" section 2.
#pragma once

#include "laz/arithmetic_decoder.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <memory>

namespace rayscan::io::laz {

/// Wraps a sum into 0..255 (LASzip U8_FOLD).
inline std::uint8_t u8_fold(int v) { return static_cast<std::uint8_t>(v & 0xFF); }
/// Clamps to 0..255 (LASzip U8_CLAMP).
inline int u8_clamp(int v) { return v <= 0 ? 0 : (v >= 255 ? 255 : v); }

/// Context tables of the POINT10/POINT14 coders indexed [number_of_returns][return_number]
/// (LASzip laszip_common_v2.hpp): a context id 0..15 and the "level" |n - r| 0..7.
inline constexpr std::uint8_t kNumberReturnMap[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8},  {14, 0, 1, 3, 6, 10, 10, 9},   {13, 1, 2, 4, 7, 11, 11, 10},
    {12, 3, 4, 5, 8, 12, 12, 11},    {11, 6, 7, 8, 9, 13, 13, 12},  {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15}};
inline int number_return_level(int n, int r) { return n > r ? n - r : r - n; }

/// Median of the last five values, updated in O(1) by LASzip's "streaming median" insertion
/// (values kept sorted; `high` says which end the next insertion replaces).
struct StreamingMedian5 {
  std::int32_t v[5] = {0, 0, 0, 0, 0};
  bool high = true;
  [[nodiscard]] std::int32_t get() const { return v[2]; }
  void add(std::int32_t x) {
    if (high) {
      if (x < v[2]) {
        v[4] = v[3];
        v[3] = v[2];
        if (x < v[0]) { v[2] = v[1]; v[1] = v[0]; v[0] = x; }
        else if (x < v[1]) { v[2] = v[1]; v[1] = x; }
        else v[2] = x;
      } else {
        if (x < v[3]) { v[4] = v[3]; v[3] = x; }
        else v[4] = x;
        high = false;
      }
    } else {
      if (v[2] < x) {
        v[0] = v[1];
        v[1] = v[2];
        if (v[4] < x) { v[2] = v[3]; v[3] = v[4]; v[4] = x; }
        else if (v[3] < x) { v[2] = v[3]; v[3] = x; }
        else v[2] = x;
      } else {
        if (v[1] < x) { v[0] = v[1]; v[1] = x; }
        else v[0] = x;
        high = true;
      }
    }
  }
};

/// N models of `Symbols` symbols each, created on first use (LASzip creates the models keyed by
/// a previous value lazily; a fresh model equals a freshly initialised one).
template <std::size_t N, std::uint32_t Symbols>
struct LazyModels {
  std::array<std::unique_ptr<SymbolModel>, N> m;
  SymbolModel& operator[](std::size_t i) {
    if (!m[i]) m[i] = std::make_unique<SymbolModel>(Symbols);
    return *m[i];
  }
};

/// POINT10 v2: x/y predicted from the streaming median of the last differences in the same
/// return context, z from the last z at the same return level, flags/intensity/classification/
/// scan angle/user data/point source sent only when a 6-bit "changed" mask says so.
class Point10V2 {
 public:
  void init(const std::uint8_t* first) {
    std::memcpy(last_, first, 20);
    last_[12] = last_[13] = 0;  // LASzip seeds the intensity with zero
  }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    std::uint32_t r, n, m, l;
    const std::uint32_t changed = dec.decode_symbol(m_changed_);
    if (changed != 0) {
      if (changed & 32) last_[14] = static_cast<std::uint8_t>(dec.decode_symbol(m_bit_byte_[last_[14]]));
      r = last_[14] & 7;
      n = (last_[14] >> 3) & 7;
      m = kNumberReturnMap[n][r];
      l = static_cast<std::uint32_t>(number_return_level(static_cast<int>(n), static_cast<int>(r)));
      std::uint16_t intensity;
      if (changed & 16) {
        intensity = static_cast<std::uint16_t>(ic_intensity_.decompress(dec, last_intensity_[m], m < 3 ? m : 3));
        last_intensity_[m] = intensity;
      } else {
        intensity = last_intensity_[m];
      }
      std::memcpy(last_ + 12, &intensity, 2);
      if (changed & 8) last_[15] = static_cast<std::uint8_t>(dec.decode_symbol(m_class_[last_[15]]));
      if (changed & 4) {
        const int val = static_cast<int>(dec.decode_symbol(m_scan_angle_[(last_[14] >> 6) & 1]));
        last_[16] = u8_fold(val + last_[16]);
      }
      if (changed & 2) last_[17] = static_cast<std::uint8_t>(dec.decode_symbol(m_user_data_[last_[17]]));
      if (changed & 1) {
        std::uint16_t psid;
        std::memcpy(&psid, last_ + 18, 2);
        psid = static_cast<std::uint16_t>(ic_psid_.decompress(dec, psid));
        std::memcpy(last_ + 18, &psid, 2);
      }
    } else {
      r = last_[14] & 7;
      n = (last_[14] >> 3) & 7;
      m = kNumberReturnMap[n][r];
      l = static_cast<std::uint32_t>(number_return_level(static_cast<int>(n), static_cast<int>(r)));
    }
    std::int32_t x, y, z;
    std::memcpy(&x, last_, 4);
    std::memcpy(&y, last_ + 4, 4);
    std::int32_t diff = ic_dx_.decompress(dec, median_x_[m].get(), n == 1);
    x = static_cast<std::int32_t>(static_cast<std::uint32_t>(x) + static_cast<std::uint32_t>(diff));
    median_x_[m].add(diff);
    std::uint32_t kb = ic_dx_.k();
    diff = ic_dy_.decompress(dec, median_y_[m].get(), (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    y = static_cast<std::int32_t>(static_cast<std::uint32_t>(y) + static_cast<std::uint32_t>(diff));
    median_y_[m].add(diff);
    kb = (ic_dx_.k() + ic_dy_.k()) / 2;
    z = ic_z_.decompress(dec, last_height_[l], (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
    last_height_[l] = z;
    std::memcpy(last_, &x, 4);
    std::memcpy(last_ + 4, &y, 4);
    std::memcpy(last_ + 8, &z, 4);
    std::memcpy(out, last_, 20);
  }

 private:
  std::uint8_t last_[20] = {};
  std::uint16_t last_intensity_[16] = {};
  StreamingMedian5 median_x_[16], median_y_[16];
  std::int32_t last_height_[8] = {};
  SymbolModel m_changed_{64};
  IntegerDecompressor ic_intensity_{16, 4};
  SymbolModel m_scan_angle_[2] = {SymbolModel(256), SymbolModel(256)};
  IntegerDecompressor ic_psid_{16};
  LazyModels<256, 256> m_bit_byte_, m_class_, m_user_data_;
  IntegerDecompressor ic_dx_{32, 2}, ic_dy_{32, 22}, ic_z_{32, 20};
};

/// GPSTIME11 v2: the 64-bit time as up to four interleaved sequences, each predicted from a
/// multiple (-10..500) of its last 32-bit difference; large jumps are coded in full.
class GpsTime11V2 {
 public:
  static constexpr int kMulti = 500, kMultiMinus = -10;
  static constexpr int kUnchanged = kMulti - kMultiMinus + 1;  // 511
  static constexpr int kCodeFull = kMulti - kMultiMinus + 2;   // 512
  static constexpr int kTotal = kMulti - kMultiMinus + 6;      // 516

  void init(const std::uint8_t* first) {
    std::memcpy(&last_time_[0], first, 8);
  }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    for (;;) {  // a "switch sequence" symbol is followed by the value in the new sequence
      if (last_diff_[last_] == 0) {
        const std::uint32_t multi = dec.decode_symbol(m_0diff_);
        if (multi == 1) {
          last_diff_[last_] = ic_.decompress(dec, 0, 0);
          last_time_[last_] = wrap_add(last_time_[last_], last_diff_[last_]);
          extreme_[last_] = 0;
        } else if (multi == 2) {
          full(dec);
        } else if (multi > 2) {
          last_ = (last_ + multi - 2) & 3;
          continue;
        }
      } else {
        int multi = static_cast<int>(dec.decode_symbol(m_multi_));
        if (multi == 1) {
          last_time_[last_] = wrap_add(last_time_[last_], ic_.decompress(dec, last_diff_[last_], 1));
          extreme_[last_] = 0;
        } else if (multi < kUnchanged) {
          std::int32_t d;
          if (multi == 0) {
            d = ic_.decompress(dec, 0, 7);
            bump(d);
          } else if (multi < kMulti) {
            d = ic_.decompress(dec, times(multi, last_diff_[last_]), multi < 10 ? 2 : 3);
          } else if (multi == kMulti) {
            d = ic_.decompress(dec, times(kMulti, last_diff_[last_]), 4);
            bump(d);
          } else {
            multi = kMulti - multi;
            if (multi > kMultiMinus) {
              d = ic_.decompress(dec, times(multi, last_diff_[last_]), 5);
            } else {
              d = ic_.decompress(dec, times(kMultiMinus, last_diff_[last_]), 6);
              bump(d);
            }
          }
          last_time_[last_] = wrap_add(last_time_[last_], d);
        } else if (multi == kCodeFull) {
          full(dec);
        } else if (multi > kCodeFull) {
          last_ = (last_ + static_cast<std::uint32_t>(multi - kCodeFull)) & 3;
          continue;
        }
      }
      break;
    }
    std::memcpy(out, &last_time_[last_], 8);
  }

 private:
  static std::int32_t times(int a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
  }
  void bump(std::int32_t d) {
    if (++extreme_[last_] > 3) {
      last_diff_[last_] = d;
      extreme_[last_] = 0;
    }
  }
  void full(ArithmeticDecoder& dec) {
    next_ = (next_ + 1) & 3;
    const auto hi = static_cast<std::uint32_t>(
        ic_.decompress(dec, static_cast<std::int32_t>(static_cast<std::uint64_t>(last_time_[last_]) >> 32), 8));
    const std::uint64_t v = (static_cast<std::uint64_t>(hi) << 32) | dec.read_int();
    last_time_[next_] = static_cast<std::int64_t>(v);
    last_ = next_;
    last_diff_[last_] = 0;
    extreme_[last_] = 0;
  }

  std::uint32_t last_ = 0, next_ = 0;
  std::int64_t last_time_[4] = {};
  std::int32_t last_diff_[4] = {};
  std::int32_t extreme_[4] = {};
  SymbolModel m_multi_{kTotal}, m_0diff_{6};
  IntegerDecompressor ic_{32, 9};
};

/// Decodes one colour byte pair set of RGB12 v2 / RGB14 v3: a 7-bit mask of which bytes changed
/// (bit 6: green/blue differ from red), green and blue predicted from red's change.
/// `last` holds R, G, B (16-bit each) and is updated.
inline void read_rgb_v2(ArithmeticDecoder& dec, SymbolModel& m_used, SymbolModel* m_diff,
                        std::uint16_t* last, std::uint16_t* out) {
  const std::uint32_t sym = dec.decode_symbol(m_used);
  std::uint16_t o[3];
  if (sym & 1) o[0] = u8_fold(static_cast<int>(dec.decode_symbol(m_diff[0])) + (last[0] & 0xFF));
  else o[0] = last[0] & 0xFF;
  if (sym & 2) o[0] |= static_cast<std::uint16_t>(u8_fold(static_cast<int>(dec.decode_symbol(m_diff[1])) + (last[0] >> 8)) << 8);
  else o[0] |= last[0] & 0xFF00;
  if (sym & 64) {
    int diff = (o[0] & 0xFF) - (last[0] & 0xFF);
    if (sym & 4) o[1] = u8_fold(static_cast<int>(dec.decode_symbol(m_diff[2])) + u8_clamp(diff + (last[1] & 0xFF)));
    else o[1] = last[1] & 0xFF;
    if (sym & 16) {
      const int c = static_cast<int>(dec.decode_symbol(m_diff[4]));
      diff = (diff + ((o[1] & 0xFF) - (last[1] & 0xFF))) / 2;
      o[2] = u8_fold(c + u8_clamp(diff + (last[2] & 0xFF)));
    } else {
      o[2] = last[2] & 0xFF;
    }
    diff = (o[0] >> 8) - (last[0] >> 8);
    if (sym & 8) {
      const int c = static_cast<int>(dec.decode_symbol(m_diff[3]));
      o[1] |= static_cast<std::uint16_t>(u8_fold(c + u8_clamp(diff + (last[1] >> 8))) << 8);
    } else {
      o[1] |= last[1] & 0xFF00;
    }
    if (sym & 32) {
      const int c = static_cast<int>(dec.decode_symbol(m_diff[5]));
      diff = (diff + ((o[1] >> 8) - (last[1] >> 8))) / 2;
      o[2] |= static_cast<std::uint16_t>(u8_fold(c + u8_clamp(diff + (last[2] >> 8))) << 8);
    } else {
      o[2] |= last[2] & 0xFF00;
    }
  } else {
    o[1] = o[0];
    o[2] = o[0];
  }
  last[0] = o[0], last[1] = o[1], last[2] = o[2];
  std::memcpy(out, o, 6);
}

/// RGB12 v2 (6 bytes: red, green, blue as 16-bit little-endian).
class Rgb12V2 {
 public:
  void init(const std::uint8_t* first) { std::memcpy(last_, first, 6); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    std::uint16_t o[3];
    read_rgb_v2(dec, m_used_, m_diff_, last_, o);
    std::memcpy(out, o, 6);
  }

 private:
  std::uint16_t last_[3] = {};
  SymbolModel m_used_{128};
  SymbolModel m_diff_[6] = {SymbolModel(256), SymbolModel(256), SymbolModel(256),
                            SymbolModel(256), SymbolModel(256), SymbolModel(256)};
};

/// BYTE v2: each extra byte as the difference to the previous record's byte (one model per byte).
class ByteV2 {
 public:
  explicit ByteV2(std::size_t n) : last_(n), models_(n, SymbolModel(256)) {}
  void init(const std::uint8_t* first) { std::memcpy(last_.data(), first, last_.size()); }
  void read(ArithmeticDecoder& dec, std::uint8_t* out) {
    for (std::size_t i = 0; i < last_.size(); ++i) {
      last_[i] = u8_fold(last_[i] + static_cast<int>(dec.decode_symbol(models_[i])));
      out[i] = last_[i];
    }
  }

 private:
  std::vector<std::uint8_t> last_;
  std::vector<SymbolModel> models_;
};

}  // namespace rayscan::io::laz
