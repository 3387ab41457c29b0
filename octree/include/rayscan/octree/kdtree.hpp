// A kd-tree (Bentley 1975) over raw points, written in this library to show that the ray query of
// paper Algorithm 1 runs unchanged on any bounding-volume index.
#pragma once

#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <span>
#include <vector>

namespace rayscan {

/// kd-tree satisfying SpatialIndex. Built top-down: split the node's points at the median of the
/// axis with the largest extent of their tight box (ties broken by original index, so the tree is
/// deterministic), until a node holds at most `leaf_size` points. Points are stored contiguously in
/// depth-first order; the two children of a node are adjacent in the node array; node bounds are
/// the tight boxes of their points.
class KdTree {
 public:
  using Node = std::uint32_t;

  /// Build over `positions` (copied). leaf_size >= 1. Throws std::invalid_argument for leaf_size 0
  /// or a non-finite position, std::length_error above 2^32 - 2 points.
  explicit KdTree(std::span<const Vec3> positions, std::uint32_t leaf_size = 16);

  [[nodiscard]] bool empty() const { return pos_.empty(); }
  [[nodiscard]] Node root() const { return 0; }
  [[nodiscard]] const AABB& node_bounds(Node n) const { return nodes_[n].box; }
  [[nodiscard]] SlotRange node_points(Node n) const {
    return nodes_[n].left ? SlotRange{0, 0} : SlotRange{nodes_[n].begin, nodes_[n].end};
  }
  [[nodiscard]] unsigned child_count(Node n) const { return nodes_[n].left ? 2u : 0u; }
  [[nodiscard]] Node child(Node n, unsigned i) const { return nodes_[n].left + i; }
  [[nodiscard]] std::span<const Vec3> positions() const { return pos_; }
  [[nodiscard]] std::span<const PointIndex> ids() const { return ids_; }
  /// All slots below n (contiguous).
  [[nodiscard]] SlotRange subtree_points(Node n) const { return {nodes_[n].begin, nodes_[n].end}; }
  /// Number of nodes.
  [[nodiscard]] std::size_t node_count() const { return nodes_.size(); }
  /// Bytes held: reordered positions, ids and nodes.
  [[nodiscard]] std::size_t memory_bytes() const {
    return pos_.capacity() * sizeof(Vec3) + ids_.capacity() * sizeof(PointIndex) +
           nodes_.capacity() * sizeof(NodeRec);
  }

 private:
  struct NodeRec {
    AABB box;
    std::uint32_t left = 0;  // index of the left child (right = left + 1); 0 for a leaf
    std::uint32_t begin = 0, end = 0;
  };
  void build(Node n, std::uint32_t b, std::uint32_t e, std::span<const Vec3> src);

  std::uint32_t leaf_size_;
  std::vector<NodeRec> nodes_;
  std::vector<Vec3> pos_;
  std::vector<PointIndex> ids_;
};

static_assert(SpatialIndex<KdTree>);

}  // namespace rayscan
