// What every library job (render, visibility, compare, query, ...) shares: how many threads it
// may use, whether it draws a progress bar, and where its log lines go. Each job is one call
// `Result run_<job>(const <Job>Options&)` in the library of its area; the CLI only parses, calls
// and prints (docs/library.md).
#pragma once

#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <string>

namespace rayscan {

class WorkDistributor;  // rayscan/base/work_distributor.hpp

/// Wall-clock seconds since `t0` on the steady clock: the times of a job's log lines.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Thrown by a job whose cancel flag (JobControl::cancel) was set while it ran: the job stops at
/// its next check and unwinds, writing no output (its AtomicFile and OutputTransaction temporaries
/// are removed as on any error). Not a std::runtime_error, so that the handlers that give a
/// reader's or a stage's error its file name or option pass it on unchanged.
class Cancelled : public std::exception {
 public:
  const char* what() const noexcept override { return "cancelled"; }
};

/// Throws Cancelled when `flag` is set; nullptr never cancels. The jobs' loops call it once per
/// work item (a render tile, a chunk of points), never per ray, so that the relaxed load of a
/// flag that is almost always clear costs nothing measurable.
inline void throw_if_cancelled(const std::atomic<bool>* flag) {
  if (flag && flag->load(std::memory_order_relaxed)) throw Cancelled();
}

/// Run-time controls of a job that never change its result.
struct JobControl {
  unsigned threads = 0;   ///< worker threads; 0 = all cores (resolve_threads); results are identical
  bool progress = false;  ///< draw a progress bar on stderr (only when stderr is a terminal)
  /// Receives one human-readable line per stage ("read 1000 points from x.las in 0.01 s");
  /// empty = silent.
  std::function<void(const std::string&)> log;
  /// Spreads the job's parallel stages over processes (MPI ranks; rayscan::mpi, docs/mpi.md);
  /// nullptr = this process computes everything. Every process then runs the same job; only the
  /// root (rank 0) gets complete results and writes outputs. Not owned.
  WorkDistributor* distributor = nullptr;
  /// Set by another thread to stop the job (the Python module sets it on Ctrl-C): the job then
  /// throws Cancelled from its next check, a render tile, a chunk of points or the start of a
  /// stage, and writes nothing; nullptr = never cancelled. Not with a `distributor` of several
  /// processes, whose ranks would then disagree on the work left. Not owned.
  const std::atomic<bool>* cancel = nullptr;

  /// Throws Cancelled when `cancel` is set (throw_if_cancelled).
  void check_cancel() const { throw_if_cancelled(cancel); }

  /// Send `line` to `log` when set.
  void info(const std::string& line) const {
    if (log) log(line);
  }
};

}  // namespace rayscan
