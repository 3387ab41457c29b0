// `rayscan translate` / io::translate_las: LAZ -> LAS gives the derived LAS files of the shared
// data byte for byte (they were decoded by laz-perf, header and VLRs copied from the LAZ); LAS ->
// LAZ -> LAS gives the original back byte for byte; our LAZ decodes to the same records with an
// independent decoder (npm laz-perf under Node), and is within 5% of LASzip's size.
#include "io_test_util.hpp"
#include "../common/las_patch.hpp"
#include "../common/npm_tools.hpp"

#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_reader.hpp"
#include "rayscan/io/translate.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
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

// LAS <-> LAZ copies records as they are, so a file whose scale takes a point beyond the
// coordinate bound (1e9) would become a file every reader refuses: translate_las refuses it with
// the LAS reader's own line (oracle: the reader's error on the same file) and writes nothing.
TEST(Translate, ARecordBeyondTheCoordinateBoundIsRefusedAsTheReaderRefusesIt) {
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(3, 0, 0)};
  const fs::path las = temp_dir() / "beyond_bound_in.las";
  write_unit_grid_las(las, pc);
  patch_las_x_scale(las, 5e8);  // point 2: 3 x 5e8 = 1.5e9; points 0 and 1 stay 0
  const std::string reader = reader_error(las);
  ASSERT_NE(reader.find(": point 2: X coordinate is 1.5e+09 (stored integer 3 x scale 5e+08"), std::string::npos)
      << reader;
  for (const char* name : {"beyond_bound.laz", "beyond_bound.las"}) {
    const fs::path out = temp_dir() / name;
    fs::remove(out);
    try {
      io::translate_las(las, out);
      ADD_FAILURE() << name << ": written";
    } catch (const io::FormatError& e) {
      EXPECT_EQ(std::string(e.what()), reader) << name;
    }
    EXPECT_FALSE(fs::exists(out)) << name;
  }
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

/// Record length of the core of a point data record format (LAS 1.4 R15 tables 7-17).
std::size_t core_length(int pdrf) {
  static constexpr std::size_t kLen[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  return kLen[pdrf];
}

TEST(Translate, InternalWaveformRecordIsCopiedAndAddressed) {
  // simple1_3.las: LAS 1.3, PDRF 4, global encoding bit 1 (waveform packets internal), its
  // 160-byte waveform data packet record after the 999 records (header byte 227). Oracle: the
  // input's own bytes; LAS -> LAS keeps every byte, so the output equals the input.
  RAYSCAN_REQUIRE_FILE(in, "las/simple1_3.las");
  const auto a = slurp(in);
  ASSERT_EQ(load_at<std::uint16_t>(a, 6) & 2u, 2u);
  const fs::path out = temp_dir() / "simple1_3_copy.las";
  io::translate_las(in, out);
  expect_same_file(out, in);
  const auto b = slurp(out);
  const std::uint64_t wave = load_at<std::uint64_t>(b, 227);
  ASSERT_LT(wave + 60, b.size());
  EXPECT_EQ(load_at<std::uint16_t>(b, wave + 18), 65535u);  // the waveform record's EVLR-style header
  // LAZ cannot hold it: refused with one line, no file left.
  const fs::path laz = temp_dir() / "simple1_3.laz";
  EXPECT_THROW(io::translate_las(in, laz), std::invalid_argument);
  EXPECT_FALSE(fs::exists(laz));
  // A start that is not after the point records is malformed: named at byte 227.
  auto bad = a;
  store_at<std::uint64_t>(bad, 227, 1000);
  const fs::path bad_in = temp_dir() / "simple1_3_bad_wave.las", bad_out = temp_dir() / "bad_wave_out.las";
  { std::ofstream(bad_in, std::ios::binary).write(reinterpret_cast<const char*>(bad.data()), static_cast<std::streamsize>(bad.size())); }
  try {
    io::translate_las(bad_in, bad_out);
    FAIL() << "waveform start inside the header accepted";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("byte 227"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad_out));
}

TEST(Translate, WaveformStartIsClearedWhenNoWaveformRecordIsCopied) {
  // simple1_3.las with global encoding bit 1 cleared (bit 2, packets in a .wdp file, and no bit):
  // the bytes after the point records are not a waveform record then and are not copied, so the
  // output's start of waveform data packet record (byte 227) is 0 (LAS 1.3 R11: 0 when the file
  // holds no waveform records), never the input's start at or past the output's end. Oracle: the
  // input's own header (offset to point data, count, record length) and bytes.
  RAYSCAN_REQUIRE_FILE(in, "las/simple1_3.las");
  const auto a = slurp(in);
  ASSERT_NE(load_at<std::uint64_t>(a, 227), 0u);
  const std::uint64_t points_end =
      load_at<std::uint32_t>(a, 96) + std::uint64_t(load_at<std::uint32_t>(a, 107)) * load_at<std::uint16_t>(a, 105);
  ASSERT_LT(points_end, a.size());  // the waveform record follows the points
  for (const std::uint16_t encoding : {std::uint16_t(0), std::uint16_t(4)}) {
    auto b = a;
    store_at<std::uint16_t>(b, 6, encoding);
    const fs::path src = temp_dir() / "wave_bit_clear.las", out = temp_dir() / "wave_bit_clear_out.las";
    { std::ofstream(src, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size())); }
    io::translate_las(src, out);
    const auto c = slurp(out);
    ASSERT_EQ(c.size(), points_end) << encoding;
    EXPECT_EQ(load_at<std::uint64_t>(c, 227), 0u) << encoding;
    EXPECT_TRUE(std::equal(c.begin() + 235, c.end(), b.begin() + 235)) << encoding;  // VLRs and records as they were
    EXPECT_TRUE(std::equal(c.begin(), c.begin() + 227, b.begin())) << encoding;
  }
}

TEST(Translate, Las14FormatsRoundTripThroughTheLayeredEncoder) {
  // PDRF 6 (three files), 7 (autzen in LAS 1.4) and 8 + 3 extra bytes (append-bug, via its LAZ)
  for (const char* rel : {"las/test1_4.las", "las/1_4_w_evlr.las", "las/file_with_both_wkt_and_geotiff_vlrs.las",
                          "las/autzen_trim_7.las", "laz/append-bug.laz"}) {
    const fs::path in = data_file(rel);
    if (in.empty()) continue;
    const fs::path laz = temp_dir() / "l14.laz", back = temp_dir() / "l14_back.las", las = temp_dir() / "l14_in.las";
    io::translate_las(in, las);  // plain LAS reference (identity for a LAS input)
    const io::TranslateResult r = io::translate_las(las, laz);
    EXPECT_TRUE(r.compressed) << rel;
    const io::LasRecords ours = io::read_las_records(laz), ref = io::read_las_records(las);
    EXPECT_TRUE(ours.compressed);
    EXPECT_GE(ours.pdrf, 6);
    EXPECT_TRUE(ours.records == ref.records) << rel;
    io::translate_las(laz, back);
    expect_same_file(back, las);
  }
}

// A header count one above what the chunks hold: the last chunk's stream runs out. Reading the
// file (info, query) and translating it must fail alike, naming the file and the stream, instead
// of translate writing one record invented from the stream's padding with success.
TEST(Translate, HeaderCountAboveTheChunksIsRefusedByEveryDecodingPath) {
  RAYSCAN_REQUIRE_FILE(src, "laz/autzen_trim.laz");
  std::vector<std::uint8_t> bytes = slurp(src);
  const std::uint8_t minor = bytes[25];
  std::uint32_t legacy = 0;
  std::memcpy(&legacy, bytes.data() + 107, 4);
  ASSERT_GT(legacy, 0u);
  ++legacy;
  std::memcpy(bytes.data() + 107, &legacy, 4);
  if (minor >= 4) {
    std::uint64_t count = 0;
    std::memcpy(&count, bytes.data() + 247, 8);
    ++count;
    std::memcpy(bytes.data() + 247, &count, 8);
  }
  const fs::path bad = temp_dir() / "count_plus_one.laz", out = temp_dir() / "count_plus_one.las";
  {
    std::ofstream f(bad, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  auto error_of = [](auto&& call) -> std::string {
    try {
      call();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  const std::string read = error_of([&] { (void)io::read_point_cloud(bad); });
  const std::string translated = error_of([&] { (void)io::translate_las(bad, out); });
  EXPECT_NE(read.find("count_plus_one.laz"), std::string::npos) << read;
  EXPECT_NE(read.find("past its end"), std::string::npos) << read;
  EXPECT_NE(translated.find("count_plus_one.laz"), std::string::npos) << translated;
  EXPECT_NE(translated.find("past its end"), std::string::npos) << translated;
  EXPECT_FALSE(fs::exists(out));
}

TEST(Translate, LayeredEncoderKeepsEveryFieldUnderScannerChannelSwitches) {
  // Records rewritten so that every context of the POINT14/RGBNIR14/BYTE14 coders is exercised:
  // scanner channels 0-3 switching (new and already used contexts), return numbers jumping,
  // GPS times with 64-bit jumps and returns to old sequences, negative scan angles, coordinates
  // wrapping int32, all in chunks of 97 points; the decoded records must equal them exactly.
  RAYSCAN_REQUIRE_FILE(src, "laz/append-bug.laz");  // PDRF 8 + 3 extra bytes
  const fs::path las = temp_dir() / "mix.las", laz = temp_dir() / "mix.laz";
  io::translate_las(src, las);
  std::vector<std::uint8_t> bytes = slurp(las);
  const io::LasRecords in = io::read_las_records(las);
  ASSERT_EQ(in.pdrf, 8);
  const std::size_t rec = in.record_length, n = std::min<std::uint64_t>(in.count, 6000);
  std::uint64_t state = 88172645463325252ull;
  auto rnd = [&]() { state ^= state << 13; state ^= state >> 7; state ^= state << 17; return state; };
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* p = bytes.data() + in.point_offset + i * rec;
    const std::uint64_t r = rnd();
    if (r % 7 == 0) p[15] = static_cast<std::uint8_t>((p[15] & 0xCF) | ((r >> 8) % 4) << 4);   // channel
    if (r % 5 == 0) p[14] = static_cast<std::uint8_t>((r >> 12) & 0xFF);                        // returns
    if (r % 11 == 0) { const std::int16_t a = static_cast<std::int16_t>(-(static_cast<int>(r >> 20) % 30000)); std::memcpy(p + 18, &a, 2); }
    if (r % 13 == 0) { const std::uint32_t x = static_cast<std::uint32_t>(r >> 32); std::memcpy(p, &x, 4); }
    if (r % 17 == 0) { double t = static_cast<double>(r >> 40) * 1e3; std::memcpy(p + 22, &t, 8); }
    if (r % 19 == 0) { const double t = -0.0; std::memcpy(p + 22, &t, 8); }
    if (r % 3 == 0) p[core_length(8) + (r >> 50) % 3] = static_cast<std::uint8_t>(r >> 24);    // extra bytes
    if (r % 23 == 0) { const std::uint16_t c = static_cast<std::uint16_t>(r >> 16); std::memcpy(p + 30 + 2 * ((r >> 40) % 4), &c, 2); }
    if (r % 29 == 0) p[16] = static_cast<std::uint8_t>(r >> 28);                                 // classification
    if (r % 31 == 0) p[15] ^= 0xC5;                                                               // flags
  }
  {
    std::ofstream f(las, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  io::TranslateOptions o;
  o.chunk_size = 97;
  io::translate_las(las, laz, o);
  const io::LasRecords ours = io::read_las_records(laz), ref = io::read_las_records(las);
  ASSERT_EQ(ours.records.size(), ref.records.size());
  std::size_t first = 0;
  while (first < ref.records.size() && ours.records[first] == ref.records[first]) ++first;
  EXPECT_EQ(first, ref.records.size()) << "first differing record " << first / rec << " byte " << first % rec;
}

TEST(Translate, LayeredEncoderSizeComparesWithLaszip) {
  // The shared LAZ files were written by LASzip with layered chunks of 50,000 points; ours on the
  // same records must be within 5% of their size (it is equal: 186,462 and 3,240,041 bytes).
  for (const char* name : {"append-bug", "las_with_several_extra_byte_bloc"}) {
    const fs::path their = data_file(std::string("laz/") + name + ".laz");
    const fs::path las = data_file(std::string("las/derived/") + name + ".las");
    if (their.empty() || las.empty()) GTEST_SKIP() << name << ": ../shared/data absent";
    const fs::path laz = temp_dir() / "size.laz";
    io::translate_las(las, laz);
    const double ours = static_cast<double>(fs::file_size(laz)), theirs = static_cast<double>(fs::file_size(their));
    EXPECT_LT(std::abs(ours - theirs) / theirs, 0.05) << name << ": " << ours << " vs LASzip " << theirs;
    EXPECT_TRUE(io::read_las_records(laz).records == io::read_las_records(las).records) << name;
    // Stronger: the compressed point data (chunk table offset, chunks, chunk table) is LASzip's
    // byte for byte; only the LASzip VLR's description and version fields differ.
    const auto a = slurp(laz), b = slurp(their);
    const std::uint64_t from = io::read_las_records(their).point_offset;
    ASSERT_EQ(a.size(), b.size()) << name;
    EXPECT_TRUE(std::equal(a.begin() + static_cast<std::ptrdiff_t>(from), a.end(), b.begin() + static_cast<std::ptrdiff_t>(from)))
        << name << ": compressed point data differs from LASzip's";
  }
}

TEST(Translate, LazPerfUnderNodeDecodesOurLaz) {
  std::string why;
  const fs::path modules = npm_modules(why);
  if (modules.empty()) GTEST_SKIP() << why;
  for (const char* rel : {"las/conformance/point-color-time.las", "las/conformance/extrabytes.las", "las/autzen_trim.las",
                          "las/test1_4.las", "las/autzen_trim_7.las", "laz/append-bug.laz"}) {
    const fs::path src = data_file(rel);
    if (src.empty()) continue;
    const fs::path laz = temp_dir() / "lp.laz", rec = temp_dir() / "lp.rec", las = temp_dir() / "lp.las";
    io::translate_las(src, las);  // plain LAS reference (identity for a LAS input)
    io::translate_las(las, laz);
    const std::string cmd = "node '" + std::string(RAYSCAN_SOURCE_DIR) + "/tests/io/lazperf_decode.js' '" +
                            modules.string() + "' '" + laz.string() + "' '" + rec.string() + "' >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    EXPECT_TRUE(slurp(rec) == io::read_las_records(las).records) << rel;
  }
}

}  // namespace
}  // namespace rayscan::test
