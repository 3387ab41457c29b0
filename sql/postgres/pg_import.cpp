// import_postgres (rayscan/sql/import.hpp): plain rows (default) or pgpointcloud patches
// (--pcpatch) through COPY in one transaction.
// Plain rows rather than pgpointcloud patches: the SQL functions take x, y, z as float8 columns and
// must see the reader's exact doubles (pcpatch dimensions are scaled integers or float32 unless a
// double schema is declared, and every query would first unpack patches with PC_Explode); the chunk
// boxes live in <table>_chunks with a GiST index whose consistent/distance are the bounds evaluation.
#include "rayscan/sql/import.hpp"

#include "rayscan/base/option_error.hpp"
#include "rayscan/io/crs.hpp"

#include "rayscan/sql/site_stream.hpp"

#include <libpq-fe.h>

#include <charconv>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::sql {

namespace {

/// libpq's text as one line: PQerrorMessage ends in a newline and continues a message on lines
/// indented with a tab (a connection failure's "Is the server running ...?"); the lines are
/// joined with "; " (rayscan::one_line would keep every line, escaping the newlines).
std::string join_message_lines(const std::string& text) {
  std::string out, line;
  auto flush = [&] {
    const auto b = line.find_first_not_of(" \t\r"), e = line.find_last_not_of(" \t\r");
    if (b != std::string::npos) out += (out.empty() ? "" : "; ") + line.substr(b, e - b + 1);
    line.clear();
  };
  for (char ch : text) {
    if (ch == '\n') flush();
    else line += ch == '\t' ? ' ' : ch;
  }
  flush();
  return out;
}

/// A PGresult freed with its owner.
using Result = std::unique_ptr<PGresult, decltype(&PQclear)>;

struct Conn {
  PGconn* c = nullptr;
  ~Conn() { PQfinish(c); }
  /// Throws std::runtime_error "postgres: <what>: <message>": the server's primary message of `r`
  /// (PG_DIAG_MESSAGE_PRIMARY: one line, without its detail, hint or the statement), else the
  /// connection's last message as one line.
  [[noreturn]] void fail(const std::string& what, const PGresult* r = nullptr) const {
    const char* primary = r ? PQresultErrorField(r, PG_DIAG_MESSAGE_PRIMARY) : nullptr;
    const std::string m = primary ? primary : c ? PQerrorMessage(c) : "out of memory";
    throw std::runtime_error("postgres: " + what + ": " + join_message_lines(m));
  }
  /// Runs `sql` with text parameters (nullptr: NULL) and returns its result; throws (fail(what))
  /// unless it returned rows or completed.
  Result run(const std::string& sql, const std::vector<const char*>& params, const std::string& what) {
    Result r(PQexecParams(c, sql.c_str(), static_cast<int>(params.size()), nullptr, params.data(), nullptr,
                          nullptr, 0),
             &PQclear);
    const auto st = PQresultStatus(r.get());
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(what, r.get());
    return r;
  }
  /// The one value of a one-row query, std::nullopt for none or NULL.
  std::optional<std::string> value(const std::string& sql, const std::vector<const char*>& params,
                                   const std::string& what) {
    const Result r = run(sql, params, what);
    if (PQntuples(r.get()) < 1 || PQgetisnull(r.get(), 0, 0)) return std::nullopt;
    return std::string(PQgetvalue(r.get(), 0, 0));
  }
  /// Runs `sql` (one or more statements, no parameters); throws (fail(what)) on an error.
  void exec(const std::string& sql, const std::string& what) {
    const Result r(PQexec(c, sql.c_str()), &PQclear);
    const auto st = PQresultStatus(r.get());
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) fail(what, r.get());
  }
  void copy_in(const std::string& sql, const std::string& what) {
    const Result r(PQexec(c, sql.c_str()), &PQclear);
    if (PQresultStatus(r.get()) != PGRES_COPY_IN) fail(what, r.get());
  }
  /// Ends a COPY FROM STDIN and checks the server's results; throws (fail(what)) on an error.
  void copy_end(const std::string& what) {
    if (PQputCopyEnd(c, nullptr) != 1) fail(what);
    for (PGresult* p; (p = PQgetResult(c));) {
      const Result r(p, &PQclear);
      if (PQresultStatus(p) != PGRES_COMMAND_OK) fail(what, p);
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

/// The EPSG code of the sources' horizontal CRS (io::epsg_codes_from_wkt, as `rayscan info`
/// identifies it), the srid of a pgpointcloud schema; 0 (pgpointcloud's "unknown") when no source
/// has a CRS, one has none GDAL identifies, or two disagree.
int sources_srid(const std::vector<SourceRow>& sources) {
  int srid = -1;
  for (const SourceRow& s : sources) {
    if (s.crs_wkt.empty()) continue;
    const int code = io::epsg_codes_from_wkt(s.crs_wkt).horizontal;
    if (srid >= 0 && code != srid) return 0;
    srid = code;
  }
  return srid > 0 ? srid : 0;
}

/// One import into PostgreSQL: the site's chunks (open_site) streamed through COPY, all inside one
/// transaction. Each step throws std::runtime_error "postgres: <what>: <server message>" (Conn::fail)
/// on the first failing statement; the transaction then never commits.
struct PgImport {
  const std::string& table;             ///< the table's name as given (checked: lower case)
  std::string schema;                   ///< current_schema() of the connection, where it is created
  std::string rayscan_schema;           ///< the schema of rs_box and the functions (ensure_extension)
  std::string pointcloud_schema;        ///< pgpointcloud's (--pcpatch; register_pcpatch_schema)
  SiteStream* site = nullptr;           ///< set by attach()
  ChunkRows c;                          ///< the current chunk (vectors reused)
  ImportSummary sum;
  Conn db;
  const ImportOptions& options;
  std::optional<ImportProgress> progress;  ///< the import's own phases of ImportOptions::progress

  PgImport(const std::string& t, const ImportOptions& o) : table(t), options(o) {}

  /// The table `<table><suffix>` schema-qualified and quoted: what every statement names, so that
  /// no schema earlier in the search path (pg_catalog: `--table pg_class`) can capture it.
  [[nodiscard]] std::string name(const char* suffix = "") const {
    return quote_ident(schema) + "." + quote_ident(table + suffix);
  }
  /// `<table><suffix>` as the messages show it: schema.name, unquoted.
  [[nodiscard]] std::string shown(const std::string& relation) const { return schema + "." + relation; }
  /// An index `<table><suffix>`, quoted (an index is created in its table's schema).
  [[nodiscard]] std::string index(const char* suffix) const { return quote_ident(table + suffix); }
  /// rs_box qualified with the schema that holds it (the search path need not include it).
  [[nodiscard]] std::string box_type() const { return quote_ident(rayscan_schema) + ".rs_box"; }

  /// The relations the import creates: tables and the indexes it names (the primary keys'
  /// indexes PostgreSQL names itself, avoiding taken names).
  [[nodiscard]] std::vector<std::string> relations() const {
    if (options.pcpatch) return {table, table + "_sources", table + "_box"};
    return {table, table + "_chunks", table + "_sources", table + "_chunk_idx", table + "_chunks_box"};
  }

  /// Throws std::runtime_error "postgres: table <schema>.<name> exists: choose another --table or
  /// drop it" (index, view, ... for another kind of relation).
  [[noreturn]] void exists(const std::string& relation, char relkind) const {
    const char* kind = relkind == 'r' || relkind == 'p' ? "table"
                       : relkind == 'i' || relkind == 'I' ? "index"
                       : relkind == 'v' || relkind == 'm' ? "view"
                       : relkind == 'S' ? "sequence" : "relation";
    throw std::runtime_error("postgres: " + std::string(kind) + " " + shown(relation) +
                             " exists: choose another --table or drop it");
  }

  /// Connects with `conninfo` (libpq connection string), lowers the client's message level, finds
  /// the schema to create the tables in and checks that none of the import's relations exists
  /// there yet: before the sort, so that a wrong server or a taken name fails at once.
  void connect(const std::string& conninfo) {
    db.c = PQconnectdb(conninfo.c_str());
    if (PQstatus(db.c) != CONNECTION_OK) db.fail("cannot connect");
    db.exec("SET client_min_messages = warning", "set client_min_messages");
    const std::optional<std::string> s = db.value("SELECT current_schema()", {}, "current_schema()");
    if (!s)
      throw std::runtime_error("postgres: no schema to create table '" + table +
                               "' in: no schema of the search_path exists (SHOW search_path)");
    schema = *s;
    std::string names = "{";
    for (const std::string& r : relations()) names += (names.size() > 1 ? "," : "") + r;  // checked identifiers
    names += "}";
    const Result r = db.run("SELECT c.relname, c.relkind FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace "
                            "WHERE n.nspname = $1 AND c.relname = ANY ($2::text[]) "
                            "ORDER BY array_position($2::text[], c.relname::text) LIMIT 1",
                            {schema.c_str(), names.c_str()}, "look up the tables");
    if (PQntuples(r.get()) > 0) exists(PQgetvalue(r.get(), 0, 0), PQgetvalue(r.get(), 0, 1)[0]);
  }

  /// The site to import, once sorted; starts the "insert" phase.
  void attach(SiteStream& s) {
    site = &s;
    progress.emplace(options, total_points(s));
  }

  /// Runs `sql`, a CREATE of `relation`: a relation of that name made since connect() checked
  /// (42P07 duplicate_table) is reported as exists() reports it.
  void create(const std::string& sql, const std::string& relation) {
    const Result r(PQexec(db.c, sql.c_str()), &PQclear);
    if (PQresultStatus(r.get()) == PGRES_COMMAND_OK) return;
    const char* state = PQresultErrorField(r.get(), PG_DIAG_SQLSTATE);
    if (state && std::string(state) == "42P07") exists(relation, 'r');
    db.fail("create " + shown(relation), r.get());
  }

  /// The schema of extension `name` (pg_extension.extnamespace), std::nullopt when the database
  /// does not have it.
  std::optional<std::string> extension_schema(const char* name) {
    return db.value("SELECT n.nspname FROM pg_extension e JOIN pg_namespace n ON n.oid = e.extnamespace "
                    "WHERE e.extname = $1", {name}, std::string("look up extension ") + name);
  }

  /// Where CREATE EXTENSION puts an extension the database lacks: public, the schema of a
  /// database's shared objects (PostGIS's and pgpointcloud's usual place) rather than the
  /// tables' schema, which a search_path such as `survey` would make the data's; the tables'
  /// schema when the database has no public.
  std::string extension_home() {
    return db.value("SELECT to_regnamespace('public') IS NOT NULL", {}, "look up schema public") == "t" ? "public"
                                                                                                        : schema;
  }

  /// Opens the transaction (all or nothing: a failure, or the server going away, leaves no half
  /// table) and finds rs_box and the functions: the rayscan extension's schema (CREATE EXTENSION
  /// rayscan, an installed build), else the schema of an rs_box loaded from a build tree with
  /// rayscan_build_tree.sql (docs/sql.md; the one the search path sees first, else public, else
  /// the first by name); without either, creates the extension in extension_home(). Every type
  /// the import's statements name is qualified with that schema, so they work whatever the
  /// connection's search_path.
  void begin() {
    db.exec("BEGIN", "begin");
    if (std::optional<std::string> s = extension_schema("rayscan")) {
      rayscan_schema = *s;
      return;
    }
    if (std::optional<std::string> s =
            db.value("SELECT n.nspname FROM pg_type t JOIN pg_namespace n ON n.oid = t.typnamespace "
                     "WHERE t.typname = 'rs_box' ORDER BY pg_type_is_visible(t.oid) DESC, n.nspname <> 'public', "
                     "n.nspname LIMIT 1", {}, "look up type rs_box")) {
      rayscan_schema = *s;
      return;
    }
    rayscan_schema = extension_home();
    db.exec("CREATE EXTENSION rayscan SCHEMA " + quote_ident(rayscan_schema),
            "create extension rayscan in schema " + rayscan_schema);
  }

  /// Registers a pgpointcloud schema (pointcloud_formats row) under a new pcid and returns the
  /// pcid: double X/Y/Z (scale 1: the reader's exact doubles), the point's index and source, then
  /// the attributes (int64 or double); no compression; srid the sources' EPSG code
  /// (sources_srid), which PDAL's readers.pgpointcloud reads as the cloud's CRS. Creates the
  /// extension pointcloud in extension_home() when the database lacks it. Throws
  /// std::runtime_error when all 65535 pcids are in use.
  int register_pcpatch_schema() {
    if (std::optional<std::string> s = extension_schema("pointcloud")) {
      pointcloud_schema = *s;
    } else {
      pointcloud_schema = extension_home();
      db.exec("CREATE EXTENSION pointcloud SCHEMA " + quote_ident(pointcloud_schema),
              "create extension pointcloud in schema " + pointcloud_schema);
    }
    const std::string formats = quote_ident(pointcloud_schema) + ".pointcloud_formats";
    db.exec("LOCK TABLE " + formats + " IN SHARE ROW EXCLUSIVE MODE", "lock pointcloud_formats");  // a unique new pcid
    const std::optional<std::string> next =
        db.value("SELECT coalesce(max(pcid), 0) + 1 FROM " + formats, {}, "read pointcloud_formats");
    const int pcid = next ? std::atoi(next->c_str()) : 0;
    if (pcid >= 65536) throw std::runtime_error("postgres: pointcloud_formats is full (pcid 65535 in use)");
    struct Dim {
      std::string name, type;
      int size;
    };
    std::vector<Dim> dims = {{"X", "double", 8}, {"Y", "double", 8}, {"Z", "double", 8},
                             {"PointIndex", "uint64_t", 8}, {"Source", "uint32_t", 4}};
    for (const auto& col : site->columns()) dims.push_back({col.name, col.integer ? "int64_t" : "double", 8});
    std::string xml = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<pc:PointCloudSchema "
                      "xmlns:pc=\"http://pointcloud.org/schemas/PC/1.1\" "
                      "xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\">";
    for (std::size_t i = 0; i < dims.size(); ++i)
      xml += "<pc:dimension><pc:position>" + std::to_string(i + 1) + "</pc:position><pc:size>" +
             std::to_string(dims[i].size) + "</pc:size><pc:name>" + dims[i].name +
             "</pc:name><pc:interpretation>" + dims[i].type + "</pc:interpretation><pc:scale>1</pc:scale></pc:dimension>";
    xml += "<pc:metadata><Metadata name=\"compression\">none</Metadata></pc:metadata></pc:PointCloudSchema>";
    const std::string id = std::to_string(pcid), srid = std::to_string(sources_srid(site->sources()));
    db.run("INSERT INTO " + formats + " (pcid, srid, schema) VALUES ($1, $2, $3)", {id.c_str(), srid.c_str(), xml.c_str()},
           "insert the pointcloud_formats schema");
    return pcid;
  }

  /// <table>_sources: each input file's path, point count and CRS (WKT, NULL when unknown), as
  /// SQLite's sources table.
  void create_sources() {
    create("CREATE TABLE " + name("_sources") + " (source int PRIMARY KEY, path text NOT NULL, "
           "point_count bigint NOT NULL, crs_wkt text)", table + "_sources");
  }
  void insert_sources() {
    const std::vector<SourceRow>& sources = site->sources();
    for (std::size_t i = 0; i < sources.size(); ++i) {
      const std::string n = std::to_string(i), cnt = std::to_string(sources[i].points);
      const std::string& wkt = sources[i].crs_wkt;
      db.run("INSERT INTO " + name("_sources") + " VALUES ($1, $2, $3, $4)",
             {n.c_str(), sources[i].path.c_str(), cnt.c_str(), wkt.empty() ? nullptr : wkt.c_str()},
             "insert into " + shown(table + "_sources"));
    }
  }

  /// COPY of one row per chunk into <table>: chunk id, the patch as hex WKB, the box. Patch WKB:
  /// byte order 1 (NDR), uint32 pcid, uint32 compression 0 (none), uint32 npoints, then the
  /// points in schema order (pgpointcloud README, "Binary Formats"). Sent in ~1 MiB pieces.
  void copy_patches(int pcid) {
    const std::vector<ColumnInfo>& cols = site->columns();
    const std::string what = "copy into " + shown(table);
    db.copy_in("COPY " + name() + " FROM STDIN", what);
    std::string buf;
    while (site->next(c)) {
      const std::size_t count = c.size();
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
      flush(buf, false, what);
      progress->insert(count);
    }
    flush(buf, true, what);
    db.copy_end(what);
  }

  /// --pcpatch: one uncompressed pgpointcloud patch per chunk in <table> (chunk, pa, box) with a
  /// GiST index on the boxes, and <table>_sources; commits and analyzes.
  void import_pcpatch() {
    const int pcid = register_pcpatch_schema();
    const std::string id = std::to_string(pcid);
    create("CREATE TABLE " + name() + " (chunk int PRIMARY KEY, pa " + quote_ident(pointcloud_schema) + ".pcpatch(" +
           id + ") NOT NULL, box " + box_type() + " NOT NULL)", table);
    create_sources();
    copy_patches(pcid);
    insert_sources();
    progress->index();
    create("CREATE INDEX " + index("_box") + " ON " + name() + " USING gist (box)", table + "_box");
    db.exec("COMMIT", "commit");
    db.exec("ANALYZE " + name(), "analyze " + shown(table));
  }

  /// The plain-rows tables (docs/sql.md): <table> (point_index, source, chunk, x, y, z,
  /// <attributes>), <table>_chunks (chunk, box, first_row, count), <table>_sources.
  void create_point_tables() {
    std::string create_points = "CREATE TABLE " + name() +
                                " (point_index bigint NOT NULL, source int NOT NULL, chunk int NOT NULL, "
                                "x float8 NOT NULL, y float8 NOT NULL, z float8 NOT NULL";
    for (const auto& col : site->columns())
      create_points += ", " + quote_ident(folded_sql_name(col.name)) + (col.integer ? " bigint" : " float8");
    create(create_points + ")", table);
    create("CREATE TABLE " + name("_chunks") + " (chunk int PRIMARY KEY, box " + box_type() + " NOT NULL, "
           "first_row bigint NOT NULL, count int NOT NULL)", table + "_chunks");
    create_sources();
  }

  /// Sends `buf` as COPY data when it holds 1 MiB or more, or always with `force`; throws
  /// (fail(what)) when libpq refuses it.
  void flush(std::string& buf, bool force, const std::string& what) {
    if (buf.size() < (1u << 20) && !force) return;
    if (PQputCopyData(db.c, buf.data(), static_cast<int>(buf.size())) != 1) db.fail(what);
    buf.clear();
  }

  /// COPY of every point into <table> (coordinates and doubles in their shortest exact form).
  /// Returns the <table>_chunks rows, one short line per chunk, kept for copy_chunks(): one COPY
  /// at a time on a connection.
  std::string copy_points() {
    const std::vector<ColumnInfo>& cols = site->columns();
    const std::string what = "copy into " + shown(table);
    db.copy_in("COPY " + name() + " FROM STDIN", what);
    std::string buf;
    std::string chunk_rows;
    while (site->next(c)) {
      const std::size_t count = c.size();
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
        flush(buf, false, what);
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
      progress->insert(count);
    }
    flush(buf, true, what);
    db.copy_end(what);
    return chunk_rows;
  }

  /// COPY of the chunk rows copy_points() collected into <table>_chunks.
  void copy_chunks(std::string rows) {
    const std::string what = "copy into " + shown(table + "_chunks");
    db.copy_in("COPY " + name("_chunks") + " FROM STDIN", what);
    flush(rows, true, what);
    db.copy_end(what);
  }

  /// <table>_sources, the chunk index of <table> and the GiST index of the chunk boxes, the
  /// planner's n_distinct of chunk; commits and analyzes.
  void finish_indexes() {
    insert_sources();
    progress->index();
    create("CREATE INDEX " + index("_chunk_idx") + " ON " + name() + " (chunk)", table + "_chunk_idx");
    // The number of distinct chunks is known exactly: tell the planner (ANALYZE's sample estimates it
    // from 30,000 rows, ~4x too few chunks at 2e8 points; the join's row estimate then crossed the
    // JIT and parallel-plan thresholds and a pruned query scanned every chunk; bench/README.md).
    if (sum.points > 0) {
      char nd[40];
      std::snprintf(nd, sizeof nd, "%.17g", -static_cast<double>(sum.chunks) / static_cast<double>(sum.points));
      db.exec("ALTER TABLE " + name() + " ALTER COLUMN chunk SET (n_distinct = " + nd + ")",
              "set n_distinct of " + shown(table) + ".chunk");
    }
    create("CREATE INDEX " + index("_chunks_box") + " ON " + name("_chunks") + " USING gist (box)",
           table + "_chunks_box");
    db.exec("COMMIT", "commit");
    db.exec("ANALYZE " + name() + "; ANALYZE " + name("_chunks"), "analyze " + shown(table));
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
  PgImport im(table, options);
  im.connect(conninfo);
  const std::unique_ptr<SiteStream> site = open_site(paths, options);
  im.attach(*site);
  im.sum.sources = site->sources();
  im.begin();
  if (options.pcpatch) {
    im.import_pcpatch();
  } else {
    im.create_point_tables();
    im.copy_chunks(im.copy_points());
    im.finish_indexes();
  }
  im.progress->done();
  return im.sum;
}

}  // namespace rayscan::sql
