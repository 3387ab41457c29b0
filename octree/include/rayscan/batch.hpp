// Batch ray queries: many rays answered in parallel with TBB; each result equals the single-ray call.
#pragma once

#include "rayscan/ray_query.hpp"

#include <tbb/parallel_for.h>

#include <span>
#include <vector>

namespace rayscan {

/// Answer `rays[i]` with ray_query(index, rays[i], q) into result[i], for all i in parallel
/// (tbb::parallel_for over blocks of rays). Results are identical to the single-ray calls for any
/// thread count. Throws std::invalid_argument (before any work) for an invalid q.
template <SpatialIndex I>
[[nodiscard]] std::vector<std::vector<RayHit>> ray_query_batch(const I& index,
                                                               std::span<const Ray> rays,
                                                               const RayQuery& q) {
  q.validate();
  std::vector<std::vector<RayHit>> result(rays.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        ray_query(index, rays[i], q, result[i]);
                    });
  return result;
}

}  // namespace rayscan
