// Shared helpers of the rayscan benchmark programs: wall-clock timing, medians over interleaved
// repetitions, deterministic workloads (fixed seeds, never the clock) and resident-memory probes.
// Benchmarks print figures; they are never tests (see bench/README.md).
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <sys/resource.h>

namespace rayscan::bench {

/// Wall-clock stopwatch (std::chrono::steady_clock), milliseconds.
class Stopwatch {
 public:
  Stopwatch() : t0_(std::chrono::steady_clock::now()) {}
  /// Milliseconds since construction.
  [[nodiscard]] double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }

 private:
  std::chrono::steady_clock::time_point t0_;
};

/// CPU time of the calling thread (clock_gettime(CLOCK_THREAD_CPUTIME_ID)), milliseconds. On a
/// shared, loaded machine this excludes the time the thread waits for a core, so single-threaded
/// figures stay comparable between runs (cache interference from other processes remains).
class ThreadCpuStopwatch {
 public:
  ThreadCpuStopwatch() : t0_(now()) {}
  [[nodiscard]] double ms() const { return now() - t0_; }

 private:
  static double now() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
  }
  double t0_;
};

/// The process's page faults and system CPU (getrusage(RUSAGE_SELF): every thread, TBB's workers
/// included) since construction. A first touch of fresh memory is a minor fault; on a VM whose
/// balloon reports free pages to the host it is also a host fault, which shows as system CPU
/// (bench/notes/: the octree build's page faults).
class ProcessFaults {
 public:
  ProcessFaults() : r0_(now()) {}
  /// Minor page faults since construction.
  [[nodiscard]] double minor_faults() const { return static_cast<double>(now().ru_minflt - r0_.ru_minflt); }
  /// System CPU since construction, milliseconds.
  [[nodiscard]] double sys_ms() const { return ms(now().ru_stime) - ms(r0_.ru_stime); }

 private:
  static rusage now() {
    rusage r{};
    getrusage(RUSAGE_SELF, &r);
    return r;
  }
  static double ms(const timeval& t) { return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) * 1e-3; }
  rusage r0_;
};

/// Median of a sample (the upper median for an even count); NaN for an empty sample.
[[nodiscard]] inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Uniform doubles in [0, 1) from a 64-bit Mersenne Twister (53 random bits per value, so the
/// stream is the same on every standard library, unlike std::uniform_real_distribution).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  [[nodiscard]] double uniform() { return static_cast<double>(g_() >> 11) * 0x1.0p-53; }
  [[nodiscard]] Vec3 point_in_unit_cube() {
    const double x = uniform(), y = uniform(), z = uniform();
    return {x, y, z};
  }
  /// A direction uniform on the unit sphere (Marsaglia 1972 / normalised Gaussian-free rejection).
  [[nodiscard]] Vec3 unit_vector() {
    for (;;) {
      const Vec3 v(2 * uniform() - 1, 2 * uniform() - 1, 2 * uniform() - 1);
      const double l2 = glm::dot(v, v);
      if (l2 > 1e-6 && l2 <= 1.0) return v / std::sqrt(l2);
    }
  }

 private:
  std::mt19937_64 g_;
};

/// n points uniform in the unit cube [0, 1)^3 (the paper's Table 1 workload), fixed seed.
[[nodiscard]] inline std::vector<Vec3> uniform_cube(std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Vec3> p(n);
  for (auto& v : p) v = rng.point_in_unit_cube();
  return p;
}

/// A field of /proc/self/status in bytes (VmRSS = resident now, VmHWM = peak resident since start
/// or since the last reset_peak_rss()); 0 when unavailable.
[[nodiscard]] inline std::uint64_t proc_status_bytes(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(field) + ":";
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::strtoull(line.c_str() + key.size(), nullptr, 10) * 1024;
  return 0;
}
[[nodiscard]] inline std::uint64_t rss_bytes() { return proc_status_bytes("VmRSS"); }
[[nodiscard]] inline std::uint64_t peak_rss_bytes() { return proc_status_bytes("VmHWM"); }
/// Reset VmHWM to the current RSS (Linux >= 4.0: write "5" to /proc/self/clear_refs).
/// Returns false when the kernel refuses.
inline bool reset_peak_rss() {
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
  f.flush();
  return static_cast<bool>(f);
}

/// Keeps a value alive so the optimiser cannot drop the work that produced it.
template <class T>
inline void keep(const T& v) {
  asm volatile("" : : "g"(&v) : "memory");
}

/// Abort the benchmark loudly: a cross-check between rayscan and a peer failed.
[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "CROSS-CHECK FAILED: %s\n", what.c_str());
  std::fflush(stdout);
  std::exit(3);
}

/// The machine's CPU model line from /proc/cpuinfo ("model name").
[[nodiscard]] inline std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto c = line.find(':');
      return c == std::string::npos ? line : line.substr(c + 2);
    }
  return "unknown";
}

/// The first three fields of /proc/loadavg (1, 5, 15 minute load): other work on the machine.
[[nodiscard]] inline std::string loadavg() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

}  // namespace rayscan::bench
