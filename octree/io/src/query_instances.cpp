// The per-ISA first-hit instances of the ray query (ray_query.hpp: ray_traverse_avx2 / _avx512,
// first_hit_packet_avx2 / _avx512) for the index file (MappedIndex) and COPC (CopcIndex) indexes,
// compiled once here; the headers declare them extern (issue 12: build time, bench/README.md).
#include "rayscan/io/copc.hpp"
#include "rayscan/io/index_file.hpp"
#include "rayscan/ray_query.hpp"

#if RAYSCAN_SIMD_X86
namespace rayscan::detail {
template bool ray_traverse_avx2<true, io::MappedIndex, OrderKey>(
    const io::MappedIndex&, const Ray&, const RayQuery&, Candidate&, RayQueryStats*, const OrderKey&);
template bool ray_traverse_avx512<true, io::MappedIndex, OrderKey>(
    const io::MappedIndex&, const Ray&, const RayQuery&, Candidate&, RayQueryStats*, const OrderKey&);
template unsigned first_hit_packet_avx2<io::MappedIndex, OrderKey>(
    const io::MappedIndex&, const Ray*, unsigned, const RayQuery&, Candidate*, RayQueryStats*, const OrderKey*);
template unsigned first_hit_packet_avx512<io::MappedIndex, OrderKey>(
    const io::MappedIndex&, const Ray*, unsigned, const RayQuery&, Candidate*, RayQueryStats*, const OrderKey*);
template bool ray_traverse_avx2<true, io::CopcIndex, OrderKey>(
    const io::CopcIndex&, const Ray&, const RayQuery&, Candidate&, RayQueryStats*, const OrderKey&);
template bool ray_traverse_avx512<true, io::CopcIndex, OrderKey>(
    const io::CopcIndex&, const Ray&, const RayQuery&, Candidate&, RayQueryStats*, const OrderKey&);
template unsigned first_hit_packet_avx2<io::CopcIndex, OrderKey>(
    const io::CopcIndex&, const Ray*, unsigned, const RayQuery&, Candidate*, RayQueryStats*, const OrderKey*);
template unsigned first_hit_packet_avx512<io::CopcIndex, OrderKey>(
    const io::CopcIndex&, const Ray*, unsigned, const RayQuery&, Candidate*, RayQueryStats*, const OrderKey*);
}  // namespace rayscan::detail
#endif
