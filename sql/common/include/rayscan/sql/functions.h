/* The paper's SQL user-defined functions (Teuscher et al., "Ray Queries On Raw Point Clouds",
 * section 4.2, eqs. 5 and 6) and their bounds evaluation over a chunk box, with the argument rules
 * both database engines share (SQLite extension sql/sqlite, PostgreSQL extension sql/postgres).
 * A plain C interface so that the PostgreSQL glue can stay C; the values come from the core
 * (octree/include/rayscan/octree/distance.hpp, ray_query.hpp), so both engines agree with `rayscan query`
 * to the last bit. No function throws; none allocates. */
#ifndef RAYSCAN_SQL_FUNCTIONS_H
#define RAYSCAN_SQL_FUNCTIONS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/** The three point functions of the SQL extensions (all take 9 arguments: 3-vector, 3-vector, point). */
typedef enum rs_function {
  RS_DIST_RAY = 0,  /**< dist_ray(ox,oy,oz, dx,dy,dz, x,y,z): distance to the ray line, eq. 5 */
  RS_RAY_TIME = 1,  /**< ray_time(ox,oy,oz, dx,dy,dz, x,y,z): t of the projection, world units */
  RS_DIST_PLANE = 2 /**< dist_plane(px,py,pz, nx,ny,nz, x,y,z): signed distance, eq. 6 */
} rs_function;

/** Size of the message buffer the functions below write an error into. */
#define RS_ERRBUF 192

/** What kind of fault an error reports, for an engine that gives each kind its own code
 * (PostgreSQL's SQLSTATE, chosen in one table in sql/postgres/rayscan_pg.c); SQLite has one. */
typedef enum rs_error_kind {
  RS_ERROR_ARGUMENT = 0,     /**< an argument outside the function's domain: NaN or infinite, a zero or
                                  unnormalisable direction, min > max, r < 0, t_min > t_max */
  RS_ERROR_OUT_OF_RANGE = 1, /**< a number beyond double's range: a result that overflows, a number
                                  in a text form that float8 would refuse */
  RS_ERROR_SYNTAX = 2,       /**< a text form that is not the type's syntax */
  RS_ERROR_BINARY = 3        /**< a binary form of the wrong size (PostgreSQL's rs_box receive) */
} rs_error_kind;

/** SQL name of f ("dist_ray", "ray_time", "dist_plane"). */
const char* rs_function_name(rs_function f);

/** Evaluates f at a[0..8] into *out. Returns NULL on success, else a one-line message in err that
 * starts with `fn`, the SQL function the user called (the messages name the caller, not the shared
 * code: "dist_ray: argument 7 (x) is NaN; expected a finite number",
 * "ray_dwithin: the result overflows double precision; ..."), and its kind in *kind (when not
 * NULL): RS_ERROR_OUT_OF_RANGE for the overflow, else RS_ERROR_ARGUMENT. Argument numbers in the
 * message are positions in a[], so a caller whose own arguments are laid out differently checks
 * them first. */
const char* rs_eval(const char* fn, rs_function f, const double a[9], double* out, rs_error_kind* kind,
                    char err[RS_ERRBUF]);

/** Bounds evaluation (section 4.2) of f over the box a[6..11] = (xmin,ymin,zmin,xmax,ymax,zmax)
 * with a[0..5] as in rs_eval: [*lo, *hi] holds every value rs_eval returns for a point of the
 * box (the exact bounds widened by the octree node test's rounding allowance, node_test_tolerance:
 * about 1e-9 of the distance from o to the box plus its extent; dist_ray's lo is at least 0).
 * SQL names: <name>_min / <name>_max. Errors as rs_eval (starting with `fn`, e.g.
 * "dist_ray_min: box xmin > xmax; expected min <= max on every axis"), plus a box with min > max
 * on an axis (RS_ERROR_ARGUMENT). */
const char* rs_eval_bounds(const char* fn, rs_function f, const double a[12], double* lo, double* hi,
                           rs_error_kind* kind, char err[RS_ERRBUF]);

/** The number of the n points p[3i..3i+2] with dist_ray(o, d, p) <= r, each by the core function
 * rs_eval returns; only finite distances are counted (one that overflows is rs_eval's error, also
 * for r = +inf, which rs_check_ray accepts). For a ray checked once (rs_check_ray) instead of at
 * every point: a planner's estimate over a sample of points. */
size_t rs_count_dist_ray_within(const double o[3], const double d[3], double r, const double* p, size_t n);

/** Outcome of testing a chunk box against a ray predicate (SQLite's R*Tree eWithin values). */
typedef enum rs_within { RS_NOT_WITHIN = 0, RS_PARTLY_WITHIN = 1, RS_FULLY_WITHIN = 2 } rs_within;

/** The chunk pruning test of the paper's section 4.2 for the predicate
 * dist_ray(o,d,p) <= r AND t_min <= ray_time(o,d,p) <= t_max over box[6] = (xmin,ymin,zmin,
 * xmax,ymax,zmax): NOT_WITHIN when the bounds exclude every point (with tolerance, so rounding
 * never prunes a qualifying point), FULLY_WITHIN when they admit every point, else PARTLY_WITHIN.
 * *score receives a lower bound of the distance (order_time = 0) or of the time (order_time = 1)
 * of any qualifying point, below rs_eval's value at every point of the box; for a one-point box,
 * rs_eval's value itself: the "nearest first" key (the GiST distance). Arguments must have passed
 * rs_check_ray. */
rs_within rs_ray_box_test(const double o[3], const double d[3], double r, double t_min,
                          double t_max, int order_time, const double box[6], double* score);

/** Cheap conservative reject for rs_ray_box_test's predicate (finite r only): 1 when the line
 * segment {o + t u : t in [t_min - g, t_max + g]} (u = d / |d|) misses the box grown by
 * g = r + tolerance on every axis (slab test; Kay & Kajiya 1986, pbrt-v4 section 6.1.2), which
 * implies that no point of the box has dist_ray <= r with ray_time in [t_min, t_max]; else 0.
 * Used before the exact bounds evaluation on R*Tree / GiST nodes. Arguments as rs_ray_box_test. */
int rs_ray_box_misses(const double o[3], const double d[3], double r, double t_min, double t_max,
                      const double box[6]);

/** Half-space test {p : dist_plane(p0, n, p) <= 0} over a box (a frustum is a set of them). */
rs_within rs_plane_box_test(const double p0[3], const double n[3], const double box[6]);

/** Parses the text form of the PostgreSQL types rs_box, rs_ray, rs_plane: "(v1,...,vn)" with spaces
 * allowed around the numbers, each number as strtod reads it (so "inf" and "nan" parse: the types'
 * own checks refuse them where they are not allowed). Writes n doubles to v. Returns NULL, or
 * "invalid input syntax for type <type>: expected <n> comma-separated numbers in parentheses", or,
 * when the syntax holds, for the first number beyond double's range as PostgreSQL's float8 input
 * refuses it (strtod's ERANGE with an infinite or zero result: 1e400, 1e-400; a subnormal one such
 * as 1e-310 is kept) "<type>: <names[i]> \"<number>\" is out of range for type double precision"
 * (the number's text up to 64 characters). names: the n values' names. *kind (when not NULL)
 * receives RS_ERROR_OUT_OF_RANGE for that last error (float8's SQLSTATE 22003), else
 * RS_ERROR_SYNTAX. */
const char* rs_parse_tuple(const char* s, double* v, int n, const char* type, const char* const* names,
                           rs_error_kind* kind, char err[RS_ERRBUF]);

/** Checks a ray direction (normal = 0, named "direction (dx,dy,dz)") or a plane normal (normal = 1,
 * "normal (nx,ny,nz)") against the core's rule (rayscan::is_valid_direction in
 * rayscan/octree/ray.hpp): non-zero, finite, and |v|^2 a normal double (about 1.5e-154 <= |v| <=
 * 1.3e154), so that v / |v| is finite and exact. `fn` names the SQL function in the message.
 * NULL when valid. This and the other rs_check_* report RS_ERROR_ARGUMENT faults only. */
const char* rs_check_direction(const char* fn, int normal, const double v[3], char err[RS_ERRBUF]);

/** Checks a plane's point p and normal n (dist_plane's first six arguments, the half-space of
 * SQLite's plane_prune and PostgreSQL's plane_below / rs_plane): each value finite, named as the
 * functions name them ("plane_below: pz is NaN; expected a finite number"), then the normal under
 * rs_check_direction. `fn` names the SQL function or type in the message. NULL when valid. */
const char* rs_check_plane(const char* fn, const double p[3], const double n[3], char err[RS_ERRBUF]);

/** Checks query arguments: origin and direction finite, direction valid (rs_check_direction), r >= 0 and not NaN,
 * t_min <= t_max, neither NaN. `fn` names the SQL function in the message. NULL when valid. */
const char* rs_check_ray(const char* fn, const double o[3], const double d[3], double r,
                         double t_min, double t_max, char err[RS_ERRBUF]);

#ifdef __cplusplus
}
#endif
#endif
