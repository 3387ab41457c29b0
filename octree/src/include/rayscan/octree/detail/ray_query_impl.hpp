// The definitions of the ray query's entry points (ray_query.hpp declares them, with their
// documentation): the one traversal (ray_traversal.hpp), its per-ISA instances and their run-time
// choice (ray_dispatch.hpp) and the packets (ray_packets.hpp). Private to the library: included by
// the translation units that compile the instances for the library's index types
// (octree/src/query/ray_query.cpp, site/src/query_instances.cpp) and by the tests of the traversal.
// Needs -ffp-contract=off (rayscan_octree_impl's compile option): the traversal's double
// expressions are inlined into AVX2 + FMA instances and must round as in baseline code.
#pragma once

#include "rayscan/octree/detail/ray_packets.hpp"
#include "rayscan/octree/ray_query.hpp"

namespace rayscan {

template <SpatialIndex I, class KeyPolicy>
void ray_query(const I& index, const Ray& ray, const RayQuery& q, std::vector<RayHit>& out,
               RayQueryStats* stats, const KeyPolicy& key_policy) {
  q.validate();
  out.clear();
  if (index.empty() || q.k == 0) return;
  detail::Candidate best;
  if (q.k == 1) {  // first hit: the single-candidate policy (same answer as the k-heap)
    if (detail::ray_traverse<true>(index, ray, q, best, stats, key_policy))
      out.push_back(detail::to_ray_hit(best));
    return;
  }
  detail::ray_traverse<false>(index, ray, q, best, stats, key_policy);
  auto& cands = detail::ray_scratch<typename I::Node>().cands;
  std::sort(cands.begin(), cands.end(), detail::cand_less);
  out.reserve(cands.size());
  for (const detail::Candidate& c : cands) out.push_back(detail::to_ray_hit(c));
}

template <SpatialIndex I>
std::optional<RayHit> ray_first_hit(const I& index, const Ray& ray, const RayQuery& q,
                                                  RayQueryStats* stats) {
  if (index.empty()) return std::nullopt;
  detail::Candidate best;
  if (!detail::ray_traverse<true>(index, ray, q, best, stats)) return std::nullopt;
  return detail::to_ray_hit(best);
}

template <SpatialIndex I>
void ray_first_hit_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                        std::span<std::optional<RayHit>> out, RayQueryStats* stats) {
  detail::require_one_result_per_ray("ray_first_hit_each", out.size(), rays.size());
  if (index.empty()) {
    std::fill(out.begin(), out.end(), std::nullopt);
    return;
  }
  std::size_t i = 0;
  if (!interleaved_pairs()) {
    for (; i < rays.size(); ++i) out[i] = ray_first_hit(index, rays[i], q, stats);
    return;
  }
  for (; i + 2 <= rays.size(); i += 2) {
    detail::Candidate best[2];
    const unsigned found = detail::first_hit_pair(index, rays.data() + i, q, best, stats);
    for (unsigned j = 0; j < 2; ++j)
      out[i + j] = detail::hit_of(found, best, j);
  }
  if (i < rays.size()) out[i] = ray_first_hit(index, rays[i], q, stats);
}

template <SpatialIndex I>
void ray_first_hit_packet(const I& index, std::span<const Ray> rays, const RayQuery& q,
                          std::span<std::optional<RayHit>> out, RayQueryStats* stats) {
  detail::require_one_result_per_ray("ray_first_hit_packet", out.size(), rays.size());
  if (index.empty() || q.any_hit) {
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = ray_first_hit(index, rays[i], q, stats);
    return;
  }
  detail::for_each_ray_packet(index, rays, q, stats,
                              [&](std::size_t b, unsigned n, const detail::Candidate* best, std::uint32_t found) {
                                for (unsigned i = 0; i < n; ++i)
                                  out[b + i] = detail::hit_of(found, best, i);
                              });
}

template <SpatialIndex I>
void ray_any_hit_packet(const I& index, std::span<const Ray> rays, const RayQuery& q, std::span<bool> out,
                        RayQueryStats* stats) {
  detail::require_one_result_per_ray("ray_any_hit_packet", out.size(), rays.size());
  if (index.empty()) {
    std::fill(out.begin(), out.end(), false);
    return;
  }
  detail::for_each_ray_packet(index, rays, q, stats,
                              [&](std::size_t b, unsigned n, const detail::Candidate*, std::uint32_t found) {
                                for (unsigned i = 0; i < n; ++i) out[b + i] = (found >> i) & 1u;
                              });
}

template <SpatialIndex I>
void ray_query_each(const I& index, std::span<const Ray> rays, const RayQuery& q,
                    std::span<std::vector<RayHit>> out, RayQueryStats* stats) {
  q.validate();
  detail::require_one_result_per_ray("ray_query_each", out.size(), rays.size());
  if (q.k != 1) {
    for (std::size_t i = 0; i < rays.size(); ++i) ray_query(index, rays[i], q, out[i], stats);
    return;
  }
  constexpr std::size_t kChunk = 64;  // (a multiple of 2: every pair stays a pair)
  std::optional<RayHit> hit[kChunk];
  for (std::size_t i = 0; i < rays.size(); i += kChunk) {
    const std::size_t n = std::min(kChunk, rays.size() - i);
    ray_first_hit_each(index, rays.subspan(i, n), q, std::span<std::optional<RayHit>>(hit, n), stats);
    for (std::size_t j = 0; j < n; ++j) {
      out[i + j].clear();
      if (hit[j]) out[i + j].push_back(*hit[j]);
    }
  }
}

}  // namespace rayscan
