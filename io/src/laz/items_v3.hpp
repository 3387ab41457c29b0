// Internal: LASzip item decoders of versions 3/4 (layered-chunked compressor, LAS 1.4 point data
// record formats 6-10): POINT14 (item type 10, 30 bytes, nine layers), RGB14 (11, 6 bytes, one
// layer), RGBNIR14 (12, 8 bytes, two layers), BYTE14 (14, n bytes, one layer per byte). Each
// layer has its own arithmetic decoder over its own byte range, so a layer that is not asked for
// is skipped without decoding ("selective decompression"); its field keeps the chunk's first
// value. State is kept per scanner channel (four contexts). Format reference (read, not
// copied): LASzip src/lasreaditemcompressed_v3.cpp / _v4.cpp (POINT14 read/read_gps_time,
// RGB14, RGBNIR14, BYTE14, createAndInitModelsAndDecompressors) and src/lasreadpoint.cpp (chunk
// layout); laz-perf cpp/lazperf/detail/field_point14.hpp, field_rgb14.hpp, field_nir14.hpp,
// field_byte14.hpp. docs/formats.md "LAZ" section 3.
#pragma once

#include "laz/items_v2.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace rayscan::io::laz {

/// Layers a caller may ask for (bit mask). XY and the return numbers are always decoded.
enum Layer : std::uint32_t {
  kLayerZ = 1u << 0,
  kLayerClassification = 1u << 1,
  kLayerFlags = 1u << 2,
  kLayerIntensity = 1u << 3,
  kLayerScanAngle = 1u << 4,
  kLayerUserData = 1u << 5,
  kLayerPointSource = 1u << 6,
  kLayerGpsTime = 1u << 7,
  kLayerRgb = 1u << 8,
  kLayerNir = 1u << 9,
  kLayerExtraBytes = 1u << 10,
  kLayerAll = 0xFFFFFFFFu,
};

/// One byte range of a chunk and whether it is decoded.
struct LayerStream {
  ArithmeticDecoder dec;
  bool active = false;  ///< requested and non-empty
};

/// Return-number context tables of POINT14 (LASzip lasreaditemcompressed_v3.cpp).
inline constexpr std::uint8_t kNumberReturnMap6[16][16] = {
    {0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5}, {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
    {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3}, {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
    {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};
/// min(|n - r|, 7): the "level" context of z.
inline int number_return_level8(int n, int r) {
  const int d = n > r ? n - r : r - n;
  return d < 7 ? d : 7;
}

/// The fields of a PDRF 6 core record (LAS 1.4 R15 table 13) as POINT14 tracks them.
struct Point14 {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint8_t ret = 0, nret = 0;        // 4 bits each
  std::uint8_t class_flags = 0, channel = 0, scan_dir = 0, edge = 0;
  std::uint8_t classification = 0, user_data = 0;
  std::int16_t scan_angle = 0;
  std::uint16_t psid = 0;
  std::int64_t gps = 0;  // bit pattern of the float64 GPS time
  bool gps_change = false;

  void load(const std::uint8_t* p) {
    std::memcpy(&x, p, 4);
    std::memcpy(&y, p + 4, 4);
    std::memcpy(&z, p + 8, 4);
    std::memcpy(&intensity, p + 12, 2);
    ret = p[14] & 0x0F;
    nret = p[14] >> 4;
    class_flags = p[15] & 0x0F;
    channel = (p[15] >> 4) & 3;
    scan_dir = (p[15] >> 6) & 1;
    edge = p[15] >> 7;
    classification = p[16];
    user_data = p[17];
    std::memcpy(&scan_angle, p + 18, 2);
    std::memcpy(&psid, p + 20, 2);
    std::memcpy(&gps, p + 22, 8);
  }
  void store(std::uint8_t* p) const {
    std::memcpy(p, &x, 4);
    std::memcpy(p + 4, &y, 4);
    std::memcpy(p + 8, &z, 4);
    std::memcpy(p + 12, &intensity, 2);
    p[14] = static_cast<std::uint8_t>((ret & 0x0F) | (nret << 4));
    p[15] = static_cast<std::uint8_t>((class_flags & 0x0F) | ((channel & 3) << 4) | ((scan_dir & 1) << 6) | (edge << 7));
    p[16] = classification;
    p[17] = user_data;
    std::memcpy(p + 18, &scan_angle, 2);
    std::memcpy(p + 20, &psid, 2);
    std::memcpy(p + 22, &gps, 8);
  }
};

/// POINT14 v3/v4: nine layers (0 channel/returns/XY, 1 Z, 2 classification, 3 flags,
/// 4 intensity, 5 scan angle, 6 user data, 7 point source, 8 GPS time).
class Point14V3 {
 public:
  static constexpr int kLayers = 9;
  static constexpr int kMulti = 500, kMultiMinus = -10;
  static constexpr int kCodeFull = kMulti - kMultiMinus + 1;  // 511
  static constexpr int kTotal = kMulti - kMultiMinus + 5;     // 515

  explicit Point14V3(int version) : version_(version) {}

  /// Seeds the channel context of the chunk's first (raw) record. `layers` are the nine streams.
  void init(const std::uint8_t* first, LayerStream* layers) {
    layers_ = layers;
    Point14 p;
    p.load(first);
    current_ = p.channel;
    ctx_[current_] = std::make_unique<Context>();
    ctx_[current_]->seed(p);
    context_out = current_;
  }

  /// Decodes the next record into out[0..30). Sets `context_out` to the channel context the
  /// other items of this record use (LASzip v3 quirk: 0 unless the channel changed, see
  /// docs/formats.md; v4: the current channel).
  void read(std::uint8_t* out) {
    Context* c = ctx_[current_].get();
    Point14* last = &c->last;
    ArithmeticDecoder& dxy = layers_[0].dec;
    int lpr = (last->ret == 1 ? 1 : 0) + (last->ret >= last->nret ? 2 : 0) + (last->gps_change ? 4 : 0);
    const std::uint32_t changed = dxy.decode_symbol(c->m_changed[lpr]);
    context_out = version_ >= 4 ? current_ : 0;
    if (changed & (1u << 6)) {
      const std::uint32_t diff = dxy.decode_symbol(c->m_channel);
      const std::uint32_t ch = (current_ + diff + 1) % 4;
      if (!ctx_[ch]) {
        ctx_[ch] = std::make_unique<Context>();
        ctx_[ch]->seed(c->last);
      }
      current_ = ch;
      context_out = current_;
      c = ctx_[current_].get();
      last = &c->last;
      last->channel = static_cast<std::uint8_t>(ch);
    }
    const bool psid_change = changed & (1u << 5);
    const bool gps_change = changed & (1u << 4);
    const bool angle_change = changed & (1u << 3);
    const std::uint32_t last_n = last->nret, last_r = last->ret;
    std::uint32_t n = last_n;
    if (changed & (1u << 2)) {
      n = dxy.decode_symbol(c->m_nret[last_n]);
      last->nret = static_cast<std::uint8_t>(n);
    }
    std::uint32_t r;
    switch (changed & 3) {
      case 0: r = last_r; break;
      case 1: r = (last_r + 1) % 16; break;
      case 2: r = (last_r + 15) % 16; break;
      default:
        if (gps_change) r = dxy.decode_symbol(c->m_ret[last_r]);
        else r = (last_r + dxy.decode_symbol(c->m_ret_gps_same) + 2) % 16;
        break;
    }
    last->ret = static_cast<std::uint8_t>(r);
    const std::uint32_t m = kNumberReturnMap6[n][r];
    const int l = number_return_level8(static_cast<int>(n), static_cast<int>(r));
    const int cpr = (r == 1 ? 1 : 0) + (r >= n ? 2 : 0);
    const std::uint32_t mi = (m << 1) | (gps_change ? 1u : 0u);
    std::int32_t diff = c->ic_dx.decompress(dxy, c->median_x[mi].get(), n == 1);
    last->x = static_cast<std::int32_t>(static_cast<std::uint32_t>(last->x) + static_cast<std::uint32_t>(diff));
    c->median_x[mi].add(diff);
    std::uint32_t kb = c->ic_dx.k();
    diff = c->ic_dy.decompress(dxy, c->median_y[mi].get(), (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    last->y = static_cast<std::int32_t>(static_cast<std::uint32_t>(last->y) + static_cast<std::uint32_t>(diff));
    c->median_y[mi].add(diff);
    if (layers_[1].active) {
      kb = (c->ic_dx.k() + c->ic_dy.k()) / 2;
      last->z = c->ic_z.decompress(layers_[1].dec, c->last_z[l], (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
      c->last_z[l] = last->z;
    }
    if (layers_[2].active) {
      const std::size_t ccc = static_cast<std::size_t>(((last->classification & 0x1F) << 1) + (cpr == 3 ? 1 : 0));
      last->classification = static_cast<std::uint8_t>(layers_[2].dec.decode_symbol(c->m_class[ccc]));
    }
    if (layers_[3].active) {
      const std::size_t lf = static_cast<std::size_t>((last->edge << 5) | (last->scan_dir << 4) | last->class_flags);
      const std::uint32_t f = layers_[3].dec.decode_symbol(c->m_flags[lf]);
      last->edge = (f >> 5) & 1;
      last->scan_dir = (f >> 4) & 1;
      last->class_flags = f & 0x0F;
    }
    if (layers_[4].active) {
      const std::size_t ii = static_cast<std::size_t>((cpr << 1) | (gps_change ? 1 : 0));
      const auto v = static_cast<std::uint16_t>(c->ic_intensity.decompress(layers_[4].dec, c->last_intensity[ii], static_cast<std::uint32_t>(cpr)));
      c->last_intensity[ii] = v;
      last->intensity = v;
    }
    if (layers_[5].active && angle_change)
      last->scan_angle = static_cast<std::int16_t>(c->ic_angle.decompress(layers_[5].dec, last->scan_angle, gps_change));
    if (layers_[6].active)
      last->user_data = static_cast<std::uint8_t>(layers_[6].dec.decode_symbol(c->m_user[last->user_data / 4]));
    if (layers_[7].active && psid_change)
      last->psid = static_cast<std::uint16_t>(c->ic_psid.decompress(layers_[7].dec, last->psid));
    if (layers_[8].active && gps_change) {
      read_gps(*c, layers_[8].dec);
      last->gps = c->gps_time[c->gps_last];
    }
    last->store(out);
    last->gps_change = gps_change;
  }

  std::uint32_t context_out = 0;

 private:
  struct Context {
    Point14 last;
    SymbolModel m_changed[8] = {SymbolModel(128), SymbolModel(128), SymbolModel(128), SymbolModel(128),
                                SymbolModel(128), SymbolModel(128), SymbolModel(128), SymbolModel(128)};
    SymbolModel m_channel{3};
    LazyModels<16, 16> m_nret, m_ret;
    SymbolModel m_ret_gps_same{13};
    IntegerDecompressor ic_dx{32, 2}, ic_dy{32, 22}, ic_z{32, 20};
    StreamingMedian5 median_x[12], median_y[12];
    std::int32_t last_z[8] = {};
    LazyModels<64, 256> m_class;
    LazyModels<64, 64> m_flags;
    LazyModels<64, 256> m_user;
    IntegerDecompressor ic_intensity{16, 4};
    std::uint16_t last_intensity[8] = {};
    IntegerDecompressor ic_angle{16, 2};
    IntegerDecompressor ic_psid{16};
    SymbolModel m_gps_multi{kTotal}, m_gps_0diff{5};
    IntegerDecompressor ic_gps{32, 9};
    std::uint32_t gps_last = 0, gps_next = 0;
    std::int64_t gps_time[4] = {};
    std::int32_t gps_diff[4] = {};
    std::int32_t gps_extreme[4] = {};

    void seed(const Point14& p) {
      last = p;
      last.gps_change = false;
      for (std::int32_t& z : last_z) z = p.z;
      for (std::uint16_t& i : last_intensity) i = p.intensity;
      gps_time[0] = p.gps;
    }
  };

  static std::int32_t times(int a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
  }
  static void bump(Context& c, std::int32_t d) {
    if (++c.gps_extreme[c.gps_last] > 3) {
      c.gps_diff[c.gps_last] = d;
      c.gps_extreme[c.gps_last] = 0;
    }
  }
  static void full(Context& c, ArithmeticDecoder& dec) {
    c.gps_next = (c.gps_next + 1) & 3;
    const auto hi = static_cast<std::uint32_t>(c.ic_gps.decompress(
        dec, static_cast<std::int32_t>(static_cast<std::uint64_t>(c.gps_time[c.gps_last]) >> 32), 8));
    c.gps_time[c.gps_next] = static_cast<std::int64_t>((static_cast<std::uint64_t>(hi) << 32) | dec.read_int());
    c.gps_last = c.gps_next;
    c.gps_diff[c.gps_last] = 0;
    c.gps_extreme[c.gps_last] = 0;
  }
  /// GPS time of POINT14: GPSTIME11's scheme without the "unchanged" code (that is the
  /// gps_time_change bit of the changed-values symbol), so the codes shift down by one.
  static void read_gps(Context& c, ArithmeticDecoder& dec) {
    for (;;) {
      std::uint32_t& last = c.gps_last;
      if (c.gps_diff[last] == 0) {
        const std::uint32_t multi = dec.decode_symbol(c.m_gps_0diff);
        if (multi == 0) {
          c.gps_diff[last] = c.ic_gps.decompress(dec, 0, 0);
          c.gps_time[last] = wrap_add(c.gps_time[last], c.gps_diff[last]);
          c.gps_extreme[last] = 0;
        } else if (multi == 1) {
          full(c, dec);
        } else {
          last = (last + multi - 1) & 3;
          continue;
        }
      } else {
        int multi = static_cast<int>(dec.decode_symbol(c.m_gps_multi));
        if (multi == 1) {
          c.gps_time[last] = wrap_add(c.gps_time[last], c.ic_gps.decompress(dec, c.gps_diff[last], 1));
          c.gps_extreme[last] = 0;
        } else if (multi < kCodeFull) {
          std::int32_t d;
          if (multi == 0) {
            d = c.ic_gps.decompress(dec, 0, 7);
            bump(c, d);
          } else if (multi < kMulti) {
            d = c.ic_gps.decompress(dec, times(multi, c.gps_diff[last]), multi < 10 ? 2 : 3);
          } else if (multi == kMulti) {
            d = c.ic_gps.decompress(dec, times(kMulti, c.gps_diff[last]), 4);
            bump(c, d);
          } else {
            multi = kMulti - multi;
            if (multi > kMultiMinus) {
              d = c.ic_gps.decompress(dec, times(multi, c.gps_diff[last]), 5);
            } else {
              d = c.ic_gps.decompress(dec, times(kMultiMinus, c.gps_diff[last]), 6);
              bump(c, d);
            }
          }
          c.gps_time[last] = wrap_add(c.gps_time[last], d);
        } else if (multi == kCodeFull) {
          full(c, dec);
        } else {
          last = (last + static_cast<std::uint32_t>(multi - kCodeFull)) & 3;
          continue;
        }
      }
      return;
    }
  }

  int version_;
  LayerStream* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::unique_ptr<Context> ctx_[4];
};

/// RGB14 (one layer) or RGBNIR14 (two layers: RGB, NIR) v3/v4, per channel context.
class RgbNir14V3 {
 public:
  RgbNir14V3(bool nir, int version) : nir_(nir), version_(version) {}

  void init(const std::uint8_t* first, LayerStream* layers, std::uint32_t context) {
    layers_ = layers;
    current_ = context;
    ctx_[current_] = std::make_unique<Context>();
    std::memcpy(ctx_[current_]->last, first, nir_ ? 8 : 6);
    last_ = ctx_[current_]->last;
  }
  void read(std::uint8_t* out, std::uint32_t context) {
    std::uint16_t* last = ctx_[current_]->last;
    if (context != current_) {
      current_ = context;
      if (!ctx_[current_]) {
        ctx_[current_] = std::make_unique<Context>();
        std::memcpy(ctx_[current_]->last, last, 8);
        last = ctx_[current_]->last;
      } else if (version_ >= 4) {
        last = ctx_[current_]->last;
      }
      // v3 keeps reading and writing the previous context's record when switching back to a
      // context already in use (LASzip lasreaditemcompressed_v3.cpp RGB14::read).
    }
    Context& c = *ctx_[current_];
    std::uint16_t o[4];
    if (layers_[0].active) {
      read_rgb_v2(layers_[0].dec, c.m_used, c.m_diff, last, o);
    } else {
      std::memcpy(o, last, 6);
    }
    if (nir_) {
      if (layers_[1].active) {
        const std::uint32_t sym = layers_[1].dec.decode_symbol(c.m_nir_used);
        std::uint16_t v;
        if (sym & 1) v = u8_fold(static_cast<int>(layers_[1].dec.decode_symbol(c.m_nir_diff[0])) + (last[3] & 0xFF));
        else v = last[3] & 0xFF;
        if (sym & 2) v |= static_cast<std::uint16_t>(u8_fold(static_cast<int>(layers_[1].dec.decode_symbol(c.m_nir_diff[1])) + (last[3] >> 8)) << 8);
        else v |= last[3] & 0xFF00;
        last[3] = v;
      }
      o[3] = last[3];
    }
    std::memcpy(out, o, nir_ ? 8 : 6);
  }

 private:
  struct Context {
    std::uint16_t last[4] = {};
    SymbolModel m_used{128};
    SymbolModel m_diff[6] = {SymbolModel(256), SymbolModel(256), SymbolModel(256),
                             SymbolModel(256), SymbolModel(256), SymbolModel(256)};
    SymbolModel m_nir_used{4};
    SymbolModel m_nir_diff[2] = {SymbolModel(256), SymbolModel(256)};
  };
  bool nir_;
  int version_;
  LayerStream* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::uint16_t* last_ = nullptr;
  std::unique_ptr<Context> ctx_[4];
};

/// BYTE14 v3/v4: n extra bytes, one layer each, per channel context.
class Byte14V3 {
 public:
  Byte14V3(std::size_t n, int version) : n_(n), version_(version) {}

  void init(const std::uint8_t* first, LayerStream* layers, std::uint32_t context) {
    layers_ = layers;
    current_ = context;
    ctx_[current_] = std::make_unique<Context>(n_);
    std::memcpy(ctx_[current_]->last.data(), first, n_);
  }
  void read(std::uint8_t* out, std::uint32_t context) {
    std::uint8_t* last = ctx_[current_]->last.data();
    if (context != current_) {
      current_ = context;
      if (!ctx_[current_]) {
        ctx_[current_] = std::make_unique<Context>(n_);
        std::memcpy(ctx_[current_]->last.data(), last, n_);
        last = ctx_[current_]->last.data();
      } else if (version_ >= 4) {
        last = ctx_[current_]->last.data();
      }
    }
    Context& c = *ctx_[current_];
    for (std::size_t i = 0; i < n_; ++i) {
      if (layers_[i].active) last[i] = u8_fold(last[i] + static_cast<int>(layers_[i].dec.decode_symbol(c.models[i])));
      out[i] = last[i];
    }
  }

 private:
  struct Context {
    explicit Context(std::size_t n) : last(n), models(n, SymbolModel(256)) {}
    std::vector<std::uint8_t> last;
    std::vector<SymbolModel> models;
  };
  std::size_t n_;
  int version_;
  LayerStream* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::unique_ptr<Context> ctx_[4];
};

}  // namespace rayscan::io::laz
