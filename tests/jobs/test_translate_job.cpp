// The translate job (rayscan/jobs/translate.hpp) on real files; oracle: the point records and
// bytes of the input, read back by the io reader.
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/jobs/translate.hpp"

#include <gtest/gtest.h>

#include "jobs_test_util.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace rayscan;
using rayscan::test::data_file;
using rayscan::test::fields_of_option_error;
using rayscan::test::file_bytes;
using rayscan::test::temp_dir;
namespace fs = std::filesystem;

TEST(TranslateJob, LasToLazToLasKeepsRecordsAndBytes) {
  const fs::path las = data_file("las/point-color.las");
  const fs::path laz = temp_dir() / "point_color.laz", back = temp_dir() / "point_color_back.las";
  jobs::TranslateJobOptions o;
  o.in = las;
  o.out = laz;
  o.chunk_size = 100;
  const jobs::TranslateJobResult r = jobs::run_translate(o);
  const io::LasRecords in = io::read_las_records(las), z = io::read_las_records(laz);
  EXPECT_TRUE(r.compressed);
  EXPECT_TRUE(z.compressed);
  EXPECT_EQ(r.points, in.count);
  EXPECT_EQ(r.chunks, (in.count + 99) / 100);
  EXPECT_EQ(r.in_bytes, fs::file_size(las));
  EXPECT_EQ(r.out_bytes, fs::file_size(laz));
  EXPECT_TRUE(z.records == in.records);
  EXPECT_EQ(io::read_point_cloud(laz).positions, io::read_point_cloud(las).positions);

  jobs::TranslateJobOptions b;
  b.in = laz;
  b.out = back;
  const jobs::TranslateJobResult rb = jobs::run_translate(b);
  EXPECT_FALSE(rb.compressed);
  EXPECT_EQ(rb.chunks, 0u);
  EXPECT_EQ(rb.points, in.count);
  EXPECT_EQ(file_bytes(back), file_bytes(las));
}

TEST(TranslateJob, CompressionOverridesTheExtension) {
  const fs::path las = data_file("las/point-color.las"), out = temp_dir() / "plain.laz";
  jobs::TranslateJobOptions o;
  o.in = las;
  o.out = out;
  o.compression = jobs::LasCompression::las;
  const jobs::TranslateJobResult r = jobs::run_translate(o);
  EXPECT_FALSE(r.compressed);
  EXPECT_EQ(file_bytes(out), file_bytes(las));
}

TEST(TranslateJob, ChunkSizeOutOfRangeNamesTheField) {
  jobs::TranslateJobOptions o;
  o.in = data_file("las/point-color.las");
  o.out = temp_dir() / "never.laz";
  for (const std::uint32_t n : {0u, 0xFFFFFFFFu}) {
    o.chunk_size = n;
    EXPECT_EQ(fields_of_option_error([&] { jobs::run_translate(o); }), std::vector<std::string>{"chunk_size"});
  }
  EXPECT_FALSE(fs::exists(o.out));
}

// The output's extension decides what is written, for any readable input: LAS -> PLY keeps the
// positions exactly (double) and the colour; PLY -> LAS keeps them at least to half a step of
// write_las's default 0.001 grid; an extension no writer has (.e57, .xyzn) or a COPC name is
// refused before anything is read or written. Before, `translate a.las a.ply` wrote LAS bytes and
// `translate bunny.ply b.las` failed with "expected file signature LASF". Oracle: the readers.
TEST(TranslateJob, WritesWhatTheOutputExtensionSays) {
  const fs::path las = data_file("las/point-color.las");
  const fs::path ply = temp_dir() / "tr.ply", back = temp_dir() / "tr_back.las";
  jobs::TranslateJobOptions o;
  o.in = las;
  o.out = ply;
  const jobs::TranslateJobResult r = jobs::run_translate(o);
  const PointCloud a = io::read_point_cloud(las), b = io::read_point_cloud(ply);
  EXPECT_EQ(r.points, a.size());
  EXPECT_FALSE(r.compressed);
  EXPECT_EQ(file_bytes(ply).substr(0, 4), "ply\n");
  EXPECT_EQ(b.positions, a.positions);
  ASSERT_EQ(b.rgb.size(), a.rgb.size());
  o.in = ply;
  o.out = back;
  jobs::run_translate(o);
  EXPECT_EQ(file_bytes(back).substr(0, 4), "LASF");
  const PointCloud c = io::read_point_cloud(back);
  ASSERT_EQ(c.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(c.positions[i][k], a.positions[i][k], 0.0005 + 1e-9) << i;
  // Refused before reading: the input need not even exist.
  for (const char* name : {"x.e57", "x.xyzn"}) {
    o.in = temp_dir() / "missing.las";
    o.out = temp_dir() / name;
    try {
      jobs::run_translate(o);
      ADD_FAILURE() << name << " accepted";
    } catch (const std::invalid_argument& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(name), std::string::npos) << m;
      // Every name the job writes, .copc.laz included.
      EXPECT_NE(m.find("expected a file name ending in .las, .laz, .copc.laz, .ply, .pcd, .xyz, .csv or .txt"),
                std::string::npos) << m;
    }
    EXPECT_FALSE(fs::exists(temp_dir() / name));
  }
  // A COPC name is written as COPC (io::write_copc): a missing input is an input error, and
  // nothing is left under the name.
  for (const char* name : {"x.copc.laz", "X.COPC.LAZ"}) {
    o.in = temp_dir() / "missing.las";
    o.out = temp_dir() / name;
    EXPECT_ANY_THROW(jobs::run_translate(o)) << name;
    EXPECT_FALSE(fs::exists(temp_dir() / name));
  }
}

namespace {

/// The colour fields of every record of a LAS file, as stored (ASPRS LAS 1.4 R15 section 2.6:
/// red, green, blue at byte 20 of PDRF 2, 28 of PDRF 3 and 5, 30 of PDRF 7, 8 and 10).
std::vector<std::uint16_t> stored_rgb(const fs::path& las) {
  const io::LasRecords r = io::read_las_records(las);
  const std::size_t at = r.pdrf == 2 ? 20 : (r.pdrf == 3 || r.pdrf == 5) ? 28 : 30;
  std::vector<std::uint16_t> v;
  for (std::uint64_t i = 0; i < r.count; ++i)
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint8_t* p = r.records.data() + i * r.record_length + at + 2 * k;
      v.push_back(static_cast<std::uint16_t>(p[0] | p[1] << 8));
    }
  return v;
}

/// The red, green and blue columns of a text file with a header line, point after point, as the
/// file spells them (whole numbers).
std::vector<std::uint16_t> text_rgb(const fs::path& text) {
  std::istringstream in(file_bytes(text));
  std::string line;
  std::getline(in, line);
  std::istringstream header(line);
  std::vector<std::string> names;
  for (std::string n; header >> n;) names.push_back(n);
  const auto column = [&](const std::string& n) {
    return static_cast<std::size_t>(std::find(names.begin(), names.end(), n) - names.begin());
  };
  const std::size_t cols[3] = {column("red"), column("green"), column("blue")};
  EXPECT_LT(cols[2], names.size()) << line;
  std::vector<std::uint16_t> v;
  while (std::getline(in, line)) {
    std::istringstream values(line);
    std::vector<std::string> f;
    for (std::string s; values >> s;) f.push_back(s);
    for (std::size_t c : cols) {
      EXPECT_EQ(f.at(c).find_first_not_of("0123456789"), std::string::npos) << line;
      v.push_back(static_cast<std::uint16_t>(std::stoul(f.at(c))));
    }
  }
  return v;
}

/// `in` translated to `out` by the job.
void translate(const fs::path& in, const fs::path& out) {
  jobs::TranslateJobOptions o;
  o.in = in;
  o.out = out;
  jobs::run_translate(o);
}

}  // namespace

TEST(TranslateJob, TextColourIsTheSourcesOwnValuesBothWays) {
  // autzen_trim.las holds 8-bit colour (max 236) in its 16-bit fields: the text says the file's
  // own values, and a LAS file made from the text stores them again.
  const fs::path las = data_file("las/autzen_trim.las");
  const fs::path xyz = temp_dir() / "autzen_rgb.xyz", back = temp_dir() / "autzen_rgb_back.las",
                 xyz2 = temp_dir() / "autzen_rgb_back.xyz";
  const std::vector<std::uint16_t> own = stored_rgb(las);
  ASSERT_EQ(own.size(), 3u * 110000u);
  ASSERT_EQ(*std::max_element(own.begin(), own.end()), 236);
  translate(las, xyz);
  EXPECT_EQ(text_rgb(xyz), own);
  translate(xyz, back);
  EXPECT_EQ(stored_rgb(back), own);
  translate(back, xyz2);
  EXPECT_EQ(text_rgb(xyz2), own);

  // Text -> LAS -> text keeps a text file's own colour values, 8-bit and 16-bit alike.
  for (const std::string& rgb : {std::string("236 10 0\n100 200 255\n"), std::string("60652 2570 0\n256 65535 1\n")}) {
    SCOPED_TRACE(rgb);
    const fs::path src = temp_dir() / "rgb_src.xyz", mid = temp_dir() / "rgb_mid.las", out = temp_dir() / "rgb_out.xyz";
    std::istringstream lines(rgb);
    std::string text = "x y z red green blue\n";
    std::vector<std::uint16_t> want;
    int k = 0;
    for (std::string line; std::getline(lines, line); ++k) {
      text += std::to_string(k) + " 2 3 " + line + "\n";
      std::istringstream v(line);
      for (unsigned c; v >> c;) want.push_back(static_cast<std::uint16_t>(c));
    }
    std::ofstream(src, std::ios::binary) << text;
    ASSERT_EQ(text_rgb(src), want);
    translate(src, mid);
    EXPECT_EQ(stored_rgb(mid), want);
    translate(mid, out);
    EXPECT_EQ(text_rgb(out), want);
  }
}

namespace {

/// Record i's bytes [at, at + n) of a LAS file's records.
std::string record_bytes(const io::LasRecords& r, std::uint64_t i, std::size_t at, std::size_t n) {
  return {reinterpret_cast<const char*>(r.records.data() + i * r.record_length + at), n};
}

}  // namespace

// extrabytes.las has an Extra Bytes field "Intensity" beside the standard intensity: LAS -> csv ->
// LAS keeps both, the extra field under "Intensity_1" (the text reader would take a second
// "intensity" column for the same attribute). Oracle: the source's records (X, Y, Z and
// intensity bytes) and the cloud the LAS reader gives of the source.
TEST(TranslateJob, LasToCsvToLasKeepsAnExtraFieldNamedLikeAStandardOne) {
  const fs::path las = data_file("las/extrabytes.las");
  const fs::path csv = temp_dir() / "extrabytes.csv", back = temp_dir() / "extrabytes_back.las";
  translate(las, csv);
  const std::string text = file_bytes(csv);
  const std::string header = "," + text.substr(0, text.find('\n')) + ",";
  EXPECT_NE(header.find(",intensity,"), std::string::npos) << header;
  EXPECT_NE(header.find(",Intensity_1,"), std::string::npos) << header;
  translate(csv, back);

  const io::LasRecords a = io::read_las_records(las), b = io::read_las_records(back);
  ASSERT_EQ(b.count, a.count);
  for (std::uint64_t i = 0; i < a.count; ++i)  // X, Y, Z (same 0.01 grid, offset 0) and intensity
    ASSERT_EQ(record_bytes(b, i, 0, 14), record_bytes(a, i, 0, 14)) << "record " << i;
  const PointCloud src = io::read_point_cloud(las), out = io::read_point_cloud(back);
  EXPECT_EQ(out.positions, src.positions);
  EXPECT_EQ(out.intensity, src.intensity);
  EXPECT_EQ(out.classification, src.classification);
  EXPECT_EQ(out.gps_time, src.gps_time);
  EXPECT_EQ(out.rgb, src.rgb);
  ASSERT_NE(src.scalar("Intensity"), nullptr);
  for (const ScalarField& f : src.scalars) {
    std::string name = f.name == "Intensity" ? "Intensity_1" : f.name;
    for (char& c : name)
      if (c == '[' || c == ']') c = '_';  // "Colors[0]" is written as the token "Colors_0_"
    const ScalarField* g = out.scalar(name);
    ASSERT_NE(g, nullptr) << name;
    ASSERT_EQ(g->values.size(), f.values.size()) << name;
    // PDRF 0-5's whole-degree scan angle is stored in PDRF 6's 0.006-degree steps (formats.md).
    const double tol = f.name == "scan_angle" ? 0.003 : 0.0;
    for (std::size_t i = 0; i < f.values.size(); ++i) ASSERT_NEAR(g->values[i], f.values[i], tol) << name << " " << i;
  }
}

// An index file translates like the files it was built from: its points in the sources' order,
// the attributes it stores, and LAS positions on the sources' grid (bit-exact records). Oracle:
// the source's records and the cloud the LAS reader gives of it.
TEST(TranslateJob, IndexFileToLasGivesTheSourcesPointsAndStoredAttributes) {
  const fs::path src_las = data_file("las/autzen_trim.las");
  const fs::path rsi = temp_dir() / "autzen_translate.rsi", out = temp_dir() / "autzen_from_rsi.las";
  jobs::IndexJobOptions io_opt;
  io_opt.inputs = {src_las};
  io_opt.output = rsi;
  io_opt.attributes = "id,rgb,intensity,classification,gps_time";
  jobs::run_index(io_opt);
  jobs::TranslateJobOptions o;
  o.in = rsi;
  o.out = out;
  const jobs::TranslateJobResult r = jobs::run_translate(o);
  const PointCloud src = io::read_point_cloud(src_las), back = io::read_point_cloud(out);
  EXPECT_EQ(r.points, src.size());
  EXPECT_EQ(back.positions, src.positions);
  EXPECT_EQ(back.rgb, src.rgb);
  EXPECT_EQ(back.intensity, src.intensity);
  EXPECT_EQ(back.classification, src.classification);
  EXPECT_EQ(back.gps_time, src.gps_time);
  EXPECT_EQ(back.crs_wkt, src.crs_wkt);
  const io::LasRecords a = io::read_las_records(src_las), b = io::read_las_records(out);
  ASSERT_EQ(b.count, a.count);
  for (std::uint64_t i = 0; i < a.count; ++i) ASSERT_EQ(record_bytes(b, i, 0, 12), record_bytes(a, i, 0, 12)) << i;
  EXPECT_EQ(stored_rgb(out), stored_rgb(src_las));  // the source's 8-bit values (max 236), not x 257

  // COPC is written from point files only: refused before anything is written, naming the input.
  o.out = temp_dir() / "autzen_from_rsi.copc.laz";
  try {
    jobs::run_translate(o);
    ADD_FAILURE() << "COPC output of an index file accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(rsi.string() + ": COPC output of an index file"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out));
}
