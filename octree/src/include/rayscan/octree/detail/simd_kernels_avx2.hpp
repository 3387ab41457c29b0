// The AVX2 + FMA kernels of the traversal: all 8 children of a node in one register, 4 points per
// step. Part of simd_kernels.hpp (include that); the
// conventions (target attributes, conservative filters, -ffp-contract=off) are stated there.
#pragma once

#include "rayscan/octree/detail/simd_kernels_sse2.hpp"

namespace rayscan::simd::kernels {

#if RAYSCAN_SIMD_X86
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

// The point filter's terms of v = p - o against the unit direction d, 4 lanes: t = v.d and
// d^2 = |v|^2 - t^2, |v|^2 computed beside t, so the distance waits on one fused step after t
// instead of four; it differs from |v - t d|^2 by a few ulps of |v|^2, far inside the filter's
// slack (PointFilterD: 1e-12 of the largest |v|^2). Every filter (one ray, or a packet's rays in
// the lanes) uses these expressions, so they keep the same points.
__attribute__((target("avx2,fma"), always_inline)) inline void filter_terms4(__m256d vx, __m256d vy, __m256d vz,
                                                                             __m256d dx, __m256d dy, __m256d dz,
                                                                             __m256d& t, __m256d& d2) {
  t = _mm256_fmadd_pd(vz, dz, _mm256_fmadd_pd(vy, dy, _mm256_mul_pd(vx, dx)));
  const __m256d vv = _mm256_fmadd_pd(vz, vz, _mm256_fmadd_pd(vy, vy, _mm256_mul_pd(vx, vx)));
  d2 = _mm256_fnmadd_pd(t, t, vv);
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

// For each 4-lane mask: its set lanes in ascending order (then zeros), and how many there are.
struct Compact4 {
  alignas(16) std::uint32_t lanes[16][4];
  std::uint32_t count[16];
  constexpr Compact4() : lanes{}, count{} {
    for (unsigned m = 0; m < 16; ++m)
      for (unsigned l = 0; l < 4; ++l)
        if ((m >> l) & 1u) lanes[m][count[m]++] = l;
  }
};
inline constexpr Compact4 kCompact4{};

// store_kept4 of any 4 values of the step (as a box kernel's ids): the lanes of `values` in m,
// permuted by the same table (vpermilps) and stored whole at out[n, n + 4).
__attribute__((target("avx2,fma"), always_inline)) inline unsigned store_kept4_of(unsigned m, __m128i values,
                                                                                  std::uint32_t* out, unsigned n) {
  const __m128i lanes = _mm_load_si128(reinterpret_cast<const __m128i*>(kCompact4.lanes[m]));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out + n),
                   _mm_castps_si128(_mm_permutevar_ps(_mm_castsi128_ps(values), lanes)));
  return n + kCompact4.count[m];
}
// append_lanes<4> for a full step without its early exit, which mispredicts where steps keep
// points about as often as not (as store_kept8 on AVX-512, which compresses; AVX2 has no
// compress): the kept indices as one 4-lane store from kCompact4 at out[n, n + 4). Needs n <= i
// and i + 4 <= the point count (out's room).
__attribute__((target("avx2,fma"), always_inline)) inline unsigned store_kept4(unsigned m, unsigned i,
                                                                               std::uint32_t* out, unsigned n) {
  const __m128i lanes = _mm_load_si128(reinterpret_cast<const __m128i*>(kCompact4.lanes[m]));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out + n), _mm_add_epi32(lanes, _mm_set1_epi32(static_cast<int>(i))));
  return n + kCompact4.count[m];
}

// The distance-only filter (knn_query's leaves, whose steps keep points about as often as not:
// store_kept4).
inline __attribute__((target("avx2,fma"))) unsigned dist_filter_avx2(const double* xyz, unsigned count,
                                                              const PointFilterD& f, std::uint32_t* out) {
  const __m256d ox = _mm256_set1_pd(f.o[0]), oy = _mm256_set1_pd(f.o[1]), oz = _mm256_set1_pd(f.o[2]);
  const __m256d d2max = _mm256_set1_pd(f.d2_max);
  unsigned i = 0, n = 0;
  for (; i + 4 <= count; i += 4) n = store_kept4(dist_step4(xyz, i, ox, oy, oz, d2max), i, out, n);
  if (i < count && count >= 4)
    return append_lanes<4>(dist_step4(xyz, count - 4, ox, oy, oz, d2max) & tail_lanes4(i, count), count - 4, out, n);
  for (; i < count; ++i) out[n++] = i;  // (count < 4) left to the exact test
  return n;
}

// The lane mask of points [i, i + 4) inside the closed box [lo, hi] (lo[a], hi[a]: coordinate a
// in every lane), with AABB::contains' comparisons (a NaN coordinate fails).
__attribute__((target("avx2,fma"), always_inline)) inline unsigned box_step4(const double* xyz, unsigned i,
                                                                             const __m256d* lo, const __m256d* hi) {
  const double* p = xyz + 3 * static_cast<std::size_t>(i);
  __m256d v[3];
  deinterleave4(_mm256_loadu_pd(p), _mm256_loadu_pd(p + 4), _mm256_loadu_pd(p + 8), v[0], v[1], v[2]);
  __m256d m = _mm256_and_pd(_mm256_cmp_pd(v[0], lo[0], _CMP_GE_OQ), _mm256_cmp_pd(v[0], hi[0], _CMP_LE_OQ));
  for (unsigned a = 1; a < 3; ++a)
    m = _mm256_and_pd(m, _mm256_and_pd(_mm256_cmp_pd(v[a], lo[a], _CMP_GE_OQ), _mm256_cmp_pd(v[a], hi[a], _CMP_LE_OQ)));
  return static_cast<unsigned>(_mm256_movemask_pd(m));
}

// BoxPointsFn (simd.hpp) on AVX2: 4 points per step, the kept indices (or their ids, permuted
// by the same lane table) stored whole (store_kept4: a cut node's steps keep points about as often
// as not), the last count % 4 points as one overlapping step; fewer than 4 points compared one by
// one.
inline __attribute__((target("avx2,fma"))) unsigned box_points_avx2(const double* xyz, unsigned count,
                                                                    const double* lo, const double* hi,
                                                                    const std::uint32_t* ids, std::uint32_t* out) {
  const __m256d l[3] = {_mm256_set1_pd(lo[0]), _mm256_set1_pd(lo[1]), _mm256_set1_pd(lo[2])};
  const __m256d h[3] = {_mm256_set1_pd(hi[0]), _mm256_set1_pd(hi[1]), _mm256_set1_pd(hi[2])};
  unsigned i = 0, n = 0;
  for (; i + 4 <= count; i += 4) {
    const unsigned m = box_step4(xyz, i, l, h);
    n = ids ? store_kept4_of(m, _mm_loadu_si128(reinterpret_cast<const __m128i*>(ids + i)), out, n)
            : store_kept4(m, i, out, n);
  }
  const unsigned full = n;
  if (i < count && count >= 4) {
    n = append_lanes<4>(box_step4(xyz, count - 4, l, h) & tail_lanes4(i, count), count - 4, out, n);
  } else if (i < count) {
    const AABB box{Vec3(lo[0], lo[1], lo[2]), Vec3(hi[0], hi[1], hi[2])};  // (count < 4)
    for (; i < count; ++i) {
      const double* p = xyz + 3 * static_cast<std::size_t>(i);
      out[n] = i;
      n += static_cast<unsigned>(box.contains(Vec3(p[0], p[1], p[2])));
    }
  }
  if (ids) map_kept_to_ids(out, full, n, ids);
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
  __m256d t, d2;
  filter_terms4(vx, vy, vz, dx, dy, dz, t, d2);
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

// The largest / least of the four lanes of v, in every lane.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d lanes_max4(__m256d v) {
  v = _mm256_max_pd(v, _mm256_permute4x64_pd(v, 0x4E));
  return _mm256_max_pd(v, _mm256_permute_pd(v, 0x5));
}
__attribute__((target("avx2,fma"), always_inline)) inline __m256d lanes_min4(__m256d v) {
  v = _mm256_min_pd(v, _mm256_permute4x64_pd(v, 0x4E));
  return _mm256_min_pd(v, _mm256_permute_pd(v, 0x5));
}

// The packet loop's lane helpers on AVX2 (first_hit_packet with 16 rays): the lanes i < 16
// where !(lb[i] > bound[i]), as bits; and the least v[i] over the lanes of `mask` (+inf for none;
// any order of the minima: it only orders pushes).
inline __attribute__((target("avx2,fma"))) std::uint32_t lanes_not_above16_avx2(const double* lb,
                                                                                              const double* bound) {
  std::uint32_t m = 0;
  for (unsigned l = 0; l < 16; l += 4)
    m |= static_cast<std::uint32_t>(
             _mm256_movemask_pd(_mm256_cmp_pd(_mm256_loadu_pd(lb + l), _mm256_loadu_pd(bound + l), _CMP_NGT_UQ)))
         << l;
  return m;
}
inline __attribute__((target("avx2,fma"))) double masked_min16_avx2(const double* v, std::uint32_t mask) {
  const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  const __m256i bit = _mm256_setr_epi64x(1, 2, 4, 8);
  __m256d r = inf;
  for (unsigned l = 0; l < 16; l += 4) {
    const __m256i sel = _mm256_cmpeq_epi64(_mm256_and_si256(_mm256_set1_epi64x((mask >> l) & 0xFu), bit), bit);
    r = _mm256_min_pd(r, _mm256_blendv_pd(inf, _mm256_loadu_pd(v + l), _mm256_castsi256_pd(sel)));
  }
  return _mm256_cvtsd_f64(lanes_min4(r));
}

// PacketPointFilterFn (simd.hpp) on AVX2: each point broadcast against the rays in groups of 4
// lanes (only the groups holding a ray of `rays`), with filter_step4's terms (filter_terms4).
inline __attribute__((target("avx2,fma"))) unsigned packet_point_filter_avx2(const double* xyz, unsigned count,
                                                                             const PointFilterPacketD& f,
                                                                             std::uint32_t rays, std::uint32_t* idx,
                                                                             std::uint32_t* masks) {
  unsigned group[4], ng = 0;
  for (unsigned g = 0; g < 4; ++g)
    if ((rays >> (4 * g)) & 0xFu) group[ng++] = 4 * g;
  unsigned n = 0;
  for (unsigned j = 0; j < count; ++j) {
    const double* p = xyz + 3 * static_cast<std::size_t>(j);
    const __m256d px = _mm256_broadcast_sd(p), py = _mm256_broadcast_sd(p + 1), pz = _mm256_broadcast_sd(p + 2);
    std::uint32_t m = 0;
    for (unsigned k = 0; k < ng; ++k) {
      const unsigned l = group[k];
      const __m256d vx = _mm256_sub_pd(px, _mm256_load_pd(f.o[0] + l));
      const __m256d vy = _mm256_sub_pd(py, _mm256_load_pd(f.o[1] + l));
      const __m256d vz = _mm256_sub_pd(pz, _mm256_load_pd(f.o[2] + l));
      __m256d t, d2;
      filter_terms4(vx, vy, vz, _mm256_load_pd(f.d[0] + l), _mm256_load_pd(f.d[1] + l), _mm256_load_pd(f.d[2] + l),
                    t, d2);
      const __m256d ok =
          _mm256_and_pd(_mm256_cmp_pd(d2, _mm256_load_pd(f.d2_max + l), _CMP_LE_OQ),
                        _mm256_and_pd(_mm256_cmp_pd(t, _mm256_load_pd(f.t_lo + l), _CMP_GE_OQ),
                                      _mm256_cmp_pd(t, _mm256_load_pd(f.t_hi + l), _CMP_LE_OQ)));
      m |= static_cast<std::uint32_t>(_mm256_movemask_pd(ok)) << l;
    }
    m &= rays;
    idx[n] = j;
    masks[n] = m;
    n += m != 0;
  }
  return n;
}

#endif

}  // namespace rayscan::simd::kernels
