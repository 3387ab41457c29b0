// make_site OUT.las N [SOURCE.las] [--pdrf 0|3]: the index-file benchmark site, generated (never
// committed): the bundled autzen scan (LAS 1.2 PDRF 3) tiled 4 x 4, then repeated with +-0.5 m xy
// jitter until N points, written as LAS 1.2 PDRF 3 (34 bytes per point) or, with --pdrf 0, PDRF 0
// (20 bytes per point: the first 20 bytes of each PDRF 3 record, LAS 1.2 Table 7 vs Table 10, no
// GPS time or colour). With --tile-major the copies are written tile by tile (all of tile 0's,
// then tile 1's, ...), as a site delivered in tiles and concatenated would be; by default they
// go round the 16 tiles, so every stretch of the file covers the whole site. Check free disk
// first (1e9 points = 20 GB at PDRF 0), delete after.
#include "bench_cli.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  std::string out, n_text, src_path = std::string(RAYSCAN_SOURCE_DIR) + "/scenes/data/autzen_trim.las";
  int pdrf = 3;
  bool tile_major = false;
  CLI::App app{"make_site: the index-file benchmark site, the bundled autzen scan tiled 4 x 4 and repeated to N points"};
  app.add_option("OUT", out, "output LAS 1.2 file")->required();
  app.add_option("N", n_text, "points (e.g. 2e7; at most 2^32 - 1)")->required();
  app.add_option("SOURCE", src_path, "LAS PDRF 3 source (34-byte records)")->capture_default_str();
  app.add_option("--pdrf", pdrf, "point data record format of the output: 3 (34 bytes) or 0 (20 bytes)")
      ->check(CLI::IsMember({0, 3}))->capture_default_str();
  app.add_flag("--tile-major", tile_major, "write the copies tile by tile (default: round the 16 tiles)");
  rayscan::bench::parse_or_exit(app, argc, argv);
  // N as a number of points: "2e7" as well as "20000000".
  char* end = nullptr;
  const double nd = std::strtod(n_text.c_str(), &end);
  if (end == n_text.c_str() || *end != '\0' || !(nd >= 1.0) || nd > 4294967295.0 || nd != std::floor(nd)) {
    std::cerr << "make_site: N: expected a whole number of points from 1 to 2^32 - 1 (LAS 1.2 point count), got '"
              << n_text << "'\n";
    return 2;
  }
  const auto n = static_cast<std::uint64_t>(nd);
  const std::size_t rl = pdrf == 0 ? 20 : 34;  // output record length
  std::ifstream in(src_path, std::ios::binary);
  if (!in) {
    std::cerr << src_path << ": cannot open file\n";
    return 2;
  }
  std::vector<char> src((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto u32 = [&](std::size_t o) { std::uint32_t v; std::memcpy(&v, src.data() + o, 4); return v; };
  auto u16 = [&](std::size_t o) { std::uint16_t v; std::memcpy(&v, src.data() + o, 2); return v; };
  auto f64 = [&](std::size_t o) { double v; std::memcpy(&v, src.data() + o, 8); return v; };
  if (src.size() < 227 || (src[104] & 0x3F) != 3 || u16(105) != 34 || !(f64(131) >= 1e-9)) {
    std::cerr << src_path << ": expected LAS PDRF 3 with 34-byte records and an x scale of at least 1e-9\n";
    return 2;
  }
  const std::uint32_t off = u32(96), count = u32(107);
  if (count == 0 || off < 227 || std::uint64_t{off} + std::uint64_t{count} * 34 > src.size()) {
    std::cerr << src_path << ": byte 96: point data at offset " << off << " with " << count
              << " records of 34 bytes, expected at least one record within the file's " << src.size() << " bytes\n";
    return 2;
  }
  const char* recs = src.data() + off;
  std::int32_t lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, hi[3] = {INT32_MIN, INT32_MIN, INT32_MIN};
  for (std::uint32_t i = 0; i < count; ++i)
    for (int k = 0; k < 3; ++k) {
      std::int32_t v;
      std::memcpy(&v, recs + i * 34 + 4 * k, 4);
      lo[k] = std::min(lo[k], v), hi[k] = std::max(hi[k], v);
    }
  const std::int64_t ext[2] = {std::int64_t(hi[0]) - lo[0] + 1, std::int64_t(hi[1]) - lo[1] + 1};
  const int jit = static_cast<int>(0.5 / f64(131));
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> J(-jit, jit);
  const std::string tmp = out + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) {
    std::cerr << out << ": cannot write (" << std::strerror(errno) << ")\n";
    return 2;
  }
  std::vector<char> hdr(src.begin(), src.begin() + 227);
  hdr[104] = static_cast<char>(pdrf);
  const auto rl16 = static_cast<std::uint16_t>(rl);
  std::memcpy(hdr.data() + 105, &rl16, 2);
  std::fwrite(hdr.data(), 1, 227, f);
  std::vector<char> block(static_cast<std::size_t>(count) * rl);
  std::int64_t blo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, bhi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
  std::uint64_t done = 0;
  // Copy r goes to tile r % 16 (jittered from the second round on); the order of the copies.
  const std::uint64_t copies = (n + count - 1) / count;
  std::vector<std::uint64_t> order(copies);
  for (std::uint64_t r = 0; r < copies; ++r) order[r] = r;
  if (tile_major) std::stable_sort(order.begin(), order.end(), [](std::uint64_t a, std::uint64_t b) { return a % 16 < b % 16; });
  for (std::uint64_t k = 0; done < n; ++k) {
    const std::uint64_t rep = order[k];
    const std::uint64_t m = std::min<std::uint64_t>(count, n - done);
    const int t = static_cast<int>(rep % 16);
    for (std::uint64_t i = 0; i < m; ++i) {
      char* r = block.data() + i * rl;
      std::memcpy(r, recs + i * 34, rl);
      std::int32_t xyz[3];
      std::memcpy(xyz, r, 12);
      std::int64_t x = xyz[0] + (t % 4) * ext[0], y = xyz[1] + (t / 4) * ext[1];
      if (rep >= 16) x += J(rng), y += J(rng);
      xyz[0] = static_cast<std::int32_t>(x), xyz[1] = static_cast<std::int32_t>(y);
      for (int k = 0; k < 3; ++k) blo[k] = std::min<std::int64_t>(blo[k], xyz[k]), bhi[k] = std::max<std::int64_t>(bhi[k], xyz[k]);
      std::memcpy(r, xyz, 12);
    }
    if (std::fwrite(block.data(), rl, m, f) != m) {
      std::cerr << out << ": write failed (" << std::strerror(errno) << ")\n";
      std::fclose(f);
      std::remove(tmp.c_str());
      return 2;
    }
    done += m;
  }
  const std::uint32_t zero = 0, n32 = static_cast<std::uint32_t>(n), off227 = 227;
  std::memcpy(hdr.data() + 96, &off227, 4);
  std::memcpy(hdr.data() + 100, &zero, 4);
  std::memcpy(hdr.data() + 107, &n32, 4);
  const std::uint32_t by_return[5] = {n32, 0, 0, 0, 0};
  std::memcpy(hdr.data() + 111, by_return, 20);
  for (int k = 0; k < 3; ++k) {
    const double s = f64(131 + 8 * k), o = f64(155 + 8 * k);
    const double mx = static_cast<double>(bhi[k]) * s + o, mn = static_cast<double>(blo[k]) * s + o;
    std::memcpy(hdr.data() + 179 + 16 * k, &mx, 8);
    std::memcpy(hdr.data() + 187 + 16 * k, &mn, 8);
  }
  const bool header_written = std::fseek(f, 0, SEEK_SET) == 0 && std::fwrite(hdr.data(), 1, 227, f) == 227;
  if (std::fclose(f) != 0 || !header_written || std::rename(tmp.c_str(), out.c_str()) != 0) {
    std::cerr << out << ": write failed (" << std::strerror(errno) << ")\n";
    std::remove(tmp.c_str());
    return 2;
  }
  std::cout << out << ": " << n << " points\n";
  return 0;
}
