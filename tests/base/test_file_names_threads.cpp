// The shared rules of rayscan_base every job calls instead of its own: extension tests and
// messages (file_names.hpp), thread counts (threads.hpp).
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/threads.hpp"

#include <tbb/global_control.h>

#include <gtest/gtest.h>

#include <sched.h>

using namespace rayscan;

TEST(FileNames, LowerExtensionFoldsAsciiCaseOnly) {
  EXPECT_EQ(lower_extension("a/b/Cloud.LAS"), ".las");
  EXPECT_EQ(lower_extension("x.tar.GZ"), ".gz");
  EXPECT_EQ(lower_extension("noext"), "");
  EXPECT_EQ(lower_extension(".hidden"), "");  // a dot file has no extension (std::filesystem)
  EXPECT_TRUE(has_extension("m.TIFF", {".tif", ".tiff"}));
  EXPECT_FALSE(has_extension("m.tif.png", {".tif", ".tiff"}));
  EXPECT_FALSE(has_extension("tif", {".tif"}));
  EXPECT_EQ(extensions_expected({".las"}), "expected a file name ending in .las");
  EXPECT_EQ(extensions_expected({".las", ".ply"}), "expected a file name ending in .las or .ply");
  EXPECT_EQ(extensions_expected({".a", ".b", ".c"}), "expected a file name ending in .a, .b or .c");
}

TEST(Threads, ZeroMeansTheArenaLimitAndLargerRequestsAreCappedAtIt) {
  // The process's CPU affinity (the kernel's own count) bounds what TBB runs at once.
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof set, &set), 0);
  const unsigned cpus = static_cast<unsigned>(CPU_COUNT(&set));
  EXPECT_EQ(resolve_threads(1), 1u);
  EXPECT_GE(resolve_threads(0), 1u);
  EXPECT_LE(resolve_threads(0), cpus);
  EXPECT_EQ(resolve_threads(1024), resolve_threads(0));  // more than any core count here: capped
  EXPECT_EQ(resolve_threads(cpus + 1), resolve_threads(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
  EXPECT_EQ(resolve_threads(0), 1u);
  EXPECT_EQ(resolve_threads(3), 1u);  // the global limit caps a request too
}
