// The translate job (rayscan/jobs/translate.hpp) on real files; oracle: the point records and
// bytes of the input, read back by the io reader.
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/translate.hpp"

#include <gtest/gtest.h>

#include "jobs_test_util.hpp"

#include <filesystem>
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
      EXPECT_NE(m.find("expected a file name ending in .las, .laz, .ply, .pcd, .xyz, .csv or .txt"), std::string::npos) << m;
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
