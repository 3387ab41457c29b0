// import_postgres (rayscan/sql/import.hpp): plain rows (default) or pgpointcloud patches
// (--pcpatch) through COPY in one transaction.
// Plain rows rather than pgpointcloud patches: the SQL functions take x, y, z as float8 columns and
// must see the reader's exact doubles (pcpatch dimensions are scaled integers or float32 unless a
// double schema is declared, and every query would first unpack patches with PC_Explode); the chunk
// boxes live in <table>_chunks with a GiST index whose consistent/distance are the bounds evaluation.
#include "rayscan/sql/import.hpp"

#include "rayscan/base/option_error.hpp"

#include "rayscan/sql/site_stream.hpp"

#include <libpq-fe.h>

#include <charconv>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

namespace rayscan::sql {

namespace {

struct Conn {
  PGconn* c = nullptr;
  ~Conn() { PQfinish(c); }
  [[noreturn]] void fail(const std::string& what) const {
    std::string m = c ? PQerrorMessage(c) : "out of memory";
    while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
    for (char& ch : m)
      if (ch == '\n') ch = ' ';
    throw std::runtime_error("postgres: " + what + ": " + m);
  }
  void exec(const std::string& sql) {
    PGresult* r = PQexec(c, sql.c_str());
    const auto st = PQresultStatus(r);
    PQclear(r);
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(sql.substr(0, 60));
  }
  void copy_in(const std::string& sql) {
    PGresult* r = PQexec(c, sql.c_str());
    const auto st = PQresultStatus(r);
    PQclear(r);
    if (st != PGRES_COPY_IN) fail(sql);
  }
  /// Ends a COPY FROM STDIN and checks the server's results; throws (fail(what)) on an error.
  void copy_end(const char* what) {
    if (PQputCopyEnd(c, nullptr) != 1) fail(what);
    for (PGresult* r; (r = PQgetResult(c));) {
      const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
      PQclear(r);
      if (!ok) fail(what);
    }
  }
};

/// `name` as a quoted identifier (PostgreSQL's quote_ident rules, always quoting): in double quotes,
/// with each double quote doubled. The checked names are lower case, so the quoted name is the one
/// an unquoted name would fold to.
std::string quote_ident(const std::string& name) {
  std::string q = "\"";
  for (char c : name) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + '"';
}

void append_double(std::string& s, double v) {
  char buf[32];
  auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form: exact
  s.append(buf, p);
}

// Hex digits of little-endian bytes of v (uncompressed pcpatch WKB is written in NDR order).
template <class T>
void append_hex(std::string& s, T v) {
  static const char* kHex = "0123456789ABCDEF";
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof v);
  for (unsigned char c : b) {
    s += kHex[c >> 4];
    s += kHex[c & 15];
  }
}

// Rows of the sources table (`sources`: schema-qualified and quoted): each input file's path and
// point count.
void insert_sources(Conn& db, const std::string& sources_table, const std::vector<SourceRow>& sources) {
  for (std::size_t i = 0; i < sources.size(); ++i) {
    const std::string& p = sources[i].path;
    const std::string n = std::to_string(i), cnt = std::to_string(sources[i].points);
    const char* vals[3] = {n.c_str(), p.c_str(), cnt.c_str()};
    PGresult* r = PQexecParams(db.c, ("INSERT INTO " + sources_table + " VALUES($1,$2,$3)").c_str(), 3,
                               nullptr, vals, nullptr, nullptr, 0);
    const bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
    PQclear(r);
    if (!ok) db.fail("insert source");
  }
}

/// One import into PostgreSQL: the site's chunks (open_site) streamed through COPY, all inside one
/// transaction. Each step throws std::runtime_error "postgres: <what>: <server message>" (Conn::fail)
/// on the first failing statement; the transaction then never commits.
struct PgImport {
  const std::string& table;             ///< the table's name as given (checked: lower case)
  std::string schema;                   ///< current_schema() of the connection, where it is created
  SiteStream& site;
  const std::vector<ColumnInfo>& cols;  ///< the extra columns (attributes)
  ChunkRows c;                          ///< the current chunk (vectors reused)
  ImportSummary sum;
  Conn db;
  InsertProgress progress;              ///< the "insert" phase of ImportOptions::progress

  PgImport(const std::string& t, SiteStream& s, const ImportOptions& o)
      : table(t), site(s), cols(s.columns()), progress(o, total_points(s)) {}

  /// The table `<table><suffix>` schema-qualified and quoted: what every statement names, so that
  /// no schema earlier in the search path (pg_catalog: `--table pg_class`) can capture it.
  [[nodiscard]] std::string name(const char* suffix = "") const {
    return quote_ident(schema) + "." + quote_ident(table + suffix);
  }
  /// An index `<table><suffix>`, quoted (an index is created in its table's schema).
  [[nodiscard]] std::string index(const char* suffix) const { return quote_ident(table + suffix); }

  /// Connects with `conninfo` (libpq connection string), lowers the client's message level and
  /// opens the transaction: all or nothing, a failure (or the server going away) leaves no half
  /// table.
  void connect_and_begin(const std::string& conninfo) {
    db.c = PQconnectdb(conninfo.c_str());
    if (PQstatus(db.c) != CONNECTION_OK) db.fail("cannot connect");
    db.exec("SET client_min_messages = warning");
    db.exec("BEGIN");
    PGresult* r = PQexec(db.c, "SELECT current_schema()");
    const bool ok = PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) == 1;
    const bool none = ok && PQgetisnull(r, 0, 0);
    if (ok && !none) schema = PQgetvalue(r, 0, 0);
    PQclear(r);
    if (!ok) db.fail("current_schema()");
    if (none)
      throw std::runtime_error("postgres: no schema to create table '" + table +
                               "' in: no schema of the search_path exists (SHOW search_path)");
  }

  /// The functions come from `CREATE EXTENSION rayscan` (an installed build), or were loaded from a
  /// build tree with rayscan_build_tree.sql (docs/sql.md); creates the extension only when the
  /// rs_box type is absent.
  void ensure_extension() {
    PGresult* r = PQexec(db.c, "SELECT to_regtype('rs_box') IS NOT NULL");
    const bool ok = PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) == 1;
    const bool present = ok && std::string(PQgetvalue(r, 0, 0)) == "t";
    PQclear(r);
    if (!ok) db.fail("to_regtype");
    if (!present) db.exec("CREATE EXTENSION IF NOT EXISTS rayscan");
  }

  /// Registers a pgpointcloud schema (pointcloud_formats row) under a new pcid and returns the
  /// pcid: double X/Y/Z (scale 1: the reader's exact doubles), the point's index and source, then
  /// the attributes (int64 or double); no compression. Throws std::runtime_error when all 65535
  /// pcids are in use.
  int register_pcpatch_schema() {
    db.exec("CREATE EXTENSION IF NOT EXISTS pointcloud");
    db.exec("LOCK TABLE pointcloud_formats IN SHARE ROW EXCLUSIVE MODE");  // a unique new pcid
    PGresult* r = PQexec(db.c, "SELECT coalesce(max(pcid), 0) + 1 FROM pointcloud_formats");
    const bool ok = PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) == 1;
    const int pcid = ok ? std::atoi(PQgetvalue(r, 0, 0)) : 0;
    PQclear(r);
    if (!ok) db.fail("pointcloud_formats");
    if (pcid >= 65536) throw std::runtime_error("postgres: pointcloud_formats is full (pcid 65535 in use)");
    struct Dim {
      std::string name, type;
      int size;
    };
    std::vector<Dim> dims = {{"X", "double", 8}, {"Y", "double", 8}, {"Z", "double", 8},
                             {"PointIndex", "uint64_t", 8}, {"Source", "uint32_t", 4}};
    for (const auto& col : cols) dims.push_back({col.name, col.integer ? "int64_t" : "double", 8});
    std::string xml = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<pc:PointCloudSchema "
                      "xmlns:pc=\"http://pointcloud.org/schemas/PC/1.1\" "
                      "xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\">";
    for (std::size_t i = 0; i < dims.size(); ++i)
      xml += "<pc:dimension><pc:position>" + std::to_string(i + 1) + "</pc:position><pc:size>" +
             std::to_string(dims[i].size) + "</pc:size><pc:name>" + dims[i].name +
             "</pc:name><pc:interpretation>" + dims[i].type + "</pc:interpretation><pc:scale>1</pc:scale></pc:dimension>";
    xml += "<pc:metadata><Metadata name=\"compression\">none</Metadata></pc:metadata></pc:PointCloudSchema>";
    const std::string id = std::to_string(pcid);
    const char* vals[2] = {id.c_str(), xml.c_str()};
    r = PQexecParams(db.c, "INSERT INTO pointcloud_formats (pcid, srid, schema) VALUES ($1, 0, $2)", 2, nullptr, vals,
                     nullptr, nullptr, 0);
    const bool ins = PQresultStatus(r) == PGRES_COMMAND_OK;
    PQclear(r);
    if (!ins) db.fail("insert pointcloud_formats schema");
    return pcid;
  }

  /// COPY of one row per chunk into <table>: chunk id, the patch as hex WKB, the box. Patch WKB:
  /// byte order 1 (NDR), uint32 pcid, uint32 compression 0 (none), uint32 npoints, then the
  /// points in schema order (pgpointcloud README, "Binary Formats"). Sent in ~1 MiB pieces.
  void copy_patches(int pcid) {
    db.copy_in("COPY " + name() + " FROM STDIN");
    std::string buf;
    while (site.next(c)) {
      const std::size_t count = c.size();
      progress.add(count);
      buf += std::to_string(c.chunk) + '\t';
      buf += "01";
      append_hex(buf, static_cast<std::uint32_t>(pcid));
      append_hex(buf, std::uint32_t{0});
      append_hex(buf, static_cast<std::uint32_t>(count));
      for (std::size_t r = 0; r < count; ++r) {
        const PointRef ref = c.refs[r];
        const Vec3& p = c.positions[r];
        append_hex(buf, p.x);
        append_hex(buf, p.y);
        append_hex(buf, p.z);
        append_hex(buf, static_cast<std::uint64_t>(ref.index));
        append_hex(buf, static_cast<std::uint32_t>(ref.source));
        for (std::size_t a = 0; a < cols.size(); ++a) {
          const double v = c.values[a * count + r];
          if (cols[a].integer) append_hex(buf, static_cast<std::int64_t>(v));
          else append_hex(buf, v);
        }
      }
      buf += "\t(";
      const double v[6] = {c.box.lo.x, c.box.lo.y, c.box.lo.z, c.box.hi.x, c.box.hi.y, c.box.hi.z};
      for (int i = 0; i < 6; ++i) {
        if (i) buf += ',';
        append_double(buf, v[i]);
      }
      buf += ")\n";
      sum.points += count;
      ++sum.chunks;
      if (buf.size() >= (1u << 20)) {
        if (PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1) db.fail("COPY patches");
        buf.clear();
      }
    }
    if (!buf.empty() && PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1) db.fail("COPY patches");
    db.copy_end("COPY patches");
  }

  /// --pcpatch: one uncompressed pgpointcloud patch per chunk in <table> (chunk, pa, box) with a
  /// GiST index on the boxes, and <table>_sources; commits and analyzes.
  void import_pcpatch() {
    const int pcid = register_pcpatch_schema();
    const std::string id = std::to_string(pcid);
    db.exec("CREATE TABLE " + name() + " (chunk int PRIMARY KEY, pa pcpatch(" + id + ") NOT NULL, box rs_box NOT NULL)");
    db.exec("CREATE TABLE " + name("_sources") + " (source int PRIMARY KEY, path text NOT NULL, point_count bigint NOT NULL)");
    copy_patches(pcid);
    insert_sources(db, name("_sources"), site.sources());
    db.exec("CREATE INDEX " + index("_box") + " ON " + name() + " USING gist (box)");
    db.exec("COMMIT");
    db.exec("ANALYZE " + name());
  }

  /// The plain-rows tables (docs/sql.md): <table> (point_index, source, chunk, x, y, z,
  /// <attributes>), <table>_chunks (chunk, box, first_row, count), <table>_sources.
  void create_point_tables() {
    std::string create = "CREATE TABLE " + name() +
                         " (point_index bigint NOT NULL, source int NOT NULL, chunk int NOT NULL, "
                         "x float8 NOT NULL, y float8 NOT NULL, z float8 NOT NULL";
    for (const auto& col : cols) create += ", " + quote_ident(folded_sql_name(col.name)) + (col.integer ? " bigint" : " float8");
    db.exec(create + ")");
    db.exec("CREATE TABLE " + name("_chunks") + " (chunk int PRIMARY KEY, box rs_box NOT NULL, "
            "first_row bigint NOT NULL, count int NOT NULL)");
    db.exec("CREATE TABLE " + name("_sources") + " (source int PRIMARY KEY, path text NOT NULL, "
            "point_count bigint NOT NULL)");
  }

  /// Sends `buf` as COPY data when it holds 1 MiB or more, or always with `force`; throws
  /// (fail(what)) when libpq refuses it.
  void flush(std::string& buf, bool force, const char* what) {
    if (buf.size() < (1u << 20) && !force) return;
    if (PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1) db.fail(what);
    buf.clear();
  }

  /// COPY of every point into <table> (coordinates and doubles in their shortest exact form).
  /// Returns the <table>_chunks rows, one short line per chunk, kept for copy_chunks(): one COPY
  /// at a time on a connection.
  std::string copy_points() {
    db.copy_in("COPY " + name() + " FROM STDIN");
    std::string buf;
    std::string chunk_rows;
    while (site.next(c)) {
      const std::size_t count = c.size();
      progress.add(count);
      const std::string ci = std::to_string(c.chunk);
      for (std::size_t r = 0; r < count; ++r) {
        const PointRef ref = c.refs[r];
        const Vec3& p = c.positions[r];
        buf += std::to_string(ref.index) + '\t' + std::to_string(ref.source) + '\t' + ci;
        for (double v : {p.x, p.y, p.z}) {
          buf += '\t';
          append_double(buf, v);
        }
        for (std::size_t a = 0; a < cols.size(); ++a) {
          buf += '\t';
          const double v = c.values[a * count + r];
          if (cols[a].integer) buf += std::to_string(static_cast<long long>(v));
          else append_double(buf, v);
        }
        buf += '\n';
        flush(buf, false, "COPY points");
      }
      // Chunk boxes in double: exact, no outward rounding needed.
      chunk_rows += ci + "\t(";
      const double v[6] = {c.box.lo.x, c.box.lo.y, c.box.lo.z, c.box.hi.x, c.box.hi.y, c.box.hi.z};
      for (int i = 0; i < 6; ++i) {
        if (i) chunk_rows += ',';
        append_double(chunk_rows, v[i]);
      }
      chunk_rows += ")\t" + std::to_string(c.first_row) + '\t' + std::to_string(count) + '\n';
      sum.points += count;
      ++sum.chunks;
    }
    flush(buf, true, "COPY points");
    db.copy_end("COPY points");
    return chunk_rows;
  }

  /// COPY of the chunk rows copy_points() collected into <table>_chunks.
  void copy_chunks(std::string rows) {
    db.copy_in("COPY " + name("_chunks") + " FROM STDIN");
    flush(rows, true, "COPY points");  // a refused send reports "COPY points", as in copy_points()
    db.copy_end("COPY chunks");
  }

  /// <table>_sources, the chunk index of <table> and the GiST index of the chunk boxes, the
  /// planner's n_distinct of chunk; commits and analyzes.
  void finish_indexes() {
    insert_sources(db, name("_sources"), site.sources());
    db.exec("CREATE INDEX " + index("_chunk_idx") + " ON " + name() + " (chunk)");
    // The number of distinct chunks is known exactly: tell the planner (ANALYZE's sample estimates it
    // from 30,000 rows, ~4x too few chunks at 2e8 points; the join's row estimate then crossed the
    // JIT and parallel-plan thresholds and a pruned query scanned every chunk; bench/README.md).
    if (sum.points > 0) {
      char nd[40];
      std::snprintf(nd, sizeof nd, "%.17g", -static_cast<double>(sum.chunks) / static_cast<double>(sum.points));
      db.exec("ALTER TABLE " + name() + " ALTER COLUMN chunk SET (n_distinct = " + nd + ")");
    }
    db.exec("CREATE INDEX " + index("_chunks_box") + " ON " + name("_chunks") + " USING gist (box)");
    db.exec("COMMIT");
    db.exec("ANALYZE " + name() + "; ANALYZE " + name("_chunks"));
  }
};

}  // namespace

ImportSummary import_postgres(const std::vector<std::filesystem::path>& paths,
                              const std::string& conninfo, const std::string& table,
                              const ImportOptions& options) {
  if (paths.empty()) throw std::invalid_argument("no input cloud given");
  // Lower case and <= 50: the table's companions (<table>_sources, _chunks, ...) stay within 63.
  if (!is_sql_identifier(table, 50, false))
    throw OptionError({option("table"), " '" + table + "': expected a lower-case SQL identifier [a-z_][a-z0-9_]* (max 50)"});
  if (const std::string why = reserved_sql_name(table, false); !why.empty())
    throw OptionError({option("table"), " '" + table + "': " + why + "; expected another name"});
  const std::unique_ptr<SiteStream> site = open_site(paths, options);
  PgImport im(table, *site, options);
  im.connect_and_begin(conninfo);
  im.ensure_extension();
  if (options.pcpatch) {
    im.import_pcpatch();
    return im.sum;
  }
  im.create_point_tables();
  im.copy_chunks(im.copy_points());
  im.finish_indexes();
  return im.sum;
}

}  // namespace rayscan::sql
