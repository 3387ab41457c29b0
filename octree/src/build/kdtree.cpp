#include "rayscan/octree/kdtree.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace rayscan {

KdTree::KdTree(std::span<const Vec3> positions, std::uint32_t leaf_size) : leaf_size_(leaf_size) {
  if (leaf_size == 0) throw std::invalid_argument("kdtree: leaf_size must be >= 1");
  if (positions.size() >= 0xFFFFFFFFull) throw std::length_error("kdtree: more than 2^32 - 2 points");
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Vec3& p = positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw std::invalid_argument("kdtree: point " + std::to_string(i) +
                                  " has a non-finite coordinate");
  }
  const auto n = static_cast<std::uint32_t>(positions.size());
  ids_.resize(n);
  std::iota(ids_.begin(), ids_.end(), PointIndex{0});
  nodes_.reserve(n ? 2 * (n / leaf_size + 1) : 1);
  nodes_.emplace_back();
  build(0, 0, n, positions);
  pos_.resize(n);
  for (std::uint32_t s = 0; s < n; ++s) pos_[s] = positions[ids_[s]];
  nodes_.shrink_to_fit();
}

void KdTree::build(Node n, std::uint32_t b, std::uint32_t e, std::span<const Vec3> src) {
  AABB box;
  for (std::uint32_t s = b; s < e; ++s) box.expand(src[ids_[s]]);
  nodes_[n].box = box;
  nodes_[n].begin = b;
  nodes_[n].end = e;
  if (e - b <= leaf_size_ || box.max_extent() == 0.0) return;
  const Vec3 ext = box.extent();
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
  const std::uint32_t mid = b + (e - b) / 2;
  std::nth_element(ids_.begin() + b, ids_.begin() + mid, ids_.begin() + e,
                   [&](PointIndex i, PointIndex j) {
                     const double a = src[i][axis], c = src[j][axis];
                     return a < c || (a == c && i < j);
                   });
  const auto left = static_cast<Node>(nodes_.size());
  nodes_.emplace_back();
  nodes_.emplace_back();
  nodes_[n].left = left;
  build(left, b, mid, src);
  build(left + 1, mid, e, src);
}

}  // namespace rayscan
