// rayscan_sqlite: the SQLite loadable extension (paper section 4.2).
//   .load ./rayscan_sqlite          (sqlite3 shell)      conn.load_extension("rayscan_sqlite")
// Registers
//   * dist_ray, ray_time, dist_plane (9 arguments) and their bounds evaluation over a box,
//     <name>_min / <name>_max (12 arguments: the 6 of the ray or plane, xmin,ymin,zmin,xmax,ymax,zmax);
//   * the R*Tree query callbacks ray_prune(ox,oy,oz, dx,dy,dz, r [, t_min, t_max]) and
//     plane_prune(px,py,pz, nx,ny,nz) for `chunks.id MATCH ...` (https://sqlite.org/rtree.html,
//     section 7.1 "Custom R*Tree queries"): the bounds evaluation applied to R*Tree nodes and chunk
//     boxes (prune / fully inside / partly inside), rScore = the lower bound (nearest first);
//   * the table-valued function ray_query(ox,oy,oz, dx,dy,dz, k, r, t_min, t_max, ord): kNN to
//     (ord 'ray') or along (ord 'time') the ray over the chunks, nearest chunk first, with the
//     paper's dynamic k filter (Algorithm 1, step 2); the same rows as `rayscan query`; a
//     query's LIMIT (+ OFFSET) bounds the hits kept as k does when nothing can reorder or drop
//     rows after it (vt_best_index);
//   * rayscan_stats(): JSON counters of the connection's last ray_query;
//   * rayscan_error(): the reason of the connection's last ray_prune / plane_prune failure, NULL
//     once a later MATCH's arguments pass (the R*Tree API lets a callback return only an error
//     code: SQLite says "SQL logic error").
// Values come from the core through rayscan/sql/functions.h, so they equal `rayscan query` and the
// PostgreSQL extension to the last bit.
#include <sqlite3ext.h>
SQLITE_EXTENSION_INIT1

#include "rayscan/sql/chunking.hpp"
#include "rayscan/sql/functions.h"

#include "rayscan/octree/ray.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

using rayscan::Vec3;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- scalar functions --------------------------------------------------------------------------

const char* type_name(int t) {
  switch (t) {
    case SQLITE_TEXT: return "text";
    case SQLITE_BLOB: return "blob";
    default: return "null";
  }
}

// Reads n numeric arguments; false (result already set) on NULL (-> NULL) or a non-number.
bool numeric_args(sqlite3_context* ctx, const char* fn, int n, sqlite3_value** argv, double* a) {
  for (int i = 0; i < n; ++i) {
    const int t = sqlite3_value_type(argv[i]);
    if (t == SQLITE_NULL) {
      sqlite3_result_null(ctx);
      return false;
    }
    if (t != SQLITE_INTEGER && t != SQLITE_FLOAT) {
      char msg[RS_ERRBUF];
      std::snprintf(msg, sizeof msg, "%s: argument %d has type %s; expected a number", fn, i + 1,
                    type_name(t));
      sqlite3_result_error(ctx, msg, -1);
      return false;
    }
    a[i] = sqlite3_value_double(argv[i]);
  }
  return true;
}

void point_fn(sqlite3_context* ctx, int argc, sqlite3_value** argv) {
  const auto f = static_cast<rs_function>(reinterpret_cast<std::intptr_t>(sqlite3_user_data(ctx)));
  double a[9];
  if (argc != 9 || !numeric_args(ctx, rs_function_name(f), 9, argv, a)) return;
  double v;
  char err[RS_ERRBUF];
  if (const char* e = rs_eval(rs_function_name(f), f, a, &v, nullptr, err)) return sqlite3_result_error(ctx, e, -1);
  sqlite3_result_double(ctx, v);
}

template <bool kMax>
void bounds_fn(sqlite3_context* ctx, int argc, sqlite3_value** argv) {
  const auto f = static_cast<rs_function>(reinterpret_cast<std::intptr_t>(sqlite3_user_data(ctx)));
  const std::string name = std::string(rs_function_name(f)) + (kMax ? "_max" : "_min");
  double a[12];
  if (argc != 12 || !numeric_args(ctx, name.c_str(), 12, argv, a)) return;
  double lo, hi;
  char err[RS_ERRBUF];
  if (const char* e = rs_eval_bounds(name.c_str(), f, a, &lo, &hi, nullptr, err))
    return sqlite3_result_error(ctx, e, -1);
  sqlite3_result_double(ctx, kMax ? hi : lo);
}

// ---- R*Tree query callbacks --------------------------------------------------------------------

// Box of an R*Tree node or entry: aCoord = (min_x, max_x, min_y, max_y, min_z, max_z).
void rtree_box(const sqlite3_rtree_query_info* p, double box[6]) {
  box[0] = p->aCoord[0];
  box[3] = p->aCoord[1];
  box[1] = p->aCoord[2];
  box[4] = p->aCoord[3];
  box[2] = p->aCoord[4];
  box[5] = p->aCoord[5];
}

// Parameter i, with NULL (or absent) mapped to `dflt`.
double param(const sqlite3_rtree_query_info* p, int i, double dflt) {
  if (i >= p->nParam) return dflt;
  if (p->apSqlParam && sqlite3_value_type(p->apSqlParam[i]) == SQLITE_NULL) return dflt;
  return p->aParam[i];
}

// Counters of the last ray_query on a connection (rayscan_stats()).
struct Stats {
  long long chunks_total = 0;      // rows of `chunks`
  long long chunks_candidate = 0;  // chunks the R*Tree callback admitted and ray_query read from it
  long long chunks_visited = 0;    // chunks whose points were read (after the dynamic k filter)
  long long points_tested = 0;
};

// State of one connection: the counters of its last ray_query (rayscan_stats()) and the reason
// its last checked R*Tree callback failed (rayscan_error()). Owned by the ray_query module (freed
// when the connection closes).
struct Conn {
  Stats stats;              ///< ray_query's counters
  std::string prune_error;  ///< one line; "" when no callback has failed since the last that passed
};

// Fails an R*Tree query callback with `msg`. SQLite's R*Tree API carries only an error code out
// of a callback (the statement fails with "SQL logic error"), so the reason is kept for
// rayscan_error() and for SQLite's error log.
int prune_fail(const sqlite3_rtree_query_info* p, const char* msg) {
  static_cast<Conn*>(p->pContext)->prune_error = msg;
  sqlite3_log(SQLITE_ERROR, "%s", msg);
  return SQLITE_ERROR;
}

// The callback's parameters as numbers: `names` in order, the first `required` not NULL. NULL
// for an optional parameter keeps its default (param()). Returns nullptr, or the message.
const char* check_prune_params(const sqlite3_rtree_query_info* p, const char* fn,
                               const char* const* names, int required, int n_lo, int n_hi,
                               char err[RS_ERRBUF]) {
  if (p->nParam < n_lo || p->nParam > n_hi || (n_lo == 7 && p->nParam == 8)) {
    std::snprintf(err, RS_ERRBUF, "%s: %d arguments; expected %s", fn, p->nParam,
                  n_lo == 7 ? "ox,oy,oz, dx,dy,dz, r [, t_min, t_max]" : "px,py,pz, nx,ny,nz");
    return err;
  }
  for (int i = 0; p->apSqlParam && i < p->nParam; ++i) {
    const int t = sqlite3_value_type(p->apSqlParam[i]);
    if (t == SQLITE_INTEGER || t == SQLITE_FLOAT || (t == SQLITE_NULL && i >= required)) continue;
    std::snprintf(err, RS_ERRBUF, "%s: argument %s is %s; expected a number", fn, names[i],
                  t == SQLITE_NULL ? "NULL" : t == SQLITE_TEXT ? "text" : "a blob");
    return err;
  }
  return nullptr;
}

// The arguments of a MATCH are the same on every R*Tree node of one query: a callback checks them
// on its first call and then marks the query's pUser (per query, zeroed by SQLite; nothing to free).
// Arguments that pass clear the connection's failure reason, so that rayscan_error() never
// explains a later, unrelated error with an earlier MATCH's.
bool checked(const sqlite3_rtree_query_info* p) { return p->pUser != nullptr; }
void mark_checked(sqlite3_rtree_query_info* p) {
  static char mark;
  static_cast<Conn*>(p->pContext)->prune_error.clear();
  p->pUser = &mark;
  p->xDelUser = nullptr;
}

int ray_prune(sqlite3_rtree_query_info* p) {
  static const char* const names[9] = {"ox", "oy", "oz", "dx", "dy", "dz", "r", "t_min", "t_max"};
  char err[RS_ERRBUF];
  if (!checked(p)) {
    if (p->nCoord != 6)
      return prune_fail(p, "ray_prune: the R*Tree is not 3-dimensional; expected `rayscan db import`'s "
                           "chunks(id, min_x, max_x, ...)");
    if (const char* e = check_prune_params(p, "ray_prune", names, 6, 7, 9, err)) return prune_fail(p, e);
  }
  const double o[3] = {p->aParam[0], p->aParam[1], p->aParam[2]};
  const double d[3] = {p->aParam[3], p->aParam[4], p->aParam[5]};
  const double r = param(p, 6, kInf), t0 = param(p, 7, -kInf), t1 = param(p, 8, kInf);
  if (!checked(p)) {
    if (const char* e = rs_check_ray("ray_prune", o, d, r, t0, t1, err)) return prune_fail(p, e);
    mark_checked(p);
  }
  double box[6];
  rtree_box(p, box);
  if (rs_ray_box_misses(o, d, r, t0, t1, box)) {  // most entries of an expanded node: cheap
    p->eWithin = NOT_WITHIN;
    return SQLITE_OK;
  }
  double score;
  const rs_within w = rs_ray_box_test(o, d, r, t0, t1, 0, box, &score);
  p->eWithin = w == RS_NOT_WITHIN ? NOT_WITHIN : w == RS_FULLY_WITHIN ? FULLY_WITHIN : PARTLY_WITHIN;
  p->rScore = std::max(0.0, score);
  return SQLITE_OK;
}

int plane_prune(sqlite3_rtree_query_info* p) {
  static const char* const names[6] = {"px", "py", "pz", "nx", "ny", "nz"};
  double box[6];
  char err[RS_ERRBUF];
  if (!checked(p)) {
    if (p->nCoord != 6)
      return prune_fail(p, "plane_prune: the R*Tree is not 3-dimensional; expected `rayscan db import`'s "
                           "chunks(id, min_x, max_x, ...)");
    if (const char* e = check_prune_params(p, "plane_prune", names, 6, 6, 6, err)) return prune_fail(p, e);
    if (const char* e = rs_check_plane("plane_prune", p->aParam, p->aParam + 3, err)) return prune_fail(p, e);
    mark_checked(p);
  }
  rtree_box(p, box);
  const double o[3] = {p->aParam[0], p->aParam[1], p->aParam[2]};
  const double n[3] = {p->aParam[3], p->aParam[4], p->aParam[5]};
  const rs_within w = rs_plane_box_test(o, n, box);
  p->eWithin = w == RS_NOT_WITHIN ? NOT_WITHIN : w == RS_FULLY_WITHIN ? FULLY_WITHIN : PARTLY_WITHIN;
  // Keep R*Tree order (the parent's score); planes give no "nearest" key.
  p->rScore = p->rParentScore;
  return SQLITE_OK;
}

// ---- ray_query table-valued function -----------------------------------------------------------

enum Col {
  kPointIndex, kSource, kX, kY, kZ, kT, kDistance, kRank,
  kOx, kOy, kOz, kDx, kDy, kDz, kK, kR, kTMin, kTMax, kOrd, kNumCols
};
constexpr int kFirstArg = kOx;
constexpr int kNumArgs = kNumCols - kOx;
constexpr const char* kArgNames[kNumArgs] = {"ox", "oy", "oz", "dx", "dy", "dz", "k", "r", "t_min", "t_max", "ord"};

struct Hit {
  double key, t, d2;
  long long point_index, source;
  double x, y, z;
};
bool hit_less(const Hit& a, const Hit& b) {
  if (a.key != b.key) return a.key < b.key;
  if (a.source != b.source) return a.source < b.source;
  return a.point_index < b.point_index;
}

// Statements ray_query runs, prepared once per connection (preparing costs more than a whole
// small query; bench/README.md) and finalized in xDisconnect.
struct Cached {
  sqlite3_stmt* match = nullptr;   // R*Tree candidates with ray_prune
  sqlite3_stmt* blob = nullptr;    // chunk_points.data of one chunk (NULL: table absent)
  sqlite3_stmt* rows = nullptr;    // points rows of one chunk (databases without chunk_points)
  long long chunks_total = -1;     // rows of `chunks`
  void clear() {
    sqlite3_finalize(match);
    sqlite3_finalize(blob);
    sqlite3_finalize(rows);
    *this = Cached{};
  }
};

struct VTab {
  sqlite3_vtab base{};
  sqlite3* db = nullptr;
  Stats* stats = nullptr;
  Cached st;
  bool ready = false;
};

struct Cursor {
  sqlite3_vtab_cursor base{};
  std::vector<Hit> hits;
  std::size_t pos = 0;
  /// The arguments of the current xFilter as given (by kArgNames; nullptr: not given), what every
  /// row's hidden columns read, as SQLite's own table-valued functions (generate_series) return
  /// theirs.
  sqlite3_value* args[kNumArgs] = {};
  void clear_args() {
    for (sqlite3_value*& v : args) {
      sqlite3_value_free(v);
      v = nullptr;
    }
  }
};

int vt_connect(sqlite3* db, void* aux, int, const char* const*, sqlite3_vtab** out, char**) {
  const int rc = sqlite3_declare_vtab(
      db, "CREATE TABLE x(point_index INTEGER, source INTEGER, x REAL, y REAL, z REAL, t REAL, "
          "distance REAL, rank INTEGER, ox HIDDEN, oy HIDDEN, oz HIDDEN, dx HIDDEN, dy HIDDEN, "
          "dz HIDDEN, k HIDDEN, r HIDDEN, t_min HIDDEN, t_max HIDDEN, ord HIDDEN)");
  if (rc != SQLITE_OK) return rc;
  auto* v = new VTab;
  v->db = db;
  v->stats = &static_cast<Conn*>(aux)->stats;
  *out = &v->base;
  sqlite3_vtab_config(db, SQLITE_VTAB_INNOCUOUS);
  return SQLITE_OK;
}

int vt_disconnect(sqlite3_vtab* v) {
  reinterpret_cast<VTab*>(v)->st.clear();
  delete reinterpret_cast<VTab*>(v);
  return SQLITE_OK;
}

// Sets the vtab's error message (SQLite reports it for the statement); returns SQLITE_ERROR.
int vt_error(sqlite3_vtab* v, const std::string& msg) {
  sqlite3_free(v->zErrMsg);
  v->zErrMsg = sqlite3_mprintf("%s", msg.c_str());
  return SQLITE_ERROR;
}

// idxNum: bit a (< kNumArgs) is set when argument a (kArgNames) is an xFilter argument; these two
// when the query's LIMIT and OFFSET follow the arguments, in that order.
constexpr int kArgMask = (1 << kNumArgs) - 1;
constexpr int kLimitBit = 1 << kNumArgs;
constexpr int kOffsetBit = 1 << (kNumArgs + 1);

/// The key ray_query orders its rows by, as far as the plan can tell: the column of the ord
/// argument's key (kDistance for 'ray', absent or NULL; kT for 'time'), or -1 when its value is
/// not known before xFilter (a bound parameter, an expression) or is not one of those.
int planned_key_column(sqlite3_index_info* info, int ord_constraint) {
  if (ord_constraint < 0) return kDistance;
  // sqlite3_vtab_rhs_value: SQLite 3.38 and later (older ones pass no LIMIT either).
  sqlite3_value* v = nullptr;
  if (sqlite3_libversion_number() < 3038000 || sqlite3_vtab_rhs_value(info, ord_constraint, &v) != SQLITE_OK || !v)
    return -1;
  if (sqlite3_value_type(v) == SQLITE_NULL) return kDistance;
  const char* s = reinterpret_cast<const char*>(sqlite3_value_text(v));
  if (sqlite3_value_type(v) != SQLITE_TEXT || !s) return -1;
  return std::strcmp(s, "ray") == 0 ? kDistance : std::strcmp(s, "time") == 0 ? kT : -1;
}

/// Whether the rows already come out in the ORDER BY's order. They are sorted by (key, source,
/// point_index) (hit_less), and rank counts them in that order, so an ascending ORDER BY rank, or
/// one that starts as that sequence, is consumed; (source, point_index) and rank are unique, so
/// terms after them change nothing. `key`: planned_key_column.
bool order_by_consumed(const sqlite3_index_info* info, int key) {
  const int sequence[3] = {key, kSource, kPointIndex};
  for (int i = 0; i < info->nOrderBy; ++i) {
    const auto& o = info->aOrderBy[i];
    if (o.desc) return false;
    if (i == 0 && o.iColumn == kRank) return true;
    if (sequence[i] < 0 || o.iColumn != sequence[i]) return false;
    if (i == 2) return true;
  }
  return true;
}

// Every usable equality constraint on a hidden argument column becomes an xFilter argument; any
// other condition on one is an error (a range gives the argument no value to run with, and the
// column of an argument not given reads NULL, which would silently match no row). The query's LIMIT (+ OFFSET) becomes one too when no row can be dropped or reordered after
// ray_query returns it: no condition on a result column and no ORDER BY other than the rows' own
// order (SQLite 3.40 offers LIMIT in both cases). It bounds the hits kept (a k), while SQLite
// still applies it (omit 0). idxNum: the bits above.
int vt_best_index(sqlite3_vtab* tab, sqlite3_index_info* info) {
  int slot[kNumArgs];
  std::fill(slot, slot + kNumArgs, -1);
  int limit = -1, offset = -1;
  bool row_condition = false;  // a condition SQLite checks on the rows ray_query returns
  for (int i = 0; i < info->nConstraint; ++i) {
    const auto& c = info->aConstraint[i];
    if (c.op == SQLITE_INDEX_CONSTRAINT_LIMIT || c.op == SQLITE_INDEX_CONSTRAINT_OFFSET) {
      if (c.usable) (c.op == SQLITE_INDEX_CONSTRAINT_LIMIT ? limit : offset) = i;
      continue;
    }
    if (c.iColumn < kFirstArg) {
      row_condition = true;
      continue;
    }
    const char* name = kArgNames[c.iColumn - kFirstArg];
    if (c.op != SQLITE_INDEX_CONSTRAINT_EQ)
      return vt_error(tab, std::string("ray_query: ") + name + " must be given as an argument (or " + name +
                               " = value); expected no other condition on it");
    if (!c.usable) return SQLITE_CONSTRAINT;  // arguments must be available: ask for another plan
    slot[c.iColumn - kFirstArg] = i;
  }
  int mask = 0, argv = 0;
  for (int a = 0; a < kNumArgs; ++a)
    if (slot[a] >= 0) {
      mask |= 1 << a;
      info->aConstraintUsage[slot[a]].argvIndex = ++argv;
      info->aConstraintUsage[slot[a]].omit = 1;
    }
  const bool ordered = info->nOrderBy > 0 && order_by_consumed(info, planned_key_column(info, slot[kOrd - kFirstArg]));
  if (ordered) info->orderByConsumed = 1;
  if (limit >= 0 && !row_condition && (info->nOrderBy == 0 || ordered)) {
    mask |= kLimitBit;
    info->aConstraintUsage[limit].argvIndex = ++argv;
    if (offset >= 0) {
      mask |= kOffsetBit;
      info->aConstraintUsage[offset].argvIndex = ++argv;
    }
  }
  info->idxNum = mask;
  info->estimatedCost = 1000;
  return SQLITE_OK;
}

int vt_open(sqlite3_vtab*, sqlite3_vtab_cursor** out) {
  auto* c = new Cursor;
  *out = &c->base;
  return SQLITE_OK;
}
int vt_close(sqlite3_vtab_cursor* c) {
  reinterpret_cast<Cursor*>(c)->clear_args();
  delete reinterpret_cast<Cursor*>(c);
  return SQLITE_OK;
}

struct Stmt {
  sqlite3_stmt* s = nullptr;
  ~Stmt() { sqlite3_finalize(s); }
};

// Prepares the cached statements on first use (kept only when all succeed, so a database that
// gains its tables later is picked up). chunk_points is optional (older imports): rows then.
int prepare(VTab* vt) {
  if (vt->ready) return SQLITE_OK;
  Cached& c = vt->st;
  c.clear();
  {
    Stmt s;
    if (sqlite3_prepare_v2(vt->db, "SELECT count(*) FROM main.chunks", -1, &s.s, nullptr) != SQLITE_OK)
      return vt_error(&vt->base, std::string("ray_query: the database has no chunk index (R*Tree "
                                             "'chunks'): import it with `rayscan db import` (") +
                                     sqlite3_errmsg(vt->db) + ")");
    const int rc = sqlite3_step(s.s);
    if (rc != SQLITE_ROW)
      return vt_error(&vt->base, std::string("ray_query: reading the chunk index: ") + sqlite3_errmsg(vt->db));
    c.chunks_total = sqlite3_column_int64(s.s, 0);
  }
  if (sqlite3_prepare_v2(vt->db, "SELECT data FROM main.chunk_points WHERE id = ?1", -1, &c.blob, nullptr) != SQLITE_OK) {
    sqlite3_finalize(c.blob);
    c.blob = nullptr;
    if (sqlite3_prepare_v2(vt->db, "SELECT point_index, source, x, y, z FROM main.points WHERE rowid BETWEEN ?1 AND ?2",
                           -1, &c.rows, nullptr) != SQLITE_OK) {
      const std::string e = sqlite3_errmsg(vt->db);
      c.clear();
      return vt_error(&vt->base, "ray_query: cannot read table 'points': " + e);
    }
  }
  // With chunk_points the R*Tree's auxiliary columns (first_row, count) are not read: reading them
  // makes the R*Tree prepare an internal statement on every query (~8% of a query's instructions;
  // bench/README.md, "SQL ray queries"); a chunk's count is its BLOB's size / 40.
  const std::string match = std::string("SELECT min_x, min_y, min_z, max_x, max_y, max_z, id, ") +
                            (c.blob ? "0, 0" : "first_row, count") +
                            " FROM main.chunks WHERE id MATCH ray_prune(?1,?2,?3,?4,?5,?6,?7,?8,?9)";
  if (sqlite3_prepare_v2(vt->db, match.c_str(), -1, &c.match, nullptr) != SQLITE_OK) {
    const std::string e = sqlite3_errmsg(vt->db);
    c.clear();
    return vt_error(&vt->base, "ray_query: cannot read the chunk index: " + e);
  }
  vt->ready = true;
  return SQLITE_OK;
}

/// ray_query's arguments (kOx .. kOrd), checked: defaults for absent or NULL optional ones (k all
/// points, r inf, t_min -inf, t_max inf, ord 'ray').
struct Args {
  double a[kNumArgs] = {0, 0, 0, 0, 0, 0, -1, kInf, -kInf, kInf, 0};  ///< by kArgNames
  double o3[3] = {}, d3[3] = {};  ///< ray origin and direction (world units; d not unit length)
  double r = kInf, t_min = -kInf, t_max = kInf;
  bool time_order = false;   ///< ord 'time': kNN along the ray (else kNN to the ray)
  bool bounded = false;      ///< k or a LIMIT given: keep the k best hits (else every hit)
  std::size_t k = std::size_t(-1);
  bool null_ray = false;     ///< a ray argument is NULL: no rows (NULL in, NULL out)
};

/// Reads xFilter's arguments (present ones flagged in `mask`, vt_best_index) into `out`, in
/// argument order so that the first bad argument is the one reported; k becomes the smaller of k
/// and the query's LIMIT + OFFSET when the plan passed them. Returns SQLITE_OK, or
/// SQLITE_ERROR with the vtab's error message set: a missing ray argument, a non-number, k not an
/// integer >= 0, ord not 'ray'/'time', or a ray rs_check_ray rejects. Each argument read is also
/// copied into keep[i] (sqlite3_value_dup; the hidden columns' values), SQLITE_NOMEM when a copy
/// cannot be made; reading stops at an error or a NULL ray argument, which give no row.
int parse_ray_query_args(VTab* vt, int mask, int argc, sqlite3_value** argv, Args& out,
                         sqlite3_value* (&keep)[kNumArgs]) {
  double* a = out.a;
  long long kval = -1;  // -1: k not set (all points)
  int ai = 0;
  // The six ray arguments are required, NULL or not: ray_query(ox,oy,oz, dx,dy) must report dz as
  // missing rather than run with dz = 0, and ray_query(1, NULL) is an error, not "NULL in, no rows".
  for (int i = 0; i < 6; ++i)
    if (!(mask & (1 << i)))
      return vt_error(&vt->base, std::string("ray_query: argument ") + kArgNames[i] +
                                     " is missing; expected ray_query(ox,oy,oz, dx,dy,dz [, k, r, t_min, "
                                     "t_max, ord])");
  for (int i = 0; i < kNumArgs && ai < argc; ++i) {
    if (!(mask & (1 << i))) continue;
    sqlite3_value* v = argv[ai++];
    if (!(keep[i] = sqlite3_value_dup(v))) return SQLITE_NOMEM;
    const int t = sqlite3_value_type(v);
    if (t == SQLITE_NULL) {
      if (i < 6) {
        out.null_ray = true;
        return SQLITE_OK;
      }
      continue;
    }
    if (i == kOrd - kFirstArg) {
      const char* s = reinterpret_cast<const char*>(sqlite3_value_text(v));
      if (t != SQLITE_TEXT || !s || (std::strcmp(s, "ray") && std::strcmp(s, "time")))
        return vt_error(&vt->base, "ray_query: ord must be 'ray' (kNN to the ray) or 'time' "
                                   "(kNN along the ray)");
      out.time_order = std::strcmp(s, "time") == 0;
      continue;
    }
    if (t != SQLITE_INTEGER && t != SQLITE_FLOAT)
      return vt_error(&vt->base, std::string("ray_query: argument ") + kArgNames[i] + " has type " +
                                     type_name(t) + "; expected a number");
    a[i] = sqlite3_value_double(v);
    if (i == kK - kFirstArg) {
      if (t != SQLITE_INTEGER || sqlite3_value_int64(v) < 0)
        return vt_error(&vt->base, "ray_query: k must be an integer >= 0 (NULL: all points)");
      kval = sqlite3_value_int64(v);
    }
  }
  // The query's LIMIT and OFFSET (vt_best_index): SQLite returns no row past LIMIT + OFFSET, so
  // only that many hits need be kept. As SQLite reads them: a negative LIMIT is none, a negative
  // OFFSET is 0.
  if (mask & kLimitBit) {
    const int at = __builtin_popcount(static_cast<unsigned>(mask & kArgMask));
    const auto count = [&](int i) -> long long {
      const bool integer = i < argc && sqlite3_value_type(argv[i]) == SQLITE_INTEGER;
      return integer ? sqlite3_value_int64(argv[i]) : -1;
    };
    const long long limit = count(at), skip = mask & kOffsetBit ? std::max(0LL, count(at + 1)) : 0;
    if (limit >= 0) {
      constexpr long long kMax = std::numeric_limits<long long>::max();
      const long long rows = limit > kMax - skip ? kMax : limit + skip;
      if (kval < 0 || rows < kval) kval = rows;
    }
  }
  for (int i = 0; i < 3; ++i) out.o3[i] = a[i], out.d3[i] = a[i + 3];
  out.r = a[7], out.t_min = a[8], out.t_max = a[9];
  char err[RS_ERRBUF];
  if (const char* e = rs_check_ray("ray_query", out.o3, out.d3, out.r, out.t_min, out.t_max, err))
    return vt_error(&vt->base, e);
  out.bounded = kval >= 0;
  out.k = out.bounded ? static_cast<std::size_t>(kval) : std::size_t(-1);
  return SQLITE_OK;
}

/// The hits kept so far: with k (bounded) a max-heap under hit_less of the k best, the worst on
/// top; without k every hit, unordered.
struct HitHeap {
  std::vector<Hit>& heap;
  const bool bounded;
  const std::size_t k;
  const bool time_order;  ///< key: t (ord 'time') or the distance to the ray
  double worst = kInf;    ///< key of the k-th best hit once there are k; else inf

  /// Offers a point that passed the per-point test. Out of line: few points get here, and the
  /// caller's per-point loop stays small.
  __attribute__((noinline)) void keep(const rayscan::RayPointTerms& pt, double x, double y, double z,
                                      long long point_index, long long source) {
    const Hit h{time_order ? pt.t : std::sqrt(pt.d2), pt.t, pt.d2, point_index, source, x, y, z};
    if (!bounded) {
      heap.push_back(h);
    } else if (heap.size() < k) {
      heap.push_back(h);
      std::push_heap(heap.begin(), heap.end(), hit_less);
    } else if (hit_less(h, heap.front())) {
      std::pop_heap(heap.begin(), heap.end(), hit_less);
      heap.back() = h;
      std::push_heap(heap.begin(), heap.end(), hit_less);
    }
    if (bounded && heap.size() == k) worst = heap.front().key;
  }
  /// The dynamic k filter (Algorithm 1, step 2): with k hits, a chunk whose bound `score`
  /// exceeds the worst key by more than its tolerance cannot improve them.
  [[nodiscard]] bool rejects(double score, double tol) const {
    return bounded && heap.size() == k && score > worst + tol;
  }
};

/// A chunk the R*Tree admitted: its bound (rScore recomputed for the query's order) and
/// tolerance, id, and first row and point count (databases without chunk_points).
struct Cand {
  double score, tol;
  long long id, first, count;
};

/// One ray_query evaluation over the chunks: the core's per-point terms (ray_point_terms) on the
/// unit direction of the core Ray, the candidate rule and keys of rayscan::ray_query (orders ray
/// and time). Hits go to `hits`, counters to `st`.
struct RayQuery {
  VTab* vt;
  const Args& args;
  Stats st;
  Vec3 ro, rd;  ///< origin and unit direction of the core Ray
  double r2;    ///< radius squared
  HitHeap heap;

  RayQuery(VTab* v, const Args& a, std::vector<Hit>& hits)
      : vt(v), args(a), r2(a.r * a.r), heap{hits, a.bounded, a.k, a.time_order} {
    const rayscan::Ray ray(Vec3(a.a[0], a.a[1], a.a[2]), Vec3(a.a[3], a.a[4], a.a[5]));
    ro = ray.origin();
    rd = ray.direction();
    st.chunks_total = vt->st.chunks_total;
  }

  /// The per-point test: within radius r of the ray and t in [t_min, t_max].
  __attribute__((always_inline)) void consider(double x, double y, double z, long long point_index,
                                               long long source) {
    const rayscan::RayPointTerms pt = rayscan::ray_point_terms(ro, rd, Vec3(x, y, z));
    if (pt.d2 > r2 || pt.t < args.t_min || pt.t > args.t_max) return;
    heap.keep(pt, x, y, z, point_index, source);
  }

  /// Reads one chunk's points: the packed BLOB when the database has chunk_points, else its rows.
  /// Returns SQLITE_OK, or an error with the vtab's message set (a BLOB that is not a whole
  /// number of 40-byte points, a missing row, an SQLite error).
  int read_chunk(const Cand& ch) {
    ++st.chunks_visited;
    if (sqlite3_stmt* b = vt->st.blob) {
      // Packed chunk (rayscan/sql/chunking.hpp PackedPoint): one lookup, then a tight loop.
      constexpr std::size_t kPoint = sizeof(rayscan::sql::PackedPoint);
      sqlite3_bind_int64(b, 1, ch.id);
      const int rc = sqlite3_step(b);
      const auto* data = static_cast<const unsigned char*>(sqlite3_column_blob(b, 0));
      const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(b, 0));
      if (rc != SQLITE_ROW || bytes % kPoint != 0 || (bytes && !data)) {
        const std::string msg = rc == SQLITE_ROW || rc == SQLITE_DONE
                                    ? "chunk " + std::to_string(ch.id) + ": chunk_points has " +
                                          (rc == SQLITE_ROW ? std::to_string(bytes) + " bytes" : "no row") +
                                          "; expected a whole number of 40-byte points (corrupted database?)"
                                    : std::string(sqlite3_errmsg(vt->db));
        sqlite3_reset(b);
        return vt_error(&vt->base, "ray_query: reading table 'chunk_points': " + msg);
      }
      const std::size_t count = bytes / kPoint;
      st.points_tested += static_cast<long long>(count);
      for (std::size_t i = 0; i < count; ++i) {
        rayscan::sql::PackedPoint p;
        std::memcpy(&p, data + i * kPoint, kPoint);
        consider(p.x, p.y, p.z, p.point_index, p.source);
      }
      sqlite3_reset(b);
      return SQLITE_OK;
    }
    st.points_tested += ch.count;
    sqlite3_stmt* pts = vt->st.rows;
    sqlite3_bind_int64(pts, 1, ch.first);
    sqlite3_bind_int64(pts, 2, ch.first + ch.count - 1);
    int rc;
    while ((rc = sqlite3_step(pts)) == SQLITE_ROW)
      consider(sqlite3_column_double(pts, 2), sqlite3_column_double(pts, 3), sqlite3_column_double(pts, 4),
               sqlite3_column_int64(pts, 0), sqlite3_column_int64(pts, 1));
    sqlite3_reset(pts);
    if (rc != SQLITE_DONE)
      return vt_error(&vt->base, std::string("ray_query: reading table 'points': ") + sqlite3_errmsg(vt->db));
    return SQLITE_OK;
  }

  /// Chunk candidates from the R*Tree with the pruning callback. Its rScore (the lower bound of
  /// dist_ray) makes the R*Tree return chunks nearest first from a priority queue
  /// (sqlite.org/rtree.html section 7.3), so kNN to the ray reads them as they come and stops
  /// at the first chunk the dynamic k filter rejects: the R*Tree never expands the far nodes.
  /// kNN along the ray (ord 'time') has another key: its candidates go to `later`, unread.
  /// Returns SQLITE_OK or an error with the vtab's message set.
  int candidate_chunks(std::vector<Cand>& later) {
    const Args& q = args;
    const std::size_t k = q.k;
    sqlite3_stmt* s = vt->st.match;
    for (int i = 0; i < 6; ++i) sqlite3_bind_double(s, i + 1, q.a[i]);
    sqlite3_bind_double(s, 7, q.r);
    sqlite3_bind_double(s, 8, q.t_min);
    sqlite3_bind_double(s, 9, q.t_max);
    const Vec3 o(q.a[0], q.a[1], q.a[2]);
    int rc = SQLITE_DONE;
    while (k != 0 && (rc = sqlite3_step(s)) == SQLITE_ROW) {
      double box[6];
      for (int i = 0; i < 6; ++i) box[i] = sqlite3_column_double(s, i);
      double score;
      rs_ray_box_test(q.o3, q.d3, q.r, q.t_min, q.t_max, q.time_order, box, &score);
      const rayscan::AABB b{Vec3(box[0], box[1], box[2]), Vec3(box[3], box[4], box[5])};
      const double tol = rayscan::node_test_tolerance(o, b);
      const Cand ch{score, tol, sqlite3_column_int64(s, 6), sqlite3_column_int64(s, 7), sqlite3_column_int64(s, 8)};
      ++st.chunks_candidate;
      if (q.time_order) {
        later.push_back(ch);
        continue;
      }
      if (heap.rejects(ch.score, ch.tol)) {
        rc = SQLITE_DONE;
        break;
      }
      if (const int e = read_chunk(ch); e != SQLITE_OK) {
        sqlite3_reset(s);
        return e;
      }
    }
    sqlite3_reset(s);
    if (rc != SQLITE_DONE)
      return vt_error(&vt->base, std::string("ray_query: reading the chunk index: ") + sqlite3_errmsg(vt->db));
    return SQLITE_OK;
  }

  /// Reads the chunks candidate_chunks() set aside (ord 'time'), lowest time bound first, until
  /// the dynamic k filter rejects one.
  int read_in_order(std::vector<Cand>& cands) {
    std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) { return x.score < y.score; });
    for (const Cand& ch : cands) {
      if (heap.rejects(ch.score, ch.tol)) break;
      if (const int e = read_chunk(ch); e != SQLITE_OK) return e;
    }
    return SQLITE_OK;
  }
};

int vt_filter(sqlite3_vtab_cursor* cur, int mask, const char*, int argc, sqlite3_value** argv) {
  auto* c = reinterpret_cast<Cursor*>(cur);
  auto* vt = reinterpret_cast<VTab*>(cur->pVtab);
  c->hits.clear();
  c->pos = 0;
  c->clear_args();
  Args args;
  if (const int rc = parse_ray_query_args(vt, mask, argc, argv, args, c->args); rc != SQLITE_OK || args.null_ray)
    return rc;
  if (const int rc = prepare(vt); rc != SQLITE_OK) return rc;
  RayQuery q(vt, args, c->hits);
  std::vector<Cand> cands;
  if (const int rc = q.candidate_chunks(cands); rc != SQLITE_OK) return rc;
  if (const int rc = q.read_in_order(cands); rc != SQLITE_OK) return rc;
  std::sort(c->hits.begin(), c->hits.end(), hit_less);
  *vt->stats = q.st;
  return SQLITE_OK;
}

int vt_next(sqlite3_vtab_cursor* cur) {
  ++reinterpret_cast<Cursor*>(cur)->pos;
  return SQLITE_OK;
}
int vt_eof(sqlite3_vtab_cursor* cur) {
  auto* c = reinterpret_cast<Cursor*>(cur);
  return c->pos >= c->hits.size();
}
int vt_column(sqlite3_vtab_cursor* cur, sqlite3_context* ctx, int col) {
  auto* c = reinterpret_cast<Cursor*>(cur);
  const Hit& h = c->hits[c->pos];
  switch (col) {
    case kPointIndex: sqlite3_result_int64(ctx, h.point_index); break;
    case kSource: sqlite3_result_int64(ctx, h.source); break;
    case kX: sqlite3_result_double(ctx, h.x); break;
    case kY: sqlite3_result_double(ctx, h.y); break;
    case kZ: sqlite3_result_double(ctx, h.z); break;
    case kT: sqlite3_result_double(ctx, h.t); break;
    case kDistance: sqlite3_result_double(ctx, std::sqrt(h.d2)); break;
    case kRank: sqlite3_result_int64(ctx, static_cast<sqlite3_int64>(c->pos)); break;
    default:  // hidden argument columns: the value given, NULL for one not given
      if (col >= kFirstArg && c->args[col - kFirstArg]) sqlite3_result_value(ctx, c->args[col - kFirstArg]);
      else sqlite3_result_null(ctx);
      break;
  }
  return SQLITE_OK;
}
int vt_rowid(sqlite3_vtab_cursor* cur, sqlite_int64* rowid) {
  *rowid = static_cast<sqlite_int64>(reinterpret_cast<Cursor*>(cur)->pos);
  return SQLITE_OK;
}

sqlite3_module make_module() {
  sqlite3_module m{};
  m.iVersion = 0;
  m.xCreate = nullptr;  // eponymous-only: a table-valued function, never CREATE VIRTUAL TABLE
  m.xConnect = vt_connect;
  m.xBestIndex = vt_best_index;
  m.xDisconnect = vt_disconnect;
  m.xDestroy = vt_disconnect;
  m.xOpen = vt_open;
  m.xClose = vt_close;
  m.xFilter = vt_filter;
  m.xNext = vt_next;
  m.xEof = vt_eof;
  m.xColumn = vt_column;
  m.xRowid = vt_rowid;
  return m;
}
const sqlite3_module kModule = make_module();

// rayscan_error(): why the connection's most recent ray_prune / plane_prune check failed (SQLite
// reports only "SQL logic error" for it), or NULL when none has or a later one passed.
void error_fn(sqlite3_context* ctx, int, sqlite3_value**) {
  const Conn* c = static_cast<const Conn*>(sqlite3_user_data(ctx));
  if (c->prune_error.empty()) return sqlite3_result_null(ctx);
  sqlite3_result_text(ctx, c->prune_error.c_str(), -1, SQLITE_TRANSIENT);
}

void stats_fn(sqlite3_context* ctx, int, sqlite3_value**) {
  const Stats* s = static_cast<const Stats*>(sqlite3_user_data(ctx));
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "{\"chunks_total\":%lld,\"chunks_candidate\":%lld,\"chunks_visited\":%lld,"
                "\"points_tested\":%lld}",
                s->chunks_total, s->chunks_candidate, s->chunks_visited, s->points_tested);
  sqlite3_result_text(ctx, buf, -1, SQLITE_TRANSIENT);
}

}  // namespace

namespace {
// The registration behind both entry points; internal, so that another build of this library
// loaded into the same process (SQLite dlopens with RTLD_GLOBAL) cannot interpose it.
int init_rayscan(sqlite3* db, char** err, const sqlite3_api_routines* api) {
  SQLITE_EXTENSION_INIT2(api);
  const int flags = SQLITE_UTF8 | SQLITE_DETERMINISTIC | SQLITE_INNOCUOUS;
  int rc = SQLITE_OK;
  for (int f = RS_DIST_RAY; f <= RS_DIST_PLANE && rc == SQLITE_OK; ++f) {
    void* ud = reinterpret_cast<void*>(static_cast<std::intptr_t>(f));
    const std::string name = rs_function_name(static_cast<rs_function>(f));
    rc = sqlite3_create_function(db, name.c_str(), 9, flags, ud, point_fn, nullptr, nullptr);
    if (rc == SQLITE_OK)
      rc = sqlite3_create_function(db, (name + "_min").c_str(), 12, flags, ud, bounds_fn<false>, nullptr, nullptr);
    if (rc == SQLITE_OK)
      rc = sqlite3_create_function(db, (name + "_max").c_str(), 12, flags, ud, bounds_fn<true>, nullptr, nullptr);
  }
  auto* conn = new Conn;
  if (rc == SQLITE_OK)
    rc = sqlite3_create_module_v2(db, "ray_query", &kModule, conn, [](void* p) { delete static_cast<Conn*>(p); });
  else
    delete conn;
  if (rc == SQLITE_OK)
    rc = sqlite3_create_function(db, "rayscan_stats", 0, SQLITE_UTF8, &conn->stats, stats_fn, nullptr, nullptr);
  if (rc == SQLITE_OK)
    rc = sqlite3_create_function(db, "rayscan_error", 0, SQLITE_UTF8, conn, error_fn, nullptr, nullptr);
  // The R*Tree callbacks live in libsqlite3 itself (not in the extension API table): this library
  // links libsqlite3.so.0, as the Debian sqlite3 shell and Python's sqlite3 module do. They share
  // the connection's state (its lifetime is the module's: until the connection closes).
  if (rc == SQLITE_OK) rc = sqlite3_rtree_query_callback(db, "ray_prune", ray_prune, conn, nullptr);
  if (rc == SQLITE_OK) rc = sqlite3_rtree_query_callback(db, "plane_prune", plane_prune, conn, nullptr);
  if (rc != SQLITE_OK && err) *err = sqlite3_mprintf("rayscan_sqlite: registration failed: %s", sqlite3_errmsg(db));
  return rc;
}
}  // namespace

/// Entry point (SQLite derives "sqlite3_rayscansqlite_init" from the file name rayscan_sqlite.so).
/// Returns an SQLite error code with *err set when a registration fails.
extern "C" __attribute__((visibility("default"))) int sqlite3_rayscansqlite_init(
    sqlite3* db, char** err, const sqlite3_api_routines* api) {
  return init_rayscan(db, err, api);
}

/// Generic entry point name, for hosts that call sqlite3_extension_init.
extern "C" __attribute__((visibility("default"))) int sqlite3_extension_init(
    sqlite3* db, char** err, const sqlite3_api_routines* api) {
  return init_rayscan(db, err, api);
}
