// `rayscan db import`: clouds into SQLite (default) or PostgreSQL as Morton-ordered chunks with an
// index of chunk bounds (paper section 4.2). Parsing and printing only; the job is
// rayscan::jobs::run_db_import (rayscan/jobs/db_import.hpp).
#include "commands.hpp"
#include "option_names.hpp"
#include "phase_progress.hpp"
#include "processes.hpp"

#include "rayscan/base/number_text.hpp"
#include "rayscan/jobs/db_import.hpp"
#include "rayscan/jobs/index.hpp"

#include <nlohmann/json.hpp>

#include <iostream>
#include <memory>
#include <sstream>

namespace rayscan::cli {

namespace {

struct DbImportOptions {
  std::vector<std::string> clouds;
  std::string out, postgres, table = "points", attributes, temp_dir;
  std::string memory = jobs::IndexJobOptions{}.memory;  // (the import sorts as `rayscan index` does)
  std::uint32_t chunk = jobs::DbImportJobOptions::kDefaultChunkSize;
  bool pcpatch = false, quiet = false, json = false;
};

int run_import(const DbImportOptions& o) {
  jobs::DbImportJobOptions job;
  job.clouds.assign(o.clouds.begin(), o.clouds.end());
  job.out = o.out;
  job.postgres = o.postgres;
  job.table = o.table;
  job.chunk_size = o.chunk;
  job.pcpatch = o.pcpatch;
  job.memory = o.memory;
  job.temp_dir = o.temp_dir;
  std::stringstream ss(o.attributes);
  for (std::string a; std::getline(ss, a, ',');)
    if (!a.empty()) job.attributes.push_back(a);
  const PhaseProgress progress("db import", o.quiet);
  job.progress = progress;
  const jobs::DbImportJobResult s = jobs::run_db_import(job);
  progress.finish();
  for (const std::string& w : s.warnings) std::cerr << "rayscan db: warning: " << w << "\n";
  // What was written, on stdout as `index` and `translate` report theirs; --json as the commands
  // with a report give it.
  if (o.json) {
    nlohmann::ordered_json j = {{"points", s.points}, {"chunks", s.chunks}, {"chunk_size", o.chunk}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << (o.postgres.empty() ? o.out : "PostgreSQL table " + o.table) << ": " << count_text(s.points, "point")
              << " in " << count_text(s.chunks, "chunk") << " of at most " << o.chunk << "\n";
  }
  return 0;
}

}  // namespace

Runner add_db_command(CLI::App& app) {
  auto o = std::make_shared<DbImportOptions>();
  CLI::App* db = app.add_subcommand("db", "Databases: import clouds for the SQL functions "
                                          "dist_ray / dist_plane (paper section 4.2)");
  db->require_subcommand(1);
  CLI::App* c = db->add_subcommand(
      "import", "Write clouds as Morton-ordered chunks plus an index of chunk bounds: SQLite "
                "(points table + R*Tree 'chunks') or PostgreSQL (TABLE + TABLE_chunks with GiST)");
  c->add_option("CLOUD", o->clouds, "Point cloud files (one world frame)")->required();
  c->add_option("-o,--out", o->out, "Output SQLite file (replaced atomically)");
  c->add_option("--postgres", o->postgres, "libpq connection string (instead of -o)");
  CLI::Option* table = c->add_option("--table", o->table, "PostgreSQL table name (with --postgres)")->capture_default_str();
  c->add_option(option_names("db", "chunk_size"), o->chunk, "Points per chunk")
      ->capture_default_str()
      ->transform(integer_in(1, 1 << 24));
  c->add_flag("--pcpatch", o->pcpatch,
              "PostgreSQL: one pgpointcloud patch (pcpatch, double X/Y/Z) per chunk in TABLE, with "
              "its box, instead of rows");
  c->add_option("--memory", o->memory,
                "memory budget of the external Morton sort (e.g. 4G, 512M): the clouds are ordered "
                "through a temporary index file, so memory stays bounded whatever their size; "
                "default: that of rayscan index")
      ->capture_default_str();
  c->add_option("--temp-dir", o->temp_dir,
                "folder of the temporary index file and sort runs (default: the SQLite output's "
                "folder, or the system temporary folder for --postgres)");
  c->add_option("--attributes", o->attributes,
                "Comma-separated extra columns: intensity, classification, gps_time, rgb or a "
                "scalar field name");
  c->add_flag("-q,--quiet", o->quiet, "no progress on stderr");
  c->add_flag("--json", o->json,
              "Print the summary on stdout as JSON (points, chunks, chunk_size) instead of a line of text");
  return [o, table] {
    require_single_process("rayscan db import");
    // A SQLite import writes the tables points and chunks: a --table there would have no effect.
    if (table->count() > 0 && o->postgres.empty())
      throw UsageError("--table names the PostgreSQL table (with --postgres); a SQLite import (-o) writes the "
                       "tables points and chunks");
    return run_import(*o);
  };
}

}  // namespace rayscan::cli
