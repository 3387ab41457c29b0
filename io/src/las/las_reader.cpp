// ASPRS LAS reader: LAS Specification 1.4 R15 (2019), which also defines versions 1.0-1.3.
// Header: section 2.4 (table 3, fields added in 1.3/1.4 noted); VLRs: 2.5; EVLRs: 2.7;
// point data record formats 0-10: 2.6 (tables 7-17); Extra Bytes VLR: 2.5.6 (table 24);
// CRS: 2.5.1 (OGC WKT VLR 2112) and 2.5.2 (GeoKeyDirectoryTag 34735, GeoDoubleParamsTag 34736).
#include "las/las_header.hpp"
#include "readers.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/octree/position_view.hpp"
#include "laz/laz.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <future>
#include <limits>
#include <memory>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

namespace rayscan::io::detail {

namespace {

bool pdrf_has_gps(int f) { return f != 0 && f != 2; }
bool pdrf_has_rgb(int f) { return f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10; }
/// Offset of Red within the record, or -1.
int pdrf_rgb_offset(int f) {
  switch (f) {
    case 2: return 20;
    case 3: case 5: return 28;
    case 7: case 8: case 10: return 30;
    default: return -1;
  }
}

/// One field of the Extra Bytes VLR (section 2.5.6, table 24) that rayscan exposes as a scalar.
struct ExtraField {
  std::string name;
  std::string description;  // the descriptor's (32 bytes at most), "" when it has none
  int type = 0;       // 1..10 (base type); 11..30 deprecated arrays use their base type
  int size = 0;       // bytes of one element
  int offset = 0;     // offset inside the record
  double scale = 1.0, add = 0.0;
};

/// Bytes an Extra Bytes descriptor `e` (192 bytes, table 24) occupies in the record: the data
/// type's size (types 1-10), times 2 or 3 for the deprecated arrays 11-30, the options field for
/// type 0 (undocumented bytes); -1 for a reserved type (> 30), whose size is unknown.
int extra_bytes_width(const std::uint8_t* e) {
  static constexpr int base_size[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  const int type = e[2];
  if (type > 30) return -1;
  if (type == 0) return e[3];
  if (type <= 10) return base_size[type];
  return base_size[(type - 1) % 10 + 1] * (type <= 20 ? 2 : 3);
}

double load_typed(const std::uint8_t* p, int type) {
  switch (type) {
    case 1: return load_le<std::uint8_t>(p);
    case 2: return load_le<std::int8_t>(p);
    case 3: return load_le<std::uint16_t>(p);
    case 4: return load_le<std::int16_t>(p);
    case 5: return load_le<std::uint32_t>(p);
    case 6: return load_le<std::int32_t>(p);
    case 7: return static_cast<double>(load_le<std::uint64_t>(p));
    case 8: return static_cast<double>(load_le<std::int64_t>(p));
    case 9: return load_le<float>(p);
    case 10: return load_le<double>(p);
    default: return 0.0;
  }
}

/// Output arrays of the point decoder (null when the attribute is not kept).
struct Out {
  Vec3* pos = nullptr;
  std::uint16_t* intensity = nullptr;
  std::uint8_t* cls = nullptr;
  double* gps = nullptr;
  Rgb16* rgb = nullptr;
  double *ret = nullptr, *nret = nullptr, *angle = nullptr, *udata = nullptr, *psid = nullptr, *nir = nullptr;
  double *cflags = nullptr, *channel = nullptr, *scan_dir = nullptr, *edge = nullptr;
  std::vector<double*> extra;
  glm::vec3* normals = nullptr;
};
struct Decoder {
  const std::uint8_t* base;
  std::size_t rec_len;
  Vec3 scale, offset;
  int gps_off, rgb_off;
  const std::vector<ExtraField>* extras;
  const ExtraField* normal_fields;  ///< NormalX, NormalY, NormalZ (used when out.normals is set)
  Out out;
};
struct Reduction {
  std::uint16_t rgb_max = 0;
  std::size_t first_bad = std::numeric_limits<std::size_t>::max();
};

/// Decodes records [i0, i1) (section 2.6; tables 7-12 for Legacy = PDRF 0-5, 13-17 for 6-10).
template <bool Legacy, bool HasGps, bool HasRgb>
void decode(const Decoder& dc, std::size_t i0, std::size_t i1, Reduction& red) {
  const Out& o = dc.out;
  for (std::size_t i = i0; i < i1; ++i) {
    const std::uint8_t* r = dc.base + i * dc.rec_len;
    // las_coordinate (rayscan/octree/position_view.hpp): the one expression the index file decodes with too.
    const double x = las_coordinate(load_le<std::int32_t>(r), dc.scale.x, dc.offset.x);
    const double y = las_coordinate(load_le<std::int32_t>(r + 4), dc.scale.y, dc.offset.y);
    const double z = las_coordinate(load_le<std::int32_t>(r + 8), dc.scale.z, dc.offset.z);
    // One compare per axis on the decoded doubles; false for an overflow to infinity too.
    if (!within_coordinate_bound(x, y, z)) red.first_bad = std::min(red.first_bad, i);
    o.pos[i] = Vec3(x, y, z);
    if (o.intensity != nullptr) o.intensity[i] = load_le<std::uint16_t>(r + 12);
    if (o.cls != nullptr) o.cls[i] = Legacy ? (r[15] & 0x1F) : r[16];
    if constexpr (HasGps) o.gps[i] = load_le<double>(r + dc.gps_off);
    if constexpr (HasRgb) {
      const Rgb16 c{load_le<std::uint16_t>(r + dc.rgb_off), load_le<std::uint16_t>(r + dc.rgb_off + 2),
                    load_le<std::uint16_t>(r + dc.rgb_off + 4)};
      red.rgb_max = std::max({red.rgb_max, c.r, c.g, c.b});
      o.rgb[i] = c;
    }
    if (o.ret != nullptr) {
      if constexpr (Legacy) {
        o.ret[i] = r[14] & 0x07;
        o.nret[i] = (r[14] >> 3) & 0x07;
        o.scan_dir[i] = (r[14] >> 6) & 1;
        o.edge[i] = r[14] >> 7;
        o.cflags[i] = r[15] >> 5;  // synthetic, key-point, withheld (table 8) = flag bits 0-2
        o.channel[i] = 0;
        o.angle[i] = static_cast<std::int8_t>(r[16]);
        o.udata[i] = r[17];
        o.psid[i] = load_le<std::uint16_t>(r + 18);
      } else {
        o.ret[i] = r[14] & 0x0F;
        o.nret[i] = r[14] >> 4;
        o.cflags[i] = r[15] & 0x0F;  // synthetic, key-point, withheld, overlap (table 15)
        o.channel[i] = (r[15] >> 4) & 3;
        o.scan_dir[i] = (r[15] >> 6) & 1;
        o.edge[i] = r[15] >> 7;
        o.angle[i] = load_le<std::int16_t>(r + 18) * 0.006;
        o.udata[i] = r[17];
        o.psid[i] = load_le<std::uint16_t>(r + 20);
      }
      if (o.nir != nullptr) o.nir[i] = load_le<std::uint16_t>(r + 36);
      const std::vector<ExtraField>& ex = *dc.extras;
      for (std::size_t k = 0; k < ex.size(); ++k)
        o.extra[k][i] = load_typed(r + ex[k].offset, ex[k].type) * ex[k].scale + ex[k].add;
    }
    if (o.normals != nullptr) {
      const ExtraField* nf = dc.normal_fields;
      for (int a = 0; a < 3; ++a)
        o.normals[i][a] = static_cast<float>(load_typed(r + nf[a].offset, nf[a].type) * nf[a].scale + nf[a].add);
    }
  }
}

/// LAZ layers (laz::kLayer*) a chunk decoder must decode for the attributes a reader delivers:
/// X, Y, Z always; the rest only when asked (xyz must not pay for RGB,
/// GPS time or extra bytes). Layered chunks (PDRF 6-10) honour this; pointwise ones decode all.
std::uint32_t laz_layers(AttributeSet a) {
  std::uint32_t l = laz::kLayerZ;
  if (a.has(Attribute::rgb)) l |= laz::kLayerRgb;
  if (a.has(Attribute::intensity)) l |= laz::kLayerIntensity;
  if (a.has(Attribute::classification)) l |= laz::kLayerClassification;
  if (a.has(Attribute::gps_time)) l |= laz::kLayerGpsTime;
  if (a.has(Attribute::normals)) l |= laz::kLayerExtraBytes;
  if (a.has(Attribute::scalars))
    l |= laz::kLayerFlags | laz::kLayerScanAngle | laz::kLayerUserData | laz::kLayerPointSource |
         laz::kLayerNir | laz::kLayerExtraBytes;
  return l;
}

}  // namespace

namespace {

/// ReadOptions::direct_records: byte ranges of a file read with O_DIRECT into two page-aligned
/// buffers of the reader's own, the next range's read running on a background thread while the
/// caller decodes the current one. On a VM whose balloon reports free memory to the host, reading
/// through the page cache (the map) costs ~2 s of CPU per GB for the fresh cache pages; these
/// reads cost the disk's time only (bench/notes/).
class DirectBlocks {
 public:
  /// Opens `path` with O_DIRECT; ok() is false when the file system refuses (then use the map).
  explicit DirectBlocks(const std::string& path) : name_(path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_DIRECT | O_CLOEXEC);
  }
  DirectBlocks(const DirectBlocks&) = delete;
  DirectBlocks& operator=(const DirectBlocks&) = delete;
  ~DirectBlocks() {
    if (pending_.valid()) pending_.wait();
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] bool ok() const { return fd_ >= 0; }
  /// Bytes [a, b) of the file (read now, or by the background read prefetch(a, b) started).
  /// Valid until the next get(). Throws FormatError when the read fails or the file is shorter.
  const std::uint8_t* get(std::uint64_t a, std::uint64_t b) {
    if (pending_.valid()) {
      pending_.get();  // rethrows the background read's error
      if (pa_ == a && pb_ == b) {
        cur_ ^= 1;
        return buf_[cur_].data() + (a - aligned(a, b).first);
      }
    }
    fill(cur_, a, b);
    return buf_[cur_].data() + (a - aligned(a, b).first);
  }
  /// Starts reading bytes [a, b) into the other buffer (the one get() did not return last).
  void prefetch(std::uint64_t a, std::uint64_t b) {
    if (pending_.valid()) pending_.get();
    pa_ = a, pb_ = b;
    const int other = cur_ ^ 1;
    pending_ = std::async(std::launch::async, [this, other, a, b] { fill(other, a, b); });
  }

 private:
  /// The O_DIRECT transfer holding bytes [a, b): its start (a rounded down to kDirectAlign) and
  /// length (a multiple of kDirectAlign).
  static std::pair<std::uint64_t, std::uint64_t> aligned(std::uint64_t a, std::uint64_t b) {
    const std::uint64_t a0 = a / detail::kDirectAlign * detail::kDirectAlign;
    return {a0, detail::round_up_direct(static_cast<std::size_t>(b - a0))};
  }
  void fill(int k, std::uint64_t a, std::uint64_t b) {
    const auto [a0, len] = aligned(a, b);
    if (buf_[k].size() < len) buf_[k] = detail::HugeArray<std::uint8_t>(static_cast<std::size_t>(len));  // page-aligned
    std::uint64_t got = 0;
    while (got < b - a0) {
      const ssize_t r = ::pread(fd_, buf_[k].data() + got, static_cast<std::size_t>(len - got), static_cast<off_t>(a0 + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) fail_at(name_, a0 + got, std::string("cannot read the point records: ") + std::strerror(errno));
      if (r == 0) fail_at(name_, a0 + got, "file ends inside the point records (expected " + std::to_string(b) + " bytes)");
      got += static_cast<std::uint64_t>(r);
      if (got % detail::kDirectAlign != 0) break;  // (end of file)
    }
    if (got < b - a0) fail_at(name_, a0 + got, "file ends inside the point records (expected " + std::to_string(b) + " bytes)");
  }
  std::string name_;
  int fd_ = -1;
  detail::HugeArray<std::uint8_t> buf_[2];
  int cur_ = 0;
  std::uint64_t pa_ = 0, pb_ = 0;
  std::future<void> pending_;
};

/// The chunked LAS reader: the header, VLRs, EVLRs and Extra Bytes descriptors are parsed and
/// validated at open (parse() below); read() decodes the next block of records in parallel. LAZ
/// (LASzip VLR): read() first decompresses the chunks holding the block into a window of records
/// (laz::ChunkDecoder, chunks in parallel, only the layers the attributes need), then decodes
/// the records as for LAS; memory is the window, about max_points records plus one chunk.
class LasReader final : public PointReader {
 public:
  LasReader(std::shared_ptr<Source> src, AttributeSet attrs, const ReadOptions& opt)
      : src_(std::move(src)) {
    parse(src_->in, opt);
    setup(attrs, opt);
    if (opt.direct_records && !laszip_ && src_->map) {
      direct_ = std::make_unique<DirectBlocks>(src_->in.name);
      if (!direct_->ok()) direct_.reset();
    }
  }
  const FileInfo& info() const override { return info_; }
  const std::string& crs_wkt() const override { return crs_; }
  std::uint64_t point_count() const override { return count_; }
  AttributeSet attributes() const override { return attrs_; }
  std::optional<std::pair<Vec3, Vec3>> integer_grid() const override {
    return std::make_pair(scale_, offset_);
  }
  std::size_t read(PointCloud& chunk, std::size_t max_points) override;

 private:
  void parse(const Input& in, const ReadOptions& opt);
  void setup(AttributeSet attrs, const ReadOptions& opt);
  // From the largest R/G/B value of the whole file: all zero drops colour; <= 255 means 8-bit
  // colour in 16-bit fields (LAS 1.4 R15 section 2.6 says 16-bit), scaled by 257 (rgb_mul_).
  void decide_colour_scale(std::uint16_t max_rgb);
  /// LAZ: makes records [first, first + n) available (decoding whole chunks into window_, in
  /// parallel over chunks) and returns a pointer to record `first`; n <= points of the window.
  const std::uint8_t* laz_records(std::uint64_t first, std::size_t n, std::uint32_t layers);
  /// Throws FormatError for point `index`, whose record `r` decodes to a coordinate beyond
  /// +-kMaxCoordinate (refuse_las_coordinate, las_header.hpp); the byte named is the record's
  /// offset in the uncompressed layout (point data offset + index x record length).
  [[noreturn]] void refuse_coordinate(const std::uint8_t* r, std::uint64_t index) const;
  /// laz_records for compressor 1 (LASzip 1.x pointwise): the file is one stream of all its
  /// points, so one decoder kept across calls decodes the records in sequence into a window of
  /// `n` records (memory: the window, not the file); a request before its position restarts it.
  const std::uint8_t* laz_stream_records(std::uint64_t first, std::size_t n);

  std::shared_ptr<Source> src_;
  FileInfo info_;
  std::string crs_;
  AttributeSet attrs_;
  std::uint64_t count_ = 0, next_ = 0;
  std::uint64_t point_offset_ = 0;
  std::uint16_t rec_len_ = 0;
  int pdrf_ = 0;
  Vec3 scale_, offset_;
  std::vector<ExtraField> extras_;
  ExtraField normal_fields_[3];  ///< the NormalX/Y/Z extra bytes when has_normals_
  bool has_normals_ = false;
  std::vector<std::string> scalar_names_;
  bool scalars_ = false, has_gps_ = false, has_rgb_ = false, has_nir_ = false;
  std::uint16_t rgb_mul_ = 1;  // 257 when the file stores 8-bit colour
  // LAZ (LASzip VLR present): chunks are decoded on demand into a window of records.
  bool laszip_ = false;
  laz::LaszipVlr lazvlr_;
  std::vector<laz::Chunk> chunks_;
  std::vector<std::uint8_t> window_;         // decoded records of chunks [win_c0_, win_c1_)
  std::size_t win_c0_ = 0, win_c1_ = 0;
  std::uint64_t win_first_ = 0, win_points_ = 0;
  std::uint32_t win_layers_ = 0;
  std::unique_ptr<laz::ChunkDecoder> stream_;  // compressor 1: the decoder and its next record
  std::uint64_t stream_next_ = 0;
  // ReadOptions::direct_records: each read()'s records from DirectBlocks, the next read()'s
  // range read ahead.
  std::unique_ptr<DirectBlocks> direct_;
};

const std::uint8_t* LasReader::laz_stream_records(std::uint64_t first, std::size_t n) {
  const std::size_t rec = rec_len_;
  if (win_points_ > 0 && first >= win_first_ && first + n <= win_first_ + win_points_)
    return window_.data() + (first - win_first_) * rec;
  const laz::Chunk& c = chunks_.front();
  const Input& in = src_->in;
  win_points_ = 0;  // the window is invalid until the decode below succeeds
  try {
    if (!stream_ || first < stream_next_) {
      stream_ = std::make_unique<laz::ChunkDecoder>(lazvlr_);
      stream_->start(in, 0, c, c.offset + c.bytes);
      stream_next_ = 0;
    }
    resize_huge(window_, std::max<std::size_t>(n, 1) * rec);
    while (stream_next_ < first) {  // records skipped over are decoded into the window, then dropped
      const std::size_t k = static_cast<std::size_t>(std::min<std::uint64_t>(std::max<std::size_t>(n, 1), first - stream_next_));
      stream_->next(k, window_.data());
      stream_next_ += k;
    }
    stream_->next(n, window_.data());
    stream_next_ += n;
    if (stream_next_ == c.points) stream_->finish();
  } catch (...) {
    stream_.reset();  // its state is unknown after an error: the next request starts over
    throw;
  }
  in.done(stream_->consumed_end());
  win_first_ = first, win_points_ = n;
  return window_.data();
}

const std::uint8_t* LasReader::laz_records(std::uint64_t first, std::size_t n, std::uint32_t layers) {
  if (lazvlr_.compressor == 1) return laz_stream_records(first, n);
  const bool hit = win_layers_ == layers && win_c1_ > win_c0_ && first >= win_first_ &&
                   first + n <= win_first_ + win_points_;
  if (!hit) {
    // The chunk holding `first` (chunks are in file order, first_point increasing).
    auto it = std::upper_bound(chunks_.begin(), chunks_.end(), first,
                               [](std::uint64_t v, const laz::Chunk& c) { return v < c.first_point; });
    std::size_t c0 = static_cast<std::size_t>(it - chunks_.begin()) - 1;
    std::size_t c1 = c0;
    std::uint64_t pts = 0;
    while (c1 < chunks_.size() && chunks_[c0].first_point + pts < first + n) pts += chunks_[c1++].points;
    const std::size_t rec = rec_len_;
    const std::uint64_t base = chunks_[c0].first_point;
    // Chunks already decoded at the end of the previous window (a read ending inside a chunk)
    // move to the front instead of being decoded again.
    std::size_t have = c0;
    if (win_layers_ == layers && c0 >= win_c0_ && c0 < win_c1_) {
      const std::size_t keep = static_cast<std::size_t>(win_first_ + win_points_ - base) * rec;
      std::memmove(window_.data(), window_.data() + (base - win_first_) * rec, keep);
      have = win_c1_;
    }
    win_c0_ = win_c1_ = 0;  // the window is invalid until the decode below succeeds
    resize_huge(window_, static_cast<std::size_t>(pts) * rec);
    std::vector<std::string> errors(c1 - c0);
    const Input& in = src_->in;
    tbb::parallel_for(std::max(have, c0), c1, [&](std::size_t i) {
      try {
        laz::ChunkDecoder dec(lazvlr_, layers);
        const laz::Chunk& c = chunks_[i];
        dec.start(in, i, c, c.offset + c.bytes);
        dec.next(static_cast<std::size_t>(c.points), window_.data() + (c.first_point - base) * rec);
        dec.finish();
      } catch (const FormatError& e) {
        errors[i - c0] = e.what();
      }
    });
    for (const std::string& e : errors)  // the first failing chunk in file order
      if (!e.empty()) throw FormatError(e);
    in.done(chunks_[c1 - 1].offset + chunks_[c1 - 1].bytes);
    win_c0_ = c0, win_c1_ = c1, win_first_ = base, win_points_ = pts, win_layers_ = layers;
  }
  return window_.data() + (first - win_first_) * rec_len_;
}

void LasReader::parse(const Input& in, const ReadOptions& opt) {
  FileInfo& info = info_;
  const std::string& nm = in.name;
  // The public header and (E)VLR headers, parsed and bounds-checked once (las_header.cpp).
  LasHeader h = parse_las_header(in);
  const std::uint8_t* d = in.bytes.data();
  info.format = h.laszip.present ? (h.copc_info.present ? "COPC" : "LAZ") : "LAS";
  info.version = "1." + std::to_string(h.version_minor);
  info.global_encoding = h.global_encoding;
  info.project_guid = h.project_guid;
  info.system_id = h.system_id;
  info.software = h.software;
  info.creation_day = h.creation_day;
  info.creation_year = h.creation_year;
  info.header_bounds = h.header_bounds;
  info.scale = h.scale;
  info.offset = h.offset;
  info.header_point_count = h.count;
  info.point_format = h.pdrf;
  info.record_length = h.record_length;
  info.vlrs = std::move(h.vlrs);
  info.notes.insert(info.notes.end(), h.notes.begin(), h.notes.end());
  const int pdrf = h.pdrf, vmin = h.version_minor;
  const std::uint16_t rec_len = h.record_length;
  const std::uint64_t count = h.count, point_offset = h.point_offset;
  const int need_len = pdrf_length(pdrf);
  info.extra_bytes_per_point = rec_len - need_len;
  // Point count against the file size: never allocate from an unchecked count.
  const std::uint64_t avail = h.data_end - point_offset;
  if (h.laszip.present) {
    // LAZ: the chunk table bounds the count (chunk point counts must add up to it, each checked
    // against its bytes before decoding); chunks are decoded on demand by read().
    lazvlr_ = laz::parse_laszip_vlr(d + h.laszip.at, h.laszip.len, nm, h.laszip.at, pdrf, rec_len);
    chunks_ = laz::read_chunk_table(in, lazvlr_, point_offset, h.data_end, count, info.notes);
    laszip_ = true;
  } else if (count > avail / rec_len)
    fail_at(nm, vmin >= 4 ? 247 : 107,
            "header announces " + std::to_string(count) + " points of " + std::to_string(rec_len) +
                " bytes from byte " + std::to_string(point_offset) + " but only " +
                std::to_string(avail) + " bytes of point data follow (room for " +
                std::to_string(avail / rec_len) + ")");

  // Extra Bytes descriptors (192 bytes each). A file may split them over several Extra Bytes
  // VLRs (append-bug.las: one per field); their descriptors follow each other in the record when
  // their widths add up to the extra bytes of the record, else only the last VLR is used.
  std::vector<std::pair<const std::uint8_t*, std::uint64_t>> eb_vlrs;  // payloads whose descriptors apply
  if (h.extra_bytes.present) {
    std::uint64_t sum = 0;
    bool known = true;
    for (const LasHeader::Found& f : h.extra_bytes_all)
      for (std::uint64_t k = 0; k + 192 <= f.len; k += 192) {
        const int w = extra_bytes_width(d + f.at + k);
        if (w < 0) known = false;
        else sum += static_cast<std::uint64_t>(w);
      }
    if (h.extra_bytes_all.size() > 1 && known && sum == static_cast<std::uint64_t>(info.extra_bytes_per_point)) {
      for (const LasHeader::Found& f : h.extra_bytes_all) eb_vlrs.emplace_back(d + f.at, f.len);
    } else {
      eb_vlrs.emplace_back(d + h.extra_bytes.at, h.extra_bytes.len);
      if (h.extra_bytes_all.size() > 1)
        info.notes.push_back(std::to_string(h.extra_bytes_all.size()) + " Extra Bytes VLRs whose fields do not add up to the " +
                             std::to_string(info.extra_bytes_per_point) + " extra bytes per record: the last one used");
    }
  }
  std::vector<ExtraField> extras;
  {
    int off = need_len;
    bool stop = false;
    for (const auto& [payload, len] : eb_vlrs) {
      for (std::uint64_t k = 0; k + 192 <= len && !stop; k += 192) {
        const std::uint8_t* e = payload + k;
        const int type = e[2];
        const int options = e[3];
        static constexpr int base_size[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
        const std::string name = fixed_string(e + 4, 32);
        const int width = extra_bytes_width(e);
        if (width < 0) {  // reserved data types (table 25): the layout is unknown from here on
          info.notes.push_back("Extra Bytes VLR field '" + name + "' has reserved data type " +
                               std::to_string(type) + ": it and later extra bytes are skipped");
          stop = true;
          break;
        }
        int base = type, n = 1;
        if (type >= 11 && type <= 30) {
          base = (type - 1) % 10 + 1;
          n = type <= 20 ? 2 : 3;
        }
        if (off + width > rec_len) {
          info.notes.push_back("Extra Bytes VLR field '" + name + "' runs past the " +
                               std::to_string(rec_len) + "-byte record: extra bytes ignored");
          extras.clear();
          stop = true;
          break;
        }
        if (type != 0) {
          for (int j = 0; j < n; ++j) {
            ExtraField f;
            f.name = n == 1 ? name : name + "[" + std::to_string(j) + "]";
            f.description = fixed_string(e + 160, 32);
            f.type = base;
            f.size = base_size[base];
            f.offset = off + j * f.size;
            if (options & 0x08) f.scale = load_le<double>(e + 112 + 8 * std::min(j, 2));
            if (options & 0x10) f.add = load_le<double>(e + 136 + 8 * std::min(j, 2));
            if (!std::isfinite(f.scale) || !std::isfinite(f.add)) f.scale = 1.0, f.add = 0.0;
            extras.push_back(f);
          }
        }
        off += width;
      }
      if (stop) break;
    }
  }
  // Normals: the three fields PDAL's writers.las names NormalX, NormalY, NormalZ (its Dimension
  // names; write_las writes PointCloud::normals under them) become PointCloud::normals, not
  // scalars; the other fields are scalars when ReadOptions::scalars asks for them.
  {
    int at[3] = {-1, -1, -1};
    for (std::size_t k = 0; k < extras.size(); ++k)
      for (int a = 0; a < 3; ++a)
        if (extras[k].name == kLasNormalNames[a] && at[a] < 0) at[a] = static_cast<int>(k);
    if (at[0] >= 0 && at[1] >= 0 && at[2] >= 0) {
      for (int a = 0; a < 3; ++a) normal_fields_[a] = extras[static_cast<std::size_t>(at[a])];
      has_normals_ = true;
      std::vector<ExtraField> rest;
      for (std::size_t k = 0; k < extras.size(); ++k)
        if (static_cast<int>(k) != at[0] && static_cast<int>(k) != at[1] && static_cast<int>(k) != at[2])
          rest.push_back(extras[k]);
      extras = std::move(rest);
    }
  }
  if (!opt.scalars) extras.clear();
  for (const ExtraField& f : extras)
    if (!f.description.empty()) info.extra_bytes.emplace(f.name, ExtraBytesInfo{f.description, std::nullopt});
  if (info.extra_bytes_per_point > 0 && extras.empty() && !has_normals_)
    info.notes.push_back(std::to_string(info.extra_bytes_per_point) +
                         " extra bytes per record " +
                         (h.extra_bytes.present ? std::string("not kept") : "not described by an Extra Bytes VLR") +
                         ": skipped");

  // CRS: the OGC WKT VLR when it holds a CRS GDAL reads, else the GeoKeys. Where the global
  // encoding's WKT bit is set (LAS 1.4 requires it for PDRF 6-10) the WKT is the CRS of record and
  // GeoKeys beside it are a courtesy to older readers; without the bit the GeoKeys are, so a
  // WKT record GDAL cannot read gives way to GeoKeys GDAL reads either way, with a warning naming
  // this file. With none readable the WKT's text is kept: an output that needs a CRS (a GeoTIFF,
  // COPC) refuses it naming the input (require_readable_crs), one that needs none drops it.
  struct { std::string crs_wkt; } pc;
  std::string wkt_vlr;
  if (h.wkt.present) {
    std::string wkt = wkt_vlr_text(d, h);
    // A WKT CRS is KEYWORD[...]; anything else (empty, "''") carries no CRS.
    if (wkt.find('[') != std::string::npos)
      wkt_vlr = std::move(wkt);
    else
      info.notes.push_back("OGC WKT VLR holds no WKT ('" + crs_excerpt(wkt) + "'): ignored");
  }
  std::string geokeys_wkt;
  if (h.geokeys.present) {
    // The GeoDoubleParamsTag holds the keys of type double (ProjLinearUnitSizeGeoKey).
    const GeoDoubles doubles = h.geodoubles.present ? GeoDoubles{d + h.geodoubles.at, h.geodoubles.len} : GeoDoubles{};
    geokeys_wkt = crs_from_geokeys(d + h.geokeys.at, h.geokeys.len, info, doubles);  // "" unless GDAL reads it
  }
  const bool wkt_readable = !wkt_vlr.empty() && crs_wkt_readable(wkt_vlr);
  if (wkt_readable || (!wkt_vlr.empty() && geokeys_wkt.empty())) {
    pc.crs_wkt = std::move(wkt_vlr);
    info.crs_source = "WKT VLR";
  } else if (!geokeys_wkt.empty() || info.epsg != 0) {
    if (!wkt_vlr.empty()) {
      info.crs_warning = unreadable_wkt_vlr(nm, wkt_vlr) + ": the CRS is taken from its GeoKeys";
      info.notes.push_back(info.crs_warning);
    }
    pc.crs_wkt = std::move(geokeys_wkt);
    info.crs_source = "GeoKeys";
  }
  if (info.epsg == 0 && !pc.crs_wkt.empty()) info.epsg = epsg_from_wkt(pc.crs_wkt);

  crs_ = std::move(pc.crs_wkt);
  count_ = count;
  point_offset_ = point_offset;
  rec_len_ = rec_len;
  pdrf_ = pdrf;
  scale_ = h.scale;
  offset_ = h.offset;
  extras_ = std::move(extras);
  info.fields = {"X", "Y", "Z", "intensity", "return_number", "number_of_returns", "classification",
                 "classification_flags", "scanner_channel", "scan_direction_flag",
                 "edge_of_flight_line", "scan_angle", "user_data", "point_source_id"};
  has_gps_ = pdrf_has_gps(pdrf);
  has_rgb_ = pdrf_has_rgb(pdrf);
  has_nir_ = pdrf == 8 || pdrf == 10;
  if (has_gps_) info.fields.push_back("gps_time");
  if (has_rgb_) info.fields.insert(info.fields.end(), {"red", "green", "blue"});
  if (has_nir_) info.fields.push_back("nir");
  for (const ExtraField& f : extras_) info.fields.push_back(f.name);
  if (has_normals_)
    for (const char* nm : kLasNormalNames) info.fields.emplace_back(nm);
}

void LasReader::refuse_coordinate(const std::uint8_t* r, std::uint64_t index) const {
  refuse_las_coordinate(src_->in.name, point_offset_ + index * rec_len_, index, r, scale_, offset_);
}

void LasReader::decide_colour_scale(std::uint16_t mx) {
  if (mx == 0) {
    attrs_ = AttributeSet{attrs_.bits & ~static_cast<std::uint32_t>(Attribute::rgb)};
    info_.notes.push_back("RGB fields present but all zero: colour dropped");
  } else if (mx <= 255) {
    rgb_mul_ = 257;
    info_.notes.push_back("RGB stored as 8-bit values (max " + std::to_string(mx) +
                          ") in 16-bit fields: scaled by 257");
  }
}

void LasReader::setup(AttributeSet want, const ReadOptions& opt) {
  AttributeSet have = AttributeSet::none();
  have.add(Attribute::intensity).add(Attribute::classification);
  if (has_gps_) have.add(Attribute::gps_time);
  if (has_rgb_) have.add(Attribute::rgb);
  if (has_normals_) have.add(Attribute::normals);
  if (opt.scalars) have.add(Attribute::scalars);
  attrs_ = want & have;
  scalars_ = attrs_.has(Attribute::scalars);
  if (scalars_) {
    // Flag bits (indices 5-8), kept so that a derived LAS file carries them unchanged.
    scalar_names_ = {"return_number", "number_of_returns", "scan_angle", "user_data", "point_source_id",
                     "classification_flags", "scanner_channel", "scan_direction_flag", "edge_of_flight_line"};
    if (has_nir_) scalar_names_.push_back("nir");
    for (const ExtraField& f : extras_) scalar_names_.push_back(f.name);
  }
  // Colour normalisation (docs/formats.md) is a whole-file decision: 8-bit values stored in the
  // 16-bit fields are scaled by 257; a colour format whose channels are all zero carries no
  // colour and is dropped. A streaming reader therefore scans the colour fields once at open.
  if (opt.stored_colour) {
    // The caller takes the colour as stored (ReadOptions::stored_colour): no pass, no scaling.
  } else if (attrs_.has(Attribute::rgb) && count_ > 0 && laszip_) {
    // LAZ: one pass over the chunks decoding only X/Y/RGB (layered chunks), stopped as soon as a
    // value above 255 shows the colour is 16-bit (usually in the first window).
    const int off = pdrf_rgb_offset(pdrf_);
    std::uint16_t mx = 0;
    const std::size_t step = std::max<std::size_t>(1, (16u << 20) / rec_len_);
    for (std::uint64_t p = 0; p < count_ && mx <= 255;) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(step, count_ - p));
      const std::uint8_t* base = laz_records(p, n, laz::kLayerRgb);
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint8_t* r = base + i * rec_len_ + off;
        mx = std::max({mx, load_le<std::uint16_t>(r), load_le<std::uint16_t>(r + 2),
                       load_le<std::uint16_t>(r + 4)});
      }
      p += n;
    }
    window_.clear();
    window_.shrink_to_fit();
    win_c0_ = win_c1_ = 0;
    win_points_ = 0;
    decide_colour_scale(mx);
  } else if (attrs_.has(Attribute::rgb) && count_ > 0) {
    const std::uint8_t* base = src_->in.bytes.data() + point_offset_;
    const int off = pdrf_rgb_offset(pdrf_);
    const std::size_t block = std::max<std::size_t>(1, (16u << 20) / rec_len_);
    std::uint16_t mx = 0;
    for (std::size_t b0 = 0; b0 < count_ && mx <= 255; b0 += block) {
      const std::size_t b1 = std::min<std::size_t>(count_, b0 + block);
      mx = std::max(mx, tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(b0, b1, 8192), std::uint16_t{0},
          [&](const tbb::blocked_range<std::size_t>& rg, std::uint16_t m) {
            for (std::size_t i = rg.begin(); i < rg.end(); ++i) {
              const std::uint8_t* r = base + i * rec_len_ + off;
              m = std::max({m, load_le<std::uint16_t>(r), load_le<std::uint16_t>(r + 2),
                            load_le<std::uint16_t>(r + 4)});
            }
            return m;
          },
          [](std::uint16_t a, std::uint16_t b) { return std::max(a, b); }));
      src_->in.done(point_offset_ + b1 * rec_len_);
    }
    decide_colour_scale(mx);
  }
}

std::size_t LasReader::read(PointCloud& pc, std::size_t max_points) {
  const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(max_points, count_ - next_));
  resize_huge(pc.positions, n);
  auto fit = [n](auto& v, bool keep) {
    if (keep) resize_huge(v, n);
    else v.clear();
  };
  fit(pc.intensity, attrs_.has(Attribute::intensity));
  fit(pc.classification, attrs_.has(Attribute::classification));
  fit(pc.gps_time, attrs_.has(Attribute::gps_time));
  fit(pc.rgb, attrs_.has(Attribute::rgb));
  fit(pc.normals, attrs_.has(Attribute::normals));
  pc.crs_wkt.clear();
  if (scalars_) {
    pc.scalars.resize(scalar_names_.size());
    for (std::size_t k = 0; k < scalar_names_.size(); ++k) {
      pc.scalars[k].name = scalar_names_[k];
      resize_huge(pc.scalars[k].values, n);
    }
  } else {
    pc.scalars.clear();
  }
  if (n == 0) return 0;
  Out out;
  out.pos = pc.positions.data();
  out.intensity = pc.intensity.empty() ? nullptr : pc.intensity.data();
  out.cls = pc.classification.empty() ? nullptr : pc.classification.data();
  out.gps = pc.gps_time.empty() ? nullptr : pc.gps_time.data();
  out.rgb = pc.rgb.empty() ? nullptr : pc.rgb.data();
  out.normals = pc.normals.empty() ? nullptr : pc.normals.data();
  if (scalars_) {
    out.ret = pc.scalars[0].values.data();
    out.nret = pc.scalars[1].values.data();
    out.angle = pc.scalars[2].values.data();
    out.udata = pc.scalars[3].values.data();
    out.psid = pc.scalars[4].values.data();
    out.cflags = pc.scalars[5].values.data();
    out.channel = pc.scalars[6].values.data();
    out.scan_dir = pc.scalars[7].values.data();
    out.edge = pc.scalars[8].values.data();
    const std::size_t first_extra = has_nir_ ? 10 : 9;
    out.nir = has_nir_ ? pc.scalars[9].values.data() : nullptr;
    for (std::size_t k = first_extra; k < pc.scalars.size(); ++k) out.extra.push_back(pc.scalars[k].values.data());
  }
  // Records [next_, next_ + n) decoded into chunk slots [0, n): the decoder's base pointer is the
  // first record of the chunk.
  const Input& in = src_->in;
  const std::uint8_t* first_rec = nullptr;
  if (laszip_) {
    first_rec = laz_records(next_, n, laz_layers(attrs_));
  } else if (direct_) {  // this block's records, then the next block of the same size read ahead
    const std::uint64_t a = point_offset_ + next_ * rec_len_;
    first_rec = direct_->get(a, a + std::uint64_t{n} * rec_len_);
    const std::uint64_t m = std::min<std::uint64_t>(max_points, count_ - next_ - n);
    if (m > 0) direct_->prefetch(a + std::uint64_t{n} * rec_len_, a + (std::uint64_t{n} + m) * rec_len_);
  } else {
    first_rec = in.bytes.data() + point_offset_ + next_ * rec_len_;
  }
  Decoder dec{first_rec, rec_len_, scale_, offset_,
              pdrf_ >= 6 ? 22 : 20, pdrf_rgb_offset(pdrf_), &extras_, normal_fields_, out};
  using DecodeFn = void (*)(const Decoder&, std::size_t, std::size_t, Reduction&);
  DecodeFn fn = nullptr;
  const bool gps = out.gps != nullptr, rgb = out.rgb != nullptr;
  if (pdrf_ < 6) {
    fn = gps ? (rgb ? &decode<true, true, true> : &decode<true, true, false>)
             : (rgb ? &decode<true, false, true> : &decode<true, false, false>);
  } else {
    fn = gps ? (rgb ? &decode<false, true, true> : &decode<false, true, false>)
             : (rgb ? &decode<false, false, true> : &decode<false, false, false>);
  }
  // Blocks of ~16 MB of records, decoded in parallel (TBB); the pages of each finished block are
  // released, so the resident part of the file stays bounded.
  const std::size_t block = std::max<std::size_t>(1, (16u << 20) / rec_len_);
  for (std::size_t b0 = 0; b0 < n; b0 += block) {
    const std::size_t b1 = std::min(n, b0 + block);
    const Reduction r = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(b0, b1, 8192), Reduction{},
        [&](const tbb::blocked_range<std::size_t>& rg, Reduction acc) {
          fn(dec, rg.begin(), rg.end(), acc);
          return acc;
        },
        [](Reduction x, const Reduction& y) {
          x.first_bad = std::min(x.first_bad, y.first_bad);
          return x;
        });
    if (r.first_bad != Reduction{}.first_bad)
      refuse_coordinate(first_rec + r.first_bad * rec_len_, next_ + r.first_bad);
    if (!laszip_ && !direct_) in.done(point_offset_ + (next_ + b1) * rec_len_);
  }
  // Colour normalisation (docs/formats.md), decided at open (setup()).
  if (rgb_mul_ != 1) {
    for (Rgb16& c : pc.rgb) {
      c.r = static_cast<std::uint16_t>(c.r * rgb_mul_);
      c.g = static_cast<std::uint16_t>(c.g * rgb_mul_);
      c.b = static_cast<std::uint16_t>(c.b * rgb_mul_);
    }
    pc.rgb_from_8bit_las = true;  // write_las divides by 257 again: derived files keep the values
  }
  next_ += n;
  return n;
}

}  // namespace

std::unique_ptr<PointReader> open_las(std::shared_ptr<Source> src, AttributeSet attrs,
                                      const ReadOptions& opt) {
  return std::make_unique<LasReader>(std::move(src), attrs, opt);
}

}  // namespace rayscan::io::detail
