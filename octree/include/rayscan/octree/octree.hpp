// Octree over raw points after Warren & Salmon (1993), as customised in paper section 4.1: node ids
// of depth + Morton code, lazily built per-level index maps, and three data organisations.
#pragma once

#include "rayscan/base/default_init_vector.hpp"
#include "rayscan/octree/morton.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/simd.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <algorithm>
#include <bit>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rayscan {

/// Data organisation of an octree (paper section 4.1).
enum class OctreeLayout {
  layered,   ///< every node keeps up to `capacity` points (the first inserted, i.e. the smallest
             ///< original indices) and passes the rest down: each level is a subsample (LOD)
  fixed,     ///< all points in the leaves at depth `depth`: a regular grid
  adaptive   ///< a leaf splits when it holds more than `capacity` points, up to `max_depth`
};

/// Parses "layered" | "fixed" | "adaptive"; throws std::invalid_argument otherwise.
OctreeLayout parse_octree_layout(const std::string& s);
/// The name parse_octree_layout accepts.
const char* to_string(OctreeLayout layout);

/// The node capacity (points) of a layout when none is given: the one default of OctreeConfig,
/// IndexOptions, scene files, `rayscan index` / `rayscan query` and the Python Octree.
/// - adaptive: 64 points per leaf. Measured against 32 (bench/notes/):
///   first sphere hits 1.05-1.6x faster on uniform clouds of 1e6 and 1e7 points (32 leaves cells of
///   ~31 points split into eight leaves of ~4), renders of the bundled Autzen scan 2-11% faster,
///   fewer node records.
/// - layered: 32 points per node, the paper's Table 1 configuration (64 measured ~10% slower for
///   first hits, as every node's points are tested on the way down).
/// - fixed: unused (every point sits in a leaf at `depth`); 64, as adaptive.
[[nodiscard]] constexpr std::uint32_t default_capacity(OctreeLayout layout) {
  return layout == OctreeLayout::layered ? 32u : 64u;
}

/// Octree build parameters. The default capacity is the default layout's; a caller that sets
/// another layout takes default_capacity(layout) (or for_layout) for its capacity.
struct OctreeConfig {
  OctreeLayout layout = OctreeLayout::adaptive;
  std::uint32_t capacity = default_capacity(OctreeLayout::adaptive);  ///< points per node (layered) / per leaf before a split (adaptive)
  unsigned max_depth = 21;      ///< deepest level for layered and adaptive (<= 21)
  unsigned depth = 6;           ///< leaf depth for fixed (<= 21)
  /// Throws std::invalid_argument for capacity 0 or a depth above 21.
  void validate() const;
  /// The defaults of `layout`: its default_capacity, max_depth 21, depth 6.
  [[nodiscard]] static OctreeConfig for_layout(OctreeLayout layout) {
    OctreeConfig c;
    c.layout = layout;
    c.capacity = default_capacity(layout);
    return c;
  }
};

/// The construction rules every builder of the octree shares, defined once: the in-memory builders
/// below and the external-memory index file build (rayscan/site/index_file.hpp) call these, so
/// their trees are identical node for node.
struct OctreeRules {
  /// The root cell of points whose bounding box is `bounds`: the cube of edge max_extent grown by
  /// 1e-9 relative (edge 1 for a single point or an empty box) anchored at bounds.lo.
  static AABB root_cell(const AABB& bounds);
  /// The edge length of root_cell(bounds) as computed before adding it to the corner.
  static double root_side(const AABB& bounds);
  /// Quantises positions to the 2^21 cells per axis of a root cell and returns their 63-bit
  /// Morton code (coordinates are truncated; outside points clamp to the border cells).
  struct Quantizer {
    Vec3 lo;
    double scale;  ///< cells per world unit
    /// Cells of the root cell with corner `lo` and edge `side` (root_side()).
    Quantizer(const Vec3& lo, double side);
    /// The cell in [0, 2^21) of coordinate v on axis a (0 x, 1 y, 2 z): truncated, clamped to the
    /// border cells (NaN: 0).
    [[nodiscard]] std::uint32_t cell(double v, unsigned a) const {
      constexpr std::uint32_t kCells = 1u << kMortonBits;
      const double f = (v - lo[a]) * scale;  // truncation == floor for f >= 0
      if (!(f >= 0.0)) return 0;
      if (f >= kCells - 1) return kCells - 1;
      return static_cast<std::uint32_t>(f);
    }
    [[nodiscard]] std::uint64_t code(const Vec3& p) const {
      return morton_encode(cell(p.x, 0), cell(p.y, 1), cell(p.z, 2));
    }
  };
  /// Whether a node at `depth` holding `count` points (all with one Morton code when `all_same`)
  /// is split (layout rules of paper section 4.1; the adaptive duplicate guard).
  static bool splits(const OctreeConfig& c, unsigned depth, std::size_t count, bool all_same);
  /// A float bound strictly below (up = false) or above (up = true) the double offset `off`
  /// from the root cell corner, so that a stored float box always contains the points.
  static float float_bound(double off, bool up);
  /// Octant digit of a 63-bit Morton code when descending from `depth` to depth + 1.
  static unsigned octant(std::uint64_t code, unsigned depth) {
    return static_cast<unsigned>((code >> (3 * (kMortonBits - depth - 1))) & 7u);
  }
};

/// An octree index satisfying SpatialIndex.
///
/// Storage: positions are copied into one contiguous array in depth-first traversal order, so each
/// node's own points and each subtree's points are contiguous; ids() maps a slot back to the
/// caller's original point index. Children of a node are contiguous in the node array. Node bounds
/// are the tight boxes of the points below the node (tighter than the node's cell, so pruning is
/// stronger; the cell itself is available from cell_bounds()), stored as float offsets from the
/// root cell's corner rounded outwards (so they still contain every point), which keeps a node at
/// 48 bytes and the whole index under 40 bytes per point.
///
/// Cells: the root cell is the cube of edge max_extent (grown by 1e-9 relative so the maximum point
/// falls inside) anchored at the cloud's minimum corner; a point's cell at depth D is given by the
/// top D levels of its 21-bit-per-axis Morton code. Duplicate points never split endlessly: an
/// adaptive leaf whose points all share one 21-bit Morton code is not split.
///
/// Build by insertion (build_by_insertion, as the paper measures) and by bulk loading (build_bulk,
/// sort by Morton code) produce the identical node array, slot order and ids.
class Octree {
 public:
  using Node = std::uint32_t;

  /// Bulk load: Morton-sort the points, then split ranges top-down. O(N log N), in parallel (TBB):
  /// the upper tree serially, then subtrees of at most max(N / 64, 256) points built, gathered and
  /// bounded on their own and renumbered into the serial order (bench/notes/: the parallel bulk
  /// build). Throws std::invalid_argument for a bad config or non-finite position,
  /// std::length_error above 2^32 - 2 points.
  static Octree build_bulk(std::span<const Vec3> positions, const OctreeConfig& config = {});
  /// Insert points one at a time in index order into a pointer-based tree, splitting leaves as they
  /// overflow, then compact it. Same errors as build_bulk; same resulting tree.
  static Octree build_by_insertion(std::span<const Vec3> positions, const OctreeConfig& config = {});

  // SpatialIndex concept ---------------------------------------------------------------------
  [[nodiscard]] bool empty() const { return pos_.empty(); }
  [[nodiscard]] Node root() const { return 0; }
  [[nodiscard]] AABB node_bounds(Node n) const {
    const NodeRec& r = nodes_[n];
    return {cell_.lo + Vec3(r.lo), cell_.lo + Vec3(r.hi)};
  }
  [[nodiscard]] SlotRange node_points(Node n) const {
    return {nodes_[n].own_begin, nodes_[n].own_end};
  }
  [[nodiscard]] unsigned child_count(Node n) const { return nodes_[n].child_count; }
  [[nodiscard]] Node child(Node n, unsigned i) const { return nodes_[n].first_child + i; }
  /// child(n, i) is child(n, 0) + i (ray_query's child step pushes the children in one kernel).
  static constexpr bool kContiguousChildren = true;
  [[nodiscard]] std::span<const Vec3> positions() const { return pos_; }
  [[nodiscard]] std::span<const PointIndex> ids() const { return ids_; }
  /// All slots of the subtree rooted at n (its own points and every descendant's): contiguous.
  [[nodiscard]] SlotRange subtree_points(Node n) const {
    Node last = n;
    while (nodes_[last].child_count) last = nodes_[last].first_child + nodes_[last].child_count - 1;
    return {nodes_[n].own_begin, nodes_[last].own_end};
  }

  // Optional SIMD extension of the concept (see ray_query) -------------------------------------
  /// The float boxes of n's children (contiguous in the node array), relative to float_origin();
  /// rows8 when 8 records from the first child lie inside the node array; soa: n's child block
  /// (the same boxes transposed, child_blocks()).
  [[nodiscard]] simd::ChildBoxesF child_boxes_f(Node n) const {
    const NodeRec& r = nodes_[n];
    return {&nodes_[r.first_child].lo.x, sizeof(NodeRec) / sizeof(float), r.child_count,
            std::size_t{r.first_child} + 8 <= nodes_.size(),
            r.child_count ? child_soa_.data() + std::size_t{kChildBlockFloats} * block_of_[n] : nullptr};
  }
  /// Floats per child block: the 6 x 8 transposed child boxes of one interior node.
  static constexpr unsigned kChildBlockFloats = 48;
  /// The child blocks (bench/notes/: the first hit's child step): for each interior node n,
  /// its children's float boxes as 6 rows of 8 floats at child_blocks() + 48 * block_of(n), so the
  /// 8-wide child test loads them as they are instead of transposing 8 node records; 192 bytes per
  /// interior node and 4 per node (about 1 B per point at the default capacity). Lanes past the
  /// child count hold empty boxes (+inf lo, -inf hi). Built with the tree (build_child_blocks).
  [[nodiscard]] const float* child_blocks() const { return child_soa_.data(); }
  /// The block index of interior node n (unspecified for a leaf).
  [[nodiscard]] std::uint32_t block_of(Node n) const { return block_of_[n]; }
  /// The origin the float boxes are relative to (the root cell's minimum corner), and the largest
  /// magnitude of a float box coordinate (the root cell's edge).
  [[nodiscard]] const Vec3& float_origin() const { return cell_.lo; }
  [[nodiscard]] double float_extent() const { return cell_.max_extent(); }

  /// One cell of an entry grid: the deepest node whose cell contains the grid cell, and its depth
  /// (node_id(node).depth(), kept here so that the search reads one cache line, not the node's).
  struct EntryCell {
    Node node;
    std::uint32_t depth;
  };
  /// The entry grids (entry-point search: a ray starts at the node of the cell where it enters
  /// instead of at the root; Havran's thesis, section 5.3, and the entry points of Reshetov,
  /// Soupikov & Hurley, "Multi-level ray tracing algorithm", SIGGRAPH 2005): for each level l in
  /// [0, depth], the 2^l cells per axis of the root cell at depth l, cell (i, j, k) of level l at
  /// at(l, i, j, k). Every point inside a grid cell's node's cell is in that node's subtree. Depth 0
  /// (cells == nullptr) where the tree has none: a tree of depth <= 1, or nodes above the grid's
  /// depth with points of their own (the layered layout: a subtree there does not hold every point
  /// of its cell).
  struct EntryGrid {
    const EntryCell* cells;  ///< the levels 0..depth one after the other (slot())
    unsigned depth;
    OctreeRules::Quantizer quant;  ///< the points' quantizer (Octree::quantizer())
    double side;                   ///< its root edge (OctreeRules::root_side), world units
    /// The position of cell (i, j, k) of level l in `cells`: levels 0..l-1 before it, then
    /// i + 2^l j + 4^l k.
    [[nodiscard]] static std::size_t slot(unsigned l, unsigned i, unsigned j, unsigned k) {
      return ((std::size_t{1} << (3 * l)) - 1) / 7 + i + (std::size_t{j} << l) + (std::size_t{k} << (2 * l));
    }
    /// Cell (i, j, k) of level l <= depth (each index < 2^l).
    [[nodiscard]] const EntryCell& at(unsigned l, unsigned i, unsigned j, unsigned k) const {
      return cells[slot(l, i, j, k)];
    }
    /// The deepest level's cell index of coordinate v on axis a: the top `depth` bits of its
    /// Morton cell (Quantizer::cell), so the cell a point of that coordinate was sorted into.
    [[nodiscard]] unsigned coord(double v, unsigned a) const { return quant.cell(v, a) >> (kMortonBits - depth); }
    /// The deepest level whose cells hold deepest-level cell indices that differ in the bits
    /// `diff` (their XOR; OR-ed over the axes for a box): depth - bit_width(diff), depth for 0.
    [[nodiscard]] unsigned shared_level(unsigned diff) const {
      return depth - std::min(depth, static_cast<unsigned>(std::bit_width(diff)));
    }
  };
  /// The deepest entry grid: 2^15 cells of 8 bytes (with the coarser levels 293 KB, within a
  /// core's L2).
  static constexpr unsigned kEntryGridMaxDepth = 5;
  /// The entry grids, built with the tree, down to depth min(depth() - 1, kEntryGridMaxDepth): one
  /// level above the deepest leaves (bench/notes/), and no deeper than 8 cells per node.
  [[nodiscard]] EntryGrid entry_grid() const {
    return {entry_cells_.empty() ? nullptr : entry_cells_.data(), entry_depth_, quantizer(), side_};
  }
  // Octree specifics ---------------------------------------------------------------------------
  /// The Warren & Salmon id (depth + Morton code) of node n.
  [[nodiscard]] OctreeNodeId node_id(Node n) const { return OctreeNodeId::from_bits(nodes_[n].key); }
  /// The node with id `id`, or nullopt. Uses the per-level index map of id.depth(), built lazily on
  /// first use (thread-safe) as a sorted (Morton code -> node) table (paper section 4.1).
  [[nodiscard]] std::optional<Node> find(OctreeNodeId id) const;
  /// The deepest existing node whose cell contains p (nullopt outside the root cell).
  [[nodiscard]] std::optional<Node> locate(const Vec3& p) const;
  /// The cubic cell of node n (not the tight bounds).
  [[nodiscard]] AABB cell_bounds(Node n) const;
  /// The root cell (a cube).
  [[nodiscard]] const AABB& root_cell() const { return cell_; }
  /// The quantizer the points' Morton codes (and so their cells) were computed with: corner
  /// root_cell().lo, edge OctreeRules::root_side of the points' bounds (which may differ in the
  /// last bits from root_cell()'s edge, the difference of two rounded corners).
  [[nodiscard]] OctreeRules::Quantizer quantizer() const { return {cell_.lo, side_}; }
  /// Number of nodes.
  [[nodiscard]] std::size_t node_count() const { return nodes_.size(); }
  /// Depth of the deepest node.
  [[nodiscard]] unsigned depth() const { return depth_; }
  /// Build parameters.
  [[nodiscard]] const OctreeConfig& config() const { return config_; }
  /// Bytes held: reordered positions, ids and nodes (level maps excluded until built).
  [[nodiscard]] std::size_t memory_bytes() const;
  /// True when both trees have the same cell, node array, slot order and ids (used to show that
  /// insertion and bulk builds agree).
  [[nodiscard]] bool same_structure(const Octree& other) const;

  Octree(Octree&&) noexcept;
  Octree& operator=(Octree&&) noexcept;
  Octree(const Octree&) = delete;
  Octree& operator=(const Octree&) = delete;
  ~Octree();

  /// Node record (public for the builders in octree.cpp; not part of the API contract). No
  /// member initialisers: default-initialised records (nodes_.resize) are left for the builders
  /// to write, and `NodeRec{}` is all zero (then a root needs key 1).
  struct NodeRec {
    glm::vec3 lo, hi;  ///< bounds of the subtree's points relative to root_cell().lo, rounded
                       ///< outwards to float
    std::uint64_t key;  ///< Warren & Salmon id bits (the root: 1)
    std::uint32_t first_child;
    std::uint32_t own_begin, own_end;
    std::uint8_t child_count;
  };
  static_assert(sizeof(NodeRec) % sizeof(float) == 0);

 private:
  Octree() = default;
  friend struct OctreeBuilder;

  struct LevelMaps;
  OctreeConfig config_;
  AABB cell_;                       // root cube
  double side_ = 1.0;               // the quantizer's root edge (quantizer())
  unsigned depth_ = 0;
  // resize() leaves them uninitialised (default_init_vector.hpp): the bulk build's parallel
  // passes are the first to touch them.
  DefaultInitVector<NodeRec> nodes_;
  DefaultInitVector<Vec3> pos_;
  DefaultInitVector<PointIndex> ids_;
  DefaultInitVector<float> child_soa_;          // child blocks (child_boxes_f's soa)
  DefaultInitVector<std::uint32_t> block_of_;  // node -> its child block (interior nodes)
  DefaultInitVector<EntryCell> entry_cells_;  // entry_grid()
  unsigned entry_depth_ = 0;
  std::unique_ptr<LevelMaps> levels_;  // lazily filled per level
  /// Fills child_soa_ and block_of_ from the node records, then the entry grid (the builders'
  /// last step).
  void build_child_blocks();
};

static_assert(SpatialIndex<Octree>);

}  // namespace rayscan
