// Cloud Optimized Point Cloud (COPC 1.0, https://copc.io): a LAZ 1.4 file whose variable-size
// chunks are the nodes of an octree described by a hierarchy EVLR. Its hierarchy is exactly the
// paper's *layered* organisation (section 4: every node holds a subsample of its subtree), so
// CopcIndex satisfies the SpatialIndex concept and the one ray query (Algorithm 1) runs on the
// file directly: opening reads the header and the hierarchy, nodes are decompressed on first
// touch and kept in a bounded cache.
#pragma once

#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/simd.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/spatial_index.hpp"
#include "rayscan/octree/surfel.hpp"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace rayscan::io {

/// One hierarchy entry (COPC 1.0 "Hierarchy entry", 32 bytes): the voxel key, the byte range of
/// the node's LAZ chunk and its point count.
struct CopcNode {
  std::int32_t level = 0, x = 0, y = 0, z = 0;  ///< VoxelKey (depth and integer cell)
  std::uint64_t offset = 0;                     ///< file offset of the node's compressed chunk
  std::int32_t byte_size = 0;                   ///< bytes of the chunk
  std::int32_t point_count = 0;                 ///< points stored in the node itself
};

/// The COPC info VLR (user "copc", record 1, 160 bytes) and the parsed hierarchy.
struct CopcInfo {
  Vec3 center{0.0};          ///< centre of the root cube (file units)
  double halfsize = 0;       ///< half the root cube's edge length
  double spacing = 0;        ///< the root node's point spacing
  std::uint64_t root_hier_offset = 0, root_hier_size = 0;  ///< first hierarchy page
  double gps_min = 0, gps_max = 0;
  Vec3 scale{1.0}, offset{0.0};  ///< LAS header scale and offset
  std::uint64_t point_count = 0;  ///< header point count
  int pdrf = 6;
  std::uint16_t record_length = 0;
  std::vector<CopcNode> nodes;  ///< every node with a chunk or children, hierarchy order
  int depth = 0;                ///< deepest level + 1
  std::vector<std::uint64_t> nodes_per_level, points_per_level;
  std::uint64_t hierarchy_pages = 0;

  /// Cube of a voxel key (COPC 1.0: level 0 is the root cube; each level halves the edge).
  [[nodiscard]] AABB node_cube(const CopcNode& n) const;
};

/// Reads the COPC info VLR and walks the hierarchy EVLR pages (record 1000) from the root page.
/// Throws FormatError naming the file and byte offset for: no COPC VLR, a page or chunk range
/// past the end of the file, a page visited twice (cycle), a duplicate or out-of-range key, a
/// node without its parent, a negative point count other than the -1 page marker, a root cube
/// centre coordinate that is not finite or a halfsize that is not finite and > 0 (each named at
/// its own byte).
CopcInfo read_copc_info(std::span<const std::uint8_t> bytes, const std::string& name);
/// Same for a file (reads only the header, VLRs and hierarchy pages).
CopcInfo read_copc_info(const std::filesystem::path& path);

/// True when `path` is a LAS/LAZ file (by extension .las/.laz/.copc) whose header carries the COPC
/// info VLR (user "copc", record 1; COPC 1.0 section "Info VLR"). Reads only the header and VLR
/// headers; false for any other or unreadable file (the caller's reader reports why).
bool is_copc_file(const std::filesystem::path& path);

/// The default budget of a CopcIndex's decoded nodes, bytes (2 GiB: `--cache` of the commands
/// that open a COPC file in place).
inline constexpr std::size_t kCopcDefaultCacheBytes = std::size_t{2} << 30;

/// A COPC file as a SpatialIndex (layered octree). Node 0 is the root; a node's children are
/// the existing keys one level down. ids() are the points' indices in file order, the order
/// read_point_cloud() returns them in. positions() spans reserved virtual memory: a node's slots
/// are filled on first touch (thread-safe), which decodes only the X, Y and Z layers of the node
/// and of those of its ancestors not resident.
/// Coordinates: x = X * scale + offset in double, exactly as read_point_cloud(); a node holding a
/// point beyond +-kMaxCoordinate (rayscan/base/coordinate_bound.hpp) throws FormatError when it is
/// decoded, the reader's one-line refusal naming the point (its byte: the node's chunk). Node
/// bounds are the COPC voxel cubes, grown by one scale step (points on a face may be rounded
/// outside by the LAS quantisation).
///
/// Points pushed down (a ray crosses one local tree, not one per level): every level of a COPC
/// hierarchy is a subsample of the whole cube, so a ray reaching a point at the deepest level
/// would otherwise descend one local tree per level above it. Each point is instead *owned* by
/// the deepest existing hierarchy node on its Morton path whose grown cube holds it, from the
/// node its chunk stores it in downwards (Morton codes of the root cube's 2^21 cells per axis,
/// OctreeRules::Quantizer; no descent below level 21). A node's points node holds exactly the
/// points it owns: its own chunk's points that no child takes, and its ancestors' points that
/// end at it. So a hierarchy node whose 8 children exist owns (almost) nothing, and a leaf owns
/// its chunk's points and its ancestors' points in its cube. Decoding a node therefore needs its
/// ancestors decoded: each keeps its own points sorted by Morton code (a node's cube is one code
/// range) for its descendants to take their share, counted in the cache budget.
///
/// Local index (a node sub-indexed when decoded): the owned points, tens of thousands in
/// practice, are sorted in Morton order within their bounding box (a node's slots hold them in
/// that order) and a small octree of cells over them is built (cells split at the Morton digits
/// until at most kLeafPoints points, single-child chains collapsed, each cell's box the tight
/// bounds of its points; cf. the adaptive organisation of the paper, section 4). The cells are
/// virtual nodes of this index: a hierarchy node stores no point itself; its children are a
/// "points" node (the root cell of its local tree, bounded by the voxel cube so that it needs no
/// decode until a ray reaches it) and its hierarchy children (under one extra "group" node,
/// bounded by the voxel cube, when there are 8 of them, so that no node has more than 8
/// children). A node's slot range (aligned to 1024 slots so that its pages can be released on
/// eviction) is assigned at its first decode and kept. The cells and the slot permutation are
/// cached with the node's points and counted in the cache budget. Node handles: low 32 bits the
/// hierarchy node, high 32 bits 0 (the hierarchy node), kGroup (its group) or 1 + a cell index
/// of its local tree.
class CopcIndex {
 public:
  using Node = std::uint64_t;
  /// Most points a leaf cell of a node's local tree holds (fewer where the Morton digits run out).
  static constexpr std::uint32_t kLeafPoints = 32;

  /// Opens `path` (memory-mapped) and reads its header and hierarchy. `cache_bytes` bounds the
  /// decoded nodes (positions, ids, attributes, local trees) kept resident: by trim_cache()
  /// between queries, or as QueryScopes end while queries run. Throws FormatError.
  explicit CopcIndex(const std::filesystem::path& path, std::size_t cache_bytes = kCopcDefaultCacheBytes);
  ~CopcIndex();
  CopcIndex(const CopcIndex&) = delete;
  CopcIndex& operator=(const CopcIndex&) = delete;

  [[nodiscard]] bool empty() const { return nodes_.empty() || info_.point_count == 0; }
  [[nodiscard]] Node root() const { return 0; }
  /// The voxel cube (grown) of a hierarchy, group or points node; a cell's tight box.
  [[nodiscard]] AABB node_bounds(Node n) const {
    const std::uint32_t h = hier(n), c = part(n);
    return c == 0 || c == kGroup || c == 1 ? nodes_[h].box : local_[h].cells[c - 1].box;
  }
  /// The slots of the points stored at a cell (none at hierarchy and group nodes). A points node
  /// (the root cell) decodes its hierarchy node (and its ancestors) on first touch (throws
  /// FormatError for a corrupted chunk).
  [[nodiscard]] SlotRange node_points(Node n) const {
    const std::uint32_t h = hier(n), c = part(n);
    if (c == 0 || c == kGroup) return SlotRange{0, 0};
    if (c == 1) touch(h);
    return local_[h].cells[c - 1].slots;
  }
  [[nodiscard]] unsigned child_count(Node n) const {
    const std::uint32_t h = hier(n), c = part(n);
    if (c == 0) return nodes_[h].top_count;
    if (c == kGroup) return nodes_[h].child_count;
    if (c == 1) ensure_loaded(h);
    return local_[h].cells[c - 1].child_count;
  }
  [[nodiscard]] Node child(Node n, unsigned i) const {
    const std::uint32_t h = hier(n), c = part(n);
    const NodeData& nd = nodes_[h];
    if (c == 0) {
      const bool pts = nd.has_points;
      if (pts && i == 0) return handle(h, 1);
      if (nd.top_count == 2 && nd.child_count == 8) return handle(h, kGroup);
      return handle(nd.children[i - (pts ? 1u : 0u)], 0);
    }
    if (c == kGroup) return handle(nd.children[i], 0);
    return handle(h, local_[h].cells[c - 1].first_child + i + 1);
  }
  [[nodiscard]] std::span<const Vec3> positions() const { return {pos_, slots_}; }
  [[nodiscard]] std::span<const PointIndex> ids() const { return {ids_, slots_}; }

  // Optional SIMD extension of the concept (see ray_query): the float boxes of a
  // node's children relative to float_origin(), rounded outwards (hierarchy children: stored
  // per hierarchy node at open; cells: stored in the cells when a node is decoded).
  [[nodiscard]] simd::ChildBoxesF child_boxes_f(Node n) const {
    const std::uint32_t h = hier(n), c = part(n);
    const NodeData& nd = nodes_[h];
    const float* f = &fboxes_[std::size_t{h} * kBoxesPerNode].v[0];
    constexpr unsigned stride = sizeof(FBox) / sizeof(float);
    if (c == 0) {
      const bool pts = nd.has_points;
      if (pts && nd.top_count == 2 && nd.child_count == 8) return {f + 9 * stride, stride, 2};
      return {pts ? f : f + stride, stride, nd.top_count};
    }
    if (c == kGroup) return {f + stride, stride, nd.child_count};
    const std::vector<Cell>& cells = local_[h].cells;
    const Cell& cell = cells[c - 1];
    return {&cells[cell.first_child].f[0], sizeof(Cell) / sizeof(float), cell.child_count};
  }
  /// The root box's minimum corner (float boxes are relative to it) and its largest edge.
  [[nodiscard]] Vec3 float_origin() const { return nodes_.empty() ? Vec3(0.0) : nodes_[0].box.lo; }
  [[nodiscard]] double float_extent() const { return nodes_.empty() ? 0.0 : nodes_[0].box.max_extent(); }

  [[nodiscard]] const CopcInfo& info() const { return info_; }
  [[nodiscard]] std::size_t node_count() const { return nodes_.size(); }
  /// Nodes decoded so far (including re-decodes after eviction) and nodes resident now.
  [[nodiscard]] std::uint64_t decodes() const { return decodes_.load(); }
  [[nodiscard]] std::size_t resident_nodes() const;
  /// Bytes of decoded nodes resident now (the cache's own accounting: per node the whole pages
  /// of its slots' positions and ids, its slots' decoded attributes, its local tree's cells and
  /// permutation, and the sorted copy of its own points a node with children keeps), and the
  /// most that were resident at once since opening.
  [[nodiscard]] std::size_t resident_bytes() const { return resident_bytes_.load(); }
  [[nodiscard]] std::size_t peak_resident_bytes() const { return peak_bytes_.load(); }
  /// Position of the point with file-order index `id` (the RayHit::index of a query on this
  /// index), decoding its node if needed (slots are in Morton order: found via the node's
  /// permutation). Throws std::out_of_range for id >= the point count,
  /// FormatError for a corrupted chunk.
  [[nodiscard]] Vec3 position_of(PointIndex id) const;
  /// Releases least recently touched nodes (by batch: the nodes touched since the last call or
  /// QueryScope are the most recent, in no order among themselves) until the resident positions,
  /// ids, attributes and local trees fit the cache budget; returns the nodes evicted. Must not
  /// run concurrently with queries on this index (call it between batches).
  std::size_t trim_cache();

  /// One unit of query work (e.g. a render tile) on one thread, during which the nodes it
  /// touches stay valid while other threads' scopes end and trim the cache. Opening announces
  /// the scope; closing withdraws it and, when the resident bytes near the budget, evicts least
  /// recently used nodes: a node that a scope still open might have reached is only retired
  /// (unpublished: the next touch revives it without a decode) and its memory released by the
  /// first scope to close after every scope open at its retirement has closed. The open scopes'
  /// nodes cannot be evicted, so closing scopes keep a reserve for what they decode: they trim
  /// once the resident bytes pass the budget less the reserve (a quarter of the budget, grown by
  /// each excess over the budget a closing scope sees, up to a half). So while queries run in
  /// scopes, resident_bytes() stays within cache_bytes() once the reserve has learnt what the
  /// scopes in flight decode, unless they decode more than half the budget (a budget
  /// below what the open scopes reach: the reserve is then dropped, the budget exceeded by
  /// about what they reach, and nodes not evicted early only to be decoded again), with no
  /// lock or shared write per ray. When scopes are in use, every query running
  /// concurrently with them must run in one. Nothing in a scope may keep a slot, span or
  /// position of this index past its end. Not copyable or movable; close it on the thread
  /// that opened it.
  class QueryScope {
   public:
    explicit QueryScope(const CopcIndex& index);
    ~QueryScope();
    QueryScope(const QueryScope&) = delete;
    QueryScope& operator=(const QueryScope&) = delete;

   private:
    const CopcIndex& index_;
    unsigned slot_;
  };
  /// The cache budget in bytes (the constructor's `cache_bytes`).
  [[nodiscard]] std::size_t cache_bytes() const { return cache_bytes_; }

  /// Per-point attributes decoded into slots with the positions (bits, `Attr`).
  enum Attr : unsigned { kRgb = 1, kIntensity = 2, kClassification = 4 };
  /// Also decode `attrs` (Attr bits) into slot-ordered arrays (rgb(), intensity(),
  /// classification()) when a node is loaded, from the chunk's RGB, intensity and classification
  /// layers only (LAZ layered chunks: the other layers stay compressed). Colour is normalised as
  /// read_point_cloud() does (docs/formats.md): 8-bit values in the 16-bit fields are scaled by
  /// 257, a file whose colours are all zero has none (rgb() then stays empty); deciding this
  /// decodes RGB layers node by node in file order until a channel exceeds 255. Resident nodes
  /// are dropped. Must not run concurrently with queries. Throws FormatError.
  void set_attributes(unsigned attrs);
  /// Slot-ordered attributes (size positions().size() when decoded, else empty); a slot is valid
  /// once node_points() returned its node and until the next trim_cache() (or, in a QueryScope,
  /// until the scope ends).
  [[nodiscard]] std::span<const Rgb16> rgb() const { return {rgb_, rgb_ ? slots_ : 0}; }
  [[nodiscard]] std::span<const std::uint16_t> intensity() const { return {int_, int_ ? slots_ : 0}; }
  [[nodiscard]] std::span<const std::uint8_t> classification() const { return {cls_, cls_ ? slots_ : 0}; }
  /// True when the point format carries RGB (PDRF 7, 8) and not every colour is zero; only
  /// known after set_attributes(kRgb) (false before).
  [[nodiscard]] bool has_rgb() const { return rgb_ != nullptr; }

  /// One node's points as a whole-file pass sees them: positions, and (when asked) normalised
  /// colour, intensity, classification (empty spans otherwise), in the node's file order.
  struct NodeBlock {
    std::span<const Vec3> positions;
    std::span<const Rgb16> rgb;
    std::span<const std::uint16_t> intensity;
    std::span<const std::uint8_t> classification;
  };
  /// Decodes every node with points in file (chunk offset) order into a scratch buffer, outside
  /// the cache, and calls f with it until f returns false: a streaming whole-file pass in bounded
  /// memory (one node at a time), for whole-cloud statistics. `attrs`: Attr bits to decode
  /// (kRgb needs set_attributes(kRgb) first for the normalisation). Throws FormatError.
  void scan(unsigned attrs, const std::function<bool(const NodeBlock&)>& f) const;

  /// Sample positions for the auto radius without decoding the file: `max_nodes` nodes chosen
  /// as those holding the file-order points i * N / max_nodes (so a node is picked with
  /// probability proportional to its point count, as the whole-file evenly spaced sample picks
  /// its points), and within them evenly spaced points, at most `max_samples` in all. Decodes
  /// only those nodes and their ancestors. Deterministic.
  [[nodiscard]] std::vector<Vec3> spacing_samples(std::size_t max_samples = 20000, std::size_t max_nodes = 64) const;

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  struct NodeData {
    AABB box;
    std::uint32_t entry = 0;         // index into info_.nodes
    std::uint32_t own = 0;           // points its chunk stores
    std::uint64_t first_id = 0;      // file-order index of the node's first point
    std::uint32_t parent = kNone;    // nodes_ index
    std::uint32_t children[8] = {};  // hierarchy children (nodes_ indices)
    std::uint32_t in_octant[8] = {kNone, kNone, kNone, kNone, kNone, kNone, kNone, kNone};  // child per Morton digit
    unsigned child_count = 0;        // hierarchy children
    unsigned top_count = 0;          // children of the hierarchy node's handle (see the class doc)
    int level = 0;
    bool has_points = false;         // it or an ancestor stores points: it has a points node
    bool pushes = false;             // its points may move to its children (children, level < 21)
    std::uint64_t code_lo = 0, code_hi = 0;  // Morton codes of its cube: [code_lo, code_hi)
  };
  /// One cell of a node's local tree: tight box, its slots (absolute; empty unless a leaf), its
  /// children (contiguous cells from first_child).
  struct Cell {
    float f[8];  // box relative to float_origin(), rounded outwards (lo xyz, hi xyz, 2 unused)
    AABB box;
    SlotRange slots;
    std::uint32_t first_child = 0;
    std::uint32_t child_count = 0;
  };
  /// Decoded points column by column: position, file-order id and the decoded attributes (an
  /// attribute column is empty when not decoded).
  struct Points {
    std::vector<Vec3> pos;
    std::vector<PointIndex> id;
    std::vector<Rgb16> rgb;
    std::vector<std::uint16_t> intensity;
    std::vector<std::uint8_t> classification;
    void clear();
    /// Appends point j of `from` (its non-empty columns).
    void append(const Points& from, std::size_t j);
  };
  /// A decoded node's own points sorted by (Morton code, file order), kept while it is resident
  /// when its children may take some of them (NodeData::pushes); index_of[k] = the sorted
  /// position of its file-order point k.
  struct Source : Points {
    std::vector<std::uint64_t> code;
    std::vector<std::uint32_t> index_of;
    [[nodiscard]] std::size_t bytes() const;
  };
  /// A decoded node's local tree over the points it owns, the slot permutation (slot_of[j] =
  /// slot - begin of owned candidate j, the node's own points first in file order; empty when
  /// the node is small enough to stay in that order) and, when it pushes, its Source.
  struct Local {
    std::vector<Cell> cells;
    std::vector<std::uint32_t> slot_of;
    Source src;
  };
  static constexpr std::uint32_t kGroup = 0xFFFFFFFFu;
  /// Float boxes of a hierarchy node's children: [points node, 8 hierarchy children, points
  /// node, group] (the last two: the children of the handle when they are grouped).
  struct FBox {
    float v[8];
  };
  static constexpr std::size_t kBoxesPerNode = 11;
  static FBox float_box(const AABB& b, const Vec3& origin);
  static std::uint32_t hier(Node n) { return static_cast<std::uint32_t>(n); }
  static std::uint32_t part(Node n) { return static_cast<std::uint32_t>(n >> 32); }
  static Node handle(std::uint32_t h, std::uint32_t part) { return Node{part} << 32 | h; }
  /// Marks hierarchy node h as used in the current batch (the LRU clock counts trim_cache calls
  /// and QueryScopes: no shared counter written per ray) and decodes it on first touch.
  void touch(std::uint32_t h) const {
    const std::uint64_t now = clock_.load(std::memory_order_relaxed);
    if (touched_[h].load(std::memory_order_relaxed) != now) touched_[h].store(now, std::memory_order_relaxed);
    ensure_loaded(h);
  }
  // Node states (state_): not decoded, decoded and published, retired (decoded but unpublished
  // until no scope open at its retirement can reach it; the next touch publishes it again).
  static constexpr std::uint8_t kAbsent = 0, kLoaded = 1, kRetired = 2;
  // The state is read sequentially consistent: with the scope's announcement (an RMW) and the
  // trimmer's retire-then-read-announcements, a scope either is seen by the trimmer or sees the
  // retirement (the same instruction as an acquire load on x86-64 and AArch64).
  void ensure_loaded(std::uint32_t h) const {
    if (state_[h].load(std::memory_order_seq_cst) != kLoaded) load(h);
  }
  void load(std::uint32_t n) const;
  // Releases node n's pages and local tree (caller holds its lock; no query can reach it).
  void release(std::uint32_t n) const;
  // The trim run when a scope closes over budget (caller holds trim_mutex_).
  void trim_in_flight() const;
  // Releases the retired nodes no open scope can reach (caller holds trim_mutex_).
  void free_retired() const;
  // Orders the points node n owns (pos[j], j < slots.size()) in Morton order for its slots and
  // builds its local tree into local_[n] (order[r] = the candidate at slot slots.begin + r).
  void build_local(std::uint32_t n, SlotRange slots, std::vector<Vec3>& pos, std::vector<std::uint32_t>& order) const;
  // The node owning a point with Morton code `code` stored by (or pushed to) node `from`.
  [[nodiscard]] std::uint32_t owner(const Vec3& p, std::uint64_t code, std::uint32_t from) const;
  // Position of the k-th point (file order) of decoded hierarchy node n.
  [[nodiscard]] Vec3 own_position(std::uint32_t n, std::uint64_t k) const;
  // Decodes node n's records (layers: laz Layer bits) into `buf`.
  void decode_records(std::uint32_t n, std::uint32_t layers, std::vector<std::uint8_t>& buf) const;
  [[nodiscard]] std::size_t slot_bytes() const;

  CopcInfo info_;
  std::string name_;
  struct Map;
  std::unique_ptr<Map> map_;
  std::vector<NodeData> nodes_;
  std::vector<FBox> fboxes_;  // kBoxesPerNode per hierarchy node
  std::vector<std::uint32_t> by_first_id_;  // nodes holding points, by first_id
  std::size_t slots_ = 0;
  Vec3* pos_ = nullptr;
  PointIndex* ids_ = nullptr;
  Rgb16* rgb_ = nullptr;
  std::uint16_t* int_ = nullptr;
  std::uint8_t* cls_ = nullptr;
  std::uint16_t rgb_mul_ = 1;  // 257 when the file stores 8-bit colour
  unsigned attrs_ = 0;
  std::size_t cache_bytes_;
  mutable std::unique_ptr<Local[]> local_;  // per hierarchy node, filled by load()
  // Slot range of each node's owned points, assigned at its first decode (a node owns the same
  // points at every decode) from next_slot_ ({kNone, kNone} before); the owned sets partition
  // the file's points.
  mutable std::unique_ptr<SlotRange[]> range_;
  mutable std::atomic<std::size_t> next_slot_{0};
  mutable std::unique_ptr<std::atomic<std::uint8_t>[]> state_;
  mutable std::unique_ptr<std::atomic<std::uint64_t>[]> touched_;
  mutable std::unique_ptr<std::atomic<std::size_t>[]> node_bytes_;     // accounted bytes of a resident node
  mutable std::unique_ptr<std::atomic<std::uint64_t>[]> retired_at_;  // epoch of a node's retirement
  mutable std::atomic<std::uint64_t> clock_{1}, decodes_{0};
  mutable std::atomic<std::size_t> resident_bytes_{0}, peak_bytes_{0};
  // The room kept for the nodes the open scopes decode (QueryScope): a quarter of the budget at
  // first, grown by each excess over the budget a closing scope sees, up to a half.
  mutable std::atomic<std::size_t> reserve_;
  // Set when an excess would take the reserve past half the budget: the scopes in flight
  // alone reach about what the budget holds, so no reserve can keep it, and one only evicts
  // nodes to decode them again; the reserve is then 0 for good (trims at the budget itself).
  mutable std::atomic<bool> over_reach_{false};
  // Bytes above which a closing scope trims: the budget less the reserve.
  std::size_t trim_threshold() const;
  // Grows the reserve by `excess` (bytes over the budget at a scope's close); see over_reach_.
  void grow_reserve(std::size_t excess) const;
  mutable std::mutex locks_[32];
  // Scopes: open scopes announce the retirement epoch they started in (0: slot free).
  static constexpr unsigned kScopeSlots = 256;
  mutable std::atomic<std::uint64_t> epoch_{1};
  mutable std::unique_ptr<std::atomic<std::uint64_t>[]> scopes_;
  mutable std::mutex trim_mutex_;
  mutable std::vector<std::uint32_t> retired_;  // nodes retired and not yet released (trim_mutex_)
};

static_assert(SpatialIndex<CopcIndex>);

}  // namespace rayscan::io

// The ray, kNN and surfel queries of this index, compiled once in the library
// (site/src/query_instances.cpp, site/src/surfel_instances.cpp) where the traversal's definitions are.
namespace rayscan {
RAYSCAN_RAY_QUERY_INSTANCES(extern template, io::CopcIndex)
RAYSCAN_KNN_QUERY_INSTANCES(extern template, io::CopcIndex)
RAYSCAN_SURFEL_INSTANCES(extern template, io::CopcIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(extern template, io::CopcIndex)
}  // namespace rayscan
