// Test-only encoder of LASzip version 1 items (POINT10, GPSTIME11, RGB12, BYTE), the inverse of
// io/src/laz/items_v1.hpp, used to build pointwise-chunked (compressor 2) files with version 1
// items, of which no public sample was found. It makes the same choices as LASzip's writer
// (src/laswriteitemcompressed_v1.cpp: which fields count as changed, the GPS-time multiplier
// rounded in float and clamped to 0..509), so that it can be checked against a stream LASzip
// wrote: encoding the records of PDAL's simple.las must give the point data of
// simple-laszip-compressor-version-1.2r0.laz byte for byte (test_laz.cpp).
#pragma once

#include "laz/encoder_v2.hpp"
#include "laz/items_v1.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace rayscan::test::lazv1 {

using io::laz::ArithmeticEncoder;
using io::laz::IntegerCompressor;
using io::laz::SymbolModel;

/// POINT10 v1 encoder (inverse of laz::Point10V1).
class Point10Enc {
 public:
  explicit Point10Enc(const std::uint8_t* first) { std::memcpy(last_, first, 20); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    std::int32_t x, y, z, lx, ly, lz;
    std::memcpy(&x, it, 4), std::memcpy(&y, it + 4, 4), std::memcpy(&z, it + 8, 4);
    std::memcpy(&lx, last_, 4), std::memcpy(&ly, last_ + 4, 4), std::memcpy(&lz, last_ + 8, 4);
    const auto dx = static_cast<std::int32_t>(static_cast<std::uint32_t>(x) - static_cast<std::uint32_t>(lx));
    const auto dy = static_cast<std::int32_t>(static_cast<std::uint32_t>(y) - static_cast<std::uint32_t>(ly));
    ic_dx_.compress(enc, io::laz::median3(last_dx_), dx);
    std::uint32_t k = ic_dx_.k();
    ic_dy_.compress(enc, io::laz::median3(last_dy_), dy, k < 19 ? k : 19);
    k = (k + ic_dy_.k()) / 2;
    ic_z_.compress(enc, lz, z, k < 19 ? k : 19);
    const bool intensity = std::memcmp(it + 12, last_ + 12, 2) != 0, psid = std::memcmp(it + 18, last_ + 18, 2) != 0;
    const std::uint32_t changed = (intensity ? 32u : 0u) | (it[14] != last_[14] ? 16u : 0u) | (it[15] != last_[15] ? 8u : 0u) |
                                  (it[16] != last_[16] ? 4u : 0u) | (it[17] != last_[17] ? 2u : 0u) | (psid ? 1u : 0u);
    enc.encode_symbol(m_changed_, changed);
    if (changed & 32) ic_intensity_.compress(enc, u16(last_ + 12), u16(it + 12));
    if (changed & 16) enc.encode_symbol(model(m_bit_byte_, last_[14]), it[14]);
    if (changed & 8) enc.encode_symbol(model(m_class_, last_[15]), it[15]);
    if (changed & 4) ic_scan_angle_.compress(enc, last_[16], it[16], k < 3);
    if (changed & 2) enc.encode_symbol(model(m_user_data_, last_[17]), it[17]);
    if (changed & 1) ic_psid_.compress(enc, u16(last_ + 18), u16(it + 18));
    last_dx_[slot_] = dx, last_dy_[slot_] = dy;
    slot_ = slot_ == 2 ? 0 : slot_ + 1;
    std::memcpy(last_, it, 20);
  }

 private:
  using Models = std::array<std::unique_ptr<SymbolModel>, 256>;
  static SymbolModel& model(Models& m, std::uint8_t i) {
    if (!m[i]) m[i] = std::make_unique<SymbolModel>(256, false);
    return *m[i];
  }
  static std::int32_t u16(const std::uint8_t* p) { return p[0] | (p[1] << 8); }
  std::uint8_t last_[20];
  std::int32_t last_dx_[3] = {}, last_dy_[3] = {};
  std::uint32_t slot_ = 0;
  IntegerCompressor ic_dx_{32, 1}, ic_dy_{32, 20}, ic_z_{32, 20};
  IntegerCompressor ic_intensity_{16, 1}, ic_scan_angle_{8, 2}, ic_psid_{16, 1};
  SymbolModel m_changed_{64, false};
  Models m_bit_byte_, m_class_, m_user_data_;
};

/// GPSTIME11 v1 encoder (inverse of laz::GpsTime11V1).
class GpsEnc {
 public:
  explicit GpsEnc(const std::uint8_t* first) { std::memcpy(&last_, first, 8); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    std::int64_t t;
    std::memcpy(&t, it, 8);
    const std::int64_t d64 = io::laz::wrap_sub(t, last_);
    const auto d = static_cast<std::int32_t>(d64);
    if (last_diff_ == 0) {
      if (t == last_) {
        enc.encode_symbol(m_0diff_, 0);
      } else if (d64 == d) {
        enc.encode_symbol(m_0diff_, 1);
        ic_.compress(enc, 0, d, 0);
        last_diff_ = d;
      } else {
        enc.encode_symbol(m_0diff_, 2);
        write_int64(enc, t);
      }
    } else if (t == last_) {
      enc.encode_symbol(m_multi_, 511);
    } else if (d64 != d) {
      enc.encode_symbol(m_multi_, 510);
      write_int64(enc, t);
    } else {
      const float f = static_cast<float>(d) / static_cast<float>(last_diff_) + 0.5f;
      const int m = f >= 509.0f ? 509 : f < 1.0f ? 0 : static_cast<int>(f);
      enc.encode_symbol(m_multi_, static_cast<std::uint32_t>(m));
      if (m == 1) {
        ic_.compress(enc, last_diff_, d, 1);
        last_diff_ = d;
        extreme_ = 0;
      } else if (m == 0) {
        ic_.compress(enc, last_diff_ / 4, d, 2);
        extreme(d);
      } else {
        const auto pred = static_cast<std::int32_t>(static_cast<std::uint32_t>(m) * static_cast<std::uint32_t>(last_diff_));
        ic_.compress(enc, pred, d, m < 10 ? 3 : m < 50 ? 4 : 5);
        if (m == 509) extreme(d);
      }
    }
    last_ = t;
  }

 private:
  static void write_int64(ArithmeticEncoder& enc, std::int64_t t) {
    const auto u = static_cast<std::uint64_t>(t);
    enc.write_int(static_cast<std::uint32_t>(u));
    enc.write_int(static_cast<std::uint32_t>(u >> 32));
  }
  void extreme(std::int32_t d) {
    if (++extreme_ > 3) last_diff_ = d, extreme_ = 0;
  }
  std::int64_t last_;
  std::int32_t last_diff_ = 0, extreme_ = 0;
  SymbolModel m_multi_{512, false}, m_0diff_{3, false};
  IntegerCompressor ic_{32, 6};
};

/// RGB12 v1 encoder (inverse of laz::Rgb12V1).
class RgbEnc {
 public:
  explicit RgbEnc(const std::uint8_t* first) { std::memcpy(last_, first, 6); }
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    std::uint32_t used = 0;
    for (std::uint32_t b = 0; b < 6; ++b) used |= it[b] != last_[b] ? 1u << b : 0u;
    enc.encode_symbol(m_used_, used);
    for (std::uint32_t b = 0; b < 6; ++b)
      if (used & (1u << b)) ic_.compress(enc, last_[b], it[b], b);
    std::memcpy(last_, it, 6);
  }

 private:
  std::uint8_t last_[6];
  SymbolModel m_used_{64, false};
  IntegerCompressor ic_{8, 6};
};

/// BYTE v1 encoder (inverse of laz::ByteV1).
class ByteEnc {
 public:
  ByteEnc(const std::uint8_t* first, std::size_t n) : last_(first, first + n), ic_(8, static_cast<std::uint32_t>(n)) {}
  void write(ArithmeticEncoder& enc, const std::uint8_t* it) {
    for (std::size_t i = 0; i < last_.size(); ++i) ic_.compress(enc, last_[i], it[i], static_cast<std::uint32_t>(i));
    std::memcpy(last_.data(), it, last_.size());
  }

 private:
  std::vector<std::uint8_t> last_;
  IntegerCompressor ic_;
};

/// One stream of version 1 items (a compressor 1 file's point data, or one compressor 2 chunk):
/// the first record raw, then the arithmetic-coded rest. `n` records of `rec` bytes, PDRF 0-3
/// (GPS time for 1 and 3, RGB for 2 and 3), the bytes past the PDRF's core as one BYTE item.
inline std::vector<std::uint8_t> encode_stream(const std::uint8_t* recs, std::size_t n, std::size_t rec, int pdrf) {
  std::vector<std::uint8_t> out(recs, recs + rec);
  const bool gps = pdrf == 1 || pdrf == 3, rgb = pdrf == 2 || pdrf == 3;
  const std::size_t off_rgb = gps ? 28 : 20, core = off_rgb + (rgb ? 6 : 0);
  Point10Enc p(recs);
  std::unique_ptr<GpsEnc> g = gps ? std::make_unique<GpsEnc>(recs + 20) : nullptr;
  std::unique_ptr<RgbEnc> c = rgb ? std::make_unique<RgbEnc>(recs + off_rgb) : nullptr;
  std::unique_ptr<ByteEnc> b = rec > core ? std::make_unique<ByteEnc>(recs + core, rec - core) : nullptr;
  ArithmeticEncoder enc(out);
  for (std::size_t i = 1; i < n; ++i) {
    const std::uint8_t* r = recs + i * rec;
    p.write(enc, r);
    if (g) g->write(enc, r + 20);
    if (c) c->write(enc, r + off_rgb);
    if (b) b->write(enc, r + core);
  }
  enc.done();
  return out;
}

}  // namespace rayscan::test::lazv1
