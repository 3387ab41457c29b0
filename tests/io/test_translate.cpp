// `rayscan translate` / io::translate_las: LAZ -> LAS gives the derived LAS files of the shared
// data byte for byte (they were decoded by laz-perf, header and VLRs copied from the LAZ); LAS ->
// LAZ -> LAS gives the original back byte for byte; our LAZ decodes to the same records with an
// independent decoder (npm laz-perf under Node), and is within 5% of LASzip's size.
#include "io_test_util.hpp"

#include "rayscan/io/las_records.hpp"
#include "rayscan/io/translate.hpp"

#include <cstdlib>
#include <sys/wait.h>

namespace rayscan::test {
namespace {

void expect_same_file(const fs::path& a, const fs::path& b) {
  const auto x = slurp(a), y = slurp(b);
  ASSERT_EQ(x.size(), y.size()) << a << " vs " << b;
  std::size_t i = 0;
  while (i < x.size() && x[i] == y[i]) ++i;
  EXPECT_EQ(i, x.size()) << "first differing byte " << i;
}

TEST(Translate, LazToLasEqualsTheDerivedFiles) {
  for (const char* name : {"lone-star", "append-bug"}) {
    const fs::path laz = data_file(std::string("laz/") + name + ".laz");
    const fs::path las = data_file(std::string("las/derived/") + name + ".las");
    if (laz.empty() || las.empty()) GTEST_SKIP() << name << ": ../shared/data absent";
    const fs::path out = temp_dir() / (std::string(name) + ".las");
    const io::TranslateResult r = io::translate_las(laz, out);
    EXPECT_FALSE(r.compressed);
    expect_same_file(out, las);
  }
}

TEST(Translate, LasToLazToLasRoundTripsAndStaysCloseToLaszipSize) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(laszip_laz, "laz/autzen_trim.laz");
  const fs::path laz = temp_dir() / "autzen.laz", back = temp_dir() / "autzen_back.las";
  const io::TranslateResult r = io::translate_las(las, laz);
  EXPECT_TRUE(r.compressed);
  EXPECT_EQ(r.chunks, 3u);  // 110000 points in chunks of 50000
  const io::LasRecords a = io::read_las_records(laz), b = io::read_las_records(las);
  EXPECT_TRUE(a.compressed);
  EXPECT_TRUE(a.records == b.records);
  io::translate_las(laz, back);
  expect_same_file(back, las);
  const double ours = static_cast<double>(fs::file_size(laz)), theirs = static_cast<double>(fs::file_size(laszip_laz));
  EXPECT_LT(std::abs(ours - theirs) / theirs, 0.05) << ours << " vs LASzip " << theirs;
}

TEST(Translate, ExtraBytesAndSmallChunksRoundTrip) {
  RAYSCAN_REQUIRE_FILE(las, "las/conformance/extrabytes.las");  // PDRF 3 + 27 extra bytes
  const fs::path laz = temp_dir() / "eb.laz";
  io::TranslateOptions o;
  o.chunk_size = 100;
  const io::TranslateResult r = io::translate_las(las, laz, o);
  EXPECT_EQ(r.chunks, 11u);
  EXPECT_TRUE(io::read_las_records(laz).records == io::read_las_records(las).records);
}

TEST(Translate, LazPerfUnderNodeDecodesOurLaz) {
  // npm laz-perf (WASM) is installed into a cache outside the repository.
  const char* home = std::getenv("HOME");
  const fs::path cache = fs::path(std::getenv("RAYSCAN_NPM_CACHE") ? std::getenv("RAYSCAN_NPM_CACHE")
                                  : (home ? std::string(home) + "/.cache/rayscan-npm" : "/tmp/rayscan-npm"));
  if (std::system("node --version >/dev/null 2>&1") != 0) GTEST_SKIP() << "node is not installed";
  if (!fs::exists(cache / "node_modules" / "laz-perf")) {
    fs::create_directories(cache);
    const std::string cmd = "cd '" + cache.string() + "' && timeout 120 npm install --no-audit --no-fund laz-perf@0.0.7 >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0 || !fs::exists(cache / "node_modules" / "laz-perf"))
      GTEST_SKIP() << "npm could not install laz-perf into " << cache << " (registry unreachable?)";
  }
  for (const char* rel : {"las/conformance/point-color-time.las", "las/conformance/extrabytes.las", "las/autzen_trim.las"}) {
    const fs::path las = data_file(rel);
    if (las.empty()) continue;
    const fs::path laz = temp_dir() / "lp.laz", rec = temp_dir() / "lp.rec";
    io::translate_las(las, laz);
    const std::string cmd = "node '" + std::string(RAYSCAN_SOURCE_DIR) + "/tests/io/lazperf_decode.js' '" +
                            (cache / "node_modules").string() + "' '" + laz.string() + "' '" + rec.string() + "' >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    EXPECT_TRUE(slurp(rec) == io::read_las_records(las).records) << rel;
  }
}

}  // namespace
}  // namespace rayscan::test
