// LAZ decoding against independent oracles: the uncompressed LAS files holding the same records
// (the shared data README: autzen_trim.laz = autzen_trim.las; las/derived/*.las were decoded
// from their LAZ by laz-perf), compared byte for byte.
#include "io_test_util.hpp"

#include "rayscan/site/copc.hpp"
#include "rayscan/io/las_records.hpp"

#include <algorithm>
#include <cstring>

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

// ---- bad input: corrupted streams, tables and counts give one FormatError naming file, chunk, byte

namespace rayscan::test {
namespace {

std::vector<std::uint8_t> autzen_laz() { return slurp(data_file("laz/autzen_trim.laz")); }

std::string error_of(const std::vector<std::uint8_t>& bytes) {
  try {
    io::read_las_records(bytes, "bad.laz");
  } catch (const io::FormatError& e) {
    return e.what();
  }
  return "";
}

std::uint64_t u64_at(const std::vector<std::uint8_t>& b, std::size_t at) {
  std::uint64_t v;
  std::memcpy(&v, b.data() + at, 8);
  return v;
}

TEST(LazBadInput, CorruptedArithmeticStreamNamesTheChunk) {
  if (data_file("laz/autzen_trim.laz").empty()) GTEST_SKIP() << "autzen_trim.laz absent";
  const auto good = autzen_laz();
  std::uint32_t po;
  std::memcpy(&po, good.data() + 96, 4);
  const std::uint64_t table = u64_at(good, po);
  // Chunk 1 starts where chunk 0 ends; corrupt bytes well inside the last chunk instead, whose
  // start we do not need: anywhere between 60% and 90% of the point data is inside chunk 1 or 2.
  for (double frac : {0.6, 0.75, 0.9}) {
    auto bad = good;
    const std::size_t at = po + static_cast<std::size_t>(frac * static_cast<double>(table - po));
    for (std::size_t k = 0; k < 16; ++k) bad[at + k] ^= 0x5A;
    const std::string e = error_of(bad);
    EXPECT_EQ(e.rfind("bad.laz: byte ", 0), 0u) << e;
    EXPECT_NE(e.find("LAZ chunk "), std::string::npos) << e;
  }
}

TEST(LazBadInput, ChunkTablePastTheEndFallsBackToWalkingTheChunks) {
  if (data_file("laz/autzen_trim.laz").empty()) GTEST_SKIP() << "autzen_trim.laz absent";
  const auto good = autzen_laz();
  std::uint32_t po;
  std::memcpy(&po, good.data() + 96, 4);
  auto bad = good;
  const std::uint64_t past = good.size() + 1000;
  std::memcpy(bad.data() + po, &past, 8);
  const std::uint64_t also = good.size() * 2;  // and the copy in the last 8 bytes
  std::memcpy(bad.data() + bad.size() - 8, &also, 8);
  const io::LasRecords r = io::read_las_records(bad, "bad.laz");
  EXPECT_TRUE(r.records == io::read_las_records(good, "good.laz").records);
  ASSERT_FALSE(r.notes.empty());
  EXPECT_NE(r.notes[0].find("points outside the file"), std::string::npos) << r.notes[0];
}

TEST(LazBadInput, PointCountDisagreeingWithTheChunksIsRefused) {
  if (data_file("laz/append-bug.laz").empty()) GTEST_SKIP() << "append-bug.laz absent";
  auto bad = slurp(data_file("laz/append-bug.laz"));  // LAS 1.4 layered: 64-bit count at 247
  const std::uint64_t n = u64_at(bad, 247) + 7;
  std::memcpy(bad.data() + 247, &n, 8);
  const std::string e = error_of(bad);
  EXPECT_EQ(e.rfind("bad.laz: byte ", 0), 0u) << e;
  EXPECT_NE(e.find("37812"), std::string::npos) << e;
}

TEST(LazBadInput, UnknownItemTypeNamesTheVlrByte) {
  if (data_file("laz/autzen_trim.laz").empty()) GTEST_SKIP() << "autzen_trim.laz absent";
  auto bad = autzen_laz();
  // find the LASzip VLR payload; its first item type is at payload + 34
  const std::string key = "laszip encoded";
  const auto it = std::search(bad.begin(), bad.end(), key.begin(), key.end());
  ASSERT_NE(it, bad.end());
  const std::size_t payload = static_cast<std::size_t>(it - bad.begin()) - 2 + 54;
  bad[payload + 34 + 6] = 99;  // second item: type 99
  const std::string e = error_of(bad);
  EXPECT_EQ(e, "bad.laz: byte " + std::to_string(payload + 34 + 6) +
                   ": LASzip item 1 (type 99 version 2, 8 bytes): unknown item type") << e;
}

TEST(LazBadInput, CopcHierarchyCycleAndPageOffsetsPastTheEnd) {
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const auto good = slurp(p);
  const io::CopcInfo c = io::read_copc_info(good, "good.copc.laz");
  const std::size_t page = static_cast<std::size_t>(c.root_hier_offset);
  {  // the last entry of the root page becomes a reference to the root page itself
    auto bad = good;
    const std::size_t e = page + static_cast<std::size_t>(c.root_hier_size) - 32;
    std::memcpy(bad.data() + e + 16, &c.root_hier_offset, 8);
    const std::int32_t size = static_cast<std::int32_t>(c.root_hier_size), minus1 = -1;
    std::memcpy(bad.data() + e + 24, &size, 4);
    std::memcpy(bad.data() + e + 28, &minus1, 4);
    try {
      io::read_copc_info(bad, "bad.copc.laz");
      FAIL() << "cycle accepted";
    } catch (const io::FormatError& ex) {
      EXPECT_NE(std::string(ex.what()).find("cycle"), std::string::npos) << ex.what();
    }
  }
  {  // a node's chunk offset past the end of the file
    auto bad = good;
    const std::uint64_t past = good.size() + 5;
    std::memcpy(bad.data() + page + 16, &past, 8);
    try {
      io::read_copc_info(bad, "bad.copc.laz");
      FAIL() << "offset past the end accepted";
    } catch (const io::FormatError& ex) {
      EXPECT_EQ(std::string(ex.what()).rfind("bad.copc.laz: byte " + std::to_string(page + 16), 0), 0u) << ex.what();
    }
  }
}

}  // namespace
}  // namespace rayscan::test
