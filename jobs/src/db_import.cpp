// The database import job (rayscan/jobs/db_import.hpp): options checked, then the SQL library's
// import into SQLite or PostgreSQL.
#include "rayscan/jobs/db_import.hpp"

#include "rayscan/analysis/site_location.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/sql/import.hpp"

#include <ogr_spatialref.h>

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

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

/// The SQL functions take x, y and z as lengths in one unit of a frame with z up (dist_ray, a
/// radius, ray_time's t): in a geographic CRS x and y are degrees beside heights in metres, in a
/// geocentric one z is not up, so the values mix units or axes. One warning per such CRS (the
/// inputs of one index share theirs), naming its first source and the CRS (its name as GDAL reads
/// it, and its EPSG code where io identifies one), with the wording of the analyses' refusal
/// (analysis::refuse_unprojected_crs).
std::vector<std::string> unprojected_crs_warnings(const std::vector<sql::SourceRow>& sources) {
  std::vector<std::string> warnings, seen;
  for (const sql::SourceRow& s : sources) {
    if (std::find(seen.begin(), seen.end(), s.crs_wkt) != seen.end()) continue;
    seen.push_back(s.crs_wkt);
    try {
      analysis::refuse_unprojected_crs(s.crs_wkt, "the SQL functions' distances, radii and times");
    } catch (const std::invalid_argument& e) {
      OGRSpatialReference srs;
      srs.importFromWkt(s.crs_wkt.c_str());  // read already by refuse_unprojected_crs
      std::string crs = srs.GetName() ? srs.GetName() : "";
      // io's codes are those of a horizontal CRS; a geocentric one's is the WKT's own authority
      // (EPSG:4978 and EPSG:4326 are both named "WGS 84").
      int epsg = io::epsg_codes_from_wkt(s.crs_wkt).horizontal;
      const char* authority = srs.GetAuthorityName(nullptr);
      const char* code = srs.GetAuthorityCode(nullptr);
      if (epsg == 0 && authority && code && std::string_view(authority) == "EPSG") epsg = std::atoi(code);
      if (epsg > 0) crs += (crs.empty() ? "EPSG:" : ", EPSG:") + std::to_string(epsg);
      warnings.push_back(s.path + (crs.empty() ? "" : " (" + crs + ")") + ": " + e.what());
    }
  }
  return warnings;
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
  return {s.points, s.chunks, unprojected_crs_warnings(s.sources)};
}

}  // namespace rayscan::jobs
