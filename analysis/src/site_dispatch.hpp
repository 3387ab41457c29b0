// The analyses' one dispatch on a site's storage (Site::visit) and what their per-point loops need
// to run on every storage, a COPC file in place included: the cache scope a chunk of work holds
// open, the order the loops visit the points in, and the point count.
#pragma once

#include "rayscan/octree/id_view.hpp"
#include "rayscan/site/site.hpp"

#include <cstddef>
#include <span>
#include <vector>

namespace rayscan::analysis::detail {

/// Returns f(index) for the concrete index of `site` (`const Octree&`, `const KdTree&`,
/// `const BruteForceIndex&`, `const io::MappedIndex&` or `const io::CopcIndex&`): every storage
/// answers the analyses' queries, a COPC file in place in the QueryScopes of chunk_scope.
template <class R, class F>
R over_site(const Site& site, F&& f) {
  return site.visit([&](const auto& index) -> R { return f(index); });
}

/// What a chunk of work (a block of points, a range of image rows) holds open on its index while
/// its queries run: on a COPC file in place a CopcIndex::QueryScope (the nodes its queries reach
/// stay decoded until it ends, when the cache is trimmed to its budget; nothing read through the
/// index may outlive it), an empty object elsewhere, so the other storages' loops are unchanged.
struct NoScope {};
template <class I>
auto chunk_scope(const I& index) {
  if constexpr (is_copc_index<I>)
    return io::CopcIndex::QueryScope(index);  // (not movable: guaranteed elision)
  else
    return NoScope{};
}

/// Points the index answers for: the COPC header's count (its positions() spans slots, more than
/// the points), the positions' count elsewhere.
template <class I>
std::size_t index_points(const I& index) {
  if constexpr (is_copc_index<I>)
    return static_cast<std::size_t>(index.info().point_count);
  else
    return index.positions().size();
}

/// The visiting order of a per-point loop over `index` (see loop_ids): copc_point_order of
/// `positions` on a COPC file in place, empty (the index's own slot order) elsewhere.
template <class I>
std::vector<PointIndex> loop_order(const I&, std::span<const Vec3> positions) {
  if constexpr (is_copc_index<I>)
    return copc_point_order(positions);
  else
    return {};
}

/// The positions of a per-point loop on a COPC file in place: the caller's `positions` (original
/// order) read in the loop's `order`.
struct OrderedPositions {
  std::span<const Vec3> positions;
  std::span<const PointIndex> order;
  const Vec3& operator[](std::size_t s) const { return positions[order[s]]; }
};

/// The positions a per-point loop reads at its running position s, next to loop_ids: the index's
/// own positions in storage order (consecutive slots are spatial neighbours, so consecutive
/// queries share nodes), or on a COPC file in place, whose slots hold only decoded nodes, the
/// caller's `positions` (original order) in the loop's `order` (loop_order).
template <class I>
auto loop_positions(const I& index, std::span<const Vec3> positions, std::span<const PointIndex> order) {
  if constexpr (is_copc_index<I>)
    return OrderedPositions{positions, order};
  else
    return index.positions();
}

/// The original point id at a per-point loop's running position s (see loop_positions): the
/// index's stored ids, or on a COPC file in place the loop's `order` (loop_order).
template <class I>
IdView loop_ids(const I& index, std::span<const PointIndex> order) {
  if constexpr (is_copc_index<I>)
    return IdView(order);
  else
    return index.ids();
}

}  // namespace rayscan::analysis::detail
