// The SIMD kernels of the traversal (simd.hpp) as inline definitions, and the compile-time kernel
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
// double code. Builds must use -ffp-contract=off (rayscan_octree's public compile option): a
// double expression of the traversal inlined into an FMA target must round as in baseline code.
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

#if RAYSCAN_SIMD_X86
// ---- SSE2 (x86-64 baseline) ----------------------------------------------------------------

// Box i's lo.xyz, hi.xyz as 8 floats (the record's next 2 floats are read and ignored); lanes
// past b.count repeat box 0 and are masked off by the caller.
inline const float* box_row(const ChildBoxesF& b, unsigned i) {
  // (i < count) * i: no branch (the conditional mispredicted ~1 M times in the same run)
  return b.base + static_cast<std::size_t>(i * static_cast<unsigned>(i < b.count)) * b.stride;
}

// Boxes h .. h + 3 transposed in registers: rows [lx ly lz hx] and [hy hz . .] -> one register
// per coordinate, lo[a] / hi[a] (no copy through memory).
inline void transpose_boxes4(const ChildBoxesF& b, unsigned h, __m128 lo[3], __m128 hi[3]) {
  const float* p0 = box_row(b, h), *p1 = box_row(b, h + 1), *p2 = box_row(b, h + 2), *p3 = box_row(b, h + 3);
  __m128 lx = _mm_loadu_ps(p0), ly = _mm_loadu_ps(p1), lz = _mm_loadu_ps(p2), hx = _mm_loadu_ps(p3);
  _MM_TRANSPOSE4_PS(lx, ly, lz, hx);
  const __m128 u01 = _mm_unpacklo_ps(_mm_loadu_ps(p0 + 4), _mm_loadu_ps(p1 + 4));  // hy0 hy1 hz0 hz1
  const __m128 u23 = _mm_unpacklo_ps(_mm_loadu_ps(p2 + 4), _mm_loadu_ps(p3 + 4));
  lo[0] = lx, lo[1] = ly, lo[2] = lz;
  hi[0] = hx, hi[1] = _mm_movelh_ps(u01, u23), hi[2] = _mm_movehl_ps(u23, u01);
}

inline unsigned child_slab_sse2(const ChildBoxesF& b, const SlabRayF& r, float* entry) {
  const __m128 eps = _mm_set1_ps(kRelSlack);
  const __m128 sign = _mm_set1_ps(-0.0f);
  unsigned mask = 0;
  for (unsigned h = 0; h < b.count; h += 4) {
    __m128 lo[3], hi[3];
    transpose_boxes4(b, h, lo, hi);
    __m128 tn = _mm_set1_ps(r.t_lo), tf = _mm_set1_ps(r.t_hi < r.enter_max ? r.t_hi : r.enter_max);
    for (int a = 0; a < 3; ++a) {
      const __m128 inv = _mm_set1_ps(r.inv_d[a]);
      const __m128 ta = _mm_mul_ps(_mm_sub_ps(lo[a], _mm_set1_ps(r.o_plus[a])), inv);
      const __m128 tb = _mm_mul_ps(_mm_sub_ps(hi[a], _mm_set1_ps(r.o_minus[a])), inv);
      __m128 t0 = _mm_min_ps(ta, tb), t1 = _mm_max_ps(ta, tb);
      t0 = _mm_sub_ps(t0, _mm_mul_ps(_mm_andnot_ps(sign, t0), eps));
      t1 = _mm_add_ps(t1, _mm_mul_ps(_mm_andnot_ps(sign, t1), eps));
      tn = _mm_max_ps(t0, tn);  // a NaN in t0/t1 keeps the accumulator (conservative)
      tf = _mm_min_ps(t1, tf);
    }
    mask |= static_cast<unsigned>(_mm_movemask_ps(_mm_cmple_ps(tn, tf))) << h;
    _mm_storeu_ps(entry + h, _mm_max_ps(tn, _mm_set1_ps(r.lb_floor)));
  }
  return mask & ((1u << b.count) - 1u);
}

// Child boxes x rays of a packet: box i's six coordinates broadcast, 4 rays per register.
inline void packet_child_slab_sse2(const ChildBoxesF& b, const SlabPacketF& p, unsigned lanes, std::uint32_t* hits,
                            float* entry) {
  const __m128 eps = _mm_set1_ps(kRelSlack);
  const __m128 sign = _mm_set1_ps(-0.0f);
  for (unsigned c = 0; c < b.count; ++c) {
    const float* bx = b.base + static_cast<std::size_t>(c) * b.stride;
    const __m128 lo[3] = {_mm_set1_ps(bx[0]), _mm_set1_ps(bx[1]), _mm_set1_ps(bx[2])};
    const __m128 hi[3] = {_mm_set1_ps(bx[3]), _mm_set1_ps(bx[4]), _mm_set1_ps(bx[5])};
    unsigned mask = 0;
    for (unsigned h = 0; h < lanes; h += 4) {
      __m128 tn = _mm_load_ps(p.t_lo + h), tf = _mm_load_ps(p.t_hi + h);
      for (int a = 0; a < 3; ++a) {
        const __m128 inv = _mm_load_ps(p.inv_d[a] + h);
        const __m128 ta = _mm_mul_ps(_mm_sub_ps(lo[a], _mm_load_ps(p.o_plus[a] + h)), inv);
        const __m128 tb = _mm_mul_ps(_mm_sub_ps(hi[a], _mm_load_ps(p.o_minus[a] + h)), inv);
        __m128 t0 = _mm_min_ps(ta, tb), t1 = _mm_max_ps(ta, tb);
        t0 = _mm_sub_ps(t0, _mm_mul_ps(_mm_andnot_ps(sign, t0), eps));
        t1 = _mm_add_ps(t1, _mm_mul_ps(_mm_andnot_ps(sign, t1), eps));
        tn = _mm_max_ps(t0, tn);  // a NaN in t0/t1 keeps the accumulator (conservative)
        tf = _mm_min_ps(t1, tf);
      }
      mask |= static_cast<unsigned>(_mm_movemask_ps(_mm_cmple_ps(tn, tf))) << h;
      _mm_storeu_ps(entry + 16 * c + h, tn);
    }
    hits[c] = mask;
  }
}

// MINDIST^2 lower bounds, 4 children per register, transposed in registers like child_slab_sse2.
inline void child_dist2_sse2(const ChildBoxesF& b, const float* q, float margin, float* lb2) {
  const __m128 m = _mm_set1_ps(margin), zero = _mm_setzero_ps(), shrink = _mm_set1_ps(1.0f - kRelSlack);
  for (unsigned h = 0; h < b.count; h += 4) {
    __m128 lo[3], hi[3];
    transpose_boxes4(b, h, lo, hi);
    __m128 d2 = zero;
    for (int a = 0; a < 3; ++a) {
      const __m128 qa = _mm_set1_ps(q[a]);
      const __m128 g = _mm_max_ps(_mm_sub_ps(lo[a], qa), _mm_sub_ps(qa, hi[a]));
      const __m128 gm = _mm_max_ps(_mm_sub_ps(g, m), zero);
      d2 = _mm_add_ps(d2, _mm_mul_ps(gm, gm));
    }
    _mm_storeu_ps(lb2 + h, _mm_mul_ps(d2, shrink));
  }
}

// With d = 0 (knn_query: |p - q|^2 only) the point filter needs neither t nor the projection: these
// distance-only loops drop 3 multiplies, 3 subtractions and the two t comparisons per point
// (t = d.(p - o) = 0 exactly, so when 0 lies in [t_lo, t_hi] the t test passes every point).
[[nodiscard]] inline bool distance_only(const PointFilterD& f) {
  return f.d[0] == 0.0 && f.d[1] == 0.0 && f.d[2] == 0.0 && f.t_lo <= 0.0 && 0.0 <= f.t_hi;
}

// Whether point i at p (xyz) passes the point filter f with per-point radii: the lane tests in
// scalar double, for the last count % W points of a kernel, so that every point the filter keeps
// passed its radius test (RayTraversal skips reject() on them). Its rounding differs from the
// lanes' and the exact test's by a few ulps, far below the widening already in f.
[[nodiscard]] inline bool keep_point(const double* p, unsigned i, const PointFilterD& f) {
  const double vx = p[0] - f.o[0], vy = p[1] - f.o[1], vz = p[2] - f.o[2];
  const double t = vx * f.d[0] + vy * f.d[1] + vz * f.d[2];
  const double wx = vx - t * f.d[0], wy = vy - t * f.d[1], wz = vz - t * f.d[2];
  const double d2 = wx * wx + wy * wy + wz * wz;
  double lim = f.d2_max, tl = f.t_lo;
  const double r = f.radii[i];
  if (r * r + f.d2_slack < lim) lim = r * r + f.d2_slack;  // (a NaN radius keeps d2_max)
  if (f.t_lo_own - r > tl) tl = f.t_lo_own - r;            // (and t_lo)
  return d2 <= lim && t >= tl && t <= f.t_hi;
}

// The tail of a point filter kernel: points [i, count) appended to out[n...]; returns the new
// count. With per-point radii (kRadii: f.radii is set) each through keep_point (no branch per
// point); without, all of them, left to the exact test (measured: filtering them in scalar code
// cost the sphere mode 0.9% more instructions than it saved, bench/README.md). The SSE2 kernels
// (at most one point) and counts below 4 end here; the AVX2 kernels overlap (tail_lanes4).
template <bool kRadii>
[[nodiscard]] inline unsigned append_tail(const double* xyz, unsigned i, unsigned count, const PointFilterD& f,
                                          std::uint32_t* out, unsigned n) {
  if constexpr (!kRadii) {
    for (; i < count; ++i) out[n++] = i;
    return n;
  }
  for (; i < count; ++i) {
    out[n] = i;
    n += keep_point(xyz + 3 * static_cast<std::size_t>(i), i, f) ? 1u : 0u;
  }
  return n;
}

// Appends i + the index of each set bit of the W-lane mask m to out[n...] and returns the new
// count. Each lane's index is written at out[n] and n advances only when its bit is set, without a
// branch per bit (a loop over the set bits mispredicted ~1.6 M times in a 150x100, 8 spp surfel
// run, set-up included: bench/README.md). Writes stay below i + W (n <= i + j at lane j), so out needs no
// capacity beyond the point count.
template <unsigned W>
[[nodiscard]] inline unsigned append_lanes(unsigned m, unsigned i, std::uint32_t* out, unsigned n) {
  if (!m) return n;  // most steps of a thin ray tube keep nothing: a well-predicted exit
  for (unsigned j = 0; j < W; ++j) {
    out[n] = i + j;
    n += (m >> j) & 1u;
  }
  return n;
}

// Two AoS points p[0..5] (x0 y0 z0 x1 y1 z1) as x, y and z lanes relative to (ox, oy, oz).
inline void load_rel2(const double* p, __m128d ox, __m128d oy, __m128d oz, __m128d& vx, __m128d& vy, __m128d& vz) {
  const __m128d a = _mm_loadu_pd(p), b = _mm_loadu_pd(p + 2), c = _mm_loadu_pd(p + 4);
  vx = _mm_sub_pd(_mm_shuffle_pd(a, b, 0b10), ox);
  vy = _mm_sub_pd(_mm_shuffle_pd(a, c, 0b01), oy);
  vz = _mm_sub_pd(_mm_shuffle_pd(b, c, 0b10), oz);
}

inline unsigned dist_filter_sse2(const double* xyz, unsigned count, const PointFilterD& f, std::uint32_t* out) {
  const __m128d ox = _mm_set1_pd(f.o[0]), oy = _mm_set1_pd(f.o[1]), oz = _mm_set1_pd(f.o[2]);
  const __m128d d2max = _mm_set1_pd(f.d2_max);
  unsigned i = 0, n = 0;
  for (; i + 2 <= count; i += 2) {
    __m128d vx, vy, vz;
    load_rel2(xyz + 3 * static_cast<std::size_t>(i), ox, oy, oz, vx, vy, vz);
    const __m128d d2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(vx, vx), _mm_mul_pd(vy, vy)), _mm_mul_pd(vz, vz));
    unsigned m = static_cast<unsigned>(_mm_movemask_pd(_mm_cmple_pd(d2, d2max)));
    n = append_lanes<2>(m, i, out, n);
  }
  for (; i < count; ++i) out[n++] = i;  // tail: left to the exact test
  return n;
}

// kRadii: f.radii is set (one instance each, so the loop without radii carries none of their work).
template <bool kRadii>
inline unsigned point_filter_sse2_impl(const double* xyz, unsigned count, const PointFilterD& f, std::uint32_t* out) {
  const __m128d ox = _mm_set1_pd(f.o[0]), oy = _mm_set1_pd(f.o[1]), oz = _mm_set1_pd(f.o[2]);
  const __m128d dx = _mm_set1_pd(f.d[0]), dy = _mm_set1_pd(f.d[1]), dz = _mm_set1_pd(f.d[2]);
  const __m128d d2max = _mm_set1_pd(f.d2_max), tlo = _mm_set1_pd(f.t_lo), thi = _mm_set1_pd(f.t_hi);
  const __m128d slack = _mm_set1_pd(f.d2_slack), tlo_own = _mm_set1_pd(f.t_lo_own);
  unsigned i = 0, n = 0;
  for (; i + 2 <= count; i += 2) {
    __m128d vx, vy, vz;
    load_rel2(xyz + 3 * static_cast<std::size_t>(i), ox, oy, oz, vx, vy, vz);
    const __m128d t = _mm_add_pd(_mm_add_pd(_mm_mul_pd(vx, dx), _mm_mul_pd(vy, dy)), _mm_mul_pd(vz, dz));
    const __m128d wx = _mm_sub_pd(vx, _mm_mul_pd(t, dx));
    const __m128d wy = _mm_sub_pd(vy, _mm_mul_pd(t, dy));
    const __m128d wz = _mm_sub_pd(vz, _mm_mul_pd(t, dz));
    const __m128d d2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(wx, wx), _mm_mul_pd(wy, wy)), _mm_mul_pd(wz, wz));
    __m128d lim = d2max, tl = tlo;
    if constexpr (kRadii) {  // each point's own radius as well (PointFilterD::radii, t_lo_own)
      const __m128d r = _mm_set_pd(f.radii[i + 1], f.radii[i]);
      lim = _mm_min_pd(_mm_add_pd(_mm_mul_pd(r, r), slack), d2max);  // (d2max when r is NaN)
      tl = _mm_max_pd(_mm_sub_pd(tlo_own, r), tlo);                  // (t_lo when r is NaN)
    }
    const __m128d ok = _mm_and_pd(_mm_cmple_pd(d2, lim), _mm_and_pd(_mm_cmpge_pd(t, tl), _mm_cmple_pd(t, thi)));
    unsigned m = static_cast<unsigned>(_mm_movemask_pd(ok));
    n = append_lanes<2>(m, i, out, n);
  }
  return append_tail<kRadii>(xyz, i, count, f, out, n);
}

inline unsigned point_filter_sse2(const double* xyz, unsigned count, const PointFilterD& f, std::uint32_t* out) {
  if (distance_only(f)) return dist_filter_sse2(xyz, count, f, out);
  return f.radii ? point_filter_sse2_impl<true>(xyz, count, f, out) : point_filter_sse2_impl<false>(xyz, count, f, out);
}

// ---- AVX2 + FMA: all 8 children in one register -------------------------------------------------

// The 8 child boxes of a node transposed in registers from their records: lo[a] / hi[a] hold
// coordinate a of boxes 0..7 (8 row loads of lo.xyz, hi.xyz + 2 ignored floats, an 8x8 transpose
// of which 6 rows are kept; rows past b.count repeat box 0). Measured history: 6 masked gathers per node were slower
// than scalar; a lane-by-lane copy to SoA arrays through memory cost ~100 instructions per node.
__attribute__((target("avx2,fma"), always_inline)) inline void transpose_rows8(const ChildBoxesF& b, __m256* lo,
                                                                            __m256* hi) {
  __m256 r0, r1, r2, r3, r4, r5, r6, r7;
  if (b.rows8) {  // rows past count readable: no clamp (ChildBoxesF::rows8)
    const float* p = b.base;
    const std::size_t s = b.stride;
    r0 = _mm256_loadu_ps(p), r1 = _mm256_loadu_ps(p + s), r2 = _mm256_loadu_ps(p + 2 * s);
    r3 = _mm256_loadu_ps(p + 3 * s), r4 = _mm256_loadu_ps(p + 4 * s), r5 = _mm256_loadu_ps(p + 5 * s);
    r6 = _mm256_loadu_ps(p + 6 * s), r7 = _mm256_loadu_ps(p + 7 * s);
  } else {
    r0 = _mm256_loadu_ps(box_row(b, 0)), r1 = _mm256_loadu_ps(box_row(b, 1));
    r2 = _mm256_loadu_ps(box_row(b, 2)), r3 = _mm256_loadu_ps(box_row(b, 3));
    r4 = _mm256_loadu_ps(box_row(b, 4)), r5 = _mm256_loadu_ps(box_row(b, 5));
    r6 = _mm256_loadu_ps(box_row(b, 6)), r7 = _mm256_loadu_ps(box_row(b, 7));
  }
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);
  const __m256 t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
  const __m256 t4 = _mm256_unpacklo_ps(r4, r5), t5 = _mm256_unpackhi_ps(r4, r5);
  const __m256 t6 = _mm256_unpacklo_ps(r6, r7), t7 = _mm256_unpackhi_ps(r6, r7);
  const __m256 s0 = _mm256_shuffle_ps(t0, t2, 0x44), s1 = _mm256_shuffle_ps(t0, t2, 0xEE);
  const __m256 s2 = _mm256_shuffle_ps(t1, t3, 0x44), s3 = _mm256_shuffle_ps(t1, t3, 0xEE);
  const __m256 s4 = _mm256_shuffle_ps(t4, t6, 0x44), s5 = _mm256_shuffle_ps(t4, t6, 0xEE);
  const __m256 s6 = _mm256_shuffle_ps(t5, t7, 0x44), s7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  lo[0] = _mm256_permute2f128_ps(s0, s4, 0x20);
  lo[1] = _mm256_permute2f128_ps(s1, s5, 0x20);
  lo[2] = _mm256_permute2f128_ps(s2, s6, 0x20);
  hi[0] = _mm256_permute2f128_ps(s3, s7, 0x20);
  hi[1] = _mm256_permute2f128_ps(s0, s4, 0x31);
  hi[2] = _mm256_permute2f128_ps(s1, s5, 0x31);
}

// The 8 child boxes in registers as transpose_rows8 gives them: loaded as they are from the child
// block when there is one (ChildBoxesF::soa), else transposed from the records.
__attribute__((target("avx2,fma"), always_inline)) inline void transpose_boxes8(const ChildBoxesF& b, __m256* lo,
                                                                             __m256* hi) {
  if (!b.soa) return transpose_rows8(b, lo, hi);
  lo[0] = _mm256_loadu_ps(b.soa), lo[1] = _mm256_loadu_ps(b.soa + 8), lo[2] = _mm256_loadu_ps(b.soa + 16);
  hi[0] = _mm256_loadu_ps(b.soa + 24), hi[1] = _mm256_loadu_ps(b.soa + 32), hi[2] = _mm256_loadu_ps(b.soa + 40);
}

// The slab test of the 8-wide child kernels: returns the mask of the boxes that pass (lanes past
// b.count clear) and sets `entry` to the entry lower bounds raised to r.lb_floor.
__attribute__((target("avx2,fma"), always_inline)) inline unsigned child_slab8(const ChildBoxesF& b, const SlabRayF& r,
                                                                            __m256& entry) {
  __m256 lo[3], hi[3];
  transpose_boxes8(b, lo, hi);
  const __m256 eps = _mm256_set1_ps(kRelSlack);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  __m256 tn = _mm256_set1_ps(r.t_lo), tf = _mm256_set1_ps(r.t_hi < r.enter_max ? r.t_hi : r.enter_max);
  for (int a = 0; a < 3; ++a) {
    // (box - o) / d as one fused step, box * inv - o * inv: the product o * inv depends on the ray
    // alone (off the data's critical path); its rounding, 2^-24 of |o| |inv|, is a position error
    // of 2^-24 |o|, inside the margin the caller grew o_plus / o_minus by (2^-20 of the
    // magnitudes: ray_query.hpp, update_simd), and the fused step's own rounding is relative.
    const __m256 inv = _mm256_set1_ps(r.inv_d[a]);
    const __m256 ta = _mm256_fmsub_ps(lo[a], inv, _mm256_mul_ps(_mm256_set1_ps(r.o_plus[a]), inv));
    const __m256 tb = _mm256_fmsub_ps(hi[a], inv, _mm256_mul_ps(_mm256_set1_ps(r.o_minus[a]), inv));
    __m256 t0a = _mm256_min_ps(ta, tb), t1a = _mm256_max_ps(ta, tb);
    tn = _mm256_max_ps(t0a, tn);
    tf = _mm256_min_ps(t1a, tf);
  }
  // The relative slack once, on the accumulated bounds (x -> x -+ |x| eps is increasing, so it
  // commutes with the max / min over the axes; t_lo and t_hi, already rounded outwards, get it too).
  tn = _mm256_fnmadd_ps(_mm256_andnot_ps(sign, tn), eps, tn);
  tf = _mm256_fmadd_ps(_mm256_andnot_ps(sign, tf), eps, tf);
  const unsigned mask = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(tn, tf, _CMP_LE_OQ)));
  entry = _mm256_max_ps(tn, _mm256_set1_ps(r.lb_floor));
  return mask & ((1u << b.count) - 1u);
}

inline __attribute__((target("avx2,fma"))) unsigned child_slab_avx2(const ChildBoxesF& b, const SlabRayF& r,
                                                             float* entry) {
  __m256 e;
  const unsigned mask = child_slab8(b, r, e);
  _mm256_storeu_ps(entry, e);
  return mask;
}

// The child order keys of lanes e (simd.hpp, child_key; lanes outside mask ~0u) stored to keys[0..8),
// and the least of them reduced in registers (the traversals' next node does not wait for the
// keys' store to reach a scalar load). Shared by child_slab_keys and child_dist2_keys.
__attribute__((target("avx2,fma"), always_inline)) inline std::uint32_t store_child_keys8(__m256 e, unsigned mask,
                                                                                          std::uint32_t* keys) {
  const __m256i bits = _mm256_castps_si256(e);
  // Order-preserving: negatives complemented, positives with the sign bit set.
  __m256i k = _mm256_xor_si256(bits, _mm256_or_si256(_mm256_srai_epi32(bits, 31),
                                                     _mm256_set1_epi32(static_cast<int>(0x80000000u))));
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  k = _mm256_or_si256(_mm256_and_si256(k, _mm256_set1_epi32(~7)), lane);
  const __m256i bit = _mm256_sllv_epi32(_mm256_set1_epi32(1), lane);
  const __m256i in = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(mask)), bit), bit);
  k = _mm256_or_si256(k, _mm256_andnot_si256(in, _mm256_set1_epi32(-1)));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys), k);
  __m128i h = _mm_min_epu32(_mm256_castsi256_si128(k), _mm256_extracti128_si256(k, 1));
  h = _mm_min_epu32(h, _mm_shuffle_epi32(h, 0x4E));
  h = _mm_min_epu32(h, _mm_shuffle_epi32(h, 0xB1));
  return static_cast<std::uint32_t>(_mm_cvtsi128_si32(h));
}

// ChildSlabKeysFn (simd.hpp): child_slab_avx2 with the entries as child order keys.
inline __attribute__((target("avx2,fma"))) unsigned child_slab_keys_avx2(const ChildBoxesF& b, const SlabRayF& r,
                                                                  std::uint32_t* keys, std::uint32_t& near) {
  __m256 e;
  const unsigned mask = child_slab8(b, r, e);
  near = store_child_keys8(e, mask, keys);
  return mask;
}

// One layer of a sorting network on 8 unsigned keys: lane i is compared with lane perm[i]; the
// lanes of kHi (the larger index of each pair) keep the larger key, the others the smaller.
template <int kHi>
__attribute__((target("avx2,fma"), always_inline)) inline __m256i sort_layer(__m256i k, __m256i perm) {
  const __m256i o = _mm256_permutevar8x32_epi32(k, perm);
  return _mm256_blend_epi32(_mm256_min_epu32(k, o), _mm256_max_epu32(k, o), kHi);
}

// Sorts 8 unsigned keys ascending: a sorting network of 19 comparators in 6 layers (Knuth, TAOCP
// vol. 3, section 5.3.4, the optimal network for n = 8; checked on all 256 0-1 inputs by the test).
__attribute__((target("avx2,fma"), always_inline)) inline __m256i sort8(__m256i k) {
  k = sort_layer<0b11001100>(k, _mm256_setr_epi32(2, 3, 0, 1, 6, 7, 4, 5));  // (0,2) (1,3) (4,6) (5,7)
  k = sort_layer<0b11110000>(k, _mm256_setr_epi32(4, 5, 6, 7, 0, 1, 2, 3));  // (0,4) (1,5) (2,6) (3,7)
  k = sort_layer<0b10101010>(k, _mm256_setr_epi32(1, 0, 3, 2, 5, 4, 7, 6));  // (0,1) (2,3) (4,5) (6,7)
  k = sort_layer<0b00110000>(k, _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7));  // (2,4) (3,5)
  k = sort_layer<0b01010000>(k, _mm256_setr_epi32(0, 4, 2, 6, 1, 5, 3, 7));  // (1,4) (3,6)
  return sort_layer<0b01010100>(k, _mm256_setr_epi32(0, 2, 1, 4, 3, 6, 5, 7));  // (1,2) (3,4) (5,6)
}

inline __attribute__((target("avx2,fma"))) void sort_keys8_avx2(std::uint32_t* keys) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys), sort8(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(keys))));
}

// sort_push_keys8's lanes before the stores (simd.hpp, SortPushKeys8Fn): the keys sorted and
// reversed so that lane j holds the (n - 1 - j)-th least (lanes 0 .. n - 2: the farther children,
// farthest first), their bounds (child_key_bound in lanes: the float's bits back from the
// order-preserving key, a NaN to -inf) and their nodes.
struct PushLanes8 {
  __m256 lb;
  __m256i node;
};
__attribute__((target("avx2,fma"), always_inline)) inline PushLanes8 push_lanes8(const std::uint32_t* keys, unsigned n,
                                                                                  std::uint32_t first_child) {
  __m256i k = sort8(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(keys)));
  const __m256i rev = _mm256_and_si256(
      _mm256_sub_epi32(_mm256_set1_epi32(static_cast<int>(n) - 1), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)),
      _mm256_set1_epi32(7));
  k = _mm256_permutevar8x32_epi32(k, rev);
  const __m256i u = _mm256_and_si256(k, _mm256_set1_epi32(~7));
  const __m256i nonneg = _mm256_srai_epi32(u, 31);  // all ones: the key of a float with the sign bit clear
  const __m256i bits = _mm256_blendv_epi8(_mm256_xor_si256(u, _mm256_set1_epi32(-1)),
                                          _mm256_and_si256(u, _mm256_set1_epi32(0x7FFFFFFF)), nonneg);
  const __m256 f = _mm256_castsi256_ps(bits);
  const __m256 lb = _mm256_blendv_ps(_mm256_set1_ps(-std::numeric_limits<float>::infinity()), f, _mm256_cmp_ps(f, f, _CMP_ORD_Q));
  return {lb, _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(first_child)), _mm256_and_si256(k, _mm256_set1_epi32(7)))};
}

// SortPushKeys8Fn (simd.hpp) on AVX2: the 8 entries built 4 at a time (bounds widened to double,
// nodes to 64 bits, interleaved by unpack and a 128-bit lane swap), four 256-bit stores.
inline __attribute__((target("avx2,fma"))) void sort_push_keys8_avx2(const std::uint32_t* keys, unsigned n,
                                                                     std::uint32_t first_child, void* out) {
  const PushLanes8 p = push_lanes8(keys, n, first_child);
  double* o = static_cast<double*>(out);
  for (int h = 0; h < 2; ++h) {  // entries 4h .. 4h + 3
    const __m256d lb = _mm256_cvtps_pd(h ? _mm256_extractf128_ps(p.lb, 1) : _mm256_castps256_ps128(p.lb));
    const __m256d nd = _mm256_castsi256_pd(
        _mm256_cvtepu32_epi64(h ? _mm256_extracti128_si256(p.node, 1) : _mm256_castsi256_si128(p.node)));
    const __m256d lo = _mm256_unpacklo_pd(lb, nd), hi = _mm256_unpackhi_pd(lb, nd);  // entries 0 2 / 1 3
    _mm256_storeu_pd(o + 8 * h, _mm256_permute2f128_pd(lo, hi, 0x20));
    _mm256_storeu_pd(o + 8 * h + 4, _mm256_permute2f128_pd(lo, hi, 0x31));
  }
}

inline __attribute__((target("avx2,fma"))) void packet_child_slab_avx2(const ChildBoxesF& b, const SlabPacketF& p,
                                                                unsigned lanes, std::uint32_t* hits, float* entry) {
  const __m256 eps = _mm256_set1_ps(kRelSlack);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  for (unsigned c = 0; c < b.count; ++c) {
    const float* bx = b.base + static_cast<std::size_t>(c) * b.stride;
    const __m256 lo[3] = {_mm256_set1_ps(bx[0]), _mm256_set1_ps(bx[1]), _mm256_set1_ps(bx[2])};
    const __m256 hi[3] = {_mm256_set1_ps(bx[3]), _mm256_set1_ps(bx[4]), _mm256_set1_ps(bx[5])};
    unsigned mask = 0;
    for (unsigned h = 0; h < lanes; h += 8) {
      __m256 tn = _mm256_load_ps(p.t_lo + h), tf = _mm256_load_ps(p.t_hi + h);
      for (int a = 0; a < 3; ++a) {
        const __m256 inv = _mm256_load_ps(p.inv_d[a] + h);
        const __m256 ta = _mm256_mul_ps(_mm256_sub_ps(lo[a], _mm256_load_ps(p.o_plus[a] + h)), inv);
        const __m256 tb = _mm256_mul_ps(_mm256_sub_ps(hi[a], _mm256_load_ps(p.o_minus[a] + h)), inv);
        __m256 t0a = _mm256_min_ps(ta, tb), t1a = _mm256_max_ps(ta, tb);
        t0a = _mm256_fnmadd_ps(_mm256_andnot_ps(sign, t0a), eps, t0a);
        t1a = _mm256_fmadd_ps(_mm256_andnot_ps(sign, t1a), eps, t1a);
        tn = _mm256_max_ps(t0a, tn);
        tf = _mm256_min_ps(t1a, tf);
      }
      mask |= static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(tn, tf, _CMP_LE_OQ))) << h;
      _mm256_storeu_ps(entry + 16 * c + h, tn);
    }
    hits[c] = mask;
  }
}

// MINDIST^2 lower bounds of the 8 children on the transposed boxes (no gather, no copy). From the
// records even where child blocks exist (ChildBoxesF::soa): knn_query reads the children's records
// anyway, and the blocks' extra 192 bytes per node made Table 1's layered kNN 5-9% slower
// (bench/notes/).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 child_dist2_8(const ChildBoxesF& b, const float* q,
                                                                            float margin) {
  __m256 lo[3], hi[3];
  transpose_rows8(b, lo, hi);
  const __m256 m = _mm256_set1_ps(margin), zero = _mm256_setzero_ps();
  __m256 d2 = zero;
  for (int a = 0; a < 3; ++a) {
    const __m256 qa = _mm256_set1_ps(q[a]);
    const __m256 g = _mm256_max_ps(_mm256_sub_ps(lo[a], qa), _mm256_sub_ps(qa, hi[a]));
    const __m256 gm = _mm256_max_ps(_mm256_sub_ps(g, m), zero);
    d2 = _mm256_fmadd_ps(gm, gm, d2);
  }
  return _mm256_mul_ps(d2, _mm256_set1_ps(1.0f - kRelSlack));
}

inline __attribute__((target("avx2,fma"))) void child_dist2_avx2(const ChildBoxesF& b, const float* q, float margin,
                                                          float* lb2) {
  _mm256_storeu_ps(lb2, child_dist2_8(b, q, margin));
}

// ChildDist2KeysFn (simd.hpp): child_dist2's bounds as child order keys, the children within
// `bound` in the mask.
inline __attribute__((target("avx2,fma"))) unsigned child_dist2_keys_avx2(const ChildBoxesF& b, const float* q,
                                                                   float margin, float bound, std::uint32_t* keys,
                                                                   std::uint32_t& near) {
  const __m256 d2 = child_dist2_8(b, q, margin);
  const __m256 in = _mm256_cmp_ps(d2, _mm256_set1_ps(bound), _CMP_LE_OQ);
  const unsigned mask = static_cast<unsigned>(_mm256_movemask_ps(in)) & ((1u << b.count) - 1u);
  near = store_child_keys8(d2, mask, keys);
  return mask;
}

// 4 AoS points p[0..11] (12 doubles) as x, y and z lanes relative to (ox, oy, oz):
// P = x0 y0 x2 y2, Q = z0 x1 z2 x3, R = y1 z1 y3 z3, then one shuffle per coordinate.
// Four AoS triples held in a, b, c (x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3) as x, y and z lanes.
__attribute__((target("avx2,fma"), always_inline)) inline void deinterleave4(__m256d a, __m256d b, __m256d c,
                                                                             __m256d& x, __m256d& y, __m256d& z) {
  const __m256d P = _mm256_blend_pd(a, b, 0b1100);
  const __m256d Q = _mm256_permute2f128_pd(a, c, 0x21);
  const __m256d R = _mm256_blend_pd(b, c, 0b1100);
  x = _mm256_shuffle_pd(P, Q, 0b1010);
  y = _mm256_shuffle_pd(P, R, 0b0101);
  z = _mm256_shuffle_pd(Q, R, 0b1010);
}

__attribute__((target("avx2,fma"), always_inline)) inline void load_rel4(const double* p, __m256d ox, __m256d oy,
                                                                         __m256d oz, __m256d& vx, __m256d& vy,
                                                                         __m256d& vz) {
  deinterleave4(_mm256_loadu_pd(p), _mm256_loadu_pd(p + 4), _mm256_loadu_pd(p + 8), vx, vy, vz);
  vx = _mm256_sub_pd(vx, ox);
  vy = _mm256_sub_pd(vy, oy);
  vz = _mm256_sub_pd(vz, oz);
}

// The lanes of points [i, i + 4) whose disc the ray provably misses (PointFilterD::normals; v =
// p - o, r the radii as doubles): the ray-disc test with the margins stated there. Lanes with
// |d.n| < 2^-10 |n| or NaN data are never set.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d disc_miss4(const PointFilterD& f, unsigned i,
                                                                             __m256d vx, __m256d vy, __m256d vz,
                                                                             __m256d r) {
  const float* nf = f.normals + 3 * static_cast<std::size_t>(i);
  __m256d nx, ny, nz;
  deinterleave4(_mm256_cvtps_pd(_mm_loadu_ps(nf)), _mm256_cvtps_pd(_mm_loadu_ps(nf + 4)),
                _mm256_cvtps_pd(_mm_loadu_ps(nf + 8)), nx, ny, nz);
  const __m256d dn = _mm256_fmadd_pd(_mm256_set1_pd(f.d[2]), nz,
                                     _mm256_fmadd_pd(_mm256_set1_pd(f.d[1]), ny, _mm256_mul_pd(_mm256_set1_pd(f.d[0]), nx)));
  const __m256d vn = _mm256_fmadd_pd(vz, nz, _mm256_fmadd_pd(vy, ny, _mm256_mul_pd(vx, nx)));
  const __m256d t = _mm256_div_pd(vn, dn);
  const __m256d wx = _mm256_fmsub_pd(t, _mm256_set1_pd(f.d[0]), vx);
  const __m256d wy = _mm256_fmsub_pd(t, _mm256_set1_pd(f.d[1]), vy);
  const __m256d wz = _mm256_fmsub_pd(t, _mm256_set1_pd(f.d[2]), vz);
  const __m256d w2 = _mm256_fmadd_pd(wz, wz, _mm256_fmadd_pd(wy, wy, _mm256_mul_pd(wx, wx)));
  const __m256d v2 = _mm256_fmadd_pd(vz, vz, _mm256_fmadd_pd(vy, vy, _mm256_mul_pd(vx, vx)));
  const __m256d r2 = _mm256_mul_pd(r, r);
  const __m256d lim = _mm256_fmadd_pd(_mm256_add_pd(r2, v2), _mm256_set1_pd(0x1p-32), r2);
  const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
  const __m256d e = _mm256_fmadd_pd(_mm256_and_pd(t, abs_mask), _mm256_set1_pd(0x1p-36), _mm256_set1_pd(f.disc_slack));
  const __m256d miss = _mm256_or_pd(
      _mm256_cmp_pd(w2, lim, _CMP_GT_OQ),
      _mm256_or_pd(_mm256_cmp_pd(t, _mm256_sub_pd(_mm256_set1_pd(f.disc_t_lo), e), _CMP_LT_OQ),
                   _mm256_cmp_pd(t, _mm256_add_pd(_mm256_set1_pd(f.disc_t_hi), e), _CMP_GT_OQ)));
  // |d.n| >= 2^-10 |n| (squared; scale-free, so a normal of any length gets the margins' bound).
  const __m256d n2 = _mm256_fmadd_pd(nz, nz, _mm256_fmadd_pd(ny, ny, _mm256_mul_pd(nx, nx)));
  const __m256d steep = _mm256_cmp_pd(_mm256_mul_pd(dn, dn), _mm256_mul_pd(n2, _mm256_set1_pd(0x1p-20)), _CMP_GE_OQ);
  return _mm256_and_pd(miss, steep);
}

// The lane mask of points [i, i + 4) of the AVX2 distance filter: |p - o|^2 <= d2max.
__attribute__((target("avx2,fma"), always_inline)) inline unsigned dist_step4(const double* xyz, unsigned i,
                                                                              __m256d ox, __m256d oy, __m256d oz,
                                                                              __m256d d2max) {
  __m256d vx, vy, vz;
  load_rel4(xyz + 3 * static_cast<std::size_t>(i), ox, oy, oz, vx, vy, vz);
  const __m256d d2 = _mm256_fmadd_pd(vz, vz, _mm256_fmadd_pd(vy, vy, _mm256_mul_pd(vx, vx)));
  return static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(d2, d2max, _CMP_LE_OQ)));
}

// The tail of the AVX2 kernels: the last count % 4 points as one more 4-wide step over points
// [count - 4, count) (count >= 4, as every caller of a kernel has), whose lanes below i (appended
// already) tail_lanes4 masks off: lane k of the step at j = count - 4 is point j + k. Writes stay
// below count: lane k writes at n <= i (k < i - j) or at n + (k - (i - j)) <= j + k. Measured
// against the scalar tails: -1.8% (surfel) and -2.6% (sphere) instructions of a render
// (bench/notes/).
[[nodiscard]] inline unsigned tail_lanes4(unsigned i, unsigned count) { return 0xFu << (i - (count - 4)); }

inline __attribute__((target("avx2,fma"))) unsigned dist_filter_avx2(const double* xyz, unsigned count,
                                                              const PointFilterD& f, std::uint32_t* out) {
  const __m256d ox = _mm256_set1_pd(f.o[0]), oy = _mm256_set1_pd(f.o[1]), oz = _mm256_set1_pd(f.o[2]);
  const __m256d d2max = _mm256_set1_pd(f.d2_max);
  unsigned i = 0, n = 0;
  for (; i + 4 <= count; i += 4) n = append_lanes<4>(dist_step4(xyz, i, ox, oy, oz, d2max), i, out, n);
  if (i < count && count >= 4)
    return append_lanes<4>(dist_step4(xyz, count - 4, ox, oy, oz, d2max) & tail_lanes4(i, count), count - 4, out, n);
  for (; i < count; ++i) out[n++] = i;  // (count < 4) left to the exact test
  return n;
}

// The lane mask of points [i, i + 4) of an AVX2 point filter step (kRadii: with f.radii).
template <bool kRadii>
__attribute__((target("avx2,fma"), always_inline)) inline unsigned filter_step4(const double* xyz, unsigned i,
                                                                                const PointFilterD& f) {
  const __m256d ox = _mm256_set1_pd(f.o[0]), oy = _mm256_set1_pd(f.o[1]), oz = _mm256_set1_pd(f.o[2]);
  const __m256d dx = _mm256_set1_pd(f.d[0]), dy = _mm256_set1_pd(f.d[1]), dz = _mm256_set1_pd(f.d[2]);
  __m256d vx, vy, vz;
  load_rel4(xyz + 3 * static_cast<std::size_t>(i), ox, oy, oz, vx, vy, vz);
  const __m256d t = _mm256_fmadd_pd(vz, dz, _mm256_fmadd_pd(vy, dy, _mm256_mul_pd(vx, dx)));
  // d^2 = |v|^2 - t^2 (unit d): |v|^2 computed beside t, so the distance waits on one fused step
  // after t instead of four; it differs from |v - t d|^2 by a few ulps of |v|^2, far inside the
  // filter's slack (PointFilterD: 1e-12 of the largest |v|^2).
  const __m256d vv = _mm256_fmadd_pd(vz, vz, _mm256_fmadd_pd(vy, vy, _mm256_mul_pd(vx, vx)));
  const __m256d d2 = _mm256_fnmadd_pd(t, t, vv);
  const __m256d d2max = _mm256_set1_pd(f.d2_max), tlo = _mm256_set1_pd(f.t_lo);
  __m256d lim = d2max, tl = tlo;
  if constexpr (kRadii) {  // each point's own radius as well (PointFilterD::radii, t_lo_own)
    const __m256d r = _mm256_cvtps_pd(_mm_loadu_ps(f.radii + i));
    lim = _mm256_min_pd(_mm256_fmadd_pd(r, r, _mm256_set1_pd(f.d2_slack)), d2max);  // (d2max when r is NaN)
    tl = _mm256_max_pd(_mm256_sub_pd(_mm256_set1_pd(f.t_lo_own), r), tlo);          // (t_lo when r is NaN)
  }
  const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(d2, lim, _CMP_LE_OQ),
                                   _mm256_and_pd(_mm256_cmp_pd(t, tl, _CMP_GE_OQ),
                                                 _mm256_cmp_pd(t, _mm256_set1_pd(f.t_hi), _CMP_LE_OQ)));
  unsigned m = static_cast<unsigned>(_mm256_movemask_pd(ok));
  if constexpr (kRadii) {  // the ray-disc test too (PointFilterD::normals), for the survivors' steps
    if (m && f.normals)
      m &= ~static_cast<unsigned>(_mm256_movemask_pd(disc_miss4(f, i, vx, vy, vz, _mm256_cvtps_pd(_mm_loadu_ps(f.radii + i)))));
  }
  return m;
}

// kRadii: as point_filter_sse2_impl; the tail as tail_lanes4 says.
template <bool kRadii>
inline __attribute__((target("avx2,fma"))) unsigned point_filter_avx2_impl(const double* xyz, unsigned count,
                                                                    const PointFilterD& f, std::uint32_t* out) {
  unsigned i = 0, n = 0;
  for (; i + 4 <= count; i += 4) n = append_lanes<4>(filter_step4<kRadii>(xyz, i, f), i, out, n);
  if (i < count && count >= 4)
    return append_lanes<4>(filter_step4<kRadii>(xyz, count - 4, f) & tail_lanes4(i, count), count - 4, out, n);
  return append_tail<kRadii>(xyz, i, count, f, out, n);
}

inline __attribute__((target("avx2,fma"))) unsigned point_filter_avx2(const double* xyz, unsigned count,
                                                               const PointFilterD& f, std::uint32_t* out) {
  if (distance_only(f)) return dist_filter_avx2(xyz, count, f, out);
  return f.radii ? point_filter_avx2_impl<true>(xyz, count, f, out) : point_filter_avx2_impl<false>(xyz, count, f, out);
}

// 16 rays per register (packets of more than 8 rays; smaller ones take the AVX2 kernel). GCC 12's
// _mm512_min_ps/_mm512_max_ps pass an undefined pass-through operand that -Wmaybe-uninitialized
// reports (a false positive inside the intrinsics header).
#pragma GCC diagnostic push
#if !defined(__clang__)  // (a GCC warning: clang, which builds the fuzzers, has no such group)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) void packet_child_slab_avx512(const ChildBoxesF& b,
                                                                                   const SlabPacketF& p,
                                                                                   unsigned lanes,
                                                                                   std::uint32_t* hits,
                                                                                   float* entry) {
  if (lanes <= 8) {
    packet_child_slab_avx2(b, p, lanes, hits, entry);
    return;
  }
  const __m512 eps = _mm512_set1_ps(kRelSlack);
  const __m512i abs_mask = _mm512_set1_epi32(0x7fffffff);
  const __m512 tl = _mm512_load_ps(p.t_lo), th = _mm512_load_ps(p.t_hi);
  const __m512 inv[3] = {_mm512_load_ps(p.inv_d[0]), _mm512_load_ps(p.inv_d[1]), _mm512_load_ps(p.inv_d[2])};
  const __m512 op[3] = {_mm512_load_ps(p.o_plus[0]), _mm512_load_ps(p.o_plus[1]), _mm512_load_ps(p.o_plus[2])};
  const __m512 om[3] = {_mm512_load_ps(p.o_minus[0]), _mm512_load_ps(p.o_minus[1]), _mm512_load_ps(p.o_minus[2])};
  for (unsigned c = 0; c < b.count; ++c) {
    const float* bx = b.base + static_cast<std::size_t>(c) * b.stride;
    __m512 tn = tl, tf = th;
    for (int a = 0; a < 3; ++a) {
      const __m512 ta = _mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(bx[a]), op[a]), inv[a]);
      const __m512 tb = _mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(bx[3 + a]), om[a]), inv[a]);
      __m512 t0a = _mm512_min_ps(ta, tb), t1a = _mm512_max_ps(ta, tb);
      t0a = _mm512_fnmadd_ps(_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(t0a), abs_mask)), eps, t0a);
      t1a = _mm512_fmadd_ps(_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(t1a), abs_mask)), eps, t1a);
      tn = _mm512_max_ps(t0a, tn);
      tf = _mm512_min_ps(t1a, tf);
    }
    hits[c] = static_cast<unsigned>(_mm512_cmp_ps_mask(tn, tf, _CMP_LE_OQ));
    _mm512_storeu_ps(entry + 16 * c, tn);
  }
}

// The largest / least of the four lanes of v, in every lane.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d lanes_max4(__m256d v) {
  v = _mm256_max_pd(v, _mm256_permute4x64_pd(v, 0x4E));
  return _mm256_max_pd(v, _mm256_permute_pd(v, 0x5));
}
__attribute__((target("avx2,fma"), always_inline)) inline __m256d lanes_min4(__m256d v) {
  v = _mm256_min_pd(v, _mm256_permute4x64_pd(v, 0x4E));
  return _mm256_min_pd(v, _mm256_permute_pd(v, 0x5));
}

// RayBoxFn (simd.hpp) on AVX2: the three axes in the lanes 0-2 of one register (lane 3 repeats z,
// and its 1 / d is made NaN: an ignored axis). The first-hit traversals' root test (ray_query.hpp,
// root_test, where its effect is measured).
inline __attribute__((target("avx2,fma"))) bool ray_box_avx2(const double* lo, const double* hi, const double* o,
                                                              const double* d, double pad, double t_lo,
                                                              double t_hi) {
  // (Element loads: a masked or wider load of values just stored, such as a box computed by the
  // caller, would not be forwarded from the stores: misses took 32 instead of 14 ns. Lane 3 repeats
  // lane 2 rather than 0.0, whose zero-extending vmovq valgrind 3.19 cannot decode: callgrind.)
  const __m256d vlo = _mm256_setr_pd(lo[0], lo[1], lo[2], lo[2]), vhi = _mm256_setr_pd(hi[0], hi[1], hi[2], hi[2]);
  const __m256d vo = _mm256_setr_pd(o[0], o[1], o[2], o[2]), vd = _mm256_setr_pd(d[0], d[1], d[2], d[2]);
  const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7FFFFFFFFFFFFFFFLL));
  const __m256d m = lanes_max4(_mm256_max_pd(
      _mm256_max_pd(_mm256_and_pd(vlo, abs_mask), _mm256_and_pd(vhi, abs_mask)), _mm256_and_pd(vo, abs_mask)));
  const double tol = node_test_tolerance_bound(_mm256_cvtsd_f64(m));
  const __m256d grow = _mm256_set1_pd(pad + tol);
  const __m256d nan = _mm256_set1_pd(std::numeric_limits<double>::quiet_NaN());
  const __m256d inv = _mm256_blend_pd(_mm256_div_pd(_mm256_set1_pd(1.0), vd), nan, 0x8);
  const __m256d ta = _mm256_mul_pd(_mm256_sub_pd(vlo, _mm256_add_pd(vo, grow)), inv);
  const __m256d tb = _mm256_mul_pd(_mm256_sub_pd(vhi, _mm256_sub_pd(vo, grow)), inv);
  const __m256d skip = _mm256_cmp_pd(ta, tb, _CMP_UNORD_Q);  // NaN in either: the axis says nothing
  const double inf = std::numeric_limits<double>::infinity();
  const __m256d near = lanes_max4(_mm256_blendv_pd(_mm256_min_pd(ta, tb), _mm256_set1_pd(-inf), skip));
  const __m256d far = lanes_min4(_mm256_blendv_pd(_mm256_max_pd(ta, tb), _mm256_set1_pd(inf), skip));
  const double t_near = std::max(_mm256_cvtsd_f64(near), t_lo - tol);
  const double t_far = std::min(_mm256_cvtsd_f64(far), t_hi + tol);
  return !(t_near > t_far);
}

// ---- AVX-512: 8 points per step (the child test stays 8-wide: an octree node has 8 children) ----

// As disc_miss4, for eight points (v = p - o, r the radii, n the normals, as doubles): the lane
// mask of the discs the ray provably misses.
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned disc_miss8(
    const PointFilterD& f, __m512d vx, __m512d vy, __m512d vz, __m512d r, __m512d nx, __m512d ny, __m512d nz) {
  const __m512d dx = _mm512_set1_pd(f.d[0]), dy = _mm512_set1_pd(f.d[1]), dz = _mm512_set1_pd(f.d[2]);
  const __m512d dn = _mm512_fmadd_pd(dz, nz, _mm512_fmadd_pd(dy, ny, _mm512_mul_pd(dx, nx)));
  const __m512d vn = _mm512_fmadd_pd(vz, nz, _mm512_fmadd_pd(vy, ny, _mm512_mul_pd(vx, nx)));
  const __m512d t = _mm512_div_pd(vn, dn);
  const __m512d wx = _mm512_fmsub_pd(t, dx, vx), wy = _mm512_fmsub_pd(t, dy, vy), wz = _mm512_fmsub_pd(t, dz, vz);
  const __m512d w2 = _mm512_fmadd_pd(wz, wz, _mm512_fmadd_pd(wy, wy, _mm512_mul_pd(wx, wx)));
  const __m512d v2 = _mm512_fmadd_pd(vz, vz, _mm512_fmadd_pd(vy, vy, _mm512_mul_pd(vx, vx)));
  const __m512d r2 = _mm512_mul_pd(r, r);
  const __m512d lim = _mm512_fmadd_pd(_mm512_add_pd(r2, v2), _mm512_set1_pd(0x1p-32), r2);
  const __m512d e = _mm512_fmadd_pd(_mm512_abs_pd(t), _mm512_set1_pd(0x1p-36), _mm512_set1_pd(f.disc_slack));
  const unsigned miss = _mm512_cmp_pd_mask(w2, lim, _CMP_GT_OQ) |
                        _mm512_cmp_pd_mask(t, _mm512_sub_pd(_mm512_set1_pd(f.disc_t_lo), e), _CMP_LT_OQ) |
                        _mm512_cmp_pd_mask(t, _mm512_add_pd(_mm512_set1_pd(f.disc_t_hi), e), _CMP_GT_OQ);
  // |d.n| >= 2^-10 |n| (squared; scale-free, so a normal of any length gets the margins' bound).
  const __m512d n2 = _mm512_fmadd_pd(nz, nz, _mm512_fmadd_pd(ny, ny, _mm512_mul_pd(nx, nx)));
  return miss & _mm512_cmp_pd_mask(_mm512_mul_pd(dn, dn), _mm512_mul_pd(n2, _mm512_set1_pd(0x1p-20)), _CMP_GE_OQ);
}

// Eight AoS triples (24 values in a, b, c) as x, y and z lanes, lane L holding point 3L mod 8:
// x_j sits at lane 3j mod 8 of one of a, b, c, y_j one lane later, z_j two, so two blends gather
// each coordinate and a rotation aligns y and z with x (2 shuffles instead of 6 two-source
// permutes: bench/notes/). Per-point inputs in point order (radii) are
// permuted into this order; lane masks go back to point order through lane_to_point_mask.
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline void deinterleave8(
    __m512d a, __m512d b, __m512d c, __m512d& x, __m512d& y, __m512d& z) {
  x = _mm512_mask_blend_pd(0x24, _mm512_mask_blend_pd(0x92, a, b), c);
  y = _mm512_mask_blend_pd(0x49, _mm512_mask_blend_pd(0x24, a, b), c);
  z = _mm512_mask_blend_pd(0x92, _mm512_mask_blend_pd(0x49, a, b), c);
  y = _mm512_castsi512_pd(_mm512_alignr_epi64(_mm512_castpd_si512(y), _mm512_castpd_si512(y), 1));
  z = _mm512_castsi512_pd(_mm512_alignr_epi64(_mm512_castpd_si512(z), _mm512_castpd_si512(z), 2));
}
// The bits of a lane mask of deinterleave8 in point order (bit 3L mod 8 <- bit L).
struct LaneToPoint8 {
  std::uint8_t t[256];
  constexpr LaneToPoint8() : t{} {
    for (unsigned m = 0; m < 256; ++m) {
      unsigned r = 0;
      for (unsigned l = 0; l < 8; ++l) r |= ((m >> l) & 1u) << ((3 * l) & 7u);
      t[m] = static_cast<std::uint8_t>(r);
    }
  }
};
inline constexpr LaneToPoint8 kLaneToPoint8{};
[[nodiscard]] inline unsigned lane_to_point_mask(unsigned m) { return kLaneToPoint8.t[m & 0xFFu]; }

// The load masks of the first `valid` (<= 8) of eight AoS triples: 3 valid values over 3 vectors of 8.
struct TripleMasks8 {
  __mmask8 a, b, c, lanes;
  explicit TripleMasks8(unsigned valid) {
    const unsigned k = 3 * valid;
    const auto first = [](unsigned m) { return static_cast<__mmask8>(m >= 8 ? 0xFFu : (1u << m) - 1u); };
    a = first(k);
    b = first(k > 8 ? k - 8 : 0);
    c = first(k > 16 ? k - 16 : 0);
    lanes = first(valid);
  }
};

// The lane mask of points [i, i + 8) of the AVX-512 point filter, or of the first `valid` of them
// (kMasked: masked loads, nothing read past them; the other lanes unset).
template <bool kMasked>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned filter_step8(
    const double* xyz, unsigned i, unsigned valid, const PointFilterD& f, bool dist_only) {
  const TripleMasks8 mk(kMasked ? valid : 8u);
  const double* p = xyz + 3 * static_cast<std::size_t>(i);
  __m512d vx, vy, vz;
  if constexpr (kMasked)
    deinterleave8(_mm512_maskz_loadu_pd(mk.a, p), _mm512_maskz_loadu_pd(mk.b, p + 8), _mm512_maskz_loadu_pd(mk.c, p + 16),
                  vx, vy, vz);
  else
    deinterleave8(_mm512_loadu_pd(p), _mm512_loadu_pd(p + 8), _mm512_loadu_pd(p + 16), vx, vy, vz);
  vx = _mm512_sub_pd(vx, _mm512_set1_pd(f.o[0]));
  vy = _mm512_sub_pd(vy, _mm512_set1_pd(f.o[1]));
  vz = _mm512_sub_pd(vz, _mm512_set1_pd(f.o[2]));
  const __m512d d2max = _mm512_set1_pd(f.d2_max);
  const unsigned lanes = kMasked ? mk.lanes : 0xFFu;
  if (dist_only)  // knn_query: |p - o|^2 alone (see distance_only)
    return lanes & lane_to_point_mask(_mm512_cmp_pd_mask(
                       _mm512_fmadd_pd(vz, vz, _mm512_fmadd_pd(vy, vy, _mm512_mul_pd(vx, vx))), d2max, _CMP_LE_OQ));
  const __m512d dx = _mm512_set1_pd(f.d[0]), dy = _mm512_set1_pd(f.d[1]), dz = _mm512_set1_pd(f.d[2]);
  const __m512d t = _mm512_fmadd_pd(vz, dz, _mm512_fmadd_pd(vy, dy, _mm512_mul_pd(vx, dx)));
  // d^2 = |v|^2 - t^2, as filter_step4.
  const __m512d vv = _mm512_fmadd_pd(vz, vz, _mm512_fmadd_pd(vy, vy, _mm512_mul_pd(vx, vx)));
  const __m512d d2 = _mm512_fnmadd_pd(t, t, vv);
  const __m512d tlo = _mm512_set1_pd(f.t_lo);
  __m512d lim = d2max, tl = tlo, r = _mm512_setzero_pd();
  if (f.radii) {  // each point's own radius as well (PointFilterD::radii, t_lo_own)
    r = _mm512_permutexvar_pd(_mm512_setr_epi64(0, 3, 6, 1, 4, 7, 2, 5),  // (in lane order)
                              _mm512_cvtps_pd(kMasked ? _mm256_maskz_loadu_ps(mk.lanes, f.radii + i)
                                                      : _mm256_loadu_ps(f.radii + i)));
    lim = _mm512_min_pd(_mm512_fmadd_pd(r, r, _mm512_set1_pd(f.d2_slack)), d2max);  // (d2max when r is NaN)
    tl = _mm512_max_pd(_mm512_sub_pd(_mm512_set1_pd(f.t_lo_own), r), tlo);          // (t_lo when r is NaN)
  }
  unsigned m = _mm512_cmp_pd_mask(d2, lim, _CMP_LE_OQ) & _mm512_cmp_pd_mask(t, tl, _CMP_GE_OQ) &
               _mm512_cmp_pd_mask(t, _mm512_set1_pd(f.t_hi), _CMP_LE_OQ);  // lanes (deinterleave8's order)
  if (m && f.normals && f.radii) {  // the ray-disc test too (PointFilterD::normals)
    const float* nf = f.normals + 3 * static_cast<std::size_t>(i);
    __m512d nx, ny, nz;
    if constexpr (kMasked)
      deinterleave8(_mm512_cvtps_pd(_mm256_maskz_loadu_ps(mk.a, nf)), _mm512_cvtps_pd(_mm256_maskz_loadu_ps(mk.b, nf + 8)),
                    _mm512_cvtps_pd(_mm256_maskz_loadu_ps(mk.c, nf + 16)), nx, ny, nz);
    else
      deinterleave8(_mm512_cvtps_pd(_mm256_loadu_ps(nf)), _mm512_cvtps_pd(_mm256_loadu_ps(nf + 8)),
                    _mm512_cvtps_pd(_mm256_loadu_ps(nf + 16)), nx, ny, nz);
    m &= ~disc_miss8(f, vx, vy, vz, r, nx, ny, nz);
  }
  return lanes & lane_to_point_mask(m);
}

inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) unsigned point_filter_avx512(const double* xyz, unsigned count,
                                                                                 const PointFilterD& f,
                                                                                 std::uint32_t* out) {
  const bool dist_only = distance_only(f);
  unsigned i = 0, n = 0;
  for (; i + 8 <= count; i += 8) n = append_lanes<8>(filter_step8<false>(xyz, i, 8, f, dist_only), i, out, n);
  if (i == count) return n;
  if (count >= 8) {
    // The last count % 8 points: one overlapping step over the last 8, the lanes before i cleared
    // (append_lanes then writes below count, as in the AVX2 kernel's tail_lanes4).
    const unsigned base = count - 8;
    return append_lanes<8>(filter_step8<false>(xyz, base, 8, f, dist_only) & (0xFFu << (i - base)), base, out, n);
  }
  // Fewer than 8 points: one masked step; its indices written for the valid lanes only (out holds count).
  const unsigned m = filter_step8<true>(xyz, 0, count, f, dist_only);
  for (unsigned j = 0; j < count; ++j) {
    out[n] = j;
    n += (m >> j) & 1u;
  }
  return n;
}
// SortPushKeys8Fn (simd.hpp) on AVX-512: as sort_push_keys8_avx2, the 8 entries interleaved by two
// two-source permutes into two 512-bit stores.
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) void sort_push_keys8_avx512(const std::uint32_t* keys,
                                                                                        unsigned n,
                                                                                        std::uint32_t first_child,
                                                                                        void* out) {
  const PushLanes8 p = push_lanes8(keys, n, first_child);
  // (the zero-masked forms: GCC 12's plain ones pass an undefined operand -Wuninitialized reports)
  const __m512d lb = _mm512_maskz_cvtps_pd(0xFF, p.lb);
  const __m512d nd = _mm512_castsi512_pd(_mm512_maskz_cvtepu32_epi64(0xFF, p.node));
  double* o = static_cast<double*>(out);
  _mm512_storeu_pd(o, _mm512_permutex2var_pd(lb, _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11), nd));
  _mm512_storeu_pd(o + 8, _mm512_permutex2var_pd(lb, _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15), nd));
}
#pragma GCC diagnostic pop  // (also _mm512_cvtps_pd / _mm512_min_pd of the per-point radii)
#endif

}  // namespace rayscan::simd::kernels

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
};
#endif

}  // namespace rayscan::simd
