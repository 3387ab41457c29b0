// The CLI's spelling of the index, translate and db import jobs' option errors: the messages the
// command line printed before these jobs moved into the library, byte for byte.
#include <gtest/gtest.h>

#include "../common/run_command.hpp"
#include "jobs_test_util.hpp"

#include <filesystem>
#include <string>

using rayscan::test::data_file;
using rayscan::test::run_command;
using rayscan::test::temp_dir;

namespace {

/// `p` in single quotes, for the shell.
std::string quoted(const std::filesystem::path& p) {
  std::string q = "'";
  q += p.string();
  q += '\'';
  return q;
}

/// Runs `rayscan ARGS` and returns its exit code and the output of stdout and stderr.
rayscan::test::CommandResult rayscan_cli(const std::string& args) {
  return run_command(quoted(RAYSCAN_BIN) + " " + args);
}

}  // namespace

TEST(JobCli, IndexErrorsAsBefore) {
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string idx = (temp_dir() / "x.idx").string();
  auto r = rayscan_cli("index -q " + las + " -o '" + idx + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: " + idx + ": the index file name must end in .rsi\n");
  const std::string rsi = (temp_dir() / "x.rsi").string();
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --memory 10Q");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: size '10Q': expected a positive number with an optional K, M, G or T suffix\n");
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --attributes colour");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out,
            "rayscan index: attribute 'colour': expected rgb, intensity, classification, gps_time, normals, "
            "scalars, id, all or none\n");
  r = rayscan_cli("index -q " + las + " -o '" + rsi + "' --layout layered");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan index: --layout layered: not supported by the external-memory index build (use adaptive or fixed)\n");
}

TEST(JobCli, DbImportErrorsAsBefore) {
  const std::string las = quoted(data_file("las/point-color.las"));
  const std::string out = quoted(temp_dir() / "x.sqlite");
  auto r = rayscan_cli("db import " + las);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: give exactly one of -o FILE.sqlite and --postgres CONNINFO\n");
  r = rayscan_cli("db import " + las + " -o " + out + " --memory 10Q");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --memory: size '10Q': expected a positive number with an optional K, M, G or T suffix\n");
  r = rayscan_cli("db import " + las + " -o " + out + " --pcpatch");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan db: --pcpatch needs --postgres CONNINFO\n");
}
