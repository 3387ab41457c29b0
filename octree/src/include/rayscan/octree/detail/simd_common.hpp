// What every SIMD kernel header shares: RAYSCAN_SIMD_X86 (x86 intrinsics available) and the
// float slack of the slab tests. Included by the per-ISA kernel headers of this folder, which
// simd_kernels.hpp gathers.
#pragma once

#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/simd.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define RAYSCAN_SIMD_X86 1
#else
#define RAYSCAN_SIMD_X86 0
#endif

namespace rayscan::simd::kernels {


inline constexpr float kRelSlack = 0x1p-20f;  // > 3 float roundings (sub, 1/d, mul) of a slab parameter

}  // namespace rayscan::simd::kernels
