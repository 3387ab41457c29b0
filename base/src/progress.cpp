#include "rayscan/base/progress.hpp"

#include <cstdio>
#include <utility>
#include <unistd.h>

namespace rayscan {

Progress::Progress(std::uint64_t total_items, bool enabled, ProgressUnits units)
    : total_(total_items ? total_items : 1),
      enabled_(enabled),
      lines_(enabled && !stderr_is_terminal()),
      units_(std::move(units)),
      start_(std::chrono::steady_clock::now()) {}

bool Progress::stderr_is_terminal() { return ::isatty(2) == 1; }

void Progress::tile_done(std::uint64_t queries) { add(1, queries); }

void Progress::add(std::uint64_t items, std::uint64_t queries) {
  const std::uint64_t done = done_.fetch_add(items) + items;
  const std::uint64_t q = queries_.fetch_add(queries) + queries;
  if (!enabled_) return;
  const std::int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::steady_clock::now() - start_).count();
  std::int64_t last = last_draw_ns_.load();
  const std::int64_t period = lines_ ? std::int64_t(kLogLineSeconds * 1e9) : 100'000'000;
  if (done != total_ && now - last < period) return;
  if (!last_draw_ns_.compare_exchange_strong(last, now) && done != total_) return;
  std::lock_guard lock(draw_mutex_);
  draw(done, q, double(now) * 1e-9);
}

void Progress::draw(std::uint64_t done, std::uint64_t queries, double elapsed) {
  const double frac = double(done) / double(total_);
  const int width = 30;
  char bar[width + 1];
  const int filled = static_cast<int>(frac * width);
  for (int i = 0; i < width; ++i) bar[i] = i < filled ? '#' : '.';
  bar[width] = 0;
  const double rate = elapsed > 0 ? double(queries) / elapsed : 0.0;
  const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
  if (lines_)  // a log line: no bar, no carriage return
    std::fprintf(stderr, "progress: %llu/%llu %s %5.1f%%  %.*f %s  %s %.0f s\n",
                 static_cast<unsigned long long>(done), static_cast<unsigned long long>(total_),
                 units_.item.c_str(), 100.0 * frac, units_.decimals, rate * units_.rate_scale,
                 units_.rate.c_str(), done == total_ ? "done in" : "ETA", done == total_ ? elapsed : eta);
  else
    std::fprintf(stderr, "\r[%s] %llu/%llu %s %5.1f%%  %.*f %s  ETA %.0f s   ", bar,
                 static_cast<unsigned long long>(done), static_cast<unsigned long long>(total_),
                 units_.item.c_str(), 100.0 * frac, units_.decimals, rate * units_.rate_scale,
                 units_.rate.c_str(), eta);
  std::fflush(stderr);
  drawn_ = true;
}

void Progress::finish() {
  if (!enabled_ || lines_) return;
  std::lock_guard lock(draw_mutex_);
  if (drawn_) {
    std::fprintf(stderr, "\r%*s\r", 90, "");
    std::fflush(stderr);
  }
}

}  // namespace rayscan
