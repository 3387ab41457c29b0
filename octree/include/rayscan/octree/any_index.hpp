// Run-time choice of index for the command line and scene files: one of the SpatialIndex types.
#pragma once

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/kdtree.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace rayscan {

/// Any of the library's indexes; use std::visit (or visit_index) to call a query template on it.
using AnyIndex = std::variant<Octree, KdTree, BruteForceIndex>;

/// Calls `f` with the concrete index: the alternative an AnyIndex holds (std::visit), or `index`
/// itself for any other SpatialIndex (e.g. io::MappedIndex), so one template body serves both.
template <class F>
decltype(auto) visit_index(F&& f, const AnyIndex& index) {
  return std::visit(std::forward<F>(f), index);
}
template <class F, class I>
decltype(auto) visit_index(F&& f, const I& index) {
  return std::forward<F>(f)(index);
}

/// Index build options shared by the CLI and scene files.
struct IndexOptions {
  std::string type = "octree-adaptive";  ///< octree-adaptive|octree-layered|octree-fixed|kdtree|brute
  /// Octree node capacity / kd-tree leaf size (points); unset: the type's default (index_capacity).
  std::optional<std::uint32_t> capacity{};
  unsigned depth = 6;            ///< octree-fixed leaf depth
  unsigned max_depth = 21;       ///< octree-adaptive/layered maximum depth, 1..21
  bool insertion = false;        ///< octree: build by insertion instead of bulk loading
};

/// The kd-tree's leaf size when none is given (points).
inline constexpr std::uint32_t kDefaultKdTreeLeaf = 32;

/// The capacity make_index builds `opts` with: opts.capacity when set, else the default of its
/// type (octrees: default_capacity(layout); kd-tree: kDefaultKdTreeLeaf; brute and any other type:
/// 0, unused: make_index rejects an unknown type). Throws std::invalid_argument for an unknown
/// octree layout.
std::uint32_t index_capacity(const IndexOptions& opts);

/// Build the index named by opts.type over `positions`. Throws std::invalid_argument for an unknown
/// type (naming the allowed ones) or invalid parameters.
AnyIndex make_index(std::span<const Vec3> positions, const IndexOptions& opts);

/// Bytes the index holds (positions copy, ids, nodes).
std::size_t index_memory_bytes(const AnyIndex& index);

}  // namespace rayscan
