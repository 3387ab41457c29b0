// A one-node "index": every query over it is an exhaustive scan. It is the test oracle that the
// traversal is checked against, and shows that the ray query needs nothing but the SpatialIndex
// concept.
#pragma once

#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <numeric>
#include <stdexcept>
#include <vector>

namespace rayscan {

/// Brute-force index: a single root node holding all points in their original order.
class BruteForceIndex {
 public:
  using Node = std::uint32_t;

  /// Copies the positions of `cloud`. Throws std::length_error above 2^32 - 1 points.
  explicit BruteForceIndex(const PointCloud& cloud) : BruteForceIndex(cloud.positions) {}
  /// Copies `positions`. Throws std::length_error above 2^32 - 1 points.
  explicit BruteForceIndex(std::span<const Vec3> positions)
      : pos_(positions.begin(), positions.end()), ids_(positions.size()) {
    if (positions.size() > 0xFFFFFFFFull) throw std::length_error("BruteForceIndex: too many points");
    std::iota(ids_.begin(), ids_.end(), PointIndex{0});
    for (const Vec3& p : pos_) bounds_.expand(p);
  }

  [[nodiscard]] bool empty() const { return pos_.empty(); }
  [[nodiscard]] Node root() const { return 0; }
  [[nodiscard]] AABB node_bounds(Node) const { return bounds_; }
  [[nodiscard]] SlotRange node_points(Node) const {
    return {0, static_cast<std::uint32_t>(pos_.size())};
  }
  [[nodiscard]] unsigned child_count(Node) const { return 0; }
  [[nodiscard]] Node child(Node, unsigned) const { return 0; }
  [[nodiscard]] std::span<const Vec3> positions() const { return pos_; }
  [[nodiscard]] std::span<const PointIndex> ids() const { return ids_; }
  /// Bytes held by the index including the coordinate copy.
  [[nodiscard]] std::size_t memory_bytes() const {
    return pos_.capacity() * sizeof(Vec3) + ids_.capacity() * sizeof(PointIndex);
  }

 private:
  std::vector<Vec3> pos_;
  std::vector<PointIndex> ids_;
  AABB bounds_;
};

static_assert(SpatialIndex<BruteForceIndex>);

}  // namespace rayscan
