// A write that fails (a full disk) is reported as one line naming the output the user asked for
// and the system's cause, never a hidden temporary (an AtomicFile's ".<name>.tmp.<pid>", the
// uncompressed LAS before a LAZ output, COPC records, index sort runs), and leaves the old output
// and no temporary behind: the LAS and LAZ writers, translate_las, the COPC writer and the index
// build. The failure is made deterministic with a file-size limit (RLIMIT_FSIZE with SIGXFSZ
// ignored: a write past it fails with EFBIG where a full disk fails with ENOSPC).
#include "../common/file_size_limit.hpp"
#include "../io/io_test_util.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/translate.hpp"
#include "rayscan/site/copc_writer.hpp"
#include "rayscan/site/index_file.hpp"

#include <sys/resource.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>

namespace rayscan::test {
namespace {

/// A folder holding only `name`, with the content "OLD".
fs::path folder_with_old(const std::string& folder, const std::string& name) {
  const fs::path dir = fresh_temp_dir(folder);
  std::ofstream(dir / name) << "OLD";
  return dir;
}

/// `error` is one line "<out>: write failed...: <EFBIG's text>" naming no temporary; `out` still
/// holds "OLD" and is the only entry of its folder.
void expect_failure_names_output(const std::string& error, const fs::path& out) {
  EXPECT_EQ(failure_names_only_output(error, out, "write failed"), "");
}

constexpr rlim_t kLimit = 64 << 10;  // far below every output here (autzen: 110,000 points)

TEST(OutputErrors, LasAndLazWritersNameTheOutput) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  const PointCloud cloud = io::read_point_cloud(las);
  for (const char* name : {"x.las", "x.laz"}) {  // x.laz: its uncompressed LAS fails first
    SCOPED_TRACE(name);
    const fs::path out = folder_with_old("rayscan_output_errors_las", name) / name;
    expect_failure_names_output(error_within_file_size(kLimit, [&] { io::write_las(out, cloud); }), out);
  }
  // translate_las's own writer (LAS copied, LAZ compressed), with the cause as well.
  for (const char* name : {"t.las", "t.laz"}) {
    SCOPED_TRACE(name);
    const fs::path out = folder_with_old("rayscan_output_errors_translate", name) / name;
    expect_failure_names_output(error_within_file_size(kLimit, [&] { (void)io::translate_las(las, out, {}); }), out);
  }
  fs::remove_all(fresh_temp_dir("rayscan_output_errors_las"));
  fs::remove_all(fresh_temp_dir("rayscan_output_errors_translate"));
}

TEST(OutputErrors, CopcWriterNamesTheOutput) {
  RAYSCAN_REQUIRE_FILE(legacy, "las/autzen_trim.las");  // PDRF 3: converted into a records file first
  RAYSCAN_REQUIRE_FILE(pdrf7, "las/autzen_trim_7.las");   // PDRF 7: mapped; the COPC file itself fails
  for (const fs::path& in : {legacy, pdrf7}) {
    SCOPED_TRACE(in.string());
    const fs::path out = folder_with_old("rayscan_output_errors_copc", "x.copc.laz") / "x.copc.laz";
    expect_failure_names_output(error_within_file_size(kLimit, [&] { (void)io::write_copc(in, out); }), out);
  }
  fs::remove_all(fresh_temp_dir("rayscan_output_errors_copc"));
}

TEST(OutputErrors, IndexBuildNamesTheOutputInEveryStage) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  io::IndexBuildOptions in_memory;  // one run: the output's sections fail
  io::IndexBuildOptions runs;       // sorted runs on disk: the first run fails
  runs.memory_bytes = 1 << 20;
  for (const io::IndexBuildOptions& opt : {in_memory, runs}) {
    SCOPED_TRACE(opt.memory_bytes);
    const fs::path out = folder_with_old("rayscan_output_errors_rsi", "x.rsi") / "x.rsi";
    const std::string error = error_within_file_size(kLimit, [&] { (void)io::build_index_file({las}, out, opt); });
    expect_failure_names_output(error, out);
    EXPECT_EQ(error.find(".runs."), std::string::npos) << error;
  }
  // Runs in another folder (IndexBuildOptions::temp_dir): that folder is the one that is full,
  // and the message says so.
  const fs::path out = folder_with_old("rayscan_output_errors_rsi", "x.rsi") / "x.rsi";
  const fs::path elsewhere = fresh_temp_dir("rayscan_output_errors_runs");
  runs.temp_dir = elsewhere;
  const std::string error = error_within_file_size(kLimit, [&] { (void)io::build_index_file({las}, out, runs); });
  EXPECT_EQ(error.rfind(out.string() + ": write failed at byte ", 0), 0u) << error;
  EXPECT_NE(error.find(" (temporary file in '" + elsewhere.string() + "'): " + std::strerror(EFBIG)), std::string::npos)
      << error;
  EXPECT_TRUE(fs::is_empty(elsewhere));
  fs::remove_all(out.parent_path());
  fs::remove_all(elsewhere);
}

}  // namespace
}  // namespace rayscan::test
