// The database import job (rayscan/jobs/db_import.hpp): options checked, then the SQL library's
// import into SQLite or PostgreSQL.
#include "rayscan/jobs/db_import.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/sql/import.hpp"

#include <stdexcept>

namespace rayscan::jobs {

static_assert(DbImportJobOptions::kDefaultChunkSize == sql::ImportOptions::kDefaultChunkSize);

namespace {

/// The import's options from the job's. Throws OptionError for the options run_db_import() names.
sql::ImportOptions import_options(const DbImportJobOptions& o) {
  if (o.postgres.empty() == o.out.empty())
    throw OptionError({"give exactly one of ", option("out"), " FILE.sqlite and ", option("postgres"), " CONNINFO"});
  sql::ImportOptions opt;
  opt.chunk_size = o.chunk_size;
  opt.pcpatch = o.pcpatch;
  opt.temp_dir = o.temp_dir;
  try {
    if (!o.memory.empty()) opt.memory_bytes = parse_byte_size(o.memory);
  } catch (const std::invalid_argument& e) {
    throw OptionError({option("memory"), std::string(": ") + e.what()});
  }
  if (o.pcpatch && o.postgres.empty()) throw OptionError({option("pcpatch"), " needs ", option("postgres"), " CONNINFO"});
  opt.attributes = o.attributes;
  opt.progress = o.progress;
  return opt;
}

}  // namespace

DbImportJobResult run_db_import(const DbImportJobOptions& options) {
  const sql::ImportOptions opt = import_options(options);
  const std::filesystem::path out[] = {options.out};
  require_outputs(out, options.clouds);
  // A SQLite database under a point cloud's or an image's name would mislead every tool after.
  static const std::vector<std::string> kSqlite{".sqlite", ".sqlite3", ".db"};
  if (!options.out.empty() && !has_extension(options.out, kSqlite))
    throw OptionError({option("out"), " '" + options.out.string() + "': " + extensions_expected(kSqlite) +
                                          " (a SQLite database)"});
  const sql::ImportSummary s = options.postgres.empty()
                                   ? sql::import_sqlite(options.clouds, options.out, opt)
                                   : sql::import_postgres(options.clouds, options.postgres, options.table, opt);
  return {s.points, s.chunks};
}

}  // namespace rayscan::jobs
