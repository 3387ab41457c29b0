// The entry grids of an octree (the first hit's and the kNN's entry-point search): which node
// holds each cell of the top levels' regular grids, built the one way for every octree storage
// (the in-memory Octree, the mapped index file).
#pragma once

#include "rayscan/octree/morton.hpp"
#include "rayscan/octree/octree_rules.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rayscan {

/// One cell of an entry grid: the deepest node whose cell contains the grid cell, and its depth
/// (the node's Warren & Salmon depth, kept here so that the search reads one cache line, not the
/// node's).
struct EntryCell {
  std::uint32_t node;
  std::uint32_t depth;
};

/// The entry grids of an octree (entry-point search: a ray starts at the node of the cell where it
/// enters instead of at the root; Havran's thesis, section 5.3, and the entry points of Reshetov,
/// Soupikov & Hurley, "Multi-level ray tracing algorithm", SIGGRAPH 2005): for each level l in
/// [0, depth], the 2^l cells per axis of the root cell at depth l, cell (i, j, k) of level l at
/// at(l, i, j, k). Every point inside a grid cell's node's cell is in that node's subtree. Depth 0
/// (cells == nullptr) where the tree has none: a tree of depth <= 1, or nodes above the grid's
/// depth with points of their own (the layered layout: a subtree there does not hold every point
/// of its cell). A view: the cells belong to the index.
struct EntryGrid {
  const EntryCell* cells;  ///< the levels 0..depth one after the other (slot())
  unsigned depth;
  OctreeRules::Quantizer quant;  ///< the quantizer the points were sorted into cells with
  double side;                   ///< its root edge (OctreeRules::root_side), world units
  /// Whether first hits start from the grid (the kNN always does): when at least half the
  /// deepest level's cells have a node of their own (entry_grid_fills_cube), as in a cloud that
  /// fills its cube. In a scan of surfaces most cells are empty and map to shallow nodes, so a
  /// ray's entry node seldom holds its hit and the restart costs more than the levels it skips
  /// (measured: bench/notes/2026-11-29-entry-grid-on-index-files.md).
  bool first_hits;
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

/// The deepest entry grid: 2^15 cells of 8 bytes (with the coarser levels 293 KB, within a core's
/// L2).
inline constexpr unsigned kEntryGridMaxDepth = 5;

/// An index's entry grids as it keeps them (build_entry_grid): the cells (EntryGrid::cells, level
/// after level; empty with depth 0 where the tree has none), their depth, EntryGrid::first_hits
/// and the quantizer and root edge they were built with.
struct EntryCells {
  std::vector<EntryCell> cells;
  unsigned depth = 0;
  bool first_hits = false;
  OctreeRules::Quantizer quant{Vec3(0.0), 1.0};
  double side = 1.0;
  /// The EntryGrid over these cells (what an index's entry_grid() returns; valid while they are).
  [[nodiscard]] EntryGrid view() const {
    return {cells.empty() ? nullptr : cells.data(), depth, quant, side, first_hits};
  }
};

/// The share of the deepest level's cells with a node of their own (EntryCell::depth == depth)
/// above which first hits use the grid (EntryGrid::first_hits): it separates the real scans
/// measured (far below) from clouds that fill their cube (all cells).
inline constexpr double kEntryGridFirstHitsShare = 0.5;

/// Whether at least kEntryGridFirstHitsShare of the deepest level's cells of `g` (cells, depth)
/// have a node of their own.
[[nodiscard]] inline bool entry_grid_fills_cube(const EntryCells& g) {
  if (g.cells.empty()) return false;
  const std::size_t first = EntryGrid::slot(g.depth, 0, 0, 0), n = g.cells.size() - first;
  std::size_t own = 0;
  for (std::size_t c = first; c < g.cells.size(); ++c) own += g.cells[c].depth == g.depth;
  return static_cast<double>(own) >= kEntryGridFirstHitsShare * static_cast<double>(n);
}

/// The entry grids of an octree index (EntryGrid), down to depth min(tree_depth - 1,
/// kEntryGridMaxDepth): one level above the deepest leaves, and no deeper than 8 cells per node
/// (so that a small tree, a tile's or a notebook's, does not carry the whole 293 KB).
/// `index`: root(), child_count(n), child(n, i) and node_points(n) of the tree (a checked
/// accessor's answers are taken as they are: the walk only goes down, to depth at most 5, so it
/// ends on any records); `tree_depth`: its deepest node's depth; `node_count`: its nodes;
/// `octant_of(c)`: child c's Morton digit (0..7) in its parent's cell (paper section 4.1: a
/// child's Warren & Salmon id is its parent's times 8 plus the digit).
/// The top levels are walked from the root, each node's cells written on every level from its own
/// depth down after its parent's, so the deepest node of each grid cell is the one left there.
/// None when a node above the grid's depth holds points of its own (the layered layout): then a
/// grid cell's node would not hold every point of its cell, which the entry-point search relies on.
/// None either when a walked node's bounds (node_bounds, world units) leave the cell its octants
/// name, by more than 2^-20 of the root edge (float bounds are rounded outwards by less): octants
/// that do not match the points (a damaged index file) would send a query to the wrong subtree.
/// `quant`, `side`: the quantizer the points were sorted into cells with and its root edge
/// (OctreeRules::root_side).
template <class I, class OctantOf>
[[nodiscard]] EntryCells build_entry_grid(const I& index, unsigned tree_depth, std::size_t node_count,
                                          OctantOf octant_of, const OctreeRules::Quantizer& quant, double side) {
  EntryCells none;
  none.quant = quant;
  none.side = side;
  if (tree_depth <= 1 || node_count == 0) return none;
  unsigned gd = std::min(tree_depth - 1, kEntryGridMaxDepth);
  while (gd > 1 && (std::size_t{1} << (3 * gd)) > 8 * node_count) --gd;
  EntryCells out = none;
  out.depth = gd;
  out.cells.assign(((std::size_t{1} << (3 * (gd + 1))) - 1) / 7, EntryCell{index.root(), 0});
  struct Item {
    std::uint32_t node;
    unsigned depth;
    std::uint64_t morton;  // the node's Morton code at its depth (3 bits a level)
  };
  std::vector<Item> stack{{index.root(), 0, 0}};
  const double margin = 0x1p-20 * side;
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const unsigned ijk[3] = {static_cast<unsigned>(morton_compact(it.morton)),
                             static_cast<unsigned>(morton_compact(it.morton >> 1)),
                             static_cast<unsigned>(morton_compact(it.morton >> 2))};
    const double edge = side / static_cast<double>(std::uint64_t{1} << it.depth);
    const AABB b = index.node_bounds(it.node);
    for (int a = 0; a < 3; ++a) {
      const double lo = quant.lo[a] + static_cast<double>(ijk[a]) * edge;
      if (!(b.lo[a] >= lo - margin) || !(b.hi[a] <= lo + edge + margin)) return none;
    }
    for (unsigned l = it.depth; l <= gd; ++l) {
      const unsigned sh = l - it.depth, w = 1u << sh;
      const unsigned i0 = ijk[0] << sh, j0 = ijk[1] << sh, k0 = ijk[2] << sh;
      for (unsigned k = k0; k < k0 + w; ++k)
        for (unsigned j = j0; j < j0 + w; ++j)
          for (unsigned i = i0; i < i0 + w; ++i) out.cells[EntryGrid::slot(l, i, j, k)] = {it.node, it.depth};
    }
    if (it.depth < gd && index.child_count(it.node) != 0) {
      if (index.node_points(it.node).size() != 0) return none;
      for (unsigned c = 0; c < index.child_count(it.node); ++c) {
        const std::uint32_t ch = index.child(it.node, c);
        stack.push_back({ch, it.depth + 1, (it.morton << 3) | (octant_of(ch) & 7u)});
      }
    }
  }
  out.first_hits = entry_grid_fills_cube(out);
  return out;
}

}  // namespace rayscan
