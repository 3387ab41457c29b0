// The ray and kNN queries (ray_query.hpp, point_query.hpp: RAYSCAN_RAY_QUERY_INSTANCES,
// RAYSCAN_KNN_QUERY_INSTANCES) for the index file (MappedIndex) and COPC (CopcIndex) indexes,
// compiled once here from the library's private definitions; the headers declare them extern.
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/detail/point_query_impl.hpp"
#include "rayscan/octree/detail/ray_query_impl.hpp"

namespace rayscan {
RAYSCAN_RAY_QUERY_INSTANCES(template, io::MappedIndex)
RAYSCAN_RAY_QUERY_INSTANCES(template, io::CopcIndex)
RAYSCAN_KNN_QUERY_INSTANCES(template, io::MappedIndex)
RAYSCAN_KNN_QUERY_INSTANCES(template, io::CopcIndex)
}  // namespace rayscan
