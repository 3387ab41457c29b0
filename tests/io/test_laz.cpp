// LAZ decoding against independent oracles: the uncompressed LAS files holding the same records
// (the shared data README: autzen_trim.laz = autzen_trim.las; las/derived/*.las were decoded
// from their LAZ by laz-perf; PDAL's simple.las = its LASzip 1.2 pointwise file), compared byte
// for byte.
#include "io_test_util.hpp"

#include "laz_v1_test_encoder.hpp"

#include "rayscan/site/copc.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/translate.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sys/wait.h>

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

// ---- LASzip 1.x: the pointwise compressor (1) and version 1 items (POINT10, GPSTIME11, RGB12,
// BYTE). Oracle: PDAL's simple.las holds the records that LASzip 1.2 compressed into
// simple-laszip-compressor-version-1.2r0.laz (compressor 1, chunk size 0, POINT10/GPSTIME11/RGB12
// version 1). Chunked files with version 1 items (no public sample found) are built with the
// test encoder laz_v1_test_encoder.hpp, itself checked against LASzip's stream first.

namespace rayscan::test {
namespace {

constexpr const char* kV1Laz = "laz/simple-laszip-compressor-version-1.2r0.laz";
constexpr const char* kV1Las = "las/simple.las";


/// Byte offset of the LASzip VLR payload (compressor field) in `b`.
std::size_t laszip_payload(const std::vector<std::uint8_t>& b) {
  const std::string key = "laszip encoded";
  const auto it = std::search(b.begin(), b.end(), key.begin(), key.end());
  if (it == b.end()) return 0;
  return static_cast<std::size_t>(it - b.begin()) - 2 + 54;
}

/// "" when `bytes` decode, else the FormatError's message.
std::string v1_error_of(const std::vector<std::uint8_t>& bytes) {
  try {
    io::read_las_records(bytes, "bad.laz");
  } catch (const io::FormatError& e) {
    return e.what();
  }
  return "";
}

TEST(Laz, LaszipV1PointwiseMatchesLas) {
  RAYSCAN_REQUIRE_FILE(laz, kV1Laz);
  RAYSCAN_REQUIRE_FILE(las, kV1Las);
  // the file is what this test is about: compressor 1, chunk size 0, three version 1 items
  const auto b = slurp(laz);
  const std::size_t p = laszip_payload(b);
  ASSERT_NE(p, 0u);
  EXPECT_EQ(load_at<std::uint16_t>(b, p), 1);       // compressor: pointwise
  EXPECT_EQ(load_at<std::uint32_t>(b, p + 12), 0u);  // chunk size
  ASSERT_EQ(load_at<std::uint16_t>(b, p + 32), 3);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(load_at<std::uint16_t>(b, p + 38 + 6 * i), 1) << "item " << i;
  expect_same_records(kV1Laz, kV1Las);
}

TEST(Laz, LaszipV1ChunkSizeFieldIsIgnoredByThePointwiseCompressor) {
  // LASzip 1.0 wrote 1 there (libLAS's 2011 copy of the same file); LASreadPoint::setup ignores
  // the field for compressor 1
  RAYSCAN_REQUIRE_FILE(laz, kV1Laz);
  RAYSCAN_REQUIRE_FILE(las, kV1Las);
  const auto good = slurp(laz);
  const auto want = io::read_las_records(las).records;
  for (std::uint32_t cs : {1u, 50000u, 0xFFFFFFFFu}) {
    auto b = good;
    store_at<std::uint32_t>(b, laszip_payload(b) + 12, cs);
    const io::LasRecords r = io::read_las_records(b, "v1.laz");
    EXPECT_EQ(r.chunks, 1u);
    EXPECT_TRUE(r.records == want) << "chunk size " << cs;
  }
}

TEST(Laz, V1TestEncoderReproducesLaszipsStream) {
  // the independent check of the test encoder used below: LASzip's own bytes
  RAYSCAN_REQUIRE_FILE(laz, kV1Laz);
  RAYSCAN_REQUIRE_FILE(las, kV1Las);
  const auto b = slurp(laz);
  const io::LasRecords r = io::read_las_records(las);
  const std::vector<std::uint8_t> ours = lazv1::encode_stream(r.records.data(), r.count, r.record_length, r.pdrf);
  const std::vector<std::uint8_t> theirs(b.begin() + load_at<std::uint32_t>(b, 96), b.end());
  ASSERT_EQ(ours.size(), theirs.size());
  std::size_t i = 0;
  while (i < ours.size() && ours[i] == theirs[i]) ++i;
  EXPECT_EQ(i, ours.size()) << "first differing byte " << i;
}

/// A compressor 2 LAZ of `las`'s records with version 1 items in chunks of `chunk` points:
/// header and VLRs from translate_las's output (chunk size, item versions patched), point data
/// and chunk table (byte sizes; with `variable`, chunk size 0 and the point counts too) here.
std::vector<std::uint8_t> chunked_v1(const fs::path& las, std::uint32_t chunk, bool variable) {
  const fs::path tmp = temp_dir() / ("v1src-" + las.filename().string() + ".laz");
  io::TranslateOptions o;
  o.chunk_size = chunk;
  io::translate_las(las, tmp, o);
  auto b = slurp(tmp);
  const std::size_t p = laszip_payload(b);
  const std::uint32_t po = load_at<std::uint32_t>(b, 96);
  store_at<std::uint32_t>(b, p + 12, variable ? 0 : chunk);
  for (std::uint16_t i = 0; i < load_at<std::uint16_t>(b, p + 32); ++i) store_at<std::uint16_t>(b, p + 38 + 6 * i, 1);
  b.resize(po + 8);
  const io::LasRecords r = io::read_las_records(las);
  std::vector<std::uint32_t> counts, sizes;
  for (std::uint64_t first = 0; first < r.count; first += chunk) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(chunk, r.count - first));
    const auto s = lazv1::encode_stream(r.records.data() + first * r.record_length, n, r.record_length, r.pdrf);
    b.insert(b.end(), s.begin(), s.end());
    counts.push_back(static_cast<std::uint32_t>(n));
    sizes.push_back(static_cast<std::uint32_t>(s.size()));
  }
  store_at<std::int64_t>(b, po, static_cast<std::int64_t>(b.size()));
  std::vector<std::uint8_t> table(8, 0);
  store_at<std::uint32_t>(table, 4, static_cast<std::uint32_t>(sizes.size()));
  {
    io::laz::ArithmeticEncoder enc(table);
    io::laz::IntegerCompressor ic(32, 2);
    for (std::size_t i = 0; i < sizes.size(); ++i) {
      if (variable) ic.compress(enc, i ? static_cast<std::int32_t>(counts[i - 1]) : 0, static_cast<std::int32_t>(counts[i]), 0);
      ic.compress(enc, i ? static_cast<std::int32_t>(sizes[i - 1]) : 0, static_cast<std::int32_t>(sizes[i]), 1);
    }
    enc.done();
  }
  b.insert(b.end(), table.begin(), table.end());
  return b;
}

TEST(Laz, V1ItemsInChunkedFilesMatchLas) {
  // PDRF 0-3 (POINT10, + GPSTIME11, + RGB12) and PDRF 3 + 27 extra bytes (BYTE), in chunks of 97
  // points (the last one shorter), fixed and variable (chunk size 0: counts in the table)
  for (const char* rel : {"las/point10.las", "las/point-time.las", "las/point-color.las", "las/point-color-time.las",
                          "las/extrabytes.las", kV1Las}) {
    RAYSCAN_REQUIRE_FILE(las, rel);
    const std::vector<std::uint8_t> want = io::read_las_records(las).records;
    for (bool variable : {false, true}) {
      const auto b = chunked_v1(las, 97, variable);
      const std::size_t p = laszip_payload(b);
      EXPECT_EQ(load_at<std::uint16_t>(b, p), 2);
      const io::LasRecords r = io::read_las_records(b, "v1-chunked.laz");
      EXPECT_EQ(r.chunks, (want.size() / r.record_length + 96) / 97) << rel;
      EXPECT_TRUE(r.notes.empty()) << rel << ": " << r.notes.front();
      EXPECT_TRUE(r.records == want) << rel << (variable ? " (variable chunks)" : "");
    }
  }
}

TEST(Laz, V1PointwiseThroughTheChunkedReaderAndTranslate) {
  RAYSCAN_REQUIRE_FILE(laz, kV1Laz);
  RAYSCAN_REQUIRE_FILE(las, kV1Las);
  io::FileInfo info;
  const PointCloud a = read(laz, &info), b = read(las);
  EXPECT_EQ(info.format, "LAZ");
  ASSERT_EQ(a.size(), 1065u);
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.rgb == b.rgb);
  EXPECT_TRUE(a.gps_time == b.gps_time);
  EXPECT_TRUE(a.intensity == b.intensity);
  EXPECT_TRUE(a.classification == b.classification);
  // `rayscan translate` to LAS: the header (the LASzip VLR dropped) and records of simple.las
  const fs::path out = temp_dir() / "v1-translated.las", err = temp_dir() / "v1-translate.err";
  const std::string cmd = std::string("'") + RAYSCAN_EXE + "' translate '" + laz.string() + "' '" + out.string() +
                          "' >/dev/null 2>'" + err.string() + "'";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  EXPECT_TRUE(slurp(out) == slurp(las));  // simple.las is that file, byte for byte
  // and to a current LAZ (compressor 2, version 2 items): the same records
  const fs::path v2 = temp_dir() / "v1-to-v2.laz";
  EXPECT_TRUE(io::translate_las(laz, v2).compressed);
  EXPECT_TRUE(io::read_las_records(v2).records == io::read_las_records(las).records);
}

TEST(LazBadInput, UnsupportedCompressorItemCombinationsAreNamed) {
  RAYSCAN_REQUIRE_FILE(v1, kV1Laz);
  const auto good = slurp(v1);
  const std::size_t p = laszip_payload(good);
  auto expect = [&](std::vector<std::uint8_t> b, std::size_t at, const std::string& what) {
    const std::string e = v1_error_of(b);
    EXPECT_EQ(e, "bad.laz: byte " + std::to_string(at) + ": " + what);
    EXPECT_EQ(e.find("chunk size"), std::string::npos) << e;
  };
  {
    auto b = good;
    store_at<std::uint16_t>(b, p, 3);
    expect(b, p + 34, "LASzip item 0: compressor 3 with item POINT10 version 1 is not supported "
                      "(LAS 1.0-1.3 items are coded by the pointwise compressors 1 and 2)");
  }
  {
    auto b = good;
    store_at<std::uint16_t>(b, p + 34 + 12 + 4, 0);  // RGB12 version 0
    expect(b, p + 34 + 12, "LASzip item 2: compressor 1 with item RGB12 version 0 is not supported "
                           "(version 0 marks an uncompressed item)");
    store_at<std::uint16_t>(b, p + 34 + 12 + 4, 3);
    expect(b, p + 34 + 12, "LASzip item 2: compressor 1 with item RGB12 version 3 is not supported "
                           "(expected version 1 or 2)");
  }
  {
    auto b = good;
    store_at<std::uint16_t>(b, p + 34 + 12, 9);  // WAVEPACKET13 in place of RGB12
    expect(b, p + 34 + 12, "LASzip item 2: compressor 1 with item WAVEPACKET13 version 1 is not supported "
                           "(waveform packets, PDRF 4/5/9/10 LAZ)");
  }
  {
    auto b = good;  // RGB12 before GPSTIME11: the sizes still add up to 34
    std::swap_ranges(b.begin() + static_cast<std::ptrdiff_t>(p + 40), b.begin() + static_cast<std::ptrdiff_t>(p + 46),
                     b.begin() + static_cast<std::ptrdiff_t>(p + 46));
    expect(b, p + 34 + 12, "LASzip item 2 (GPSTIME11 version 1, 8 bytes): out of order or repeated "
                           "(LAS 1.0-1.3 records hold POINT10, GPSTIME11, RGB12, then BYTE)");
  }
  RAYSCAN_REQUIRE_FILE(l14, "laz/append-bug.laz");  // PDRF 8: POINT14, RGBNIR14, BYTE14 version 3
  for (std::uint16_t c : {1, 2}) {
    auto b = slurp(l14);
    const std::size_t q = laszip_payload(b);
    store_at<std::uint16_t>(b, q, c);
    expect(b, q + 34, "LASzip item 0: compressor " + std::to_string(c) +
                          " with item POINT14 version 3 is not supported "
                          "(LAS 1.4 items are coded by the layered-chunked compressor 3)");
  }
}

TEST(LazBadInput, TruncatedPointwiseStreamStopsAtItsEnd) {
  RAYSCAN_REQUIRE_FILE(v1, kV1Laz);
  const auto good = slurp(v1);
  for (double frac : {0.3, 0.8}) {
    const std::vector<std::uint8_t> b(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(frac * good.size()));
    const std::string e = v1_error_of(b);
    EXPECT_EQ(e.rfind("bad.laz: byte " + std::to_string(b.size()) + ": LAZ chunk 0: compressed stream needs bytes past its end after record ", 0), 0u) << e;
  }
}

TEST(LazBadInput, CliNamesTheUnsupportedCombinationWithExitCode2) {
  RAYSCAN_REQUIRE_FILE(l14, "laz/append-bug.laz");
  auto b = slurp(l14);
  store_at<std::uint16_t>(b, laszip_payload(b), 1);
  const fs::path bad = temp_dir() / "pointwise-las14.laz", err = temp_dir() / "pointwise-las14.err";
  {
    std::ofstream o(bad, std::ios::binary);
    o.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  }
  const std::string cmd = std::string("'") + RAYSCAN_EXE + "' info '" + bad.string() + "' >/dev/null 2>'" + err.string() + "'";
  const int rc = std::system(cmd.c_str());
  EXPECT_EQ(WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, 2);
  const auto e = slurp(err);
  const std::string text(e.begin(), e.end());
  EXPECT_NE(text.find(bad.string() + ": byte "), std::string::npos) << text;
  EXPECT_NE(text.find("compressor 1 with item POINT14 version 3 is not supported"), std::string::npos) << text;
}

}  // namespace
}  // namespace rayscan::test
