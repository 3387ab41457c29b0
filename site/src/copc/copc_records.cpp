// read_records(): the input as COPC point records (PDRF 6, 7 or 8 plus extra bytes), see
// copc_build.hpp. COPC 1.0 allows only these three formats ("LAS 1.4, PDRF 6, 7 or 8"); the
// PDRF 0-3 mapping follows ASPRS LAS 1.4 R15 section 2.6 (tables 7-10 against 12-14).
#include "copc_build.hpp"

#include "las/las_header.hpp"
#include "atomic_writer.hpp"
#include "field_names.hpp"
#include "laz/laz.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/point_reader.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <optional>
#include <stdexcept>

namespace rayscan::io::copc {

namespace {

// Maps the hidden temporary `file` (`what`: "records", "LAS") that the COPC writer wrote for its
// output. A failure to open or map it is named as that output (output_error: the registered
// temporary's output, and its folder when that is another), since the hidden name means nothing
// to the user: "<out.copc.laz>: the temporary records file: cannot memory-map file: <cause>".
std::unique_ptr<detail::MappedFile> map_temporary(const std::filesystem::path& file, const char* what) {
  try {
    return std::make_unique<detail::MappedFile>(file);
  } catch (const FormatError& e) {
    std::string rest = e.what();
    if (const std::string prefix = file.string() + ": "; rest.rfind(prefix, 0) == 0) rest.erase(0, prefix.size());
    throw output_error(file, std::string("the temporary ") + what + " file: " + rest, 0);
  }
}

using detail::load_le;

/// Human-readable bytes for the memory message ("5.2 GiB").
std::string gib(std::uint64_t b) {
  char s[32];
  std::snprintf(s, sizeof s, "%.1f GiB", static_cast<double>(b) / double(1u << 30));
  return s;
}

/// Converts one PDRF 0-3 record (core `in`, `n` = its PDRF length) into PDRF 6/7 (`out`, 30 or
/// 36 bytes). The fields PDRF 6 adds (scanner channel, overlap flag) are 0.
void legacy_to_14(const std::uint8_t* in, int pdrf, std::uint8_t* out) {
  std::memset(out, 0, 36);
  std::memcpy(out, in, 14);  // X, Y, Z, intensity
  const std::uint8_t bits = in[14], cls = in[15];
  const unsigned ret = bits & 7u, nret = (bits >> 3) & 7u, dir = (bits >> 6) & 1u, edge = (bits >> 7) & 1u;
  out[14] = static_cast<std::uint8_t>(ret | (nret << 4));
  // classification flags: synthetic, key-point, withheld (legacy bits 5-7) -> bits 0-2
  out[15] = static_cast<std::uint8_t>(((cls >> 5) & 7u) | (dir << 6) | (edge << 7));
  out[16] = static_cast<std::uint8_t>(cls & 31u);
  out[17] = in[17];  // user data
  // scan angle rank (int8 degrees) -> scan angle (int16, 0.006 degree steps)
  const auto rank = static_cast<std::int8_t>(in[16]);
  const auto angle = static_cast<std::int16_t>(std::lround(rank / 0.006));
  std::memcpy(out + 18, &angle, 2);
  std::memcpy(out + 20, in + 18, 2);  // point source id
  if (pdrf == 1 || pdrf == 3) std::memcpy(out + 22, in + 20, 8);  // GPS time
  if (pdrf == 2) std::memcpy(out + 30, in + 20, 6);               // RGB
  if (pdrf == 3) std::memcpy(out + 30, in + 28, 6);
}

/// The Extra Bytes VLR payload (LAS 1.4 R15 section 2.5.6: 192-byte descriptors) with every
/// descriptor of a deprecated array type (11-30: 2 or 3 elements of base type (t - 1) % 10 + 1)
/// split into one descriptor per element, named "name[j]" as the LAS reader names them, its
/// no-data, min, max, scale and offset taken from the element's slot; the record bytes are the
/// same. R15 deprecates the array types and COPC readers (copc.js) refuse them. Sets `changed`.
std::vector<std::uint8_t> split_array_descriptors(const std::vector<std::uint8_t>& in, bool& changed) {
  std::vector<std::uint8_t> out;
  changed = false;
  std::size_t k = 0;
  for (; k + 192 <= in.size(); k += 192) {
    const std::uint8_t* e = in.data() + k;
    const int type = e[2];
    if (type < 11 || type > 30) {
      out.insert(out.end(), e, e + 192);
      continue;
    }
    changed = true;
    const int n = type <= 20 ? 2 : 3;
    const std::string name(reinterpret_cast<const char*>(e + 4), ::strnlen(reinterpret_cast<const char*>(e + 4), 32));
    for (int j = 0; j < n; ++j) {
      std::uint8_t d[192] = {};
      d[2] = static_cast<std::uint8_t>((type - 1) % 10 + 1);
      d[3] = e[3];  // options: which of no-data, min, max, scale, offset are set
      const std::string nj = name + "[" + std::to_string(j) + "]";
      std::memcpy(d + 4, nj.data(), std::min<std::size_t>(32, nj.size()));
      for (const int field : {40, 64, 88, 112, 136}) std::memcpy(d + field, e + field + 8 * j, 8);
      std::memcpy(d + 160, e + 160, 32);  // description
      out.insert(out.end(), d, d + 192);
    }
  }
  out.insert(out.end(), in.begin() + static_cast<std::ptrdiff_t>(k), in.end());
  return out;
}

bool is_crs_vlr(const std::string& user, std::uint16_t id) {
  return user == "LASF_Projection" && (id == 2112 || id == 34735 || id == 34736 || id == 34737);
}

/// A temporary file beside the output for the records of `name` ("what": its role).
std::filesystem::path temp_path(const CopcWriteOptions& opt, const std::string& name, const char* what) {
  std::string file = ".";
  file += std::filesystem::path(name).filename().string();
  file += '.';
  file += std::to_string(::getpid());
  file += ".copc-";
  file += what;  // last: "input.las" keeps the extension the LAS writer and reader go by
  return opt.temp_dir / file;  // write_copc sets temp_dir (the output's folder by default)
}

/// The records of the LAS/LAZ file `path`; `name` is the input as the user named it; `file`
/// holds `path`'s mapping (and, for a converted input, `path` as a temporary to remove);
/// `output` is the COPC output, which the errors of a temporary records file name.
Records read_las_family(const std::shared_ptr<RecordFile>& file, const std::filesystem::path& path,
                        const std::string& name, const CopcWriteOptions& opt, const std::filesystem::path& output) {
  const detail::MappedFile& map = *file->map;
  const detail::Input in{map.bytes(), name, {}};
  const detail::LasHeader h = detail::parse_las_header(in);
  const std::uint8_t* d = map.bytes().data();
  if (h.pdrf == 4 || h.pdrf == 5 || h.pdrf > 8)
    throw std::invalid_argument(name + ": point data record format " + std::to_string(h.pdrf) +
                                " (waveform packets) cannot be written as COPC (PDRF 6, 7 or 8)");
  if (h.count == 0) throw std::invalid_argument(name + ": no points to write as COPC");
  Records r;
  const int in_len = detail::pdrf_length(h.pdrf);
  const std::size_t extra = h.record_length - static_cast<std::size_t>(in_len);
  r.pdrf = h.pdrf >= 6 ? h.pdrf : (h.pdrf == 2 || h.pdrf == 3 ? 7 : 6);
  const std::size_t out_len = static_cast<std::size_t>(detail::pdrf_length(r.pdrf)) + extra;
  if (out_len > 0xFFFF) throw std::invalid_argument(name + ": record length over 65535 bytes after conversion");
  r.record_length = static_cast<std::uint16_t>(out_len);
  r.count = h.count;
  r.in_point_offset = h.point_offset;
  r.in_record_length = h.record_length;
  // Memory: the build's 12 bytes per point and the batches; the records stay on disk.
  const std::uint64_t need = h.count * kBytesPerPoint + kBatchBytes;
  if (h.count >= (std::uint64_t{1} << 32))
    throw CopcMemoryError(name + ": " + std::to_string(h.count) +
                          " points: the COPC build addresses at most 2^32 - 1 records (32-bit record indices)");
  if (need > opt.memory_bytes)
    throw CopcMemoryError(name + ": " + std::to_string(h.count) + " points need about " + gib(need) +
                          " for the COPC build (12 bytes per point and 256 MiB of batches), over the memory budget of " +
                          gib(opt.memory_bytes) + " (raise the budget)");
  const bool convert = h.pdrf < 6;
  if (convert)
    r.notes.push_back("point data record format " + std::to_string(h.pdrf) + " written as " + std::to_string(r.pdrf) +
                      " (COPC allows 6, 7 and 8)");
  if (!h.laszip.present && h.count > (h.data_end - h.point_offset) / h.record_length)
    detail::fail_at(name, h.version_minor >= 4 ? 247 : 107,
                    "header announces " + std::to_string(h.count) + " records but only " +
                        std::to_string(h.data_end - h.point_offset) + " bytes of point data follow");
  // The CRS as the readers see it (a WKT VLR, or GeoKeys turned into WKT), stored as WKT: LAS
  // 1.4 point formats 6-10 require WKT (section 2.5.1). Checked before the records are decoded:
  // a WKT VLR that GDAL cannot read is refused as write_las refuses it, naming the input.
  ReadOptions ro;
  ro.scalars = false;
  ro.stored_colour = true;
  const std::unique_ptr<PointReader> crs_reader = open_point_reader(path, AttributeSet::none(), ro);
  r.crs_wkt = crs_reader->crs_wkt();
  // A WKT VLR GDAL cannot read that gave way to GeoKeys: the CRS written is not the one of record.
  if (const std::string& w = crs_reader->info().crs_warning; !w.empty()) r.warnings.push_back(w);
  require_readable_crs(name, r.crs_wkt);
  if (!h.laszip.present && !convert) {
    r.bytes = d + h.point_offset;  // the input's own records, mapped
  } else {
    // Decoded (LAZ, chunks in parallel by batches) and/or converted (PDRF 0-3) by batches into
    // a temporary file of output records, then mapped.
    auto out = std::make_shared<RecordFile>();
    const std::filesystem::path& records = out->temp.emplace(temp_path(opt, name, "records"), output).path();
    {
      detail::AtomicWriter w(records, true);
      std::vector<std::uint8_t> raw, conv;
      const std::size_t core = static_cast<std::size_t>(detail::pdrf_length(r.pdrf));
      std::uint64_t done = 0;
      const auto emit = [&](const std::uint8_t* src, std::uint64_t n) {
        done += n;
        if (opt.progress) opt.progress("read", done, h.count);
        if (!convert) {
          w.write(src, n * h.record_length);
          return;
        }
        conv.resize(n * out_len);
        std::uint8_t tmp[36];
        for (std::uint64_t i = 0; i < n; ++i) {
          const std::uint8_t* a = src + i * h.record_length;
          std::uint8_t* b = conv.data() + i * out_len;
          legacy_to_14(a, h.pdrf, tmp);
          std::memcpy(b, tmp, core);
          std::memcpy(b + core, a + in_len, extra);
        }
        w.write(conv.data(), conv.size());
      };
      constexpr std::uint64_t kBatch = std::uint64_t{1} << 20;  // points per decode batch
      if (h.laszip.present) {
        const laz::LaszipVlr vlr =
            laz::parse_laszip_vlr(d + h.laszip.at, h.laszip.len, name, h.laszip.at, h.pdrf, h.record_length);
        std::vector<std::string> notes;
        const std::vector<laz::Chunk> chunks = laz::read_chunk_table(in, vlr, h.point_offset, h.data_end, h.count, notes);
        for (std::size_t c0 = 0; c0 < chunks.size();) {
          std::vector<laz::Chunk> batch;
          std::uint64_t pts = 0;
          for (; c0 < chunks.size() && (batch.empty() || pts + chunks[c0].points <= kBatch); ++c0) {
            laz::Chunk c = chunks[c0];
            c.first_point = pts;
            pts += c.points;
            batch.push_back(c);
          }
          raw.resize(pts * h.record_length);
          laz::decompress_all(in, vlr, batch, raw.data());
          emit(raw.data(), pts);
        }
      } else {
        for (std::uint64_t i = 0; i < h.count; i += kBatch) {
          const std::uint64_t n = std::min(kBatch, h.count - i);
          emit(d + h.point_offset + i * h.record_length, n);
        }
      }
      w.commit();
    }
    out->map = map_temporary(records, "records");
    // Named as the COPC output (output_error: the registered records file's output, and its folder
    // when that is another), since the hidden records name means nothing to the user.
    if (const std::uint64_t size = out->map->bytes().size(); size != h.count * out_len)
      throw output_error(records, "the temporary records file read back " + std::to_string(size) +
                                      " bytes, expected " + std::to_string(h.count * out_len), 0);
    r.bytes = out->map->bytes().data();
    r.file = std::move(out);
  }
  if (!r.file) r.file = file;

  r.scale = h.scale;
  r.offset = h.offset;
  r.file_source_id = load_le<std::uint16_t>(d + 4);
  r.global_encoding = static_cast<std::uint16_t>(h.global_encoding & 1u);  // GPS time type only
  std::memcpy(r.guid, d + 8, 16);
  r.creation_day = h.creation_day;
  r.creation_year = h.creation_year;
  // VLRs and EVLRs kept: not the LASzip VLR, not COPC records, not the CRS (rewritten as WKT).
  for (const VlrInfo& v : h.vlrs) {
    if (v.user_id == "copc" || (v.user_id == "laszip encoded" && v.record_id == 22204) || is_crs_vlr(v.user_id, v.record_id))
      continue;
    CarriedVlr c;
    c.user = v.user_id;
    c.record = v.record_id;
    c.description = v.description;
    const std::uint64_t at = v.offset + (v.extended ? 60 : 54);
    c.payload.assign(d + at, d + at + v.length);
    if (c.user == "LASF_Spec" && c.record == 4) {
      bool changed = false;
      c.payload = split_array_descriptors(c.payload, changed);
      if (changed)
        r.notes.push_back("Extra Bytes descriptors of deprecated array types written as one descriptor per element");
    }
    (v.extended || c.payload.size() > 0xFFFF ? r.evlrs : r.vlrs).push_back(std::move(c));
  }
  return r;
}

}  // namespace

Records read_records(const std::filesystem::path& in, const std::filesystem::path& out, const CopcWriteOptions& opt) {
  const std::uint64_t in_bytes = std::filesystem::file_size(in);
  auto file = std::make_shared<RecordFile>();
  if (format_from_extension(in) == Format::las) {
    file->map = std::make_unique<detail::MappedFile>(in);
    Records r = read_las_family(file, in, in.string(), opt, out);
    r.in_bytes = in_bytes;
    return r;
  }
  // Other formats: their attributes mapped onto LAS fields by write_las (PDRF 6/7/8 chosen from
  // them, scalars as extra bytes) in an intermediate file, then read as LAS. Read whole: these
  // readers have no bounded-memory path to COPC.
  const PointCloud cloud = read_point_cloud(in);
  if (cloud.size() == 0) throw std::invalid_argument(in.string() + ": no points to write as COPC");
  require_readable_crs(in.string(), cloud.crs_wkt);  // named as the input, not the intermediate
  const std::filesystem::path& las = file->temp.emplace(temp_path(opt, in.string(), "input.las"), out).path();
  write_las(las, cloud);
  file->map = map_temporary(las, "LAS");
  Records r = read_las_family(file, las, in.string(), opt, out);
  r.in_bytes = in_bytes;
  r.creation_day = r.creation_year = 0;  // write_las's date is today's: not a property of the input
  r.notes.push_back("converted from " + in.extension().string() + " through LAS point data record format " +
                    std::to_string(r.pdrf));
  return r;
}

}  // namespace rayscan::io::copc
