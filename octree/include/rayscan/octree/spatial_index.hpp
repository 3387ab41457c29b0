// The small index concept that the ray query (paper Algorithm 1) and the point queries are written
// against once. Any bounding-volume hierarchy that can go from its root to its leaves fits
// (paper section 3: "It works on top of any bounding volume indexing structure").
#pragma once

#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/id_view.hpp"
#include "rayscan/octree/position_view.hpp"

#include <concepts>
#include <cstdint>
#include <span>

namespace rayscan {

/// The "no point" value of a PointIndex: a ray that hits nothing, an empty pixel of the renderer's
/// point-index AOV (stored as uint32 0xFFFFFFFF, the bits of int32 -1). Indexes hold at most
/// kNoPoint - 1 points, so it never names a real point.
inline constexpr PointIndex kNoPoint = 0xFFFFFFFFu;

/// Half-open range [begin, end) of storage slots: positions in an index's reordered point array.
struct SlotRange {
  std::uint32_t begin = 0;
  std::uint32_t end = 0;
  [[nodiscard]] constexpr std::uint32_t size() const { return end - begin; }
};

/// The bounding-volume index concept. An index stores its points contiguously per node, in
/// traversal order (nanoflann/`bvh` style), and keeps the permutation back to original indices.
///  - `Node` is a small handle (an integer).
///  - `empty()`: true when the index holds no point (then root() must not be traversed).
///  - `root()`: the root node.
///  - `node_bounds(n)`: a closed box containing every point stored in n and in its descendants.
///  - `node_points(n)`: the slots of the points stored at n itself (internal nodes of the layered
///    octree hold points too; other indexes hold points only in leaves).
///  - `child_count(n)`, `child(n, i)`: the children of n, i in [0, child_count(n)).
///  - `positions()`: all positions by slot (a PositionRange: `std::span<const Vec3>` for the
///    in-memory indexes, a decoding PositionView for the index file's compact encodings; read
///    them only through `[slot]`, `size()` and position_block()), `ids()`: the original
///    PointIndex of each slot, convertible to IdView (rayscan/octree/id_view.hpp): a span of stored ids
///    for the in-memory indexes, the identity for an index file built without ids (outputs then
///    in slot order); read them only through IdView's `[slot]` and `size()`.
template <class I>
concept SpatialIndex = requires(const I& idx, typename I::Node n, unsigned i) {
  typename I::Node;
  { idx.empty() } -> std::convertible_to<bool>;
  { idx.root() } -> std::convertible_to<typename I::Node>;
  { idx.node_bounds(n) } -> std::convertible_to<AABB>;
  { idx.node_points(n) } -> std::convertible_to<SlotRange>;
  { idx.child_count(n) } -> std::convertible_to<unsigned>;
  { idx.child(n, i) } -> std::convertible_to<typename I::Node>;
  { idx.positions() } -> PositionRange;
  { idx.ids() } -> std::convertible_to<IdView>;
};

}  // namespace rayscan
