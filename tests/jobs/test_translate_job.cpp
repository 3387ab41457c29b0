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
