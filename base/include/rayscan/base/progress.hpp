// Progress reporting on stderr: a one-line bar (work items done, percent, rate, ETA) redrawn at
// most 10 times per second, shown only when stderr is a terminal. The labels default to a
// render's (tiles, M rays/s); other users (visibility: chunks, points/s) pass their own.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace rayscan {

/// What the bar counts: "<done>/<total> <item> ... <rate x rate_scale, `decimals` digits> <rate>".
struct ProgressUnits {
  std::string item = "tiles";     ///< name of the work items counted by done()
  std::string rate = "M rays/s";  ///< label of the rate of the amounts passed to done()
  double rate_scale = 1e-6;       ///< the amount per second is multiplied by this before printing
  int decimals = 2;               ///< digits after the decimal point of the printed rate
};

/// Thread-safe progress report on stderr. Call tile_done() from worker threads; finish() once at
/// the end. On a terminal a bar redrawn in place (every 0.1 s); into a log file or a pipe (stderr
/// not a terminal) plain lines, one every kLogLineSeconds and one when the last item is done,
/// never a carriage return.
class Progress {
 public:
  /// Seconds between two plain lines when stderr is not a terminal.
  static constexpr double kLogLineSeconds = 5.0;
  /// `total_items` > 0 (0 is treated as 1). `enabled` = report (e.g. not --quiet); bar or lines
  /// by stderr_is_terminal(). `units` labels the items and the rate.
  Progress(std::uint64_t total_items, bool enabled, ProgressUnits units = {});
  /// Record one finished item and `amount` units of work for the rate (a render: ray queries);
  /// redraws when due.
  void tile_done(std::uint64_t amount);
  /// Record `items` finished items at once and `amount` units of work for the rate (a phase that
  /// reports a running count of points, e.g. SurfelOptions::progress); redraws when due.
  void add(std::uint64_t items, std::uint64_t amount);
  /// Clear the bar line (if drawn).
  void finish();
  /// True when file descriptor 2 is a terminal.
  static bool stderr_is_terminal();

 private:
  void draw(std::uint64_t done, std::uint64_t queries, double elapsed);
  std::uint64_t total_;
  bool enabled_;
  bool lines_;  ///< plain lines (stderr is not a terminal) instead of the bar
  ProgressUnits units_;
  std::atomic<std::uint64_t> done_{0}, queries_{0};
  std::chrono::steady_clock::time_point start_;
  std::atomic<std::int64_t> last_draw_ns_{0};
  std::mutex draw_mutex_;
  bool drawn_ = false;
};

}  // namespace rayscan
