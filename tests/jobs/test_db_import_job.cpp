// The database import job (rayscan/jobs/db_import.hpp) into SQLite on a real file; oracle: the
// cloud read by the io reader and the tables read back through sqlite3.
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/db_import.hpp"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "jobs_test_util.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

using namespace rayscan;
using rayscan::test::data_file;
using rayscan::test::quoted;
using rayscan::test::run_command;
using rayscan::test::fields_of_option_error;
using rayscan::test::temp_dir;
namespace fs = std::filesystem;

namespace {

/// A read-only SQLite connection.
struct Db {
  sqlite3* db = nullptr;
  explicit Db(const fs::path& p) {
    if (sqlite3_open_v2(p.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK)
      throw std::runtime_error(p.string() + ": " + sqlite3_errmsg(db));
  }
  ~Db() { sqlite3_close(db); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  /// Calls row(stmt) for each row of `sql`.
  template <class F>
  void each(const std::string& sql, F&& row) const {
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
    int rc;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) row(st);
    EXPECT_EQ(rc, SQLITE_DONE) << sqlite3_errmsg(db);
    sqlite3_finalize(st);
  }
  /// The one integer `sql` returns.
  long long integer(const std::string& sql) const {
    long long v = -1;
    each(sql, [&v](sqlite3_stmt* st) { v = sqlite3_column_int64(st, 0); });
    return v;
  }
};

}  // namespace

TEST(DbImportJob, SqliteHoldsEveryPointOfTheFile) {
  const fs::path las = data_file("las/point-color.las"), out = temp_dir() / "site.sqlite";
  jobs::DbImportJobOptions o;
  o.clouds = {las};
  o.out = out;
  o.chunk_size = 100;
  o.attributes = {"intensity"};
  o.memory = "1M";
  const jobs::DbImportJobResult r = jobs::run_db_import(o);
  const PointCloud cloud = io::read_point_cloud(las);
  ASSERT_GT(cloud.size(), 0u);
  EXPECT_EQ(r.points, cloud.size());
  EXPECT_EQ(r.chunks, (cloud.size() + 99) / 100);

  const Db db(out);
  EXPECT_EQ(db.integer("SELECT count(*) FROM points"), static_cast<long long>(cloud.size()));
  EXPECT_EQ(db.integer("SELECT count(*) FROM chunks"), static_cast<long long>(r.chunks));
  EXPECT_EQ(db.integer("SELECT sum(count) FROM chunks"), static_cast<long long>(cloud.size()));
  std::vector<bool> seen(cloud.size(), false);
  db.each("SELECT point_index, x, y, z, intensity FROM points", [&](sqlite3_stmt* st) {
    const auto i = static_cast<std::size_t>(sqlite3_column_int64(st, 0));
    ASSERT_LT(i, cloud.size());
    EXPECT_FALSE(seen[i]) << "point " << i << " imported twice";
    seen[i] = true;
    EXPECT_EQ(Vec3(sqlite3_column_double(st, 1), sqlite3_column_double(st, 2), sqlite3_column_double(st, 3)),
              cloud.positions[i]);
    EXPECT_EQ(sqlite3_column_int64(st, 4), cloud.intensity[i]);
  });
}

TEST(DbImportJob, BadOptionsNameTheirFields) {
  const fs::path out = temp_dir() / "never.sqlite";
  jobs::DbImportJobOptions o;
  o.clouds = {data_file("las/point-color.las")};
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_db_import(o); }), (std::vector<std::string>{"out", "postgres"}));
  o.out = out;
  o.postgres = "dbname=x";
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_db_import(o); }), (std::vector<std::string>{"out", "postgres"}));
  o.postgres.clear();
  o.memory = "lots";
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_db_import(o); }), std::vector<std::string>{"memory"});
  o.memory.clear();
  o.pcpatch = true;
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_db_import(o); }), (std::vector<std::string>{"pcpatch", "postgres"}));
  o.pcpatch = false;
  o.chunk_size = 0;
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_db_import(o); }), std::vector<std::string>{"chunk_size"});
  EXPECT_FALSE(fs::exists(out));
}

// `rayscan db import` reports what it wrote on stdout, as `index` and `translate` do: one line of
// text, or with --json one JSON object; -q silences only the progress on stderr. Oracle: the
// tables' own counts read back through sqlite3 (1065 points in chunks of 100: 11 chunks).
TEST(DbImportCli, SummaryOnStdoutIsALineOfTextOrJson) {
  const std::string las = quoted(data_file("las/point-color.las"));
  const fs::path out = temp_dir() / "summary.sqlite";
  const std::string cmd = quoted(RAYSCAN_BIN) + " db import " + las + " -o " + quoted(out) + " --chunk 100 -q";
  auto r = run_command(cmd, false);
  ASSERT_EQ(r.code, 0) << r.out;
  long long points = 0, chunks = 0;
  {
    const Db db(out);
    points = db.integer("SELECT count(*) FROM points");
    chunks = db.integer("SELECT count(*) FROM chunks");
  }
  EXPECT_EQ(points, 1065);
  EXPECT_EQ(chunks, 11);
  EXPECT_EQ(r.out, out.string() + ": " + std::to_string(points) + " points in " + std::to_string(chunks) +
                       " chunks of at most 100\n");
  // -q: nothing on stderr (in a subshell, so that run_command's own redirection of standard error
  // applies outside it: stdout discarded, stderr captured).
  const auto quiet = run_command("( " + cmd + " 2>&1 >/dev/null )", false);
  EXPECT_EQ(quiet.code, 0);
  EXPECT_EQ(quiet.out, "");

  r = run_command(cmd + " --json", false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j, (nlohmann::json{{"points", points}, {"chunks", chunks}, {"chunk_size", 100}})) << r.out;
}
