// Run-time choice of index for the command line and scene files: one of the SpatialIndex types.
#pragma once

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/kdtree.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

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

/// Every index type make_index builds (IndexOptions::type), in the order messages list them: the
/// octrees first, octree_index_type of each of kOctreeLayouts in its order.
inline constexpr std::array<std::string_view, 5> kIndexTypes = {"octree-adaptive", "octree-layered", "octree-fixed",
                                                                "kdtree", "brute"};

/// The index type (IndexOptions::type) of an octree of layout `layout`: "octree-" and the layout's
/// name (to_string), e.g. "octree-fixed"; one of kIndexTypes.
[[nodiscard]] std::string octree_index_type(OctreeLayout layout);

/// The octree layout of index type `type` (OctreeLayout::fixed for "octree-fixed"), the inverse of
/// octree_index_type; nullopt for a type that names no octree ("kdtree", "brute", ""). Throws
/// std::invalid_argument (parse_octree_layout's message) for "octree-" and an unknown layout.
[[nodiscard]] std::optional<OctreeLayout> octree_layout_of(std::string_view type);

/// Index build options shared by the CLI and scene files.
struct IndexOptions {
  std::string type = "octree-adaptive";  ///< octree-adaptive|octree-layered|octree-fixed|kdtree|brute
  /// Octree node capacity / kd-tree leaf size (points); unset: the type's default (index_capacity).
  std::optional<std::uint32_t> capacity{};
  unsigned depth = 6;            ///< octree-fixed leaf depth
  unsigned max_depth = 21;       ///< octree-adaptive/layered maximum depth, 1..21
  bool insertion = false;        ///< octree: build by insertion instead of bulk loading
};

/// A build option of IndexOptions that only some index types use, named by its field (to_string),
/// as an OptionError names it: each front end writes it as its own option (`--max-depth`,
/// `max_depth=`).
enum class IndexOption { capacity, max_depth, depth, insertion };

/// The field of IndexOptions (and OctreeConfig) that sets `o`: "capacity", "max_depth", "depth"
/// or "insertion".
const char* to_string(IndexOption o);

/// Whether building an index of type `type` (IndexOptions::type) uses option `o`: the one rule by
/// which `rayscan query`, `rayscan index` and the Python Octree refuse an option rather than
/// ignore it (make_index builds the same index whatever value an unused option holds).
/// - capacity: octree-adaptive and octree-layered (points per leaf / node), kdtree (leaf size);
///   not octree-fixed, which splits every node down to `depth` whatever it holds, nor brute.
/// - max_depth: octree-adaptive and octree-layered (octree-fixed stops at `depth`).
/// - depth: octree-fixed.
/// - insertion: the three octrees (the kd-tree and brute have one build).
/// False for an unknown type.
[[nodiscard]] bool index_option_applies(std::string_view type, IndexOption o);

/// The options of IndexOptions a caller set itself rather than left at their defaults: the ones
/// check_applicable refuses when the index type does not use them.
struct GivenIndexOptions {
  bool capacity = false;
  bool max_depth = false;
  bool depth = false;
  bool insertion = false;
};

/// How a front end writes its choice of index in check_applicable's message, so that the message
/// names the index as the user chose it.
struct IndexChoiceWords {
  /// The option choosing the index, with what joins it to its value: "--index ", "layout=".
  std::string option = "index type ";
  /// Values are octree layouts ("fixed", octree_layout_of the type: `rayscan index --layout`, the
  /// Python Octree) instead of the type itself ("octree-fixed").
  bool layouts = false;
  /// Written around each value ("'" for Python's layout='fixed').
  std::string quote;
  /// The types the front end offers (IndexOptions::type), in the order the message lists them;
  /// empty: every type, or with `layouts` the three octrees.
  std::vector<std::string> types;
};

/// Refuses an option given for an index type that does not use it (index_option_applies), the
/// first of capacity, max_depth, depth and insertion: throws OptionError "<option> applies to
/// <choice> <the offered types that use it> only (got <choice> <type>)", the option named by its
/// field for the front end to spell, e.g. "--capacity applies to --index octree-adaptive,
/// octree-layered and kdtree only (got --index brute)". A type not among the offered ones (or
/// unknown) is not checked: the front end or make_index refuses it, naming the types it accepts.
void check_applicable(std::string_view type, const GivenIndexOptions& given, const IndexChoiceWords& words = {});

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
