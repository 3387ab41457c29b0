// `rayscan db import`: clouds into a database as Morton-ordered chunks. Library code;
// tools/cmd_db.cpp only parses options and prints.
#pragma once

#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/sql/chunking.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace rayscan::sql {

/// Options shared by both engines.
struct ImportOptions {
  /// Default points per chunk. 512 rather than 4096: a radius query with r at the point spacing
  /// then reads ~0.35% of the chunks of a 0.7 M-point scan (2.2% at 4096) and SQLite's ray_query
  /// costs ~15-18x the in-memory octree (38x at 4096); bench/README.md, "SQL ray queries".
  static constexpr std::uint32_t kDefaultChunkSize = 512;
  std::uint32_t chunk_size = kDefaultChunkSize;  ///< points per chunk (>= 1)
  std::vector<std::string> attributes;  ///< extra columns: intensity, classification, gps_time,
                                        ///< rgb (red, green, blue) or any scalar field's name
  bool pcpatch = false;  ///< PostgreSQL only: one pgpointcloud patch per chunk instead of rows
  /// Memory budget (bytes) of the external Morton sort that orders the points (the temporary
  /// index file of open_site(); io::IndexBuildOptions::memory_bytes).
  std::uint64_t memory_bytes = io::IndexBuildOptions{}.memory_bytes;
  /// Folder of the temporary index file and its sort runs. Empty: SQLite uses the output file's
  /// folder, PostgreSQL the system's temporary folder.
  std::filesystem::path temp_dir;
  /// Called with (phase, points done, points in total) as the import goes, in this order: the
  /// temporary index's phases (io::IndexBuildOptions::progress: scan, read, sort, write or merge,
  /// nodes; not its "spacing", a sample count the import does not use, nor its "done"), then the
  /// import's own (ImportProgress): "insert", "index" and "done", the last report of the import.
  /// May be empty.
  io::IndexProgress progress;
};

/// Reports the import's own phases through ImportOptions::progress, each in points of the site:
/// "insert" from construction on (0 of total; then after each chunk, whenever the count crosses a
/// multiple of 2^21 points or reaches the total: insert(n)), "index" (index(): the indexes over
/// the inserted points, reported at its start) and "done" (done(): everything committed; the
/// total). A phase starts at its first report, so each gets its own time.
class ImportProgress {
 public:
  ImportProgress(const ImportOptions& o, std::uint64_t total) : progress_(o.progress), total_(total) {
    report("insert", 0);
  }
  /// n more rows inserted.
  void insert(std::uint64_t n) {
    const std::uint64_t before = done_;
    done_ += n;
    if (before >> 21 != done_ >> 21 || done_ == total_) report("insert", done_);
  }
  /// The inserts are over; the indexes are being built.
  void index() { report("index", 0); }
  /// The import is complete.
  void done() { report("done", total_); }

 private:
  void report(const char* phase, std::uint64_t n) const {
    if (progress_) progress_(phase, n, total_);
  }
  const io::IndexProgress& progress_;
  std::uint64_t total_, done_ = 0;
};

/// Whether s has the form of an SQL regular identifier, restricted to ASCII (SQL:2016 section 5.2):
/// a letter or '_', then letters, digits or '_' (upper-case letters only with allow_upper:
/// PostgreSQL folds unquoted names to lower case), at most max_len characters (PostgreSQL keeps
/// 63: NAMEDATALEN - 1). Key words are not excluded: callers that emit s unquoted only accept
/// names they know.
[[nodiscard]] bool is_sql_identifier(const std::string& s, std::size_t max_len, bool allow_upper);

/// The name PostgreSQL folds an unquoted identifier to, and the one SQLite compares names by:
/// ASCII upper case to lower case.
[[nodiscard]] std::string folded_sql_name(std::string name);

/// The second half of the identifier check (the first is is_sql_identifier): why `name`, compared
/// without case, cannot name a table (column = false) or a column (column = true) of an import, or
/// "" when it can. Refused: the engines' own column names (SQLite's row id rowid, oid, _rowid_: a
/// column so named would be the row id; PostgreSQL's system columns tableoid, xmin, cmin, xmax,
/// cmax, ctid, oid), for columns only, and PostgreSQL's reserved key words (select, order, user,
/// ...), which would need quotes in every query. The message reads "'rowid' is SQLite's row id
/// (reserved column names: ...)".
[[nodiscard]] std::string reserved_sql_name(const std::string& name, bool column);

/// One extra column of the points table.
struct AttributeColumn {
  std::string name;  ///< column name (an SQL identifier: [A-Za-z_][A-Za-z0-9_]*)
  bool integer;      ///< INTEGER (true) or REAL / double precision
  /// Value of point i of a cloud (integers are exact in a double).
  std::function<double(const PointCloud&, std::size_t)> value;
};

/// Checks the requested attribute names (`--attributes`) before an import reads anything: each an
/// SQL identifier (is_sql_identifier, 63 characters) that no engine reserves (reserved_sql_name),
/// and no two columns they make ("rgb": red,
/// green, blue; any other name: itself) equal but for case to each other or to a built-in column
/// (point_index, source, chunk, x, y, z), since PostgreSQL folds unquoted names to lower case and
/// SQLite compares names without case: e.g. an attribute asked twice, "GpsTime" with "gpstime",
/// "X" with x, a scalar "red" with rgb. With `pcpatch` (ImportOptions::pcpatch) the pgpointcloud
/// schema's PointIndex dimension is built in too. Throws std::invalid_argument naming the
/// attribute and the column it would collide with.
void check_attribute_names(const std::vector<std::string>& names, bool pcpatch = false);

/// Resolves the requested attribute names against every cloud. Throws std::invalid_argument
/// ("<file>: attribute 'gps_time' requested but the file has none") when a cloud lacks one, or
/// as check_attribute_names for the names themselves.
[[nodiscard]] std::vector<AttributeColumn> resolve_attributes(
    const std::vector<std::string>& names, const std::vector<std::filesystem::path>& paths,
    const std::vector<PointCloud>& clouds);

/// One input file of the site: the `sources` table row.
struct SourceRow {
  std::string path;         ///< as given on the command line (or as stored in an index file)
  std::uint64_t points = 0; ///< points read from it
  std::string crs_wkt;      ///< "" when unknown
};

/// What an import wrote.
struct ImportSummary {
  std::uint64_t points = 0;  ///< rows in the points table
  std::uint64_t chunks = 0;  ///< chunks (R*Tree / chunk table rows)
  std::vector<SourceRow> sources;  ///< the `sources` table's rows, in source order
};

/// Imports `clouds` into a new SQLite file `out` (replaced atomically: a temporary file renamed
/// into place, so a failed import leaves the old file or none). Schema (docs/sql.md):
///   points(point_index, source, chunk, x, y, z, <attributes>), rowid = 1 + row in Morton order;
///   chunks: R*Tree (id, min_x, max_x, min_y, max_y, min_z, max_z, +first_row, +count) whose
///   float32 boxes SQLite rounds outwards, so they stay conservative;
///   chunk_points(id = chunk, data BLOB): the chunk's points packed as PackedPoint (what ray_query
///   reads: one b-tree lookup per chunk instead of one row per point);
///   sources(source, path, point_count, crs_wkt); rayscan_meta(key, value).
/// Throws io::FormatError for unreadable clouds, std::invalid_argument for bad options and
/// std::runtime_error ("site.sqlite: sqlite: <message>") for database errors.
ImportSummary import_sqlite(const std::vector<std::filesystem::path>& clouds,
                            const std::filesystem::path& out, const ImportOptions& options);

/// Imports `clouds` into PostgreSQL (libpq CONNINFO) as plain rows in one transaction:
///   <table>(point_index bigint, source int, chunk int, x, y, z float8, <attributes>),
///   <table>_chunks(chunk int primary key, box rs_box, first_row bigint, count int) with a GiST
///   index on box (extension rayscan) and <table>_sources(source, path, point_count, crs_wkt: the
///   CRS as WKT, NULL when unknown). A failure rolls the transaction back: no half table.
/// With options.pcpatch: pgpointcloud instead of rows (extension `pointcloud`): a new schema in
///   pointcloud_formats (dimensions X, Y, Z double, PointIndex uint64_t, Source uint32_t, then the
///   attributes as double / int64_t; scale 1, uncompressed; srid the sources' EPSG code, 0 when
///   none is identified) and <table>(chunk int primary key, pa pcpatch(pcid), box rs_box) with a
///   GiST index on box: one patch per chunk, written as uncompressed patch WKB (pgpointcloud
///   README, "Binary Formats"), and <table>_sources.
/// Every table lives in the connection's current_schema() (the first existing schema of its
/// search_path) and every statement names it schema-qualified and quoted, so `--table pg_class`
/// writes <schema>.pg_class and never the catalog's; the extensions' types and tables are named
/// with the extensions' own schemas (pg_extension), and an extension the database lacks is
/// created in public (docs/sql.md). `table` must be a lower-case identifier of at most 50
/// characters that reserved_sql_name accepts (OptionError "table" otherwise, before anything is
/// read); attribute columns are the folded (lower-case) names.
/// Throws as import_sqlite; std::runtime_error for server errors, one line: "postgres: table
/// <schema>.<table> exists: choose another --table or drop it" (checked before the clouds are
/// read), "postgres: cannot connect: <libpq's message>", "postgres: <what failed>: <the server's
/// primary message>".
ImportSummary import_postgres(const std::vector<std::filesystem::path>& clouds,
                              const std::string& conninfo, const std::string& table,
                              const ImportOptions& options);

}  // namespace rayscan::sql
