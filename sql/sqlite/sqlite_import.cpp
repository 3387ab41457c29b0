// import_sqlite (rayscan/sql/import.hpp): Morton-ordered chunks plus an R*Tree of chunk bounds.
#include "rayscan/sql/import.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/sql/site_stream.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace rayscan::sql {

namespace {

struct Db {
  sqlite3* db = nullptr;
  std::string name;
  ~Db() { sqlite3_close(db); }
  /// Throws std::runtime_error "<file>: sqlite: <what>: <sqlite3_errmsg>", one line: `what` names
  /// the step ("create table points", "insert into chunks"), never the SQL text, as the
  /// PostgreSQL import names its steps.
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(one_line(name) + ": sqlite: " + what + ": " +
                             one_line(db ? sqlite3_errmsg(db) : "out of memory"));
  }
  /// Runs `sql` (one or more statements); throws (fail(what)) on an error.
  void exec(const std::string& sql, const std::string& what) {
    if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) fail(what);
  }
  /// Prepares `sql` into `s`; throws (fail("prepare " + what)) on an error.
  void prepare(const std::string& sql, sqlite3_stmt** s, const std::string& what) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, s, nullptr) != SQLITE_OK) fail("prepare " + what);
  }
};

struct Stmt {
  sqlite3_stmt* s = nullptr;
  ~Stmt() { sqlite3_finalize(s); }
};

}  // namespace

ImportSummary import_sqlite(const std::vector<std::filesystem::path>& paths,
                            const std::filesystem::path& out, const ImportOptions& options) {
  require_replaceable_output(out);  // before the (long) sort: a bad output path fails first
  ImportOptions opt = options;
  if (opt.temp_dir.empty()) opt.temp_dir = out.has_parent_path() ? out.parent_path() : std::filesystem::path(".");
  const std::unique_ptr<SiteStream> site = open_site(paths, opt, out);
  const std::vector<ColumnInfo>& cols = site->columns();

  AtomicFile file(out);
  std::filesystem::remove(file.temp());
  ImportSummary sum;
  sum.sources = site->sources();
  ImportProgress progress(opt, total_points(*site));
  {
    Db db;
    db.name = out.string();
    // One thread uses the connection: no per-call mutex (7% of an import's time in a profile).
    if (sqlite3_open_v2(file.temp().c_str(), &db.db,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK)
      db.fail("create the database");
    // The temporary file is renamed into place only when complete: no journal needed. The page
    // cache (also the in-memory budget of CREATE INDEX's external sorter) gets a quarter of the
    // memory budget, at most 1 GiB, instead of SQLite's default 2 MB.
    const std::uint64_t cache_kib = std::min<std::uint64_t>(opt.memory_bytes / 4, std::uint64_t{1} << 30) >> 10;
    db.exec("PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF; PRAGMA page_size=8192; PRAGMA cache_size=-" +
                std::to_string(cache_kib) + ";",
            "set journal, page size and cache");
    db.exec("BEGIN", "begin");
    db.exec("CREATE TABLE rayscan_meta(key TEXT PRIMARY KEY, value TEXT) WITHOUT ROWID", "create table rayscan_meta");
    db.exec("CREATE TABLE sources(source INTEGER PRIMARY KEY, path TEXT NOT NULL, "
            "point_count INTEGER NOT NULL, crs_wkt TEXT)",
            "create table sources");
    std::string create = "CREATE TABLE points(point_index INTEGER NOT NULL, source INTEGER NOT NULL, "
                         "chunk INTEGER NOT NULL, x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL";
    std::string insert = "INSERT INTO points(rowid, point_index, source, chunk, x, y, z";
    std::string values = "VALUES(?,?,?,?,?,?,?";
    for (const auto& c : cols) {
      create += ", \"" + c.name + "\" " + (c.integer ? "INTEGER" : "REAL");
      insert += ", \"" + c.name + "\"";
      values += ",?";
    }
    db.exec(create + ")", "create table points");
    // R*Tree of chunk bounds (https://sqlite.org/rtree.html, section 3.1: auxiliary columns).
    db.exec("CREATE VIRTUAL TABLE chunks USING rtree(id, min_x, max_x, min_y, max_y, min_z, max_z, "
            "+first_row INTEGER, +count INTEGER)",
            "create table chunks");
    // Each chunk's points once more as one packed BLOB (a "patch", as pgpointcloud's pcpatch):
    // ray_query reads a chunk with one b-tree lookup and evaluates it in a tight loop instead of
    // paying SQLite's per-row cost (bench/README.md, "SQL ray queries": the profile).
    db.exec("CREATE TABLE chunk_points(id INTEGER PRIMARY KEY, data BLOB NOT NULL)", "create table chunk_points");
    {
      Stmt m;
      db.prepare("INSERT INTO rayscan_meta VALUES(?,?)", &m.s, "insert into rayscan_meta");
      auto meta = [&](const char* k, const std::string& v) {
        sqlite3_bind_text(m.s, 1, k, -1, SQLITE_STATIC);
        sqlite3_bind_text(m.s, 2, v.c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(m.s) != SQLITE_DONE) db.fail("insert into rayscan_meta");
        sqlite3_reset(m.s);
      };
      meta("format", "rayscan-sqlite 1");
      meta("chunk_size", std::to_string(options.chunk_size));
      meta("order", "morton");
      meta("chunk_points", kChunkPointsLayout);
      Stmt s;
      db.prepare("INSERT INTO sources VALUES(?,?,?,?)", &s.s, "insert into sources");
      const auto& sources = site->sources();
      for (std::size_t i = 0; i < sources.size(); ++i) {
        sqlite3_bind_int64(s.s, 1, static_cast<sqlite3_int64>(i));
        sqlite3_bind_text(s.s, 2, sources[i].path.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_int64(s.s, 3, static_cast<sqlite3_int64>(sources[i].points));
        if (sources[i].crs_wkt.empty()) sqlite3_bind_null(s.s, 4);
        else sqlite3_bind_text(s.s, 4, sources[i].crs_wkt.c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(s.s) != SQLITE_DONE) db.fail("insert into sources");
        sqlite3_reset(s.s);
      }
    }
    Stmt ins, rt, blob;
    db.prepare("INSERT INTO chunk_points VALUES(?,?)", &blob.s, "insert into chunk_points");
    std::vector<unsigned char> packed;
    db.prepare(insert + ") " + values + ")", &ins.s, "insert into points");
    db.prepare("INSERT INTO chunks VALUES(?,?,?,?,?,?,?,?,?)", &rt.s, "insert into chunks");
    ChunkRows c;
    while (site->next(c)) {
      const std::size_t count = c.size();
      const auto ci = static_cast<sqlite3_int64>(c.chunk);
      packed.resize(count * sizeof(PackedPoint));
      for (std::size_t r = 0; r < count; ++r) {
        const PointRef ref = c.refs[r];
        const Vec3& p = c.positions[r];
        const PackedPoint pp{p.x, p.y, p.z, static_cast<std::int64_t>(ref.index), ref.source};
        std::memcpy(packed.data() + r * sizeof(PackedPoint), &pp, sizeof pp);
        sqlite3_bind_int64(ins.s, 1, static_cast<sqlite3_int64>(c.first_row + r + 1));
        sqlite3_bind_int64(ins.s, 2, static_cast<sqlite3_int64>(ref.index));
        sqlite3_bind_int64(ins.s, 3, ref.source);
        sqlite3_bind_int64(ins.s, 4, ci);
        sqlite3_bind_double(ins.s, 5, p.x);
        sqlite3_bind_double(ins.s, 6, p.y);
        sqlite3_bind_double(ins.s, 7, p.z);
        for (std::size_t a = 0; a < cols.size(); ++a) {
          const double v = c.values[a * count + r];
          if (cols[a].integer) sqlite3_bind_int64(ins.s, int(8 + a), static_cast<sqlite3_int64>(v));
          else sqlite3_bind_double(ins.s, int(8 + a), v);
        }
        if (sqlite3_step(ins.s) != SQLITE_DONE) db.fail("insert into points");
        sqlite3_reset(ins.s);
      }
      // SQLite's R*Tree stores float32 and rounds lower bounds down and upper bounds up
      // (rtreeValueDown / rtreeValueUp), so the stored box contains the exact double box.
      sqlite3_bind_int64(rt.s, 1, ci);
      sqlite3_bind_double(rt.s, 2, c.box.lo.x);
      sqlite3_bind_double(rt.s, 3, c.box.hi.x);
      sqlite3_bind_double(rt.s, 4, c.box.lo.y);
      sqlite3_bind_double(rt.s, 5, c.box.hi.y);
      sqlite3_bind_double(rt.s, 6, c.box.lo.z);
      sqlite3_bind_double(rt.s, 7, c.box.hi.z);
      sqlite3_bind_int64(rt.s, 8, static_cast<sqlite3_int64>(c.first_row + 1));
      sqlite3_bind_int64(rt.s, 9, static_cast<sqlite3_int64>(count));
      if (sqlite3_step(rt.s) != SQLITE_DONE) db.fail("insert into chunks");
      sqlite3_reset(rt.s);
      sqlite3_bind_int64(blob.s, 1, ci);
      sqlite3_bind_blob64(blob.s, 2, packed.data(), packed.size(), SQLITE_STATIC);
      if (sqlite3_step(blob.s) != SQLITE_DONE) db.fail("insert into chunk_points");
      sqlite3_reset(blob.s);
      sum.points += count;
      ++sum.chunks;
      progress.insert(count);
    }
    progress.index();
    db.exec("CREATE INDEX points_source_index ON points(source, point_index)", "create index points_source_index");
    db.exec("COMMIT", "commit");
  }
  file.commit();
  progress.done();
  return sum;
}

}  // namespace rayscan::sql
