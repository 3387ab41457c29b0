// knn_query for the core's indexes (declared extern in point_query.hpp), compiled once here from
// the private definitions (detail/point_query_impl.hpp).
#include "rayscan/octree/point_query.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/detail/point_query_impl.hpp"

namespace rayscan {
RAYSCAN_KNN_QUERY_INSTANCES(template, Octree)
RAYSCAN_KNN_QUERY_INSTANCES(template, KdTree)
RAYSCAN_KNN_QUERY_INSTANCES(template, BruteForceIndex)
}  // namespace rayscan
