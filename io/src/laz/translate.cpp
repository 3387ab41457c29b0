// translate_las(): see rayscan/io/translate.hpp.
#include "rayscan/io/translate.hpp"

#include "atomic_writer.hpp"
#include "bytes.hpp"
#include "field_names.hpp"
#include "laz/encoder_v2.hpp"
#include "laz/encoder_v3.hpp"
#include "laz/laz.hpp"
#include "las/las_header.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/octree/position_view.hpp"

#include <optional>
#include <stdexcept>
#include <string>

namespace rayscan::io {

namespace {

using detail::append_le;
using detail::load_le;
using detail::store_le;

/// Sequential source of raw records: from the map (LAS) or decoded chunk by chunk (LAZ).
class RecordSource {
 public:
  RecordSource(const detail::Input& in, const detail::LasHeader& h, std::vector<std::string>& notes) : in_(in), h_(h) {
    if (h.laszip.present) {
      vlr_ = laz::parse_laszip_vlr(in.bytes.data() + h.laszip.at, h.laszip.len, in.name, h.laszip.at, h.pdrf,
                                   h.record_length);
      chunks_ = laz::read_chunk_table(in, *vlr_, h.point_offset, h.data_end, h.count, notes);
      dec_ = std::make_unique<laz::ChunkDecoder>(*vlr_);
    } else if (h.count > (h.data_end - h.point_offset) / h.record_length) {
      detail::fail_at(in.name, h.version_minor >= 4 ? 247 : 107,
                      "header announces " + std::to_string(h.count) + " records but only " +
                          std::to_string(h.data_end - h.point_offset) + " bytes of point data follow");
    }
  }
  /// Pointer to the next `n` records (valid until the next call). Throws FormatError, as the LAS
  /// reader does, for a record whose coordinates decode beyond +-kMaxCoordinate: a copy that
  /// keeps the records as they are would otherwise write a file every reader refuses.
  const std::uint8_t* next(std::size_t n) {
    const std::size_t rec = h_.record_length;
    if (!vlr_) {
      const std::uint8_t* p = in_.bytes.data() + h_.point_offset + done_ * rec;
      check_coordinates(p, n);
      done_ += n;
      return p;
    }
    buf_.resize(n * rec);
    std::size_t got = 0;
    while (got < n) {
      if (left_ == 0) {
        const laz::Chunk& c = chunks_.at(chunk_);
        dec_->start(in_, chunk_, c, c.offset + c.bytes);
        left_ = c.points;
        ++chunk_;
      }
      const std::size_t k = static_cast<std::size_t>(std::min<std::uint64_t>(left_, n - got));
      dec_->next(k, buf_.data() + got * rec);
      got += k;
      left_ -= k;
      // Each chunk's stream is checked as soon as its last point is decoded, the last chunk's too:
      // a header count above what the chunks hold then reads past a stream's end and is an
      // error, as in the other decoding paths, instead of a record invented from padding.
      if (left_ == 0) dec_->finish();
    }
    check_coordinates(buf_.data(), n);
    done_ += n;
    return buf_.data();
  }

 private:
  /// The `n` records at `p` (points done_ onwards), one compare per axis; the first beyond the
  /// bound is refused with the reader's line (detail::checked_las_position), at the byte the
  /// reader names.
  void check_coordinates(const std::uint8_t* p, std::size_t n) const {
    const std::size_t rec = h_.record_length;
    for (std::size_t i = 0; i < n; ++i)
      (void)detail::checked_las_position(in_.name, h_.point_offset + (done_ + i) * rec, done_ + i, p + i * rec, h_.scale,
                                         h_.offset);
  }

  const detail::Input& in_;
  const detail::LasHeader& h_;
  std::optional<laz::LaszipVlr> vlr_;
  std::vector<laz::Chunk> chunks_;
  std::unique_ptr<laz::ChunkDecoder> dec_;
  std::vector<std::uint8_t> buf_;
  std::size_t chunk_ = 0;
  std::uint64_t left_ = 0, done_ = 0;
};

/// Compresses `n` records into one chunk (first record raw, then the arithmetic-coded rest).
void encode_chunk_v2(const std::uint8_t* recs, std::size_t n, std::size_t rec, int pdrf, std::size_t extra,
                     std::vector<std::uint8_t>& out) {
  out.insert(out.end(), recs, recs + rec);
  if (n == 1) return;
  laz::Point10V2Enc p;
  std::optional<laz::GpsTime11V2Enc> g;
  std::optional<laz::Rgb12V2Enc> c;
  std::optional<laz::ByteV2Enc> b;
  std::size_t off = 20, og = 0, oc = 0, ob = 0;
  p.init(recs);
  if (pdrf == 1 || pdrf == 3) g.emplace(), g->init(recs + off), og = off, off += 8;
  if (pdrf == 2 || pdrf == 3) c.emplace(), c->init(recs + off), oc = off, off += 6;
  if (extra > 0) b.emplace(extra), b->init(recs + off), ob = off;
  laz::ArithmeticEncoder enc(out);
  for (std::size_t i = 1; i < n; ++i) {
    const std::uint8_t* r = recs + i * rec;
    p.write(enc, r);
    if (g) g->write(enc, r + og);
    if (c) c->write(enc, r + oc);
    if (b) b->write(enc, r + ob);
  }
  enc.done();
}

}  // namespace

namespace laz {

// LASzip VLR payload (laszip.cpp LASzip::pack): see laz.hpp.
std::vector<std::uint8_t> laszip_vlr_payload(int pdrf, std::size_t extra, std::uint32_t chunk_size) {
  const bool layered = pdrf >= 6;
  const std::uint16_t iv = layered ? 3 : 2;
  std::vector<std::uint16_t> items;  // type, size pairs
  if (!layered) {
    items.insert(items.end(), {laz::kPoint10, 20});
    if (pdrf == 1 || pdrf == 3) items.insert(items.end(), {laz::kGpsTime11, 8});
    if (pdrf == 2 || pdrf == 3) items.insert(items.end(), {laz::kRgb12, 6});
    if (extra > 0) items.insert(items.end(), {laz::kByte, static_cast<std::uint16_t>(extra)});
  } else {
    items.insert(items.end(), {laz::kPoint14, 30});
    if (pdrf == 7) items.insert(items.end(), {laz::kRgb14, 6});
    if (pdrf == 8) items.insert(items.end(), {laz::kRgbNir14, 8});
    if (extra > 0) items.insert(items.end(), {laz::kByte14, static_cast<std::uint16_t>(extra)});
  }
  std::vector<std::uint8_t> v;
  append_le<std::uint16_t>(v, layered ? 3 : 2);  // compressor: layered-chunked / pointwise-chunked
  append_le<std::uint16_t>(v, 0);                // coder: arithmetic
  v.push_back(layered ? 3 : 2);                  // LASzip version of the item coders
  v.push_back(layered ? 4 : 2);
  append_le<std::uint16_t>(v, layered ? 3 : 0);
  append_le<std::uint32_t>(v, 0);  // options
  append_le<std::uint32_t>(v, chunk_size);
  append_le<std::int64_t>(v, -1);  // number of special EVLRs
  append_le<std::int64_t>(v, -1);  // offset of special EVLRs
  append_le<std::uint16_t>(v, static_cast<std::uint16_t>(items.size() / 2));
  for (std::size_t i = 0; i < items.size(); i += 2) {
    append_le<std::uint16_t>(v, items[i]);
    append_le<std::uint16_t>(v, items[i + 1]);
    append_le<std::uint16_t>(v, iv);
  }
  return v;
}

std::vector<std::uint8_t> chunk_table_bytes(std::span<const std::uint32_t> points, std::span<const std::uint32_t> bytes) {
  // LASzip lasreadpoint.cpp read_chunk_table: version 0, count, then per chunk the point count
  // (variable chunks only, context 0) and the byte size (context 1), each against the previous.
  std::vector<std::uint8_t> table;
  append_le<std::uint32_t>(table, 0);
  append_le<std::uint32_t>(table, static_cast<std::uint32_t>(bytes.size()));
  if (!bytes.empty()) {
    ArithmeticEncoder enc(table);
    IntegerCompressor ic(32, 2);
    std::int32_t prev_points = 0, prev_bytes = 0;
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      if (!points.empty()) {
        ic.compress(enc, prev_points, static_cast<std::int32_t>(points[i]), 0);
        prev_points = static_cast<std::int32_t>(points[i]);
      }
      ic.compress(enc, prev_bytes, static_cast<std::int32_t>(bytes[i]), 1);
      prev_bytes = static_cast<std::int32_t>(bytes[i]);
    }
    enc.done();
  }
  return table;
}

}  // namespace laz

TranslateResult translate_las(const std::filesystem::path& in_path, const std::filesystem::path& out_path,
                              const TranslateOptions& opt) {
  // 0xFFFFFFFF marks variable-sized chunks in the LASzip VLR (LASzip laszip.hpp, chunk_size).
  if (opt.chunk_size == 0 || opt.chunk_size == 0xFFFFFFFFu)
    throw OptionError({option("chunk_size"), " " + std::to_string(opt.chunk_size) +
                                                 ": expected 1 to 4294967294 points per chunk"});
  const laz::FileMap map(in_path);
  const detail::Input in{map.bytes(), in_path.string(), {}};
  const detail::LasHeader h = detail::parse_las_header(in);
  const std::uint8_t* d = map.bytes().data();
  bool to_laz = false;
  if (opt.compression == LasCompression::laz) to_laz = true;
  else if (opt.compression == LasCompression::by_extension) to_laz = lower_extension(out_path) == ".laz";
  const std::size_t rec = h.record_length;
  static constexpr int kLen[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  if (rec < static_cast<std::size_t>(kLen[h.pdrf]))
    detail::fail_at(in.name, 105, "point record length " + std::to_string(rec) + " smaller than PDRF " +
                                      std::to_string(h.pdrf) + " needs (" + std::to_string(kLen[h.pdrf]) + ")");
  const std::size_t extra = rec - static_cast<std::size_t>(kLen[h.pdrf]);
  if (to_laz && (h.pdrf == 4 || h.pdrf == 5 || h.pdrf > 8))
    throw std::invalid_argument(in.name + ": LAZ output of point data record format " + std::to_string(h.pdrf) +
                                " (waveform packets) is not implemented (the writer covers PDRF 0-3 and 6-8 with extra bytes)");
  std::vector<std::string> notes;
  RecordSource src(in, h, notes);
  TranslateResult res;
  // A copy keeps every VLR (a user converting LAS <-> LAZ wants the file's own records, as PDAL
  // and laszip keep them) and writes no CRS of its own, so an unreadable WKT VLR is neither
  // replaced nor duplicated; but the output inherits it, which GDAL, PDAL and QGIS may refuse.
  if (const std::string wkt = detail::wkt_vlr_text(d, h); !wkt.empty() && !crs_wkt_readable(wkt))
    res.warnings.push_back(detail::unreadable_wkt_vlr(in.name, wkt) + ": copied unchanged with the other VLRs");
  // Waveform data packets stored in the file (global encoding bit 1, LAS 1.3+; section 2.4 table
  // 4): the point records' wave packet descriptors address them by their offset from the start of
  // the waveform data packet record, so a LAS output copies that record byte for byte and points
  // header byte 227 at its new place. In a LAS 1.3 file it follows the point records; in 1.4 it is
  // an EVLR (copied with the other EVLRs below). LAZ holds no waveform record (LASzip writes
  // waveforms to a separate file), so LAZ input or output of such a file is refused.
  const bool waveform_internal = h.version_minor >= 3 && (h.global_encoding & 2u) != 0 && h.waveform_start != 0;
  const std::uint64_t points_end = h.point_offset + h.count * rec;  // (LAS input: count checked by src)
  bool waveform_after_points = false;  // the record lies in [points_end, data_end): copied with those bytes
  if (waveform_internal) {
    if (h.laszip.present || to_laz)
      throw std::invalid_argument(in.name + ": waveform data packets stored inside the file "
                                  "(global encoding bit 1) cannot be kept in LAZ (LAS to LAS only)");
    bool at_evlr = false;
    for (const VlrInfo& v : h.vlrs) at_evlr = at_evlr || (v.extended && v.offset == h.waveform_start);
    waveform_after_points = h.waveform_start >= points_end && h.waveform_start < h.data_end;
    if (!at_evlr && !waveform_after_points)
      detail::fail_at(in.name, 227, "start of waveform data packet record " + std::to_string(h.waveform_start) +
                                        " is neither after the point records (bytes " + std::to_string(points_end) +
                                        " to " + std::to_string(h.data_end) + ") nor at an EVLR");
  }
  std::uint64_t waveform_out = 0;  // where the waveform data packet record lands in the output

  // Header and VLRs: everything but the LASzip VLR and COPC records, plus a new LASzip VLR.
  std::vector<std::uint8_t> head(d, d + h.header_size);
  std::uint32_t n_vlr = 0;
  std::uint64_t pos = h.header_size;
  const std::uint32_t n_vlr_in = load_le<std::uint32_t>(d + 100);
  for (std::uint32_t i = 0; i < n_vlr_in; ++i) {
    const std::string user = detail::fixed_string(d + pos + 2, 16);
    const std::uint16_t id = load_le<std::uint16_t>(d + pos + 18);
    const std::uint16_t len = load_le<std::uint16_t>(d + pos + 20);
    const bool drop = (user == "laszip encoded" && id == 22204) || user == "copc";
    if (!drop) {
      head.insert(head.end(), d + pos, d + pos + 54 + len);
      ++n_vlr;
    }
    pos += 54 + len;
  }
  head.insert(head.end(), d + pos, d + h.point_offset);  // bytes between the VLRs and the points
  if (to_laz) {
    const std::vector<std::uint8_t> payload = laz::laszip_vlr_payload(h.pdrf, extra, opt.chunk_size);
    std::vector<std::uint8_t> vh;
    detail::append_vlr_header(vh, "laszip encoded", 22204, payload.size(),
                              h.pdrf >= 6 ? "by rayscan (LASzip 3.4 items)" : "by rayscan (LASzip 2.2 items)", false);
    // insert before the trailing user bytes: right after the last kept VLR
    const std::size_t at = head.size() - (h.point_offset - pos);
    head.insert(head.begin() + static_cast<std::ptrdiff_t>(at), payload.begin(), payload.end());
    head.insert(head.begin() + static_cast<std::ptrdiff_t>(at), vh.begin(), vh.end());
    ++n_vlr;
  }
  store_le<std::uint32_t>(head, 96, static_cast<std::uint32_t>(head.size()));
  store_le<std::uint32_t>(head, 100, n_vlr);
  head[104] = static_cast<std::uint8_t>(to_laz ? (h.pdrf | 0x80) : h.pdrf);
  // Without bit 1 no waveform record is copied (the bytes after the point records are dropped),
  // so a start the input holds would address nothing, or bytes past the output's end: 0, as LAS
  // 1.3 R11 (public header block) asks of a file that contains no waveform records.
  if (h.version_minor >= 3 && !waveform_internal) store_le<std::uint64_t>(head, 227, 0);

  detail::AtomicStream f(out_path);
  f.write(head.data(), head.size());
  res.points = h.count;
  res.compressed = to_laz;
  std::uint64_t written = head.size();
  // Progress every 2^21 points (and at the end), not every chunk.
  const auto report = [&](std::uint64_t before, std::uint64_t after) {
    if (opt.progress && (before >> 21 != after >> 21 || after == h.count))
      opt.progress(to_laz ? "encode" : "copy", after, h.count);
  };
  if (!to_laz) {
    const std::size_t batch = std::max<std::size_t>(1, (8u << 20) / rec);
    for (std::uint64_t i = 0; i < h.count; i += batch) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(batch, h.count - i));
      f.write(src.next(n), n * rec);
      report(i, i + n);
    }
    written += h.count * rec;
    if (waveform_after_points) {  // the bytes from the end of the records to the EVLRs or the end
      waveform_out = written + (h.waveform_start - points_end);
      f.write(d + points_end, h.data_end - points_end);
      written += h.data_end - points_end;
    }
  } else {
    std::vector<std::uint8_t> table_ptr(8, 0);
    f.write(table_ptr.data(), 8);
    written += 8;
    std::vector<std::uint32_t> sizes;
    std::vector<std::uint8_t> chunk;
    std::optional<laz::LayeredChunkEncoder> layered;
    if (h.pdrf >= 6) layered.emplace(h.pdrf, extra);
    for (std::uint64_t i = 0; i < h.count; i += opt.chunk_size) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(opt.chunk_size, h.count - i));
      chunk.clear();
      if (layered) layered->encode(src.next(n), n, rec, chunk);
      else encode_chunk_v2(src.next(n), n, rec, h.pdrf, extra, chunk);
      f.write(chunk.data(), chunk.size());
      sizes.push_back(static_cast<std::uint32_t>(chunk.size()));
      written += chunk.size();
      report(i, i + n);
    }
    const std::uint64_t table_at = written;
    const std::vector<std::uint8_t> table = laz::chunk_table_bytes({}, sizes);
    f.write(table.data(), table.size());
    written += table.size();
    res.chunks = sizes.size();
    f.seek(head.size());
    const auto t = static_cast<std::int64_t>(table_at);
    f.write(&t, 8);
    f.seek(written);
  }
  // EVLRs (LAS 1.4): copied after the point data, COPC ones dropped; the header start updated.
  if (h.version_minor >= 4) {
    const std::uint32_t n_evlr_in = load_le<std::uint32_t>(d + 243);
    std::uint64_t ep = h.data_end;
    std::uint32_t n_evlr = 0;
    const std::uint64_t evlr_start = written;
    for (std::uint32_t i = 0; i < n_evlr_in; ++i) {
      const std::string user = detail::fixed_string(d + ep + 2, 16);
      const std::uint64_t len = load_le<std::uint64_t>(d + ep + 20);
      if (user != "copc") {
        if (waveform_internal && ep == h.waveform_start) waveform_out = written;
        f.write(d + ep, 60 + len);
        written += 60 + len;
        ++n_evlr;
      }
      ep += 60 + len;
    }
    f.seek(235);
    const std::uint64_t start = n_evlr > 0 ? evlr_start : 0;
    f.write(&start, 8);
    f.write(&n_evlr, 4);
  }
  if (waveform_internal) {
    f.seek(227);
    f.write(&waveform_out, 8);
  }
  f.commit();
  res.in_bytes = map.bytes().size();
  res.out_bytes = written;
  return res;
}

}  // namespace rayscan::io
