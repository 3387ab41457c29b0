// Commands ended by a signal leave nothing behind (docs/cli.md, "Outputs"): the real `rayscan`
// program is started on a cloud large enough to run for a while, its output folder is watched,
// and the signal is sent as soon as the first temporary appears there (the output's temporary,
// the COPC records file, the sort runs). The oracles are the wait status (ended by that signal:
// a shell reports 128 + its number) and the folder, which must be empty again.
#include "jobs_test_util.hpp"

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
#include <vector>

namespace rayscan::test {
namespace {

namespace fs = std::filesystem;

/// Starts `rayscan ARGS` (standard streams to /dev/null), sends `sig` as soon as an entry appears
/// in the empty folder `out_dir`, and returns the wait status; the status of a command that ended
/// before anything appeared is a test failure.
int run_and_signal(const std::vector<std::string>& args, const fs::path& out_dir, int sig) {
  std::vector<char*> argv{const_cast<char*>(RAYSCAN_BIN)};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    // A signal ignored by the test's own starter would stay ignored in the command.
    for (const int s : {SIGINT, SIGTERM, SIGHUP}) ::signal(s, SIG_DFL);
    const int null = ::open("/dev/null", O_RDWR);
    for (const int fd : {0, 1, 2}) ::dup2(null, fd);
    ::execv(RAYSCAN_BIN, argv.data());
    ::_exit(127);
  }
  // A guard against a hang only: the signal goes out when the first file appears.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  int status = 0;
  while (rayscan::test::entry_names(out_dir).empty()) {
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ADD_FAILURE() << "the command ended before a file appeared (status " << status << ")";
      return status;
    }
    if (std::chrono::steady_clock::now() > deadline) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ::kill(pid, sig);
  ::waitpid(pid, &status, 0);
  return status;
}

class InterruptCli : public ::testing::Test {
 protected:
  /// 1.5e6 uniform points (LAS, about 45 MB, and the same as LAZ), written once for every case:
  /// each command below takes about a second on them, far longer than the reaction to the first
  /// file.
  static void SetUpTestSuite() {
    dir_ = temp_dir() / "interrupt";
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "in");
    PointCloud pc;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1000.0);
    pc.positions.resize(1500000);
    for (auto& p : pc.positions) p = Vec3(u(rng), u(rng), 0.01 * u(rng));
    io::LasWriteOptions o;
    o.scale = Vec3(0.001);
    io::write_las(in("big.las"), pc, o);
    io::write_las(in("big.laz"), pc, o);
    std::ofstream(in("ray.csv")) << "ox,oy,oz,dx,dy,dz\n500,500,100,0,0,-1\n";
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string in(const std::string& name) { return (dir_ / "in" / name).string(); }

  /// A fresh empty output folder for one case.
  static fs::path out_dir(const std::string& name) {
    const fs::path d = dir_ / name;
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
  }

  /// Runs the case and checks: ended by `sig`, the output folder empty, the inputs untouched.
  static void expect_clean_end(const std::vector<std::string>& args, const fs::path& out, int sig) {
    const int status = run_and_signal(args, out, sig);
    ASSERT_TRUE(WIFSIGNALED(status)) << "status " << (WIFEXITED(status) ? WEXITSTATUS(status) : status);
    EXPECT_EQ(WTERMSIG(status), sig) << "a shell would report " << 128 + WTERMSIG(status);
    EXPECT_EQ(rayscan::test::entry_names(out), std::set<std::string>{});
    EXPECT_EQ(rayscan::test::entry_names(dir_ / "in"), (std::set<std::string>{"big.las", "big.laz", "ray.csv"}));
  }

  static fs::path dir_;
};

fs::path InterruptCli::dir_;

TEST_F(InterruptCli, TranslateToLazLeavesNoTemporary) {
  const fs::path out = out_dir("laz");
  expect_clean_end({"translate", "-q", in("big.las"), (out / "o.laz").string()}, out, SIGINT);
}

TEST_F(InterruptCli, TranslateToTextLeavesNoTemporary) {
  const fs::path out = out_dir("csv");
  expect_clean_end({"translate", "-q", in("big.las"), (out / "o.csv").string()}, out, SIGHUP);
}

TEST_F(InterruptCli, TranslateToCopcLeavesNoRecordsFileNorTemporary) {
  // A LAZ input is decoded into a records file in the output's folder first: the signal comes
  // while that file is being written or used.
  const fs::path out = out_dir("copc");
  expect_clean_end({"translate", "-q", in("big.laz"), (out / "o.copc.laz").string()}, out, SIGTERM);
}

TEST_F(InterruptCli, DbImportLeavesNoSortRunsNorTemporary) {
  const fs::path out = out_dir("db");
  expect_clean_end({"db", "import", "-q", in("big.las"), "-o", (out / "o.sqlite").string()}, out, SIGINT);
}

TEST_F(InterruptCli, QueryLeavesNoTemporary) {
  // --all on a ray through every point's column: 1.5e6 rows to write.
  const fs::path out = out_dir("query");
  expect_clean_end({"query", "-q", "--cloud", in("big.las"), "--rays", in("ray.csv"), "--all", "-o",
                    (out / "o.csv").string()},
                   out, SIGTERM);
}

TEST_F(InterruptCli, TheSameCommandsNotInterruptedWriteTheirOutputs) {
  // The signal, not the options, stopped them: each writes exactly its output when left to run.
  const struct {
    std::vector<std::string> args;
    std::string output;
  } cases[] = {
      {{"translate", "-q", in("big.las"), "o.laz"}, "o.laz"},
      {{"translate", "-q", in("big.las"), "o.csv"}, "o.csv"},
      {{"translate", "-q", in("big.laz"), "o.copc.laz"}, "o.copc.laz"},
      {{"db", "import", "-q", in("big.las"), "-o", "o.sqlite"}, "o.sqlite"},
      {{"query", "-q", "--cloud", in("big.las"), "--rays", in("ray.csv"), "--all", "-o", "o.csv"}, "o.csv"},
  };
  for (const auto& c : cases) {
    const fs::path out = out_dir("whole");
    std::string cmd = "cd ";
    cmd += test::quoted(out);
    cmd += " && ";
    cmd += test::quoted(RAYSCAN_BIN);
    for (const std::string& a : c.args) {
      cmd += ' ';
      cmd += test::quoted(fs::path(a));
    }
    const CommandResult r = run_command(cmd + " > /dev/null");
    EXPECT_EQ(r.code, 0) << cmd << "\n" << r.out;
    EXPECT_EQ(rayscan::test::entry_names(out), std::set<std::string>{c.output}) << cmd;
  }
}

}  // namespace
}  // namespace rayscan::test
