// Internal: the encoding side of LASzip's arithmetic coder, integer compressor and version 2
// items (POINT10, GPSTIME11, RGB12, BYTE) -- the exact inverses of arithmetic_decoder.hpp and
// items_v2.hpp. Format reference (read, not copied): LASzip src/arithmeticencoder.cpp (encodeBit,
// encodeSymbol, writeBits/writeShort/writeInt, propagate_carry, done), src/integercompressor.cpp
// (compress, writeCorrector), src/laswriteitemcompressed_v2.cpp. docs/formats.md "LAZ" section 4.
#pragma once

#include "laz/items_v2.hpp"

#include <cstdint>
#include <cstring>
#include <vector>

namespace rayscan::io::laz {

/// LASzip's GPS-time multiplier: round(d / last_diff) in float (I32_QUANTIZE), clamped first so
/// the float-to-int conversion never overflows (values past +-1e6 code the same symbol as 500
/// or -10 anyway). Reference: laswriteitemcompressed_v2.cpp/_v3.cpp write_gps_time.
inline std::int32_t gps_multiplier(std::int32_t d, std::int32_t last_diff) {
  float mf = static_cast<float>(d) / static_cast<float>(last_diff);
  if (mf > 1e6f) mf = 1e6f;
  if (mf < -1e6f) mf = -1e6f;
  return static_cast<std::int32_t>(mf >= 0 ? mf + 0.5f : mf - 0.5f);
}

/// Range encoder writing into a growing byte vector.
class ArithmeticEncoder {
 public:
  explicit ArithmeticEncoder(std::vector<std::uint8_t>& out) : out_(out) {}

  void encode_bit(BitModel& m, std::uint32_t sym) {
    const std::uint32_t x = m.bit0_prob * (length_ >> kBitShift);
    if (sym == 0) {
      length_ = x;
      ++m.bit0_count;
    } else {
      const std::uint32_t init = base_;
      base_ += x;
      length_ -= x;
      if (init > base_) carry();
    }
    if (length_ < kMinLength) renorm();
    if (--m.bits_until_update == 0) m.update();
  }
  void encode_symbol(SymbolModel& m, std::uint32_t sym) {
    const std::uint32_t init = base_;
    std::uint32_t x;
    if (sym == m.last_symbol_) {
      x = m.distribution_[sym] * (length_ >> kSymShift);
      base_ += x;
      length_ -= x;
    } else {
      x = m.distribution_[sym] * (length_ >>= kSymShift);
      base_ += x;
      length_ = m.distribution_[sym + 1] * length_ - x;
    }
    if (init > base_) carry();
    if (length_ < kMinLength) renorm();
    ++m.count_[sym];
    if (--m.symbols_until_update_ == 0) m.update();
  }
  void write_bits(std::uint32_t bits, std::uint32_t sym) {
    if (bits > 19) {
      write_short(sym & 0xFFFFu);
      sym >>= 16;
      bits -= 16;
    }
    const std::uint32_t init = base_;
    base_ += sym * (length_ >>= bits);
    if (init > base_) carry();
    if (length_ < kMinLength) renorm();
  }
  void write_short(std::uint32_t sym) {
    const std::uint32_t init = base_;
    base_ += sym * (length_ >>= 16);
    if (init > base_) carry();
    if (length_ < kMinLength) renorm();
  }
  void write_int(std::uint32_t sym) {
    write_short(sym & 0xFFFFu);
    write_short(sym >> 16);
  }
  /// Flushes the final one or two bytes and then three or two zero bytes, four in all, exactly
  /// the bytes a decoder reads past the last renormalisation (LASzip ArithmeticEncoder::done).
  void done() {
    const std::uint32_t init = base_;
    const bool another_byte = length_ > 2 * kMinLength;
    if (another_byte) {
      base_ += kMinLength;
      length_ = kMinLength >> 1;
    } else {
      base_ += kMinLength >> 1;
      length_ = kMinLength >> 9;
    }
    if (init > base_) carry();
    renorm();
    out_.push_back(0);
    out_.push_back(0);
    if (another_byte) out_.push_back(0);
  }

 private:
  void carry() {
    std::size_t p = out_.size();
    while (p > start_ && out_[p - 1] == 0xFF) out_[--p] = 0;
    if (p > start_) ++out_[p - 1];
  }
  void renorm() {
    do {
      out_.push_back(static_cast<std::uint8_t>(base_ >> 24));
      base_ <<= 8;
    } while ((length_ <<= 8) < kMinLength);
  }
  std::vector<std::uint8_t>& out_;
  std::size_t start_ = out_.size();
  std::uint32_t base_ = 0, length_ = kMaxLength;
};

/// LASzip IntegerCompressor, encoding side (same model layout as IntegerDecompressor).
class IntegerCompressor {
 public:
  IntegerCompressor(std::uint32_t bits = 16, std::uint32_t contexts = 1, std::uint32_t bits_high = 8)
      : bits_high_(bits_high) {
    if (bits != 0 && bits < 32) {
      corr_bits_ = bits;
      corr_range_ = 1u << bits;
      corr_min_ = -static_cast<std::int32_t>(corr_range_ / 2);
      corr_max_ = corr_min_ + static_cast<std::int32_t>(corr_range_ - 1);
    } else {
      corr_bits_ = 32;
      corr_range_ = 0;
      corr_min_ = INT32_MIN;
      corr_max_ = INT32_MAX;
    }
    bits_models_.assign(contexts, SymbolModel(corr_bits_ + 1, false));
    corrector_.emplace_back(2, false);
    for (std::uint32_t i = 1; i <= corr_bits_; ++i)
      corrector_.emplace_back(i <= bits_high_ ? (1u << i) : (1u << bits_high_), false);
  }

  void compress(ArithmeticEncoder& enc, std::int32_t pred, std::int32_t real, std::uint32_t context = 0) {
    std::int32_t corr = static_cast<std::int32_t>(static_cast<std::uint32_t>(real) - static_cast<std::uint32_t>(pred));
    if (corr_range_ != 0) {
      if (corr < corr_min_) corr += static_cast<std::int32_t>(corr_range_);
      else if (corr > corr_max_) corr -= static_cast<std::int32_t>(corr_range_);
    }
    write_corrector(enc, corr, bits_models_[context]);
  }
  [[nodiscard]] std::uint32_t k() const { return k_; }

 private:
  void write_corrector(ArithmeticEncoder& enc, std::int32_t c, SymbolModel& mbits) {
    std::uint32_t c1 = c <= 0 ? 0u - static_cast<std::uint32_t>(c) : static_cast<std::uint32_t>(c) - 1;
    k_ = 0;
    while (c1 != 0) {
      c1 >>= 1;
      ++k_;
    }
    enc.encode_symbol(mbits, k_);
    if (k_ == 0) {
      enc.encode_bit(corrector0_, static_cast<std::uint32_t>(c));
      return;
    }
    if (k_ >= 32) return;  // only corr_min: the decoder knows it from k alone
    std::uint32_t u = static_cast<std::uint32_t>(c);
    if (c < 0) u += (1u << k_) - 1;
    else u -= 1;
    if (k_ <= bits_high_) {
      enc.encode_symbol(corrector_[k_], u);
    } else {
      const std::uint32_t k1 = k_ - bits_high_;
      enc.encode_symbol(corrector_[k_], u >> k1);
      enc.write_bits(k1, u & ((1u << k1) - 1));
    }
  }

  std::uint32_t bits_high_, corr_bits_ = 0, corr_range_ = 0;
  std::int32_t corr_min_ = 0, corr_max_ = 0;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> bits_models_;
  BitModel corrector0_;
  std::vector<SymbolModel> corrector_;
};

/// POINT10 v2 encoder (inverse of Point10V2).
class Point10V2Enc {
 public:
  void init(const std::uint8_t* first) { std::memcpy(last_, first, 20); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    const std::uint32_t r = it[14] & 7, n = (it[14] >> 3) & 7;
    const std::uint32_t m = kNumberReturnMap[n][r];
    const auto l = static_cast<std::uint32_t>(number_return_level(static_cast<int>(n), static_cast<int>(r)));
    std::uint16_t intensity, psid, last_psid;
    std::memcpy(&intensity, it + 12, 2);
    std::memcpy(&psid, it + 18, 2);
    std::memcpy(&last_psid, last_ + 18, 2);
    const std::uint32_t changed = ((last_[14] != it[14]) << 5) | ((last_intensity_[m] != intensity) << 4) |
                                  ((last_[15] != it[15]) << 3) | ((last_[16] != it[16]) << 2) |
                                  ((last_[17] != it[17]) << 1) | (last_psid != psid ? 1u : 0u);
    enc.encode_symbol(m_changed_, changed);
    if (changed & 32) enc.encode_symbol(m_bit_byte_[last_[14]], it[14]);
    if (changed & 16) {
      ic_intensity_.compress(enc, last_intensity_[m], intensity, m < 3 ? m : 3);
      last_intensity_[m] = intensity;
    }
    if (changed & 8) enc.encode_symbol(m_class_[last_[15]], it[15]);
    if (changed & 4) enc.encode_symbol(m_scan_angle_[(it[14] >> 6) & 1], u8_fold(it[16] - last_[16]));
    if (changed & 2) enc.encode_symbol(m_user_data_[last_[17]], it[17]);
    if (changed & 1) ic_psid_.compress(enc, last_psid, psid);
    std::int32_t x, y, z, lx, ly;
    std::memcpy(&x, it, 4);
    std::memcpy(&y, it + 4, 4);
    std::memcpy(&z, it + 8, 4);
    std::memcpy(&lx, last_, 4);
    std::memcpy(&ly, last_ + 4, 4);
    std::int32_t diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(x) - static_cast<std::uint32_t>(lx));
    ic_dx_.compress(enc, median_x_[m].get(), diff, n == 1);
    median_x_[m].add(diff);
    std::uint32_t kb = ic_dx_.k();
    diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(y) - static_cast<std::uint32_t>(ly));
    ic_dy_.compress(enc, median_y_[m].get(), diff, (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    median_y_[m].add(diff);
    kb = (ic_dx_.k() + ic_dy_.k()) / 2;
    ic_z_.compress(enc, last_height_[l], z, (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
    last_height_[l] = z;
    std::memcpy(last_, it, 20);
  }

 private:
  std::uint8_t last_[20] = {};
  std::uint16_t last_intensity_[16] = {};
  StreamingMedian5 median_x_[16], median_y_[16];
  std::int32_t last_height_[8] = {};
  SymbolModel m_changed_{64, false};
  IntegerCompressor ic_intensity_{16, 4};
  SymbolModel m_scan_angle_[2] = {SymbolModel(256, false), SymbolModel(256, false)};
  IntegerCompressor ic_psid_{16};
  struct Lazy {
    std::array<std::unique_ptr<SymbolModel>, 256> m;
    SymbolModel& operator[](std::size_t i) {
      if (!m[i]) m[i] = std::make_unique<SymbolModel>(256, false);
      return *m[i];
    }
  } m_bit_byte_, m_class_, m_user_data_;
  IntegerCompressor ic_dx_{32, 2}, ic_dy_{32, 22}, ic_z_{32, 20};
};

/// GPSTIME11 v2 encoder (inverse of GpsTime11V2; LASzip's choice of multipliers and sequences).
class GpsTime11V2Enc {
 public:
  void init(const std::uint8_t* first) { std::memcpy(&last_time_[0], first, 8); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    std::int64_t t;
    std::memcpy(&t, it, 8);
    for (;;) {
      if (last_diff_[last_] == 0) {
        if (t == last_time_[last_]) {
          enc.encode_symbol(m_0diff_, 0);
          return;
        }
        const std::int64_t d64 = wrap_sub(t, last_time_[last_]);
        if (d64 == static_cast<std::int32_t>(d64)) {
          enc.encode_symbol(m_0diff_, 1);
          ic_.compress(enc, 0, static_cast<std::int32_t>(d64), 0);
          last_diff_[last_] = static_cast<std::int32_t>(d64);
          extreme_[last_] = 0;
        } else {
          const int other = other_sequence(t);
          if (other > 0) {
            enc.encode_symbol(m_0diff_, static_cast<std::uint32_t>(other + 2));
            last_ = (last_ + static_cast<std::uint32_t>(other)) & 3;
            continue;
          }
          enc.encode_symbol(m_0diff_, 2);
          full(enc, t);
        }
        last_time_[last_] = t;
        return;
      }
      if (t == last_time_[last_]) {
        enc.encode_symbol(m_multi_, GpsTime11V2::kUnchanged);
        return;
      }
      const std::int64_t d64 = wrap_sub(t, last_time_[last_]);
      if (d64 == static_cast<std::int32_t>(d64)) {
        const auto d = static_cast<std::int32_t>(d64);
        const std::int32_t multi = gps_multiplier(d, last_diff_[last_]);
        constexpr int M = GpsTime11V2::kMulti, MM = GpsTime11V2::kMultiMinus;
        if (multi == 1) {
          enc.encode_symbol(m_multi_, 1);
          ic_.compress(enc, last_diff_[last_], d, 1);
          extreme_[last_] = 0;
        } else if (multi > 0) {
          if (multi < M) {
            enc.encode_symbol(m_multi_, static_cast<std::uint32_t>(multi));
            ic_.compress(enc, times(multi, last_diff_[last_]), d, multi < 10 ? 2 : 3);
          } else {
            enc.encode_symbol(m_multi_, M);
            ic_.compress(enc, times(M, last_diff_[last_]), d, 4);
            bump(d);
          }
        } else if (multi < 0) {
          if (multi > MM) {
            enc.encode_symbol(m_multi_, static_cast<std::uint32_t>(M - multi));
            ic_.compress(enc, times(multi, last_diff_[last_]), d, 5);
          } else {
            enc.encode_symbol(m_multi_, static_cast<std::uint32_t>(M - MM));
            ic_.compress(enc, times(MM, last_diff_[last_]), d, 6);
            bump(d);
          }
        } else {
          enc.encode_symbol(m_multi_, 0);
          ic_.compress(enc, 0, d, 7);
          bump(d);
        }
      } else {
        const int other = other_sequence(t);
        if (other > 0) {
          enc.encode_symbol(m_multi_, static_cast<std::uint32_t>(GpsTime11V2::kCodeFull + other));
          last_ = (last_ + static_cast<std::uint32_t>(other)) & 3;
          continue;
        }
        enc.encode_symbol(m_multi_, GpsTime11V2::kCodeFull);
        full(enc, t);
      }
      last_time_[last_] = t;
      return;
    }
  }

 private:
  static std::int32_t times(int a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
  }
  int other_sequence(std::int64_t t) const {
    for (int i = 1; i < 4; ++i) {
      const std::int64_t d = wrap_sub(t, last_time_[(last_ + static_cast<std::uint32_t>(i)) & 3]);
      if (d == static_cast<std::int32_t>(d)) return i;
    }
    return 0;
  }
  void bump(std::int32_t d) {
    if (++extreme_[last_] > 3) {
      last_diff_[last_] = d;
      extreme_[last_] = 0;
    }
  }
  void full(ArithmeticEncoder& enc, std::int64_t t) {
    const auto u = static_cast<std::uint64_t>(t);
    ic_.compress(enc, static_cast<std::int32_t>(static_cast<std::uint64_t>(last_time_[last_]) >> 32),
                 static_cast<std::int32_t>(u >> 32), 8);
    enc.write_int(static_cast<std::uint32_t>(u));
    next_ = (next_ + 1) & 3;
    last_ = next_;
    last_diff_[last_] = 0;
    extreme_[last_] = 0;
  }
  std::uint32_t last_ = 0, next_ = 0;
  std::int64_t last_time_[4] = {};
  std::int32_t last_diff_[4] = {};
  std::int32_t extreme_[4] = {};
  SymbolModel m_multi_{GpsTime11V2::kTotal, false}, m_0diff_{6, false};
  IntegerCompressor ic_{32, 9};
};

/// RGB12 v2 encoder (inverse of Rgb12V2).
class Rgb12V2Enc {
 public:
  void init(const std::uint8_t* first) { std::memcpy(last_, first, 6); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    std::uint16_t c[3];
    std::memcpy(c, it, 6);
    std::uint32_t sym = ((last_[0] & 0x00FF) != (c[0] & 0x00FF)) << 0;
    sym |= ((last_[0] & 0xFF00) != (c[0] & 0xFF00)) << 1;
    sym |= ((last_[1] & 0x00FF) != (c[1] & 0x00FF)) << 2;
    sym |= ((last_[1] & 0xFF00) != (c[1] & 0xFF00)) << 3;
    sym |= ((last_[2] & 0x00FF) != (c[2] & 0x00FF)) << 4;
    sym |= ((last_[2] & 0xFF00) != (c[2] & 0xFF00)) << 5;
    sym |= (((c[0] & 0x00FF) != (c[1] & 0x00FF)) || ((c[0] & 0x00FF) != (c[2] & 0x00FF)) ||
            ((c[0] & 0xFF00) != (c[1] & 0xFF00)) || ((c[0] & 0xFF00) != (c[2] & 0xFF00))) << 6;
    enc.encode_symbol(m_used_, sym);
    int dl = 0, dh = 0;
    if (sym & 1) {
      dl = (c[0] & 255) - (last_[0] & 255);
      enc.encode_symbol(m_diff_[0], u8_fold(dl));
    }
    if (sym & 2) {
      dh = (c[0] >> 8) - (last_[0] >> 8);
      enc.encode_symbol(m_diff_[1], u8_fold(dh));
    }
    if (sym & 64) {
      if (sym & 4) enc.encode_symbol(m_diff_[2], u8_fold((c[1] & 255) - u8_clamp(dl + (last_[1] & 255))));
      if (sym & 16) {
        dl = (dl + (c[1] & 255) - (last_[1] & 255)) / 2;
        enc.encode_symbol(m_diff_[4], u8_fold((c[2] & 255) - u8_clamp(dl + (last_[2] & 255))));
      }
      if (sym & 8) enc.encode_symbol(m_diff_[3], u8_fold((c[1] >> 8) - u8_clamp(dh + (last_[1] >> 8))));
      if (sym & 32) {
        dh = (dh + (c[1] >> 8) - (last_[1] >> 8)) / 2;
        enc.encode_symbol(m_diff_[5], u8_fold((c[2] >> 8) - u8_clamp(dh + (last_[2] >> 8))));
      }
    }
    std::memcpy(last_, c, 6);
  }

 private:
  std::uint16_t last_[3] = {};
  SymbolModel m_used_{128, false};
  SymbolModel m_diff_[6] = {SymbolModel(256, false), SymbolModel(256, false), SymbolModel(256, false),
                            SymbolModel(256, false), SymbolModel(256, false), SymbolModel(256, false)};
};

/// BYTE v2 encoder (inverse of ByteV2).
class ByteV2Enc {
 public:
  explicit ByteV2Enc(std::size_t n) : last_(n), models_(n, SymbolModel(256, false)) {}
  void init(const std::uint8_t* first) { std::memcpy(last_.data(), first, last_.size()); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    for (std::size_t i = 0; i < last_.size(); ++i) {
      enc.encode_symbol(models_[i], u8_fold(it[i] - last_[i]));
      last_[i] = it[i];
    }
  }

 private:
  std::vector<std::uint8_t> last_;
  std::vector<SymbolModel> models_;
};

}  // namespace rayscan::io::laz
