// The surfel queries (surfel.hpp: RAYSCAN_SURFEL_INSTANCES, RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES)
// for the index file (MappedIndex) and COPC (CopcIndex) indexes, compiled once here from the
// library's private definitions; the headers declare them extern.
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/detail/surfel_impl.hpp"

namespace rayscan {
RAYSCAN_SURFEL_INSTANCES(template, io::MappedIndex)
RAYSCAN_SURFEL_INSTANCES(template, io::CopcIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(template, io::MappedIndex)
RAYSCAN_SURFEL_FLOAT_BOX_INSTANCES(template, io::CopcIndex)
}  // namespace rayscan
