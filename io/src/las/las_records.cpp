// read_las_records(): the raw point records of LAS/LAZ files (see rayscan/io/las_records.hpp).
// Header and (E)VLR headers: parse_las_header (las_header.hpp).
#include "rayscan/io/las_records.hpp"

#include "laz/laz.hpp"
#include "las/las_header.hpp"

#include <fstream>
#include <iterator>

namespace rayscan::io {

LasRecords read_las_records(std::span<const std::uint8_t> bytes, const std::string& name, std::uint32_t layers) {
  using detail::fail_at;
  const detail::Input in{bytes, name, {}};
  const detail::LasHeader h = detail::parse_las_header(in);
  LasRecords r;
  r.version_minor = h.version_minor;
  r.pdrf = h.pdrf;
  r.record_length = h.record_length;
  r.count = h.count;
  r.point_offset = h.point_offset;
  r.copc = h.copc_info.present;
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
