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

double PhaseProgress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - s_->start).count();
}

void PhaseProgress::print(const char* start, const char* phase, std::uint64_t done, std::uint64_t total, double rate,
                          const char* end) const {
  const State& s = *s_;
  if (total > 0)
    std::fprintf(stderr, "%s%s: %-6s %6.1f%%  %llu / %llu points  %.1f M points/s%s", start, s.command.c_str(), phase,
                 100.0 * static_cast<double>(done) / static_cast<double>(total), static_cast<unsigned long long>(done),
                 static_cast<unsigned long long>(total), rate / 1e6, end);
  else
    std::fprintf(stderr, "%s%s: %-6s %llu points%s", start, s.command.c_str(), phase,
                 static_cast<unsigned long long>(done), end);
  std::fflush(stderr);
}

void PhaseProgress::end_phase(double t) const {
  State& s = *s_;
  if (s.phase.empty()) return;
  // The phase ran to its end: all it processed is done (the last count it reported, or its total
  // for a phase that reports only at its start, as "sort" does). "done" marks the end of the whole
  // job: its rate is the job's.
  const std::uint64_t n = s.done > 0 ? s.done : s.total;
  const double dt = s.phase == "done" ? t : t - s.phase_start;
  print("", s.phase.c_str(), n, s.total > 0 ? n : 0, dt > 0 ? static_cast<double>(n) / dt : 0.0, "\n");
  s.phase.clear();
}

void PhaseProgress::operator()(const char* phase, std::uint64_t done, std::uint64_t total) const {
  State& s = *s_;
  if (s.quiet) return;
  std::lock_guard lock(s.mutex);
  const double t = seconds();
  if (s.tty) {
    print("\r", phase, done, total, t > 0 ? static_cast<double>(done) / t : 0.0, "   ");
    s.drawn = true;
    return;
  }
  if (s.phase != phase) {  // a new phase: the previous one has ended
    // The phases split the run at their first reports (the first phase starts with the command).
    const bool first = !s.started;
    end_phase(t);
    s.phase = phase;
    s.phase_start = first ? 0.0 : t;
    s.started = true;
    s.last_line = t;
  }
  s.done = done;
  s.total = total;
  // A long phase also reports while it runs, every kLogLineSeconds.
  if (t - s.last_line >= kLogLineSeconds) {
    s.last_line = t;
    const double dt = t - s.phase_start;
    print("", phase, done, total, dt > 0 ? static_cast<double>(done) / dt : 0.0, "\n");
  }
}

void PhaseProgress::finish(bool completed) const {
  std::lock_guard lock(s_->mutex);
  if (s_->quiet) return;
  if (s_->tty) {
    if (s_->drawn) std::fprintf(stderr, "\n");
    s_->drawn = false;
    return;
  }
  if (completed) end_phase(seconds());
  s_->phase.clear();
}

}  // namespace rayscan::cli
