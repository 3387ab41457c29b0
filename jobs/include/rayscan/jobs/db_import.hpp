// The database import job: point clouds into SQLite or PostgreSQL as Morton-ordered chunks with an
// index of chunk bounds, for the SQL functions dist_ray / dist_plane (paper section 4.2,
// docs/sql.md). `rayscan db import` runs it. Defined in the library rayscan_jobs_db (rayscan_jobs
// plus the SQL import library and the database clients), which the `rayscan` program links; the
// installed CMake package does not carry it.
#pragma once

#include "rayscan/base/job.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace rayscan::jobs {

/// Inputs of run_db_import(). Exactly one of `out` (SQLite) and `postgres` is set.
struct DbImportJobOptions {
  std::vector<std::filesystem::path> clouds;  ///< point cloud files in one world frame
  std::filesystem::path out;  ///< the SQLite file to write (replaced atomically); empty with `postgres`
  std::string postgres;       ///< libpq connection string (PostgreSQL); empty with `out`
  std::string table = "points";  ///< PostgreSQL table name (a lower-case SQL identifier)
  /// Default points per chunk (sql::ImportOptions::kDefaultChunkSize; bench/README.md, "SQL ray
  /// queries", for why 512).
  static constexpr std::uint32_t kDefaultChunkSize = 512;
  std::uint32_t chunk_size = kDefaultChunkSize;  ///< points per chunk (>= 1)
  /// Extra columns: intensity, classification, gps_time, rgb (red, green, blue) or a scalar
  /// field's name.
  std::vector<std::string> attributes;
  bool pcpatch = false;  ///< PostgreSQL only: one pgpointcloud patch per chunk instead of rows
  /// Called with (phase, points done, points in total): the temporary index's phases, then
  /// "insert", "index" and "done", the last report (sql::ImportOptions::progress). May be empty.
  std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)> progress;
  /// Memory budget of the external Morton sort, a byte size as parse_byte_size reads it ("4G",
  /// "512M"); empty = that of the index job (4G).
  std::string memory;
  /// Folder of the temporary index file and its sort runs; empty = the SQLite output's folder, or
  /// the system's temporary folder for PostgreSQL.
  std::filesystem::path temp_dir;
  JobControl control;  ///< the jobs' common controls; run_db_import reads none (progress: above)
};

/// Output of run_db_import().
struct DbImportJobResult {
  std::uint64_t points = 0;  ///< rows (points) written
  std::uint64_t chunks = 0;  ///< chunks written (R*Tree / chunk table rows)
  /// One line per geographic or geocentric CRS of the inputs, naming the first file with it and
  /// the CRS: the SQL functions' distances, radii and times would mix degrees with heights
  /// or take an axis that is not up (the import writes the points all the same).
  std::vector<std::string> warnings;
};

/// Checks the options and imports the clouds (sql::import_sqlite or sql::import_postgres: the
/// schema is in docs/sql.md). Throws OptionError naming "out" and "postgres" unless exactly one is
/// set, "memory" for a malformed byte size, "pcpatch" without `postgres`, and the import's own
/// (e.g. "chunk_size", "table", "memory_bytes"); std::invalid_argument for bad attribute names or
/// attributes a cloud lacks; io::FormatError for unreadable clouds; std::runtime_error for
/// database errors ("site.sqlite: sqlite: ...", "postgres: ..."). A failed import leaves no
/// partial output (SQLite: the previous file or none; PostgreSQL: the transaction rolled back).
DbImportJobResult run_db_import(const DbImportJobOptions& options);

}  // namespace rayscan::jobs
