// Point queries over any SpatialIndex: box range, kNN, radius and k + radius (paper section 5.1,
// Table 1 measures the first two). Written once against the concept, like the ray query. The box
// query is a walk of traverse.hpp, defined here; knn_query (and knn, radius_search over it) is
// compiled once per index type of the library (RAYSCAN_KNN_QUERY_INSTANCES below), its traversal
// in the library's private headers (octree/src/include: detail/point_query_impl.hpp).
#pragma once

#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/spatial_index.hpp"
#include "rayscan/octree/traverse.hpp"

#include <algorithm>
#include <cstddef>
#include <vector>

namespace rayscan {

/// One neighbour of a point query.
struct Neighbor {
  PointIndex index;  ///< original point index
  double distance;   ///< Euclidean distance to the query point (not squared; world units)
};

/// Box range query: the original indices of all points p with box.lo <= p <= box.hi (inclusive on
/// every side), in the index's storage order (deterministic, the same on every SIMD path; sort the
/// result if ascending indices are needed: the peers Boost.Geometry rtree and nanoflann also
/// return tree order). Nodes inside the box are taken whole (contiguous slots) without per-point
/// tests. An empty box (lo > hi on an axis) returns nothing. On the AVX2 and AVX-512 paths the
/// points of a node the box cuts (of more than 16 points) are tested by simd::BoxPointsFn
/// (exact: the comparisons of AABB::contains). Throws what the index's checked ids throw (an
/// io::MappedIndex of an unverified file with a bad id); `out` then holds unspecified values.
template <SpatialIndex I>
void box_query(const I& index, const AABB& box, std::vector<PointIndex>& out) {
  out.clear();
  if (index.empty() || box.empty()) return;
  using Node = typename I::Node;
  const auto pos = index.positions();
  const IdView ids = index.ids();
  const simd::Kernels& kern = simd::active_kernels();
  depth_first(
      index,
      [&](Node n) {
        const AABB nb = index.node_bounds(n);
        if (!box.overlaps(nb)) return Enter::no;
        return box.contains(nb.lo) && box.contains(nb.hi) ? Enter::whole : Enter::yes;
      },
      [&](const NodeVisit<Node>& v) {
        const SlotRange sr = v.slots;
        if (sr.size() == 0) return;
        if (v.whole) {
          ids.append_to(out, sr.begin, sr.end);
          return;
        }
        const std::size_t first = out.size();
        // The kernel for nodes of more than kScalarMaxPoints points: on smaller ones (a kd-tree's
        // leaves) the call and the second pass over the kept ids cost more than the vector steps
        // save (bench/notes/2026-11-28-box-points-kernel.md).
        constexpr std::uint32_t kScalarMaxPoints = 16;
        if (kern.box_points != nullptr && sr.size() > kScalarMaxPoints) {
          // The kept points' ids written at the end of `out` by the kernel where the ids are
          // stored unchecked, else their slots (local numbers), then mapped to their ids.
          out.resize(first + sr.size());
          PointIndex* o = out.data() + first;
          const PointIndex* raw = ids.unchecked_data();
          const unsigned n = kern.box_points(position_block(pos, sr.begin, sr.size()), sr.size(), &box.lo.x, &box.hi.x,
                                             raw ? raw + sr.begin : nullptr, o);
          if (!raw) ids.map_slots(o, n, sr.begin);
          out.resize(first + n);
          return;
        }
        // Scalar: the node's ids copied at the end of `out`, then compacted in place, each kept by
        // advancing the write position when its point is inside (no branch: the outcome is
        // unpredictable there). The node's bounds contain its points, so only the box's faces that
        // cut those bounds need a test; most cut nodes are cut by one face, which is then the only
        // comparison per point.
        const AABB nb = index.node_bounds(v.node);
        unsigned faces = 0, face = 0;
        for (unsigned a = 0; a < 3; ++a) {
          if (box.lo[a] > nb.lo[a]) ++faces, face = 2 * a;
          if (box.hi[a] < nb.hi[a]) ++faces, face = 2 * a + 1;
        }
        ids.append_to(out, sr.begin, sr.end);
        std::size_t k = first;
        PointIndex* o = out.data();
        if (faces == 1) {
          const unsigned a = face / 2;
          if (face % 2 == 0) {
            const double lo = box.lo[a];
            for (std::uint32_t s = sr.begin; s < sr.end; ++s) {
              o[k] = o[first + (s - sr.begin)];
              k += static_cast<std::size_t>(pos[s][a] >= lo);
            }
          } else {
            const double hi = box.hi[a];
            for (std::uint32_t s = sr.begin; s < sr.end; ++s) {
              o[k] = o[first + (s - sr.begin)];
              k += static_cast<std::size_t>(pos[s][a] <= hi);
            }
          }
        } else {
          for (std::uint32_t s = sr.begin; s < sr.end; ++s) {
            o[k] = o[first + (s - sr.begin)];
            k += static_cast<std::size_t>(box.contains(pos[s]));
          }
        }
        out.resize(k);
      });
}

/// kNN with optional radius: the at most k points nearest to q with distance <= radius (inclusive),
/// sorted by (squared distance, index). k = kAllPoints means no k limit (a pure radius query);
/// radius = kInf means no radius. Ordering and pruning use squared distances; Neighbor::distance is
/// their square root.
///
/// Traversal: ordered depth-first over node MINDIST (nearest child
/// first, as nanoflann; a node is skipped when its bound exceeds the current k-th distance), with
/// the policies of ray_query: on the active simd_path() an index with detail::FloatChildBoxes
/// bounds all children's MINDIST at once in float (child_dist2 on the boxes transposed in
/// registers; lower bounds, rounded down; on AVX2 / AVX-512 as child order keys ordered by a
/// sorting network, child_dist2_keys), and a node's points pass the SIMD distance filter with
/// a widened bound before the exact double test, so the answers are bit-identical on every path.
/// The own points of a node that also has children (the layered octree's interior points, a
/// subsample spread over the whole cell) are deferred below its children on the stack: they are
/// tested after the nearest subtree has tightened the k-th distance, so the filter rejects nearly
/// all of them. The k best are kept in vectors filled without a branch (k <= 8, on AVX2 /
/// AVX-512 and FloatChildBoxes indexes), a sorted array (k <= 32) or a heap (bench/notes/: kNN
/// without mispredicted branches). On an index with an entry grid (Octree and MappedIndex:
/// entry_grid; unless set_entry_point_search(false)) the search starts at the node of q's grid
/// cell instead of the root and then visits the other grid cells the k-th distance reaches
/// (Havran's entry-point search, as for first hits; bench/notes/2026-11-28-knn-entry-point-search.md);
/// the answer is the same.
/// Throws std::invalid_argument for a NaN/negative radius or a non-finite q.
template <SpatialIndex I>
void knn_query(const I& index, const Vec3& q, std::size_t k, double radius, std::vector<Neighbor>& out);

/// Declares (KW = `extern template`) or defines (KW = `template`) knn_query for index type I, as
/// RAYSCAN_RAY_QUERY_INSTANCES (ray_query.hpp) does for the ray query: the headers of the library's
/// indexes declare it extern and their libraries define it once (octree/src/query/point_query.cpp,
/// site/src/query_instances.cpp), where the traversal's definitions are.
#define RAYSCAN_KNN_QUERY_INSTANCES(KW, I) \
  KW void knn_query<I>(const I&, const Vec3&, std::size_t, double, std::vector<Neighbor>&);

RAYSCAN_KNN_QUERY_INSTANCES(extern template, Octree)
RAYSCAN_KNN_QUERY_INSTANCES(extern template, KdTree)
RAYSCAN_KNN_QUERY_INSTANCES(extern template, BruteForceIndex)

/// kNN: the k nearest points (see knn_query above for order and ties).
template <SpatialIndex I>
[[nodiscard]] std::vector<Neighbor> knn(const I& index, const Vec3& q, std::size_t k) {
  std::vector<Neighbor> out;
  knn_query(index, q, k, kInf, out);
  return out;
}

/// Radius query: every point within distance r of q (inclusive), sorted by (distance, index).
template <SpatialIndex I>
[[nodiscard]] std::vector<Neighbor> radius_search(const I& index, const Vec3& q, double r) {
  std::vector<Neighbor> out;
  knn_query(index, q, kAllPoints, r, out);
  return out;
}

}  // namespace rayscan
