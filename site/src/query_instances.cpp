// The table-kernel instances of the plain ray query (ray_query.hpp: ray_traverse_base,
// first_hit_packet_any), the per-ISA first-hit instances of the ray query (ray_query.hpp:
// ray_traverse_avx2 / _avx512, first_hit_packet_avx2 / _avx512) and those of the kNN query (point_query.hpp: knn_query_avx2 /
// _avx512) for the index file (MappedIndex) and COPC (CopcIndex) indexes, compiled once here; the
// headers declare them extern (build time, bench/notes/).
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"

namespace rayscan::detail {
RAYSCAN_BASE_INSTANCES(template, io::MappedIndex)
RAYSCAN_BASE_INSTANCES(template, io::CopcIndex)
}  // namespace rayscan::detail

#if RAYSCAN_SIMD_X86
namespace rayscan::detail {
RAYSCAN_FIRST_HIT_ISA_INSTANCES(template, io::MappedIndex)
RAYSCAN_FIRST_HIT_ISA_INSTANCES(template, io::CopcIndex)
RAYSCAN_KNN_ISA_INSTANCES(template, io::MappedIndex)
RAYSCAN_KNN_ISA_INSTANCES(template, io::CopcIndex)
}  // namespace rayscan::detail
#endif
