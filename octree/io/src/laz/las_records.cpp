// read_las_records(): the raw point records of LAS/LAZ files (see rayscan/io/las_records.hpp).
// Header fields: ASPRS LAS 1.4 R15 section 2.4 table 3; VLR headers: section 2.5.
#include "rayscan/io/las_records.hpp"

#include "laz.hpp"

#include <fstream>
#include <iterator>

namespace rayscan::io {

namespace laz {

LasHeaderLite parse_header_lite(const Input& in) {
  using detail::fail_at;
  using detail::load_le;
  const std::string& name = in.name;
  const std::uint8_t* d = in.bytes.data();
  in.need(0, 227, "LAS public header block");
  if (std::memcmp(d, "LASF", 4) != 0) fail_at(name, 0, "expected file signature \"LASF\"");
  LasHeaderLite h;
  h.version_minor = d[25];
  if (d[24] != 1 || h.version_minor > 4) fail_at(name, 24, "unsupported LAS version (expected 1.0 to 1.4)");
  h.header_size = load_le<std::uint16_t>(d + 94);
  h.point_offset = load_le<std::uint32_t>(d + 96);
  const std::uint32_t n_vlr = load_le<std::uint32_t>(d + 100);
  h.pdrf_raw = d[104];
  h.pdrf = h.pdrf_raw & 0x3F;
  h.record_length = load_le<std::uint16_t>(d + 105);
  h.count = load_le<std::uint32_t>(d + 107);
  h.scale = Vec3(load_le<double>(d + 131), load_le<double>(d + 139), load_le<double>(d + 147));
  h.offset = Vec3(load_le<double>(d + 155), load_le<double>(d + 163), load_le<double>(d + 171));
  h.data_end = in.size();
  std::uint64_t evlr_start = 0;
  std::uint32_t n_evlr = 0;
  if (h.version_minor >= 4) {
    in.need(0, 375, "LAS 1.4 public header block");
    evlr_start = load_le<std::uint64_t>(d + 235);
    n_evlr = load_le<std::uint32_t>(d + 243);
    const std::uint64_t c64 = load_le<std::uint64_t>(d + 247);
    if (c64 != 0 || h.count == 0) h.count = c64;
  }
  if (h.point_offset < h.header_size || h.point_offset > in.size())
    fail_at(name, 96, "offset to point data " + std::to_string(h.point_offset) + " outside [header size, file size]");
  if (h.pdrf > 10) fail_at(name, 104, "point data record format " + std::to_string(h.pdrf) + " (expected 0 to 10)");
  if (h.record_length == 0) fail_at(name, 105, "point record length 0");
  std::uint64_t pos = h.header_size;
  for (std::uint32_t i = 0; i < n_vlr; ++i) {
    if (pos + 54 > h.point_offset) fail_at(name, pos, "VLR " + std::to_string(i) + " header runs into the point data");
    const std::string user = detail::fixed_string(d + pos + 2, 16);
    const std::uint16_t id = load_le<std::uint16_t>(d + pos + 18);
    const std::uint16_t len = load_le<std::uint16_t>(d + pos + 20);
    if (pos + 54 + len > h.point_offset) fail_at(name, pos + 20, "VLR " + std::to_string(i) + " runs into the point data");
    if (user == "laszip encoded" && id == 22204) h.laszip = {pos + 54, len, true};
    if (user == "copc" && id == 1) h.copc_info = {pos + 54, len, true};
    pos += 54 + len;
  }
  if (n_evlr > 0) {
    if (evlr_start < h.point_offset || evlr_start > in.size() || n_evlr > (in.size() - evlr_start) / 60)
      fail_at(name, 235, "EVLR start " + std::to_string(evlr_start) + " with " + std::to_string(n_evlr) +
                             " EVLRs lies outside the file (size " + std::to_string(in.size()) + ")");
    h.data_end = evlr_start;
    std::uint64_t ep = evlr_start;
    for (std::uint32_t i = 0; i < n_evlr; ++i) {
      in.need(ep, 60, "EVLR " + std::to_string(i) + " header");
      const std::string user = detail::fixed_string(d + ep + 2, 16);
      const std::uint16_t id = load_le<std::uint16_t>(d + ep + 18);
      const std::uint64_t len = load_le<std::uint64_t>(d + ep + 20);
      if (len > in.size() - ep - 60)
        fail_at(name, ep + 20, "EVLR " + std::to_string(i) + " of " + std::to_string(len) + " bytes runs past the end of the file");
      if (user == "copc" && id == 1000) h.copc_hierarchy = {ep + 60, len, true};
      ep += 60 + len;
    }
  }
  return h;
}

}  // namespace laz

LasRecords read_las_records(std::span<const std::uint8_t> bytes, const std::string& name, std::uint32_t layers) {
  using detail::fail_at;
  const detail::Input in{bytes, name, {}};
  const laz::LasHeaderLite h = laz::parse_header_lite(in);
  LasRecords r;
  r.version_minor = h.version_minor;
  r.pdrf = h.pdrf;
  r.record_length = h.record_length;
  r.count = h.count;
  r.point_offset = h.point_offset;
  r.copc = h.copc_info.present;
  if ((h.pdrf_raw & 0xC0) != 0 && !h.laszip.present)
    fail_at(name, 104, "compression bit set in the point data record format byte but no LASzip VLR");
  if (h.laszip.present) {
    r.compressed = true;
    const laz::LaszipVlr v = laz::parse_laszip_vlr(bytes.data() + h.laszip.at, h.laszip.len, name, h.laszip.at,
                                                   r.pdrf, r.record_length);
    const std::vector<laz::Chunk> chunks = laz::read_chunk_table(in, v, r.point_offset, h.data_end, r.count, r.notes);
    r.chunks = chunks.size();
    r.records.resize(static_cast<std::size_t>(r.count) * r.record_length);
    laz::decompress_all(in, v, chunks, r.records.data(), layers);
  } else {
    if (r.count > (h.data_end - r.point_offset) / r.record_length)
      fail_at(name, r.version_minor >= 4 ? 247 : 107,
              "header announces " + std::to_string(r.count) + " records of " + std::to_string(r.record_length) +
                  " bytes but only " + std::to_string(h.data_end - r.point_offset) + " bytes follow");
    r.records.assign(bytes.data() + r.point_offset, bytes.data() + r.point_offset + r.count * r.record_length);
  }
  return r;
}

LasRecords read_las_records(const std::filesystem::path& path, std::uint32_t layers) {
  const laz::FileMap m(path);
  return read_las_records(m.bytes(), path.string(), layers);
}

}  // namespace rayscan::io
