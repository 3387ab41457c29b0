// LAZ container and chunk decoding; see laz.hpp. Sections cited are of docs/formats.md "LAZ".
#include "laz/laz.hpp"

#include <algorithm>
#include <optional>

#include <tbb/parallel_for.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace rayscan::io::laz {

namespace {

std::string item_name(std::uint16_t t) {
  switch (t) {
    case kByte: return "BYTE";
    case kPoint10: return "POINT10";
    case kGpsTime11: return "GPSTIME11";
    case kRgb12: return "RGB12";
    case kWavePacket13: return "WAVEPACKET13";
    case kPoint14: return "POINT14";
    case kRgb14: return "RGB14";
    case kRgbNir14: return "RGBNIR14";
    case kWavePacket14: return "WAVEPACKET14";
    case kByte14: return "BYTE14";
    default: return "type " + std::to_string(t);
  }
}

/// Upper bound on points per compressed byte: every record costs at least the "changed values"
/// symbol of a 64- or 128-symbol model whose 15-bit distribution never gives a symbol less than
/// 1/32768, i.e. >= 63/32768 * log2(e) = 2.8e-3 bits, so <= ~2900 points per byte. 8192 leaves
/// margin; it only serves to refuse absurd counts before allocating.
constexpr std::uint64_t kMaxPointsPerByte = 8192;

}  // namespace

std::size_t LaszipVlr::record_length() const {
  std::size_t s = 0;
  for (const Item& it : items) s += it.size;
  return s;
}

LaszipVlr parse_laszip_vlr(const std::uint8_t* p, std::uint64_t len, const std::string& name,
                           std::uint64_t offset, int pdrf, std::size_t record_length) {
  using detail::fail_at;
  using detail::load_le;
  if (len < 34)
    fail_at(name, offset, "LASzip VLR of " + std::to_string(len) + " bytes (expected at least 34)");
  LaszipVlr v;
  v.compressor = load_le<std::uint16_t>(p);
  v.coder = load_le<std::uint16_t>(p + 2);
  v.version_major = p[4];
  v.version_minor = p[5];
  v.revision = load_le<std::uint16_t>(p + 6);
  v.options = load_le<std::uint32_t>(p + 8);
  v.chunk_size = load_le<std::uint32_t>(p + 12);
  v.special_evlrs = load_le<std::int64_t>(p + 16);
  v.special_evlr_offset = load_le<std::int64_t>(p + 24);
  const std::uint16_t n = load_le<std::uint16_t>(p + 32);
  if (34 + 6ull * n > len)
    fail_at(name, offset + 32, "LASzip VLR lists " + std::to_string(n) + " items but holds only " +
                                   std::to_string(len) + " bytes");
  if (v.compressor < 1 || v.compressor > 3)
    fail_at(name, offset, "LASzip compressor " + std::to_string(v.compressor) +
                              " (expected 1 pointwise, 2 pointwise-chunked or 3 layered-chunked)");
  if (v.coder != 0) fail_at(name, offset + 2, "LASzip coder " + std::to_string(v.coder) + " (expected 0, arithmetic)");
  // Compressor 1 has no chunks: LASreadPoint::setup (lasreadpoint.cpp) ignores the chunk size
  // (LASzip 1.0 wrote 1, 1.2 wrote 0). For compressors 2 and 3 it keeps "variable" (U32_MAX) when
  // the field is 0, so a 0 there means chunk sizes from the table (variable_chunks()).
  int last_rank = -1;  // pointwise items in record order: POINT10, GPSTIME11, RGB12, BYTE
  for (std::uint16_t i = 0; i < n; ++i) {
    Item it{load_le<std::uint16_t>(p + 34 + 6 * i), load_le<std::uint16_t>(p + 36 + 6 * i),
            load_le<std::uint16_t>(p + 38 + 6 * i)};
    const std::uint64_t at = offset + 34 + 6ull * i;
    const bool layered = v.compressor == 3;
    auto bad = [&](const std::string& why) {
      fail_at(name, at, "LASzip item " + std::to_string(i) + " (" + item_name(it.type) + " version " +
                            std::to_string(it.version) + ", " + std::to_string(it.size) + " bytes): " + why);
    };
    // a combination of compressor, item type and item version this decoder has no coder for
    auto unsupported = [&](const std::string& why) {
      fail_at(name, at, "LASzip item " + std::to_string(i) + ": compressor " + std::to_string(v.compressor) +
                            " with item " + item_name(it.type) + " version " + std::to_string(it.version) +
                            " is not supported (" + why + ")");
    };
    const bool v2item = it.type == kByte || it.type == kPoint10 || it.type == kGpsTime11 || it.type == kRgb12;
    const bool v3item = it.type == kPoint14 || it.type == kRgb14 || it.type == kRgbNir14 || it.type == kByte14;
    if (it.type == kWavePacket13 || it.type == kWavePacket14)
      unsupported("waveform packets, PDRF 4/5/9/10 LAZ");
    if (!v2item && !v3item) bad("unknown item type");
    if (v2item && layered)
      unsupported("LAS 1.0-1.3 items are coded by the pointwise compressors 1 and 2");
    if (v3item && !layered)
      unsupported("LAS 1.4 items are coded by the layered-chunked compressor 3");
    if (v2item && it.version != 1 && it.version != 2)
      unsupported(it.version == 0 ? "version 0 marks an uncompressed item" : "expected version 1 or 2");
    if (v3item && it.version != 3 && it.version != 4) unsupported("expected version 3 or 4");
    const int want = it.type == kPoint10 ? 20 : it.type == kGpsTime11 ? 8 : it.type == kRgb12 ? 6
                   : it.type == kPoint14 ? 30 : it.type == kRgb14 ? 6 : it.type == kRgbNir14 ? 8 : -1;
    if (want > 0 && it.size != want) bad("expected " + std::to_string(want) + " bytes");
    if (want < 0 && it.size == 0) bad("zero extra bytes");
    if (i == 0 && it.type != kPoint10 && it.type != kPoint14) bad("the first item must be POINT10 or POINT14");
    if (i > 0 && (it.type == kPoint10 || it.type == kPoint14)) bad("a second point item");
    if (v2item) {  // the pointwise decoder keeps one coder per kind and decodes them in this order
      const int rank = it.type == kPoint10 ? 0 : it.type == kGpsTime11 ? 1 : it.type == kRgb12 ? 2 : 3;
      if (rank <= last_rank)
        bad("out of order or repeated (LAS 1.0-1.3 records hold POINT10, GPSTIME11, RGB12, then BYTE)");
      last_rank = rank;
    }
    v.items.push_back(it);
  }
  if (v.items.empty()) fail_at(name, offset + 32, "LASzip VLR lists no items");
  if (v.record_length() != record_length)
    fail_at(name, offset + 34, "LASzip items add up to " + std::to_string(v.record_length()) +
                                   " bytes per record but the header's record length is " +
                                   std::to_string(record_length));
  const bool is14 = v.items[0].type == kPoint14;
  if (is14 != (pdrf >= 6))
    fail_at(name, offset + 34, "LASzip item " + item_name(v.items[0].type) +
                                   " does not match point data record format " + std::to_string(pdrf));
  return v;
}

// ---------------------------------------------------------------------------------------------
// Chunk decoder

struct ChunkDecoder::Impl {
  const LaszipVlr& vlr;
  std::uint32_t layers;
  std::size_t rec_len;
  // pointwise (compressors 1 and 2): at most one item of each kind, version 1 or 2
  ArithmeticDecoder dec;
  std::optional<Point10V2> p10;
  std::optional<GpsTime11V2> gps;
  std::optional<Rgb12V2> rgb;
  std::optional<ByteV2> bytes;
  std::optional<Point10V1> p10_1;
  std::optional<GpsTime11V1> gps_1;
  std::optional<Rgb12V1> rgb_1;
  std::optional<ByteV1> bytes_1;
  std::size_t off_gps = 0, off_rgb = 0, off_bytes = 0;
  // layered (v3/v4): streams in file order
  std::vector<LayerStream> streams;
  std::optional<Point14V3> p14;
  std::optional<RgbNir14V3> rgbnir;
  std::optional<Byte14V3> b14;
  std::size_t first_rgb_stream = 0, first_byte_stream = 0;
  std::vector<std::uint64_t> stream_end;  // file offset of each stream's end (errors)
  // chunk state
  std::string name;
  std::size_t index = 0;
  std::uint64_t chunk_offset = 0, points = 0, done = 0;
  const std::uint8_t* base = nullptr;  // file bytes
  const std::uint8_t* raw = nullptr;   // first record
  std::uint64_t dec_end = 0;

  Impl(const LaszipVlr& v, std::uint32_t l) : vlr(v), layers(l), rec_len(v.record_length()) {}

  [[noreturn]] void fail(std::uint64_t off, const std::string& what) const {
    detail::fail_at(name, off, "LAZ chunk " + std::to_string(index) + ": " + what);
  }

  void start(const Input& in, std::size_t idx, const Chunk& c, std::uint64_t limit) {
    name = in.name;
    index = idx;
    chunk_offset = c.offset;
    points = c.points;
    done = 0;
    base = in.bytes.data();
    const std::uint64_t end = c.bytes != 0 ? c.offset + c.bytes : limit;
    if (end > in.size() || c.offset > end) fail(c.offset, "chunk runs past the end of the file");
    if (c.points == 0) return;
    if (c.points / kMaxPointsPerByte > end - c.offset)
      fail(c.offset, std::to_string(c.points) + " points cannot be coded in " + std::to_string(end - c.offset) + " bytes");
    if (end - c.offset < rec_len)
      fail(c.offset, "chunk of " + std::to_string(end - c.offset) + " bytes cannot hold its first " +
                         std::to_string(rec_len) + "-byte record");
    raw = base + c.offset;
    std::uint64_t pos = c.offset + rec_len;
    if (!vlr.layered()) {
      // fresh coders per chunk: LASzip re-initialises every model at a chunk start
      // (LASreadItemCompressed_*::init), which equals constructing them anew
      p10.reset(), gps.reset(), rgb.reset(), bytes.reset();
      p10_1.reset(), gps_1.reset(), rgb_1.reset(), bytes_1.reset();
      std::size_t off = 0;
      for (const Item& it : vlr.items) {  // parse_laszip_vlr: one of each kind, in this order
        const bool v1 = it.version == 1;
        if (it.type == kPoint10) {
          if (v1) p10_1.emplace(), p10_1->init(raw);
          else p10.emplace(), p10->init(raw);
        } else if (it.type == kGpsTime11) {
          if (v1) gps_1.emplace(), gps_1->init(raw + off);
          else gps.emplace(), gps->init(raw + off);
          off_gps = off;
        } else if (it.type == kRgb12) {
          if (v1) rgb_1.emplace(), rgb_1->init(raw + off);
          else rgb.emplace(), rgb->init(raw + off);
          off_rgb = off;
        } else {
          if (v1) bytes_1.emplace(it.size), bytes_1->init(raw + off);
          else bytes.emplace(it.size), bytes->init(raw + off);
          off_bytes = off;
        }
        off += it.size;
      }
      dec.init(base + pos, base + end);
      dec_end = end;
      return;
    }
    // Layered chunk: first record raw, uint32 point count, then the byte size of every layer of
    // every item, then the layers in that order (lasreadpoint.cpp read, chunk_sizes()).
    if (end - pos < 4) fail(pos, "chunk ends inside its point count");
    const std::uint32_t stored = detail::load_le<std::uint32_t>(base + pos);
    if (stored != c.points)
      fail(pos, "chunk stores " + std::to_string(stored) + " points but the chunk table/header say " +
                    std::to_string(c.points));
    pos += 4;
    std::size_t nstreams = 0;
    for (const Item& it : vlr.items)
      nstreams += it.type == kPoint14 ? 9 : it.type == kRgbNir14 ? 2 : it.type == kByte14 ? it.size : 1;
    if ((end - pos) / 4 < nstreams) fail(pos, "chunk ends inside its layer sizes");
    streams.assign(nstreams, LayerStream{});
    stream_end.assign(nstreams, 0);
    std::vector<std::uint32_t> sizes(nstreams);
    for (std::size_t s = 0; s < nstreams; ++s) sizes[s] = detail::load_le<std::uint32_t>(base + pos + 4 * s);
    const std::uint64_t sizes_at = pos;
    pos += 4 * nstreams;
    // which streams are wanted
    std::vector<bool> want(nstreams, true);
    std::size_t s = 0;
    for (const Item& it : vlr.items) {
      if (it.type == kPoint14) {
        static constexpr std::uint32_t bit[9] = {0, kLayerZ, kLayerClassification, kLayerFlags, kLayerIntensity,
                                                 kLayerScanAngle, kLayerUserData, kLayerPointSource, kLayerGpsTime};
        for (int k = 1; k < 9; ++k) want[s + k] = (layers & bit[k]) != 0;
        s += 9;
      } else if (it.type == kRgb14 || it.type == kRgbNir14) {
        first_rgb_stream = s;
        want[s] = (layers & kLayerRgb) != 0;
        if (it.type == kRgbNir14) want[s + 1] = (layers & kLayerNir) != 0;
        s += it.type == kRgbNir14 ? 2 : 1;
      } else {
        first_byte_stream = s;
        for (std::size_t k = 0; k < it.size; ++k) want[s + k] = (layers & kLayerExtraBytes) != 0;
        s += it.size;
      }
    }
    for (std::size_t k = 0; k < nstreams; ++k) {
      if (sizes[k] > end - pos)
        fail(sizes_at + 4 * k, "layer " + std::to_string(k) + " of " + std::to_string(sizes[k]) +
                                   " bytes runs past the chunk end at byte " + std::to_string(end));
      streams[k].active = want[k] && sizes[k] > 0;
      if (streams[k].active) streams[k].dec.init(base + pos, base + pos + sizes[k]);
      pos += sizes[k];
      stream_end[k] = pos;
    }
    if (!streams[0].active && c.points > 1) fail(sizes_at, "empty XY layer in a chunk of several points");
    std::uint32_t context = 0;
    std::size_t off = 0;
    p14.reset(), rgbnir.reset(), b14.reset();
    for (const Item& it : vlr.items) {
      if (it.type == kPoint14) {
        p14.emplace(it.version);
        p14->init(raw, streams.data());
        context = p14->context_out;
      } else if (it.type == kRgb14 || it.type == kRgbNir14) {
        rgbnir.emplace(it.type == kRgbNir14, it.version);
        rgbnir->init(raw + off, streams.data() + first_rgb_stream, context);
      } else {
        b14.emplace(it.size, it.version);
        b14->init(raw + off, streams.data() + first_byte_stream, context);
      }
      off += it.size;
    }
  }

  void next(std::size_t n, std::uint8_t* out) {
    for (std::size_t i = 0; i < n; ++i, out += rec_len) {
      if (done++ == 0) {
        std::memcpy(out, raw, rec_len);
        continue;
      }
      if (!vlr.layered()) {
        if (p10) p10->read(dec, out);
        else p10_1->read(dec, out);
        if (gps) gps->read(dec, out + off_gps);
        else if (gps_1) gps_1->read(dec, out + off_gps);
        if (rgb) rgb->read(dec, out + off_rgb);
        else if (rgb_1) rgb_1->read(dec, out + off_rgb);
        if (bytes) bytes->read(dec, out + off_bytes);
        else if (bytes_1) bytes_1->read(dec, out + off_bytes);
        // A valid stream never needs bytes past its end (finish()); stopping at once bounds the
        // work a damaged one costs: a pointwise file is one chunk of all its points.
        if (dec.overrun > 0)
          fail(dec_end, "compressed stream needs bytes past its end after record " + std::to_string(done - 1) +
                            " of " + std::to_string(points) + " (corrupted or truncated chunk)");
      } else {
        p14->read(out);
        const std::uint32_t ctx = p14->context_out;
        std::size_t off = 30;
        for (std::size_t k = 1; k < vlr.items.size(); ++k) {
          const Item& it = vlr.items[k];
          if (it.type == kByte14) b14->read(out + off, ctx);
          else rgbnir->read(out + off, ctx);
          off += it.size;
        }
      }
    }
  }

  /// A well-formed stream is consumed exactly up to its end, give or take the encoder's zero
  /// padding (LASzip ArithmeticEncoder::done writes 2-3 bytes the decoder may not read): reading
  /// past the end, or leaving more than kSlack bytes unread, means the stream is corrupted.
  static constexpr std::uint64_t kSlack = 8;
  void check_stream(const ArithmeticDecoder& d, std::uint64_t end, const std::string& what, bool strict) const {
    if (d.overrun > 0)
      fail(end, what + " needs " + std::to_string(d.overrun) + " bytes past its end (corrupted or truncated chunk)");
    const auto used = static_cast<std::uint64_t>(d.position() - base);
    if (strict && end - used > kSlack)
      fail(used, what + " decoded all points with " + std::to_string(end - used) +
                     " bytes left before byte " + std::to_string(end) + " (corrupted chunk or wrong point count)");
  }
  void finish(bool strict) const {
    if (points <= 1) return;
    if (!vlr.layered()) {
      check_stream(dec, dec_end, "compressed stream", strict);
      return;
    }
    for (std::size_t k = 0; k < streams.size(); ++k)
      if (streams[k].active) check_stream(streams[k].dec, stream_end[k], "layer " + std::to_string(k), strict);
  }
};

ChunkDecoder::ChunkDecoder(const LaszipVlr& vlr, std::uint32_t layers)
    : impl_(std::make_unique<Impl>(vlr, layers)) {}
ChunkDecoder::~ChunkDecoder() = default;
void ChunkDecoder::start(const Input& in, std::size_t index, const Chunk& chunk, std::uint64_t limit) {
  impl_->start(in, index, chunk, limit);
}
void ChunkDecoder::next(std::size_t n, std::uint8_t* out) { impl_->next(n, out); }
void ChunkDecoder::finish(bool strict) { impl_->finish(strict); }
std::uint64_t ChunkDecoder::consumed_end() const {
  return static_cast<std::uint64_t>(impl_->dec.position() - impl_->base);
}

// ---------------------------------------------------------------------------------------------
// Chunk table

namespace {

/// Rebuilds the chunk list by walking a fixed-size-chunk stream from `first` (no usable table).
std::vector<Chunk> walk_chunks(const Input& in, const LaszipVlr& vlr, std::uint64_t first,
                               std::uint64_t data_end, std::uint64_t point_count) {
  std::vector<Chunk> chunks;
  ChunkDecoder dec(vlr);
  const std::size_t rec = vlr.record_length();
  std::vector<std::uint8_t> scratch;
  std::uint64_t pos = first, done = 0;
  while (done < point_count) {
    Chunk c;
    c.offset = pos;
    c.first_point = done;
    c.points = std::min<std::uint64_t>(vlr.chunk_size, point_count - done);
    if (pos >= data_end)
      detail::fail_at(in.name, pos, "LAZ chunk " + std::to_string(chunks.size()) +
                                        ": point data ends after " + std::to_string(done) + " of " +
                                        std::to_string(point_count) + " points");
    if (vlr.layered()) {
      // the chunk's size is in its header: raw record, count, layer sizes
      dec.start(in, chunks.size(), c, data_end);
      std::size_t nstreams = 0;
      for (const Item& it : vlr.items)
        nstreams += it.type == kPoint14 ? 9 : it.type == kRgbNir14 ? 2 : it.type == kByte14 ? it.size : 1;
      std::uint64_t end = pos + rec + 4 + 4 * nstreams;
      for (std::size_t s = 0; s < nstreams; ++s)
        end += detail::load_le<std::uint32_t>(in.bytes.data() + pos + rec + 4 + 4 * s);
      c.bytes = end - pos;
    } else {
      dec.start(in, chunks.size(), c, data_end);
      scratch.resize(static_cast<std::size_t>(c.points) * rec);
      dec.next(static_cast<std::size_t>(c.points), scratch.data());
      dec.finish(false);
      c.bytes = dec.consumed_end() - pos;
    }
    pos += c.bytes;
    done += c.points;
    chunks.push_back(c);
  }
  return chunks;
}

}  // namespace

std::vector<Chunk> read_chunk_table(const Input& in, const LaszipVlr& vlr, std::uint64_t point_offset,
                                    std::uint64_t data_end, std::uint64_t point_count,
                                    std::vector<std::string>& notes) {
  using detail::fail_at;
  using detail::load_le;
  const std::string& nm = in.name;
  if (point_count > 0 && (data_end <= point_offset || point_count / kMaxPointsPerByte > data_end - point_offset))
    fail_at(nm, point_offset, "header announces " + std::to_string(point_count) + " points but only " +
                                  std::to_string(data_end > point_offset ? data_end - point_offset : 0) +
                                  " bytes of compressed point data follow");
  if (vlr.compressor == 1) {  // pointwise: one stream for the whole file, no table
    if (point_count == 0) return {};
    return {Chunk{point_offset, data_end - point_offset, 0, point_count}};
  }
  in.need(point_offset, 8, "LAZ chunk table offset");
  const std::uint64_t first = point_offset + 8;
  if (point_count == 0) return {};
  std::int64_t table = load_le<std::int64_t>(in.bytes.data() + point_offset);
  const std::uint64_t fsize = in.size();
  auto plausible = [&](std::int64_t t) {
    return t > static_cast<std::int64_t>(first) && static_cast<std::uint64_t>(t) + 8 <= fsize;
  };
  std::string problem;
  if (!plausible(table)) {
    // -1 (or 0 in old writers): the writer could not seek back; the offset is in the last 8 bytes
    if (fsize >= 8 && plausible(load_le<std::int64_t>(in.bytes.data() + fsize - 8)))
      table = load_le<std::int64_t>(in.bytes.data() + fsize - 8);
    else
      problem = "chunk table offset " + std::to_string(table) + " at byte " + std::to_string(point_offset) +
                " points outside the file";
  }
  std::vector<Chunk> chunks;
  if (problem.empty()) {
    const auto t = static_cast<std::uint64_t>(table);
    const std::uint32_t version = load_le<std::uint32_t>(in.bytes.data() + t);
    const std::uint32_t n = load_le<std::uint32_t>(in.bytes.data() + t + 4);
    if (version != 0) {
      problem = "chunk table at byte " + std::to_string(t) + " has version " + std::to_string(version) + " (expected 0)";
    } else if (n == 0 || n > t - first || n > point_count) {
      problem = "chunk table at byte " + std::to_string(t) + " lists " + std::to_string(n) + " chunks for " +
                std::to_string(point_count) + " points in " + std::to_string(t - first) + " bytes";
    } else {
      ArithmeticDecoder dec(in.bytes.data() + t + 8, in.bytes.data() + fsize);
      IntegerDecompressor ic(32, 2);
      std::uint32_t prev_count = 0, prev_bytes = 0;
      std::uint64_t pos = first, done = 0;
      chunks.reserve(n);
      for (std::uint32_t i = 0; i < n; ++i) {
        Chunk c;
        c.offset = pos;
        c.first_point = done;
        if (vlr.variable_chunks()) {
          prev_count = static_cast<std::uint32_t>(ic.decompress(dec, static_cast<std::int32_t>(prev_count), 0));
          c.points = prev_count;
        } else {
          c.points = std::min<std::uint64_t>(vlr.chunk_size, point_count > done ? point_count - done : 0);
        }
        prev_bytes = static_cast<std::uint32_t>(ic.decompress(dec, static_cast<std::int32_t>(prev_bytes), 1));
        c.bytes = prev_bytes;
        if (c.bytes == 0 || c.bytes > t - pos) {
          problem = "chunk table entry " + std::to_string(i) + " (" + std::to_string(c.bytes) +
                    " bytes from byte " + std::to_string(pos) + ") runs past the table at byte " + std::to_string(t);
          break;
        }
        pos += c.bytes;
        done += c.points;
        chunks.push_back(c);
      }
      if (problem.empty() && dec.overrun > 0)
        problem = "chunk table at byte " + std::to_string(t) + " is truncated";
      if (problem.empty() && done != point_count) {
        if (vlr.variable_chunks())
          fail_at(nm, t, "chunk table: chunk point counts add up to " + std::to_string(done) +
                             " but the header announces " + std::to_string(point_count) + " points");
        problem = "chunk table covers " + std::to_string(done) + " of " + std::to_string(point_count) + " points";
      }
    }
  }
  if (problem.empty()) return chunks;
  if (vlr.variable_chunks()) fail_at(nm, point_offset, "LAZ with variable chunk sizes: " + problem);
  notes.push_back("LAZ " + problem + ": chunks located by decoding them in sequence (no parallel decode)");
  return walk_chunks(in, vlr, first, data_end, point_count);
}

void decompress_all(const Input& in, const LaszipVlr& vlr, const std::vector<Chunk>& chunks,
                    std::uint8_t* out, std::uint32_t layers) {
  const std::size_t rec = vlr.record_length();
  std::vector<std::string> errors(chunks.size());
  tbb::parallel_for(std::size_t{0}, chunks.size(), [&](std::size_t i) {
    try {
      ChunkDecoder dec(vlr, layers);
      const Chunk& c = chunks[i];
      dec.start(in, i, c, c.offset + c.bytes);
      dec.next(static_cast<std::size_t>(c.points), out + c.first_point * rec);
      dec.finish();
    } catch (const FormatError& e) {
      errors[i] = e.what();
    }
  });
  // the first failing chunk in file order, whatever the thread schedule
  for (const std::string& e : errors)
    if (!e.empty()) throw FormatError(e);
}

}  // namespace rayscan::io::laz
