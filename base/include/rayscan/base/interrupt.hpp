// Interrupted commands leave no temporary files. The `rayscan` program installs one handler of
// SIGINT, SIGTERM and SIGHUP (install_interrupt_handler); every temporary file or folder that
// rayscan creates (AtomicFile's temporary, the sort runs of an index build, the records file of a
// COPC output) is marked while it exists (RemoveOnInterrupt), and the handler removes the marked
// paths and ends the process by the same signal. The marks live in a fixed table of paths and the
// handler only reads atomics and calls unlink(2), rmdir(2) and their kin, which are
// async-signal-safe, so the handler may run on any thread at any moment. A library loaded into
// another program (the Python module) installs no handler of its own for good: around a write it
// holds an InterruptCleanup, which takes only the signals whose action is still the default one.
// Without either, nothing is marked and signals keep their own disposition. A process that ends
// without unwinding (MPI_Abort) removes the marked paths first (remove_marked_paths).
#pragma once

#include <filesystem>

namespace rayscan {

/// Marks `path` (a temporary file, or a folder of temporary files) to be removed should the
/// process be ended by SIGINT, SIGTERM or SIGHUP while this object lives. Mark a path before
/// creating it, and destroy the mark only after removing or renaming the path, so that no moment
/// is uncovered. The destructor removes nothing: the owner removes its temporaries on every
/// ordinary path. A folder is emptied (its entries, not recursively) and removed. Does nothing
/// when neither install_interrupt_handler() has run nor an InterruptCleanup been made (marks are
/// recorded from the first one on), for an empty path or one of PATH_MAX bytes or
/// more, and when all 128 slots of the table are taken (the path then survives a signal, as it did
/// without a handler). Never throws. Movable, not copyable.
class RemoveOnInterrupt {
 public:
  enum class Kind { file, folder };
  /// Marks nothing.
  RemoveOnInterrupt() = default;
  explicit RemoveOnInterrupt(const std::filesystem::path& path, Kind kind = Kind::file) noexcept;
  RemoveOnInterrupt(RemoveOnInterrupt&& other) noexcept;
  RemoveOnInterrupt& operator=(RemoveOnInterrupt&& other) noexcept;
  RemoveOnInterrupt(const RemoveOnInterrupt&) = delete;
  RemoveOnInterrupt& operator=(const RemoveOnInterrupt&) = delete;
  ~RemoveOnInterrupt();

 private:
  void release() noexcept;
  int slot_ = -1;  // index in the table; -1: nothing marked
};

/// Installs the handler of SIGINT, SIGTERM and SIGHUP: it removes every marked path, then ends the
/// process by the same signal with its default action (a shell reports 128 + the signal number).
/// A signal ignored when this is called (`nohup` ignores SIGHUP) stays ignored. For the `rayscan`
/// program's main() only, before it starts threads; never for a library loaded into another
/// program (the Python module), whose signals are its host's.
void install_interrupt_handler();

/// For a library loaded into another program (the Python module), around a call that writes
/// temporary files: while at least one InterruptCleanup lives, each of SIGINT, SIGTERM and SIGHUP
/// whose action was the default one (SIG_DFL, which ends the process) when the first of them was
/// made gets install_interrupt_handler's handler, so that the signal removes the marked paths and
/// then ends the process by its default action, as it would have ended anyway. A signal the host
/// handles or ignores (Python's own SIGINT handler, a Dask worker's SIGTERM) stays the host's.
/// When the last one is destroyed each signal taken gets SIG_DFL back, unless the host has set
/// another action meanwhile. A child forked meanwhile gets the default actions back and none of
/// the marks (its parent's temporaries are not its own). Thread-safe: objects on several threads
/// share one handler. Never throws. Not copyable.
class InterruptCleanup {
 public:
  InterruptCleanup() noexcept;
  InterruptCleanup(const InterruptCleanup&) = delete;
  InterruptCleanup& operator=(const InterruptCleanup&) = delete;
  ~InterruptCleanup();
};

/// Removes every path marked now (RemoveOnInterrupt), as the signal handler does, for a process
/// about to end without unwinding, where no destructor removes its temporaries (MPI_Abort, which
/// rayscan::mpi calls when a job under mpirun fails). The marks removed stay taken: their owners'
/// later removal or rename finds no file, and their destruction frees nothing. Only
/// async-signal-safe calls, like the handler. Does nothing when nothing is marked. Never throws.
void remove_marked_paths() noexcept;

/// For a job that stops itself and unwinds (`rayscan index`, whose progress callback checks
/// pending_interrupt()): from now on the first of the three signals is only recorded; a second
/// one removes the marked paths and ends the process as above. No effect without the handler.
void defer_interrupts() noexcept;

/// The signal recorded since defer_interrupts() (SIGINT, SIGTERM or SIGHUP), or 0 when none
/// arrived.
[[nodiscard]] int pending_interrupt() noexcept;

}  // namespace rayscan
