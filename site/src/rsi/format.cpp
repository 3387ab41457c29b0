// The index file's (.rsi) names, element sizes and header encoding: docs/index-format.md,
// "Header" and "Sections".
#include "format.hpp"

#include "bytes.hpp"
#include "rayscan/base/file_names.hpp"

#include <sys/stat.h>

#include <cstdio>

namespace rayscan::io {

bool is_index_file(const std::filesystem::path& path) { return lower_extension(path) == ".rsi"; }

namespace rsi {

const char* section_name(std::uint32_t id) {
  switch (id) {
    case kSources: return "sources";
    case kCrs: return "crs";
    case kPositions: return "positions";
    case kIds: return "ids";
    case kRgb: return "rgb";
    case kIntensity: return "intensity";
    case kClassification: return "classification";
    case kGpsTime: return "gps_time";
    case kNodes: return "nodes";
    case kRgb8: return "rgb8";
  }
  return "unknown";
}

std::uint32_t elem_size(std::uint32_t id, PositionEncoding enc) {
  switch (id) {
    case kPositions: return static_cast<std::uint32_t>(position_bytes(enc));
    case kIds: return 4;
    case kRgb: return 6;
    case kRgb8: return 3;
    case kIntensity: return 2;
    case kClassification: return 1;
    case kGpsTime: return 8;
    case kNodes: return kNodeBytes;
    default: return 1;
  }
}

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08x", v);
  return buf;
}

std::vector<std::uint8_t> encode_header(const Header& h) {
  std::vector<std::uint8_t> b(kHeaderBytes, 0);
  std::memcpy(b.data(), kMagic, 8);
  put<std::uint32_t>(b.data(), 8, kVersion);
  put<std::uint32_t>(b.data(), 12, static_cast<std::uint32_t>(kHeaderBytes));
  put<std::uint32_t>(b.data(), 16, kEndianMarker);
  put<std::uint32_t>(b.data(), 20, static_cast<std::uint32_t>(h.sections.size()));
  put<std::uint64_t>(b.data(), 24, h.points);
  put<std::uint64_t>(b.data(), 32, h.nodes);
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), 40 + 8 * k, h.cell.lo[k]);
    put<double>(b.data(), 64 + 8 * k, h.cell.hi[k]);
  }
  put<std::uint32_t>(b.data(), 88, static_cast<std::uint32_t>(h.config.layout));
  put<std::uint32_t>(b.data(), 92, h.config.capacity);
  put<std::uint32_t>(b.data(), 96, h.config.max_depth);
  put<std::uint32_t>(b.data(), 100, h.config.depth);
  put<std::uint32_t>(b.data(), 104, h.depth);
  put<std::uint32_t>(b.data(), 108, h.attributes);
  put<double>(b.data(), kSpacingOffset, h.spacing);
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), kBoundsOffset + 8 * k, h.bounds.lo[k]);
    put<double>(b.data(), kBoundsOffset + 24 + 8 * k, h.bounds.hi[k]);
  }
  for (unsigned d = 0; d < kLevels; ++d) put<std::uint64_t>(b.data(), kLevelsOffset + 8 * d, h.levels[d]);
  put<std::uint32_t>(b.data(), kEncodingOffset, static_cast<std::uint32_t>(h.encoding));
  for (int k = 0; k < 3; ++k) {
    put<double>(b.data(), kScaleOffset + 8 * k, h.grid_scale[k]);
    put<double>(b.data(), kGridOffsetOffset + 8 * k, h.grid_offset[k]);
  }
  put<std::uint32_t>(b.data(), kRgbMulOffset, h.rgb_mul);
  for (std::size_t i = 0; i < h.sections.size(); ++i) {
    const SectionEntry& s = h.sections[i];
    const std::size_t o = kTableOffset + i * kEntryBytes;
    put<std::uint32_t>(b.data(), o, s.id);
    put<std::uint32_t>(b.data(), o + 4, s.elem);
    put<std::uint64_t>(b.data(), o + 8, s.offset);
    put<std::uint64_t>(b.data(), o + 16, s.size);
    put<std::uint32_t>(b.data(), o + 24, s.crc);
  }
  put<std::uint32_t>(b.data(), kCrcOffset, crc32_of(b.data(), b.size()));
  return b;
}

std::string encode_sources(const std::vector<IndexSource>& src) {
  std::string out;
  for (const IndexSource& s : src)
    out += std::to_string(s.size) + "\t" + std::to_string(s.mtime_ns) + "\t" + std::to_string(s.points) +
           "\t" + std::to_string(s.first_id) + "\t" + s.format + "\t" + s.path + "\n";
  return out;
}

std::int64_t mtime_ns(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return 0;
  return static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
}

}  // namespace rsi
}  // namespace rayscan::io
