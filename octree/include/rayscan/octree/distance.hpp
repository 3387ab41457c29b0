// Distance predicates of the paper (section 3.2, eqs. 1-2; section 4.2, eqs. 5-6) and their
// "bounds evaluation" versions over an axis-aligned box (section 4.2): the interval of values the
// function can take for any point inside the box. The interval versions drive node pruning in the
// ray query (section 3.3) and are the functions a SQL engine uses to prune chunks by statistics.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace rayscan {

/// Orthogonal distance from point p to the infinite line through o with direction dir
/// (paper eq. 1 / eq. 5, `dist_ray`). dir need not be unit length; a zero dir gives NaN.
/// Computed as |(p - o) - ((p - o).u) u| with u = dir / |dir|, which equals eq. 1 and avoids the
/// cancellation of |p-o|^2 - t^2 far from the origin. Units: world units.
[[nodiscard]] inline double dist_ray(const Vec3& o, const Vec3& dir, const Vec3& p) {
  const Vec3 u = dir / glm::length(dir);
  const Vec3 v = p - o;
  return glm::length(v - glm::dot(v, u) * u);
}

/// Signed distance from p to the plane through p0 with normal n (paper eq. 2 / eq. 6,
/// `dist_plane`): n.(p - p0) / |n|. Positive on the side n points to. With p0 = ray origin and
/// n = ray direction it is the time t_p of p's projection on the ray. A zero n gives NaN.
[[nodiscard]] inline double dist_plane(const Vec3& p0, const Vec3& n, const Vec3& p) {
  return glm::dot(n, p - p0) / glm::length(n);
}

/// Bounds evaluation of dist_plane over box b: the exact [min, max] of n.(p - p0)/|n| for p in b
/// (paper section 4.2; with p0 = o, n = d it is the projected time interval [t_near, t_far] of
/// eq. 4, computed from the nearest and farthest corners). Returns an empty Interval for an empty box.
[[nodiscard]] inline Interval dist_plane_bounds(const Vec3& p0, const Vec3& n, const AABB& b) {
  if (b.empty()) return {};
  const Vec3 u = n / glm::length(n);
  const Vec3 a = u * (b.lo - p0);
  const Vec3 c = u * (b.hi - p0);
  const Vec3 mn = glm::min(a, c);
  const Vec3 mx = glm::max(a, c);
  return {mn.x + mn.y + mn.z, mx.x + mx.y + mx.z};
}

/// Exact squared minimum distance between box b and the ray segment {o + t u : t in [t0, t1]}
/// (u unit; t0/t1 may be infinite: [-inf, inf] is the whole line). This is the "accurate measure
/// of the shortest distance between an axis-aligned cube and a ray" that paper section 3.3 names
/// as the exact alternative to eq. 3.
/// Method: g(t) = dist^2(o + t u, b) is a convex piecewise quadratic in t with at most 6
/// breakpoints (where o_i + t u_i crosses lo_i or hi_i); on each piece the set of violated faces is
/// fixed, so the piece minimum is the clamped stationary point of a 1-D quadratic. The minimum over
/// all pieces is exact up to rounding. Returns +inf for an empty box or t0 > t1.
[[nodiscard]] double segment_box_distance2(const Vec3& o, const Vec3& u, double t0, double t1,
                                           const AABB& b);

/// Bounds evaluation of dist_ray over box b (paper section 4.2): [min, max] of the orthogonal
/// distance from points of b to the line (o, dir). The minimum is exact (segment_box_distance2 over
/// the whole line); the maximum is attained at a corner because the squared distance is convex.
/// dir need not be unit length. Returns an empty Interval for an empty box.
[[nodiscard]] Interval dist_ray_bounds(const Vec3& o, const Vec3& dir, const AABB& b);

/// The paper's cheap conservative node distance, eq. 3: |c' - c| - |u - l| / 2, clamped at 0,
/// where c is the box centre and c' its projection on the line (o, dir). It never exceeds the
/// exact minimum distance, so it is a safe pruning bound, only a weaker one.
[[nodiscard]] inline double node_ray_distance_eq3(const Vec3& o, const Vec3& dir, const AABB& b) {
  const double dc = dist_ray(o, dir, b.center());
  const double half_diag = 0.5 * glm::length(b.hi - b.lo);
  return std::max(0.0, dc - half_diag);
}

/// Separating-axis lower bound of the box-to-line distance: with c the box centre, e its half
/// extents, w the unit vector from the line towards c orthogonal to u (unit), every box point p
/// has dist_ray >= w.(p - o) >= |c - c'| - sum_i |w_i| e_i. It is never below eq. 3 (Cauchy-Schwarz:
/// sum |w_i| e_i <= |e|) and costs one square root; rayscan uses it to reject nodes before the exact
/// distance. Returns 0 when the centre lies on the line.
[[nodiscard]] inline double node_ray_distance_sat(const Vec3& o, const Vec3& u, const AABB& b) {
  const Vec3 e = 0.5 * (b.hi - b.lo);
  const Vec3 v = b.center() - o;
  const Vec3 w = v - glm::dot(v, u) * u;
  const double dc = glm::length(w);
  if (!(dc > 0.0)) return 0.0;
  const Vec3 aw = glm::abs(w);
  return std::max(0.0, dc - (aw.x * e.x + aw.y * e.y + aw.z * e.z) / dc);
}

/// Slab test (Kay & Kajiya 1986; pbrt-v4 section 6.1.2) of the line o + t u against box b grown
/// by `pad` on every side, clipped to [t0, t1], with the per-ray constants precomputed:
/// o_plus = o + pad, o_minus = o - pad (component-wise) and inv_u = 1/u (inf for a zero component
/// is fine). Returns the [t_near, t_far] interval inside the grown box, empty when the line misses
/// it. Every point p of b with dist_ray <= pad and t_p in [t0, t1] projects inside the returned
/// interval, so it is a conservative time bound for the node (paper section 3.3).
[[nodiscard]] __attribute__((always_inline)) inline Interval slab_interval_grown(
    const Vec3& o_plus, const Vec3& o_minus, const Vec3& inv_u, const AABB& b, double t0,
    double t1) {
  double tn = t0, tf = t1;
  for (int i = 0; i < 3; ++i) {
    // For u_i = 0, inv_u is +-inf: the products are +-inf (line outside the slab: empty result)
    // or NaN (line exactly on a slab plane); a NaN fails both comparisons below and leaves the
    // interval unchanged, which keeps the touching line (conservative).
    double ta = (b.lo[i] - o_plus[i]) * inv_u[i];
    double tb = (b.hi[i] - o_minus[i]) * inv_u[i];
    if (ta > tb) std::swap(ta, tb);
    tn = ta > tn ? ta : tn;
    tf = tb < tf ? tb : tf;
  }
  return {tn, tf};
}

/// Rounding allowance of node tests for queries from origin o on box b (world units): the bounds
/// above are computed in double and may err, so a node is pruned only when its bound exceeds the
/// query's limit by more than this. 1e-9 of o's distance to b's centre plus b's extent covers the
/// errors relative to the geometry; 2^-48 (16-32 ulp) of the largest coordinate magnitude covers the
/// rounding of box centres and points on the ray at the coordinates' own magnitude, which does not
/// shrink with the box (UTM northings ~5.3e6 m: ulp 9.3e-10 m). Without that term a ray touching a
/// tight box's corner at r = 0 was pruned by a separating-axis bound of 3.7e-10 m
/// (bench/notes/). Used by the ray query and the SQL box tests.
/// `dist_to_centre` = |o - b.center()|, for callers that have it already.
[[nodiscard]] inline double node_test_tolerance(const Vec3& o, const AABB& b, double dist_to_centre) {
  // The largest magnitude as a tree of maxima (depth 4, not a chain of 8: every ray query starts
  // with it, and a max takes 4 cycles on some cores); the maximum of finite values is the same in
  // any order.
  using std::abs, std::max;
  const double mo = max(max(abs(o.x), abs(o.y)), abs(o.z));
  const double mb = max(max(max(abs(b.lo.x), abs(b.lo.y)), max(abs(b.lo.z), abs(b.hi.x))),
                        max(abs(b.hi.y), abs(b.hi.z)));
  const double mag = max(mo, mb);
  return 1e-9 * (dist_to_centre + b.max_extent()) + 0x1p-48 * mag + 1e-300;
}

/// node_test_tolerance_bound's coefficients (relative to the magnitude, and absolute, world
/// units), for the SIMD kernels that evaluate it lane by lane.
inline constexpr double kNodeTestToleranceBoundRel = 0x1p-26;
inline constexpr double kNodeTestToleranceBoundAbs = 1e-299;

/// An upper bound of node_test_tolerance(o, b) for every origin o and box b with coordinates of
/// magnitude at most `mag` (|o_i|, |b.lo_i|, |b.hi_i| <= mag), with a factor 2 to spare for the
/// rounding of either: |o - b.center()| <= 2 sqrt(3) mag and b.max_extent() <= 2 mag give
/// node_test_tolerance <= (5.47e-9 + 2^-48) mag + 1e-300, and 2^-26 = 1.49e-8 (for mag far below
/// 1e308, where node_test_tolerance itself stays finite). World units. For a
/// test that must accept whatever the node test accepts without computing the tolerance itself
/// (simd::RayBoxFn, the first-hit traversals' root test).
[[nodiscard]] constexpr double node_test_tolerance_bound(double mag) {
  return kNodeTestToleranceBoundRel * mag + kNodeTestToleranceBoundAbs;
}

/// node_test_tolerance with |o - b.center()| computed here.
[[nodiscard]] inline double node_test_tolerance(const Vec3& o, const AABB& b) {
  return node_test_tolerance(o, b, glm::length(o - b.center()));
}

/// slab_interval_grown for a ray origin o and pad (computes o +- pad itself).
[[nodiscard]] inline Interval slab_interval(const Vec3& o, const Vec3& inv_u, const AABB& b,
                                            double pad, double t0, double t1) {
  return slab_interval_grown(o + pad, o - pad, inv_u, b, t0, t1);
}

}  // namespace rayscan
