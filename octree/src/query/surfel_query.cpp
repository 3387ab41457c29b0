// The surfel queries for the core's indexes (declared extern in surfel.hpp), compiled once here
// from the private definitions (detail/surfel_impl.hpp); the float child boxes for the octree.
#include "rayscan/octree/surfel.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/detail/surfel_impl.hpp"

namespace rayscan {
RAYSCAN_SURFEL_INSTANCES(template, Octree)
RAYSCAN_SURFEL_INSTANCES(template, KdTree)
RAYSCAN_SURFEL_INSTANCES(template, BruteForceIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(template, Octree)
}  // namespace rayscan
