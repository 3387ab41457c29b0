// `rayscan render`'s memory limits through the command line: an image whose buffers exceed the
// machine's physical memory is refused with the estimate, and an allocation that fails anyway is
// one line and exit code 2, never an abort.
#include <gtest/gtest.h>

#include "../common/run_command.hpp"
#include "../common/sanitizers.hpp"
#include "jobs_test_util.hpp"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

using rayscan::test::data_file;
using rayscan::test::run_command;
using rayscan::test::quoted;
using rayscan::test::rayscan_cli;
using rayscan::test::temp_dir;

namespace {

/// The machine's physical memory in GiB (sysconf).
double physical_memory_gib() {
  return double(::sysconf(_SC_PHYS_PAGES)) * double(::sysconf(_SC_PAGESIZE)) / double(std::uint64_t{1} << 30);
}

}  // namespace

TEST(RenderMemoryCli, RefusesAnImageWhoseBuffersExceedTheMachinesMemory) {
  // 65536 x 65536 pixels, every AOV, one .exr: the framebuffer holds 12 (beauty) + 4 + 12 + 12 + 4
  // + 12 (albedo) + 4 (its coverage) + 4 bytes a pixel, the writer an exposure-scaled beauty (12)
  // and the interleaved float image of beauty, the 14 float AOV channels and the 4-byte ids
  // (12 + 56 + 4): 136 bytes, 544 GiB.
  const double need_gib = 65536.0 * 65536.0 * 136.0 / double(std::uint64_t{1} << 30);
  ASSERT_DOUBLE_EQ(need_gib, 544.0);
  if (physical_memory_gib() >= need_gib) GTEST_SKIP() << "this machine holds 544 GiB";
  const auto dir = temp_dir() / "render_memory";
  std::filesystem::create_directories(dir);
  char have[32];
  std::snprintf(have, sizeof have, "%.1f", physical_memory_gib());
  const std::string ply = quoted(data_file("ply/cube_binary.ply"));
  auto r = rayscan_cli("render -q " + ply + " --width 65536 --height 65536 -o " + quoted(dir / "big.exr") +
                       " --aov depth --aov normal --aov position --aov index --aov albedo --aov cost");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: an image of 65536 x 65536 pixels with AOVs needs about 544.0 GiB of buffers, more "
                   "than this machine's " + std::string(have) + " GiB of memory; give a smaller --width or --height\n");
  // A PNG without AOVs: beauty (12), its scaled copy (12) and the float RGB image (12), 144 GiB.
  if (physical_memory_gib() < 144.0) {
    r = rayscan_cli("render -q " + ply + " --width 65536 --height 65536 -o " + quoted(dir / "big.png"));
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.out, "rayscan render: an image of 65536 x 65536 pixels needs about 144.0 GiB of buffers, more than "
                     "this machine's " + std::string(have) + " GiB of memory; give a smaller --width or --height\n");
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

TEST(RenderMemoryCli, AFailedAllocationIsOneLineAndExitCode2) {
  if (rayscan::test::kSanitized) GTEST_SKIP() << "a sanitizer reserves its shadow memory beyond any ulimit -v";
  // 16384 x 16384 pixels for a PNG: 36 bytes a pixel, 9 GiB, within the memory check on a machine
  // of more than 9 GiB. A 2 GB data-size limit (ulimit -d, which the check does not read) makes the
  // 3 GiB framebuffer's allocation fail; a 2 GB address-space limit (ulimit -v) is the check's own
  // limit: refused up front with the estimate.
  if (physical_memory_gib() <= 9.0) GTEST_SKIP() << "the memory check refuses this image here";
  const auto dir = temp_dir() / "render_bad_alloc";
  std::filesystem::create_directories(dir);
  const std::string args = " render -q " + quoted(data_file("ply/cube_binary.ply")) +
                           " --width 16384 --height 16384 -o " + quoted(dir / "mid.png");
  auto r = run_command("ulimit -d 2000000 && " + quoted(RAYSCAN_BIN) + args);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: out of memory (std::bad_alloc)\n");
  r = run_command("ulimit -v 2000000 && " + quoted(RAYSCAN_BIN) + args);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: an image of 16384 x 16384 pixels needs about 9.0 GiB of buffers, more than the "
                   "1.9 GiB of address space this process may use (ulimit -v); give a smaller --width or --height\n");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

TEST(RenderMemoryCli, AnOrthoMapBeyondTheLimitNamesItsCell) {
  if (rayscan::test::kSanitized) GTEST_SKIP() << "a sanitizer reserves its shadow memory beyond any ulimit -v";
  // simple.las spans x 635619.85 .. 638982.55, y 848899.70 .. 853535.43 (`rayscan info`); cells of
  // 0.4 on the grid of its multiples: floor(hi / 0.4) - floor(lo / 0.4) + 1 = 1597456 - 1589049 + 1
  // = 8408 columns and 2133838 - 2122249 + 1 = 11590 rows. The map's buffers (beauty 12, depth 4,
  // albedo 12 and its coverage 4 bytes a pixel) are 2.9 GiB, over a 2 GB address-space limit. The map's size follows
  // from --ortho-map, which the message names (the map takes no --width or --height).
  const auto dir = temp_dir() / "render_memory_ortho";
  std::filesystem::create_directories(dir);
  const auto r = run_command("ulimit -v 2000000 && " + quoted(RAYSCAN_BIN) + " render -q " +
                             quoted(data_file("las/simple.las")) + " --ortho-map 0.4 -o " + quoted(dir / "o.tif"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan render: an image of 8408 x 11590 pixels with AOVs needs about 2.9 GiB of buffers, more than "
                   "the 1.9 GiB of address space this process may use (ulimit -v); give a smaller map (a larger "
                   "--ortho-map cell)\n");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}
