// What every library job (render, visibility, compare, query, ...) shares: how many threads it
// may use, whether it draws a progress bar, and where its log lines go. Each job is one call
// `Result run_<job>(const <Job>Options&)` in the library of its area; the CLI only parses, calls
// and prints (docs/library.md).
#pragma once

#include <chrono>
#include <functional>
#include <string>

namespace rayscan {

class WorkDistributor;  // rayscan/base/work_distributor.hpp

/// Wall-clock seconds since `t0` on the steady clock: the times of a job's log lines.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
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

  /// Send `line` to `log` when set.
  void info(const std::string& line) const {
    if (log) log(line);
  }
};

}  // namespace rayscan
