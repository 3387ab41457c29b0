// The SIMD kernels of the traversal (simd.hpp) as inline definitions (one header per instruction
// set in detail/: simd_kernels_sse2.hpp, _avx2.hpp, _avx512.hpp), and the compile-time kernel
// policies of the traversal compiled per instruction set (ray_traverse and
// first_hit_packet run an instance of the one traversal with target("avx2,fma") or
// target("avx512f,...") and these kernels inlined, instead of calling them through the run-time
// table simd::Kernels). simd.cpp builds that table from the same definitions, so each kernel is
// written once.
//
// The wider kernels carry GCC's function-level target attributes (not per-file -m flags, which
// could leak AVX code into inline functions shared with baseline code): they are only ever called
// from code of the same target (the table entries, chosen with __builtin_cpu_supports, or the
// per-ISA traversal instances), so one binary runs on any x86-64 and uses what the CPU has.
// Every kernel is a conservative filter; the traversal confirms survivors with the exact scalar
// double code. Builds must use -ffp-contract=off (rayscan_octree_impl's compile option): a
// double expression of the traversal inlined into an FMA target must round as in baseline code.
#pragma once

#include "rayscan/octree/detail/simd_kernels_avx512.hpp"

namespace rayscan::simd {

#if RAYSCAN_SIMD_X86
/// Compile-time kernel policy of the AVX2 (+FMA) path: the members of simd::Kernels as constants,
/// so that a traversal instance compiled with target("avx2,fma") calls (and inlines) them directly.
struct Avx2Kernels {
  static constexpr SimdPath path = SimdPath::avx2;
  static constexpr ChildSlabFn child_slab = kernels::child_slab_avx2;
  static constexpr PointFilterFn point_filter = kernels::point_filter_avx2;
  static constexpr ChildDist2Fn child_dist2 = kernels::child_dist2_avx2;
  static constexpr ChildDist2KeysFn child_dist2_keys = kernels::child_dist2_keys_avx2;
  static constexpr PacketChildSlabFn packet_child_slab = kernels::packet_child_slab_avx2;
  static constexpr ChildSlabKeysFn child_slab_keys = kernels::child_slab_keys_avx2;
  static constexpr SortKeys8Fn sort_keys8 = kernels::sort_keys8_avx2;
  static constexpr SortPushKeys8Fn sort_push_keys8 = kernels::sort_push_keys8_avx2;
  static constexpr RayBoxFn ray_box = kernels::ray_box_avx2;
  static constexpr PacketPointFilterFn packet_point_filter = kernels::packet_point_filter_avx2;
  static constexpr PacketRayBoxFn packet_ray_box = nullptr;
  static constexpr BoxPointsFn box_points = kernels::box_points_avx2;
  // The packet loop's lane helpers (first_hit_packet's 16-ray instance only; no run-time entry).
  static constexpr std::uint32_t (*lanes_not_above16)(const double*, const double*) = kernels::lanes_not_above16_avx2;
  static constexpr double (*masked_min16)(const double*, std::uint32_t) = kernels::masked_min16_avx2;
};

/// Compile-time kernel policy of the AVX-512 (F + VL) path: the child tests stay 8-wide (an octree
/// node has 8 children: the AVX2 kernels), points 8 per step, packets 16 rays per register.
struct Avx512Kernels {
  static constexpr SimdPath path = SimdPath::avx512;
  static constexpr ChildSlabFn child_slab = kernels::child_slab_avx2;
  static constexpr PointFilterFn point_filter = kernels::point_filter_avx512;
  static constexpr ChildDist2Fn child_dist2 = kernels::child_dist2_avx2;
  static constexpr ChildDist2KeysFn child_dist2_keys = kernels::child_dist2_keys_avx2;
  static constexpr PacketChildSlabFn packet_child_slab = kernels::packet_child_slab_avx512;
  static constexpr ChildSlabKeysFn child_slab_keys = kernels::child_slab_keys_avx2;
  static constexpr SortKeys8Fn sort_keys8 = kernels::sort_keys8_avx2;
  static constexpr SortPushKeys8Fn sort_push_keys8 = kernels::sort_push_keys8_avx512;
  static constexpr RayBoxFn ray_box = kernels::ray_box_avx2;
  static constexpr PacketPointFilterFn packet_point_filter = kernels::packet_point_filter_avx512;
  static constexpr PacketRayBoxFn packet_ray_box = kernels::packet_ray_box_avx512;
  static constexpr BoxPointsFn box_points = kernels::box_points_avx512;
  static constexpr std::uint32_t (*lanes_not_above16)(const double*, const double*) = kernels::lanes_not_above16_avx512;
  static constexpr double (*masked_min16)(const double*, std::uint32_t) = kernels::masked_min16_avx512;
};
#endif

}  // namespace rayscan::simd
