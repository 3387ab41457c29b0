// The translate job (rayscan/jobs/translate.hpp) on real files; oracle: the point records and
// bytes of the input, read back by the io reader, and the output's header bytes.
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/jobs/translate.hpp"

#include <cpl_conv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include "jobs_test_util.hpp"
#include "../common/extra_bytes_descriptors.hpp"
#include "../common/file_size_limit.hpp"
#include "../common/las_patch.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <sstream>
#include <string>
#include <utility>
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
  for (std::uint64_t i = 0; i < a.count; ++i)  // intensity
    ASSERT_EQ(record_bytes(b, i, 12, 2), record_bytes(a, i, 12, 2)) << "record " << i;
  const PointCloud src = io::read_point_cloud(las), out = io::read_point_cloud(back);
  // X, Y, Z: the text's 2 decimals on the source's 0.01 grid (offset 0), the writer's grid found
  // from them (its offset may differ), so the same coordinates when rounded to the scale.
  ASSERT_EQ(out.size(), a.count);
  for (std::uint64_t i = 0; i < a.count; ++i)
    for (int k = 0; k < 3; ++k) {
      std::int32_t q = 0;
      std::memcpy(&q, a.records.data() + i * a.record_length + 4 * k, 4);
      ASSERT_EQ(std::llround(out.positions[i][k] / 0.01), q) << "record " << i;
    }
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

namespace {

/// The header's scale factors and offsets, X Y Z each (ASPRS LAS 1.4 R15 table 3: doubles at
/// bytes 131, 139, 147 and 155, 163, 171; the same in LAS 1.2, and a LAZ or COPC header is not
/// compressed).
std::pair<Vec3, Vec3> header_grid(const fs::path& las) {
  const std::string b = file_bytes(las);
  EXPECT_GE(b.size(), 179u) << las;
  Vec3 scale(0.0), offset(0.0);
  for (int k = 0; k < 3 && b.size() >= 179; ++k) {
    std::memcpy(&scale[k], b.data() + 131 + 8 * k, 8);
    std::memcpy(&offset[k], b.data() + 155 + 8 * k, 8);
  }
  return {scale, offset};
}

/// A 0.5-unit float scan (a small object in metres): 3000 float coordinates off every decimal grid,
/// around (12.3, -4.5, 0.8), written as binary PLY.
fs::path small_float_scan() {
  const fs::path ply = temp_dir() / "small_object.ply";
  PointCloud pc;
  std::uint32_t h = 12345;
  auto u = [&] {  // a fixed sequence in [0, 0.5) (xorshift), as floats like a scanner's
    h ^= h << 13, h ^= h >> 17, h ^= h << 5;
    return static_cast<double>(static_cast<float>((h % 1000000) * 5e-7));
  };
  for (int i = 0; i < 3000; ++i)
    pc.positions.emplace_back(static_cast<float>(12.3 + u()), static_cast<float>(-4.5 + u()), static_cast<float>(0.8 + u()));
  io::write_ply(ply, pc);
  return ply;
}

/// The largest |a - b| per axis of two clouds of the same size.
Vec3 max_error(const PointCloud& a, const PointCloud& b) {
  EXPECT_EQ(a.size(), b.size());
  Vec3 e(0.0);
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    for (int k = 0; k < 3; ++k) e[k] = std::max(e[k], std::abs(a.positions[i][k] - b.positions[i][k]));
  return e;
}

}  // namespace

// --scale / --offset (PDAL writers.las scale_x, offset_x): LAS, LAZ and COPC output of a small
// float scan carry the asked grid in their header, and every point reads back within half a step.
// The automatic rule (0.001 here: the floats lie on no decimal grid) keeps only half a millimetre.
// Oracle: the header's own bytes and the PLY's coordinates.
TEST(TranslateJob, ScaleAndOffsetAreTheHeadersAndPointsReadBackWithinHalfAStep) {
  const fs::path ply = small_float_scan();
  const PointCloud src = io::read_point_cloud(ply);
  jobs::TranslateJobOptions o;
  o.in = ply;
  o.out = temp_dir() / "small_auto.las";
  jobs::run_translate(o);
  EXPECT_EQ(header_grid(o.out).first, Vec3(0.001));
  EXPECT_GT(max_error(io::read_point_cloud(o.out), src).x, 1e-4);  // millimetres only

  for (const char* name : {"small_1e-6.las", "small_1e-6.laz", "small_1e-6.copc.laz"}) {
    SCOPED_TRACE(name);
    o.out = temp_dir() / name;
    o.scale = {1e-6};
    o.offset = Vec3(12, -5, 0.5);
    if (std::string(name) == "small_1e-6.laz") o.chunk_size = 1000;  // (refused for the others)
    else o.chunk_size.reset();
    const jobs::TranslateJobResult r = jobs::run_translate(o);
    EXPECT_EQ(r.points, src.size());
    const auto [scale, offset] = header_grid(o.out);
    EXPECT_EQ(scale, Vec3(1e-6));
    EXPECT_EQ(offset, Vec3(12, -5, 0.5));
    const Vec3 e = max_error(io::read_point_cloud(o.out), src);
    for (int k = 0; k < 3; ++k) EXPECT_LE(e[k], 0.5e-6 * (1 + 1e-6)) << k;
    if (std::string(name) == "small_1e-6.laz") {
      EXPECT_EQ(r.chunks, 3u);  // the job's chunk size
    }
  }
  for (const auto& de : fs::directory_iterator(temp_dir()))  // no temporary left behind
    EXPECT_EQ(de.path().filename().string().find(".grid.las"), std::string::npos) << de.path();

  // Three scales with automatic offsets: each at or below the axis' lowest point, within 1000 steps.
  o.out = temp_dir() / "small_xyz.las";
  o.scale = {1e-5, 2e-5, 1e-4};
  o.offset.reset();
  jobs::run_translate(o);
  const auto [scale, offset] = header_grid(o.out);
  EXPECT_EQ(scale, Vec3(1e-5, 2e-5, 1e-4));
  const PointCloud back = io::read_point_cloud(o.out);
  const AABB box = src.bounds();
  const Vec3 e = max_error(back, src);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(offset[k], box.lo[k]) << k;
    EXPECT_GT(offset[k] + 1000 * scale[k], box.lo[k]) << k;
    EXPECT_LE(e[k], 0.5 * scale[k] * (1 + 1e-6)) << k;
  }
}

// A new grid for a LAZ or COPC output goes through an intermediate LAS beside the output: however
// the write ends, while that LAS is written (a file-size limit: EFBIG, as a full disk gives
// ENOSPC) or after, while it is compressed (a progress callback that throws), the error is the
// output's, the old output is kept and neither the intermediate nor a temporary is left.
// Oracle: the folder's own listing and the old file's bytes.
TEST(TranslateJob, AFailedWriteThroughAnIntermediateLasLeavesOnlyTheOldOutput) {
  jobs::TranslateJobOptions o;
  o.in = data_file("las/autzen_trim.las");  // 110,000 points: 3 MB of LAS
  o.scale = {0.001};
  for (const char* name : {"x.laz", "x.copc.laz"}) {
    SCOPED_TRACE(name);
    const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_translate_failure");
    o.out = dir / name;
    std::ofstream(o.out) << "OLD";
    o.progress = nullptr;
    const std::string error = rayscan::test::error_within_file_size(64 << 10, [&] { (void)jobs::run_translate(o); });
    EXPECT_EQ(error.rfind(o.out.string() + ": write failed", 0), 0u) << error;
    EXPECT_EQ(file_bytes(o.out), "OLD");
    EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{name});

    std::set<std::string> seen;  // the folder when the first progress report came
    o.progress = [&](const char*, std::uint64_t, std::uint64_t) {
      if (!seen.empty()) return;
      seen = rayscan::test::entry_names(dir);
      throw std::runtime_error("stopped");
    };
    EXPECT_THROW((void)jobs::run_translate(o), std::runtime_error);
    EXPECT_TRUE(std::any_of(seen.begin(), seen.end(),
                            [](const std::string& n) { return n.find(".grid.las") != std::string::npos; }))
        << "the intermediate LAS was not there yet";
    EXPECT_EQ(file_bytes(o.out), "OLD");
    EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{name});
    fs::remove_all(dir);
  }
}

// A LAS input keeps its own grid unless asked: the lossless LAS -> LAZ copy keeps the header
// (autzen_trim.las: 0.01, offset 0); --offset alone keeps the input's scale with the given
// offsets, --offset auto the input's scale with the low corner rounded down to 1000 steps (10
// units), and the points keep their values. Oracle: the header bytes of input and output.
TEST(TranslateJob, LasInputKeepsItsScaleAndTakesAGivenOrAutomaticOffset) {
  const fs::path las = data_file("las/autzen_trim.las");
  const auto [in_scale, in_offset] = header_grid(las);
  ASSERT_EQ(in_scale, Vec3(0.01));
  ASSERT_EQ(in_offset, Vec3(0.0));
  const PointCloud src = io::read_point_cloud(las);
  jobs::TranslateJobOptions o;
  o.in = las;
  o.out = temp_dir() / "autzen_keep.laz";
  jobs::run_translate(o);
  EXPECT_EQ(header_grid(o.out), header_grid(las));

  o.out = temp_dir() / "autzen_offset.las";
  o.offset = Vec3(636000, 848900, 400);
  jobs::run_translate(o);
  EXPECT_EQ(header_grid(o.out), std::make_pair(Vec3(0.01), Vec3(636000, 848900, 400)));
  Vec3 e = max_error(io::read_point_cloud(o.out), src);
  for (int k = 0; k < 3; ++k) EXPECT_LE(e[k], 1e-9) << k;  // the same decimals, to the last place

  o.out = temp_dir() / "autzen_auto.las";
  o.offset.reset();
  o.auto_offset = true;
  jobs::run_translate(o);
  const AABB box = src.bounds();  // 636001.76 848935.20 406.26 (rayscan info)
  EXPECT_EQ(header_grid(o.out), std::make_pair(Vec3(0.01), Vec3(std::floor(box.lo.x / 10) * 10,
                                                                  std::floor(box.lo.y / 10) * 10,
                                                                  std::floor(box.lo.z / 10) * 10)));
  EXPECT_EQ(header_grid(o.out).second, Vec3(636000, 848930, 400));
  e = max_error(io::read_point_cloud(o.out), src);
  for (int k = 0; k < 3; ++k) EXPECT_LE(e[k], 1e-9) << k;
}

// Refused before anything is written: a scale <= 0 or not finite, two scales, a non-finite
// offset, an offset with auto, a grid for an output without one; and a point whose
// (value - offset) / scale does not fit a 32-bit integer (autzen's X = 636001.76 at 1e-6 from
// offset 0: 6.4e11), naming the axis and the value.
TEST(TranslateJob, BadScaleOrOffsetIsRefusedNamingTheOption) {
  const fs::path las = data_file("las/autzen_trim.las");
  jobs::TranslateJobOptions o;
  o.in = las;
  o.out = temp_dir() / "never_scaled.las";
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  for (const std::vector<double>& s : std::vector<std::vector<double>>{{0.0}, {-0.01}, {nan}, {inf}, {0.01, 0.01}}) {
    o.scale = s;
    EXPECT_EQ(fields_of_option_error([&] { jobs::run_translate(o); }), std::vector<std::string>{"scale"});
  }
  o.scale.clear();
  o.offset = Vec3(0, nan, 0);
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_translate(o); }), std::vector<std::string>{"offset"});
  o.offset = Vec3(0.0);
  o.auto_offset = true;
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_translate(o); }), std::vector<std::string>{"offset"});
  o.auto_offset = false;
  o.out = temp_dir() / "never_scaled.ply";
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_translate(o); }), std::vector<std::string>{"offset"});
  EXPECT_FALSE(fs::exists(o.out));

  const PointCloud src = io::read_point_cloud(las);
  for (const char* name : {"never_scaled.las", "never_scaled.laz", "never_scaled.copc.laz"}) {
    o.out = temp_dir() / name;
    o.scale = {1e-6};
    o.offset = Vec3(0.0);
    try {
      jobs::run_translate(o);
      ADD_FAILURE() << name << ": accepted";
    } catch (const std::invalid_argument& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind(o.out.string() + ": point 0 coordinate X = " + shortest_text(src.positions[0].x), 0), 0u) << m;
      EXPECT_NE(m.find("does not fit a 32-bit LAS integer (scale 1e-06, offset 0)"), std::string::npos) << m;
    }
    EXPECT_FALSE(fs::exists(o.out)) << name;
  }
  for (const auto& de : fs::directory_iterator(temp_dir()))
    EXPECT_EQ(de.path().filename().string().find(".grid.las"), std::string::npos) << de.path();
}

// The command line: --scale S or SX,SY,SZ and --offset auto|X,Y,Z reach the header; bad values
// are one line and exit 2, with nothing written.
TEST(TranslateJob, CliScaleAndOffset) {
  const fs::path ply = small_float_scan(), dir = temp_dir() / "cli_grid";
  fs::create_directories(dir);
  auto r = test::rayscan_cli("translate -q " + test::quoted(ply) + " " + test::quoted(dir / "a.las") +
                             " --scale 1e-5,2e-5,1e-4 --offset 12,-5,0.5");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(header_grid(dir / "a.las"), std::make_pair(Vec3(1e-5, 2e-5, 1e-4), Vec3(12, -5, 0.5)));
  fs::remove(dir / "a.las");
  const std::string base = "translate -q " + test::quoted(ply) + " " + test::quoted(dir / "b.las");
  r = test::rayscan_cli(base + " --scale 0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --scale 0: expected a finite number > 0\n");
  r = test::rayscan_cli(base + " --scale 0.1,x,0.1");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --scale '0.1,x,0.1': expected S or SX,SY,SZ (numbers > 0)\n");
  r = test::rayscan_cli(base + " --scale 0.1,0.1");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --scale: expected one value (x, y and z) or three (x,y,z), got 2\n");
  r = test::rayscan_cli(base + " --offset 1,2");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --offset '1,2': expected auto or X,Y,Z (three finite numbers)\n");
  // An offset beyond the readers' coordinate bound (1e9) would write a header they refuse, though
  // the stored integers fit at this scale ((0 - 5e9) / 10 = -5e8).
  r = test::rayscan_cli(base + " --scale 10 --offset 0,5e9,0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --offset Y = 5e+09: expected within +-1e+09, the coordinate bound in world units\n");
  r = test::rayscan_cli(base + " --scale 1e-9 --offset 0,0,0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_NE(r.out.find(": point 0 coordinate X = "), std::string::npos) << r.out;
  r = test::rayscan_cli("translate -q " + test::quoted(ply) + " " + test::quoted(dir / "c.xyz") + " --scale 0.01");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out, "rayscan translate: --scale applies to LAS, LAZ and COPC output, not to " + (dir / "c.xyz").string() + "\n");
  EXPECT_TRUE(fs::is_empty(dir));
}

// --memory and --temp-dir are the COPC build's, but a bad one is refused for every output, in one
// line naming the option, before anything is
// written. A given --temp-dir leaves the COPC file's bytes as they are without it, and nothing
// behind. --chunk-size is decimal: 010 is ten points a chunk of a LAS file compressed (the chunk
// count the command reports against the point count read back), not octal 8.
TEST(TranslateJob, CliMemoryAndTempDirAreCheckedForEveryOutput) {
  const fs::path ply = small_float_scan(), dir = temp_dir() / "cli_memory";
  fs::create_directories(dir);
  const fs::path temp = dir / "records";
  fs::create_directories(temp);
  for (const char* name : {"a.ply", "a.las", "a.laz", "a.xyz", "a.copc.laz"}) {
    const std::string base = "translate -q " + test::quoted(ply) + " " + test::quoted(dir / name);
    auto r = test::rayscan_cli(base + " --memory 1Q");
    EXPECT_EQ(r.code, 2) << name;
    EXPECT_EQ(r.out, "rayscan translate: --memory: size '1Q': expected a positive number with an optional K, M, G "
                     "or T suffix\n") << name;
    r = test::rayscan_cli(base + " --temp-dir " + test::quoted(dir / "missing"));
    EXPECT_EQ(r.code, 2) << name;
    EXPECT_EQ(r.out, "rayscan translate: --temp-dir '" + (dir / "missing").string() + "': not an existing folder\n")
        << name;
    EXPECT_FALSE(fs::exists(dir / name)) << name;
  }
  auto r = test::rayscan_cli("translate -q " + test::quoted(ply) + " " + test::quoted(dir / "b.copc.laz"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = test::rayscan_cli("translate -q " + test::quoted(ply) + " " + test::quoted(dir / "c.copc.laz") + " --temp-dir " +
                        test::quoted(temp));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(file_bytes(dir / "c.copc.laz"), file_bytes(dir / "b.copc.laz"));
  EXPECT_TRUE(fs::is_empty(temp));
  const fs::path las = data_file("las/point-color.las");  // LAS to LAZ: chunks of --chunk-size
  r = test::rayscan_cli("translate -q " + test::quoted(las) + " " + test::quoted(dir / "d.laz") + " --chunk-size 010");
  ASSERT_EQ(r.code, 0) << r.out;
  const std::size_t points = io::read_point_cloud(dir / "d.laz").size();
  EXPECT_NE(r.out.find(" in " + std::to_string((points + 9) / 10) + " chunks"), std::string::npos)
      << points << " points: " << r.out;
}

// LAS -> text prints each coordinate with the decimals of the file's scale (autzen_trim.las:
// 0.01, 2 decimals), as las2txt does, not the reader's double (849393.9500000001): every X, Y, Z
// is the record's integer x scale + offset when rounded to the scale, and no coordinate has more
// decimals. Text -> LAS stores the same integers again. A source with no LAS grid (PLY floats)
// keeps the shortest form that reads back bit for bit. Oracle: the LAS records' own bytes and
// the header's scale and offset (table 3).
TEST(TranslateJob, TextOfLasHasTheDecimalsOfTheScale) {
  const fs::path las = data_file("las/autzen_trim.las");
  const fs::path txt = temp_dir() / "autzen_grid.txt", back = temp_dir() / "autzen_grid_back.las";
  translate(las, txt);
  const auto [scale, offset] = header_grid(las);
  ASSERT_EQ(scale, Vec3(0.01));
  const io::LasRecords rec = io::read_las_records(las);
  std::istringstream in(file_bytes(txt));
  std::string line;
  std::getline(in, line);
  ASSERT_EQ(line.substr(0, 6), "x y z ");
  std::uint64_t i = 0;
  for (; std::getline(in, line) && i < rec.count; ++i) {
    std::istringstream values(line);
    for (int k = 0; k < 3; ++k) {
      std::string t;
      values >> t;
      const std::size_t dot = t.find('.');
      ASSERT_NE(dot, std::string::npos) << line;
      ASSERT_EQ(t.size() - dot - 1, 2u) << "record " << i << ": " << t;
      std::int32_t q = 0;
      std::memcpy(&q, rec.records.data() + i * rec.record_length + 4 * k, 4);
      ASSERT_EQ(std::llround((std::stod(t) - offset[k]) / scale[k]), q) << "record " << i << ": " << t;
    }
  }
  EXPECT_EQ(i, rec.count);
  // Text -> LAS: the same 0.01 grid found from the decimals, and the same coordinates on it.
  translate(txt, back);
  EXPECT_EQ(header_grid(back).first, Vec3(0.01));
  const PointCloud b = io::read_point_cloud(back);
  ASSERT_EQ(b.size(), rec.count);
  for (std::uint64_t j = 0; j < rec.count; ++j)
    for (int k = 0; k < 3; ++k) {
      std::int32_t q = 0;
      std::memcpy(&q, rec.records.data() + j * rec.record_length + 4 * k, 4);
      ASSERT_EQ(std::llround((b.positions[j][k] - offset[k]) / scale[k]), q) << "record " << j;
    }

  const fs::path ply = small_float_scan(), xyz = temp_dir() / "small_object.xyz";
  translate(ply, xyz);
  EXPECT_EQ(io::read_point_cloud(xyz).positions, io::read_point_cloud(ply).positions);
}

namespace {

/// The header lines of the PLY or PCD file `path`, up to (without) the line starting with `last`
/// ("end_header", "DATA").
std::vector<std::string> header_lines(const fs::path& path, const std::string& last) {
  std::istringstream in(file_bytes(path));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line) && line.rfind(last, 0) != 0;) lines.push_back(line);
  return lines;
}

/// The number of chunks that the chunk table of the LAZ file `path` lists, from its own bytes:
/// the int64 at the point data offset (header byte 96) addresses the table, whose uint32 version
/// is followed by the uint32 chunk count (LASzip lasreadpoint.cpp read_chunk_table).
std::uint32_t laz_chunk_count(const fs::path& path) {
  const std::string b = file_bytes(path);
  std::uint32_t point_offset = 0, count = 0;
  std::int64_t table = 0;
  std::memcpy(&point_offset, b.data() + 96, 4);
  std::memcpy(&table, b.data() + point_offset, 8);
  std::memcpy(&count, b.data() + table + 4, 4);
  return count;
}

}  // namespace

// A LAS input's Extra Bytes descriptions travel with its fields: a PLY output describes each in a
// header comment ("comment field <property>: <description>"), a PCD output in a '#' comment line
// before VERSION ("# field <field>: <description>"; PCL and Open3D skip such lines), and a LAS
// rewritten on a new grid keeps them in its descriptors. extrabytes.las: Colors and Flags are
// deprecated arrays (types 23 and 12: three and two fields, each described as its array),
// Intensity is described as "Brightness" and written as Intensity_1 beside the LAS intensity.
// Oracle: the descriptors in the input's and the output's own bytes, and the written header.
TEST(TranslateJob, ExtraBytesDescriptionsTravelToPlyPcdAndARewrittenLas) {
  const fs::path las = data_file("las/extrabytes.las");
  std::map<std::string, std::string> described;  // field as read -> description, from the input's bytes
  for (const test::ExtraBytesDescriptor& d : test::extra_bytes_descriptors_of(las)) {
    if (d.type == 0) continue;  // undocumented bytes: no field
    const int n = d.type <= 10 ? 1 : d.type <= 20 ? 2 : 3;
    for (int j = 0; j < n; ++j) described[n == 1 ? d.name : d.name + "[" + std::to_string(j) + "]"] = d.description;
  }
  ASSERT_EQ(described.size(), 7u);
  ASSERT_EQ(described.at("Intensity"), "Brightness");
  // Each field's name in the PLY and PCD headers (characters other than [A-Za-z0-9_] as '_', a
  // suffix where the reader would take the name for another field).
  const std::map<std::string, std::string> written = {
      {"Colors[0]", "Colors_0_"}, {"Colors[1]", "Colors_1_"}, {"Colors[2]", "Colors_2_"}, {"Flags[0]", "Flags_0_"},
      {"Flags[1]", "Flags_1_"},   {"Intensity", "Intensity_1"}, {"Time", "Time"}};
  const auto count_prefixed = [](const std::vector<std::string>& lines, const std::string& prefix) {
    return std::count_if(lines.begin(), lines.end(), [&](const std::string& l) { return l.rfind(prefix, 0) == 0; });
  };
  jobs::TranslateJobOptions o;
  o.in = las;

  o.out = temp_dir() / "described.ply";
  jobs::run_translate(o);
  const std::vector<std::string> ply = header_lines(o.out, "end_header");
  const auto ply_at = [&](const std::string& l) { return std::find(ply.begin(), ply.end(), l) - ply.begin(); };
  const std::ptrdiff_t element = ply_at("element vertex 1065");
  ASSERT_LT(element, static_cast<std::ptrdiff_t>(ply.size()));
  for (const auto& [field, description] : described) {
    SCOPED_TRACE(field);
    const std::string name = "scalar_" + written.at(field);
    EXPECT_LT(ply_at("comment field " + name + ": " + description), element);
    EXPECT_LT(ply_at("property double " + name), static_cast<std::ptrdiff_t>(ply.size()));
  }
  EXPECT_EQ(count_prefixed(ply, "comment field "), 7);

  o.out = temp_dir() / "described.pcd";
  jobs::run_translate(o);
  const std::vector<std::string> pcd = header_lines(o.out, "DATA");
  const auto pcd_at = [&](const std::string& l) { return std::find(pcd.begin(), pcd.end(), l) - pcd.begin(); };
  const std::ptrdiff_t version = pcd_at("VERSION 0.7");
  ASSERT_LT(version, static_cast<std::ptrdiff_t>(pcd.size()));
  const auto fields =
      std::find_if(pcd.begin(), pcd.end(), [](const std::string& l) { return l.rfind("FIELDS ", 0) == 0; });
  ASSERT_NE(fields, pcd.end());
  for (const auto& [field, description] : described) {
    SCOPED_TRACE(field);
    EXPECT_LT(pcd_at("# field " + written.at(field) + ": " + description), version);
    EXPECT_NE((*fields + " ").find(" " + written.at(field) + " "), std::string::npos) << *fields;
  }
  EXPECT_EQ(count_prefixed(pcd, "# field "), 7);

  o.out = temp_dir() / "described.las";
  o.scale = {0.001};
  jobs::run_translate(o);
  std::map<std::string, std::string> kept;
  for (const test::ExtraBytesDescriptor& d : test::extra_bytes_descriptors_of(o.out)) kept[d.name] = d.description;
  EXPECT_EQ(kept, described);
}

// --chunk-size sizes the chunks of every LAZ output, from any input and on any grid (a PLY's
// cloud too, which the LAS writer compressed in chunks of 50000 whatever was asked), and is
// refused for every other output, before anything is read, in one line naming the option and the
// output it does not apply to; without it every output is written. Oracle: the chunk table in
// the written file's own bytes.
TEST(TranslateJob, ChunkSizeSizesEveryLazOutputAndIsRefusedForOthers) {
  const fs::path dir = temp_dir() / "chunk_size";
  fs::create_directories(dir);
  const fs::path ply = small_float_scan(), las = data_file("las/point-color.las");
  for (const fs::path& in : {ply, las})
    for (const bool new_grid : {false, true}) {
      SCOPED_TRACE(in.string() + (new_grid ? " on a new grid" : ""));
      jobs::TranslateJobOptions o;
      o.in = in;
      o.out = dir / "a.laz";
      o.chunk_size = 7;
      if (new_grid) o.scale = {0.001};
      const jobs::TranslateJobResult r = jobs::run_translate(o);
      const std::uint64_t want = (io::read_point_cloud(in).size() + 6) / 7;
      EXPECT_EQ(laz_chunk_count(o.out), want);
      EXPECT_EQ(r.chunks, want);
      EXPECT_EQ(io::read_point_cloud(o.out).size(), io::read_point_cloud(in).size());
    }
  auto r =
      test::rayscan_cli("translate -q " + test::quoted(ply) + " " + test::quoted(dir / "b.laz") + " --chunk-size 100");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(laz_chunk_count(dir / "b.laz"), 30u);  // 3000 points
  for (const char* name : {"c.las", "c.ply", "c.pcd", "c.xyz", "c.csv", "c.copc.laz"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / name;
    r = test::rayscan_cli("translate -q " + test::quoted(las) + " " + test::quoted(out) + " --chunk-size 10");
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.out, "rayscan translate: --chunk-size applies to LAZ output, not to " + out.string() +
                         (std::string(name) == "c.copc.laz" ? " (COPC writes one chunk per octree node)" : "") + "\n");
    EXPECT_FALSE(fs::exists(out));
    r = test::rayscan_cli("translate -q " + test::quoted(las) + " " + test::quoted(out));
    EXPECT_EQ(r.code, 0) << r.out;
  }
}

// LAS <-> LAZ copies every VLR as it is, a WKT VLR that GDAL cannot read too (as PDAL and laszip
// keep a file's records): the copy writes no CRS of its own, so the output holds the input's CRS
// records and no other, and LAZ -> LAS gives the input back byte for byte. It warns once, naming
// the input and quoting the text, also with -q; a readable WKT gets no warning. Crafted from
// file_with_both_wkt_and_geotiff_vlrs.las (WKT and GeoKeys): its WKT made unreadable
// ("XROJCS[...") or no WKT at all ("unknown"). Oracle: the files' own bytes (the CRS records
// counted in the VLR headers), and GDAL's reading of each text.
TEST(TranslateJob, AnUnreadableWktVlrIsCopiedAloneAndWarnedOnce) {
  const fs::path src = data_file("las/file_with_both_wkt_and_geotiff_vlrs.las"), dir = temp_dir() / "bad_wkt";
  fs::create_directories(dir);
  const std::string good = file_bytes(src);
  /// The payload offset and length of each VLR "LASF_Projection" record `id` of the LAS bytes `b`.
  const auto crs_vlrs = [](const std::string& b, std::uint16_t id) {
    std::vector<std::pair<std::size_t, std::size_t>> found;
    for (const test::LasVlr& v : test::las_vlrs(b))
      if (v.user_id == "LASF_Projection" && v.record == id) found.emplace_back(v.payload, v.length);
    return found;
  };
  const auto wkt = crs_vlrs(good, 2112);
  ASSERT_EQ(wkt.size(), 1u);
  ASSERT_EQ(good.compare(wkt[0].first, 7, "PROJCS["), 0);
  ASSERT_TRUE(io::crs_wkt_readable(good.substr(wkt[0].first, wkt[0].second).c_str()));

  jobs::TranslateJobOptions o;
  o.in = src;
  o.out = dir / "good.laz";
  EXPECT_TRUE(jobs::run_translate(o).warnings.empty());

  for (const std::string& text : {std::string("X"), std::string("unknown")}) {
    SCOPED_TRACE(text);
    std::string bad = good;
    if (text == "X") bad[wkt[0].first] = 'X';  // "XROJCS[...": WKT in form, not a CRS GDAL reads
    else bad.replace(wkt[0].first, wkt[0].second, text + std::string(wkt[0].second - text.size(), '\0'));
    const std::string payload = bad.substr(wkt[0].first, wkt[0].second);
    const std::string shown = payload.c_str();  // the text without its NUL padding
    ASSERT_FALSE(io::crs_wkt_readable(shown));
    const fs::path in = dir / "bad.las", laz = dir / "bad.laz", back = dir / "bad_back.las";
    std::ofstream(in, std::ios::binary) << bad;

    o.in = in;
    o.out = laz;
    const jobs::TranslateJobResult r = jobs::run_translate(o);
    const std::string warning = in.string() + ": the OGC WKT VLR holds no CRS that GDAL reads ('" +
                                (shown.size() > 40 ? shown.substr(0, 40) + "..." : shown) +
                                "'): copied unchanged with the other VLRs";
    EXPECT_EQ(r.warnings, std::vector<std::string>{warning});
    const std::string z = file_bytes(laz);
    for (const std::uint16_t id : {2112, 34735, 34736, 34737}) {
      SCOPED_TRACE(id);
      const auto ours = crs_vlrs(z, id), theirs = crs_vlrs(bad, id);
      ASSERT_EQ(ours.size(), theirs.size());
      for (std::size_t k = 0; k < ours.size(); ++k)
        EXPECT_EQ(z.substr(ours[k].first, ours[k].second), bad.substr(theirs[k].first, theirs[k].second));
    }
    o.in = laz;
    o.out = back;
    EXPECT_EQ(jobs::run_translate(o).warnings.size(), 1u);
    EXPECT_EQ(file_bytes(back), bad);

    const auto cli = test::rayscan_cli("translate -q " + test::quoted(in) + " " + test::quoted(dir / "cli.laz"));
    EXPECT_EQ(cli.code, 0) << cli.out;
    const std::string line = "rayscan translate: warning: " + warning + "\n";
    EXPECT_NE(cli.out.find(line), std::string::npos) << cli.out;
    EXPECT_EQ(cli.out.find("warning"), cli.out.rfind("warning")) << cli.out;  // once
  }
}

// A WKT VLR that looks like WKT but GDAL cannot read ("XROJCS[...") gives way to the file's
// GeoKeys when GDAL reads them: PLY and PCD are written, the PLY with the GeoKeys' CRS, and one
// warning names the input; with no GeoKeys (their directory's record id changed) the points
// are written without a CRS, with a warning, rather than refused naming the output. Oracle: OGR's
// EPSG:32104 in US survey foot (the file's GeoKeys, its README), and each output's own bytes.
TEST(TranslateJob, AnUnreadableWktVlrGivesWayToGeoKeysOrToNoCrs) {
  const fs::path dir = temp_dir() / "bad_wkt_crs";
  fs::create_directories(dir);
  const std::string bad = test::las_with_unreadable_wkt(true), neither = test::las_with_unreadable_wkt(false);
  const fs::path with_keys = dir / "keys.las", without = dir / "none.las";
  std::ofstream(with_keys, std::ios::binary) << bad;
  std::ofstream(without, std::ios::binary) << neither;

  OGRSpatialReference expect;
  ASSERT_EQ(expect.SetFromUserInput("EPSG:32104"), OGRERR_NONE);
  expect.SetLinearUnitsAndUpdateParameters(SRS_UL_US_FOOT, CPLAtof(SRS_UL_US_FOOT_CONV));
  for (const char* ext : {".ply", ".pcd"}) {
    SCOPED_TRACE(ext);
    jobs::TranslateJobOptions o;
    o.in = with_keys;
    o.out = dir / (std::string("keys") + ext);
    jobs::TranslateJobResult r = jobs::run_translate(o);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_EQ(r.warnings[0].rfind(with_keys.string() + ": the OGC WKT VLR holds no CRS that GDAL reads ('XROJCS[", 0), 0u)
        << r.warnings[0];
    EXPECT_NE(r.warnings[0].find("the CRS is taken from its GeoKeys"), std::string::npos) << r.warnings[0];
    if (std::string(ext) == ".ply") {
      const PointCloud back = io::read_point_cloud(o.out);
      OGRSpatialReference got;
      ASSERT_EQ(got.importFromWkt(back.crs_wkt.c_str()), OGRERR_NONE) << back.crs_wkt;
      const char* unit = nullptr;
      EXPECT_DOUBLE_EQ(got.GetLinearUnits(&unit), expect.GetLinearUnits());
      EXPECT_NEAR(got.GetProjParm(SRS_PP_FALSE_EASTING), expect.GetProjParm(SRS_PP_FALSE_EASTING), 1e-6);
      EXPECT_NEAR(got.GetProjParm(SRS_PP_STANDARD_PARALLEL_1), expect.GetProjParm(SRS_PP_STANDARD_PARALLEL_1), 1e-9);
    }
    o.in = without;
    o.out = dir / (std::string("none") + ext);
    r = jobs::run_translate(o);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_EQ(r.warnings[0], without.string() + ": the CRS is WKT that GDAL cannot read ('XROJCS[\"NAD83_2011_Nebraska_ft\",GEOGCS[\"...'): " +
                                 o.out.string() + " is written without a CRS");
    EXPECT_TRUE(io::read_point_cloud(o.out).crs_wkt.empty());
    EXPECT_EQ(file_bytes(o.out).find("crs"), std::string::npos);
  }
}

// COPC output of a LAS whose WKT VLR GDAL cannot read but whose GeoKeys it reads stores the
// GeoKeys' CRS as its WKT and says so once, naming the input, as the point formats do: without a
// grid (the records copied, the CRS taken by the COPC reader of the input), with one (--scale,
// through the points read whole), and from `translate` and `index` on the command line, also with
// -q. Oracle: OGR's EPSG:32104 in US survey foot (the file's GeoKeys, its README) against the
// CRS read back from each COPC file.
TEST(TranslateJob, CopcOfAnUnreadableWktVlrWarnsOnceThatItsCrsIsTheGeoKeys) {
  const fs::path dir = temp_dir() / "bad_wkt_copc";
  fs::create_directories(dir);
  const fs::path keys = dir / "keys.las";
  std::ofstream(keys, std::ios::binary) << test::las_with_unreadable_wkt(true);
  OGRSpatialReference expect;
  ASSERT_EQ(expect.SetFromUserInput("EPSG:32104"), OGRERR_NONE);
  expect.SetLinearUnitsAndUpdateParameters(SRS_UL_US_FOOT, CPLAtof(SRS_UL_US_FOOT_CONV));
  const auto expect_crs = [&](const fs::path& copc) {
    const PointCloud back = io::read_point_cloud(copc);
    OGRSpatialReference got;
    ASSERT_EQ(got.importFromWkt(back.crs_wkt.c_str()), OGRERR_NONE) << back.crs_wkt;
    const char* unit = nullptr;
    EXPECT_DOUBLE_EQ(got.GetLinearUnits(&unit), expect.GetLinearUnits());
    EXPECT_NEAR(got.GetProjParm(SRS_PP_FALSE_EASTING), expect.GetProjParm(SRS_PP_FALSE_EASTING), 1e-6);
    EXPECT_NEAR(got.GetProjParm(SRS_PP_STANDARD_PARALLEL_1), expect.GetProjParm(SRS_PP_STANDARD_PARALLEL_1), 1e-9);
  };
  const std::string prefix = keys.string() + ": the OGC WKT VLR holds no CRS that GDAL reads ('XROJCS[";
  const std::string suffix = "'): the CRS is taken from its GeoKeys";
  for (const bool grid : {false, true}) {
    SCOPED_TRACE(grid ? "with --scale" : "without a grid");
    jobs::TranslateJobOptions o;
    o.in = keys;
    o.out = dir / (grid ? "grid.copc.laz" : "keys.copc.laz");
    if (grid) o.scale = {0.001};
    const jobs::TranslateJobResult r = jobs::run_translate(o);
    ASSERT_TRUE(r.copc);
    ASSERT_EQ(r.warnings.size(), 1u);
    EXPECT_EQ(r.warnings[0].rfind(prefix, 0), 0u) << r.warnings[0];
    EXPECT_EQ(r.warnings[0].substr(r.warnings[0].size() - suffix.size()), suffix) << r.warnings[0];
    expect_crs(o.out);
  }
  for (const std::string& command : {"translate -q " + test::quoted(keys) + " " + test::quoted(dir / "cli.copc.laz"),
                                    "index -q " + test::quoted(keys) + " -o " + test::quoted(dir / "index.copc.laz")}) {
    SCOPED_TRACE(command);
    const auto cli = test::rayscan_cli(command);
    ASSERT_EQ(cli.code, 0) << cli.out;
    const std::string name = command.substr(0, command.find(' '));
    const std::size_t at = cli.out.find("rayscan " + name + ": warning: " + prefix);
    EXPECT_NE(at, std::string::npos) << cli.out;
    EXPECT_EQ(cli.out.find("warning"), cli.out.rfind("warning")) << cli.out;  // once
  }
  expect_crs(dir / "index.copc.laz");
}

// COPC output with a grid of its own refuses a LAS WKT VLR GDAL cannot read (no GeoKeys beside
// it) from the file's header, before the points are read: the crafted file's first record holds
// an X beyond the coordinate bound (X scale 1, patch_las_x_scale; X = 2^31 - 1), which reading the points refuses,
// so the CRS refusal can only come first if no point was read. Oracle: the header fields of ASPRS
// LAS 1.4 R15 table 3 (offset to point data at byte 96).
TEST(TranslateJob, CopcWithAGridRefusesAnUnreadableCrsBeforeReadingThePoints) {
  const fs::path dir = temp_dir() / "bad_wkt_copc_grid";
  fs::create_directories(dir);
  std::string b = test::las_with_unreadable_wkt(false);
  const std::int32_t far = 2147483647;
  std::uint32_t point_offset = 0;
  std::memcpy(&point_offset, b.data() + 96, 4);
  std::memcpy(b.data() + point_offset, &far, 4);
  const fs::path in = dir / "far.las";
  std::ofstream(in, std::ios::binary) << b;
  test::patch_las_x_scale(in, 1.0);
  // The crafted record is refused when the points are read (the file is otherwise readable).
  EXPECT_NE(test::reader_error(in), "");
  jobs::TranslateJobOptions o;
  o.in = in;
  o.out = dir / "far.copc.laz";
  o.scale = {0.001};
  try {
    (void)jobs::run_translate(o);
    ADD_FAILURE() << "expected a refusal";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), in.string() + ": the CRS is WKT that GDAL cannot read ('XROJCS[\"NAD83_2011_Nebraska_ft\",GEOGCS[\"...'); "
                                                   "expected a CRS GDAL reads, or none");
  }
  EXPECT_FALSE(fs::exists(o.out));
}
