// LAZ decoding against independent oracles: the uncompressed LAS files holding the same records
// (the shared data README: autzen_trim.laz = autzen_trim.las; las/derived/*.las were decoded
// from their LAZ by laz-perf), compared byte for byte.
#include "io_test_util.hpp"

#include "rayscan/io/las_records.hpp"

namespace rayscan::test {
namespace {

void expect_same_records(const std::string& laz_rel, const std::string& las_rel) {
  const fs::path laz = data_file(laz_rel), las = data_file(las_rel);
  if (laz.empty() || las.empty()) GTEST_SKIP() << laz_rel << " or " << las_rel << " absent";
  const io::LasRecords a = io::read_las_records(laz);
  const io::LasRecords b = io::read_las_records(las);
  EXPECT_TRUE(a.compressed);
  EXPECT_FALSE(b.compressed);
  ASSERT_EQ(a.count, b.count);
  ASSERT_EQ(a.record_length, b.record_length);
  ASSERT_EQ(a.records.size(), b.records.size());
  std::size_t first_diff = a.records.size();
  for (std::size_t i = 0; i < a.records.size(); ++i)
    if (a.records[i] != b.records[i]) { first_diff = i; break; }
  EXPECT_EQ(first_diff, a.records.size()) << "first differing byte " << first_diff << " = record "
                                          << first_diff / a.record_length << " byte " << first_diff % a.record_length;
}

TEST(Laz, AutzenPdrf3MatchesLas) { expect_same_records("laz/autzen_trim.laz", "las/autzen_trim.las"); }
TEST(Laz, LoneStarPdrf1MatchesDerivedLas) { expect_same_records("laz/lone-star.laz", "las/derived/lone-star.las"); }
TEST(Laz, AppendBugPdrf8MatchesDerivedLas) { expect_same_records("laz/append-bug.laz", "las/derived/append-bug.las"); }
TEST(Laz, SeveralExtraBytesPdrf8MatchesDerivedLas) {
  expect_same_records("laz/las_with_several_extra_byte_bloc.laz", "las/derived/las_with_several_extra_byte_bloc.las");
}

}  // namespace
}  // namespace rayscan::test
