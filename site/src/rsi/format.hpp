// The byte layout of the index file (.rsi) shared by its builder and its reader: the header's
// fields and offsets, the section ids and element sizes, the checksum and the little-endian
// field access. docs/index-format.md, "Conventions", "Header" and "Sections".
#pragma once

#include "rayscan/base/crc32c.hpp"
#include "rayscan/site/index_file.hpp"

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace rayscan::io::rsi {

namespace fs = std::filesystem;

// ---- format constants (docs/index-format.md, "Header") -------------------------------------------
constexpr char kMagic[8] = {'R', 'S', 'I', 'N', 'D', 'E', 'X', '\0'};
constexpr std::uint32_t kVersion = 4;
constexpr std::uint32_t kEndianMarker = 0x01020304;
constexpr std::uint64_t kHeaderBytes = 4096;
constexpr std::uint64_t kAlign = 4096;
constexpr std::uint32_t kMaxSections = 16;
constexpr std::size_t kTableOffset = 128;
constexpr std::size_t kEntryBytes = 32;
constexpr std::size_t kNodeBytes = 32;
constexpr std::size_t kCrcOffset = 120;
constexpr std::size_t kSpacingOffset = 112;  // float64 median nearest-neighbour spacing
constexpr std::size_t kBoundsOffset = 640;   // float64[6] exact point bounds (after the table)
constexpr std::size_t kLevelsOffset = 688;   // uint64[22] points stored at each depth 0..21
constexpr unsigned kLevels = 22;
constexpr std::size_t kEncodingOffset = 864;  // uint32 PositionEncoding (version 3)
constexpr std::size_t kScaleOffset = 872;     // float64[3] LAS grid scale (las_int32)
constexpr std::size_t kGridOffsetOffset = 896;  // float64[3] LAS grid offset (las_int32)
constexpr std::size_t kRgbMulOffset = 920;      // uint32 rgb8 multiplier (version 4): 1, 256, 257; 0 without rgb8

/// The section ids of the section table (docs/index-format.md, "Sections").
enum SectionId : std::uint32_t {
  kSources = 1, kCrs = 2, kPositions = 3, kIds = 4, kRgb = 5, kIntensity = 6,
  kClassification = 7, kGpsTime = 8, kNodes = 9, kRgb8 = 10
};
constexpr std::uint32_t kLastSection = kRgb8;
/// True for the sections of N elements (one per point slot).
constexpr bool per_point(std::uint32_t id) { return (id >= kPositions && id <= kGpsTime) || id == kRgb8; }
/// The section's name as `rayscan info` and the error messages print it ("unknown" for no id).
const char* section_name(std::uint32_t id);
/// Bytes per element of a per-point or per-node section; 1 for byte sections.
std::uint32_t elem_size(std::uint32_t id, PositionEncoding enc = PositionEncoding::float64);

static_assert(sizeof(Vec3) == 24 && alignof(Vec3) <= 8, "positions section is an array of 3 float64");
static_assert(sizeof(Rgb16) == 6, "rgb section is an array of 3 uint16");
static_assert(sizeof(IndexNodeRecord) == kNodeBytes);
static_assert(offsetof(IndexNodeRecord, lo) == 0 && offsetof(IndexNodeRecord, hi) == 12 &&
                  offsetof(IndexNodeRecord, first) == 24 && offsetof(IndexNodeRecord, packed) == 28,
              "the nodes section is read in place as IndexNodeRecord");
static_assert(std::endian::native == std::endian::little, "the index file is little-endian");

/// The next section offset at or after v (sections start at multiples of kAlign).
inline std::uint64_t align_up(std::uint64_t v) { return (v + kAlign - 1) / kAlign * kAlign; }

/// The section and header checksum (version 2: CRC-32C, hardware-accelerated; docs/index-format.md).
inline std::uint32_t crc32_of(const void* p, std::size_t n, std::uint32_t crc = 0) { return crc32c(p, n, crc); }

/// A checksum as the error messages print it (8 lower-case hex digits).
std::string hex32(std::uint32_t v);

/// Stores v at byte `off` of b (little-endian, any alignment).
template <class T>
void put(std::uint8_t* b, std::size_t off, T v) {
  std::memcpy(b + off, &v, sizeof(T));
}
/// Loads the T at byte `off` of b (little-endian, any alignment).
template <class T>
T get(const std::uint8_t* b, std::size_t off) {
  T v;
  std::memcpy(&v, b + off, sizeof(T));
  return v;
}

/// One entry of the section table (docs/index-format.md, "Header": 32 bytes each).
struct SectionEntry {
  std::uint32_t id = 0, elem = 0;
  std::uint64_t offset = 0, size = 0;
  std::uint32_t crc = 0;
};

/// The fixed header (docs/index-format.md, "Header").
struct Header {
  std::uint64_t points = 0, nodes = 0;
  AABB cell;
  OctreeConfig config;
  std::uint32_t depth = 0;
  std::uint32_t attributes = 0;
  double spacing = 0.0;  ///< median_nn_spacing_by_id of the stored points
  AABB bounds;           ///< exact bounds of the stored positions (bounds_of)
  std::array<std::uint64_t, kLevels> levels{};  ///< points per depth
  PositionEncoding encoding = PositionEncoding::float64;
  Vec3 grid_scale{1.0}, grid_offset{0.0};  ///< las_int32 only
  std::uint32_t rgb_mul = 0;  ///< the rgb8 section's multiplier (1, 256, 257), 0 without it
  std::vector<SectionEntry> sections;
};

/// The kHeaderBytes bytes of header `h`, its CRC-32C included.
std::vector<std::uint8_t> encode_header(const Header& h);

/// The sources section's text: one "size \t mtime_ns \t points \t first_id \t format \t path"
/// line per source (docs/index-format.md, "Sections").
std::string encode_sources(const std::vector<IndexSource>& src);

/// The modification time of `p` in ns since the epoch (0 when it cannot be read).
std::int64_t mtime_ns(const fs::path& p);

}  // namespace rayscan::io::rsi
