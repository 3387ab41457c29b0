// `rayscan index` stopped by a signal (a build that fails or is interrupted leaves no file at
// the output path; a demanding user also expects no temporary output or sort runs left beside
// it). The real CLI is started on a real LAS file, signalled as soon as its temporary files exist,
// and the folder is then listed: the oracle is the file system.
#include "../common/temp_dir.hpp"
#include "../io/io_test_util.hpp"

#include "rayscan/io/point_io.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <thread>

namespace {

namespace fs = std::filesystem;

/// 2e6 uniform points in a 1 km box, as LAS (about 60 MB): enough for a build of many sort runs
/// with `--memory 8M`, so the signal arrives while it runs.
void write_site(const fs::path& las) {
  rayscan::PointCloud pc;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1000.0);
  pc.positions.resize(2000000);
  for (auto& p : pc.positions) p = rayscan::Vec3(u(rng), u(rng), 0.1 * u(rng));
  rayscan::io::LasWriteOptions o;
  o.scale = rayscan::Vec3(0.001);
  rayscan::io::write_las(las, pc, o);
}

/// Starts `rayscan index LAS -o OUT --memory 8M -q` (stderr to ERR), sends `sig` as soon as an
/// entry besides the LAS appears in the folder (the temporary output or the runs folder), and
/// returns the wait status.
int index_and_signal(const fs::path& dir, const fs::path& las, const fs::path& out, const fs::path& err, int sig) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 2);
      ::dup2(fd, 1);
    }
    ::execl(RAYSCAN_EXE, RAYSCAN_EXE, "index", las.c_str(), "-o", out.c_str(), "--memory", "8M", "-q",
            static_cast<char*>(nullptr));
    ::_exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  int status = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ADD_FAILURE() << "rayscan index ended before a temporary file was seen (status " << status << ")";
      return status;
    }
    if (rayscan::test::entry_names(dir).size() > 1) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(pid, sig);
  ::waitpid(pid, &status, 0);
  return status;
}

std::string slurp_text(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST(IndexInterrupt, SigtermAndSigintLeaveNoOutputAndNoTemporaryFiles) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_index_interrupt_sig");
  const fs::path las = dir / "site.las", out = dir / "site.rsi";
  const fs::path err = fs::temp_directory_path() / ("rayscan_index_interrupt_" + std::to_string(::getpid()) + ".err");
  write_site(las);
  for (const int sig : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(sig == SIGTERM ? "SIGTERM" : "SIGINT");
    const int status = index_and_signal(dir, las, out, err, sig);
    // The build unwound (the signal did not kill the process): exit code 128 + signal, the shell's
    // convention, and one line saying so.
    ASSERT_TRUE(WIFEXITED(status)) << "status " << status;
    EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
    const std::string text = slurp_text(err);
    EXPECT_NE(text.find(sig == SIGTERM ? "interrupted by SIGTERM" : "interrupted by SIGINT"), std::string::npos) << text;
    // Nothing left but the input: no index, no temporary output, no runs folder.
    EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{"site.las"});
  }
  // The same command not interrupted writes the index (the signal, not the options, stopped it).
  const std::string cmd = std::string(RAYSCAN_EXE) + " index " + las.string() + " -o " + out.string() + " --memory 8M -q > /dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_EQ(rayscan::test::entry_names(dir), (std::set<std::string>{"site.las", "site.rsi"}));
  fs::remove_all(dir);
  fs::remove(err);
}
