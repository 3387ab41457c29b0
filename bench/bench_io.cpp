// bench_io: read throughput and peak memory of the LAS reader on a synthetic 10-million-point
// LAS 1.4 file (point data record format 7, 36-byte records, about 360 MB).
//
// Usage: bench_io [POINTS (default 10000000)] [DIR (default /tmp)] [--keep (keep the LAS file)]
// Each read runs in a forked child so that its peak resident set (getrusage of the child) counts
// only that read. "cold" reads first evict the file from the page cache with
// posix_fadvise(POSIX_FADV_DONTNEED) (only this file; nothing system-wide is dropped); "warm"
// reads follow a read of the same file. The reference "disk" figure is a plain sequential read()
// of the cold file into a 4 MiB buffer.
#include "bench_cli.hpp"
#include "rayscan/io/point_io.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

void evict(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return;
  ::fdatasync(fd);
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  ::close(fd);
}

long rss_kb() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return 0;
  char line[256];
  long kb = 0;
  while (std::fgets(line, sizeof line, f) != nullptr)
    if (std::sscanf(line, "VmRSS: %ld kB", &kb) == 1) break;
  std::fclose(f);
  return kb;
}

struct Result {
  double seconds = 0;
  double bytes_out = 0;  // bytes of the output arrays
  long start_rss_kb = 0;
  long peak_rss_kb = 0;
  std::size_t points = 0;
};

/// Runs `work` in a child process; returns its timing and peak RSS.
template <class F>
Result in_child(F work) {
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe: cannot create");
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    Result r;
    try {
      r = work();
    } catch (const std::exception& e) {  // (the child never returns into main: _Exit, no flush)
      std::fprintf(stderr, "bench_io: %s\n", e.what());
      std::_Exit(1);
    }
    if (::write(fds[1], &r, sizeof r) != static_cast<ssize_t>(sizeof r)) std::_Exit(1);
    std::_Exit(0);
  }
  ::close(fds[1]);
  Result r;
  const bool got = ::read(fds[0], &r, sizeof r) == static_cast<ssize_t>(sizeof r);
  ::close(fds[0]);
  int status = 0;
  rusage ru{};
  ::wait4(pid, &status, 0, &ru);
  if (!got) throw std::runtime_error("a read in its child process failed");
  r.peak_rss_kb = ru.ru_maxrss;
  return r;
}

double output_bytes(const rayscan::PointCloud& pc) {
  double b = pc.positions.size() * sizeof(rayscan::Vec3) + pc.rgb.size() * sizeof(rayscan::Rgb16) +
             pc.intensity.size() * 2.0 + pc.classification.size() + pc.gps_time.size() * 8.0 +
             pc.normals.size() * 12.0;
  for (const auto& s : pc.scalars) b += s.values.size() * 8.0;
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t n = 10'000'000;
  std::filesystem::path dir = "/tmp";
  bool keep = false;
  CLI::App app{"bench_io: LAS read throughput and peak memory on a synthetic LAS 1.4 file (PDRF 7)"};
  app.add_option("POINTS", n, "points in the generated file")->check(CLI::Range(std::size_t{1}, std::size_t{1} << 32))
      ->capture_default_str();
  app.add_option("DIR", dir, "where the file is written (and deleted after)")->check(CLI::ExistingDirectory)
      ->capture_default_str();
  app.add_flag("--keep", keep, "keep the generated file");
  rayscan::bench::parse_or_exit(app, argc, argv);
  const std::string las = (dir / ("rayscan_bench_" + std::to_string(n) + ".las")).string();
  try {

    // Synthetic airborne-like scan: UTM coordinates, colour, intensity, class, GPS time, returns.
    double write_s = 0;
    {
      rayscan::PointCloud pc;
      std::mt19937_64 rng(42);
      std::uniform_real_distribution<double> u(0.0, 1.0);
      pc.positions.resize(n);
      pc.rgb.resize(n);
      pc.intensity.resize(n);
      pc.classification.resize(n);
      pc.gps_time.resize(n);
      pc.scalars.push_back({"return_number", std::vector<double>(n)});
      pc.scalars.push_back({"number_of_returns", std::vector<double>(n)});
      for (std::size_t i = 0; i < n; ++i) {
        pc.positions[i] = rayscan::Vec3(500000.0 + 2000.0 * u(rng), 4900000.0 + 2000.0 * u(rng), 300.0 + 50.0 * u(rng));
        pc.rgb[i] = {static_cast<std::uint16_t>(rng()), static_cast<std::uint16_t>(rng()), static_cast<std::uint16_t>(rng())};
        pc.intensity[i] = static_cast<std::uint16_t>(rng());
        pc.classification[i] = static_cast<std::uint8_t>(rng() % 20);
        pc.gps_time[i] = 3.0e8 + 1e-5 * static_cast<double>(i);
        pc.scalars[0].values[i] = 1.0 + static_cast<double>(rng() % 3);
        pc.scalars[1].values[i] = 3.0;
      }
      rayscan::io::LasWriteOptions opt;
      opt.scale = rayscan::Vec3(0.001);
      const auto t0 = Clock::now();
      rayscan::io::write_las(las, pc, opt);
      write_s = std::chrono::duration<double>(Clock::now() - t0).count();
    }
    const double mb = static_cast<double>(std::filesystem::file_size(las)) / 1e6;
    std::printf("bench_io: %zu points, %s, %.1f MB (LAS 1.4 PDRF 7, 36-byte records)\n", n, las.c_str(), mb);
    std::printf("write_las                     %7.2f s  %7.0f MB/s\n", write_s, mb / write_s);

    // Reference: plain sequential read() of the cold file.
    evict(las);
    const Result disk = in_child([&] {
      Result r;
      r.start_rss_kb = rss_kb();
      const auto t0 = Clock::now();
      const int fd = ::open(las.c_str(), O_RDONLY);
      std::vector<char> buf(4 << 20);
      while (::read(fd, buf.data(), buf.size()) > 0) {
      }
      ::close(fd);
      r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      return r;
    });
    std::printf("disk read() cold, 4 MiB buf   %7.2f s  %7.0f MB/s\n", disk.seconds, mb / disk.seconds);

    auto reader = [&](bool scalars) {
      return [&, scalars] {
        Result r;
        r.start_rss_kb = rss_kb();
        const auto t0 = Clock::now();
        const rayscan::PointCloud pc = rayscan::io::read_point_cloud(las, rayscan::io::ReadOptions{scalars});
        r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        r.bytes_out = output_bytes(pc);
        r.points = pc.size();
        return r;
      };
    };
    for (const bool scalars : {false, true}) {
      for (const bool cold : {true, false}) {
        if (cold) evict(las);
        const Result r = in_child(reader(scalars));
        if (r.points != n) {
          throw std::runtime_error("read " + std::to_string(r.points) + " points, expected " + std::to_string(n));
        }
        std::printf("read_point_cloud %-4s %-8s %7.2f s  %7.0f MB/s  %6.1f Mpts/s  peak RSS %6.0f MB"
                    " = output %6.0f MB + %4.0f MB (process start %3.0f MB)\n",
                    cold ? "cold" : "warm", scalars ? "all" : "core", r.seconds, mb / r.seconds,
                    n / r.seconds / 1e6, r.peak_rss_kb / 1024.0, r.bytes_out / 1048576.0,
                    r.peak_rss_kb / 1024.0 - r.bytes_out / 1048576.0, r.start_rss_kb / 1024.0);
      }
    }
    if (keep) std::printf("kept %s\n", las.c_str());
    else std::filesystem::remove(las);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_io: %s\n", e.what());
    std::error_code ec;
    if (!keep) std::filesystem::remove(las, ec);  // (the generated file, when there is one)
    return 2;
  }
  return 0;
}
