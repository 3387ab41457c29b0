// The progress report of the jobs that run in phases over points (index, translate, db import).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

namespace rayscan::cli {

/// Prints "<command>: <phase> <pct>%  <done> / <total> points  <rate> M points/s" on stderr, the
/// rate of the phase since it began (its first report, or the report before when its first already
/// counts points done). On a terminal one status line redrawn in place; a
/// phase's report at its start (0 of its total) reads "<command>: <phase> running, <total> points",
/// not 0.0% (sort and db import's SQL indexes report nothing more until they end). Into a log file
/// or a pipe plain lines, never a carriage return (a 2e8-point build once wrote one 35 KB line of
/// \r updates): one line when a phase ends (the next one reports, or finish()), at 100% with the
/// phase's own rate, and while a phase runs at most one every kLogLineSeconds; a phase the job
/// skips prints nothing. A phase ends with all it processed done: the line shows the last count it
/// reported (its total when it reported only at its start). The phase "done" (the index build's
/// last report) stands for the whole run: its rate is the run's. `total` 0 prints the count only.
/// Thread-safe; copies share one state (for std::function callbacks).
class PhaseProgress {
 public:
  static constexpr double kLogLineSeconds = 5.0;
  /// `quiet`: print nothing.
  PhaseProgress(std::string command, bool quiet);
  void operator()(const char* phase, std::uint64_t done, std::uint64_t total) const;
  /// Ends the report: on a terminal a newline after the status line when one was drawn; into a
  /// log the line of the last phase, unless `completed` is false (the job was stopped: its last
  /// phase did not end).
  void finish(bool completed = true) const;

 private:
  struct State {
    std::string command;
    bool quiet = false, tty = false, drawn = false;
    int drawn_chars = 0;  ///< on a terminal: the length of the status line drawn (for the redraw)
    std::chrono::steady_clock::time_point start;
    std::mutex mutex;
    bool started = false;               ///< a phase has reported
    std::string phase;                  ///< the phase running ("" once its line is printed)
    std::uint64_t done = 0, total = 0;  ///< its last report
    double phase_start = 0;             ///< seconds since start when it began
    double last_line = 0;               ///< seconds since start of the last line printed
    double last_report = 0;             ///< seconds since start of the last report
  };
  [[nodiscard]] double seconds() const;
  /// One line: `start`, the report, `end` (rate in points per second); the characters printed.
  int print(const char* start, const char* phase, std::uint64_t done, std::uint64_t total, double rate,
             const char* end) const;
  /// Into a log: the line of the phase that just ended (none when none runs); `t`: when it ended,
  /// seconds since start. Call with the mutex held.
  void end_phase(double t) const;
  std::shared_ptr<State> s_;
};

}  // namespace rayscan::cli
