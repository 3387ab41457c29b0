// Batch queries: many rays (or query points, boxes) answered in parallel with TBB; each result
// equals the single call.
#pragma once

#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan {

/// out[i] = ray_query(index, rays[i], q) for all i, in parallel (tbb::parallel_for over runs of
/// whole kMaxRayPacket-ray blocks counted from rays[0], a grain that keeps every pair of
/// ray_first_hit_each whole, each run answered by ray_query_each). Identical to the single-ray
/// calls for any thread count. Throws std::invalid_argument (before any work) for an invalid q or
/// out.size() != rays.size().
template <SpatialIndex I>
void ray_query_each_parallel(const I& index, std::span<const Ray> rays, const RayQuery& q,
                             std::span<std::vector<RayHit>> out) {
  q.validate();
  if (out.size() != rays.size())
    throw std::invalid_argument("ray_query_each_parallel: " + std::to_string(out.size()) + " results for " +
                                std::to_string(rays.size()) + " rays");
  const std::size_t blocks = (rays.size() + kMaxRayPacket - 1) / kMaxRayPacket;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 4), [&](const tbb::blocked_range<std::size_t>& r) {
    const std::size_t b = r.begin() * kMaxRayPacket, e = std::min(rays.size(), r.end() * kMaxRayPacket);
    ray_query_each(index, rays.subspan(b, e - b), q, out.subspan(b, e - b));
  });
}

/// Answer `rays[i]` with ray_query(index, rays[i], q) into result[i], for all i in parallel
/// (ray_query_each_parallel). Results are identical to the single-ray calls for any thread count.
/// Throws std::invalid_argument (before any work) for an invalid q.
template <SpatialIndex I>
[[nodiscard]] std::vector<std::vector<RayHit>> ray_query_batch(const I& index,
                                                               std::span<const Ray> rays,
                                                               const RayQuery& q) {
  std::vector<std::vector<RayHit>> result(rays.size());
  ray_query_each_parallel(index, rays, q, std::span<std::vector<RayHit>>(result));
  return result;
}

/// kNN / radius query for every point of `queries` in parallel: result[i] = knn_query(index,
/// queries[i], k, radius) (k = kAllPoints: no limit; radius = kInf: none). Identical to the single
/// calls for any thread count. Throws std::invalid_argument (before any work) for a NaN or
/// negative radius or a non-finite query point (naming its position in `queries`).
template <SpatialIndex I>
[[nodiscard]] std::vector<std::vector<Neighbor>> knn_query_batch(const I& index,
                                                                 std::span<const Vec3> queries,
                                                                 std::size_t k, double radius) {
  if (std::isnan(radius) || radius < 0.0)
    throw std::invalid_argument("knn query: radius must be >= 0");
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Vec3& q = queries[i];
    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z))
      throw std::invalid_argument("knn query: query point " + std::to_string(i) + " is not finite");
  }
  std::vector<std::vector<Neighbor>> result(queries.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        knn_query(index, queries[i], k, radius, result[i]);
                    });
  return result;
}

/// Box range query for every box in parallel: result[i] = box_query(index, boxes[i]) (original
/// indices in the index's storage order). Identical to the single calls for any thread count.
template <SpatialIndex I>
[[nodiscard]] std::vector<std::vector<PointIndex>> box_query_batch(const I& index,
                                                                   std::span<const AABB> boxes) {
  std::vector<std::vector<PointIndex>> result(boxes.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, boxes.size(), 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        box_query(index, boxes[i], result[i]);
                    });
  return result;
}

}  // namespace rayscan
