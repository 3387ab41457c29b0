// Octree over raw points after Warren & Salmon (1993), as customised in paper section 4.1: node ids
// of depth + Morton code, lazily built per-level index maps, and three data organisations.
#pragma once

#include "rayscan/base/default_init_vector.hpp"
#include "rayscan/octree/entry_grid.hpp"
#include "rayscan/octree/morton.hpp"
#include "rayscan/octree/octree_rules.hpp"
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

  /// The entry grid's types (entry_grid.hpp), as members of the index that has them.
  using EntryCell = rayscan::EntryCell;
  using EntryGrid = rayscan::EntryGrid;
  static constexpr unsigned kEntryGridMaxDepth = rayscan::kEntryGridMaxDepth;
  /// The entry grids (EntryGrid), built with the tree by build_entry_grid: down to depth
  /// min(depth() - 1, kEntryGridMaxDepth), no deeper than 8 cells per node.
  [[nodiscard]] EntryGrid entry_grid() const {
    return entry_.view();
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
  EntryCells entry_;  // entry_grid()
  std::unique_ptr<LevelMaps> levels_;  // lazily filled per level
  /// Fills child_soa_ and block_of_ from the node records, then the entry grid (the builders'
  /// last step).
  void build_child_blocks();
};

static_assert(SpatialIndex<Octree>);

}  // namespace rayscan
