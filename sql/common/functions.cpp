// The shared SQL function semantics (see rayscan/sql/functions.h): argument checks in one place,
// values from the core so that SQLite, PostgreSQL and `rayscan query` agree to the last bit.
#include "rayscan/sql/functions.h"

#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/ray.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>

namespace {

using rayscan::AABB;
using rayscan::Interval;
using rayscan::Vec3;

constexpr const char* kNames[3] = {"dist_ray", "ray_time", "dist_plane"};
constexpr const char* kArgs[3][12] = {
    {"ox", "oy", "oz", "dx", "dy", "dz", "x", "y", "z", "xmax", "ymax", "zmax"},
    {"ox", "oy", "oz", "dx", "dy", "dz", "x", "y", "z", "xmax", "ymax", "zmax"},
    {"px", "py", "pz", "nx", "ny", "nz", "x", "y", "z", "xmax", "ymax", "zmax"}};
constexpr const char* kBoxArgs[6] = {"xmin", "ymin", "zmin", "xmax", "ymax", "zmax"};


// Every argument finite; the direction/normal (a[3..5]) one the core accepts. `fn` is the SQL
// function the user called, which every message names.
const char* check(const char* fn, rs_function f, const double* a, int n, bool box, char* err) {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(a[i])) {
      const char* name = (box && i >= 6) ? kBoxArgs[i - 6] : kArgs[f][i];
      std::snprintf(err, RS_ERRBUF, "%s: argument %d (%s) is %s; expected a finite number", fn,
                    i + 1, name,
                    std::isnan(a[i]) ? "NaN" : "infinite");
      return err;
    }
  return rs_check_direction(fn, f == RS_DIST_PLANE, a + 3, err);
}

AABB make_box(const double* b) { return {Vec3(b[0], b[1], b[2]), Vec3(b[3], b[4], b[5])}; }

// The scalar function f at a[0..9) (checked arguments).
double value(rs_function f, const double* a) {
  const Vec3 o(a[0], a[1], a[2]), d(a[3], a[4], a[5]), p(a[6], a[7], a[8]);
  switch (f) {
    case RS_DIST_RAY: return rayscan::dist_ray(o, d, p);
    // The t of `rayscan query`: the projection on the ray's unit direction, normalised as the
    // core Ray does, through the one per-point function every index uses.
    case RS_RAY_TIME: return rayscan::ray_point_terms(o, rayscan::Ray(o, d).direction(), p).t;
    case RS_DIST_PLANE: return rayscan::dist_plane(o, d, p);
  }
  return 0.0;
}

}  // namespace

extern "C" const char* rs_function_name(rs_function f) { return kNames[f]; }

extern "C" const char* rs_eval(const char* fn, rs_function f, const double a[9], double* out,
                               rs_error_kind* kind, char err[RS_ERRBUF]) {
  if (kind) *kind = RS_ERROR_ARGUMENT;
  if (const char* e = check(fn, f, a, 9, false, err)) return e;
  *out = value(f, a);
  // Finite inputs near the double range can overflow the core's squares and products (from about
  // 1e150): an error rather than an infinite or NaN distance passed off as a value.
  if (!std::isfinite(*out)) {
    if (kind) *kind = RS_ERROR_OUT_OF_RANGE;
    std::snprintf(err, RS_ERRBUF, "%s: the result overflows double precision; expected coordinates and "
                  "vector components of magnitude below about 1e150", fn);
    return err;
  }
  return nullptr;
}

extern "C" size_t rs_count_dist_ray_within(const double o_[3], const double d_[3], double r, const double* p,
                                           size_t n) {
  const Vec3 o(o_[0], o_[1], o_[2]), d(d_[0], d_[1], d_[2]);
  size_t count = 0;
  for (size_t i = 0; i < n; ++i) {
    // A distance that overflows is rs_eval's error, not a value within r, even when r is +inf.
    const double v = rayscan::dist_ray(o, d, Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
    count += std::isfinite(v) && v <= r;
  }
  return count;
}

extern "C" const char* rs_eval_bounds(const char* fn, rs_function f, const double a[12], double* lo,
                                      double* hi, rs_error_kind* kind, char err[RS_ERRBUF]) {
  if (kind) *kind = RS_ERROR_ARGUMENT;
  if (const char* e = check(fn, f, a, 12, true, err)) return e;
  for (int i = 0; i < 3; ++i)
    if (a[6 + i] > a[9 + i]) {
      std::snprintf(err, RS_ERRBUF, "%s: box %s > %s; expected min <= max on every axis", fn,
                    kBoxArgs[i], kBoxArgs[i + 3]);
      return err;
    }
  const Vec3 o(a[0], a[1], a[2]), d(a[3], a[4], a[5]);
  const AABB b = make_box(a + 6);
  // ray_time's t is dist_plane with p0 = o, n = d (eq. 4: the projected time interval).
  const Interval iv = f == RS_DIST_RAY ? rayscan::dist_ray_bounds(o, d, b)
                                       : rayscan::dist_plane_bounds(o, d, b);
  // The exact bounds are computed in double too, and the scalar function at a point of the box
  // rounds differently (by some ulps of the coordinates' magnitude): widened by the octree node
  // test's rounding allowance, [lo, hi] holds what
  // the scalar function returns at every point of the box, so `dist_ray_min(...) <= r` never
  // prunes a box holding a point with `dist_ray(...) <= r`.
  const double tol = rayscan::node_test_tolerance(o, b);
  *lo = f == RS_DIST_RAY ? std::max(0.0, iv.lo - tol) : iv.lo - tol;
  *hi = iv.hi + tol;
  if (!std::isfinite(*lo) || !std::isfinite(*hi)) {
    if (kind) *kind = RS_ERROR_OUT_OF_RANGE;
    std::snprintf(err, RS_ERRBUF, "%s: the result overflows double precision; expected coordinates "
                  "and vector components of magnitude below about 1e150", fn);
    return err;
  }
  return nullptr;
}

extern "C" const char* rs_parse_tuple(const char* s, double* v, int n, const char* type,
                                      const char* const* names, rs_error_kind* kind, char err[RS_ERRBUF]) {
  const char* p = s;
  char* end = nullptr;
  bool ok = true;
  // The first number beyond double's range, [range_at, range_end) of s: reported only once the
  // whole text has parsed, so that bad syntax anywhere is reported as such.
  int range_i = -1;
  const char *range_at = nullptr, *range_end = nullptr;
  if (kind) *kind = RS_ERROR_SYNTAX;
  while (*p == ' ') ++p;
  ok = *p++ == '(';
  for (int i = 0; ok && i < n; ++i) {
    errno = 0;
    v[i] = std::strtod(p, &end);
    ok = end != p;
    // float8in's rule: strtod's ERANGE with an infinite or zero result; a subnormal one is kept.
    if (ok && errno == ERANGE && (v[i] == 0.0 || std::isinf(v[i])) && range_i < 0) {
      range_i = i, range_at = p, range_end = end;
      while (range_at < range_end && std::isspace(static_cast<unsigned char>(*range_at))) ++range_at;
    }
    p = end;
    while (ok && *p == ' ') ++p;
    ok = ok && *p++ == (i + 1 < n ? ',' : ')');
  }
  while (ok && *p == ' ') ++p;
  if (ok && *p == 0) {
    if (range_i < 0) return nullptr;
    if (kind) *kind = RS_ERROR_OUT_OF_RANGE;
    std::snprintf(err, RS_ERRBUF, "%s: %s \"%.*s\" is out of range for type double precision", type,
                  names[range_i], static_cast<int>(std::min<std::ptrdiff_t>(range_end - range_at, 64)), range_at);
    return err;
  }
  // The input itself is not repeated: it may be long or hold control characters.
  std::snprintf(err, RS_ERRBUF, "invalid input syntax for type %s: expected %d comma-separated numbers "
                "in parentheses", type, n);
  return err;
}

extern "C" const char* rs_check_direction(const char* fn, int normal, const double v[3],
                                          char err[RS_ERRBUF]) {
  if (rayscan::is_valid_direction(Vec3(v[0], v[1], v[2]))) return nullptr;
  const char* what = normal ? "normal (nx,ny,nz)" : "direction (dx,dy,dz)";
  if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0)
    std::snprintf(err, RS_ERRBUF, "%s: %s is zero; expected a non-zero vector", fn, what);
  else
    std::snprintf(err, RS_ERRBUF,
                  "%s: %s = (%g,%g,%g) cannot be normalised exactly; expected a finite length "
                  "between about 1.5e-154 and 1.3e154", fn, what, v[0], v[1], v[2]);
  return err;
}

extern "C" const char* rs_check_plane(const char* fn, const double p[3], const double n[3],
                                      char err[RS_ERRBUF]) {
  static const char* names[6] = {"px", "py", "pz", "nx", "ny", "nz"};
  for (int i = 0; i < 6; ++i) {
    const double v = i < 3 ? p[i] : n[i - 3];
    if (!std::isfinite(v)) {
      std::snprintf(err, RS_ERRBUF, "%s: %s is %s; expected a finite number", fn, names[i],
                    std::isnan(v) ? "NaN" : "infinite");
      return err;
    }
  }
  return rs_check_direction(fn, 1, n, err);
}

extern "C" const char* rs_check_ray(const char* fn, const double o[3], const double d[3], double r,
                                    double t_min, double t_max, char err[RS_ERRBUF]) {
  static const char* names[6] = {"ox", "oy", "oz", "dx", "dy", "dz"};
  for (int i = 0; i < 6; ++i) {
    const double v = i < 3 ? o[i] : d[i - 3];
    if (!std::isfinite(v)) {
      std::snprintf(err, RS_ERRBUF, "%s: %s is %s; expected a finite number", fn, names[i],
                    std::isnan(v) ? "NaN" : "infinite");
      return err;
    }
  }
  if (const char* e = rs_check_direction(fn, 0, d, err)) return e;
  if (std::isnan(r) || r < 0.0) {
    std::snprintf(err, RS_ERRBUF, "%s: radius r is %s; expected a number >= 0 (NULL: unbounded)",
                  fn, std::isnan(r) ? "NaN" : "negative");
    return err;
  }
  if (std::isnan(t_min) || std::isnan(t_max) || t_min > t_max) {
    std::snprintf(err, RS_ERRBUF, "%s: t_min/t_max (%g, %g): expected t_min <= t_max, not NaN", fn,
                  t_min, t_max);
    return err;
  }
  return nullptr;
}

extern "C" rs_within rs_ray_box_test(const double o_[3], const double d_[3], double r, double t_min,
                                     double t_max, int order_time, const double box[6],
                                     double* score) {
  const Vec3 o(o_[0], o_[1], o_[2]), d(d_[0], d_[1], d_[2]);
  const AABB b = make_box(box);
  const double tol = rayscan::node_test_tolerance(o, b);
  const Interval dr = rayscan::dist_ray_bounds(o, d, b);
  const Interval tb = rayscan::dist_plane_bounds(o, d, b);
  // The GiST distance: for a one-point box the scalar function's own value (so `ORDER BY <->`
  // orders as `ORDER BY dist_ray` / `ray_time` does), else the bound widened by the rounding
  // allowance, below the value at every point inside (a lower bound, as index order needs).
  if (b.lo == b.hi) {
    const double a[9] = {o_[0], o_[1], o_[2], d_[0], d_[1], d_[2], b.lo.x, b.lo.y, b.lo.z};
    *score = order_time ? std::max(value(RS_RAY_TIME, a), t_min) : value(RS_DIST_RAY, a);
  } else {
    *score = order_time ? std::max(tb.lo - tol, t_min) : std::max(0.0, dr.lo - tol);
  }
  if (dr.empty() || dr.lo > r + tol || tb.hi < t_min - tol || tb.lo > t_max + tol)
    return RS_NOT_WITHIN;
  if (dr.hi <= r - tol && tb.lo >= t_min + tol && tb.hi <= t_max - tol) return RS_FULLY_WITHIN;
  return RS_PARTLY_WITHIN;
}

extern "C" rs_within rs_plane_box_test(const double p0_[3], const double n_[3], const double box[6]) {
  const Vec3 p0(p0_[0], p0_[1], p0_[2]), n(n_[0], n_[1], n_[2]);
  const AABB b = make_box(box);
  const double tol = rayscan::node_test_tolerance(p0, b);
  const Interval iv = rayscan::dist_plane_bounds(p0, n, b);
  if (iv.empty() || iv.lo > tol) return RS_NOT_WITHIN;
  if (iv.hi <= -tol) return RS_FULLY_WITHIN;
  return RS_PARTLY_WITHIN;
}

extern "C" int rs_ray_box_misses(const double o_[3], const double d_[3], double r, double t_min,
                                 double t_max, const double box[6]) {
  if (!std::isfinite(r)) return 0;
  const Vec3 o(o_[0], o_[1], o_[2]);
  const Vec3 u = rayscan::Ray(o, Vec3(d_[0], d_[1], d_[2])).direction();  // the core's unit direction
  const AABB b = make_box(box);
  // A qualifying point p lies within r of the line point o + t_p u (t_p in [t_min, t_max]), so
  // that line point lies in the box grown by r (+ the pruning tolerance) on every axis: if the
  // line segment misses the grown box (slab test), no point of the box qualifies.
  const double g = r + rayscan::node_test_tolerance(o, b);
  double t0 = t_min - g, t1 = t_max + g;
  for (int i = 0; i < 3; ++i) {
    const double lo = b.lo[i] - g, hi = b.hi[i] + g;
    if (u[i] == 0.0) {
      if (o[i] < lo || o[i] > hi) return 1;
      continue;
    }
    double ta = (lo - o[i]) / u[i], tb = (hi - o[i]) / u[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return 1;
  }
  return 0;
}
