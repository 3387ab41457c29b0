// Internal: the adaptive binary arithmetic (range) decoder of LASzip and its two kinds of
// adaptive models. The coder is A. Said's ("Lossless Compression Handbook", ch. 5, 2003) with the
// constants LASzip fixed: 32-bit interval, renormalisation when the length drops below 2^24,
// 13-bit probabilities for bit models and 15-bit distributions for symbol models.
// Format reference (read, not copied): LASzip src/arithmeticdecoder.cpp (decodeBit,
// decodeSymbol, readBits/readShort/readInt) and src/arithmeticmodel.cpp (model init/update);
// laz-perf cpp/lazperf/decoder.hpp. docs/formats.md "LAZ" section 1.
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

namespace rayscan::io::laz {

/// Two's-complement wrapping add of 64-bit integers: LASzip's GPS-time sequences (I64 += I32)
/// wrap on hostile data instead of overflowing (signed overflow is undefined in C++).
inline std::int64_t wrap_add(std::int64_t a, std::int64_t b) {
  return static_cast<std::int64_t>(static_cast<std::uint64_t>(a) + static_cast<std::uint64_t>(b));
}
/// Two's-complement wrapping difference a - b (the encoder's GPS-time deltas).
inline std::int64_t wrap_sub(std::int64_t a, std::int64_t b) {
  return static_cast<std::int64_t>(static_cast<std::uint64_t>(a) - static_cast<std::uint64_t>(b));
}

inline constexpr std::uint32_t kMinLength = 0x01000000u;  ///< AC__MinLength
inline constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;  ///< AC__MaxLength
inline constexpr int kBitShift = 13;                      ///< BM__LengthShift
inline constexpr std::uint32_t kBitMaxCount = 1u << kBitShift;
inline constexpr int kSymShift = 15;                      ///< DM__LengthShift
inline constexpr std::uint32_t kSymMaxCount = 1u << kSymShift;

/// Adaptive model of one binary decision: probability of 0 in 13 bits, refreshed every
/// `update_cycle` (4, growing by 5/4 up to 64) bits (LASzip ArithmeticBitModel).
struct BitModel {
  std::uint32_t bit0_prob = 1u << (kBitShift - 1);
  std::uint32_t bit0_count = 1, bit_count = 2;
  std::uint32_t update_cycle = 4, bits_until_update = 4;

  void update() {
    if ((bit_count += update_cycle) > kBitMaxCount) {
      bit_count = (bit_count + 1) >> 1;
      bit0_count = (bit0_count + 1) >> 1;
      if (bit0_count == bit_count) ++bit_count;
    }
    const std::uint32_t scale = 0x80000000u / bit_count;
    bit0_prob = (bit0_count * scale) >> (31 - kBitShift);
    update_cycle = (5 * update_cycle) >> 2;
    if (update_cycle > 64) update_cycle = 64;
    bits_until_update = update_cycle;
  }
};

/// Adaptive model of an alphabet of 2..2048 symbols: cumulative distribution in 15 bits, counts
/// halved when their total passes 2^15, refreshed on a cycle growing by 5/4 up to 8*(n+6).
/// `for_decoder` adds the lookup table LASzip's decoder uses to start its bisection (a pure
/// speed-up: it never changes the decoded symbol).
class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols = 2, bool for_decoder = true) { reset(symbols, for_decoder); }

  void reset(std::uint32_t symbols, bool for_decoder) {
    symbols_ = symbols;
    last_symbol_ = symbols - 1;
    if (for_decoder && symbols > 16) {
      std::uint32_t table_bits = 3;
      while (symbols > (1u << (table_bits + 2))) ++table_bits;
      table_size_ = 1u << table_bits;
      table_shift_ = kSymShift - table_bits;
      table_.assign(table_size_ + 2, 0);
    } else {
      table_size_ = table_shift_ = 0;
      table_.clear();
    }
    distribution_.assign(symbols, 0);
    count_.assign(symbols, 1);
    total_count_ = 0;
    update_cycle_ = symbols;
    update();
    symbols_until_update_ = update_cycle_ = (symbols + 6) >> 1;
  }

  void update() {
    if ((total_count_ += update_cycle_) > kSymMaxCount) {
      total_count_ = 0;
      for (std::uint32_t n = 0; n < symbols_; ++n) total_count_ += (count_[n] = (count_[n] + 1) >> 1);
    }
    std::uint32_t sum = 0, s = 0;
    const std::uint32_t scale = 0x80000000u / total_count_;
    if (table_size_ == 0) {
      for (std::uint32_t k = 0; k < symbols_; ++k) {
        distribution_[k] = (scale * sum) >> (31 - kSymShift);
        sum += count_[k];
      }
    } else {
      for (std::uint32_t k = 0; k < symbols_; ++k) {
        distribution_[k] = (scale * sum) >> (31 - kSymShift);
        sum += count_[k];
        const std::uint32_t w = distribution_[k] >> table_shift_;
        while (s < w) table_[++s] = k - 1;
      }
      table_[0] = 0;
      while (s <= table_size_) table_[++s] = symbols_ - 1;
    }
    update_cycle_ = (5 * update_cycle_) >> 2;
    const std::uint32_t max_cycle = (symbols_ + 6) << 3;
    if (update_cycle_ > max_cycle) update_cycle_ = max_cycle;
    symbols_until_update_ = update_cycle_;
  }

  std::uint32_t symbols_ = 0, last_symbol_ = 0;
  std::uint32_t table_size_ = 0, table_shift_ = 0;
  std::uint32_t total_count_ = 0, update_cycle_ = 0, symbols_until_update_ = 0;
  std::vector<std::uint32_t> distribution_, count_, table_;
};

/// Decoder over one byte range (one LAZ chunk or layer). Reading past the range yields zero
/// bytes and counts them in `overrun` (a valid stream never needs more than its own bytes), so
/// a corrupted stream decodes to garbage but never reads outside the mapping.
class ArithmeticDecoder {
 public:
  ArithmeticDecoder() = default;
  ArithmeticDecoder(const std::uint8_t* begin, const std::uint8_t* end) { init(begin, end); }

  /// Starts decoding at `begin` (reads the first 4 bytes, big-endian, into the value register).
  void init(const std::uint8_t* begin, const std::uint8_t* end) {
    p_ = begin;
    end_ = end;
    overrun = 0;
    length_ = kMaxLength;
    value_ = 0;
    for (int i = 0; i < 4; ++i) value_ = (value_ << 8) | byte();
  }

  std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t x = m.bit0_prob * (length_ >> kBitShift);
    const std::uint32_t sym = value_ >= x;
    if (sym == 0) {
      length_ = x;
      ++m.bit0_count;
    } else {
      value_ -= x;
      length_ -= x;
    }
    if (length_ < kMinLength) renorm();
    if (--m.bits_until_update == 0) m.update();
    return sym;
  }

  std::uint32_t decode_symbol(SymbolModel& m) {
    std::uint32_t n, sym, x, y = length_;
    if (m.table_size_ != 0) {
      const std::uint32_t dv = value_ / (length_ >>= kSymShift);
      const std::uint32_t t = dv >> m.table_shift_;
      sym = m.table_[t];
      n = m.table_[t + 1] + 1;
      while (n > sym + 1) {
        const std::uint32_t k = (sym + n) >> 1;
        if (m.distribution_[k] > dv) n = k; else sym = k;
      }
      x = m.distribution_[sym] * length_;
      if (sym != m.last_symbol_) y = m.distribution_[sym + 1] * length_;
    } else {
      x = sym = 0;
      length_ >>= kSymShift;
      std::uint32_t k = (n = m.symbols_) >> 1;
      do {
        const std::uint32_t z = length_ * m.distribution_[k];
        if (z > value_) {
          n = k;
          y = z;
        } else {
          sym = k;
          x = z;
        }
      } while ((k = (sym + n) >> 1) != sym);
    }
    value_ -= x;
    length_ = y - x;
    if (length_ < kMinLength) renorm();
    ++m.count_[sym];
    if (--m.symbols_until_update_ == 0) m.update();
    return sym;
  }

  /// `bits` (1..32) raw bits, most significant part first for bits > 19 (LASzip readBits).
  std::uint32_t read_bits(std::uint32_t bits) {
    if (bits > 19) {
      const std::uint32_t lo = read_short();
      const std::uint32_t hi = read_bits(bits - 16);
      return (hi << 16) | lo;
    }
    const std::uint32_t sym = value_ / (length_ >>= bits);
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    return sym;
  }
  std::uint32_t read_short() {
    const std::uint32_t sym = value_ / (length_ >>= 16);
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    return sym & 0xFFFFu;
  }
  /// 32 raw bits as two shorts, low half first.
  std::uint32_t read_int() {
    const std::uint32_t lo = read_short();
    const std::uint32_t hi = read_short();
    return (hi << 16) | lo;
  }

  /// Bytes requested past the end of the range (0 for a well-formed stream).
  std::uint64_t overrun = 0;
  /// Next byte position (for error messages).
  [[nodiscard]] const std::uint8_t* position() const { return p_; }

 private:
  std::uint8_t byte() {
    if (p_ < end_) return *p_++;
    ++overrun;
    return 0;
  }
  void renorm() {
    do {
      value_ = (value_ << 8) | byte();
    } while ((length_ <<= 8) < kMinLength);
  }

  const std::uint8_t* p_ = nullptr;
  const std::uint8_t* end_ = nullptr;
  std::uint32_t value_ = 0, length_ = kMaxLength;
};

/// LASzip's IntegerCompressor, decoding side: an integer is predicted, and the corrector
/// (real - pred, folded into the `bits`-bit range) is sent as its bit length k (a symbol model
/// per context) followed by its position inside [-(2^k-1), 2^k] (a symbol model for k <= 8
/// bits, the top 8 bits modelled and the rest raw above). Reference: LASzip
/// src/integercompressor.cpp (constructor, initDecompressor, decompress, readCorrector).
class IntegerDecompressor {
 public:
  IntegerDecompressor(std::uint32_t bits = 16, std::uint32_t contexts = 1, std::uint32_t bits_high = 8,
                      std::uint32_t range = 0)
      : bits_high_(bits_high) {
    if (range != 0) {
      corr_bits_ = 0;
      corr_range_ = range;
      while (range != 0) {
        range >>= 1;
        ++corr_bits_;
      }
      if (corr_range_ == (1u << (corr_bits_ - 1))) --corr_bits_;
    } else if (bits != 0 && bits < 32) {
      corr_bits_ = bits;
      corr_range_ = 1u << bits;
    } else {
      corr_bits_ = 32;
      corr_range_ = 0;
    }
    corr_min_ = corr_range_ != 0 ? -static_cast<std::int32_t>(corr_range_ / 2) : INT32_MIN;
    bits_models_.assign(contexts, SymbolModel(corr_bits_ + 1));
    corrector_.reserve(corr_bits_ + 1);
    corrector_.emplace_back(2);  // unused slot 0 (the 1-bit corrector is a BitModel)
    for (std::uint32_t i = 1; i <= corr_bits_; ++i)
      corrector_.emplace_back(i <= bits_high_ ? (1u << i) : (1u << bits_high_));
  }

  /// pred + decoded corrector, wrapped into the compressor's range (32-bit: modulo 2^32).
  std::int32_t decompress(ArithmeticDecoder& dec, std::int32_t pred, std::uint32_t context = 0) {
    std::uint32_t real = static_cast<std::uint32_t>(pred) + static_cast<std::uint32_t>(read_corrector(dec, bits_models_[context]));
    if (corr_range_ != 0) {
      if (static_cast<std::int32_t>(real) < 0) real += corr_range_;
      else if (real >= corr_range_) real -= corr_range_;
    }
    return static_cast<std::int32_t>(real);
  }
  /// Bit length k of the last corrector (the context some items derive from it).
  [[nodiscard]] std::uint32_t k() const { return k_; }

 private:
  std::int32_t read_corrector(ArithmeticDecoder& dec, SymbolModel& mbits) {
    k_ = dec.decode_symbol(mbits);
    if (k_ == 0) return static_cast<std::int32_t>(dec.decode_bit(corrector0_));
    if (k_ >= 32) return corr_min_;
    std::uint32_t c;
    if (k_ <= bits_high_) {
      c = dec.decode_symbol(corrector_[k_]);
    } else {
      const std::uint32_t k1 = k_ - bits_high_;
      c = dec.decode_symbol(corrector_[k_]);
      const std::uint32_t c1 = dec.read_bits(k1);
      c = (c << k1) | c1;
    }
    if (c >= (1u << (k_ - 1))) c += 1;
    else c -= (1u << k_) - 1;
    return static_cast<std::int32_t>(c);
  }

  std::uint32_t bits_high_ = 8, corr_bits_ = 0, corr_range_ = 0;
  std::int32_t corr_min_ = 0;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> bits_models_;
  BitModel corrector0_;
  std::vector<SymbolModel> corrector_;
};

}  // namespace rayscan::io::laz
