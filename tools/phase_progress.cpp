#include "phase_progress.hpp"

#include "rayscan/base/progress.hpp"

#include <algorithm>
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

int PhaseProgress::print(const char* start, const char* phase, std::uint64_t done, std::uint64_t total, double rate,
                         const char* end) const {
  const State& s = *s_;
  int n = 0;
  if (total > 0)
    n = std::fprintf(stderr, "%s%s: %-6s %6.1f%%  %llu / %llu points  %.1f M points/s%s", start, s.command.c_str(),
                     phase, 100.0 * static_cast<double>(done) / static_cast<double>(total),
                     static_cast<unsigned long long>(done), static_cast<unsigned long long>(total), rate / 1e6, end);
  else
    n = std::fprintf(stderr, "%s%s: %-6s %llu points%s", start, s.command.c_str(), phase,
                     static_cast<unsigned long long>(done), end);
  std::fflush(stderr);
  return n;
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
  const double previous = s.last_report;
  if (s.phase != phase) {  // a new phase: the previous one has ended
    // The phases split the run at their first reports (the first phase starts with the command).
    // A first report that already counts work done (a phase that reports at its end, or every
    // 2^22 points) comes after that work: the phase began at the previous report. A phase that
    // reported only its start ("sort") then ends at this report: nothing tells where the two
    // split, and both lines count the time between.
    const bool first = !s.started;
    const double begin = first ? 0.0 : done > 0 ? previous : t;
    if (!s.tty) end_phase(s.done > 0 ? begin : t);
    s.phase = phase;
    s.phase_start = begin;
    s.started = true;
    s.last_line = t;
  }
  s.done = done;
  s.total = total;
  s.last_report = t;
  const double dt = s.phase == "done" ? t : t - s.phase_start;
  const double rate = dt > 0 ? static_cast<double>(done) / dt : 0.0;
  if (s.tty) {
    // A phase's report at its start (none of its total done) says the phase runs rather than
    // "0.0%", which a phase that reports nothing more until it ends (sort, the SQL indexes) would
    // show for all its time. Spaces cover the rest of a longer line drawn before.
    const int n = done == 0 && total > 0
                      ? std::fprintf(stderr, "\r%s: %-6s running, %llu points", s.command.c_str(), phase,
                                     static_cast<unsigned long long>(total))
                      : print("\r", phase, done, total, rate, "");
    std::fprintf(stderr, "%*s", std::max(3, s.drawn_chars - n + 3), "");
    std::fflush(stderr);
    s.drawn_chars = n;
    s.drawn = true;
    return;
  }
  // A long phase also reports while it runs, every kLogLineSeconds.
  if (t - s.last_line >= kLogLineSeconds) {
    s.last_line = t;
    print("", phase, done, total, rate, "\n");
  }
}

void PhaseProgress::finish(bool completed) const {
  std::lock_guard lock(s_->mutex);
  if (s_->quiet) return;
  if (s_->tty) {
    if (s_->drawn) std::fprintf(stderr, "\n");
    s_->drawn = false;
    s_->drawn_chars = 0;
    s_->phase.clear();
    return;
  }
  if (completed) end_phase(seconds());
  s_->phase.clear();
}

}  // namespace rayscan::cli
