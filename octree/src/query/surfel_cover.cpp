// The covering discs of a hit point from a per-pixel candidate set (surfel.hpp: CoverCandidates,
// cover_hits_among, covering_discs_among, blended_normal_among).
#include "rayscan/octree/surfel.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace rayscan {

void CoverCandidates::finish() {
  const std::size_t n = cands.size();
  px.resize(n);
  py.resize(n);
  pz.resize(n);
  lim2.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const CoverCandidate& c = cands[i];
    const Vec3 v = c.p - x0;
    px[i] = static_cast<float>(v.x);
    py[i] = static_cast<float>(v.y);
    pz[i] = static_cast<float>(v.z);
    // For x within delta of x0, the float difference float(p - x0) - float(x - x0) of each axis
    // lies within e of the exact p - x: the two roundings to float (2^-24 relative each, of |p -
    // x0| and |x - x0| <= delta), the double subtractions before them and the float subtraction
    // (2^-24 of |p - x| <= |p - x0| + delta); e = 2^-21 (|p - x0| + delta) covers all of them
    // with room. So |p - x| <= reach gives a float length <= reach + 2 e (sqrt(3) e, rounded
    // up), and its float square sum exceeds the exact one by less than 2^-21 relative: the bound
    // takes 2^-18.
    const double e = 0x1p-21 * (glm::length(v) + delta);
    const double reach = std::sqrt(surfel_detail::cover_reach2(c.r, 0.0)) + 2.0 * e;
    const double lim = reach * reach * (1.0 + 0x1p-18);
    float f = static_cast<float>(lim);
    if (static_cast<double>(f) < lim) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    // A NaN bound (a NaN radius) would reject the candidate; +inf leaves it to the exact tests,
    // which keep it as the descent does.
    lim2[i] = f >= 0.0f ? f : std::numeric_limits<float>::infinity();
  }
}

void cover_hits_among(const CoverCandidates& set, const Vec3& x, std::vector<CoverHit>& out) {
  out.clear();
  const std::size_t n = set.cands.size();
  assert(set.px.size() == n && set.py.size() == n && set.pz.size() == n && set.lim2.size() == n);
  // The exact tests of covering_discs (the descent's reach on the index position, then the cover
  // test), with the same expressions.
  const auto exact = [&](std::size_t i) {
    const CoverCandidate& c = set.cands[i];
    const Vec3 v = c.p - x;
    const double d2 = glm::dot(v, v);
    if (d2 > surfel_detail::cover_reach2(c.r, 0.0)) return;
    const double pd2 = cover_in_plane_d2(c.c, Vec3(c.n), c.r, x);
    if (!(pd2 < kInf)) return;
    out.push_back({d2, c.id, pd2, &c});
  };
  const Vec3 q = x - set.x0;
  const float qx = static_cast<float>(q.x), qy = static_cast<float>(q.y), qz = static_cast<float>(q.z);
  const float* px = set.px.data();
  const float* py = set.py.data();
  const float* pz = set.pz.data();
  const float* lim = set.lim2.data();
  std::size_t i = 0;
#if defined(__SSE2__)
  // Four candidates per step; the same float expressions as the scalar loop below (no fused
  // multiply-add on SSE2), so the lanes decide as it would.
  const __m128 vx = _mm_set1_ps(qx), vy = _mm_set1_ps(qy), vz = _mm_set1_ps(qz);
  for (; i + 4 <= n; i += 4) {
    const __m128 dx = _mm_sub_ps(_mm_loadu_ps(px + i), vx);
    const __m128 dy = _mm_sub_ps(_mm_loadu_ps(py + i), vy);
    const __m128 dz = _mm_sub_ps(_mm_loadu_ps(pz + i), vz);
    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    for (unsigned m = static_cast<unsigned>(_mm_movemask_ps(_mm_cmple_ps(d2, _mm_loadu_ps(lim + i)))); m; m &= m - 1)
      exact(i + static_cast<std::size_t>(std::countr_zero(m)));
  }
#endif
  for (; i < n; ++i) {
    const float dx = px[i] - qx, dy = py[i] - qy, dz = pz[i] - qz;
    if (dx * dx + dy * dy + dz * dz <= lim[i]) exact(i);
  }
  std::sort(out.begin(), out.end(),
            [](const CoverHit& a, const CoverHit& b) { return surfel_detail::cover_less(a.d2, a.id, b.d2, b.id); });
}

void covering_discs_among(const CoverCandidates& set, const Vec3& x, std::vector<Neighbor>& out,
                          std::vector<CoverHit>& scratch) {
  cover_hits_among(set, x, scratch);
  out.clear();
  for (const CoverHit& h : scratch) out.push_back({h.id, std::sqrt(h.d2)});
}

Vec3 blended_normal_among(const CoverCandidates& set, PointIndex hit, const glm::vec3& n0, const Vec3& x,
                          std::vector<CoverHit>& scratch) {
  cover_hits_among(set, x, scratch);
  surfel_detail::NormalBlend b{Vec3(n0), hit};
  for (const CoverHit& h : scratch) b.add(h.id, Vec3(h.cand->n), double(h.cand->r), [&] { return h.plane_d2; });
  return b.normal();
}

}  // namespace rayscan
