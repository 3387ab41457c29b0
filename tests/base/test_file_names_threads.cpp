// The shared rules of rayscan_base every job calls instead of its own: extension tests and
// messages (file_names.hpp), lists in messages (list_text.hpp), thread counts (threads.hpp), byte
// sizes (byte_size.hpp).
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/list_text.hpp"
#include "rayscan/base/threads.hpp"

#include <tbb/global_control.h>

#include <gtest/gtest.h>

#include <sched.h>

#include <array>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

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

// Expected: the lists as written by hand, for none, one, two and three words, from each kind of
// container the callers hold.
TEST(ListText, JoinsTheLastTwoByTheConjunctionAndTheRestByCommas) {
  EXPECT_EQ(join_alternatives(std::vector<std::string>{}), "");
  EXPECT_EQ(join_alternatives(std::vector<std::string>{"las"}), "las");
  EXPECT_EQ(join_alternatives(std::vector<std::string>{"las", "ply"}), "las or ply");
  EXPECT_EQ(join_alternatives(std::vector<std::string>{"las", "ply", "pcd"}), "las, ply or pcd");
  EXPECT_EQ(join_words(std::array<std::string_view, 0>{}, "and"), "");
  EXPECT_EQ(join_words(std::array<std::string_view, 1>{"a"}, "and"), "a");
  EXPECT_EQ(join_words(std::array<std::string_view, 2>{"a", "b"}, "and"), "a and b");
  EXPECT_EQ(join_words(std::array<std::string_view, 3>{"a", "b", "c"}, "and"), "a, b and c");
  EXPECT_EQ(join_alternatives(std::vector<const char*>{"depth", "normal", "position", "id"}),
            "depth, normal, position or id");
  // Words are written as given: commas, spaces and quotes inside them are not escaped.
  EXPECT_EQ(join_alternatives(std::vector<std::string>{"'a, b'", ""}), "'a, b' or ");
}

TEST(ByteSize, BinaryMultiplesWithTheUnitInEitherAsciiCase) {
  // K, M, G, T are 2^10, 2^20, 2^30, 2^40 bytes, with an optional B or iB, in any ASCII case.
  EXPECT_EQ(parse_byte_size("65536"), 65536u);
  EXPECT_EQ(parse_byte_size("4G"), 4ull << 30);
  EXPECT_EQ(parse_byte_size("4g"), 4ull << 30);
  EXPECT_EQ(parse_byte_size("512mib"), 512ull << 20);
  EXPECT_EQ(parse_byte_size("2KiB"), 2048u);
  EXPECT_EQ(parse_byte_size("2kB"), 2048u);
  EXPECT_EQ(parse_byte_size("1.5G"), 3ull << 29);
  EXPECT_EQ(parse_byte_size("3tB"), 3ull << 40);
  for (const char* bad : {"10Q", "0", "-1K", "K", "4GX", "4 G", "2e18", "4\xC4\xB0"}) {  // the last: 4 and U+0130
    SCOPED_TRACE(bad);
    try {
      (void)parse_byte_size(bad);
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()),
                "size '" + std::string(bad) + "': expected a positive number with an optional K, M, G or T suffix");
    }
  }
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
