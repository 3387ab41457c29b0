// The run-time dispatch of the SIMD kernels (see simd.hpp): the table of each path, built from the
// kernels' definitions in simd_kernels.hpp, and the active path.
#include "rayscan/octree/simd.hpp"

#include "rayscan/octree/detail/simd_kernels.hpp"

#include <cstdio>
#include <cstdlib>

#if RAYSCAN_SIMD_X86
#include <cpuid.h>
#endif

namespace rayscan {

const char* to_string(SimdPath p) {
  switch (p) {
    case SimdPath::scalar: return "scalar";
    case SimdPath::sse2: return "sse2";
    case SimdPath::avx2: return "avx2";
    case SimdPath::avx512: return "avx512";
  }
  return "scalar";
}

std::optional<SimdPath> parse_simd_path(const std::string& s) {
  for (SimdPath p : {SimdPath::scalar, SimdPath::sse2, SimdPath::avx2, SimdPath::avx512})
    if (s == to_string(p)) return p;
  return std::nullopt;
}

bool simd_path_supported(SimdPath p) {
#if RAYSCAN_SIMD_X86
  __builtin_cpu_init();
  switch (p) {
    case SimdPath::scalar: return true;
    case SimdPath::sse2: return __builtin_cpu_supports("sse2");
    case SimdPath::avx2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case SimdPath::avx512:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  }
  return false;
#else
  return p == SimdPath::scalar;
#endif
}

SimdPath best_simd_path() {
  for (SimdPath p : {SimdPath::avx512, SimdPath::avx2, SimdPath::sse2})
    if (simd_path_supported(p)) return p;
  return SimdPath::scalar;
}

namespace simd {
namespace {

// The table of a compile-time kernel policy (simd_kernels.hpp): one mapping of path to kernels.
template <class K>
constexpr Kernels table_of() {
  return Kernels{K::path,        K::child_slab,      K::point_filter,    K::child_dist2, K::child_dist2_keys,
                 K::packet_child_slab, K::child_slab_keys, K::sort_keys8, K::sort_push_keys8, K::ray_box,
                 K::packet_point_filter, K::packet_ray_box, K::box_points};
}

#if RAYSCAN_SIMD_X86
// The AVX-512 table, with the AVX2 box kernel on AMD's AVX-512 CPUs, Zen 4 (family 19h; Zen 3, the
// same family, has no AVX-512) and Zen 5 (1Ah): Zen 4 runs each 512-bit operation as two 256-bit
// halves, and there the 8-wide kernel's deinterleaving blends and rotations cost more than the
// 4-wide kernel's lane table; on Zen 5 the 4-wide kernel measured faster too (the three octrees'
// box queries together 4-7% in three one-process runs). On the Intel Xeon the AVX-512 kernel is
// the faster (bench/notes/2026-11-28-box-kernel-on-zen-4.md,
// bench/notes/2026-11-29-box-kernel-on-zen-5.md). The ray and kNN kernels stay 8-wide there: the
// ray traversal's AVX-512 instance is the faster.
Kernels avx512_table() {
  Kernels k = table_of<Avx512Kernels>();
  const unsigned family = amd_cpu_family();
  if (family == 0x19u || family == 0x1Au) k.box_points = Avx2Kernels::box_points;
  return k;
}
#endif

const Kernels& kernels_for(SimdPath p) {
  // child_dist2 (knn_query's child lower bounds): the gathering version measured 1.35x slower
  // than the scalar test on Table 1 kNN and was disabled; the in-register transpose (as in
  // child_slab) brought it back (bench/notes/).
  static const Kernels k_scalar{SimdPath::scalar, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr,
                                nullptr,          nullptr, nullptr, nullptr, nullptr, nullptr};
#if RAYSCAN_SIMD_X86
  static const Kernels k_sse2{SimdPath::sse2, kernels::child_slab_sse2, kernels::point_filter_sse2,
                              kernels::child_dist2_sse2, nullptr, kernels::packet_child_slab_sse2, nullptr,
                              nullptr, nullptr, nullptr, nullptr, nullptr, nullptr};
  static const Kernels k_avx2 = table_of<Avx2Kernels>();
  static const Kernels k_avx512 = avx512_table();
  switch (p) {
    case SimdPath::scalar: return k_scalar;
    case SimdPath::sse2: return k_sse2;
    case SimdPath::avx2: return k_avx2;
    case SimdPath::avx512: return k_avx512;
  }
#else
  (void)p;
#endif
  return k_scalar;
}

SimdPath initial_path() {
  if (const char* env = std::getenv("RAYSCAN_SIMD"); env && *env) {
    const std::optional<SimdPath> p = parse_simd_path(env);
    if (p && simd_path_supported(*p)) return *p;
    std::fprintf(stderr, "rayscan: RAYSCAN_SIMD=%s is %s; using %s\n", env,
                 p ? "not supported by this CPU" : "not one of scalar|sse2|avx2|avx512",
                 to_string(best_simd_path()));
  }
  return best_simd_path();
}

const Kernels*& active() {
  static const Kernels* k = &kernels_for(initial_path());
  return k;
}

}  // namespace

const Kernels& active_kernels() { return *active(); }

unsigned amd_cpu_family() {
#if RAYSCAN_SIMD_X86
  // (__builtin_cpu_init first: this may run before the constructors that initialise the CPU model)
  __builtin_cpu_init();
  if (!__builtin_cpu_is("amd")) return 0;
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return 0;
  const unsigned base = (eax >> 8) & 0xFu;
  return base == 0xFu ? base + ((eax >> 20) & 0xFFu) : base;
#else
  return 0;
#endif
}

ChildDist2Fn child_dist2_kernel(SimdPath p) {
#if RAYSCAN_SIMD_X86
  if (p == SimdPath::sse2) return kernels::child_dist2_sse2;
  if (p == SimdPath::avx2) return Avx2Kernels::child_dist2;
  if (p == SimdPath::avx512) return Avx512Kernels::child_dist2;
#endif
  (void)p;
  return nullptr;
}

}  // namespace simd

SimdPath simd_path() { return simd::active_kernels().path; }

bool set_simd_path(SimdPath p) {
  if (!simd_path_supported(p)) return false;
  simd::active() = &simd::kernels_for(p);
  return true;
}

std::string simd_description() {
  const SimdPath p = simd_path();
  std::string s = std::string("SIMD path ") + to_string(p);
  // The ray and kNN traversals on octrees run an instance compiled for the path (ray_query.hpp).
  if (p == SimdPath::avx2 || p == SimdPath::avx512) s += std::string(", traversal compiled for ") + to_string(p);
  s += " (CPU supports:";
  for (SimdPath p : {SimdPath::sse2, SimdPath::avx2, SimdPath::avx512})
    if (simd_path_supported(p)) s += std::string(" ") + to_string(p);
  return s + "; force with RAYSCAN_SIMD=scalar|sse2|avx2|avx512)";
}

}  // namespace rayscan
