// COPC info, hierarchy and the lazily decoded CopcIndex; see rayscan/site/copc.hpp.
// Format: COPC 1.0 specification (copc.io): info VLR (user "copc", record 1: center_x/y/z,
// halfsize, spacing, root_hier_offset, root_hier_size, gpstime_minimum/maximum, 11 reserved
// uint64), hierarchy EVLR (record 1000) of pages of 32-byte entries (VoxelKey level/x/y/z int32,
// offset uint64, byteSize int32, pointCount int32; pointCount -1 = a child hierarchy page).
// Reference read (not copied): copc-lib cpp/include/copc-lib/copc/info.hpp, hierarchy/entry.hpp.
#include "rayscan/site/copc.hpp"
#include "rayscan/octree/octree.hpp"

#include "laz/laz.hpp"
#include "las/las_header.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/octree/morton_sort.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <tbb/parallel_for.h>

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>
#include <tuple>

namespace rayscan::io {

namespace {

using Key = std::tuple<std::int32_t, std::int32_t, std::int32_t, std::int32_t>;

CopcInfo parse_copc(const detail::Input& in, const detail::LasHeader& h) {
  using detail::fail_at;
  using detail::load_le;
  const std::string& nm = in.name;
  const std::uint8_t* d = in.bytes.data();
  if (!h.copc_info.present) fail_at(nm, h.header_size, "no COPC info VLR (user id \"copc\", record 1)");
  if (h.copc_info.len < 160)
    fail_at(nm, h.copc_info.at, "COPC info VLR of " + std::to_string(h.copc_info.len) + " bytes (expected 160)");
  if (!h.laszip.present) fail_at(nm, h.header_size, "COPC file without a LASzip VLR");
  if (h.pdrf < 6 || h.pdrf > 8)
    fail_at(nm, 104, "COPC point data record format " + std::to_string(h.pdrf) + " (expected 6, 7 or 8)");
  CopcInfo c;
  const std::uint8_t* v = d + h.copc_info.at;
  c.center = Vec3(load_le<double>(v), load_le<double>(v + 8), load_le<double>(v + 16));
  c.halfsize = load_le<double>(v + 24);
  c.spacing = load_le<double>(v + 32);
  c.root_hier_offset = load_le<std::uint64_t>(v + 40);
  c.root_hier_size = load_le<std::uint64_t>(v + 48);
  c.gps_min = load_le<double>(v + 56);
  c.gps_max = load_le<double>(v + 64);
  c.scale = h.scale;
  c.offset = h.offset;
  c.point_count = h.count;
  c.pdrf = h.pdrf;
  c.record_length = h.record_length;
  // The root cube: the info VLR's center_x, center_y, center_z and halfsize (8 bytes each, from
  // its first byte), each named at its own byte.
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(c.center[k]))
      fail_at(nm, h.copc_info.at + 8 * k, std::string("COPC root cube has center_") + "xyz"[k] + " " +
                                              shortest_text(c.center[k]) + " (expected a finite number)");
  if (!(c.halfsize > 0) || !std::isfinite(c.halfsize))
    fail_at(nm, h.copc_info.at + 24,
            "COPC root cube has halfsize " + shortest_text(c.halfsize) + " (expected a finite number > 0)");
  // Walk the hierarchy pages breadth-first from the root page.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> todo{{c.root_hier_offset, c.root_hier_size}};
  std::set<std::uint64_t> seen_pages;
  std::map<Key, std::size_t> by_key;
  const std::uint64_t max_entries = in.size() / 32;
  for (std::size_t t = 0; t < todo.size(); ++t) {
    const auto [off, size] = todo[t];
    if (off > in.size() || size > in.size() - off)
      fail_at(nm, off, "COPC hierarchy page of " + std::to_string(size) + " bytes at byte " + std::to_string(off) +
                           " runs past the end of the file (size " + std::to_string(in.size()) + ")");
    if (size % 32 != 0) fail_at(nm, off, "COPC hierarchy page size " + std::to_string(size) + " is not a multiple of 32");
    if (!seen_pages.insert(off).second)
      fail_at(nm, off, "COPC hierarchy page at byte " + std::to_string(off) + " is referenced twice (cycle)");
    ++c.hierarchy_pages;
    for (std::uint64_t e = off; e < off + size; e += 32) {
      CopcNode n;
      n.level = load_le<std::int32_t>(d + e);
      n.x = load_le<std::int32_t>(d + e + 4);
      n.y = load_le<std::int32_t>(d + e + 8);
      n.z = load_le<std::int32_t>(d + e + 12);
      n.offset = load_le<std::uint64_t>(d + e + 16);
      n.byte_size = load_le<std::int32_t>(d + e + 24);
      n.point_count = load_le<std::int32_t>(d + e + 28);
      if (n.level < 0 || n.level > 30 || n.x < 0 || n.y < 0 || n.z < 0 || (n.x >> n.level) != 0 ||
          (n.y >> n.level) != 0 || (n.z >> n.level) != 0)
        fail_at(nm, e, "COPC hierarchy entry with invalid key " + std::to_string(n.level) + "-" + std::to_string(n.x) +
                           "-" + std::to_string(n.y) + "-" + std::to_string(n.z));
      if (n.point_count == -1) {
        if (n.byte_size < 0) fail_at(nm, e + 24, "COPC hierarchy page reference with negative size");
        todo.emplace_back(n.offset, static_cast<std::uint64_t>(n.byte_size));
        continue;
      }
      if (n.point_count < -1 || n.byte_size < 0)
        fail_at(nm, e + 24, "COPC hierarchy entry with byte size " + std::to_string(n.byte_size) + " and point count " +
                                std::to_string(n.point_count));
      if (n.point_count > 0 &&
          (n.byte_size == 0 || n.offset < h.point_offset || n.offset > h.data_end ||
           static_cast<std::uint64_t>(n.byte_size) > h.data_end - n.offset))
        fail_at(nm, e + 16, "COPC node " + std::to_string(n.level) + "-" + std::to_string(n.x) + "-" +
                                std::to_string(n.y) + "-" + std::to_string(n.z) + " chunk [" + std::to_string(n.offset) +
                                ", +" + std::to_string(n.byte_size) + ") lies outside the point data (ends at byte " +
                                std::to_string(h.data_end) + ")");
      if (!by_key.emplace(Key{n.level, n.x, n.y, n.z}, c.nodes.size()).second)
        fail_at(nm, e, "COPC hierarchy lists key " + std::to_string(n.level) + "-" + std::to_string(n.x) + "-" +
                           std::to_string(n.y) + "-" + std::to_string(n.z) + " twice");
      if (c.nodes.size() >= max_entries) fail_at(nm, e, "COPC hierarchy has more entries than the file has bytes / 32");
      c.nodes.push_back(n);
    }
  }
  std::uint64_t total = 0;
  for (const CopcNode& n : c.nodes) {
    if (n.level > 0 && by_key.find(Key{n.level - 1, n.x / 2, n.y / 2, n.z / 2}) == by_key.end())
      fail_at(nm, c.root_hier_offset, "COPC node " + std::to_string(n.level) + "-" + std::to_string(n.x) + "-" +
                                          std::to_string(n.y) + "-" + std::to_string(n.z) + " has no parent in the hierarchy");
    c.depth = std::max(c.depth, n.level + 1);
    total += static_cast<std::uint64_t>(n.point_count);
  }
  c.nodes_per_level.assign(static_cast<std::size_t>(c.depth), 0);
  c.points_per_level.assign(static_cast<std::size_t>(c.depth), 0);
  for (const CopcNode& n : c.nodes) {
    ++c.nodes_per_level[static_cast<std::size_t>(n.level)];
    c.points_per_level[static_cast<std::size_t>(n.level)] += static_cast<std::uint64_t>(n.point_count);
  }
  if (total != c.point_count)
    fail_at(nm, c.root_hier_offset, "COPC hierarchy node point counts add up to " + std::to_string(total) +
                                        " but the header announces " + std::to_string(c.point_count));
  if (!c.nodes.empty() && by_key.find(Key{0, 0, 0, 0}) == by_key.end())
    fail_at(nm, c.root_hier_offset, "COPC hierarchy has no root node 0-0-0-0");
  return c;
}

}  // namespace

AABB CopcInfo::node_cube(const CopcNode& n) const {
  const double edge = 2.0 * halfsize / std::ldexp(1.0, n.level);
  const Vec3 lo = center - Vec3(halfsize) + Vec3(n.x * edge, n.y * edge, n.z * edge);
  AABB b;
  b.lo = lo;
  b.hi = lo + Vec3(edge);
  return b;
}

CopcInfo read_copc_info(std::span<const std::uint8_t> bytes, const std::string& name) {
  const detail::Input in{bytes, name, {}};
  return parse_copc(in, detail::parse_las_header(in));
}

// ---------------------------------------------------------------------------------------------

/// The mapped COPC file: nodes are touched in query order, so the sequential read-ahead hint of
/// the streaming readers' mapping is replaced by the default one.
struct CopcIndex::Map : laz::FileMap {
  explicit Map(const std::filesystem::path& p) : laz::FileMap(p) {
    if (!bytes().empty())
      ::madvise(const_cast<std::uint8_t*>(bytes().data()), bytes().size(), MADV_NORMAL);
  }
};

CopcInfo read_copc_info(const std::filesystem::path& path) {
  const laz::FileMap m(path);
  return read_copc_info(m.bytes(), path.string());
}

bool is_copc_file(const std::filesystem::path& path) {
  try {
    if (format_from_extension(path) != Format::las) return false;
    const laz::FileMap m(path);
    const detail::Input in{m.bytes(), path.string(), {}};
    return detail::parse_las_header(in).copc_info.present;
  } catch (const std::exception&) {
    return false;
  }
}

namespace {
constexpr std::size_t kSlotAlign = 1024;  // 1024 * 24 B and 1024 * 4 B are whole 4 KiB pages
void* reserve(std::size_t bytes) {
  if (bytes == 0) return nullptr;
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  return p;
}
}  // namespace

CopcIndex::CopcIndex(const std::filesystem::path& path, std::size_t cache_bytes)
    : name_(path.string()), map_(std::make_unique<Map>(path)), cache_bytes_(cache_bytes), reserve_(cache_bytes / 4) {
  const detail::Input in{map_->bytes(), name_, {}};
  const detail::LasHeader h = detail::parse_las_header(in);
  info_ = parse_copc(in, h);
  // the LASzip VLR must describe layered POINT14 chunks
  (void)laz::parse_laszip_vlr(map_->bytes().data() + h.laszip.at, h.laszip.len, name_, h.laszip.at, h.pdrf, h.record_length);
  if (info_.nodes.empty()) return;
  // Nodes in breadth-first order from the root: node id = position in nodes_.
  std::map<Key, std::uint32_t> entry_of;
  for (std::uint32_t i = 0; i < info_.nodes.size(); ++i) {
    const CopcNode& n = info_.nodes[i];
    entry_of[Key{n.level, n.x, n.y, n.z}] = i;
  }
  // file-order ids: nodes sorted by chunk offset
  std::vector<std::uint32_t> by_offset(info_.nodes.size());
  for (std::uint32_t i = 0; i < by_offset.size(); ++i) by_offset[i] = i;
  std::sort(by_offset.begin(), by_offset.end(),
            [&](std::uint32_t a, std::uint32_t b) { return info_.nodes[a].offset < info_.nodes[b].offset; });
  std::vector<std::uint64_t> first_id(info_.nodes.size());
  std::uint64_t acc = 0;
  for (std::uint32_t i : by_offset) {
    first_id[i] = acc;
    acc += static_cast<std::uint64_t>(info_.nodes[i].point_count);
  }
  if (acc > 0xFFFFFFFFull) throw FormatError(name_ + ": COPC file of " + std::to_string(acc) + " points exceeds 2^32 - 1");
  nodes_.reserve(info_.nodes.size());
  std::vector<std::uint32_t> queue{entry_of.at(Key{0, 0, 0, 0})};
  const Vec3 grow = Vec3(std::abs(info_.scale.x), std::abs(info_.scale.y), std::abs(info_.scale.z));
  std::size_t holders = 0;  // nodes with a points node
  for (std::size_t q = 0; q < queue.size(); ++q) {
    const CopcNode& n = info_.nodes[queue[q]];
    NodeData nd;
    nd.entry = queue[q];
    nd.own = static_cast<std::uint32_t>(n.point_count);
    nd.first_id = first_id[queue[q]];
    nd.level = n.level;
    nd.box = info_.node_cube(n);
    nd.box.lo = nd.box.lo - grow;
    nd.box.hi = nd.box.hi + grow;
    if (n.level <= static_cast<int>(kMortonBits)) {
      const unsigned shift = 3 * (kMortonBits - static_cast<unsigned>(n.level));
      const std::uint64_t prefix = morton_encode(static_cast<std::uint32_t>(n.x), static_cast<std::uint32_t>(n.y),
                                                 static_cast<std::uint32_t>(n.z));
      nd.code_lo = prefix << shift;
      nd.code_hi = (prefix + 1) << shift;
    }
    for (int c = 0; c < 8; ++c) {
      auto it = entry_of.find(Key{n.level + 1, 2 * n.x + (c & 1), 2 * n.y + ((c >> 1) & 1), 2 * n.z + (c >> 2)});
      if (it == entry_of.end()) continue;
      nd.in_octant[c] = static_cast<std::uint32_t>(queue.size());
      nd.children[nd.child_count++] = static_cast<std::uint32_t>(queue.size());
      queue.push_back(it->second);
    }
    nd.pushes = nd.child_count > 0 && n.level < static_cast<int>(kMortonBits);
    nodes_.push_back(nd);
  }
  for (std::uint32_t i = 0; i < nodes_.size(); ++i) {
    NodeData& nd = nodes_[i];
    for (unsigned c = 0; c < nd.child_count; ++c) nodes_[nd.children[c]].parent = i;
    // breadth-first: a parent comes before its children
    nd.has_points = nd.own > 0 || (nd.parent != kNone && nodes_[nd.parent].has_points);
    holders += nd.has_points;
    // the handle's children: the points node (if any) and the hierarchy children, grouped when 9
    const unsigned pts = nd.has_points ? 1u : 0u;
    nd.top_count = pts + nd.child_count <= 8 ? pts + nd.child_count : 2u;
  }
  // The owned sets partition the points: their ranges, each aligned, fit in this many slots.
  slots_ = static_cast<std::size_t>(acc) + holders * kSlotAlign;
  if (slots_ > 0xFFFFFFFFull) throw FormatError(name_ + ": COPC slot space exceeds 2^32");
  const Vec3 origin = float_origin();
  fboxes_.assign(nodes_.size() * kBoxesPerNode, FBox{});
  for (std::uint32_t i = 0; i < nodes_.size(); ++i) {
    const NodeData& nd = nodes_[i];
    FBox* f = &fboxes_[std::size_t{i} * kBoxesPerNode];
    f[0] = f[9] = f[10] = float_box(nd.box, origin);  // points node and group: the voxel cube
    for (unsigned c = 0; c < nd.child_count; ++c) f[1 + c] = float_box(nodes_[nd.children[c]].box, origin);
  }
  for (std::uint32_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i].own > 0) by_first_id_.push_back(i);
  std::sort(by_first_id_.begin(), by_first_id_.end(),
            [&](std::uint32_t a, std::uint32_t b) { return nodes_[a].first_id < nodes_[b].first_id; });
  pos_ = static_cast<Vec3*>(reserve(slots_ * sizeof(Vec3)));
  ids_ = static_cast<PointIndex*>(reserve(slots_ * sizeof(PointIndex)));
  local_ = std::make_unique<Local[]>(nodes_.size());
  range_ = std::make_unique<SlotRange[]>(nodes_.size());
  std::fill_n(range_.get(), nodes_.size(), SlotRange{kNone, kNone});
  state_ = std::make_unique<std::atomic<std::uint8_t>[]>(nodes_.size());
  touched_ = std::make_unique<std::atomic<std::uint64_t>[]>(nodes_.size());
  node_bytes_ = std::make_unique<std::atomic<std::size_t>[]>(nodes_.size());
  retired_at_ = std::make_unique<std::atomic<std::uint64_t>[]>(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    state_[i].store(kAbsent), touched_[i].store(0), node_bytes_[i].store(0), retired_at_[i].store(0);
  scopes_ = std::make_unique<std::atomic<std::uint64_t>[]>(kScopeSlots);
  for (unsigned i = 0; i < kScopeSlots; ++i) scopes_[i].store(0);
}

CopcIndex::~CopcIndex() {
  if (pos_ != nullptr) ::munmap(pos_, slots_ * sizeof(Vec3));
  if (ids_ != nullptr) ::munmap(ids_, slots_ * sizeof(PointIndex));
  if (rgb_ != nullptr) ::munmap(rgb_, slots_ * sizeof(Rgb16));
  if (int_ != nullptr) ::munmap(int_, slots_ * sizeof(std::uint16_t));
  if (cls_ != nullptr) ::munmap(cls_, slots_);
}

void CopcIndex::decode_records(std::uint32_t n, std::uint32_t layers, std::vector<std::uint8_t>& buf) const {
  const NodeData& nd = nodes_[n];
  const CopcNode& e = info_.nodes[nd.entry];
  buf.resize(static_cast<std::size_t>(std::max(e.point_count, 0)) * info_.record_length);
  if (e.point_count <= 0) return;
  const detail::Input in{map_->bytes(), name_, {}};
  // the LASzip VLR was validated at open; parse again here (cheap) to keep no reference state
  const detail::LasHeader h = detail::parse_las_header(in);
  const laz::LaszipVlr v =
      laz::parse_laszip_vlr(map_->bytes().data() + h.laszip.at, h.laszip.len, name_, h.laszip.at, h.pdrf, h.record_length);
  laz::ChunkDecoder dec(v, layers);
  laz::Chunk c{e.offset, static_cast<std::uint64_t>(e.byte_size), nd.first_id, static_cast<std::uint64_t>(e.point_count)};
  dec.start(in, n, c, e.offset + static_cast<std::uint64_t>(e.byte_size));
  dec.next(static_cast<std::size_t>(e.point_count), buf.data());
  dec.finish();
  // The chunk's pages leave the process's resident set (not the page cache): what stays is the
  // decoded node, which the cache budget counts, so the peak memory follows --cache.
  map_->drop(e.offset, e.offset + static_cast<std::uint64_t>(e.byte_size));
}

namespace {
// LAS 1.4 R15 tables 13-17 (PDRF 6-8): intensity at byte 12, classification at 16, RGB at 30.
constexpr std::size_t kIntensityAt = 12, kClassAt = 16, kRgbAt = 30;

// X/Y/Z of point `index` (file order), record `r` (int32 at bytes 0, 4, 8 of every PDRF), scaled
// and offset: world units. A coordinate beyond the bound is refused as the LAS reader refuses it
// (detail::checked_las_position), naming `chunk`, the byte where the node's compressed chunk
// starts: a query of the file in place meets the point the reader would refuse.
Vec3 record_position(const CopcInfo& info, const std::uint8_t* r, const std::string& name, std::uint64_t chunk,
                     std::uint64_t index) {
  return detail::checked_las_position(name, chunk, index, r, info.scale, info.offset);
}

// The record's colour times `mul` (257 for 8-bit colour stored in the 16-bit fields, else 1).
Rgb16 record_rgb(const std::uint8_t* r, std::uint16_t mul) {
  return Rgb16{static_cast<std::uint16_t>(detail::load_le<std::uint16_t>(r + kRgbAt) * mul),
               static_cast<std::uint16_t>(detail::load_le<std::uint16_t>(r + kRgbAt + 2) * mul),
               static_cast<std::uint16_t>(detail::load_le<std::uint16_t>(r + kRgbAt + 4) * mul)};
}

std::uint32_t layers_of(unsigned attrs) {
  std::uint32_t l = laz::kLayerZ;
  if (attrs & CopcIndex::kRgb) l |= laz::kLayerRgb;
  if (attrs & CopcIndex::kIntensity) l |= laz::kLayerIntensity;
  if (attrs & CopcIndex::kClassification) l |= laz::kLayerClassification;
  return l;
}
}  // namespace

CopcIndex::FBox CopcIndex::float_box(const AABB& b, const Vec3& origin) {
  FBox f{};
  for (int a = 0; a < 3; ++a) {
    // The octree's rule (one float ulp outwards, more than the double rounding of the offset).
    f.v[a] = OctreeRules::float_bound(b.lo[a] - origin[a], false);
    f.v[3 + a] = OctreeRules::float_bound(b.hi[a] - origin[a], true);
  }
  return f;
}

void CopcIndex::build_local(std::uint32_t n, SlotRange slots, std::vector<Vec3>& pos,
                            std::vector<std::uint32_t>& order) const {
  const std::uint32_t m = slots.size();
  Local& L = local_[n];
  L.cells.clear();
  L.slot_of.clear();
  order.resize(m);
  for (std::uint32_t i = 0; i < m; ++i) order[i] = i;
  auto box_of = [&](std::uint32_t a, std::uint32_t b) {  // tight bounds of ranks [a, b)
    AABB bx;
    for (std::uint32_t r = a; r < b; ++r) bx.expand(pos[order[r]]);
    return bx;
  };
  const Vec3 origin = float_origin();
  auto set_float = [&](Cell& c) {
    const FBox f = float_box(c.box, origin);
    std::copy(f.v, f.v + 8, c.f);
  };
  if (m <= kLeafPoints) {  // one leaf cell, candidate order kept (an empty one bounded by the cube)
    L.cells.push_back(Cell{{}, m > 0 ? box_of(0, m) : nodes_[n].box, slots, 0, 0});
    set_float(L.cells[0]);
    return;
  }
  // Morton order within the node's tight bounds: 10 bits per axis (a 1024^3 grid, enough for
  // leaves of kLeafPoints points in nodes of up to ~10^7 points), ties by file order.
  constexpr unsigned kBits = 10;
  const AABB bx = box_of(0, m);
  const Vec3 ext = bx.hi - bx.lo;
  const double cells = double(1u << kBits);
  auto inv = [&](double e) { return e > 0 ? cells / e : 0.0; };
  const Vec3 sc(inv(ext.x), inv(ext.y), inv(ext.z));
  auto cell = [&](double v, double lo, double s) {
    return static_cast<std::uint32_t>(std::clamp((v - lo) * s, 0.0, cells - 1));
  };
  thread_local std::vector<MortonKey> keys, tmp;
  keys.resize(m);
  tmp.resize(m);
  for (std::uint32_t i = 0; i < m; ++i) {
    const Vec3& p = pos[i];
    keys[i] = {morton_encode(cell(p.x, bx.lo.x, sc.x), cell(p.y, bx.lo.y, sc.y), cell(p.z, bx.lo.z, sc.z)), i};
  }
  // (code, file order): the LSD radix sort of the Morton sort on the 30-bit code (profiled: a
  // comparison sort took a third of build_local).
  radix_sort_low_bits(keys.data(), m, tmp.data(), 3 * kBits);
  L.slot_of.resize(m);
  for (std::uint32_t r = 0; r < m; ++r) {
    order[r] = keys[r].idx;
    L.slot_of[order[r]] = r;
  }
  auto digit = [&](std::uint32_t r, unsigned level) {  // Morton digit of rank r at depth level (0 = top)
    return static_cast<unsigned>(keys[r].code >> (3 * (kBits - 1 - level))) & 7u;
  };
  // Cells breadth first; a cell's children are contiguous. Work item: cell, rank range, depth.
  struct Item {
    std::uint32_t cell, a, b;
    unsigned level;
  };
  std::vector<Item> todo{{0, 0, m, 0}};
  L.cells.push_back(Cell{{}, bx, {}, 0, 0});
  for (std::size_t t = 0; t < todo.size(); ++t) {
    Item it = todo[t];
    // collapse single-child chains: skip the digits every point of the range shares
    while (it.level < kBits && it.b - it.a > kLeafPoints && digit(it.a, it.level) == digit(it.b - 1, it.level)) ++it.level;
    if (it.b - it.a <= kLeafPoints || it.level == kBits) {
      L.cells[it.cell].slots = SlotRange{slots.begin + it.a, slots.begin + it.b};
      continue;
    }
    L.cells[it.cell].slots = SlotRange{slots.begin + it.a, slots.begin + it.a};
    L.cells[it.cell].first_child = static_cast<std::uint32_t>(L.cells.size());
    std::uint32_t nc = 0;
    for (std::uint32_t a = it.a; a < it.b;) {
      const unsigned dg = digit(a, it.level);
      std::uint32_t b = a + 1;
      while (b < it.b && digit(b, it.level) == dg) ++b;
      todo.push_back(Item{static_cast<std::uint32_t>(L.cells.size()), a, b, it.level + 1});
      L.cells.push_back(Cell{{}, AABB{}, {}, 0, 0});
      ++nc;
      a = b;
    }
    L.cells[it.cell].child_count = nc;
  }
  // Tight boxes bottom-up (children follow their parent in the breadth-first order): a leaf's
  // from its points, an inner cell's the union of its children's (min/max are exact).
  for (std::size_t k = L.cells.size(); k-- > 1;) {
    Cell& c = L.cells[k];
    if (c.child_count == 0) c.box = box_of(c.slots.begin - slots.begin, c.slots.end - slots.begin);
    else
      for (std::uint32_t j = 0; j < c.child_count; ++j) c.box.expand(L.cells[c.first_child + j].box);
  }
  for (Cell& c : L.cells) set_float(c);
}

std::uint32_t CopcIndex::owner(const Vec3& p, std::uint64_t code, std::uint32_t from) const {
  // A point stored outside its node's cube (within the grown box) has another cube's code: it
  // stays, since no descendant's code range, where the gather looks, would hold it.
  if (!nodes_[from].pushes || code < nodes_[from].code_lo || code >= nodes_[from].code_hi) return from;
  std::uint32_t n = from;
  while (nodes_[n].pushes) {
    const std::uint32_t c = nodes_[n].in_octant[OctreeRules::octant(code, static_cast<unsigned>(nodes_[n].level))];
    if (c == kNone || !nodes_[c].box.contains(p)) break;
    n = c;
  }
  return n;
}

void CopcIndex::Points::clear() {
  pos.clear(), id.clear(), rgb.clear(), intensity.clear(), classification.clear();
}

void CopcIndex::Points::append(const Points& from, std::size_t j) {
  pos.push_back(from.pos[j]), id.push_back(from.id[j]);
  if (!from.rgb.empty()) rgb.push_back(from.rgb[j]);
  if (!from.intensity.empty()) intensity.push_back(from.intensity[j]);
  if (!from.classification.empty()) classification.push_back(from.classification[j]);
}

std::size_t CopcIndex::Source::bytes() const {
  return code.capacity() * sizeof(std::uint64_t) + pos.capacity() * sizeof(Vec3) + id.capacity() * sizeof(PointIndex) +
         rgb.capacity() * sizeof(Rgb16) + intensity.capacity() * sizeof(std::uint16_t) + classification.capacity() +
         index_of.capacity() * sizeof(std::uint32_t);
}

void CopcIndex::load(std::uint32_t n) const {
  const NodeData& nd = nodes_[n];
  // The ancestors' sorted points, which this node takes its share of, root first (each load
  // takes only its own node's lock, so no two locks are ever held together). A node retired
  // meanwhile stays intact until the caller's scope ends.
  std::uint32_t path[64];
  unsigned depth = 0;
  if (nd.level <= static_cast<int>(kMortonBits))
    for (std::uint32_t a = nd.parent; a != kNone && depth < 64; a = nodes_[a].parent) path[depth++] = a;
  std::unique_lock<std::mutex> lock(locks_[n % 32]);
  for (bool ancestors = false;;) {
    const std::uint8_t st = state_[n].load();
    if (st == kLoaded) return;
    if (st == kRetired) {  // not released yet: its slots and local tree are intact
      state_[n].store(kLoaded);
      return;
    }
    if (ancestors) break;
    // absent: its ancestors first (without this lock), then look again (another thread may
    // have decoded it meanwhile)
    lock.unlock();
    for (unsigned d = depth; d-- > 0;) touch(path[d]);
    lock.lock();
    ancestors = true;
  }
  Local& L = local_[n];
  L = Local{};
  thread_local std::vector<std::uint8_t> buf;
  thread_local Points own, owned;  // the node's chunk in file order; the points it owns
  thread_local std::vector<std::uint32_t> order;
  thread_local std::vector<MortonKey> keys, tmp;
  own.clear(), owned.clear();
  if (nd.own > 0) {
    decode_records(n, layers_of(attrs_), buf);
    const std::size_t rec = info_.record_length;
    for (std::uint32_t i = 0; i < nd.own; ++i) {
      const std::uint8_t* rp = buf.data() + std::size_t{i} * rec;
      own.pos.push_back(record_position(info_, rp, name_, info_.nodes[nd.entry].offset, nd.first_id + i));
      own.id.push_back(static_cast<PointIndex>(nd.first_id + i));
      if (rgb_ != nullptr) own.rgb.push_back(record_rgb(rp, rgb_mul_));
      if (int_ != nullptr) own.intensity.push_back(detail::load_le<std::uint16_t>(rp + kIntensityAt));
      if (cls_ != nullptr) own.classification.push_back(rp[kClassAt]);
    }
  }
  if (nd.pushes) {
    // Sorted by (code, file order) for the descendants (Morton codes of the root cube: the
    // hierarchy's own cells, so a node's cube is one code range); kept here what no child takes.
    const OctreeRules::Quantizer qz(info_.center - Vec3(info_.halfsize), 2.0 * info_.halfsize);
    const std::uint32_t m = nd.own;
    keys.resize(m), tmp.resize(m);
    for (std::uint32_t i = 0; i < m; ++i) keys[i] = {qz.code(own.pos[i]), i};
    if (m > 0) radix_sort_low_bits(keys.data(), m, tmp.data(), 3 * kMortonBits);
    Source& S = L.src;
    S.code.resize(m), S.index_of.resize(m);
    S.pos.reserve(m), S.id.reserve(m);  // kept while resident and counted: no growth slack
    S.rgb.reserve(own.rgb.size()), S.intensity.reserve(own.intensity.size()), S.classification.reserve(own.classification.size());
    for (std::uint32_t j = 0; j < m; ++j) {
      S.code[j] = keys[j].code;
      S.index_of[keys[j].idx] = j;
      S.append(own, keys[j].idx);
    }
    for (std::uint32_t i = 0; i < m; ++i)  // file order
      if (const std::uint32_t j = S.index_of[i]; owner(S.pos[j], S.code[j], n) == n) owned.append(S, j);
  } else {
    std::swap(owned, own);  // a leaf keeps every own point, first and in file order (slot_of[k])
  }
  // The ancestors' points in this node's cube (one code range of each) that end here.
  for (unsigned d = 0; d < depth; ++d) {
    const std::uint32_t a = path[d];
    const Source& S = local_[a].src;
    const auto b = std::lower_bound(S.code.begin(), S.code.end(), nd.code_lo) - S.code.begin();
    const auto e = std::lower_bound(S.code.begin(), S.code.end(), nd.code_hi) - S.code.begin();
    for (auto j = b; j < e; ++j)
      if (owner(S.pos[j], S.code[j], a) == n) owned.append(S, static_cast<std::size_t>(j));
  }
  const std::uint32_t m = static_cast<std::uint32_t>(owned.pos.size());
  if (range_[n].begin == kNone) {  // first decode: the node's slots, kept for every later decode
    const std::size_t begin = next_slot_.fetch_add((std::size_t{m} + kSlotAlign - 1) / kSlotAlign * kSlotAlign);
    if (begin + m > slots_) throw std::logic_error(name_ + ": COPC owned points exceed the slot space");
    range_[n] = SlotRange{static_cast<std::uint32_t>(begin), static_cast<std::uint32_t>(begin + m)};
  } else if (range_[n].size() != m) {
    throw std::logic_error(name_ + ": COPC node decoded with a different point count");
  }
  if (nd.has_points) {
    build_local(n, range_[n], owned.pos, order);
    for (std::uint32_t r = 0; r < m; ++r) {  // slot begin + r holds the point of Morton rank r
      const std::uint32_t j = order[r], s = range_[n].begin + r;
      pos_[s] = owned.pos[j];
      ids_[s] = owned.id[j];
      if (int_ != nullptr) int_[s] = owned.intensity[j];
      if (cls_ != nullptr) cls_[s] = owned.classification[j];
      if (rgb_ != nullptr) rgb_[s] = owned.rgb[j];
    }
  }
  decodes_.fetch_add(1);
  // the slot arrays' whole pages (a node's range starts on a page of positions and ids)
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  auto pages = [&](std::size_t b) { return (b + page - 1) / page * page; };
  const std::size_t bytes = pages(std::size_t{m} * sizeof(Vec3)) + pages(std::size_t{m} * sizeof(PointIndex)) +
                            std::size_t{m} * (slot_bytes() - sizeof(Vec3) - sizeof(PointIndex)) +
                            L.cells.capacity() * sizeof(Cell) +
                            L.slot_of.capacity() * sizeof(std::uint32_t) + L.src.bytes();
  node_bytes_[n].store(bytes);
  const std::size_t now = resident_bytes_.fetch_add(bytes) + bytes;
  for (std::size_t peak = peak_bytes_.load(); now > peak && !peak_bytes_.compare_exchange_weak(peak, now);) {
  }
  state_[n].store(kLoaded);
}

Vec3 CopcIndex::own_position(std::uint32_t n, std::uint64_t k) const {
  const Local& L = local_[n];
  if (nodes_[n].pushes) return L.src.pos[L.src.index_of[k]];
  return pos_[range_[n].begin + static_cast<std::uint32_t>(L.slot_of.empty() ? k : L.slot_of[k])];
}

std::size_t CopcIndex::slot_bytes() const {
  return sizeof(Vec3) + sizeof(PointIndex) + (rgb_ ? sizeof(Rgb16) : 0) + (int_ ? sizeof(std::uint16_t) : 0) +
         (cls_ ? sizeof(std::uint8_t) : 0);
}

void CopcIndex::set_attributes(unsigned attrs) {
  {  // decode again with the attributes (and account for their bytes)
    const std::lock_guard<std::mutex> trim(trim_mutex_);
    for (std::uint32_t i = 0; i < nodes_.size(); ++i)
      if (state_[i].load() != kAbsent) release(i);
    retired_.clear();
  }
  const bool pdrf_rgb = info_.pdrf == 7 || info_.pdrf == 8;
  if ((attrs & kRgb) && pdrf_rgb && rgb_ == nullptr && slots_ > 0) {
    // The reader's colour normalisation (las_reader.cpp decide_colour_scale): the largest channel
    // value decides; stop at the first one above 255 (16-bit colour: usually the first node).
    std::uint16_t mx = 0;
    std::vector<std::uint8_t> buf;
    for (std::uint32_t n : by_first_id_) {
      decode_records(n, laz::kLayerRgb, buf);
      for (std::size_t i = 0; i < buf.size() / info_.record_length; ++i) {
        const std::uint8_t* r = buf.data() + i * info_.record_length + kRgbAt;
        mx = std::max({mx, detail::load_le<std::uint16_t>(r), detail::load_le<std::uint16_t>(r + 2),
                       detail::load_le<std::uint16_t>(r + 4)});
      }
      if (mx > 255) break;
    }
    if (mx > 0) {
      rgb_mul_ = mx <= 255 ? 257 : 1;
      rgb_ = static_cast<Rgb16*>(reserve(slots_ * sizeof(Rgb16)));
    }
  }
  if ((attrs & kIntensity) && int_ == nullptr && slots_ > 0)
    int_ = static_cast<std::uint16_t*>(reserve(slots_ * sizeof(std::uint16_t)));
  if ((attrs & kClassification) && cls_ == nullptr && slots_ > 0)
    cls_ = static_cast<std::uint8_t*>(reserve(slots_));
  attrs_ = (rgb_ ? kRgb : 0u) | (int_ ? kIntensity : 0u) | (cls_ ? kClassification : 0u);
}

void CopcIndex::scan(unsigned attrs, const std::function<bool(const NodeBlock&)>& f) const {
  const bool rgb = (attrs & kRgb) && rgb_ != nullptr;
  const std::uint32_t layers = layers_of(rgb ? attrs : attrs & ~unsigned(kRgb));
  // Nodes in file order, decoded a few at a time in parallel, handed to f in order.
  const std::size_t batch = 8;
  std::vector<std::vector<std::uint8_t>> bufs(batch);
  std::vector<Vec3> pos;
  std::vector<Rgb16> col;
  std::vector<std::uint16_t> inten;
  std::vector<std::uint8_t> cls;
  for (std::size_t b0 = 0; b0 < by_first_id_.size(); b0 += batch) {
    const std::size_t b1 = std::min(by_first_id_.size(), b0 + batch);
    tbb::parallel_for(b0, b1, [&](std::size_t k) { decode_records(by_first_id_[k], layers, bufs[k - b0]); });
    for (std::size_t k = b0; k < b1; ++k) {
      const std::vector<std::uint8_t>& buf = bufs[k - b0];
      const NodeData& nd = nodes_[by_first_id_[k]];
      const std::size_t rec = info_.record_length, m = buf.size() / rec;
      pos.resize(m);
      col.resize(rgb ? m : 0);
      inten.resize(attrs & kIntensity ? m : 0);
      cls.resize(attrs & kClassification ? m : 0);
      for (std::size_t i = 0; i < m; ++i) {
        const std::uint8_t* r = buf.data() + i * rec;
        pos[i] = record_position(info_, r, name_, info_.nodes[nd.entry].offset, nd.first_id + i);
        if (!inten.empty()) inten[i] = detail::load_le<std::uint16_t>(r + kIntensityAt);
        if (!cls.empty()) cls[i] = r[kClassAt];
        if (!col.empty())
          col[i] = record_rgb(r, rgb_mul_);
      }
      if (!f(NodeBlock{pos, col, inten, cls})) return;
    }
  }
}

std::vector<Vec3> CopcIndex::spacing_samples(std::size_t max_samples, std::size_t max_nodes) const {
  std::vector<Vec3> out;
  const std::uint64_t N = info_.point_count;
  if (N == 0 || by_first_id_.empty() || max_samples == 0 || max_nodes == 0) return out;
  const std::uint64_t K = std::min<std::uint64_t>(max_nodes, N);
  std::vector<std::uint32_t> picked;
  for (std::uint64_t k = 0; k < K; ++k) {
    const std::uint64_t id = k * N / K;
    auto it = std::upper_bound(by_first_id_.begin(), by_first_id_.end(), id,
                               [&](std::uint64_t v, std::uint32_t n) { return v < nodes_[n].first_id; });
    const std::uint32_t n = *--it;
    if (picked.empty() || picked.back() != n) picked.push_back(n);
  }
  const std::size_t per = std::max<std::size_t>(1, max_samples / picked.size());
  for (std::uint32_t n : picked) {
    touch(n);
    const std::size_t cnt = nodes_[n].own, m = std::min(per, cnt);
    for (std::size_t j = 0; j < m && out.size() < max_samples; ++j) out.push_back(own_position(n, j * cnt / m));
  }
  return out;
}

Vec3 CopcIndex::position_of(PointIndex id) const {
  auto it = std::upper_bound(by_first_id_.begin(), by_first_id_.end(), static_cast<std::uint64_t>(id),
                             [&](std::uint64_t v, std::uint32_t n) { return v < nodes_[n].first_id; });
  if (it == by_first_id_.begin()) throw std::out_of_range(name_ + ": no point " + std::to_string(id));
  const std::uint32_t n = *--it;
  touch(n);
  const std::uint64_t k = static_cast<std::uint64_t>(id) - nodes_[n].first_id;
  if (k >= nodes_[n].own) throw std::out_of_range(name_ + ": no point " + std::to_string(id));
  return own_position(n, k);
}

std::size_t CopcIndex::resident_nodes() const {
  std::size_t k = 0;
  for (std::size_t i = 0; i < nodes_.size(); ++i) k += state_[i].load() != kAbsent;
  return k;
}

void CopcIndex::release(std::uint32_t i) const {
  const SlotRange s = range_[i];
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  // Positions and ids: node ranges start on a page (kSlotAlign), so the pages from the first up
  // to the one holding the last slot are the node's alone.
  auto drop = [&](void* base, std::size_t elem) {
    const auto b = reinterpret_cast<std::uintptr_t>(base) + s.begin * elem;
    const auto e = (reinterpret_cast<std::uintptr_t>(base) + s.end * elem + page - 1) / page * page;
    if (e > b) ::madvise(reinterpret_cast<void*>(b), e - b, MADV_DONTNEED);
  };
  if (s.size() > 0) {
    drop(pos_, sizeof(Vec3));
    drop(ids_, sizeof(PointIndex));
    // Attribute arrays: a node's range is not page-aligned there; release only the whole pages
    // inside it (neighbours keep theirs; under 2 pages per node stay resident).
    auto drop_inner = [&](void* base, std::size_t elem) {
      if (base == nullptr) return;
      const auto b = (reinterpret_cast<std::uintptr_t>(base) + s.begin * elem + page - 1) / page * page;
      const auto e = (reinterpret_cast<std::uintptr_t>(base) + s.end * elem) / page * page;
      if (e > b) ::madvise(reinterpret_cast<void*>(b), e - b, MADV_DONTNEED);
    };
    drop_inner(rgb_, sizeof(Rgb16));
    drop_inner(int_, sizeof(std::uint16_t));
    drop_inner(cls_, sizeof(std::uint8_t));
  }
  local_[i] = Local{};
  resident_bytes_.fetch_sub(node_bytes_[i].exchange(0));
  state_[i].store(kAbsent);
}

std::size_t CopcIndex::trim_cache() {
  const std::lock_guard<std::mutex> trim(trim_mutex_);
  free_retired();
  std::vector<std::uint32_t> resident;
  for (std::uint32_t i = 0; i < nodes_.size(); ++i)
    if (state_[i].load() != kAbsent) resident.push_back(i);
  clock_.fetch_add(1);  // a new batch: what is touched from now on is more recent
  if (resident_bytes_.load() <= cache_bytes_) return 0;
  std::sort(resident.begin(), resident.end(),
            [&](std::uint32_t a, std::uint32_t b) { return touched_[a].load() < touched_[b].load(); });
  std::size_t evicted = 0;
  for (std::uint32_t i : resident) {
    if (resident_bytes_.load() <= cache_bytes_) break;
    const std::lock_guard<std::mutex> lock(locks_[i % 32]);
    release(i);
    ++evicted;
  }
  return evicted;
}

std::size_t CopcIndex::trim_threshold() const {
  return cache_bytes_ - std::min(reserve_.load(std::memory_order_relaxed), cache_bytes_ / 2);
}

void CopcIndex::grow_reserve(std::size_t excess) const {
  if (over_reach_.load(std::memory_order_relaxed)) return;
  const std::size_t r = reserve_.load(std::memory_order_relaxed);
  if (r + excess > cache_bytes_ / 2) {  // the scopes in flight reach about what the budget holds
    over_reach_.store(true, std::memory_order_relaxed);
    reserve_.store(0, std::memory_order_relaxed);
    return;
  }
  for (std::size_t m = r; r + excess > m && !reserve_.compare_exchange_weak(m, r + excess, std::memory_order_relaxed);) {
  }
}

CopcIndex::QueryScope::QueryScope(const CopcIndex& index) : index_(index) {
  index.clock_.fetch_add(1, std::memory_order_relaxed);  // LRU resolution: one scope
  // A free announcement slot, searched from a per-thread start so that threads rarely collide.
  thread_local const unsigned start = static_cast<unsigned>(std::hash<std::thread::id>{}(std::this_thread::get_id()));
  for (unsigned k = 0;; ++k) {
    const unsigned s = (start + k) % kScopeSlots;
    std::uint64_t expected = 0;
    // The announcement is an RMW (sequentially consistent) ordered before every state read of
    // the scope: a trimmer that reads this slot as free has retired its nodes before them.
    if (index.scopes_[s].compare_exchange_strong(expected, index.epoch_.load())) {
      slot_ = s;
      return;
    }
    if (k + 1 == kScopeSlots) std::this_thread::yield(), k = ~0u;  // all slots taken: wait for one
  }
}

CopcIndex::QueryScope::~QueryScope() {
  index_.scopes_[slot_].store(0);  // release: the scope's reads of node data happen before
  const std::size_t res = index_.resident_bytes_.load(std::memory_order_relaxed);
  if (res > index_.cache_bytes_) index_.grow_reserve(res - index_.cache_bytes_);
  if (res <= index_.trim_threshold()) return;
  std::unique_lock<std::mutex> trim(index_.trim_mutex_, std::try_to_lock);
  if (!trim.owns_lock()) return;  // another scope is trimming now
  try {
    index_.trim_in_flight();
  } catch (...) {  // std::bad_alloc of the candidate list: the nodes stay resident until the next trim
  }
}

void CopcIndex::free_retired() const {
  if (retired_.empty()) return;
  // The oldest announcement of an open scope: a node retired at epoch r is out of reach of
  // every scope that announced r or later (it read the state after the retirement).
  std::uint64_t oldest = ~std::uint64_t{0};
  for (unsigned s = 0; s < kScopeSlots; ++s)
    if (const std::uint64_t e = scopes_[s].load(); e != 0) oldest = std::min(oldest, e);
  std::size_t keep = 0;
  for (const std::uint32_t n : retired_) {
    const std::lock_guard<std::mutex> lock(locks_[n % 32]);
    if (state_[n].load() != kRetired) continue;  // revived by a touch (or released)
    if (retired_at_[n].load() <= oldest) release(n);
    else retired_[keep++] = n;
  }
  retired_.resize(keep);
}

void CopcIndex::trim_in_flight() const {
  free_retired();
  std::size_t pending = 0;  // bytes retired and not released yet
  for (const std::uint32_t n : retired_) pending += node_bytes_[n].load();
  // Evict down to the threshold less 1/8 of the budget, so that a full cache is not trimmed at
  // every scope end.
  const std::size_t threshold = trim_threshold();
  const std::size_t low = threshold - std::min(threshold, cache_bytes_ / 8);
  if (resident_bytes_.load() - std::min(pending, resident_bytes_.load()) <= low) return;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> loaded;  // (last touch, node)
  for (std::uint32_t i = 0; i < nodes_.size(); ++i)
    if (state_[i].load(std::memory_order_relaxed) == kLoaded) loaded.emplace_back(touched_[i].load(), i);
  std::sort(loaded.begin(), loaded.end());
  // Retire every chosen node first, then open a new epoch: scopes announcing it read the
  // retirements; scopes announced before it keep the nodes until they close.
  std::size_t live = resident_bytes_.load() - std::min(pending, resident_bytes_.load());
  const std::uint64_t r = epoch_.load() + 1;
  for (const auto& [t, n] : loaded) {
    if (live <= low) break;
    const std::lock_guard<std::mutex> lock(locks_[n % 32]);
    if (state_[n].load() != kLoaded) continue;
    retired_at_[n].store(r);
    state_[n].store(kRetired);
    retired_.push_back(n);
    live -= std::min(live, node_bytes_[n].load());
  }
  epoch_.fetch_add(1);
  free_retired();
}

}  // namespace rayscan::io
