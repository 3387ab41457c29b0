// The AVX-512 (F + VL) kernels of the traversal: 8 points per step and 16-ray packets (the child
// test stays 8-wide, the AVX2 kernel: an octree node has 8 children). Part of simd_kernels.hpp (include that); the
// conventions (target attributes, conservative filters, -ffp-contract=off) are stated there.
#pragma once

#include "rayscan/octree/detail/simd_kernels_avx2.hpp"

#include <type_traits>

namespace rayscan::simd::kernels {

#if RAYSCAN_SIMD_X86
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

// Points [i, i + 8) of AoS positions xyz as x, y and z lanes (deinterleave8's order), or the
// first mk's valid of them (kMasked: masked loads, nothing read past them; the other lanes 0).
template <bool kMasked>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline void load_points8(
    const double* xyz, unsigned i, const TripleMasks8& mk, __m512d& x, __m512d& y, __m512d& z) {
  const double* p = xyz + 3 * static_cast<std::size_t>(i);
  if constexpr (kMasked)
    deinterleave8(_mm512_maskz_loadu_pd(mk.a, p), _mm512_maskz_loadu_pd(mk.b, p + 8), _mm512_maskz_loadu_pd(mk.c, p + 16),
                  x, y, z);
  else
    deinterleave8(_mm512_loadu_pd(p), _mm512_loadu_pd(p + 8), _mm512_loadu_pd(p + 16), x, y, z);
}

// filter_terms4 (simd_kernels_avx2.hpp) in 8 lanes: the same expressions.
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline void filter_terms8(
    __m512d vx, __m512d vy, __m512d vz, __m512d dx, __m512d dy, __m512d dz, __m512d& t, __m512d& d2) {
  t = _mm512_fmadd_pd(vz, dz, _mm512_fmadd_pd(vy, dy, _mm512_mul_pd(vx, dx)));
  const __m512d vv = _mm512_fmadd_pd(vz, vz, _mm512_fmadd_pd(vy, vy, _mm512_mul_pd(vx, vx)));
  d2 = _mm512_fnmadd_pd(t, t, vv);
}

// The lane mask of points [i, i + 8) of the AVX-512 point filter, or of the first `valid` of them
// (kMasked: masked loads, nothing read past them; the other lanes unset).
template <bool kMasked>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned filter_step8(
    const double* xyz, unsigned i, unsigned valid, const PointFilterD& f, bool dist_only) {
  const TripleMasks8 mk(kMasked ? valid : 8u);
  __m512d vx, vy, vz;
  load_points8<kMasked>(xyz, i, mk, vx, vy, vz);
  vx = _mm512_sub_pd(vx, _mm512_set1_pd(f.o[0]));
  vy = _mm512_sub_pd(vy, _mm512_set1_pd(f.o[1]));
  vz = _mm512_sub_pd(vz, _mm512_set1_pd(f.o[2]));
  const __m512d d2max = _mm512_set1_pd(f.d2_max);
  const unsigned lanes = kMasked ? mk.lanes : 0xFFu;
  if (dist_only)  // knn_query: |p - o|^2 alone (see distance_only)
    return lanes & lane_to_point_mask(_mm512_cmp_pd_mask(
                       _mm512_fmadd_pd(vz, vz, _mm512_fmadd_pd(vy, vy, _mm512_mul_pd(vx, vx))), d2max, _CMP_LE_OQ));
  const __m512d dx = _mm512_set1_pd(f.d[0]), dy = _mm512_set1_pd(f.d[1]), dz = _mm512_set1_pd(f.d[2]);
  __m512d t, d2;
  filter_terms8(vx, vy, vz, dx, dy, dz, t, d2);
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

// store_kept8 of any 8 values of the step (as a box kernel's ids): the lanes of `values` in m,
// compressed and stored whole at out[n, n + 8).
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned store_kept8_of(
    unsigned m, __m256i values, std::uint32_t* out, unsigned n) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + n), _mm256_maskz_compress_epi32(static_cast<__mmask8>(m), values));
  return n + static_cast<unsigned>(__builtin_popcount(m));
}
// append_lanes<8> for a full step without its early exit, which mispredicts where steps keep
// points about as often as not: the kept indices (i + each set bit of the point-order mask m,
// ascending) compressed into one register and stored whole at out[n, n + 8). Needs n <= i and
// i + 8 <= the point count (out's room).
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned store_kept8(
    unsigned m, unsigned i, std::uint32_t* out, unsigned n) {
  return store_kept8_of(
      m, _mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(static_cast<int>(i))), out, n);
}

// The points after an 8-wide kernel's full steps (i of count done, n kept so far): the last
// count % 8 points as one overlapping step over the last 8 with the lanes before i cleared
// (append_lanes then writes below count, as in the AVX2 kernels' tail_lanes4), or, for fewer than
// 8 points (then no full step ran: i == 0), one masked step whose indices are written for the
// valid lanes only (out holds count). step(std::bool_constant<kMasked>, first, valid) returns
// the point-order lane mask of points [first, first + valid) (filter_step8, box_step8).
template <class Step>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned finish_steps8(
    const Step& step, unsigned i, unsigned count, std::uint32_t* out, unsigned n) {
  if (i == count) return n;
  if (count >= 8) {
    const unsigned base = count - 8;
    return append_lanes<8>(step(std::false_type{}, base, 8u) & (0xFFu << (i - base)), base, out, n);
  }
  const unsigned m = step(std::true_type{}, 0u, count);
  for (unsigned j = 0; j < count; ++j) {
    out[n] = j;
    n += (m >> j) & 1u;
  }
  return n;
}

inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) unsigned point_filter_avx512(const double* xyz, unsigned count,
                                                                                 const PointFilterD& f,
                                                                                 std::uint32_t* out) {
  const bool dist_only = distance_only(f);
  unsigned i = 0, n = 0;
  if (dist_only) {  // knn_query's leaves: steps keep points about as often as not (store_kept8)
    for (; i + 8 <= count; i += 8) n = store_kept8(filter_step8<false>(xyz, i, 8, f, true), i, out, n);
  } else {  // a ray's thin tube: most steps keep nothing (append_lanes' early exit predicts well)
    for (; i + 8 <= count; i += 8) n = append_lanes<8>(filter_step8<false>(xyz, i, 8, f, false), i, out, n);
  }
  return finish_steps8(
      [&](auto masked, unsigned first, unsigned valid) __attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) {
        return filter_step8<decltype(masked)::value>(xyz, first, valid, f, dist_only);
      },
      i, count, out, n);
}

// The lane mask of points [i, i + 8) inside the closed box [lo, hi] (AABB::contains'
// comparisons), or of the first `valid` of them (kMasked: masked loads; the other lanes unset).
template <bool kMasked>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned box_step8(
    const double* xyz, unsigned i, unsigned valid, const __m512d* lo, const __m512d* hi) {
  const TripleMasks8 mk(kMasked ? valid : 8u);
  __m512d v[3];
  load_points8<kMasked>(xyz, i, mk, v[0], v[1], v[2]);
  __mmask8 m = _mm512_cmp_pd_mask(v[0], lo[0], _CMP_GE_OQ);
  m = _mm512_mask_cmp_pd_mask(m, v[0], hi[0], _CMP_LE_OQ);
  for (unsigned a = 1; a < 3; ++a) {
    m = _mm512_mask_cmp_pd_mask(m, v[a], lo[a], _CMP_GE_OQ);
    m = _mm512_mask_cmp_pd_mask(m, v[a], hi[a], _CMP_LE_OQ);
  }
  return (kMasked ? mk.lanes : 0xFFu) & lane_to_point_mask(m);
}

// BoxPointsFn (simd.hpp) on AVX-512: 8 points per step, the kept indices (or their ids)
// compressed and stored whole (store_kept8), the last count % 8 points as one overlapping step,
// fewer than 8 points as one masked step (their indices then mapped to ids one by one).
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) unsigned box_points_avx512(
    const double* xyz, unsigned count, const double* lo, const double* hi, const std::uint32_t* ids,
    std::uint32_t* out) {
  const __m512d l[3] = {_mm512_set1_pd(lo[0]), _mm512_set1_pd(lo[1]), _mm512_set1_pd(lo[2])};
  const __m512d h[3] = {_mm512_set1_pd(hi[0]), _mm512_set1_pd(hi[1]), _mm512_set1_pd(hi[2])};
  unsigned i = 0, n = 0;
  for (; i + 8 <= count; i += 8) {
    const unsigned m = box_step8<false>(xyz, i, 8, l, h);
    n = ids ? store_kept8_of(m, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ids + i)), out, n)
            : store_kept8(m, i, out, n);
  }
  const unsigned full = n;
  n = finish_steps8(
      [&](auto masked, unsigned first, unsigned valid) __attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) {
        return box_step8<decltype(masked)::value>(xyz, first, valid, l, h);
      },
      i, count, out, n);
  if (ids) map_kept_to_ids(out, full, n, ids);
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
// PacketPointFilterFn (simd.hpp) on AVX-512: each point broadcast against the rays in halves of 8
// lanes (only the halves holding a ray of `rays`), with filter_step8's terms (filter_terms8).
// One half's constants (lanes l .. l + 7) and the rays of `rays` among them.
struct PacketHalf8 {
  __m512d o[3], d[3], d2max, tlo, thi;
  __mmask8 live;
};
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline void load_packet_half8(
    const PointFilterPacketD& f, unsigned l, std::uint32_t rays, PacketHalf8& h) {
  for (int a = 0; a < 3; ++a) {
    h.o[a] = _mm512_load_pd(f.o[a] + l);
    h.d[a] = _mm512_load_pd(f.d[a] + l);
  }
  h.d2max = _mm512_load_pd(f.d2_max + l);
  h.tlo = _mm512_load_pd(f.t_lo + l);
  h.thi = _mm512_load_pd(f.t_hi + l);
  h.live = static_cast<__mmask8>(rays >> l);
}
// The lanes of half h whose ray may keep the point (px, py, pz) (broadcast).
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline std::uint32_t test_packet_half8(
    const PacketHalf8& h, __m512d px, __m512d py, __m512d pz) {
  const __m512d vx = _mm512_sub_pd(px, h.o[0]), vy = _mm512_sub_pd(py, h.o[1]), vz = _mm512_sub_pd(pz, h.o[2]);
  __m512d t, d2;
  filter_terms8(vx, vy, vz, h.d[0], h.d[1], h.d[2], t, d2);
  __mmask8 k = _mm512_mask_cmp_pd_mask(h.live, d2, h.d2max, _CMP_LE_OQ);
  k = _mm512_mask_cmp_pd_mask(k, t, h.tlo, _CMP_GE_OQ);
  return static_cast<std::uint32_t>(_mm512_mask_cmp_pd_mask(k, t, h.thi, _CMP_LE_OQ));
}
template <bool kLo, bool kHi>
__attribute__((target("avx512f,avx512vl,avx2,fma"), always_inline)) inline unsigned packet_point_filter8(
    const double* xyz, unsigned count, const PointFilterPacketD& f, std::uint32_t rays, std::uint32_t* idx,
    std::uint32_t* masks) {
  PacketHalf8 lo, hi;
  if constexpr (kLo) load_packet_half8(f, 0, rays, lo);
  if constexpr (kHi) load_packet_half8(f, 8, rays, hi);
  unsigned n = 0;
  for (unsigned j = 0; j < count; ++j) {
    const double* p = xyz + 3 * static_cast<std::size_t>(j);
    const __m512d px = _mm512_set1_pd(p[0]), py = _mm512_set1_pd(p[1]), pz = _mm512_set1_pd(p[2]);
    std::uint32_t m = 0;
    if constexpr (kLo) m = test_packet_half8(lo, px, py, pz);
    if constexpr (kHi) m |= test_packet_half8(hi, px, py, pz) << 8;
    idx[n] = j;
    masks[n] = m;
    n += m != 0;
  }
  return n;
}
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) unsigned packet_point_filter_avx512(
    const double* xyz, unsigned count, const PointFilterPacketD& f, std::uint32_t rays, std::uint32_t* idx,
    std::uint32_t* masks) {
  const bool lo = (rays & 0xFFu) != 0, hi = (rays & 0xFF00u) != 0;
  if (lo && hi) return packet_point_filter8<true, true>(xyz, count, f, rays, idx, masks);
  if (hi) return packet_point_filter8<false, true>(xyz, count, f, rays, idx, masks);
  return packet_point_filter8<true, false>(xyz, count, f, rays, idx, masks);
}
// The packet loop's lane helpers (as lanes_not_above16_avx2 / masked_min16_avx2) on AVX-512.
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) std::uint32_t lanes_not_above16_avx512(
    const double* lb, const double* bound) {
  const std::uint32_t lo = _mm512_cmp_pd_mask(_mm512_loadu_pd(lb), _mm512_loadu_pd(bound), _CMP_NGT_UQ);
  const std::uint32_t hi = _mm512_cmp_pd_mask(_mm512_loadu_pd(lb + 8), _mm512_loadu_pd(bound + 8), _CMP_NGT_UQ);
  return lo | hi << 8;
}
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) double masked_min16_avx512(
    const double* v, std::uint32_t mask) {
  const __m512d inf = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  const __m512d r = _mm512_min_pd(_mm512_mask_loadu_pd(inf, static_cast<__mmask8>(mask), v),
                                  _mm512_mask_loadu_pd(inf, static_cast<__mmask8>(mask >> 8), v + 8));
  const __m256d r4 = _mm256_min_pd(_mm512_castpd512_pd256(r), _mm512_extractf64x4_pd(r, 1));
  return _mm256_cvtsd_f64(lanes_min4(r4));
}

// PacketRayBoxFn (simd.hpp) on AVX-512: ray_box_avx2's expressions with the rays in the lanes
// (8 per register; the axes one after the other), the origins and directions gathered.
inline __attribute__((target("avx512f,avx512vl,avx2,fma"))) std::uint32_t packet_ray_box_avx512(
    const double* lo, const double* hi, const double* o, const double* d, std::size_t stride, unsigned n, double pad,
    double t_lo, double t_hi) {
  double box_mag = 0.0;  // (the largest of exact magnitudes: the same whatever the order)
  for (int a = 0; a < 3; ++a) box_mag = std::max({box_mag, std::abs(lo[a]), std::abs(hi[a])});
  const __m512i abs_mask = _mm512_set1_epi64(0x7FFFFFFFFFFFFFFFLL);
  const long long s = static_cast<long long>(stride);
  const __m512i idx = _mm512_setr_epi64(0, s, 2 * s, 3 * s, 4 * s, 5 * s, 6 * s, 7 * s);
  const double inf = std::numeric_limits<double>::infinity();
  std::uint32_t out = 0;
  for (unsigned h = 0; h < n && h < 16; h += 8) {
    const __mmask8 live = static_cast<__mmask8>(n - h >= 8 ? 0xFFu : (1u << (n - h)) - 1u);
    __m512d vo[3], vd[3];
    for (int a = 0; a < 3; ++a) {  // (lanes past n: origin 0, direction 1)
      vo[a] = _mm512_mask_i64gather_pd(_mm512_setzero_pd(), live, idx, o + h * stride + a, 8);
      vd[a] = _mm512_mask_i64gather_pd(_mm512_set1_pd(1.0), live, idx, d + h * stride + a, 8);
    }
    __m512d mag = _mm512_set1_pd(box_mag);
    for (int a = 0; a < 3; ++a)
      mag = _mm512_max_pd(mag, _mm512_castsi512_pd(_mm512_and_si512(_mm512_castpd_si512(vo[a]), abs_mask)));
    // node_test_tolerance_bound(mag), lane by lane (a product, then a sum: no fused step).
    const __m512d tol = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(kNodeTestToleranceBoundRel), mag),
                                      _mm512_set1_pd(kNodeTestToleranceBoundAbs));
    const __m512d grow = _mm512_add_pd(_mm512_set1_pd(pad), tol);
    __m512d near = _mm512_set1_pd(-inf), far = _mm512_set1_pd(inf);
    for (int a = 0; a < 3; ++a) {
      const __m512d inv = _mm512_div_pd(_mm512_set1_pd(1.0), vd[a]);
      const __m512d ta = _mm512_mul_pd(_mm512_sub_pd(_mm512_set1_pd(lo[a]), _mm512_add_pd(vo[a], grow)), inv);
      const __m512d tb = _mm512_mul_pd(_mm512_sub_pd(_mm512_set1_pd(hi[a]), _mm512_sub_pd(vo[a], grow)), inv);
      const __mmask8 skip = _mm512_cmp_pd_mask(ta, tb, _CMP_UNORD_Q);  // NaN in either: the axis says nothing
      near = _mm512_max_pd(near, _mm512_mask_blend_pd(skip, _mm512_min_pd(ta, tb), _mm512_set1_pd(-inf)));
      far = _mm512_min_pd(far, _mm512_mask_blend_pd(skip, _mm512_max_pd(ta, tb), _mm512_set1_pd(inf)));
    }
    const __m512d t_near = _mm512_max_pd(near, _mm512_sub_pd(_mm512_set1_pd(t_lo), tol));
    const __m512d t_far = _mm512_min_pd(far, _mm512_add_pd(_mm512_set1_pd(t_hi), tol));
    out |= static_cast<std::uint32_t>(_mm512_mask_cmp_pd_mask(live, t_near, t_far, _CMP_NGT_UQ)) << h;
  }
  return out;
}
#pragma GCC diagnostic pop  // (also _mm512_cvtps_pd / _mm512_min_pd of the per-point radii)
#endif

}  // namespace rayscan::simd::kernels
