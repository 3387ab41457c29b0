// Internal: the encoding side of LASzip's layered-chunked compressor (compressor 3, LAS 1.4 point
// data record formats 6-8): POINT14, RGB14, RGBNIR14 and BYTE14 items of version 3 -- the exact
// inverses of the decoders in items_v3.hpp. Every layer has its own arithmetic encoder writing
// into its own buffer; at the end of a chunk a layer that never changed inside the chunk is
// dropped (size 0, its value is the chunk's first record's), the others are flushed, and the
// chunk is written as: first record raw, uint32 point count, uint32 byte size of every layer, the
// layers. Format reference (read, not copied): LASzip src/laswriteitemcompressed_v3.cpp
// (LASwriteItemCompressed_POINT14_v3 write / write_gps_time / chunk_sizes / chunk_bytes, RGB14,
// RGBNIR14, BYTE14) and src/laswritepoint.cpp (chunk layout, the per-record "context" the
// POINT14 writer hands to the other items). docs/formats.md "LAZ" section 5.
#pragma once

#include "laz/encoder_v2.hpp"
#include "laz/items_v3.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <vector>

namespace rayscan::io::laz {

/// Output side of one layer: its bytes, its encoder, and whether any value it codes changed
/// in the current chunk (LASzip's `changed_*` booleans: an unchanged layer is written as 0 bytes).
struct LayerSink {
  std::vector<std::uint8_t> bytes;
  std::optional<ArithmeticEncoder> enc;
  bool changed = false;

  /// Starts a new chunk: empties the buffer and restarts the encoder.
  void reset() {
    bytes.clear();
    enc.emplace(bytes);
    changed = false;
  }
};

/// N encoder-side symbol models of `Symbols` symbols, created on first use (LASzip creates the
/// models keyed by a previous value lazily; see LazyModels for the decoder side).
template <std::size_t N, std::uint32_t Symbols>
struct LazyEncModels {
  std::array<std::unique_ptr<SymbolModel>, N> m;
  SymbolModel& operator[](std::size_t i) {
    if (!m[i]) m[i] = std::make_unique<SymbolModel>(Symbols, false);
    return *m[i];
  }
};

/// POINT14 v3 encoder over nine layers (0 channel/returns/XY, 1 Z, 2 classification, 3 flags,
/// 4 intensity, 5 scan angle, 6 user data, 7 point source, 8 GPS time), four scanner-channel
/// contexts. `context_out` is the context the other items of the record use (0 unless the
/// channel changed on this record: LASwritePoint::write resets it per record; see items_v3.hpp).
class Point14V3Enc {
 public:
  static constexpr int kLayers = 9;

  /// Starts a chunk whose first (raw) record is `first`; `layers` are the nine sinks, reset.
  void init(const std::uint8_t* first, LayerSink* layers) {
    layers_ = layers;
    for (auto& c : ctx_) c.reset();
    Point14 p;
    p.load(first);
    current_ = p.channel;
    ctx_[current_] = std::make_unique<Context>();
    ctx_[current_]->seed(p);
    context_out = current_;
  }

  /// Encodes the 30-byte PDRF 6 core record `it`.
  void write(const std::uint8_t* it) {
    Point14 p;
    p.load(it);
    Context* c = ctx_[current_].get();
    Point14* last = &c->last;
    const int lpr = (last->ret == 1 ? 1 : 0) + (last->ret >= last->nret ? 2 : 0) + (last->gps_change ? 4 : 0);
    const std::uint32_t ch = p.channel;
    if (ch != current_ && ctx_[ch]) last = &ctx_[ch]->last;
    const bool psid_change = p.psid != last->psid;
    const bool gps_change = p.gps != last->gps;  // bit patterns: lossless for -0.0 and NaN
    const bool angle_change = p.scan_angle != last->scan_angle;
    const std::uint32_t last_n = last->nret, last_r = last->ret;
    const std::uint32_t n = p.nret, r = p.ret;
    std::uint32_t changed = ((ch != current_ ? 1u : 0u) << 6) | ((psid_change ? 1u : 0u) << 5) |
                            ((gps_change ? 1u : 0u) << 4) | ((angle_change ? 1u : 0u) << 3) |
                            ((n != last_n ? 1u : 0u) << 2);
    if (r != last_r) {
      if (r == ((last_r + 1) % 16)) changed |= 1;
      else if (r == ((last_r + 15) % 16)) changed |= 2;
      else changed |= 3;
    }
    ArithmeticEncoder& exy = *layers_[0].enc;
    layers_[0].changed = true;
    exy.encode_symbol(c->m_changed[lpr], changed);
    context_out = 0;
    if (changed & (1u << 6)) {
      exy.encode_symbol(c->m_channel, (ch + 4 - current_ - 1) % 4);  // ch = (current + sym + 1) % 4
      if (!ctx_[ch]) {
        ctx_[ch] = std::make_unique<Context>();
        ctx_[ch]->seed(c->last);
        last = &ctx_[ch]->last;
      }
      current_ = ch;
      context_out = ch;
      c = ctx_[ch].get();
    }
    if (changed & (1u << 2)) exy.encode_symbol(c->m_nret[last_n], n);
    if ((changed & 3) == 3) {
      if (gps_change) exy.encode_symbol(c->m_ret[last_r], r);
      else exy.encode_symbol(c->m_ret_gps_same, (r + 16 - last_r - 2) % 16);  // r = (last_r + sym + 2) % 16
    }
    const std::uint32_t m = kNumberReturnMap6[n][r];
    const int l = number_return_level8(static_cast<int>(n), static_cast<int>(r));
    const int cpr = (r == 1 ? 1 : 0) + (r >= n ? 2 : 0);
    const std::uint32_t mi = (m << 1) | (gps_change ? 1u : 0u);
    std::int32_t diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(p.x) - static_cast<std::uint32_t>(last->x));
    c->ic_dx.compress(exy, c->median_x[mi].get(), diff, n == 1);
    c->median_x[mi].add(diff);
    std::uint32_t kb = c->ic_dx.k();
    diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(p.y) - static_cast<std::uint32_t>(last->y));
    c->ic_dy.compress(exy, c->median_y[mi].get(), diff, (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    c->median_y[mi].add(diff);
    // Z layer (always written, like the XY layer)
    kb = (c->ic_dx.k() + c->ic_dy.k()) / 2;
    layers_[1].changed = true;
    c->ic_z.compress(*layers_[1].enc, c->last_z[l], p.z, (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
    c->last_z[l] = p.z;
    // classification
    if (p.classification != last->classification) layers_[2].changed = true;
    const std::size_t ccc = static_cast<std::size_t>(((last->classification & 0x1F) << 1) + (cpr == 3 ? 1 : 0));
    layers_[2].enc->encode_symbol(c->m_class[ccc], p.classification);
    // flags
    const std::uint32_t last_flags = (static_cast<std::uint32_t>(last->edge) << 5) |
                                     (static_cast<std::uint32_t>(last->scan_dir) << 4) | last->class_flags;
    const std::uint32_t flags = (static_cast<std::uint32_t>(p.edge) << 5) | (static_cast<std::uint32_t>(p.scan_dir) << 4) |
                                p.class_flags;
    if (flags != last_flags) layers_[3].changed = true;
    layers_[3].enc->encode_symbol(c->m_flags[last_flags], flags);
    // intensity
    if (p.intensity != last->intensity) layers_[4].changed = true;
    const std::size_t ii = static_cast<std::size_t>((cpr << 1) | (gps_change ? 1 : 0));
    c->ic_intensity.compress(*layers_[4].enc, c->last_intensity[ii], p.intensity, static_cast<std::uint32_t>(cpr));
    c->last_intensity[ii] = p.intensity;
    // scan angle
    if (angle_change) {
      layers_[5].changed = true;
      c->ic_angle.compress(*layers_[5].enc, last->scan_angle, p.scan_angle, gps_change ? 1 : 0);
    }
    // user data
    if (p.user_data != last->user_data) layers_[6].changed = true;
    layers_[6].enc->encode_symbol(c->m_user[last->user_data / 4], p.user_data);
    // point source
    if (psid_change) {
      layers_[7].changed = true;
      c->ic_psid.compress(*layers_[7].enc, last->psid, p.psid);
    }
    // GPS time
    if (gps_change) {
      layers_[8].changed = true;
      write_gps(*c, *layers_[8].enc, p.gps);
    }
    *last = p;
    last->gps_change = gps_change;
  }

  std::uint32_t context_out = 0;

 private:
  struct Context {
    Point14 last;
    SymbolModel m_changed[8] = {SymbolModel(128, false), SymbolModel(128, false), SymbolModel(128, false),
                                SymbolModel(128, false), SymbolModel(128, false), SymbolModel(128, false),
                                SymbolModel(128, false), SymbolModel(128, false)};
    SymbolModel m_channel{3, false};
    LazyEncModels<16, 16> m_nret, m_ret;
    SymbolModel m_ret_gps_same{13, false};
    IntegerCompressor ic_dx{32, 2}, ic_dy{32, 22}, ic_z{32, 20};
    StreamingMedian5 median_x[12], median_y[12];
    std::int32_t last_z[8] = {};
    LazyEncModels<64, 256> m_class;
    LazyEncModels<64, 64> m_flags;
    LazyEncModels<64, 256> m_user;
    IntegerCompressor ic_intensity{16, 4};
    std::uint16_t last_intensity[8] = {};
    IntegerCompressor ic_angle{16, 2};
    IntegerCompressor ic_psid{16};
    SymbolModel m_gps_multi{Point14V3::kTotal, false}, m_gps_0diff{5, false};
    IntegerCompressor ic_gps{32, 9};
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

  static std::int32_t times(std::int32_t a, std::int32_t b) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
  }
  static void bump(Context& c, std::int32_t d) {
    if (++c.gps_extreme[c.gps_last] > 3) {
      c.gps_diff[c.gps_last] = d;
      c.gps_extreme[c.gps_last] = 0;
    }
  }
  /// Sequence i (1..3) after the current one whose last time is within 32 bits of t, or 0.
  static std::uint32_t other_sequence(const Context& c, std::int64_t t) {
    for (std::uint32_t i = 1; i < 4; ++i) {
      const std::int64_t d = wrap_sub(t, c.gps_time[(c.gps_last + i) & 3]);
      if (d == static_cast<std::int32_t>(d)) return i;
    }
    return 0;
  }
  /// Starts a new sequence with the full 64-bit time (high half predicted, low half raw).
  static void full(Context& c, ArithmeticEncoder& enc, std::int64_t t) {
    const auto u = static_cast<std::uint64_t>(t);
    c.ic_gps.compress(enc, static_cast<std::int32_t>(static_cast<std::uint64_t>(c.gps_time[c.gps_last]) >> 32),
                      static_cast<std::int32_t>(u >> 32), 8);
    enc.write_int(static_cast<std::uint32_t>(u));
    c.gps_next = (c.gps_next + 1) & 3;
    c.gps_last = c.gps_next;
    c.gps_diff[c.gps_last] = 0;
    c.gps_extreme[c.gps_last] = 0;
  }
  /// LASzip write_gps_time of POINT14 v3 (only called when the time changed).
  static void write_gps(Context& c, ArithmeticEncoder& enc, std::int64_t t) {
    constexpr std::int32_t M = Point14V3::kMulti, MM = Point14V3::kMultiMinus;
    for (;;) {
      std::uint32_t& last = c.gps_last;
      const std::int64_t d64 = wrap_sub(t, c.gps_time[last]);
      const bool fits = d64 == static_cast<std::int32_t>(d64);
      if (c.gps_diff[last] == 0) {
        if (fits) {
          enc.encode_symbol(c.m_gps_0diff, 0);
          c.ic_gps.compress(enc, 0, static_cast<std::int32_t>(d64), 0);
          c.gps_diff[last] = static_cast<std::int32_t>(d64);
          c.gps_extreme[last] = 0;
        } else {
          const std::uint32_t other = other_sequence(c, t);
          if (other > 0) {
            enc.encode_symbol(c.m_gps_0diff, other + 1);
            last = (last + other) & 3;
            continue;
          }
          enc.encode_symbol(c.m_gps_0diff, 1);
          full(c, enc, t);
        }
        c.gps_time[last] = t;
        return;
      }
      if (fits) {
        const auto d = static_cast<std::int32_t>(d64);
        const std::int32_t multi = gps_multiplier(d, c.gps_diff[last]);
        if (multi == 1) {
          enc.encode_symbol(c.m_gps_multi, 1);
          c.ic_gps.compress(enc, c.gps_diff[last], d, 1);
          c.gps_extreme[last] = 0;
        } else if (multi > 0) {
          if (multi < M) {
            enc.encode_symbol(c.m_gps_multi, static_cast<std::uint32_t>(multi));
            c.ic_gps.compress(enc, times(multi, c.gps_diff[last]), d, multi < 10 ? 2 : 3);
          } else {
            enc.encode_symbol(c.m_gps_multi, M);
            c.ic_gps.compress(enc, times(M, c.gps_diff[last]), d, 4);
            bump(c, d);
          }
        } else if (multi < 0) {
          if (multi > MM) {
            enc.encode_symbol(c.m_gps_multi, static_cast<std::uint32_t>(M - multi));
            c.ic_gps.compress(enc, times(multi, c.gps_diff[last]), d, 5);
          } else {
            enc.encode_symbol(c.m_gps_multi, static_cast<std::uint32_t>(M - MM));
            c.ic_gps.compress(enc, times(MM, c.gps_diff[last]), d, 6);
            bump(c, d);
          }
        } else {
          enc.encode_symbol(c.m_gps_multi, 0);
          c.ic_gps.compress(enc, 0, d, 7);
          bump(c, d);
        }
      } else {
        const std::uint32_t other = other_sequence(c, t);
        if (other > 0) {
          enc.encode_symbol(c.m_gps_multi, static_cast<std::uint32_t>(Point14V3::kCodeFull) + other);
          last = (last + other) & 3;
          continue;
        }
        enc.encode_symbol(c.m_gps_multi, Point14V3::kCodeFull);
        full(c, enc, t);
      }
      c.gps_time[last] = t;
      return;
    }
  }

  LayerSink* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::unique_ptr<Context> ctx_[4];
};

/// Encodes one RGB triple (RGB12 v2 / RGB14 v3 scheme: 7-bit "which bytes changed" mask, green
/// and blue predicted from red's change) against `last`; returns the mask (0: nothing coded
/// but the mask). Reference: laswriteitemcompressed_v3.cpp RGB14 write.
inline std::uint32_t write_rgb_v3(ArithmeticEncoder& enc, SymbolModel& m_used, SymbolModel* m_diff,
                                  const std::uint16_t* last, const std::uint16_t* c) {
  std::uint32_t sym = ((last[0] & 0x00FF) != (c[0] & 0x00FF) ? 1u : 0u);
  sym |= ((last[0] & 0xFF00) != (c[0] & 0xFF00) ? 1u : 0u) << 1;
  sym |= ((last[1] & 0x00FF) != (c[1] & 0x00FF) ? 1u : 0u) << 2;
  sym |= ((last[1] & 0xFF00) != (c[1] & 0xFF00) ? 1u : 0u) << 3;
  sym |= ((last[2] & 0x00FF) != (c[2] & 0x00FF) ? 1u : 0u) << 4;
  sym |= ((last[2] & 0xFF00) != (c[2] & 0xFF00) ? 1u : 0u) << 5;
  sym |= (((c[0] & 0x00FF) != (c[1] & 0x00FF)) || ((c[0] & 0x00FF) != (c[2] & 0x00FF)) ||
          ((c[0] & 0xFF00) != (c[1] & 0xFF00)) || ((c[0] & 0xFF00) != (c[2] & 0xFF00)) ? 1u : 0u) << 6;
  enc.encode_symbol(m_used, sym);
  int dl = 0, dh = 0;
  if (sym & 1) {
    dl = (c[0] & 255) - (last[0] & 255);
    enc.encode_symbol(m_diff[0], u8_fold(dl));
  }
  if (sym & 2) {
    dh = (c[0] >> 8) - (last[0] >> 8);
    enc.encode_symbol(m_diff[1], u8_fold(dh));
  }
  if (sym & 64) {
    if (sym & 4) enc.encode_symbol(m_diff[2], u8_fold((c[1] & 255) - u8_clamp(dl + (last[1] & 255))));
    if (sym & 16) {
      dl = (dl + (c[1] & 255) - (last[1] & 255)) / 2;
      enc.encode_symbol(m_diff[4], u8_fold((c[2] & 255) - u8_clamp(dl + (last[2] & 255))));
    }
    if (sym & 8) enc.encode_symbol(m_diff[3], u8_fold((c[1] >> 8) - u8_clamp(dh + (last[1] >> 8))));
    if (sym & 32) {
      dh = (dh + (c[1] >> 8) - (last[1] >> 8)) / 2;
      enc.encode_symbol(m_diff[5], u8_fold((c[2] >> 8) - u8_clamp(dh + (last[2] >> 8))));
    }
  }
  return sym;
}

/// RGB14 (one layer) or RGBNIR14 (two layers: RGB, NIR) v3 encoder, per channel context.
/// Mirrors RgbNir14V3 including v3's context quirk: switching back to a context already in use
/// keeps reading and writing the previous context's record for that one record.
class RgbNir14V3Enc {
 public:
  explicit RgbNir14V3Enc(bool nir) : nir_(nir) {}

  /// Starts a chunk whose first record's colour is `first` (6 or 8 bytes).
  void init(const std::uint8_t* first, LayerSink* layers, std::uint32_t context) {
    layers_ = layers;
    for (auto& c : ctx_) c.reset();
    current_ = context;
    ctx_[current_] = std::make_unique<Context>();
    std::memcpy(ctx_[current_]->last, first, nir_ ? 8 : 6);
  }
  /// Encodes the colour `it` of the next record, in the context POINT14 chose for it.
  void write(const std::uint8_t* it, std::uint32_t context) {
    std::uint16_t* last = ctx_[current_]->last;
    if (context != current_) {
      current_ = context;
      if (!ctx_[current_]) {
        ctx_[current_] = std::make_unique<Context>();
        std::memcpy(ctx_[current_]->last, last, 8);
        last = ctx_[current_]->last;
      }
    }
    Context& c = *ctx_[current_];
    std::uint16_t v[4] = {};
    std::memcpy(v, it, nir_ ? 8 : 6);
    if (write_rgb_v3(*layers_[0].enc, c.m_used, c.m_diff, last, v) != 0) layers_[0].changed = true;
    if (nir_) {
      ArithmeticEncoder& en = *layers_[1].enc;
      const std::uint32_t sym = ((last[3] & 0x00FF) != (v[3] & 0x00FF) ? 1u : 0u) |
                                ((last[3] & 0xFF00) != (v[3] & 0xFF00) ? 2u : 0u);
      en.encode_symbol(c.m_nir_used, sym);
      if (sym & 1) en.encode_symbol(c.m_nir_diff[0], u8_fold((v[3] & 255) - (last[3] & 255)));
      if (sym & 2) en.encode_symbol(c.m_nir_diff[1], u8_fold((v[3] >> 8) - (last[3] >> 8)));
      if (sym != 0) layers_[1].changed = true;
    }
    std::memcpy(last, v, nir_ ? 8 : 6);
  }

 private:
  struct Context {
    std::uint16_t last[4] = {};
    SymbolModel m_used{128, false};
    SymbolModel m_diff[6] = {SymbolModel(256, false), SymbolModel(256, false), SymbolModel(256, false),
                             SymbolModel(256, false), SymbolModel(256, false), SymbolModel(256, false)};
    SymbolModel m_nir_used{4, false};
    SymbolModel m_nir_diff[2] = {SymbolModel(256, false), SymbolModel(256, false)};
  };
  bool nir_;
  LayerSink* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::unique_ptr<Context> ctx_[4];
};

/// BYTE14 v3 encoder: n extra bytes, one layer each, per channel context.
class Byte14V3Enc {
 public:
  explicit Byte14V3Enc(std::size_t n) : n_(n) {}

  /// Starts a chunk whose first record's extra bytes are `first`.
  void init(const std::uint8_t* first, LayerSink* layers, std::uint32_t context) {
    layers_ = layers;
    for (auto& c : ctx_) c.reset();
    current_ = context;
    ctx_[current_] = std::make_unique<Context>(n_);
    std::memcpy(ctx_[current_]->last.data(), first, n_);
  }
  /// Encodes the extra bytes `it` of the next record, in the context POINT14 chose for it.
  void write(const std::uint8_t* it, std::uint32_t context) {
    std::uint8_t* last = ctx_[current_]->last.data();
    if (context != current_) {
      current_ = context;
      if (!ctx_[current_]) {
        ctx_[current_] = std::make_unique<Context>(n_);
        std::memcpy(ctx_[current_]->last.data(), last, n_);
        last = ctx_[current_]->last.data();
      }
    }
    Context& c = *ctx_[current_];
    for (std::size_t i = 0; i < n_; ++i) {
      layers_[i].enc->encode_symbol(c.models[i], u8_fold(it[i] - last[i]));
      if (it[i] != last[i]) {
        layers_[i].changed = true;
        last[i] = it[i];
      }
    }
  }

 private:
  struct Context {
    explicit Context(std::size_t n) : last(n), models(n, SymbolModel(256, false)) {}
    std::vector<std::uint8_t> last;
    std::vector<SymbolModel> models;
  };
  std::size_t n_;
  LayerSink* layers_ = nullptr;
  std::uint32_t current_ = 0;
  std::unique_ptr<Context> ctx_[4];
};

/// Compresses `n` (>= 1) records of `rec` bytes (PDRF `pdrf` 6, 7 or 8 followed by `extra`
/// bytes) into one layered chunk appended to `out`: the first record raw, the uint32 point
/// count, the uint32 size of every layer (9 POINT14, 1 RGB14 or 2 RGBNIR14, one per extra byte),
/// then the layers (LASzip laswritepoint.cpp chunk(): chunk_sizes() then chunk_bytes() of every
/// item in item order). Reusable across chunks (the buffers keep their capacity).
class LayeredChunkEncoder {
 public:
  /// Encoder for point data record format `pdrf` (6, 7 or 8) with `extra` bytes per record.
  LayeredChunkEncoder(int pdrf, std::size_t extra) : pdrf_(pdrf) {
    std::size_t n = Point14V3Enc::kLayers;
    if (pdrf == 7) n += 1;
    if (pdrf == 8) n += 2;
    n += extra;
    sinks_.resize(n);
    if (pdrf == 7 || pdrf == 8) rgb_.emplace(pdrf == 8);
    if (extra > 0) bytes_.emplace(extra);
  }

  /// Appends the chunk of records recs[0, n * rec) (n >= 1, rec = 30/36/38 + extra bytes) to
  /// `out`. Never throws for any field values (all coder arithmetic wraps in unsigned).
  void encode(const std::uint8_t* recs, std::size_t n, std::size_t rec, std::vector<std::uint8_t>& out) {
    out.insert(out.end(), recs, recs + rec);
    for (LayerSink& s : sinks_) s.reset();
    const std::size_t color_bytes = pdrf_ == 7 ? 6 : pdrf_ == 8 ? 8 : 0;
    const std::size_t first_rgb = Point14V3Enc::kLayers, first_byte = first_rgb + (pdrf_ == 7 ? 1 : pdrf_ == 8 ? 2 : 0);
    point_.init(recs, sinks_.data());
    std::uint32_t ctx = point_.context_out;
    if (rgb_) rgb_->init(recs + 30, sinks_.data() + first_rgb, ctx);
    if (bytes_) bytes_->init(recs + 30 + color_bytes, sinks_.data() + first_byte, ctx);
    for (std::size_t i = 1; i < n; ++i) {
      const std::uint8_t* r = recs + i * rec;
      point_.write(r);
      ctx = point_.context_out;
      if (rgb_) rgb_->write(r + 30, ctx);
      if (bytes_) bytes_->write(r + 30 + color_bytes, ctx);
    }
    // LASzip flushes XY and Z always, the other layers only when they changed
    sinks_[0].changed = sinks_[1].changed = true;
    const auto count = static_cast<std::uint32_t>(n);
    append_u32(out, count);
    for (LayerSink& s : sinks_) {
      s.enc->done();
      append_u32(out, s.changed ? static_cast<std::uint32_t>(s.bytes.size()) : 0u);
    }
    for (const LayerSink& s : sinks_)
      if (s.changed) out.insert(out.end(), s.bytes.begin(), s.bytes.end());
  }

 private:
  static void append_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
    const std::size_t at = out.size();
    out.resize(at + 4);
    std::memcpy(out.data() + at, &v, 4);
  }
  int pdrf_;
  std::vector<LayerSink> sinks_;
  Point14V3Enc point_;
  std::optional<RgbNir14V3Enc> rgb_;
  std::optional<Byte14V3Enc> bytes_;
};

}  // namespace rayscan::io::laz
