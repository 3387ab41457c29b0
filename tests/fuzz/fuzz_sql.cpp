// libFuzzer target for the argument parsing of the SQL functions (docs/sql.md): the SQLite
// extension's functions called with arguments decoded from the input, on a small in-memory site
// (an R*Tree of chunk boxes, packed chunks), and the PostgreSQL types' text input
// (rs_parse_tuple, shared with sql/postgres). A call must either succeed or fail with one
// non-empty line; a successful call on finite arguments of moderate size returns finite numbers
// (a value the rules let through must be a right one: a direction that passes the check and gives
// NaN is a bug); ray_prune / plane_prune, whose failures SQLite reports as "SQL logic error", must
// leave their reason in rayscan_error(). ASan and UBSan check the rest.
//
// Input: the first line names the call (dist_ray, ray_time, dist_plane, their _min / _max,
// ray_query, ray_prune, plane_prune, rs_box, rs_ray, rs_plane); for rs_* the rest is the text
// given to the type's input; otherwise each further line is one argument: NULL, 'text, x'<bytes>
// (a blob of the raw bytes), an integer, a number as strtod reads it, or else text. At most 16.
// Built and run by tests/fuzz/run.sh (seeds there, dictionary sql.dict).
#include "rayscan/sql/functions.h"

#include <sqlite3.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

extern "C" int sqlite3_rayscansqlite_init(sqlite3* db, char** err, const sqlite3_api_routines* api);

namespace {

[[noreturn]] void bug(const std::string& what) {
  std::fprintf(stderr, "fuzz_sql: %s\n", what.c_str());
  std::abort();
}

/// The in-memory site: 64 points on a grid in 8 chunks, imported as `rayscan db import` lays them
/// out (R*Tree chunks with first_row and count, chunk_points BLOBs, points rows).
sqlite3* database() {
  static sqlite3* db = [] {
    sqlite3_auto_extension(reinterpret_cast<void (*)()>(sqlite3_rayscansqlite_init));
    sqlite3* d = nullptr;
    if (sqlite3_open(":memory:", &d) != SQLITE_OK) bug("cannot open an in-memory database");
    const char* schema =
        "CREATE TABLE points(point_index INTEGER, source INTEGER, chunk INTEGER, x REAL, y REAL, z REAL);"
        "CREATE VIRTUAL TABLE chunks USING rtree(id, min_x, max_x, min_y, max_y, min_z, max_z, "
        "+first_row INTEGER, +count INTEGER);"
        "CREATE TABLE chunk_points(id INTEGER PRIMARY KEY, data BLOB NOT NULL);";
    if (sqlite3_exec(d, schema, nullptr, nullptr, nullptr) != SQLITE_OK) bug(sqlite3_errmsg(d));
    for (int c = 0; c < 8; ++c) {
      std::string blob;
      for (int i = 0; i < 8; ++i) {
        const std::int64_t index = c * 8 + i, source = 0;
        const double p[3] = {double(c), double(i), 0.25 * (i % 3)};
        blob.append(reinterpret_cast<const char*>(p), sizeof p);
        blob.append(reinterpret_cast<const char*>(&index), 8);
        blob.append(reinterpret_cast<const char*>(&source), 8);
        const std::string row = "INSERT INTO points VALUES(" + std::to_string(index) + ",0," +
                                std::to_string(c) + "," + std::to_string(p[0]) + "," +
                                std::to_string(p[1]) + "," + std::to_string(p[2]) + ")";
        sqlite3_exec(d, row.c_str(), nullptr, nullptr, nullptr);
      }
      const std::string box = "INSERT INTO chunks VALUES(" + std::to_string(c) + "," + std::to_string(c) +
                              "," + std::to_string(c) + ",0,7,0,0.5," + std::to_string(c * 8 + 1) + ",8)";
      sqlite3_exec(d, box.c_str(), nullptr, nullptr, nullptr);
      sqlite3_stmt* s = nullptr;
      sqlite3_prepare_v2(d, "INSERT INTO chunk_points VALUES(?1, ?2)", -1, &s, nullptr);
      sqlite3_bind_int(s, 1, c);
      sqlite3_bind_blob(s, 2, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
      if (sqlite3_step(s) != SQLITE_DONE) bug(sqlite3_errmsg(d));
      sqlite3_finalize(s);
    }
    return d;
  }();
  return db;
}

struct Arg {
  int type;  // SQLITE_NULL, SQLITE_INTEGER, SQLITE_FLOAT, SQLITE_TEXT, SQLITE_BLOB
  long long i = 0;
  double d = 0;
  std::string s;
};

Arg decode(const std::string& t) {
  if (t == "NULL") return {SQLITE_NULL, 0, 0, {}};
  if (!t.empty() && t[0] == '\'') return {SQLITE_TEXT, 0, 0, t.substr(1)};
  if (t.size() >= 2 && t[0] == 'x' && t[1] == '\'') return {SQLITE_BLOB, 0, 0, t.substr(2)};
  long long i = 0;
  if (auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), i); ec == std::errc() && p == t.data() + t.size() && !t.empty())
    return {SQLITE_INTEGER, i, double(i), {}};
  char* end = nullptr;
  const double d = std::strtod(t.c_str(), &end);
  if (!t.empty() && end == t.c_str() + t.size()) return {SQLITE_FLOAT, 0, d, {}};
  return {SQLITE_TEXT, 0, 0, t};
}

/// Whether no numeric argument exceeds 1e100 in magnitude (and, with `all_numbers`, every
/// argument is a number). Finite results are required only then: squared distances of coordinates
/// beyond about 1e154 overflow in the core itself.
bool moderate(const std::vector<Arg>& args, bool all_numbers) {
  for (const Arg& a : args) {
    const bool number = a.type == SQLITE_INTEGER || a.type == SQLITE_FLOAT;
    if (!number && all_numbers) return false;
    if (number && !(std::fabs(a.d) <= 1e100)) return false;
  }
  return true;
}

void check_message(const std::string& call, const char* msg) {
  const std::string m = msg ? msg : "";
  if (m.empty()) bug(call + ": an error without a message");
  if (m.find('\n') != std::string::npos) bug(call + ": a message of several lines: " + m);
}

/// Runs `sql` with `args` bound; checks the outcome as the file's header says.
void run(const std::string& fn, const std::string& sql, const std::vector<Arg>& args, bool scalar) {
  sqlite3* db = database();
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &s, nullptr) != SQLITE_OK) {
    check_message(fn, sqlite3_errmsg(db));  // e.g. a wrong number of arguments
    sqlite3_finalize(s);
    return;
  }
  for (std::size_t i = 0; i < args.size(); ++i) {
    const Arg& a = args[i];
    const int k = static_cast<int>(i + 1);
    switch (a.type) {
      case SQLITE_NULL: sqlite3_bind_null(s, k); break;
      case SQLITE_INTEGER: sqlite3_bind_int64(s, k, a.i); break;
      case SQLITE_FLOAT: sqlite3_bind_double(s, k, a.d); break;
      case SQLITE_TEXT: sqlite3_bind_text(s, k, a.s.data(), static_cast<int>(a.s.size()), SQLITE_TRANSIENT); break;
      default: sqlite3_bind_blob(s, k, a.s.data(), static_cast<int>(a.s.size()), SQLITE_TRANSIENT); break;
    }
  }
  int rc, rows = 0;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    ++rows;
    for (int c = 0; c < sqlite3_column_count(s); ++c) {
      const int t = sqlite3_column_type(s, c);
      if (!scalar && moderate(args, false) && t == SQLITE_FLOAT && !std::isfinite(sqlite3_column_double(s, c)))
        bug(fn + ": a row with a non-finite column " + std::to_string(c));
      // A scalar function on moderate finite numbers: a finite number, never NULL (SQLite stores a
      // NaN result as NULL).
      if (scalar && moderate(args, true) && (t != SQLITE_FLOAT || !std::isfinite(sqlite3_column_double(s, c))))
        bug(fn + ": accepted arguments gave a non-finite result");
    }
  }
  if (rc != SQLITE_DONE) {
    check_message(fn, sqlite3_errmsg(db));
    if (fn == "ray_prune" || fn == "plane_prune") {
      sqlite3_stmt* e = nullptr;
      sqlite3_prepare_v2(db, "SELECT rayscan_error()", -1, &e, nullptr);
      const bool row = e && sqlite3_step(e) == SQLITE_ROW;
      const auto* text = row ? reinterpret_cast<const char*>(sqlite3_column_text(e, 0)) : nullptr;
      if (!text || std::strncmp(text, fn.c_str(), fn.size()) != 0)
        bug(fn + ": failed without its reason in rayscan_error()");
      check_message(fn, text);
      sqlite3_finalize(e);
    }
  }
  sqlite3_finalize(s);
  if (rows > 64 && fn == "ray_query") bug("ray_query: more rows than points");
  if (rc != SQLITE_DONE) return;
  // What the rules refuse must not succeed: ray_query without its six ray arguments (the absent
  // ones would be taken as 0), a text or blob argument to a prune callback (it would be read as a
  // number).
  if (fn == "ray_query" && args.size() < 6) bug("ray_query: succeeded with " + std::to_string(args.size()) + " arguments");
  if (fn == "ray_prune" || fn == "plane_prune")
    for (const Arg& a : args)
      if (a.type == SQLITE_TEXT || a.type == SQLITE_BLOB) bug(fn + ": succeeded with a text or blob argument");
}

std::string placeholders(std::size_t n) {
  std::string p;
  for (std::size_t i = 0; i < n; ++i) p += (i ? ",?" : "?") + std::to_string(i + 1);
  return p;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string in(reinterpret_cast<const char*>(data), size);
  const std::size_t nl = in.find('\n');
  const std::string fn = in.substr(0, nl);
  const std::string rest = nl == std::string::npos ? "" : in.substr(nl + 1);
  if (fn == "rs_box" || fn == "rs_ray" || fn == "rs_plane") {
    const int n = fn == "rs_ray" ? 9 : 6;
    double v[9];
    char err[RS_ERRBUF];
    const std::string text = rest.substr(0, rest.find('\0'));  // a cstring, as PostgreSQL passes it
    static const char* const names[9] = {"v1", "v2", "v3", "v4", "v5", "v6", "v7", "v8", "v9"};
    if (const char* e = rs_parse_tuple(text.c_str(), v, n, fn.c_str(), names, nullptr, err)) check_message(fn, e);
    return 0;
  }
  std::vector<Arg> args;
  for (std::size_t at = 0; at <= rest.size() && args.size() < 16 && !rest.empty();) {
    const std::size_t end = std::min(rest.find('\n', at), rest.size());
    args.push_back(decode(rest.substr(at, end - at)));
    at = end + 1;
  }
  static const char* const scalars[] = {"dist_ray", "ray_time", "dist_plane", "dist_ray_min", "dist_ray_max",
                                        "ray_time_min", "ray_time_max", "dist_plane_min", "dist_plane_max"};
  for (const char* f : scalars)
    if (fn == f) {
      run(fn, "SELECT " + fn + "(" + placeholders(args.size()) + ")", args, true);
      return 0;
    }
  if (fn == "ray_query")
    run(fn, "SELECT point_index, x, y, z, t, distance, rank FROM ray_query(" + placeholders(args.size()) + ")",
        args, false);
  else if (fn == "ray_prune" || fn == "plane_prune")
    run(fn, "SELECT id FROM chunks WHERE id MATCH " + fn + "(" + placeholders(args.size()) + ")", args, false);
  return 0;
}
