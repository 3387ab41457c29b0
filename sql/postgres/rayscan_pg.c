/* PostgreSQL 15 extension `rayscan` (paper section 4.2): the functions dist_ray,
 * ray_time, dist_plane and their bounds evaluation <name>_min / <name>_max, the chunk box type
 * rs_box, the ray predicate rs_ray (ray_within(...)), the operators
 *   rs_box && rs_ray   (the box may hold a point with dist_ray <= r and t in [t_min, t_max])
 *   rs_box <-> rs_ray  (lower bound of dist_ray over the box: index-ordered kNN of chunks)
 * a GiST operator class rs_box_ops whose consistent and distance methods are that bounds
 * evaluation, and for rs_box itself =, a B-tree and a hash operator class (DISTINCT, GROUP BY)
 * and binary I/O, and statistics (rs_box_analyze: a sample of the boxes, from which ray_dwithin's
 * planner support function estimates its selectivity). Values come from the core through
 * rayscan/sql/functions.h (C interface over the C++ core), so they equal the SQLite extension and
 * `rayscan query` to the last bit.
 * GiST interface: PostgreSQL 15 documentation, chapter 68.3 "Extensibility". */
#include "postgres.h"

#include "access/gist.h"
#include "access/stratnum.h"
#include "catalog/namespace.h"
#include "catalog/pg_statistic.h"
#include "catalog/pg_type.h"
#include "commands/vacuum.h"
#include "common/hashfn.h"
#include "fmgr.h"
#include "libpq/pqformat.h"
#include "nodes/makefuncs.h"
#include "nodes/pathnodes.h"
#include "nodes/supportnodes.h"
#include "optimizer/optimizer.h"
#include "parser/parse_func.h"
#include "utils/builtins.h"
#include "utils/float.h"
#include "utils/lsyscache.h"
#include "utils/selfuncs.h"
#include "utils/syscache.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "rayscan/sql/functions.h"

PG_MODULE_MAGIC;

/* A chunk box: (xmin, ymin, zmin, xmax, ymax, zmax), the layout rs_ray_box_test expects. */
typedef struct RsBox {
  double v[6];
} RsBox;

/* A ray predicate: dist_ray(o, d, p) <= r AND t_min <= ray_time(o, d, p) <= t_max. */
typedef struct RsRay {
  double o[3], d[3], r, t_min, t_max;
} RsRay;

/* A half-space {p : dist_plane(p0, n, p) <= 0} (paper eq. 6); a frustum is an AND of them. */
typedef struct RsPlane {
  double p[3], n[3];
} RsPlane;

#define RS_STRATEGY_ADMITS 1   /* && */
#define RS_STRATEGY_PLANE 3    /* && (rs_box, rs_plane) */
#define RS_STRATEGY_DISTANCE 15 /* <-> (RTKNNSearchStrategyNumber) */

/* The SQLSTATE of each kind of error (rs_error_kind), the one place that chooses them: class 22
 * "data exception" of PostgreSQL 15's appendix A, as the server's own functions and types report
 * the same faults: an argument outside the function's domain 22023 invalid_parameter_value (as
 * generate_series' zero step), a number or result beyond float8's range 22003
 * numeric_value_out_of_range (as float8's input and arithmetic), a malformed literal 22P02
 * invalid_text_representation and a malformed binary value 22P03 invalid_binary_representation
 * (as float8in and the receive functions). The module reads no file and allocates only through
 * palloc, whose failure is PostgreSQL's own 53200; a GiST strategy it does not know is an
 * internal error (elog: XX000). */
static const int kSqlState[] = {
    [RS_ERROR_ARGUMENT] = ERRCODE_INVALID_PARAMETER_VALUE,
    [RS_ERROR_OUT_OF_RANGE] = ERRCODE_NUMERIC_VALUE_OUT_OF_RANGE,
    [RS_ERROR_SYNTAX] = ERRCODE_INVALID_TEXT_REPRESENTATION,
    [RS_ERROR_BINARY] = ERRCODE_INVALID_BINARY_REPRESENTATION,
};

/* Raises `msg` (one line) with the SQLSTATE of its kind. */
static void raise_error(rs_error_kind kind, const char* msg) pg_attribute_noreturn();
static void raise_error(rs_error_kind kind, const char* msg) {
  ereport(ERROR, (errcode(kSqlState[kind]), errmsg("%s", msg)));
  pg_unreachable();
}

/* ---- scalar functions -------------------------------------------------------------------- */

static Datum point_fn(FunctionCallInfo fcinfo, rs_function f) {
  double a[9], v;
  char err[RS_ERRBUF];
  const char* e;
  rs_error_kind kind;
  int i;
  for (i = 0; i < 9; ++i) a[i] = PG_GETARG_FLOAT8(i);
  e = rs_eval(rs_function_name(f), f, a, &v, &kind, err);
  if (e) raise_error(kind, e);
  PG_RETURN_FLOAT8(v);
}

/* <name>_min / <name>_max: `fn` is that SQL name, which the error messages carry. */
static Datum bounds_fn(FunctionCallInfo fcinfo, const char* fn, rs_function f, int want_max) {
  double a[12], lo, hi;
  char err[RS_ERRBUF];
  const char* e;
  rs_error_kind kind;
  int i;
  for (i = 0; i < 12; ++i) a[i] = PG_GETARG_FLOAT8(i);
  e = rs_eval_bounds(fn, f, a, &lo, &hi, &kind, err);
  if (e) raise_error(kind, e);
  PG_RETURN_FLOAT8(want_max ? hi : lo);
}

PG_FUNCTION_INFO_V1(rs_dist_ray);
Datum rs_dist_ray(PG_FUNCTION_ARGS) { return point_fn(fcinfo, RS_DIST_RAY); }
PG_FUNCTION_INFO_V1(rs_ray_time);
Datum rs_ray_time(PG_FUNCTION_ARGS) { return point_fn(fcinfo, RS_RAY_TIME); }
PG_FUNCTION_INFO_V1(rs_dist_plane);
Datum rs_dist_plane(PG_FUNCTION_ARGS) { return point_fn(fcinfo, RS_DIST_PLANE); }
PG_FUNCTION_INFO_V1(rs_dist_ray_min);
Datum rs_dist_ray_min(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "dist_ray_min", RS_DIST_RAY, 0); }
PG_FUNCTION_INFO_V1(rs_dist_ray_max);
Datum rs_dist_ray_max(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "dist_ray_max", RS_DIST_RAY, 1); }
PG_FUNCTION_INFO_V1(rs_ray_time_min);
Datum rs_ray_time_min(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "ray_time_min", RS_RAY_TIME, 0); }
PG_FUNCTION_INFO_V1(rs_ray_time_max);
Datum rs_ray_time_max(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "ray_time_max", RS_RAY_TIME, 1); }
PG_FUNCTION_INFO_V1(rs_dist_plane_min);
Datum rs_dist_plane_min(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "dist_plane_min", RS_DIST_PLANE, 0); }
PG_FUNCTION_INFO_V1(rs_dist_plane_max);
Datum rs_dist_plane_max(PG_FUNCTION_ARGS) { return bounds_fn(fcinfo, "dist_plane_max", RS_DIST_PLANE, 1); }

/* ---- rs_box and rs_ray types ------------------------------------------------------------- */

/* Parses "(v1,...,vn)" into n doubles (rs_parse_tuple); raises its one-line error naming the type.
 * A number beyond float8's range is refused as float8's own input refuses it (float8in_internal:
 * SQLSTATE 22003), naming the value (names[i]): strtod alone would turn 1e400 into an infinity the
 * type then calls infinite, and 1e-400 into 0. Subnormal results are kept, as float8 keeps them. */
static void parse_tuple(const char* s, double* v, int n, const char* type, const char* const* names) {
  char err[RS_ERRBUF];
  rs_error_kind kind;
  if (rs_parse_tuple(s, v, n, type, names, &kind, err)) raise_error(kind, err);
}

static const char* const kBoxNames[6] = {"xmin", "ymin", "zmin", "xmax", "ymax", "zmax"};
static const char* const kRayNames[9] = {"ox", "oy", "oz", "dx", "dy", "dz", "r", "t_min", "t_max"};
static const char* const kPlaneNames[6] = {"px", "py", "pz", "nx", "ny", "nz"};

static char* format_tuple(const double* v, int n) {
  StringInfoData s;
  int i;
  initStringInfo(&s);
  appendStringInfoChar(&s, '(');
  for (i = 0; i < n; ++i) {
    char* f = float8out_internal(v[i]);
    if (i) appendStringInfoChar(&s, ',');
    appendStringInfoString(&s, f);
    pfree(f);
  }
  appendStringInfoChar(&s, ')');
  return s.data;
}

/* Every coordinate finite (a chunk box or a point; an infinite one would pass here and fail in
 * every later predicate), min <= max on every axis. */
static void check_box(const RsBox* b, bool point) {
  static const char* point_names[6] = {"x", "y", "z", "x", "y", "z"};
  char err[RS_ERRBUF];
  int i;
  for (i = 0; i < 6; ++i)
    if (!isfinite(b->v[i])) {
      snprintf(err, sizeof err, "rs_box: %s is %s; expected a finite number", point ? point_names[i] : kBoxNames[i],
               isnan(b->v[i]) ? "NaN" : "infinite");
      raise_error(RS_ERROR_ARGUMENT, err);
    }
  /* The axis named as the bounds functions name it (dist_ray_min: "box xmin > xmax"). */
  for (i = 0; i < 3; ++i)
    if (b->v[i] > b->v[i + 3]) {
      snprintf(err, sizeof err, "rs_box: %s > %s; expected min <= max on every axis", kBoxNames[i], kBoxNames[i + 3]);
      raise_error(RS_ERROR_ARGUMENT, err);
    }
}

/* `fn` is what the user called: ray_within(...), or the type's text input ('(...)'::rs_ray). */
static void check_ray(const RsRay* q, const char* fn) {
  char err[RS_ERRBUF];
  const char* e = rs_check_ray(fn, q->o, q->d, q->r, q->t_min, q->t_max, err);
  if (e) raise_error(RS_ERROR_ARGUMENT, e);
}

PG_FUNCTION_INFO_V1(rs_box_in);
Datum rs_box_in(PG_FUNCTION_ARGS) {
  RsBox* b = palloc(sizeof(RsBox));
  parse_tuple(PG_GETARG_CSTRING(0), b->v, 6, "rs_box", kBoxNames);
  check_box(b, false);
  PG_RETURN_POINTER(b);
}
PG_FUNCTION_INFO_V1(rs_box_out);
Datum rs_box_out(PG_FUNCTION_ARGS) {
  PG_RETURN_CSTRING(format_tuple(((RsBox*)PG_GETARG_POINTER(0))->v, 6));
}
PG_FUNCTION_INFO_V1(rs_box_make);
Datum rs_box_make(PG_FUNCTION_ARGS) {
  RsBox* b = palloc(sizeof(RsBox));
  int i;
  for (i = 0; i < 6; ++i) b->v[i] = PG_GETARG_FLOAT8(i);
  check_box(b, false);
  PG_RETURN_POINTER(b);
}
/* Binary I/O (COPY ... (FORMAT binary), libpq's binary results): the six coordinates as float8 in
 * network byte order, PostgreSQL's own float8send format, so a client reads them as it reads
 * float8. The receiver refuses a value of another size and applies check_box, as the text input
 * does: a corrupt or hand-made value cannot put a NaN or an inverted box into a table. */
PG_FUNCTION_INFO_V1(rs_box_send);
Datum rs_box_send(PG_FUNCTION_ARGS) {
  const RsBox* b = (const RsBox*)PG_GETARG_POINTER(0);
  StringInfoData buf;
  int i;
  pq_begintypsend(&buf);
  for (i = 0; i < 6; ++i) pq_sendfloat8(&buf, b->v[i]);
  PG_RETURN_BYTEA_P(pq_endtypsend(&buf));
}
PG_FUNCTION_INFO_V1(rs_box_recv);
Datum rs_box_recv(PG_FUNCTION_ARGS) {
  StringInfo buf = (StringInfo)PG_GETARG_POINTER(0);
  RsBox* b = palloc(sizeof(RsBox));
  char err[RS_ERRBUF];
  int i;
  if (buf->len - buf->cursor != (int)sizeof(RsBox)) {
    snprintf(err, sizeof err, "invalid binary value for type rs_box: %d bytes; expected 48 (six float8 in "
             "network byte order)", buf->len - buf->cursor);
    raise_error(RS_ERROR_BINARY, err);
  }
  for (i = 0; i < 6; ++i) b->v[i] = pq_getmsgfloat8(buf);
  check_box(b, false);
  PG_RETURN_POINTER(b);
}

/* Comparison for DISTINCT, GROUP BY, count(DISTINCT box), UNION, ORDER BY box and hash or merge
 * joins (the default operator classes rs_box_btree_ops and rs_box_hash_ops, as PostGIS gives
 * geometry both a B-tree and a hash class): two boxes are equal when their six coordinates are
 * equal as float8 (so -0 = 0; a box holds no NaN), and ordered lexicographically by (xmin, ymin,
 * zmin, xmax, ymax, zmax). The order is only a total order for sorting and grouping, not a
 * spatial relation. */
static int box_cmp(const RsBox* a, const RsBox* b) {
  int i;
  for (i = 0; i < 6; ++i)
    if (a->v[i] != b->v[i]) return a->v[i] < b->v[i] ? -1 : 1;
  return 0;
}
#define RS_BOX_CMP_ARGS box_cmp((const RsBox*)PG_GETARG_POINTER(0), (const RsBox*)PG_GETARG_POINTER(1))
PG_FUNCTION_INFO_V1(rs_box_cmp);
Datum rs_box_cmp(PG_FUNCTION_ARGS) { PG_RETURN_INT32(RS_BOX_CMP_ARGS); }
PG_FUNCTION_INFO_V1(rs_box_eq);
Datum rs_box_eq(PG_FUNCTION_ARGS) { PG_RETURN_BOOL(RS_BOX_CMP_ARGS == 0); }
PG_FUNCTION_INFO_V1(rs_box_lt);
Datum rs_box_lt(PG_FUNCTION_ARGS) { PG_RETURN_BOOL(RS_BOX_CMP_ARGS < 0); }
PG_FUNCTION_INFO_V1(rs_box_le);
Datum rs_box_le(PG_FUNCTION_ARGS) { PG_RETURN_BOOL(RS_BOX_CMP_ARGS <= 0); }
PG_FUNCTION_INFO_V1(rs_box_ge);
Datum rs_box_ge(PG_FUNCTION_ARGS) { PG_RETURN_BOOL(RS_BOX_CMP_ARGS >= 0); }
PG_FUNCTION_INFO_V1(rs_box_gt);
Datum rs_box_gt(PG_FUNCTION_ARGS) { PG_RETURN_BOOL(RS_BOX_CMP_ARGS > 0); }
/* Hash consistent with box_cmp's equality: -0 hashed as 0 (as hashfloat8 does), then the 48 bytes. */
PG_FUNCTION_INFO_V1(rs_box_hash);
Datum rs_box_hash(PG_FUNCTION_ARGS) {
  const RsBox* b = (const RsBox*)PG_GETARG_POINTER(0);
  double v[6];
  int i;
  for (i = 0; i < 6; ++i) v[i] = b->v[i] == 0.0 ? 0.0 : b->v[i];
  return hash_any((const unsigned char*)v, sizeof v);
}

PG_FUNCTION_INFO_V1(rs_ray_in);
Datum rs_ray_in(PG_FUNCTION_ARGS) {
  RsRay* q = palloc(sizeof(RsRay));
  double v[9];
  parse_tuple(PG_GETARG_CSTRING(0), v, 9, "rs_ray", kRayNames);
  memcpy(q, v, sizeof v);
  check_ray(q, "rs_ray");
  PG_RETURN_POINTER(q);
}
PG_FUNCTION_INFO_V1(rs_ray_out);
Datum rs_ray_out(PG_FUNCTION_ARGS) {
  PG_RETURN_CSTRING(format_tuple((const double*)PG_GETARG_POINTER(0), 9));
}
/* ray_within(ox,oy,oz, dx,dy,dz, r [, t_min, t_max]); NULL r / t keep the default (inf). */
PG_FUNCTION_INFO_V1(rs_ray_make);
Datum rs_ray_make(PG_FUNCTION_ARGS) {
  RsRay* q = palloc(sizeof(RsRay));
  int i;
  for (i = 0; i < 6; ++i) {
    if (PG_ARGISNULL(i)) PG_RETURN_NULL();
    (i < 3 ? q->o : q->d)[i % 3] = PG_GETARG_FLOAT8(i);
  }
  q->r = PG_NARGS() > 6 && !PG_ARGISNULL(6) ? PG_GETARG_FLOAT8(6) : get_float8_infinity();
  q->t_min = PG_NARGS() > 7 && !PG_ARGISNULL(7) ? PG_GETARG_FLOAT8(7) : -get_float8_infinity();
  q->t_max = PG_NARGS() > 8 && !PG_ARGISNULL(8) ? PG_GETARG_FLOAT8(8) : get_float8_infinity();
  check_ray(q, "ray_within");
  PG_RETURN_POINTER(q);
}

/* rs_box(x,y,z): the degenerate box of one point (what a points-table GiST index stores). */
PG_FUNCTION_INFO_V1(rs_point_box);
Datum rs_point_box(PG_FUNCTION_ARGS) {
  RsBox* b = palloc(sizeof(RsBox));
  int i;
  for (i = 0; i < 3; ++i) b->v[i] = b->v[i + 3] = PG_GETARG_FLOAT8(i);
  check_box(b, true);
  PG_RETURN_POINTER(b);
}

/* `fn` as check_ray's: plane_below(...) or the text input of rs_plane. The bad value is named
 * (rs_check_plane), as SQLite's plane_prune names it. */
static void check_plane(const RsPlane* h, const char* fn) {
  char err[RS_ERRBUF];
  const char* e = rs_check_plane(fn, h->p, h->n, err);
  if (e) raise_error(RS_ERROR_ARGUMENT, e);
}
PG_FUNCTION_INFO_V1(rs_plane_in);
Datum rs_plane_in(PG_FUNCTION_ARGS) {
  RsPlane* h = palloc(sizeof(RsPlane));
  double v[6];
  parse_tuple(PG_GETARG_CSTRING(0), v, 6, "rs_plane", kPlaneNames);
  memcpy(h, v, sizeof v);
  check_plane(h, "rs_plane");
  PG_RETURN_POINTER(h);
}
PG_FUNCTION_INFO_V1(rs_plane_out);
Datum rs_plane_out(PG_FUNCTION_ARGS) {
  PG_RETURN_CSTRING(format_tuple((const double*)PG_GETARG_POINTER(0), 6));
}
/* plane_below(px,py,pz, nx,ny,nz): the half-space dist_plane(p, n, .) <= 0. */
PG_FUNCTION_INFO_V1(rs_plane_make);
Datum rs_plane_make(PG_FUNCTION_ARGS) {
  RsPlane* h = palloc(sizeof(RsPlane));
  int i;
  for (i = 0; i < 6; ++i) (i < 3 ? h->p : h->n)[i % 3] = PG_GETARG_FLOAT8(i);
  check_plane(h, "plane_below");
  PG_RETURN_POINTER(h);
}

/* ---- operators --------------------------------------------------------------------------- */

static rs_within test(const RsBox* b, const RsRay* q, double* score) {
  return rs_ray_box_test(q->o, q->d, q->r, q->t_min, q->t_max, 0, b->v, score);
}

PG_FUNCTION_INFO_V1(rs_box_admits);
Datum rs_box_admits(PG_FUNCTION_ARGS) {
  const RsBox* b = (const RsBox*)PG_GETARG_POINTER(0);
  const RsRay* q = (const RsRay*)PG_GETARG_POINTER(1);
  double score;
  /* The same two steps as the GiST consistent method, so index and operator agree exactly. */
  if (rs_ray_box_misses(q->o, q->d, q->r, q->t_min, q->t_max, b->v)) PG_RETURN_BOOL(false);
  PG_RETURN_BOOL(test(b, q, &score) != RS_NOT_WITHIN);
}
PG_FUNCTION_INFO_V1(rs_box_admits_plane);
Datum rs_box_admits_plane(PG_FUNCTION_ARGS) {
  const RsPlane* h = (const RsPlane*)PG_GETARG_POINTER(1);
  PG_RETURN_BOOL(rs_plane_box_test(h->p, h->n, ((RsBox*)PG_GETARG_POINTER(0))->v) != RS_NOT_WITHIN);
}

PG_FUNCTION_INFO_V1(rs_box_distance);
Datum rs_box_distance(PG_FUNCTION_ARGS) {
  double score;
  test((RsBox*)PG_GETARG_POINTER(0), (RsRay*)PG_GETARG_POINTER(1), &score);
  PG_RETURN_FLOAT8(score);
}

/* ---- GiST support ------------------------------------------------------------------------ */

PG_FUNCTION_INFO_V1(rs_gist_consistent);
Datum rs_gist_consistent(PG_FUNCTION_ARGS) {
  GISTENTRY* entry = (GISTENTRY*)PG_GETARG_POINTER(0);
  const RsRay* q = (const RsRay*)PG_GETARG_POINTER(1);
  StrategyNumber strategy = (StrategyNumber)PG_GETARG_UINT16(2);
  bool* recheck = (bool*)PG_GETARG_POINTER(4);
  double score;
  /* Leaf: the same bounds test as the operator itself, so the answer is exact. */
  *recheck = false;
  if (strategy == RS_STRATEGY_PLANE) {
    const RsPlane* h = (const RsPlane*)PG_GETARG_POINTER(1);
    PG_RETURN_BOOL(rs_plane_box_test(h->p, h->n, ((const RsBox*)DatumGetPointer(entry->key))->v) !=
                   RS_NOT_WITHIN);
  }
  if (strategy != RS_STRATEGY_ADMITS) elog(ERROR, "rs_box_ops: unknown strategy %d", strategy);
  if (rs_ray_box_misses(q->o, q->d, q->r, q->t_min, q->t_max, ((const RsBox*)DatumGetPointer(entry->key))->v))
    PG_RETURN_BOOL(false);
  PG_RETURN_BOOL(test((const RsBox*)DatumGetPointer(entry->key), q, &score) != RS_NOT_WITHIN);
}

PG_FUNCTION_INFO_V1(rs_gist_distance);
Datum rs_gist_distance(PG_FUNCTION_ARGS) {
  GISTENTRY* entry = (GISTENTRY*)PG_GETARG_POINTER(0);
  const RsRay* q = (const RsRay*)PG_GETARG_POINTER(1);
  bool* recheck = (bool*)PG_GETARG_POINTER(4);
  double score;
  *recheck = false;
  test((const RsBox*)DatumGetPointer(entry->key), q, &score);
  PG_RETURN_FLOAT8(score);
}

PG_FUNCTION_INFO_V1(rs_gist_union);
Datum rs_gist_union(PG_FUNCTION_ARGS) {
  GistEntryVector* ev = (GistEntryVector*)PG_GETARG_POINTER(0);
  int* sizep = (int*)PG_GETARG_POINTER(1);
  RsBox* u = palloc(sizeof(RsBox));
  int i, j;
  *u = *(RsBox*)DatumGetPointer(ev->vector[0].key);
  for (i = 1; i < ev->n; ++i) {
    const RsBox* b = (const RsBox*)DatumGetPointer(ev->vector[i].key);
    for (j = 0; j < 3; ++j) {
      u->v[j] = Min(u->v[j], b->v[j]);
      u->v[j + 3] = Max(u->v[j + 3], b->v[j + 3]);
    }
  }
  *sizep = sizeof(RsBox);
  PG_RETURN_POINTER(u);
}

static double box_measure(const RsBox* b) {
  /* volume plus half the surface "margin", so flat boxes still have a size */
  const double ex = b->v[3] - b->v[0], ey = b->v[4] - b->v[1], ez = b->v[5] - b->v[2];
  return ex * ey * ez + (ex + ey + ez);
}

PG_FUNCTION_INFO_V1(rs_gist_penalty);
Datum rs_gist_penalty(PG_FUNCTION_ARGS) {
  const RsBox* a = (const RsBox*)DatumGetPointer(((GISTENTRY*)PG_GETARG_POINTER(0))->key);
  const RsBox* b = (const RsBox*)DatumGetPointer(((GISTENTRY*)PG_GETARG_POINTER(1))->key);
  float* penalty = (float*)PG_GETARG_POINTER(2);
  RsBox u;
  int j;
  for (j = 0; j < 3; ++j) {
    u.v[j] = Min(a->v[j], b->v[j]);
    u.v[j + 3] = Max(a->v[j + 3], b->v[j + 3]);
  }
  *penalty = (float)(box_measure(&u) - box_measure(a));
  PG_RETURN_POINTER(penalty);
}

typedef struct SplitItem {
  double c;
  OffsetNumber off;
} SplitItem;
static int split_cmp(const void* x, const void* y) {
  const double a = ((const SplitItem*)x)->c, b = ((const SplitItem*)y)->c;
  return a < b ? -1 : a > b ? 1 : 0;
}

/* Split at the median of the box centres along the axis of largest spread. */
PG_FUNCTION_INFO_V1(rs_gist_picksplit);
Datum rs_gist_picksplit(PG_FUNCTION_ARGS) {
  GistEntryVector* ev = (GistEntryVector*)PG_GETARG_POINTER(0);
  GIST_SPLITVEC* v = (GIST_SPLITVEC*)PG_GETARG_POINTER(1);
  const OffsetNumber maxoff = ev->n - 1;
  const int n = maxoff - FirstOffsetNumber + 1;
  SplitItem* items = palloc(sizeof(SplitItem) * n);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  int axis = 0, i, j;
  RsBox *l = palloc(sizeof(RsBox)), *r = palloc(sizeof(RsBox));
  for (i = 0; i < n; ++i) {
    const RsBox* b = (const RsBox*)DatumGetPointer(ev->vector[FirstOffsetNumber + i].key);
    for (j = 0; j < 3; ++j) {
      const double c = 0.5 * (b->v[j] + b->v[j + 3]);
      lo[j] = Min(lo[j], c);
      hi[j] = Max(hi[j], c);
    }
  }
  for (j = 1; j < 3; ++j)
    if (hi[j] - lo[j] > hi[axis] - lo[axis]) axis = j;
  for (i = 0; i < n; ++i) {
    const RsBox* b = (const RsBox*)DatumGetPointer(ev->vector[FirstOffsetNumber + i].key);
    items[i].c = 0.5 * (b->v[axis] + b->v[axis + 3]);
    items[i].off = FirstOffsetNumber + i;
  }
  qsort(items, n, sizeof(SplitItem), split_cmp);
  v->spl_left = palloc(sizeof(OffsetNumber) * (n + 1));
  v->spl_right = palloc(sizeof(OffsetNumber) * (n + 1));
  v->spl_nleft = v->spl_nright = 0;
  for (i = 0; i < n; ++i) {
    const RsBox* b = (const RsBox*)DatumGetPointer(ev->vector[items[i].off].key);
    const bool left = i < n / 2;
    RsBox* u = left ? l : r;
    if ((left ? v->spl_nleft : v->spl_nright) == 0) *u = *b;
    for (j = 0; j < 3; ++j) {
      u->v[j] = Min(u->v[j], b->v[j]);
      u->v[j + 3] = Max(u->v[j + 3], b->v[j + 3]);
    }
    if (left) v->spl_left[v->spl_nleft++] = items[i].off;
    else v->spl_right[v->spl_nright++] = items[i].off;
  }
  v->spl_ldatum = PointerGetDatum(l);
  v->spl_rdatum = PointerGetDatum(r);
  PG_RETURN_POINTER(v);
}

PG_FUNCTION_INFO_V1(rs_gist_same);
Datum rs_gist_same(PG_FUNCTION_ARGS) {
  const RsBox* a = (const RsBox*)PG_GETARG_POINTER(0);
  const RsBox* b = (const RsBox*)PG_GETARG_POINTER(1);
  bool* result = (bool*)PG_GETARG_POINTER(2);
  *result = memcmp(a, b, sizeof(RsBox)) == 0;
  PG_RETURN_POINTER(result);
}

/* ---- ray_dwithin and its planner support function ---------------------------------------- */

/* ray_dwithin's checks of its ray a = (ox,oy,oz, dx,dy,dz) and radius r, by its argument names
 * (ox, ..., dz): rs_eval would number the arguments by its own layout, not ray_dwithin's. Shared
 * with ray_dwithin_ray, the index condition's ray, so that a bad argument fails with the same
 * message whether the plan evaluates ray_dwithin or its index condition first, and with the
 * selectivity estimate, which gives up on a ray the function would refuse. NULL when valid, else
 * the message (an RS_ERROR_ARGUMENT), in err or static. */
static const char* dwithin_ray_error(const double a[6], double r, char err[RS_ERRBUF]) {
  if (isnan(r) || r < 0) return "ray_dwithin: radius r is negative or NaN; expected a number >= 0";
  return rs_check_ray("ray_dwithin", a, a + 3, r, -get_float8_infinity(), get_float8_infinity(), err);
}
static void check_dwithin_ray(const double a[6], double r) {
  char err[RS_ERRBUF];
  const char* e = dwithin_ray_error(a, r, err);
  if (e) raise_error(RS_ERROR_ARGUMENT, e);
}

/* ray_dwithin's value for box b, the checked ray a = (ox,oy,oz, dx,dy,dz) and radius r into
 * *within (see rs_ray_dwithin). NULL, or the message of the result's overflow (the box is valid
 * wherever it was made, check_box) with its kind in *kind; never raises, so the selectivity
 * estimate can run it over a sample. */
static const char* dwithin(const RsBox* b, const double a6[6], double r, bool* within, rs_error_kind* kind,
                           char err[RS_ERRBUF]) {
  double a[12], v, lo, hi;
  const char* e;
  memcpy(a, a6, 6 * sizeof(double));
  memcpy(a + 6, b->v, 6 * sizeof(double));
  if (b->v[0] == b->v[3] && b->v[1] == b->v[4] && b->v[2] == b->v[5]) {
    e = rs_eval("ray_dwithin", RS_DIST_RAY, a, &v, kind, err);
    *within = !e && v <= r;
    return e;
  }
  e = rs_eval_bounds("ray_dwithin", RS_DIST_RAY, a, &lo, &hi, kind, err);
  *within = !e && lo <= r;
  return e;
}

/* ray_dwithin(b, ox,oy,oz, dx,dy,dz, r): may a point of box b lie within distance r of the ray
 * line? For a point box (rs_box(x,y,z)) this is exactly dist_ray(o, d, p) <= r (the core's value);
 * for a larger box it is dist_ray_min(o, d, b) <= r (paper section 4.2, bounds evaluation). The
 * PostGIS ST_DWithin pattern: the support function below turns it into an index condition. */
PG_FUNCTION_INFO_V1(rs_ray_dwithin);
Datum rs_ray_dwithin(PG_FUNCTION_ARGS) {
  const RsBox* b = (const RsBox*)PG_GETARG_POINTER(0);
  double a[6];
  char err[RS_ERRBUF];
  const char* e;
  rs_error_kind kind;
  bool within;
  int i;
  const double r = PG_GETARG_FLOAT8(7);
  for (i = 0; i < 6; ++i) a[i] = PG_GETARG_FLOAT8(i + 1);
  check_dwithin_ray(a, r);
  e = dwithin(b, a, r, &within, &kind, err);
  if (e) raise_error(kind, e);
  PG_RETURN_BOOL(within);
}

/* ray_dwithin_ray(ox,oy,oz, dx,dy,dz, r): the ray of the index condition b && ray_dwithin_ray(...)
 * that the support function below derives from ray_dwithin(b, ...): ray_within(o, d, r) with
 * ray_dwithin's checks and messages (check_dwithin_ray). STRICT in SQL, as ray_dwithin is: a NULL
 * argument gives a NULL ray, which no index entry matches, as ray_dwithin gives NULL (no row),
 * where ray_within would take a NULL r as no bound. */
PG_FUNCTION_INFO_V1(rs_ray_dwithin_ray);
Datum rs_ray_dwithin_ray(PG_FUNCTION_ARGS) {
  RsRay* q = palloc(sizeof(RsRay));
  double a[6];
  int i;
  for (i = 0; i < 6; ++i) a[i] = PG_GETARG_FLOAT8(i);
  check_dwithin_ray(a, PG_GETARG_FLOAT8(6));
  memcpy(q->o, a, sizeof q->o);
  memcpy(q->d, a + 3, sizeof q->d);
  q->r = PG_GETARG_FLOAT8(6);
  q->t_min = -get_float8_infinity();
  q->t_max = get_float8_infinity();
  PG_RETURN_POINTER(q);
}

/* ---- statistics of rs_box and ray_dwithin's selectivity ---------------------------------- */

/* A pg_statistic slot of this kind holds a sample of the boxes ANALYZE read, in stanumbers (no
 * staop, no stavalues): first the sample's origin, the least xmin, ymin and zmin, each as a float4
 * pair (hi, lo: their sum is the double to about 2^-48 of its magnitude), then the count of numbers
 * per box, 3 when every box of the sample is a point (rs_box(x, y, z)) and 6 otherwise, then per
 * box (x, y, z) or (xmin, ymin, zmin, xmax, ymax, zmax) less the origin's, in float4 (to about 6e-8
 * of the sample's extent: 0.06 mm over 1 km). float4 numbers, as PostGIS keeps its statistics,
 * because the planner reads them in place, where a float8 array of stavalues is split into one
 * Datum per number on every plan; offsets, and a point once, because they leave PostgreSQL
 * nothing to compress, where whole or repeated coordinates are decompressed on every plan too
 * (measured on autzen's points, PostgreSQL 15 on a 2-core AMD EPYC Zen 5 guest: 10,000 as float8
 * values cost about 1 ms a plan, 3,000 as float4 coordinates 0.4 ms, as offsets 0.04 ms, nearly
 * all of it evaluating them). A private kind code (catalog/pg_statistic.h: for private use, a code
 * chosen at random in 10000-30000). */
#define RS_STATISTIC_KIND_BOX_SAMPLE 17235
/* Boxes kept per unit of the column's statistics target (default_statistics_target 100: 3,000
 * boxes, 72 KB), a tenth of ANALYZE's sample of 300 rows per unit: what ray_dwithin's estimate
 * reads and evaluates on every plan (docs/sql.md). A selectivity below one in that many is
 * estimated as 0 rows (the planner then assumes 1). */
#define RS_BOX_SAMPLE_PER_TARGET 30
/* Coordinates beyond this magnitude are left out of the sample, so that the origin and every
 * offset (at most twice this) are within float4's range. */
#define RS_BOX_SAMPLE_MAX_COORD 1e38
/* ray_dwithin's selectivity without a sample: areasel's constant, as for the && index condition. */
#define RS_DWITHIN_DEFAULT_SEL 0.005

/* The standard statistics' routine and data (std_typanalyze: null fraction, distinct count, MCVs
 * and histogram under rs_box's B-tree order, for =, DISTINCT and GROUP BY), which
 * box_compute_stats runs before it adds its sample. */
typedef struct BoxAnalyze {
  AnalyzeAttrComputeStatsFunc std_compute;
  void* std_extra;
} BoxAnalyze;

/* ANALYZE's compute_stats for rs_box: the standard statistics, then in the first free slot a
 * sample of at most RS_BOX_SAMPLE_PER_TARGET x target of the sampled boxes, every k-th row of
 * ANALYZE's sample (which is in the table's physical order), NULLs and boxes beyond
 * RS_BOX_SAMPLE_MAX_COORD left out, in the layout of RS_STATISTIC_KIND_BOX_SAMPLE. */
static void box_compute_stats(VacAttrStats* stats, AnalyzeAttrFetchFunc fetch, int samplerows, double totalrows) {
  const BoxAnalyze* an = (const BoxAnalyze*)stats->extra_data;
  const int keep = Min(samplerows, RS_BOX_SAMPLE_PER_TARGET * stats->attr->attstattarget);
  double origin[3] = {INFINITY, INFINITY, INFINITY};
  RsBox* boxes;
  float4* numbers;
  int slot = 0, n = 0, per_box = 3, i, j;
  stats->extra_data = an->std_extra;
  an->std_compute(stats, fetch, samplerows, totalrows);
  while (slot < STATISTIC_NUM_SLOTS && stats->stakind[slot] != 0) ++slot;
  if (!stats->stats_valid || slot == STATISTIC_NUM_SLOTS || keep <= 0) return;
  boxes = palloc(sizeof(RsBox) * keep);
  for (i = 0; i < keep; ++i) {
    bool isnull, fits = true;
    const Datum d = fetch(stats, (int)((int64)i * samplerows / keep), &isnull);
    vacuum_delay_point();
    if (isnull) continue;
    boxes[n] = *(const RsBox*)DatumGetPointer(d);
    for (j = 0; j < 6; ++j) fits = fits && fabs(boxes[n].v[j]) <= RS_BOX_SAMPLE_MAX_COORD;
    if (!fits) continue;
    for (j = 0; j < 3; ++j) {
      origin[j] = Min(origin[j], boxes[n].v[j]);
      if (boxes[n].v[j] != boxes[n].v[j + 3]) per_box = 6;
    }
    ++n;
  }
  if (n == 0) return;
  /* In the context that outlives the column's, which ANALYZE resets before it stores the slots. */
  numbers = MemoryContextAlloc(stats->anl_context, sizeof(float4) * (7 + per_box * n));
  for (j = 0; j < 3; ++j) {
    numbers[2 * j] = (float4)origin[j];
    numbers[2 * j + 1] = (float4)(origin[j] - numbers[2 * j]);
  }
  numbers[6] = (float4)per_box;
  for (i = 0; i < n; ++i)
    for (j = 0; j < per_box; ++j) numbers[7 + per_box * i + j] = (float4)(boxes[i].v[j] - origin[j % 3]);
  stats->stakind[slot] = RS_STATISTIC_KIND_BOX_SAMPLE;
  stats->staop[slot] = InvalidOid;
  stats->stacoll[slot] = InvalidOid;
  stats->stanumbers[slot] = numbers;
  stats->numnumbers[slot] = 7 + per_box * n;
}

/* rs_box_analyze(internal): rs_box's typanalyze (CREATE TYPE ... ANALYZE), for a column and for
 * an expression an index or CREATE STATISTICS covers (rs_box(x, y, z)): the standard statistics
 * plus the sample box_compute_stats keeps, which ray_dwithin's selectivity reads. */
PG_FUNCTION_INFO_V1(rs_box_analyze);
Datum rs_box_analyze(PG_FUNCTION_ARGS) {
  VacAttrStats* stats = (VacAttrStats*)PG_GETARG_POINTER(0);
  BoxAnalyze* an;
  if (!std_typanalyze(stats)) PG_RETURN_BOOL(false);
  an = palloc(sizeof(BoxAnalyze));
  an->std_compute = stats->compute_stats;
  an->std_extra = stats->extra_data;
  stats->compute_stats = box_compute_stats;
  stats->extra_data = an;
  PG_RETURN_BOOL(true);
}

/* ray_dwithin's selectivity in a restriction (not a join): the fraction of the box sample in the
 * statistics of its first argument (a column, or an expression such as rs_box(x, y, z) that an
 * index or CREATE STATISTICS covers) for which ray_dwithin holds, times the fraction of boxes
 * that are not NULL. -1 when there is nothing to estimate from: no sample (no statistics of the
 * box, or made before rs_box_analyze), a ray not known when planning or one ray_dwithin refuses,
 * statistics of a table the user may not read (examine_variable's acl_ok, as PostgreSQL's own
 * estimators). */
static double dwithin_selectivity(const SupportRequestSelectivity* req) {
  VariableStatData vardata;
  AttStatsSlot sslot;
  double a[6], r = 0, sel = -1;
  char err[RS_ERRBUF];
  ListCell* lc;
  int i = 0, j, n, hits = 0;
  if (req->is_join || list_length(req->args) != 8) return -1;
  for_each_from(lc, req->args, 1) {
    const Node* arg = estimate_expression_value(req->root, (Node*)lfirst(lc));
    if (!IsA(arg, Const) || ((const Const*)arg)->constisnull) return -1;
    if (i < 6) a[i++] = DatumGetFloat8(((const Const*)arg)->constvalue);
    else r = DatumGetFloat8(((const Const*)arg)->constvalue);
  }
  if (dwithin_ray_error(a, r, err)) return -1;
  examine_variable(req->root, (Node*)linitial(req->args), req->varRelid, &vardata);
  if (HeapTupleIsValid(vardata.statsTuple) && vardata.acl_ok &&
      get_attstatsslot(&sslot, vardata.statsTuple, RS_STATISTIC_KIND_BOX_SAMPLE, InvalidOid, ATTSTATSSLOT_NUMBERS)) {
    const float4* f = sslot.numbers;
    const int per_box = sslot.nnumbers > 7 && f[6] == 3 ? 3 : 6;
    double origin[3];
    n = sslot.nnumbers > 7 ? (sslot.nnumbers - 7) / per_box : 0;
    for (j = 0; j < 3 && n > 0; ++j) origin[j] = (double)f[2 * j] + (double)f[2 * j + 1];
    if (per_box == 3 && n > 0) {
      /* Points: dwithin's dist_ray <= r, counted in one call (half the time of rs_eval for each). */
      double* p = palloc(sizeof(double) * 3 * n);
      for (i = 0; i < 3 * n; ++i) p[i] = origin[i % 3] + (double)f[7 + i];
      hits = (int)rs_count_dist_ray_within(a, a + 3, r, p, (size_t)n);
      pfree(p);
    }
    for (i = 0; i < n && per_box == 6; ++i) {
      RsBox b;
      bool within;
      rs_error_kind kind;
      for (j = 0; j < 6; ++j) b.v[j] = origin[j % 3] + (double)f[7 + 6 * i + j];
      /* The GiST consistent method's cheap reject first, as most boxes lie far from the ray. */
      if (rs_ray_box_misses(a, a + 3, r, -get_float8_infinity(), get_float8_infinity(), b.v)) continue;
      if (!dwithin(&b, a, r, &within, &kind, err) && within) ++hits;
    }
    if (n > 0)
      sel = (1.0 - ((const Form_pg_statistic)GETSTRUCT(vardata.statsTuple))->stanullfrac) * hits / n;
    free_attstatsslot(&sslot);
  }
  ReleaseVariableStats(vardata);
  return sel;
}

/* Planner support for ray_dwithin (PostgreSQL 15 src/include/nodes/supportnodes.h,
 * SupportRequestIndexCondition; the pattern of PostGIS's postgis_index_supportfn): when the
 * first argument is the key of a GiST index in the rs_box_ops family, derive the lossy index
 * condition  b && ray_dwithin_ray(ox,oy,oz, dx,dy,dz, r)  (consistent = the bounds evaluation);
 * the executor rechecks ray_dwithin itself. A database whose extension predates ray_dwithin_ray
 * (0.3 and older, served by this module) gets  b && ray_within(...)  as before.
 * SupportRequestSelectivity: dwithin_selectivity, else areasel's constant (RS_DWITHIN_DEFAULT_SEL).
 * NOTE: a bare `dist_ray(...) <= r` cannot be given an index condition by any support function:
 * PostgreSQL consults support functions only for a boolean function or operator whose direct
 * argument is the index key (indxpath.c, match_funcclause_to_indexcol / match_opclause_to_indexcol),
 * and dist_ray <= r is the built-in float8le over a computed value. */
PG_FUNCTION_INFO_V1(rs_ray_dwithin_support);
Datum rs_ray_dwithin_support(PG_FUNCTION_ARGS) {
  Node* rawreq = (Node*)PG_GETARG_POINTER(0);
  if (IsA(rawreq, SupportRequestSelectivity)) {
    SupportRequestSelectivity* req = (SupportRequestSelectivity*)rawreq;
    const double sel = dwithin_selectivity(req);
    req->selectivity = sel >= 0 ? sel : RS_DWITHIN_DEFAULT_SEL;
    PG_RETURN_POINTER(req);
  }
  if (IsA(rawreq, SupportRequestIndexCondition)) {
    SupportRequestIndexCondition* req = (SupportRequestIndexCondition*)rawreq;
    FuncExpr* call;
    List* ray_args;
    Oid nsp, box_type, ray_type, op, ray_fn, argtypes[7];
    char* nspname;
    int i;
    if (!IsA(req->node, FuncExpr) || req->indexarg != 0) PG_RETURN_POINTER(NULL);
    call = (FuncExpr*)req->node;
    if (list_length(call->args) != 8) PG_RETURN_POINTER(NULL);
    /* Our types and ray_within live in ray_dwithin's schema (the extension is relocatable). */
    nsp = get_func_namespace(req->funcid);
    nspname = get_namespace_name(nsp);
    box_type = GetSysCacheOid2(TYPENAMENSP, Anum_pg_type_oid, CStringGetDatum("rs_box"), ObjectIdGetDatum(nsp));
    ray_type = GetSysCacheOid2(TYPENAMENSP, Anum_pg_type_oid, CStringGetDatum("rs_ray"), ObjectIdGetDatum(nsp));
    if (!OidIsValid(box_type) || !OidIsValid(ray_type) || !nspname) PG_RETURN_POINTER(NULL);
    op = get_opfamily_member(req->opfamily, box_type, ray_type, RS_STRATEGY_ADMITS);
    if (!OidIsValid(op)) PG_RETURN_POINTER(NULL); /* not an rs_box_ops index */
    for (i = 0; i < 7; ++i) argtypes[i] = FLOAT8OID;
    ray_fn = LookupFuncName(list_make2(makeString(nspname), makeString("ray_dwithin_ray")), 7, argtypes, true);
    if (!OidIsValid(ray_fn))
      ray_fn = LookupFuncName(list_make2(makeString(nspname), makeString("ray_within")), 7, argtypes, true);
    if (!OidIsValid(ray_fn)) PG_RETURN_POINTER(NULL);
    ray_args = list_copy_tail(call->args, 1);
    /* The ray must be known before the scan: no column of the indexed table, nothing volatile. */
    if (bms_is_member(req->index->rel->relid, pull_varnos(req->root, (Node*)ray_args)) ||
        contain_volatile_functions((Node*)ray_args))
      PG_RETURN_POINTER(NULL);
    req->lossy = true;
    PG_RETURN_POINTER(list_make1(make_opclause(
        op, BOOLOID, false, (Expr*)linitial(call->args),
        (Expr*)makeFuncExpr(ray_fn, ray_type, ray_args, InvalidOid, InvalidOid, COERCE_EXPLICIT_CALL),
        InvalidOid, InvalidOid)));
  }
  PG_RETURN_POINTER(NULL);
}
