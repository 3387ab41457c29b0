// The progress report of the jobs that run in phases over points (index, translate, db import).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

namespace rayscan::cli {

/// Prints "<command>: <phase> <pct>%  <done> / <total> points  <rate> M points/s" on stderr: on a
/// terminal one status line redrawn in place; into a log file or a pipe plain lines, at most one
/// every kLogLineSeconds per phase (and the first of each phase), never a carriage return (a
/// 2e8-point build once wrote one 35 KB line of \r updates). `total` 0 prints the count only.
/// Thread-safe; copies share one state (for std::function callbacks).
class PhaseProgress {
 public:
  static constexpr double kLogLineSeconds = 5.0;
  /// `quiet`: print nothing.
  PhaseProgress(std::string command, bool quiet);
  void operator()(const char* phase, std::uint64_t done, std::uint64_t total) const;
  /// Ends the status line on a terminal (a newline when one was drawn); nothing into a log.
  void finish() const;

 private:
  struct State {
    std::string command;
    bool quiet = false, tty = false, drawn = false;
    std::chrono::steady_clock::time_point start;
    std::mutex mutex;
    std::string last_phase;
    double last_line = -1e9;
  };
  std::shared_ptr<State> s_;
};

}  // namespace rayscan::cli
