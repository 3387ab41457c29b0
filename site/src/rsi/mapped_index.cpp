// The memory-mapped reader of the index file (.rsi): MappedIndex::open with its checks in the
// format's order, the deep checks of the node records and ids, and the accessors that need the
// map. docs/index-format.md, "Header", "Sections" and "Opening and validation".
#include "format.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/number_text.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <fstream>
#include <memory>
#include <new>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace rayscan::io {

using namespace rsi;  // the format's constants and field access (format.hpp)

/// The open file and its read-only map, owned by the index (moves keep its address), with what
/// the checked ids view and the read-ahead thread need.
struct MappedIndex::Map {
  int fd = -1;
  void* p = nullptr;
  std::size_t n = 0;
  // What a checked IdView's handler needs (MappedIndex::ids(); stable across moves of the index).
  std::string path;              ///< the file, for error messages
  std::uint64_t ids_offset = 0;  ///< byte offset of the ids section
  const PointIndex* ids = nullptr;
  std::size_t points = 0;
  bool trust_ids = false;  ///< IndexOpenOptions::trust_ids: ids() returns an unchecked view
  // IndexOpenOptions::read_ahead: the background thread asking for the file's pages, and its
  // stop flag (set and joined before the unmap).
  std::thread ahead;
  std::atomic<bool> stop{false};
  /// Starts reading bytes [first, first + len) (the nodes section), then, when `whole`, the whole
  /// file from its start, in 4 MiB sequential reads into a buffer that is thrown away: the pages
  /// land in the page cache, not in this process's resident set, and the queries' faults find
  /// them there. (MADV_WILLNEED in 64 MiB steps was tried: a cold 2e8 render took 24 s against
  /// 31 s without and 7.2 s with these reads; bench/notes/.)
  /// The read-ahead only warms the page cache, so a thread that cannot start or a buffer that
  /// cannot be allocated skips it rather than failing the open (or terminating the process: an
  /// exception leaving a thread's function would).
  void start_read_ahead(std::uint64_t first, std::uint64_t len, bool whole) noexcept {
    try {
      ahead = std::thread([this, first, len, whole]() noexcept { read_ahead(first, len, whole); });
    } catch (const std::exception&) {  // (std::system_error: no thread; std::bad_alloc)
    }
  }
  void read_ahead(std::uint64_t first, std::uint64_t len, bool whole) noexcept {
    constexpr std::uint64_t kStep = std::uint64_t{4} << 20;
    std::unique_ptr<std::uint8_t[]> buf(new (std::nothrow) std::uint8_t[kStep]);
    if (!buf) return;
    const auto ask = [&](std::uint64_t b, std::uint64_t e) {
      for (std::uint64_t o = b / 4096 * 4096; o < e && !stop.load(std::memory_order_relaxed); o += kStep)
        if (::pread(fd, buf.get(), static_cast<std::size_t>(std::min(kStep, n - o)), static_cast<off_t>(o)) <= 0) return;
    };
    const std::uint64_t end = std::min<std::uint64_t>(n, first + len);
    ask(first, end);
    if (whole) ask(0, first), ask(end, n);
  }
  ~Map() {
    stop = true;
    if (ahead.joinable()) ahead.join();
    if (p != nullptr) ::munmap(p, n);
    if (fd >= 0) ::close(fd);
  }
};

namespace {
/// MemAvailable of /proc/meminfo in bytes (0 when unknown).
std::uint64_t available_memory() {
  std::ifstream f("/proc/meminfo");
  std::string key;
  std::uint64_t kb = 0;
  std::string unit;
  while (f >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024;
  return 0;
}
}  // namespace

namespace {

/// Throws the IndexError of a check of open(): "<file>: byte <offset>: <what>".
struct Fail {
  const std::string& nm;
  [[noreturn]] void operator()(std::uint64_t off, const std::string& what) const {
    throw IndexError(nm + ": byte " + std::to_string(off) + ": " + what);
  }
};

/// The header's fields as open() reads them, and the section count.
struct OpenHeader {
  Header h;
  std::uint32_t nsec = 0;
};

/// The header (docs/index-format.md, "Header"), checked in the order the format lists: the
/// signature, version, header size, byte order and CRC, then each field as it is read.
OpenHeader read_header(const std::uint8_t* b, const Fail& fail) {
  if (std::memcmp(b, kMagic, 8) != 0) fail(0, "expected the signature \"RSINDEX\" (not a rayscan index file)");
  const auto version = get<std::uint32_t>(b, 8);
  if (version != kVersion)
    fail(8, "index format version " + std::to_string(version) + "; this rayscan reads version " +
                std::to_string(kVersion) + " (rebuild the index with `rayscan index`)");
  if (get<std::uint32_t>(b, 12) != kHeaderBytes) fail(12, "header size must be 4096");
  if (get<std::uint32_t>(b, 16) != kEndianMarker) fail(16, "byte-order marker 0x01020304 expected (little-endian)");
  {
    std::vector<std::uint8_t> hb(b, b + kHeaderBytes);
    put<std::uint32_t>(hb.data(), kCrcOffset, 0);
    const std::uint32_t want = get<std::uint32_t>(b, kCrcOffset), have = crc32_of(hb.data(), hb.size());
    if (want != have) fail(kCrcOffset, "header checksum " + hex32(have) + ", expected " + hex32(want) + " (corrupted)");
  }
  OpenHeader o;
  Header& h = o.h;
  o.nsec = get<std::uint32_t>(b, 20);
  if (o.nsec > kMaxSections) fail(20, "section count " + std::to_string(o.nsec) + " above 16");
  h.points = get<std::uint64_t>(b, 24);
  h.nodes = get<std::uint64_t>(b, 32);
  for (int k = 0; k < 3; ++k) {
    h.cell.lo[k] = get<double>(b, 40 + 8 * k);
    h.cell.hi[k] = get<double>(b, 64 + 8 * k);
  }
  const auto layout = get<std::uint32_t>(b, 88);
  if (layout > 2) fail(88, "layout " + std::to_string(layout) + " (expected 0..2)");
  h.config.layout = static_cast<OctreeLayout>(layout);
  h.config.capacity = get<std::uint32_t>(b, 92);
  h.config.max_depth = get<std::uint32_t>(b, 96);
  h.config.depth = get<std::uint32_t>(b, 100);
  h.depth = get<std::uint32_t>(b, 104);
  if (h.depth > 21) fail(104, "depth " + std::to_string(h.depth) + " (expected 0..21, the Morton code depth)");
  h.attributes = get<std::uint32_t>(b, 108);
  h.spacing = get<double>(b, kSpacingOffset);
  if (!(h.spacing >= 0.0) || !std::isfinite(h.spacing))
    fail(kSpacingOffset, "median nearest-neighbour spacing " + std::to_string(h.spacing) + " (expected a finite number >= 0)");
  for (int k = 0; k < 3; ++k) {
    h.bounds.lo[k] = get<double>(b, kBoundsOffset + 8 * k);
    h.bounds.hi[k] = get<double>(b, kBoundsOffset + 24 + 8 * k);
  }
  if (h.points >= 0xFFFFFFFFull) fail(24, "point count " + std::to_string(h.points) + " above 2^32 - 2");
  // The exact bounds feed the auto radius, the overview camera and `info`: a non-empty file's are a
  // finite, non-reversed box (a NaN here once surfaced as "use a cell of at least nan").
  if (h.points > 0)
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(h.bounds.lo[k]) || !std::isfinite(h.bounds.hi[k]) || h.bounds.lo[k] > h.bounds.hi[k])
        fail(kBoundsOffset + 8 * k, "point bounds of axis " + std::to_string(k) + " [" + std::to_string(h.bounds.lo[k]) +
                                        ", " + std::to_string(h.bounds.hi[k]) + "] (expected finite, minimum <= maximum)");
  std::uint64_t sum = 0;
  for (unsigned d = 0; d < kLevels; ++d) {
    const auto v = get<std::uint64_t>(b, kLevelsOffset + 8 * d);
    if (v > h.points || (d > h.depth && v != 0))
      fail(kLevelsOffset + 8 * d, "points at depth " + std::to_string(d) + ": " + std::to_string(v) +
                                      " (the header says " + std::to_string(h.points) + " points, depth " +
                                      std::to_string(h.depth) + ")");
    sum += v;
    h.levels[d] = v;
  }
  if (sum != h.points)
    fail(kLevelsOffset, "points per level sum to " + std::to_string(sum) + ", the header says " + std::to_string(h.points));
  const auto enc_id = get<std::uint32_t>(b, kEncodingOffset);
  if (enc_id > static_cast<std::uint32_t>(PositionEncoding::las_int32))
    fail(kEncodingOffset, "positions encoding " + std::to_string(enc_id) +
                              " (expected 0 float64, 1 float32 or 2 LAS int32 grid)");
  h.encoding = static_cast<PositionEncoding>(enc_id);
  if (h.encoding == PositionEncoding::las_int32)
    for (int k = 0; k < 3; ++k) {
      h.grid_scale[k] = get<double>(b, kScaleOffset + 8 * k);
      h.grid_offset[k] = get<double>(b, kGridOffsetOffset + 8 * k);
      if (!std::isfinite(h.grid_scale[k]) || h.grid_scale[k] == 0.0 || !std::isfinite(h.grid_offset[k]))
        fail(kScaleOffset, "LAS grid scale/offset of axis " + std::to_string(k) + " not finite and non-zero");
    }
  return o;
}

/// The section table as read and checked by read_sections: the entries, each present section by
/// id, and the table as MappedIndex::sections() lists it.
struct SectionTable {
  std::vector<SectionEntry> secs;
  std::array<const SectionEntry*, kLastSection + 1> by_id{};
  std::vector<IndexSectionInfo> infos;
};

/// Reads the `nsec` entries of the section table into `t` (docs/index-format.md, "Opening and
/// validation" 1): known ids, no duplicates, element sizes, aligned offsets, inside the file,
/// sizes of N or M elements; the CRC of the small metadata sections always, of every section
/// when `verify_all`.
void read_sections(const std::uint8_t* b, std::uint64_t size, const OpenHeader& oh, bool verify_all, const Fail& fail,
                   SectionTable& t) {
  const Header& hd = oh.h;
  t.secs.resize(oh.nsec);
  for (std::uint32_t i = 0; i < oh.nsec; ++i) {
    const std::size_t o = kTableOffset + i * kEntryBytes;
    SectionEntry& e = t.secs[i];
    e.id = get<std::uint32_t>(b, o);
    e.elem = get<std::uint32_t>(b, o + 4);
    e.offset = get<std::uint64_t>(b, o + 8);
    e.size = get<std::uint64_t>(b, o + 16);
    e.crc = get<std::uint32_t>(b, o + 24);
    if (e.id < kSources || e.id > kLastSection) fail(o, "unknown section id " + std::to_string(e.id));
    const std::string sn = std::string("section ") + section_name(e.id);
    t.infos.push_back({section_name(e.id), e.offset, e.size});
    if (t.by_id[e.id] != nullptr) fail(o, sn + " appears twice");
    t.by_id[e.id] = &e;
    if (e.elem != elem_size(e.id, hd.encoding))
      fail(o + 4, sn + ": element size " + std::to_string(e.elem) + ", expected " +
                      std::to_string(elem_size(e.id, hd.encoding)));
    if (e.offset % kAlign != 0 || e.offset < kHeaderBytes)
      fail(o + 8, sn + ": offset " + std::to_string(e.offset) + " not a multiple of 4096 after the header");
    if (e.offset > size || e.size > size - e.offset)
      fail(o + 16, sn + " [" + std::to_string(e.offset) + ", " + std::to_string(e.offset + e.size) +
                       ") runs past the end of the file (size " + std::to_string(size) + "; truncated)");
    std::uint64_t expect = e.size;
    if (per_point(e.id)) expect = hd.points * e.elem;
    if (e.id == kNodes) expect = hd.nodes * e.elem;
    if (e.size != expect) fail(o + 16, sn + ": " + std::to_string(e.size) + " bytes, expected " + std::to_string(expect));
    const bool meta = e.id == kSources || e.id == kCrs;
    if (verify_all || meta) {
      const std::uint32_t have = crc32_of(b + e.offset, e.size);
      if (have != e.crc)
        throw IndexError(fail.nm + ": " + sn + " (byte " + std::to_string(e.offset) + "): checksum " + hex32(have) +
                         ", expected " + hex32(e.crc) + " (corrupted)");
    }
  }
  // The file ends at the end of its last section (docs/index-format.md, "Conventions"): trailing
  // bytes would also move a file past the size up to which open() runs the deep checks.
  std::uint64_t end = kHeaderBytes;
  for (const SectionEntry& e : t.secs) end = std::max(end, e.offset + e.size);
  if (size != end)
    fail(end, std::to_string(size - end) + " bytes after the end of the last section (expected the file to end at byte " +
                  std::to_string(end) + ")");
}

/// The checks of the sections present against each other and the header: the required ones, the
/// optional ones exactly as the attribute bits say, the rgb8 multiplier, the node count and the
/// root cell. Returns the rgb8 multiplier.
std::uint32_t check_section_set(const std::uint8_t* b, const Header& hd, const SectionTable& t, const Fail& fail) {
  const auto& by_id = t.by_id;
  const AttributeSet attrs{hd.attributes};
  for (std::uint32_t id : {kSources, kCrs, kPositions, kNodes})
    if (by_id[id] == nullptr) fail(kTableOffset, std::string("missing section ") + section_name(id));
  if (by_id[kRgb] && by_id[kRgb8]) fail(kTableOffset, "sections rgb and rgb8 both present (expected one)");
  const std::pair<Attribute, std::uint32_t> attr_sec[] = {{Attribute::id, kIds}, {Attribute::rgb, kRgb},
                                                           {Attribute::intensity, kIntensity},
                                                           {Attribute::classification, kClassification},
                                                           {Attribute::gps_time, kGpsTime}};
  for (const auto& [a, id] : attr_sec)
    if (attrs.has(a) != (by_id[id] != nullptr || (id == kRgb && by_id[kRgb8] != nullptr)))
      fail(108, std::string("attribute set and sections disagree on ") + section_name(id));
  if ((attrs.bits & ~kIndexAttributes.bits) != 0)
    fail(108, "stored attributes " + std::to_string(attrs.bits) + " (expected a subset of " +
                  std::to_string(kIndexAttributes.bits) + ": " + kIndexAttributes.to_string() + ")");
  const auto rgb_mul = get<std::uint32_t>(b, kRgbMulOffset);
  if (by_id[kRgb8] ? rgb_mul != 1 && rgb_mul != 256 && rgb_mul != 257 : rgb_mul != 0)
    fail(kRgbMulOffset, "rgb8 multiplier " + std::to_string(rgb_mul) +
                            (by_id[kRgb8] ? " (expected 1, 256 or 257)" : " (expected 0 without an rgb8 section)"));
  if ((hd.points > 0) != (hd.nodes > 0))
    fail(32, "node count " + std::to_string(hd.nodes) + " for " + std::to_string(hd.points) + " points");
  if (hd.nodes >= 0xFFFFFFFFull) fail(32, "node count above 2^32 - 2");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(hd.cell.lo[k]) || !std::isfinite(hd.cell.hi[k]) || !(hd.cell.hi[k] > hd.cell.lo[k]))
      fail(40, "root cell is not a finite box");
  return rgb_mul;
}

/// "[lo, hi]" of axis `k` of the node record `r` in world units (the root cell's corner `origin`
/// added back, as MappedIndex::node_bounds does), for the node box messages.
std::string world_interval(const IndexNodeRecord& r, const Vec3& origin, int k) {
  std::string s(1, '[');
  s += shortest_text(origin[k] + static_cast<double>(r.lo[k])) + ", " +
       shortest_text(origin[k] + static_cast<double>(r.hi[k])) + "]";
  return s;
}

/// The root node's box (docs/index-format.md, "Opening and validation" 1), at every open: on each
/// axis minimum <= maximum and inside the header's exact point bounds, which it rounds outwards
/// (OctreeRules::float_bound: one float ulp past the float nearest to the offset from the root
/// cell's corner). The allowance, 2^-20 of the offsets plus 2^-48 of the absolute coordinates, is
/// well above that rounding and the double subtractions' (the entry grid's 2^-20 of the root
/// edge, likewise). O(1): one record; the boxes below it are checked with the other records
/// (verify_nodes). `node_off`: the nodes section's byte offset. Throws IndexError.
void check_root_box(const IndexNodeRecord& r, const Header& hd, std::uint64_t node_off, const Fail& fail) {
  for (int k = 0; k < 3; ++k) {
    const std::string what = "node 0 (the root): box of axis " + std::to_string(k) + " ";
    if (!(r.lo[k] <= r.hi[k]))
      fail(node_off + 4 * k, what + world_interval(r, hd.cell.lo, k) + " (expected minimum <= maximum)");
    const double lo = hd.bounds.lo[k] - hd.cell.lo[k], hi = hd.bounds.hi[k] - hd.cell.lo[k];
    const double coord = std::max({std::abs(hd.bounds.lo[k]), std::abs(hd.bounds.hi[k]), std::abs(hd.cell.lo[k])});
    const double tol = std::ldexp(std::max(std::abs(lo), std::abs(hi)), -20) + std::ldexp(coord, -48);
    const bool below = !(static_cast<double>(r.lo[k]) >= lo - tol), above = !(static_cast<double>(r.hi[k]) <= hi + tol);
    if (below || above)
      fail(node_off + (below ? 0 : 12) + 4 * k,
           what + world_interval(r, hd.cell.lo, k) + " (expected inside the header's point bounds [" +
               shortest_text(hd.bounds.lo[k]) + ", " + shortest_text(hd.bounds.hi[k]) + "], to float rounding)");
  }
}

/// The sources section: "size \t mtime_ns \t points \t first_id \t format \t path" lines whose
/// points sum to the header's N. `off`: the section's byte offset (error messages).
std::vector<IndexSource> read_sources(std::string_view text, std::uint64_t off, std::uint64_t points, const Fail& fail) {
  std::vector<IndexSource> out;
  std::istringstream in{std::string(text)};
  std::string line;
  std::uint64_t sum = 0;
  while (std::getline(in, line)) {
    IndexSource s;
    std::istringstream ls(line);
    std::string f[6];
    for (int k = 0; k < 5; ++k) std::getline(ls, f[k], '\t');
    std::getline(ls, f[5]);
    try {
      s.size = std::stoull(f[0]);
      s.mtime_ns = std::stoll(f[1]);
      s.points = std::stoull(f[2]);
      s.first_id = std::stoull(f[3]);
    } catch (const std::exception&) {
      fail(off, "section sources: malformed line '" + line.substr(0, 60) + "'");
    }
    s.format = f[4];
    s.path = f[5];
    if (s.points > points - sum)  // checked before adding, so a sum past 2^64 cannot wrap to N
      fail(off, "section sources: the point counts exceed the header's " + std::to_string(points) + " points");
    sum += s.points;
    out.push_back(s);
  }
  if (sum != points)
    fail(off, "section sources: " + std::to_string(sum) + " points, header says " + std::to_string(points));
  return out;
}

/// Throws IndexError when a source file that still exists changed size or modification time
/// since the build (a moved index is self-contained: missing sources are fine).
void check_sources_unchanged(const std::string& nm, const std::vector<IndexSource>& sources) {
  for (const IndexSource& s : sources) {
    std::error_code ec;
    if (!fs::exists(s.path, ec)) continue;  // a moved index is self-contained
    const std::uint64_t sz = fs::file_size(s.path, ec);
    const std::int64_t mt = mtime_ns(s.path);
    if (!ec && (sz != s.size || mt != s.mtime_ns))
      throw IndexError(nm + ": source " + s.path + " changed since the index was built (size " + std::to_string(s.size) +
                       " -> " + std::to_string(sz) + ", mtime " + std::to_string(s.mtime_ns) + " -> " +
                       std::to_string(mt) + " ns): rebuild it with `rayscan index`");
  }
}

}  // namespace

MappedIndex::MappedIndex(MappedIndex&&) noexcept = default;
MappedIndex& MappedIndex::operator=(MappedIndex&&) noexcept = default;
MappedIndex::~MappedIndex() = default;

std::uint64_t MappedIndex::file_bytes() const { return map_ ? map_->n : 0; }

MappedIndex MappedIndex::open(const fs::path& path, const IndexOpenOptions& opt) {
  const std::string nm = path.string();
  const Fail fail{nm};
  MappedIndex x;
  x.path_ = path;
  x.map_ = std::make_unique<Map>();
  Map& m = *x.map_;
  // The input policy (rayscan/base/input_file.hpp): regular files only, opened without blocking.
  std::uint64_t size = 0;
  try {
    InputFile in(path);
    size = in.size();
    m.fd = ::dup(in.fd());
  } catch (const InputFileError& e) {
    throw IndexError(e.what());
  }
  if (m.fd < 0) throw IndexError(nm + ": cannot open index file: " + std::strerror(errno));
  if (size < kHeaderBytes)
    fail(size, "file of " + std::to_string(size) + " bytes is shorter than the " + std::to_string(kHeaderBytes) +
                   "-byte index header (truncated or not an index)");
  m.n = static_cast<std::size_t>(size);
  m.p = ::mmap(nullptr, m.n, PROT_READ, MAP_SHARED, m.fd, 0);
  if (m.p == MAP_FAILED) {
    m.p = nullptr;
    throw IndexError(nm + ": cannot memory-map: " + std::strerror(errno));
  }
  const auto* b = static_cast<const std::uint8_t*>(m.p);
  const OpenHeader oh = read_header(b, fail);
  const Header& hd = oh.h;
  x.points_ = hd.points;
  x.node_count_ = hd.nodes;
  x.cell_ = hd.cell;
  x.config_ = hd.config;
  x.depth_ = hd.depth;
  x.attrs_ = AttributeSet{hd.attributes};
  x.spacing_ = hd.spacing;
  x.bounds_ = hd.bounds;
  const bool verify_all = opt.verify == IndexOpenOptions::Verify::always ||
                          (opt.verify == IndexOpenOptions::Verify::automatic && size <= opt.deep_check_bytes);
  x.verified_ = verify_all;
  SectionTable t;
  read_sections(b, size, oh, verify_all, fail, t);
  x.sections_ = std::move(t.infos);
  const std::uint32_t rgb_mul = check_section_set(b, hd, t, fail);
  const auto& by_id = t.by_id;
  auto at = [&](std::uint32_t id) { return b + by_id[id]->offset; };
  x.nodes_ = reinterpret_cast<const IndexNodeRecord*>(at(kNodes));
  x.positions_ = PositionView(hd.encoding, at(kPositions), x.points_, hd.grid_scale, hd.grid_offset);
  if (by_id[kIds]) {
    x.ids_ = reinterpret_cast<const PointIndex*>(at(kIds));
    x.ids_offset_ = by_id[kIds]->offset;
  }
  if (by_id[kRgb]) x.rgb_ = std::span<const Rgb16>(reinterpret_cast<const Rgb16*>(at(kRgb)), x.points_);
  if (by_id[kRgb8]) x.rgb_ = RgbView(at(kRgb8), x.points_, rgb_mul);
  if (by_id[kIntensity]) x.intensity_ = {reinterpret_cast<const std::uint16_t*>(at(kIntensity)), x.points_};
  if (by_id[kClassification]) x.classification_ = {at(kClassification), x.points_};
  if (by_id[kGpsTime]) x.gps_ = {reinterpret_cast<const double*>(at(kGpsTime)), x.points_};
  x.crs_.assign(reinterpret_cast<const char*>(at(kCrs)), by_id[kCrs]->size);

  // The node records are checked at every open but metadata_only (one sequential pass over the
  // nodes section, about 2 of the file's 14-26 bytes per point): a corrupted record is then an IndexError here, never a
  // traversal whose work grows without bound (a root rewritten as one leaf of all N points made
  // kNN 180x slower; random bytes made the surfel set-up run for hours). The ids (N x 4 bytes) are
  // checked with the CRCs; without them ids() returns a checked view: every id read is compared
  // with N (consumers index per-point arrays by id), without a pass over all N ids before the
  // first query. With metadata_only (a file this process just wrote) the accessors still
  // sanitise every record they return (MappedIndex::child_count / node_points), so no traversal
  // reads outside the mapping.
  if (x.node_count_ > 0) check_root_box(x.nodes_[0], hd, by_id[kNodes]->offset, fail);
  if (opt.verify != IndexOpenOptions::Verify::metadata_only) x.verify_nodes(by_id[kNodes]->offset);
  if (verify_all) x.check_ids();
  // The entry grids from the top levels' records (the pass above has just read them; after a
  // metadata_only open, at most 37,449 records are faulted in). The accessors' checks hold here
  // too, so the walk stays inside the nodes section on any records.
  // None where the header's root cell is not the one its bounds give (a file not written by the
  // build): the grid's cells would then not be the points' cells.
  const double side = OctreeRules::root_side(x.bounds_);
  const AABB built_cell = OctreeRules::root_cell(x.bounds_);
  if (x.points_ > 0 && built_cell.lo == x.cell_.lo && built_cell.hi == x.cell_.hi)
    x.entry_ = build_entry_grid(x, x.depth_, x.node_count_, [&](Node c) { return x.node_octant(c); },
                                OctreeRules::Quantizer(x.cell_.lo, side), side);

  x.sources_ = read_sources(std::string_view(reinterpret_cast<const char*>(at(kSources)), by_id[kSources]->size),
                            by_id[kSources]->offset, x.points_, fail);
  if (opt.check_sources) check_sources_unchanged(nm, x.sources_);
  ::madvise(m.p, m.n, MADV_RANDOM);
  if (opt.read_ahead && !x.verified_ && x.node_count_ > 0)  // (verified: open read every section just now)
    m.start_read_ahead(by_id[kNodes]->offset, by_id[kNodes]->size, m.n <= available_memory() / 2);
  m.path = nm;
  m.ids_offset = x.ids_offset_;
  m.ids = x.ids_;
  m.points = x.points_;
  m.trust_ids = opt.trust_ids;  // the builder's own output
  return x;
}

void MappedIndex::release_pages() const {
  if (map_ && map_->p != nullptr) (void)::madvise(map_->p, map_->n, MADV_DONTNEED);
}

void MappedIndex::verify_nodes(std::uint64_t node_off) const {
  const std::string nm = path_.string();
  auto fail = [&nm](std::uint64_t off, const std::string& what) -> void {
    throw IndexError(nm + ": byte " + std::to_string(off) + ": " + what);
  };
  const MappedIndex& x = *this;
  // Node ranges: every later access stays inside the mapping.
  for (std::size_t n = 0; n < x.node_count_; ++n) {
    const IndexNodeRecord& r = x.nodes_[n];
    const std::uint64_t o = node_off + n * kNodeBytes;
    if (r.internal()) {
      if (r.count() < 1 || r.count() > 8 || r.first <= n || r.first + std::uint64_t{r.count()} > x.node_count_)
        fail(o + 24, "node " + std::to_string(n) + ": children [" + std::to_string(r.first) + ", +" +
                         std::to_string(r.count()) + ") outside the " + std::to_string(x.node_count_) +
                         " nodes (expected 1 to 8 nodes after it)");
    } else if (r.first + std::uint64_t{r.count()} > x.points_) {
      fail(o + 24, "node " + std::to_string(n) + ": point range [" + std::to_string(r.first) + ", +" +
                       std::to_string(r.count()) + ") outside the " + std::to_string(x.points_) + " points");
    }
    for (int k = 0; k < 3; ++k) {
      if (std::isnan(r.lo[k]) || std::isnan(r.hi[k])) fail(o, "node " + std::to_string(n) + ": NaN bounds");
      if (r.lo[k] > r.hi[k])
        fail(o + 4 * k, "node " + std::to_string(n) + ": box of axis " + std::to_string(k) + " " +
                            world_interval(r, cell_.lo, k) + " (expected minimum <= maximum)");
    }
  }
  if (x.node_count_ > 0 && x.nodes_[0].octant() != 0) fail(node_off + 28, "root node octant must be 0");
  // Structure (Warren & Salmon ids, paper section 4.1): every node but the root is the child of
  // exactly one earlier node, octants strictly increase within a family (so sibling ids differ and
  // each id is its parent's times 8 plus the octant), and no node is deeper than the header's
  // depth. The depth of each node is kept (one byte per node) for the points per level below.
  std::vector<std::uint8_t> depth_of(x.node_count_, 0xFF);
  if (x.node_count_ > 0) depth_of[0] = 0;
  for (std::size_t n = 0; n < x.node_count_; ++n) {  // parents come before their children
    const IndexNodeRecord& r = x.nodes_[n];
    if (depth_of[n] == 0xFF)
      fail(node_off + n * kNodeBytes, "node " + std::to_string(n) + ": not the child of any earlier node");
    if (!r.internal()) continue;
    if (depth_of[n] >= x.depth_)
      fail(node_off + n * kNodeBytes + 28, "node " + std::to_string(n) + ": children below the deepest level " +
                                               std::to_string(x.depth_) + " of the header");
    for (unsigned c = 0; c < r.count(); ++c) {
      const std::size_t k = r.first + c;
      if (depth_of[k] != 0xFF || (c > 0 && x.nodes_[k].octant() <= x.nodes_[k - 1].octant()))
        fail(node_off + k * kNodeBytes + 28, "node " + std::to_string(k) + ": octant " +
                                                 std::to_string(x.nodes_[k].octant()) + " is not the next child of node " +
                                                 std::to_string(n));
      depth_of[k] = static_cast<std::uint8_t>(depth_of[n] + 1);
      // A box is its own points' float box widened by its children's (OctreeRules::float_bound,
      // then min / max), so a child's lies inside its parent's exactly, with no rounding allowance;
      // from the root's (check_root_box), every box is then finite and inside the point bounds.
      const IndexNodeRecord& ck = x.nodes_[k];
      for (int a = 0; a < 3; ++a)
        if (ck.lo[a] < r.lo[a] || ck.hi[a] > r.hi[a])
          fail(node_off + k * kNodeBytes + (ck.lo[a] < r.lo[a] ? 0 : 12) + 4 * a,
               "node " + std::to_string(k) + ": box of axis " + std::to_string(a) + " " + world_interval(ck, cell_.lo, a) +
                   " (expected inside its parent node " + std::to_string(n) + "'s " + world_interval(r, cell_.lo, a) + ")");
    }
  }
  // The header's points per level agree with the records.
  {
    std::vector<std::uint64_t> have(kLevels, 0);
    for (std::size_t n = 0; n < x.node_count_; ++n)
      if (!x.nodes_[n].internal()) have[depth_of[n]] += x.nodes_[n].count();  // depth <= header depth <= 21
    const std::vector<std::uint64_t> want = points_per_level();
    for (unsigned d = 0; d < kLevels; ++d)
      if (have[d] != (d < want.size() ? want[d] : 0))
        fail(kLevelsOffset + 8 * d, "points at depth " + std::to_string(d) + ": the header says " +
                                        std::to_string(d < want.size() ? want[d] : 0) + ", the nodes hold " +
                                        std::to_string(have[d]));
  }
}

IdView MappedIndex::ids() const {
  if (ids_ == nullptr) return IdView::identity(points_);  // no ids section: slot order
  const std::span<const PointIndex> ids(ids_, points_);
  if (verified_ || !map_ || map_->trust_ids) return ids;
  return IdView::checked(ids, &MappedIndex::bad_id, map_.get());
}

void MappedIndex::bad_id(const void* map, std::size_t slot) {
  const auto& m = *static_cast<const Map*>(map);
  throw IndexError(m.path + ": byte " + std::to_string(m.ids_offset + 4 * slot) + ": section ids: slot " +
                   std::to_string(slot) + " holds id " + std::to_string(m.ids[slot]) + " outside the " +
                   std::to_string(m.points) + " points (corrupted; `rayscan info --verify` checks the whole file)");
}

void MappedIndex::check_ids() const {
  if (ids_ == nullptr) return;  // the identity names every point
  std::atomic<std::size_t> bad{points_};
  // The deep check at open; isolated so that the pass never runs an outer task.
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_, 1 << 16), [&](const auto& r) {
      for (std::size_t s = r.begin(); s != r.end(); ++s)
        if (ids_[s] >= points_) {
          std::size_t cur = bad.load();
          while (s < cur && !bad.compare_exchange_weak(cur, s)) {
          }
          return;
        }
    });
  });
  if (const std::size_t s = bad.load(); s < points_)
    throw IndexError(path_.string() + ": byte " + std::to_string(ids_offset_ + 4 * s) + ": section ids: slot " +
                     std::to_string(s) + " holds id " + std::to_string(ids_[s]) + " outside the " +
                     std::to_string(points_) + " points (corrupted; `rayscan info --verify` checks the whole file)");
  // N ids below N name every point exactly once iff none repeats (a permutation): one bit per id.
  std::vector<std::atomic<std::uint64_t>> seen((points_ + 63) / 64);
  std::atomic<bool> repeated{false};
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_, 1 << 16), [&](const auto& r) {
      for (std::size_t s = r.begin(); s != r.end() && !repeated.load(std::memory_order_relaxed); ++s) {
        const std::uint64_t bit = std::uint64_t{1} << (ids_[s] % 64);
        if (seen[ids_[s] / 64].fetch_or(bit, std::memory_order_relaxed) & bit) repeated = true;
      }
    });
  });
  if (!repeated) return;
  // Name the first slot that repeats an earlier slot's id (a sequential pass, on the error path only).
  std::vector<std::uint32_t> first(points_, 0xFFFFFFFFu);
  for (std::size_t s = 0; s < points_; ++s) {
    if (first[ids_[s]] != 0xFFFFFFFFu)
      throw IndexError(path_.string() + ": byte " + std::to_string(ids_offset_ + 4 * s) + ": section ids: slot " +
                       std::to_string(s) + " holds id " + std::to_string(ids_[s]) + ", as slot " +
                       std::to_string(first[ids_[s]]) + " does (expected each point's id once; corrupted)");
    first[ids_[s]] = static_cast<std::uint32_t>(s);
  }
}

std::vector<std::uint64_t> MappedIndex::points_per_level() const {
  // Stored in the header at build time (checked at open: sums to N, nothing below the depth).
  std::vector<std::uint64_t> out(depth_ + 1, 0);
  if (!map_ || map_->p == nullptr) return out;
  const auto* b = static_cast<const std::uint8_t*>(map_->p);
  for (unsigned d = 0; d <= depth_ && d < kLevels; ++d) out[d] = get<std::uint64_t>(b, kLevelsOffset + 8 * d);
  return out;
}

PointCloud MappedIndex::to_point_cloud() const {
  PointCloud pc;
  pc.crs_wkt = crs_;
  pc.positions.resize(points_);
  if (!rgb_.empty()) pc.rgb.resize(points_);
  if (!intensity_.empty()) pc.intensity.resize(points_);
  if (!classification_.empty()) pc.classification.resize(points_);
  if (!gps_.empty()) pc.gps_time.resize(points_);
  for (std::size_t s = 0; s < points_; ++s) {
    const PointIndex i = ids_ ? ids_[s] : static_cast<PointIndex>(s);  // no ids: slot order
    if (i >= points_)
      throw IndexError(path_.string() + ": section ids: slot " + std::to_string(s) + " holds id " + std::to_string(i) +
                       " outside the " + std::to_string(points_) + " points (corrupted)");
    pc.positions[i] = positions_[s];
    if (!rgb_.empty()) pc.rgb[i] = rgb_[s];
    if (!intensity_.empty()) pc.intensity[i] = intensity_[s];
    if (!classification_.empty()) pc.classification[i] = classification_[s];
    if (!gps_.empty()) pc.gps_time[i] = gps_[s];
  }
  return pc;
}

}  // namespace rayscan::io
