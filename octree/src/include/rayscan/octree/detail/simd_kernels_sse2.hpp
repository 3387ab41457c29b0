// The SSE2 kernels (the x86-64 baseline) of the traversal: child slab and distance tests, point
// filters, key sorts. Part of simd_kernels.hpp (include that); the
// conventions (target attributes, conservative filters, -ffp-contract=off) are stated there.
#pragma once

#include "rayscan/octree/detail/simd_common.hpp"

namespace rayscan::simd::kernels {

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

// The kept local indices out[from, n) of a box kernel's tail steps replaced by their ids
// (BoxPointsFn with ids: the full steps moved the ids themselves).
inline void map_kept_to_ids(std::uint32_t* out, unsigned from, unsigned n, const std::uint32_t* ids) {
  for (unsigned k = from; k < n; ++k) out[k] = ids[out[k]];
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

#endif

}  // namespace rayscan::simd::kernels
