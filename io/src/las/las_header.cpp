// parse_las_header(): see las_header.hpp. ASPRS LAS 1.4 R15 section 2.4 (table 3), 2.5, 2.7.
#include "las/las_header.hpp"
#include "rayscan/base/coordinate_bound.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/octree/position_view.hpp"

#include <cctype>
#include <cmath>
#include <cstring>

namespace rayscan::io::detail {

int pdrf_length(int f) {
  static constexpr int len[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  return f >= 0 && f <= 10 ? len[f] : -1;
}

namespace {

/// Remembers the (E)VLRs the readers use (user id and record id per the sections cited in
/// las_header.hpp; LASzip: laszip.cpp, COPC: the COPC 1.0 specification).
void note_vlr(LasHeader& h, const VlrInfo& v) {
  const LasHeader::Found f{v.offset + (v.extended ? 60 : 54), v.length, true};
  if (v.user_id == "laszip encoded" && v.record_id == 22204 && !v.extended) h.laszip = f;
  if (v.user_id == "copc" && v.record_id == 1 && !v.extended) h.copc_info = f;
  if (v.user_id == "copc" && v.record_id == 1000 && v.extended) h.copc_hierarchy = f;
  if (v.user_id == "LASF_Projection" && v.record_id == 2112) h.wkt = f;
  if (v.user_id == "LASF_Projection" && v.record_id == 34735) h.geokeys = f;
  if (v.user_id == "LASF_Projection" && v.record_id == 34736) h.geodoubles = f;
  if (v.user_id == "LASF_Spec" && v.record_id == 4) {
    h.extra_bytes = f;
    h.extra_bytes_all.push_back(f);
  }
}

/// The 60-byte header of the extended record at byte `at` (LAS 1.4 R15 section 2.7, table 23; the
/// LAS 1.3 R11 waveform data packet record has the same header, section "Extended Variable
/// Length Records"): reserved, user id (16 bytes), record id, record length after header
/// (uint64), description (32 bytes). The one check of every such record: its header and its
/// declared payload lie inside the file. `what` names the record in the error ("EVLR 2").
/// Throws FormatError "file: byte AT: file ends ... inside <what> header" or "file: byte AT+20:
/// <what> (<user id>) of N bytes runs past end of file (size S)".
VlrInfo read_extended_record(const Input& in, std::uint64_t at, const std::string& what) {
  in.need(at, 60, what + " header");
  const std::uint8_t* d = in.bytes.data();
  VlrInfo v;
  v.offset = at;
  v.extended = true;
  v.user_id = fixed_string(d + at + 2, 16);
  v.record_id = load_le<std::uint16_t>(d + at + 18);
  v.length = load_le<std::uint64_t>(d + at + 20);
  v.description = fixed_string(d + at + 28, 32);
  if (v.length > in.size() - at - 60)
    fail_at(in.name, at + 20, what + " (" + v.user_id + ") of " + std::to_string(v.length) +
                                  " bytes runs past end of file (size " + std::to_string(in.size()) + ")");
  return v;
}

}  // namespace

std::string wkt_vlr_text(const std::uint8_t* d, const LasHeader& h) {
  if (!h.wkt.present) return {};
  std::string wkt(reinterpret_cast<const char*>(d + h.wkt.at), h.wkt.len);
  while (!wkt.empty() && (wkt.back() == '\0' || std::isspace(static_cast<unsigned char>(wkt.back()))))
    wkt.pop_back();
  return wkt;
}

std::string unreadable_wkt_vlr(const std::string& name, const std::string& wkt) {
  return name + ": the OGC WKT VLR holds no CRS that GDAL reads ('" + crs_excerpt(wkt) + "')";
}

LasHeader parse_las_header(const Input& in) {
  LasHeader h;
  const std::uint8_t* d = in.bytes.data();
  const std::string& nm = in.name;
  // The version (bytes 24-25) sets the header's least size (table 3: 227 bytes for LAS 1.0-1.2,
  // 235 for 1.3, 375 for 1.4): read first, so that a file cut short is told what its own version
  // needs. Shorter than the version, it is told the least size of any version.
  if (in.size() < 26) in.need(0, 227, "LAS public header block");
  if (std::memcmp(d, "LASF", 4) != 0) fail_at(nm, 0, "expected file signature \"LASF\"");
  const int vmaj = d[24], vmin = d[25];
  const std::string version = std::to_string(vmaj) + "." + std::to_string(vmin);
  if (vmaj != 1 || vmin > 4) fail_at(nm, 24, "unsupported LAS version " + version + " (expected 1.0 to 1.4)");
  const std::uint16_t min_header = vmin <= 2 ? 227 : (vmin == 3 ? 235 : 375);
  in.need(0, min_header, "LAS " + version + " public header block");
  h.version_minor = vmin;
  h.global_encoding = load_le<std::uint16_t>(d + 6);
  std::memcpy(h.project_guid.data(), d + 8, 16);
  h.system_id = fixed_string(d + 26, 32);
  h.software = fixed_string(d + 58, 32);
  h.creation_day = load_le<std::uint16_t>(d + 90);
  h.creation_year = load_le<std::uint16_t>(d + 92);
  h.header_size = load_le<std::uint16_t>(d + 94);
  h.point_offset = load_le<std::uint32_t>(d + 96);
  const std::uint32_t n_vlr = load_le<std::uint32_t>(d + 100);
  h.pdrf_raw = d[104];
  h.pdrf = h.pdrf_raw & 0x3F;
  h.record_length = load_le<std::uint16_t>(d + 105);
  h.count = load_le<std::uint32_t>(d + 107);
  h.scale = Vec3(load_le<double>(d + 131), load_le<double>(d + 139), load_le<double>(d + 147));
  h.offset = Vec3(load_le<double>(d + 155), load_le<double>(d + 163), load_le<double>(d + 171));
  h.header_bounds.hi = Vec3(load_le<double>(d + 179), load_le<double>(d + 195), load_le<double>(d + 211));
  h.header_bounds.lo = Vec3(load_le<double>(d + 187), load_le<double>(d + 203), load_le<double>(d + 219));

  if (h.header_size < min_header)
    fail_at(nm, 94, "header size " + std::to_string(h.header_size) + " smaller than the " +
                        std::to_string(min_header) + " bytes LAS " + version + " requires");
  in.need(0, h.header_size, "LAS public header block");
  if (vmin >= 3) h.waveform_start = load_le<std::uint64_t>(d + 227);
  std::uint64_t evlr_start = 0;
  std::uint32_t n_evlr = 0;
  if (vmin >= 4) {
    evlr_start = load_le<std::uint64_t>(d + 235);
    n_evlr = load_le<std::uint32_t>(d + 243);
    const std::uint64_t count64 = load_le<std::uint64_t>(d + 247);
    // LAS 1.4 R15 table 3: the legacy count (byte 107) is 0 or equal to the 64-bit one; a file
    // where they differ was written by a tool that updated one of them only.
    const std::uint32_t legacy = h.count;
    if (count64 != 0 || h.count == 0) h.count = count64;
    if (legacy != 0 && count64 != 0 && legacy != count64)
      h.notes.push_back("legacy point count " + std::to_string(legacy) + " (byte 107) differs from the point count " +
                        std::to_string(count64) + " (byte 247): " + std::to_string(count64) + " read");
  }

  // VLRs (section 2.5): 54-byte headers, between the public header and the point data.
  if (h.point_offset < h.header_size)
    fail_at(nm, 96, "offset to point data " + std::to_string(h.point_offset) + " is inside the " +
                        std::to_string(h.header_size) + "-byte header");
  if (h.point_offset > in.size())
    fail_at(nm, 96, "offset to point data " + std::to_string(h.point_offset) + " past end of file (size " +
                        std::to_string(in.size()) + ")");
  std::uint64_t pos = h.header_size;
  for (std::uint32_t i = 0; i < n_vlr; ++i) {
    if (pos + 54 > h.point_offset)
      fail_at(nm, pos, "VLR " + std::to_string(i) + " of " + std::to_string(n_vlr) +
                           ": header runs past the start of point data at byte " + std::to_string(h.point_offset));
    VlrInfo v;
    v.offset = pos;
    v.user_id = fixed_string(d + pos + 2, 16);
    v.record_id = load_le<std::uint16_t>(d + pos + 18);
    v.length = load_le<std::uint16_t>(d + pos + 20);
    v.description = fixed_string(d + pos + 22, 32);
    if (pos + 54 + v.length > h.point_offset)
      fail_at(nm, pos + 20, "VLR " + std::to_string(i) + " (" + v.user_id + " " + std::to_string(v.record_id) +
                                ") of " + std::to_string(v.length) + " bytes runs past the start of point data at byte " +
                                std::to_string(h.point_offset));
    note_vlr(h, v);
    h.vlrs.push_back(std::move(v));
    pos += 54 + h.vlrs.back().length;
  }
  // EVLRs (section 2.7, LAS 1.4): 60-byte headers after the point data.
  h.data_end = in.size();
  if (n_evlr > 0) {
    if (evlr_start > in.size() || n_evlr > (in.size() - evlr_start) / 60)
      fail_at(nm, 235, "EVLR start " + std::to_string(evlr_start) + " with " + std::to_string(n_evlr) +
                           " EVLRs lies past end of file (size " + std::to_string(in.size()) + ")");
    // EVLRs follow the point data (LAS 1.4 R15 section 2.7): a start inside the header or the
    // VLRs would read their bytes as EVLRs (and translate would copy them as such).
    if (evlr_start < h.point_offset)
      fail_at(nm, 235, "EVLR start " + std::to_string(evlr_start) + " lies before the point data at byte " +
                           std::to_string(h.point_offset) + " (EVLRs follow the point records)");
    h.data_end = evlr_start;
    std::uint64_t ep = evlr_start;
    for (std::uint32_t i = 0; i < n_evlr; ++i) {
      VlrInfo v = read_extended_record(in, ep, "EVLR " + std::to_string(i));
      note_vlr(h, v);
      h.vlrs.push_back(std::move(v));
      ep += 60 + h.vlrs.back().length;
    }
  }
  // Waveform data packets stored in the file (global encoding bit 1, LAS 1.3+): the waveform data
  // packet record at "start of waveform data packet record" (byte 227) is an extended record
  // after the point data (LAS 1.3 R11 section "Extended Variable Length Records"; in LAS 1.4 one
  // of the EVLRs, walked above). One that is not an EVLR gets the EVLRs' checks: a start after
  // the header and VLRs, and a header and payload inside the file, so that a file cut inside its
  // waveforms is refused here and not copied by translate as if whole.
  if (vmin >= 3 && (h.global_encoding & 2u) != 0 && h.waveform_start != 0) {
    bool walked = false;
    for (const VlrInfo& v : h.vlrs) walked = walked || (v.extended && v.offset == h.waveform_start);
    if (!walked) {
      if (h.waveform_start < h.point_offset)
        fail_at(nm, 227, "start of waveform data packet record " + std::to_string(h.waveform_start) +
                             " lies before the point data at byte " + std::to_string(h.point_offset) +
                             " (the record follows the point records)");
      read_extended_record(in, h.waveform_start,
                           "waveform data packet record at byte " + std::to_string(h.waveform_start));
    }
  }
  // LAZ: the LASzip VLR decides (LASzip also sets bit 7, historically bit 6, of the PDRF byte).
  if ((h.pdrf_raw & 0xC0) != 0 && !h.laszip.present)
    fail_at(nm, 104, "point data record format byte " + std::to_string(h.pdrf_raw) +
                         " has the LAZ compression bit set but the file has no LASzip VLR "
                         "(\"laszip encoded\", record 22204)");
  if (h.laszip.present && (h.pdrf_raw & 0xC0) == 0)
    h.notes.push_back("LASzip VLR present but the compression bits of the PDRF byte are clear: read as LAZ");
  if (h.pdrf > 10) fail_at(nm, 104, "point data record format " + std::to_string(h.pdrf) + " (expected 0 to 10)");
  const int need_len = pdrf_length(h.pdrf);
  if (h.record_length < need_len)
    fail_at(nm, 105, "point record length " + std::to_string(h.record_length) + " smaller than the " +
                         std::to_string(need_len) + " bytes point data record format " + std::to_string(h.pdrf) +
                         " needs");
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(h.scale[k]) || h.scale[k] == 0.0)
      fail_at(nm, 131 + 8 * k, std::string("scale factor ") + "XYZ"[k] + " is " + std::to_string(h.scale[k]) +
                                   " (expected a finite non-zero number)");
    if (!std::isfinite(h.offset[k])) fail_at(nm, 155 + 8 * k, std::string("offset ") + "XYZ"[k] + " is not finite");
    // An offset beyond the bound puts the file's first coordinates there too (a stored 0 is the
    // offset itself). The scale is not bounded here: a large scale is refused point by point, as
    // a file whose stored integers are all small may still lie within the bound.
    if (std::abs(h.offset[k]) > kMaxCoordinate)
      fail_at(nm, 155 + 8 * k, std::string("offset ") + "XYZ"[k] + " is " + shortest_text(h.offset[k]) + " (" +
                                   coordinate_bound_expected() + ")");
  }
  return h;
}

std::string las_coordinate_source(std::int32_t stored, double scale, double offset) {
  return "stored integer " + std::to_string(stored) + " x scale " + shortest_text(scale) + " + offset " +
         shortest_text(offset);
}

void refuse_las_coordinate(const std::string& name, std::uint64_t byte, std::uint64_t index, const std::uint8_t* r,
                           const Vec3& scale, const Vec3& offset) {
  for (int k = 0; k < 3; ++k) {
    const std::int32_t stored = load_le<std::int32_t>(r + 4 * k);
    const double v = las_coordinate(stored, scale[k], offset[k]);
    if (std::abs(v) <= kMaxCoordinate) continue;
    fail_at(name, byte, beyond_coordinate_bound(index, k, v, las_coordinate_source(stored, scale[k], offset[k])));
  }
  // Not reached from a caller that decoded the record with las_coordinate (no FP contraction).
  fail_at(name, byte, "point " + std::to_string(index) + ": coordinate beyond +-" + shortest_text(kMaxCoordinate));
}

}  // namespace rayscan::io::detail
