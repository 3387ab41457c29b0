// The rayscan index file (.rsi): an octree over one or more point cloud files, built out of core
// (external sort by Morton code within a memory budget) and queried through a read-only memory
// map. Format: docs/index-format.md. The mapped index satisfies SpatialIndex, so the ray query
// (paper Algorithm 1), the point queries and the batch API run on it unchanged and return what
// the in-memory Octree::build_bulk over the same points returns, bit for bit.
#pragma once

#include "rayscan/io/point_reader.hpp"
#include "rayscan/octree/entry_grid.hpp"
#include "rayscan/octree/id_view.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/rgb_view.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/spatial_index.hpp"
#include "rayscan/octree/surfel.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::io {

/// A malformed, truncated, corrupted or stale index file. what() is one line naming the file, the
/// section or byte offset and what was expected ("site.rsi: section positions (byte 8192):
/// checksum 1a2b3c4d, expected 5e6f7a8b").
struct IndexError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One source file of an index, as it was when the index was built.
struct IndexSource {
  std::string path;           ///< as given to build_index_file (absolute)
  std::uint64_t size = 0;     ///< bytes
  std::int64_t mtime_ns = 0;  ///< modification time, ns since the epoch
  std::uint64_t points = 0;   ///< points read from it; its points have ids [first_id, first_id + points)
  std::uint64_t first_id = 0;
  std::string format;         ///< "LAS 1.2", "PLY 1.0", ...
};

/// One section of an index file as its header's section table lists it (docs/index-format.md).
struct IndexSectionInfo {
  std::string name;           ///< "sources", "crs", "positions", "ids", "rgb" or "rgb8", ..., "nodes"
  std::uint64_t offset = 0;   ///< byte offset in the file (a multiple of 4096)
  std::uint64_t bytes = 0;    ///< size in bytes (without the alignment gap after it)
};

/// Progress of a build: `phase` is "scan" (a bounds pass, several-run builds of non-LAS inputs;
/// total 0), "read", "sort", "write" (one-run build), "merge" (several runs), "nodes" or
/// "spacing"; `done` of `total` points.
using IndexProgress = std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)>;

/// The attributes an index file can store besides positions (docs/index-format.md "Sections"):
/// id, rgb, intensity, classification, gps_time. What `rayscan index --attributes all` means, and
/// the only attribute bits a header may carry.
inline constexpr AttributeSet kIndexAttributes{static_cast<std::uint32_t>(Attribute::id) |
                                               static_cast<std::uint32_t>(Attribute::rgb) |
                                               static_cast<std::uint32_t>(Attribute::intensity) |
                                               static_cast<std::uint32_t>(Attribute::classification) |
                                               static_cast<std::uint32_t>(Attribute::gps_time)};

/// Options of build_index_file().
struct IndexBuildOptions {
  /// Tree layout and parameters: adaptive or fixed (layered is not supported by the external
  /// build; std::invalid_argument).
  OctreeConfig config;
  /// Attributes stored besides positions: any of id, rgb, intensity, classification, gps_time.
  /// `id` stores the ids section (each slot's original point id, 4 bytes per point); without it
  /// the index reports points in slot (index) order: ids() is the identity (docs/index-format.md
  /// "Ids"). Attributes some input lacks are not stored (a note says which).
  AttributeSet attributes = AttributeSet::none();
  /// Memory budget of the sort runs and merge buffers (bytes); peak RSS stays within this plus
  /// what scales with it by a small fraction or not at all: one reader chunk, the per-cell point
  /// counts of the fused node build (at most memory_bytes / 16 / 12 cells of 4 bytes), the
  /// background writer's 8 buffers (memory_bytes / 128 each, clamped to [64 KiB, 4 MiB]), and the
  /// nodes section's stage (node_stage_pages x 4 KiB) with its pinned pages (docs/index-format.md
  /// "Build").
  std::uint64_t memory_bytes = std::uint64_t{4} << 30;
  /// Positions: the most compact exact encoding (true: the LAS int32 grid when every input is
  /// LAS/LAZ on one scale and offset, else float32 when every coordinate is a float, else
  /// float64; docs/index-format.md "Positions") or always float64 (false; `--positions float64`).
  bool compact_positions = true;
  /// Colour: 3 bytes per point (rgb8 section) when every delivered rgb value is b * m, b <= 255,
  /// for one m in {1, 256, 257} (checked during the read pass; decoded bit-identically), else the
  /// 6-byte rgb section (true; docs/index-format.md "Colour"), or always 6 bytes (false).
  bool compact_rgb = true;
  /// Folder for the sort runs (default: the output's folder). Removed afterwards.
  std::filesystem::path temp_dir;
  IndexProgress progress;  ///< called every few million points (may be empty)
  /// Pages (4 KiB) of the nodes section staged before they are written by the background writer
  /// (O_DIRECT where the file system allows it; docs/index-format.md "Build" 4); 0 counts as 1.
  /// The default suits any build; tests use 1 so that every page boundary of the node records is
  /// crossed.
  std::size_t node_stage_pages = 1024;
};

/// What a build did.
struct IndexBuildStats {
  std::uint64_t points = 0, nodes = 0, runs = 0, file_bytes = 0;
  unsigned depth = 0;
  AttributeSet attributes;         ///< stored (Attribute::id: the ids section was written)
  PositionEncoding positions = PositionEncoding::float64;  ///< how the positions are stored
  /// The rgb8 multiplier (1, 256 or 257: colours stored in 3 bytes), 0 when rgb is stored in 6
  /// bytes or not at all.
  std::uint32_t rgb_multiplier = 0;
  /// Multi-run builds: true when the nodes were built during the merge from the read pass's
  /// points per cell (no pass over the written positions; docs/index-format.md, "Build"), false
  /// when the cells could not decide the upper tree and the node phase read the positions back.
  bool nodes_in_merge = false;
  std::vector<std::string> notes;  ///< decisions the user should know about
};

/// Builds the index of `inputs` (their points in this order get ids 0, 1, ...) into `output`
/// (docs/index-format.md, "Build"): when the announced points fit the memory budget, one read
/// pass into memory, a parallel sort of the Morton keys (OctreeRules) and the sections written
/// from memory; otherwise sorted runs on the grid of the LAS headers' bounds (checked; read again
/// on the exact grid when a header is wrong) or of a bounds pass, merged into the sections. The
/// nodes are built from the sorted codes exactly as Octree::build_bulk does, so the file is the
/// same byte for byte whichever path ran. Written to a temporary file and renamed (AtomicFile);
/// on any error the temporary and the runs are removed. Throws FormatError (an input),
/// IndexError (inputs disagree: names the file), std::invalid_argument (options),
/// std::runtime_error (I/O, e.g. disk full: names the file and errno text; inputs that change
/// during the build).
IndexBuildStats build_index_file(const std::vector<std::filesystem::path>& inputs,
                                 const std::filesystem::path& output, const IndexBuildOptions& options);

/// Options of MappedIndex::open().
struct IndexOpenOptions {
  /// What open() checks besides the header, the section table, the small metadata sections
  /// (sources, crs) and the root node's box, which are always checked. `always`: every
  /// section's CRC-32C and every node record and id (docs/index-format.md, "Opening and
  /// validation"; `rayscan info --verify`).
  /// `automatic` (default): the same when the file is at most 256 MiB; above, the node records
  /// only (one pass over the nodes section, about 2 bytes per point), so a corrupted file is an error
  /// and no query's work grows past that of the well-formed tree. `metadata_only`: neither (for a
  /// file this process has just written); node records are then sanitised by the accessors
  /// (never a read past the mapping) but a corrupted one can give wrong answers.
  enum class Verify { automatic, always, metadata_only } verify = Verify::automatic;
  /// `automatic` verifies every section of a file of at most this many bytes (well under 0.1 s
  /// at the default, 256 MiB).
  std::uint64_t deep_check_bytes = std::uint64_t{256} << 20;
  /// Fail when a source file still exists but its size or modification time changed.
  bool check_sources = true;
  /// Return unchecked ids from ids() even when the deep checks did not run (for the builder,
  /// which opens its own fresh output).
  bool trust_ids = false;
  /// Read the file ahead in the background (a thread of the index, stopped when it is
  /// destroyed; sequential reads into the page cache): the nodes section first, then the whole
  /// file when it fits half the available memory (MemAvailable). For a job that will touch most of it (a render, a
  /// viewshed): on a file not in the page cache (e.g. right after `rayscan index`, which writes
  /// past the cache) its queries would otherwise each wait for a 4 KiB read (the map is
  /// MADV_RANDOM). Answers are unchanged. Nothing is started when open verified every section
  /// (it has just read the whole file).
  bool read_ahead = false;
};

/// One record of the index file's nodes section (docs/index-format.md, "Node record", format
/// version 4: 32 bytes, little-endian, used in place from the map). The file holds the adaptive or
/// fixed octree, whose nodes are either internal (children, no points of their own) or leaves
/// (points, no children), so one 32-bit field names the first child or the first slot and one
/// holds the count. The Warren & Salmon id of a node is not stored: it is its parent's id times 8
/// plus its octant (paper section 4.1), found by descending from the root (key 1).
struct IndexNodeRecord {
  glm::vec3 lo{0.0f}, hi{0.0f};  ///< bounds of the subtree's points relative to the root cell's
                                 ///< minimum corner, float, rounded outwards (as Octree::NodeRec)
  std::uint32_t first = 0;       ///< internal: node number of the first child; leaf: first slot
  std::uint32_t packed = 0;      ///< bits 0-27 count, 28-30 octant in the parent (root 0), 31 internal
  /// Largest count (children of an internal node: 1..8; points of a leaf).
  static constexpr std::uint32_t kMaxCount = (std::uint32_t{1} << 28) - 1;
  /// The packed field of a node: `count` <= kMaxCount, `octant` < 8.
  static constexpr std::uint32_t pack(std::uint32_t count, unsigned octant, bool internal) {
    return count | (std::uint32_t{octant} << 28) | (internal ? std::uint32_t{1} << 31 : 0u);
  }
  /// True for an internal node (children, no points), false for a leaf (points, no children).
  [[nodiscard]] bool internal() const { return (packed >> 31) != 0; }
  /// An internal node's child count (1..8) or a leaf's point count.
  [[nodiscard]] std::uint32_t count() const { return packed & kMaxCount; }
  /// The node's octant (Morton digit 0..7) in its parent's cell; 0 for the root.
  [[nodiscard]] unsigned octant() const { return (packed >> 28) & 7u; }
};
static_assert(sizeof(IndexNodeRecord) == 32, "the nodes section's record is 32 bytes");

/// A read-only memory-mapped index file satisfying SpatialIndex. Node records, positions and ids
/// are used in place (no copy): opening a large file costs the header, section table and sources
/// checks and one pass over the node records (IndexOpenOptions::verify); the node accessors are
/// checked too, so no query reads past the mapping whichever checks ran.
class MappedIndex {
 public:
  using Node = std::uint32_t;

  /// Opens and validates `path`. Throws IndexError (one line: file, section/offset, expectation).
  static MappedIndex open(const std::filesystem::path& path, const IndexOpenOptions& options = {});

  // SpatialIndex concept ---------------------------------------------------------------------
  [[nodiscard]] bool empty() const { return points_ == 0; }
  [[nodiscard]] Node root() const { return 0; }
  [[nodiscard]] AABB node_bounds(Node n) const {
    const IndexNodeRecord& r = nodes_[n];
    return {cell_.lo + Vec3(r.lo), cell_.lo + Vec3(r.hi)};
  }
  // The node accessors are checked, so that a file opened without the deep checks (a large file;
  // IndexOpenOptions) can never lead a query outside the mapping or into a cycle: a point range
  // that is reversed or beyond the N points reads as empty, and a child range that is not strictly
  // after the node, has more than 8 children or runs past the M nodes reads as a leaf. A verified
  // (or well-formed) file never triggers either, so results are those of the in-memory octree.
  [[nodiscard]] SlotRange node_points(Node n) const {
    const IndexNodeRecord& r = nodes_[n];
    const std::uint64_t end = std::uint64_t{r.first} + r.count();
    return !r.internal() && end <= points_ ? SlotRange{r.first, static_cast<std::uint32_t>(end)} : SlotRange{0, 0};
  }
  [[nodiscard]] unsigned child_count(Node n) const {
    const IndexNodeRecord& r = nodes_[n];
    const std::uint32_t c = r.count();
    return r.internal() && c <= 8 && r.first > n && std::uint64_t{r.first} + c <= node_count_ ? c : 0u;
  }
  /// Child i < child_count(n) of n.
  [[nodiscard]] Node child(Node n, unsigned i) const { return nodes_[n].first + i; }
  /// child(n, i) is child(n, 0) + i (ray_query's child step pushes the children in one kernel).
  static constexpr bool kContiguousChildren = true;

  // Optional SIMD extension of the concept (see ray_query) -------------------------------------
  /// The float boxes of n's children (their node records' lo/hi, contiguous in the mapped nodes
  /// section with a stride of 8 floats, relative to float_origin()): the same float values as
  /// Octree::child_boxes_f, so the SIMD child test prunes exactly as on the in-memory octree. The
  /// count is the checked child_count(n) (0 for a sanitised record: no box is read), so the
  /// kernels (which read 8 floats per box: lo, hi and the record's two uint32 fields) never read
  /// past the mapping: rows past the count are read as they are (rows8) only when 8 records from
  /// the first child lie inside the nodes section.
  [[nodiscard]] simd::ChildBoxesF child_boxes_f(Node n) const {
    const unsigned nc = child_count(n);
    const std::uint64_t first = nc > 0 ? nodes_[n].first : 0;
    return {&nodes_[first].lo.x, sizeof(IndexNodeRecord) / sizeof(float), nc, nc > 0 && first + 8 <= node_count_};
  }
  /// The origin the float boxes are relative to (the root cell's minimum corner), and the largest
  /// magnitude of a float box coordinate (the root cell's edge), as Octree's.
  [[nodiscard]] const Vec3& float_origin() const { return cell_.lo; }
  /// See float_origin().
  [[nodiscard]] double float_extent() const { return cell_.max_extent(); }
  /// The entry grids of the tree (EntryGrid: the first hit's and the kNN's entry-point search, as
  /// on Octree), built at open from the node records of its top levels (build_entry_grid) and the
  /// quantizer of the build (the root cell's corner, OctreeRules::root_side of the stored point
  /// bounds): the same cells as Octree::entry_grid of the same points and config. None (cells
  /// null) for a tree of depth <= 1.
  [[nodiscard]] EntryGrid entry_grid() const { return entry_.view(); }
  /// Positions by slot, decoded from the file's encoding (float64 in place, float32 or the LAS
  /// int32 grid: docs/index-format.md "Positions"), bit-identical to the sources' readers.
  [[nodiscard]] PositionView positions() const { return positions_; }
  /// The original id of each slot (a point's index in the concatenated sources): the stored ids
  /// section, or, for a file built without ids (has_ids() false), the identity IdView (slot s is
  /// point s: every consumer then reports points in index order). Every id a consumer reads is
  /// below N: a verified file had them checked at open; on a file opened without the deep checks
  /// (IndexOpenOptions) the view is checked (IdView::checked: each id read through `[slot]` is
  /// compared with N), because every consumer indexes per-point arrays by id (normals,
  /// visibility, query, the renderer's radii, ray hits' `index`). Reading a corrupted id throws
  /// IndexError naming the file, the byte offset and the slot; queries that never read it are
  /// answered exactly. (Checking all N ids up front would hold the first rendered tile of a
  /// 1e9-point file for a second or more.) The view must not outlive the index.
  [[nodiscard]] IdView ids() const;
  /// True when the file holds the ids section (built with `--attributes id`).
  [[nodiscard]] bool has_ids() const { return ids_ != nullptr; }

  // Index file specifics -----------------------------------------------------------------------
  /// The octant (0..7, Morton digit) of node n in its parent's cell; 0 for the root. A node's
  /// Warren & Salmon id is its parent's id times 8 plus this (not stored: IndexNodeRecord).
  [[nodiscard]] unsigned node_octant(Node n) const { return nodes_[n].octant(); }
  /// The octree's root cube (world units), from the header.
  [[nodiscard]] const AABB& root_cell() const { return cell_; }
  /// Nodes in the node table (node handles are 0 .. node_count() - 1, the root 0).
  [[nodiscard]] std::size_t node_count() const { return node_count_; }
  /// The depth of the deepest node (the root is depth 0), from the header.
  [[nodiscard]] unsigned depth() const { return depth_; }
  /// The organisation the index was built with (layout, capacity, depths).
  [[nodiscard]] const OctreeConfig& config() const { return config_; }
  /// Points stored per depth (index = depth).
  [[nodiscard]] std::vector<std::uint64_t> points_per_level() const;
  /// How the positions are stored (PositionEncoding; the LAS grid's scale and offset are
  /// positions().scale() / offset()).
  [[nodiscard]] PositionEncoding position_encoding() const { return positions_.encoding(); }
  /// Stored attributes, by slot (like positions()); empty when not stored. rgb() reads the
  /// 6-byte section in place or decodes the 3-byte rgb8 section (byte x multiplier, bit-identical
  /// to the readers' values; RgbView::multiplier()).
  [[nodiscard]] RgbView rgb() const { return rgb_; }
  [[nodiscard]] std::span<const std::uint16_t> intensity() const { return intensity_; }
  [[nodiscard]] std::span<const std::uint8_t> classification() const { return classification_; }
  [[nodiscard]] std::span<const double> gps_time() const { return gps_; }
  /// The stored attributes (Attribute::id when the ids section is present).
  [[nodiscard]] AttributeSet attributes() const { return attrs_; }
  /// The files the index was built from (each with its range of ids).
  [[nodiscard]] const std::vector<IndexSource>& sources() const { return sources_; }
  /// The CRS of the stored coordinates as WKT (the crs section; "" = none).
  [[nodiscard]] const std::string& crs_wkt() const { return crs_; }
  /// Size of the mapped file, bytes.
  [[nodiscard]] std::uint64_t file_bytes() const;
  /// Drops the map's resident pages from the process (MADV_DONTNEED on the shared read-only map:
  /// the data stays in the page cache and is faulted in again when touched), so a long pass of
  /// scattered reads keeps a bounded resident set. Never changes what the index reads.
  void release_pages() const;
  /// The path the index was opened from.
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// The median nearest-neighbour spacing of the stored points (world units; 0 below two distinct
  /// points), computed at build time by median_nn_spacing_by_id (rayscan/octree/spacing.hpp) over this
  /// index and stored in the header: the "auto" radius without a kNN pass at open.
  [[nodiscard]] double median_nn_spacing() const { return spacing_; }
  /// The exact bounds of the stored positions (bounds_of(positions()), stored in the header).
  [[nodiscard]] const AABB& bounds() const { return bounds_; }
  /// The section table, in file order.
  [[nodiscard]] const std::vector<IndexSectionInfo>& sections() const { return sections_; }
  /// True when open() ran the deep checks (every section's CRC, every node record and id).
  [[nodiscard]] bool verified() const { return verified_; }
  /// The stored points and attributes in the sources' original order (ids()), as read_point_cloud
  /// of the concatenated sources would return positions and the stored attributes; in slot
  /// (index) order when the file has no ids. Allocates.
  [[nodiscard]] PointCloud to_point_cloud() const;

  MappedIndex(MappedIndex&&) noexcept;
  MappedIndex& operator=(MappedIndex&&) noexcept;
  MappedIndex(const MappedIndex&) = delete;
  MappedIndex& operator=(const MappedIndex&) = delete;
  ~MappedIndex();

 private:
  MappedIndex() = default;
  /// The node record checks of open() (docs/index-format.md, "Opening and validation" 2): point
  /// and child ranges, boxes (minimum <= maximum, inside the parent's), a tree (every node but the
  /// root the child of exactly one earlier node, octants increasing), no node below the header's
  /// depth, and the header's points per level.
  /// `node_offset`: the nodes section's byte offset (messages). Throws IndexError.
  void verify_nodes(std::uint64_t node_offset) const;
  /// Throws IndexError for the first stored id >= N or the first slot repeating an earlier slot's
  /// id (section ids, slot, byte offset); nothing without an ids section.
  void check_ids() const;
  /// The handler of the checked IdView of an unverified file: throws IndexError naming the file,
  /// the byte and the slot whose id is >= N. `map` is the index's Map.
  [[noreturn]] static void bad_id(const void* map, std::size_t slot);
  struct Map;
  std::unique_ptr<Map> map_;
  std::filesystem::path path_;
  OctreeConfig config_;
  AABB cell_;
  unsigned depth_ = 0;
  std::size_t points_ = 0, node_count_ = 0;
  double spacing_ = 0.0;
  AABB bounds_;
  EntryCells entry_;  ///< entry_grid()
  bool verified_ = false;
  std::vector<IndexSectionInfo> sections_;
  const IndexNodeRecord* nodes_ = nullptr;
  PositionView positions_;
  const PointIndex* ids_ = nullptr;  ///< null: no ids section (identity)
  std::uint64_t ids_offset_ = 0;  ///< byte offset of the ids section (error messages)
  RgbView rgb_;
  std::span<const std::uint16_t> intensity_;
  std::span<const std::uint8_t> classification_;
  std::span<const double> gps_;
  AttributeSet attrs_ = AttributeSet::none();
  std::vector<IndexSource> sources_;
  std::string crs_;
};

static_assert(SpatialIndex<MappedIndex>);

/// True when `path` names an index file (extension .rsi, case-insensitive).
bool is_index_file(const std::filesystem::path& path);

}  // namespace rayscan::io

// The ray, kNN and surfel queries of this index, compiled once in the library
// (site/src/query_instances.cpp, site/src/surfel_instances.cpp) where the traversal's definitions are.
namespace rayscan {
RAYSCAN_RAY_QUERY_INSTANCES(extern template, io::MappedIndex)
RAYSCAN_KNN_QUERY_INSTANCES(extern template, io::MappedIndex)
RAYSCAN_SURFEL_INSTANCES(extern template, io::MappedIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(extern template, io::MappedIndex)
}  // namespace rayscan
