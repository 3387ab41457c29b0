// Progress reporting of a render on stderr: a one-line bar (tiles done, percent, rays/s, ETA)
// redrawn at most 10 times per second, shown only when stderr is a terminal.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>

namespace rayscan::render {

/// Thread-safe progress bar. Call tile_done() from worker threads; finish() once at the end.
class Progress {
 public:
  /// `total_tiles` > 0. `enabled` = draw the bar (normally: stderr is a terminal, see
  /// stderr_is_terminal()).
  Progress(std::uint64_t total_tiles, bool enabled);
  /// Record one finished tile and `queries` ray queries; redraws when due.
  void tile_done(std::uint64_t queries);
  /// Clear the bar line (if drawn).
  void finish();
  /// True when file descriptor 2 is a terminal.
  static bool stderr_is_terminal();

 private:
  void draw(std::uint64_t done, std::uint64_t queries, double elapsed);
  std::uint64_t total_;
  bool enabled_;
  std::atomic<std::uint64_t> done_{0}, queries_{0};
  std::chrono::steady_clock::time_point start_;
  std::atomic<std::int64_t> last_draw_ns_{0};
  std::mutex draw_mutex_;
  bool drawn_ = false;
};

}  // namespace rayscan::render
