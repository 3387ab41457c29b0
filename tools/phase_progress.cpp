#include "phase_progress.hpp"

#include "rayscan/base/progress.hpp"

#include <cstdio>

namespace rayscan::cli {

PhaseProgress::PhaseProgress(std::string command, bool quiet) : s_(std::make_shared<State>()) {
  s_->command = std::move(command);
  s_->quiet = quiet;
  s_->tty = Progress::stderr_is_terminal();
  s_->start = std::chrono::steady_clock::now();
}

void PhaseProgress::operator()(const char* phase, std::uint64_t done, std::uint64_t total) const {
  State& s = *s_;
  if (s.quiet) return;
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - s.start).count();
  std::lock_guard lock(s.mutex);
  if (!s.tty) {
    if (s.last_phase == phase && t - s.last_line < kLogLineSeconds) return;
    s.last_phase = phase;
    s.last_line = t;
  }
  const char* start = s.tty ? "\r" : "";
  const char* end = s.tty ? "   " : "\n";
  if (total > 0)
    std::fprintf(stderr, "%s%s: %-6s %6.1f%%  %llu / %llu points  %.1f M points/s%s", start, s.command.c_str(), phase,
                 100.0 * static_cast<double>(done) / static_cast<double>(total), static_cast<unsigned long long>(done),
                 static_cast<unsigned long long>(total), t > 0 ? static_cast<double>(done) / t / 1e6 : 0.0, end);
  else
    std::fprintf(stderr, "%s%s: %-6s %llu points%s", start, s.command.c_str(), phase,
                 static_cast<unsigned long long>(done), end);
  std::fflush(stderr);
  s.drawn = true;
}

void PhaseProgress::finish() const {
  std::lock_guard lock(s_->mutex);
  if (s_->tty && s_->drawn) std::fprintf(stderr, "\n");
  s_->drawn = false;
}

}  // namespace rayscan::cli
