// The interrupt handler (rayscan/base/interrupt.hpp) in a child process that installs it, marks
// paths and signals itself: the oracles are the file system (what is left in the folder) and the
// child's wait status (ended by the signal, or exited).
#include "../common/temp_dir.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/interrupt.hpp"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

namespace {

namespace fs = std::filesystem;
using rayscan::RemoveOnInterrupt;

void touch(const fs::path& p) { std::ofstream(p) << "x"; }

/// Runs `body` in a child process (which ends with exit code 0 if `body` returns) and returns the
/// child's wait status.
template <class F>
int in_child(F body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    // The test may have been started with a signal ignored; the handler keeps such a signal ignored.
    for (const int s : {SIGINT, SIGTERM, SIGHUP}) ::signal(s, SIG_DFL);
    body();
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

}  // namespace

TEST(Interrupt, SignalRemovesTheMarkedPathsOnlyAndEndsTheProcessByIt) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_marks");
  const int status = in_child([&] {
    rayscan::install_interrupt_handler();
    touch(dir / "unmarked");
    RemoveOnInterrupt file(dir / "file");
    touch(dir / "file");
    // A folder of more entries than one getdents64 buffer holds.
    RemoveOnInterrupt folder(dir / "runs", RemoveOnInterrupt::Kind::folder);
    fs::create_directory(dir / "runs");
    for (int i = 0; i < 400; ++i) touch(dir / "runs" / ("run" + std::to_string(i)));
    {
      RemoveOnInterrupt released(dir / "released");  // its mark ends before the signal: kept
      touch(dir / "released");
    }
    RemoveOnInterrupt from(dir / "moved");
    touch(dir / "moved");
    const RemoveOnInterrupt moved = std::move(from);  // the mark moves with it
    // An AtomicFile's temporary, and one handed to an OutputTransaction by an AtomicFile that is gone.
    const rayscan::AtomicFile out(dir / "out.txt");
    rayscan::OutputTransaction tx;
    {
      rayscan::AtomicFile in_tx(dir / "tx.txt");
      const unsigned char bytes[] = {'x'};
      in_tx.write_all(bytes);
      in_tx.commit();
    }
    if (rayscan::test::entry_names(dir).size() != 7) ::_exit(3);  // the files exist before the signal
    ::raise(SIGTERM);
    ::_exit(4);  // not reached
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << "status " << status;
  EXPECT_EQ(WTERMSIG(status), SIGTERM);
  EXPECT_EQ(rayscan::test::entry_names(dir), (std::set<std::string>{"released", "unmarked"}));
  fs::remove_all(dir);
}

TEST(Interrupt, DeferredFirstSignalIsOnlyRecordedTheSecondEndsTheProcess) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_deferred");
  const int status = in_child([&] {
    rayscan::install_interrupt_handler();
    rayscan::defer_interrupts();
    RemoveOnInterrupt file(dir / "file");
    touch(dir / "file");
    if (rayscan::pending_interrupt() != 0) ::_exit(3);
    ::raise(SIGINT);
    if (rayscan::pending_interrupt() != SIGINT || !fs::exists(dir / "file")) ::_exit(4);
    ::raise(SIGHUP);
    ::_exit(5);  // not reached
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << "status " << (WIFEXITED(status) ? WEXITSTATUS(status) : status);
  EXPECT_EQ(WTERMSIG(status), SIGHUP);
  EXPECT_TRUE(rayscan::test::entry_names(dir).empty());
  fs::remove_all(dir);
}

// IntermediateFile, a file or a folder of files (COPC records, an import's index, the sort runs):
// a signal while it lives removes it, as the end of its scope would.
TEST(Interrupt, SignalRemovesIntermediateFilesAndFolders) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_intermediate");
  const int status = in_child([&] {
    rayscan::install_interrupt_handler();
    touch(dir / "unmarked");
    const rayscan::IntermediateFile file(dir / ".x.rsi.1.rsi", dir / "x.sqlite");
    touch(file.path());
    const rayscan::IntermediateFile runs(dir / ".x.rsi.runs.1", dir / "x.rsi", RemoveOnInterrupt::Kind::folder);
    for (int i = 0; i < 3; ++i) touch(runs.path() / ("run" + std::to_string(i)));
    if (rayscan::test::entry_names(dir).size() != 3) ::_exit(3);  // the files exist before the signal
    ::raise(SIGTERM);
    ::_exit(4);  // not reached
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << "status " << (WIFEXITED(status) ? WEXITSTATUS(status) : status);
  EXPECT_EQ(WTERMSIG(status), SIGTERM);
  EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{"unmarked"});
  fs::remove_all(dir);
}

// A process about to end without unwinding (MPI_Abort) removes the marked paths by an ordinary
// call; their owners, should they still run, find nothing to remove and end without an error.
TEST(Interrupt, RemoveMarkedPathsRemovesTheMarkedPathsOnly) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_remove_marked");
  const int status = in_child([&] {
    rayscan::install_interrupt_handler();
    touch(dir / "unmarked");
    {
      RemoveOnInterrupt released(dir / "released");  // its mark ends before the call: kept
      touch(dir / "released");
    }
    RemoveOnInterrupt file(dir / "file");
    touch(dir / "file");
    const rayscan::IntermediateFile runs(dir / ".x.rsi.runs.1", dir / "x.rsi", RemoveOnInterrupt::Kind::folder);
    for (int i = 0; i < 3; ++i) touch(runs.path() / ("run" + std::to_string(i)));
    rayscan::AtomicFile out(dir / "out.txt");
    const unsigned char bytes[] = {'x'};
    out.write_all(bytes);
    if (rayscan::test::entry_names(dir).size() != 5) ::_exit(3);  // the files exist before the call
    rayscan::remove_marked_paths();
    if (rayscan::test::entry_names(dir) != std::set<std::string>{"released", "unmarked"}) ::_exit(4);
    rayscan::remove_marked_paths();  // nothing left to remove
  });
  ASSERT_TRUE(WIFEXITED(status)) << "status " << status;
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_EQ(rayscan::test::entry_names(dir), (std::set<std::string>{"released", "unmarked"}));
  fs::remove_all(dir);
}

TEST(Interrupt, SignalIgnoredAtInstallStaysIgnored) {
  // `nohup rayscan ...` ignores SIGHUP: the handler must not take it over.
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_ignored");
  const int status = in_child([&] {
    ::signal(SIGHUP, SIG_IGN);
    rayscan::install_interrupt_handler();
    RemoveOnInterrupt file(dir / "file");
    touch(dir / "file");
    ::raise(SIGHUP);
  });
  ASSERT_TRUE(WIFEXITED(status)) << "status " << status;
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{"file"});
  fs::remove_all(dir);
}

namespace {

/// The handler function of `sig` now (SIG_DFL, SIG_IGN or a function).
void (*action_of(int sig))(int) {
  struct sigaction now {};
  ::sigaction(sig, nullptr, &now);
  return now.sa_handler;
}

extern "C" void host_handler(int) {}

}  // namespace

TEST(Interrupt, CleanupTakesOnlyDefaultSignalsWhileItLivesAndGivesThemBack) {
  // A library in a host program: SIGINT is the host's, SIGHUP ignored, SIGTERM left at its default.
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_interrupt_cleanup");
  const int status = in_child([&] {
    ::signal(SIGINT, host_handler);
    ::signal(SIGHUP, SIG_IGN);
    {
      const rayscan::InterruptCleanup outer;
      const rayscan::InterruptCleanup inner;  // (another writer at the same time)
      if (action_of(SIGTERM) == SIG_DFL || action_of(SIGINT) != host_handler || action_of(SIGHUP) != SIG_IGN)
        ::_exit(3);
    }
    if (action_of(SIGTERM) != SIG_DFL || action_of(SIGINT) != host_handler || action_of(SIGHUP) != SIG_IGN)
      ::_exit(4);
    const rayscan::InterruptCleanup cleanup;
    RemoveOnInterrupt file(dir / "file");
    touch(dir / "file");
    // A child forked meanwhile has the default action back and does not remove its parent's file.
    const pid_t child = ::fork();
    if (child == 0) {
      if (action_of(SIGTERM) != SIG_DFL) ::_exit(5);
      ::raise(SIGTERM);
      ::_exit(6);  // not reached
    }
    int child_status = 0;
    ::waitpid(child, &child_status, 0);
    if (!WIFSIGNALED(child_status) || WTERMSIG(child_status) != SIGTERM || !fs::exists(dir / "file")) ::_exit(7);
    ::raise(SIGTERM);
    ::_exit(8);  // not reached
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << "status " << (WIFEXITED(status) ? WEXITSTATUS(status) : status);
  EXPECT_EQ(WTERMSIG(status), SIGTERM);
  EXPECT_TRUE(rayscan::test::entry_names(dir).empty());
  fs::remove_all(dir);
}
