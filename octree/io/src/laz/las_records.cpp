// read_las_records(): the raw point records of LAS/LAZ files (see rayscan/io/las_records.hpp).
// Header fields: ASPRS LAS 1.4 R15 section 2.4 table 3; VLR headers: section 2.5.
#include "rayscan/io/las_records.hpp"

#include "laz.hpp"

#include <fstream>
#include <iterator>

namespace rayscan::io {

LasRecords read_las_records(std::span<const std::uint8_t> bytes, const std::string& name, std::uint32_t layers) {
  using detail::fail_at;
  using detail::load_le;
  const detail::Input in{bytes, name, {}};
  const std::uint8_t* d = bytes.data();
  in.need(0, 227, "LAS public header block");
  if (std::memcmp(d, "LASF", 4) != 0) fail_at(name, 0, "expected file signature \"LASF\"");
  LasRecords r;
  r.version_minor = d[25];
  if (d[24] != 1 || r.version_minor > 4) fail_at(name, 24, "unsupported LAS version (expected 1.0 to 1.4)");
  const std::uint16_t header_size = load_le<std::uint16_t>(d + 94);
  r.point_offset = load_le<std::uint32_t>(d + 96);
  const std::uint32_t n_vlr = load_le<std::uint32_t>(d + 100);
  const std::uint8_t pdrf_raw = d[104];
  r.pdrf = pdrf_raw & 0x3F;
  r.record_length = load_le<std::uint16_t>(d + 105);
  r.count = load_le<std::uint32_t>(d + 107);
  std::uint64_t data_end = in.size();
  if (r.version_minor >= 4) {
    in.need(0, 375, "LAS 1.4 public header block");
    const std::uint64_t evlr_start = load_le<std::uint64_t>(d + 235);
    const std::uint32_t n_evlr = load_le<std::uint32_t>(d + 243);
    const std::uint64_t c64 = load_le<std::uint64_t>(d + 247);
    if (c64 != 0 || r.count == 0) r.count = c64;
    if (n_evlr > 0 && evlr_start >= r.point_offset && evlr_start < data_end) data_end = evlr_start;
  }
  if (r.point_offset < header_size || r.point_offset > in.size())
    fail_at(name, 96, "offset to point data " + std::to_string(r.point_offset) + " outside [header size, file size]");
  if (r.pdrf > 10) fail_at(name, 104, "point data record format " + std::to_string(r.pdrf) + " (expected 0 to 10)");
  if (r.record_length == 0) fail_at(name, 105, "point record length 0");
  std::uint64_t pos = header_size;
  const std::uint8_t* laszip = nullptr;
  std::uint64_t laszip_len = 0, laszip_at = 0;
  for (std::uint32_t i = 0; i < n_vlr; ++i) {
    if (pos + 54 > r.point_offset) fail_at(name, pos, "VLR " + std::to_string(i) + " header runs into the point data");
    const std::string user = detail::fixed_string(d + pos + 2, 16);
    const std::uint16_t id = load_le<std::uint16_t>(d + pos + 18);
    const std::uint16_t len = load_le<std::uint16_t>(d + pos + 20);
    if (pos + 54 + len > r.point_offset) fail_at(name, pos + 20, "VLR " + std::to_string(i) + " runs into the point data");
    if (user == "laszip encoded" && id == 22204) laszip = d + pos + 54, laszip_len = len, laszip_at = pos + 54;
    if (user == "copc" && id == 1) r.copc = true;
    pos += 54 + len;
  }
  if ((pdrf_raw & 0xC0) != 0 && laszip == nullptr)
    fail_at(name, 104, "compression bit set in the point data record format byte but no LASzip VLR");
  if (laszip != nullptr) {
    r.compressed = true;
    const laz::LaszipVlr v = laz::parse_laszip_vlr(laszip, laszip_len, name, laszip_at, r.pdrf, r.record_length);
    const std::vector<laz::Chunk> chunks = laz::read_chunk_table(in, v, r.point_offset, data_end, r.count, r.notes);
    r.chunks = chunks.size();
    r.records.resize(static_cast<std::size_t>(r.count) * r.record_length);
    laz::decompress_all(in, v, chunks, r.records.data(), layers);
  } else {
    if (r.count > (data_end - r.point_offset) / r.record_length)
      fail_at(name, r.version_minor >= 4 ? 247 : 107,
              "header announces " + std::to_string(r.count) + " records of " + std::to_string(r.record_length) +
                  " bytes but only " + std::to_string(data_end - r.point_offset) + " bytes follow");
    r.records.assign(d + r.point_offset, d + r.point_offset + r.count * r.record_length);
  }
  return r;
}

LasRecords read_las_records(const std::filesystem::path& path, std::uint32_t layers) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw FormatError(path.string() + ": cannot open file");
  const std::vector<std::uint8_t> bytes{std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  return read_las_records(bytes, path.string(), layers);
}

}  // namespace rayscan::io
