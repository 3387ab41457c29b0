// The octree's layouts, build parameters and construction rules (paper section 4.1), shared by
// every builder: the in-memory Octree (octree.hpp) and the index file build (rayscan/site).
#pragma once

#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/morton.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan {

/// Data organisation of an octree (paper section 4.1).
enum class OctreeLayout {
  layered,   ///< every node keeps up to `capacity` points (the first inserted, i.e. the smallest
             ///< original indices) and passes the rest down: each level is a subsample (LOD)
  fixed,     ///< all points in the leaves at depth `depth`: a regular grid
  adaptive   ///< a leaf splits when it holds more than `capacity` points, up to `max_depth`
};

/// Every octree layout, in the order lists and messages give them (the default first): the one
/// list of layouts of parse_octree_layout, scene files and the Python Octree (kIndexTypes lists
/// their index types in the same order).
inline constexpr std::array<OctreeLayout, 3> kOctreeLayouts = {OctreeLayout::adaptive, OctreeLayout::layered,
                                                               OctreeLayout::fixed};

/// Parses a layout's name (to_string: "adaptive" | "layered" | "fixed"); throws
/// std::invalid_argument "octree layout 'x': expected adaptive, layered or fixed" otherwise.
OctreeLayout parse_octree_layout(const std::string& s);
/// The name parse_octree_layout accepts.
const char* to_string(OctreeLayout layout);
/// The names of kOctreeLayouts in its order, each written between two `quote`s ("'adaptive'"
/// for Python): the values a front end lists as accepted.
[[nodiscard]] std::vector<std::string> octree_layout_names(std::string_view quote = "");

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
  unsigned max_depth = 21;      ///< deepest level for layered and adaptive (1..21)
  unsigned depth = 6;           ///< leaf depth for fixed (0..21)
  /// Throws std::invalid_argument (naming the field and its range) for capacity 0, max_depth
  /// outside 1..21 (checked for every layout) or depth above 21.
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
    Quantizer(const Vec3& corner, double side)
        : lo(corner), scale(static_cast<double>(std::uint32_t{1} << kMortonBits) / side) {}
    /// The cell in [0, 2^21) of coordinate v on axis a (0 x, 1 y, 2 z): truncated, clamped to the
    /// border cells (NaN: 0).
    [[nodiscard]] std::uint32_t cell(double v, unsigned a) const {
      constexpr std::uint32_t kCells = 1u << kMortonBits;
      const double f = (v - lo[a]) * scale;  // truncation == floor for f >= 0
      if (!(f >= 0.0)) return 0;
      if (f >= kCells - 1) return kCells - 1;
      return static_cast<std::uint32_t>(f);
    }
    /// The 63-bit Morton code of the cells of `p` (cell() per axis, x in the lowest bit).
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

}  // namespace rayscan
