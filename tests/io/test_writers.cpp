// write_las / write_ply round trips: what is written reads back equal (LAS coordinates bit-exact
// when written with the source's scale and offset, otherwise within half a scale unit).
#include "../common/crs_wkt.hpp"
#include "io_test_util.hpp"

#include "rayscan/io/las_records.hpp"

#include <cpl_error.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <utility>
#include <vector>

namespace rayscan::test {
namespace {

TEST(Writers, LasRoundTripOfAutzenIsBitExactWithTheSourceScaleAndOffset) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  io::FileInfo info;
  PointCloud src = io::read_point_cloud(p, {}, &info);
  src.scalars.push_back({"visibility count", std::vector<double>(src.size())});
  for (std::size_t i = 0; i < src.size(); ++i) src.scalars.back().values[i] = static_cast<double>(i % 97) + 0.25;
  io::LasWriteOptions opt;
  opt.scale = *info.scale;
  opt.offset = *info.offset;
  opt.has_offset = true;
  const fs::path out = temp_dir() / "autzen_rt.las";
  io::write_las(out, src, opt);
  io::FileInfo back_info;
  const PointCloud back = io::read_point_cloud(out, {}, &back_info);
  EXPECT_EQ(back_info.version, "1.4");
  EXPECT_EQ(back_info.point_format, 7);
  ASSERT_EQ(back.size(), src.size());
  EXPECT_EQ(back.positions, src.positions);
  EXPECT_EQ(back.rgb, src.rgb);
  EXPECT_EQ(back.intensity, src.intensity);
  EXPECT_EQ(back.classification, src.classification);
  EXPECT_EQ(back.gps_time, src.gps_time);
  for (const char* s : {"return_number", "number_of_returns", "user_data", "point_source_id"})
    EXPECT_EQ(back.scalar(s)->values, src.scalar(s)->values) << s;
  // LAS 1.2 stores whole degrees, PDRF 6-10 units of 0.006 degrees: within half a unit.
  const auto& a0 = back.scalar("scan_angle")->values;
  const auto& a1 = src.scalar("scan_angle")->values;
  for (std::size_t i = 0; i < a0.size(); ++i) ASSERT_NEAR(a0[i], a1[i], 0.003 + 1e-12) << i;
  ASSERT_NE(back.scalar("visibility count"), nullptr);  // through the Extra Bytes VLR
  EXPECT_EQ(back.scalar("visibility count")->values, src.scalar("visibility count")->values);
  EXPECT_EQ(back.crs_wkt, src.crs_wkt);
  EXPECT_EQ(back_info.crs_source, "WKT VLR");
  for (const auto& de : fs::directory_iterator(out.parent_path()))  // no temporary left behind
    EXPECT_EQ(de.path().filename().string().find(".tmp."), std::string::npos) << de.path();
  fs::remove(out);
}

TEST(Writers, LazPathWritesTheSameRecordsCompressed) {
  // write_las to a .laz path: the records of the .las written from the same cloud, through the
  // layered LAZ encoder (PDRF 7 here, plus one float64 extra byte field), no temporary left.
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  PointCloud src = io::read_point_cloud(p);
  src.scalars.push_back({"score", std::vector<double>(src.size())});
  for (std::size_t i = 0; i < src.size(); ++i) src.scalars.back().values[i] = static_cast<double>(i % 13) * 0.5;
  const fs::path dir = temp_dir() / "lazw";
  fs::create_directories(dir);
  io::write_las(dir / "a.las", src);
  io::write_las(dir / "a.LAZ", src);
  const io::LasRecords las = io::read_las_records(dir / "a.las"), laz = io::read_las_records(dir / "a.LAZ");
  EXPECT_FALSE(las.compressed);
  EXPECT_TRUE(laz.compressed);
  EXPECT_EQ(laz.pdrf, 7);
  EXPECT_TRUE(laz.records == las.records);
  EXPECT_LT(fs::file_size(dir / "a.LAZ"), fs::file_size(dir / "a.las") / 3);
  for (const auto& de : fs::directory_iterator(dir))
    EXPECT_EQ(de.path().filename().string().find(".tmp."), std::string::npos) << de.path();
  fs::remove_all(dir);
}

TEST(Writers, LasAutomaticScaleKeepsCoordinatesWithinHalfAUnit) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1000.0);
  PointCloud pc;
  for (int i = 0; i < 5000; ++i) pc.positions.emplace_back(4.9e6 + u(rng), 5.1e5 + u(rng), u(rng) - 500);
  const fs::path out = temp_dir() / "auto.las";
  io::write_las(out, pc);
  io::FileInfo info;
  const PointCloud back = io::read_point_cloud(out, {}, &info);
  ASSERT_EQ(back.size(), pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_LE(std::abs(back.positions[i][k] - pc.positions[i][k]), 0.5 * (*info.scale)[k] + 1e-9);
  EXPECT_EQ(info.point_format, 6);
  // Header bounds written from the quantised points: they agree with the recomputed box.
  EXPECT_EQ(info.header_bounds->lo, back.bounds().lo);
  EXPECT_EQ(info.header_bounds->hi, back.bounds().hi);
  fs::remove(out);
}

TEST(Writers, PlyRoundTripKeepsDoublesNormalsScalarsAndEightBitColour) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  PointCloud src = io::read_point_cloud(p);
  src.normals.assign(src.size(), glm::vec3(0.f, 0.6f, 0.8f));
  const fs::path out = temp_dir() / "autzen_rt.ply";
  io::write_ply(out, src);
  const PointCloud back = io::read_point_cloud(out);
  ASSERT_EQ(back.size(), src.size());
  EXPECT_EQ(back.positions, src.positions);  // double properties: exact
  EXPECT_EQ(back.rgb, src.rgb);              // 8-bit source colour survives the uchar round trip
  EXPECT_EQ(back.normals, src.normals);
  EXPECT_EQ(back.intensity, src.intensity);
  EXPECT_EQ(back.classification, src.classification);
  EXPECT_EQ(back.gps_time, src.gps_time);
  ASSERT_FALSE(src.crs_wkt.empty());
  EXPECT_EQ(back.crs_wkt, src.crs_wkt);  // carried as "comment crs <WKT>"
  for (const ScalarField& f : src.scalars) {
    ASSERT_NE(back.scalar(f.name), nullptr) << f.name;
    EXPECT_EQ(back.scalar(f.name)->values, f.values) << f.name;
  }
  fs::remove(out);
}

/// The values of attribute `name` of `pc`: its dedicated field (intensity, classification,
/// gps_time) or else the ScalarField of that name; empty when it has neither.
std::vector<double> values_of(const PointCloud& pc, const std::string& name) {
  if (name == "intensity" && !pc.intensity.empty()) return {pc.intensity.begin(), pc.intensity.end()};
  if (name == "classification" && !pc.classification.empty()) return {pc.classification.begin(), pc.classification.end()};
  if (name == "gps_time" && !pc.gps_time.empty()) return pc.gps_time;
  if (const ScalarField* f = pc.scalar(name)) return f->values;
  return {};
}

// PCD and text (.xyz, .csv) written by write_point_cloud read back with the same coordinates bit
// for bit, the colour (8-bit source: exact through PCD's packed rgb, 16-bit values in text) and
// every attribute under its name (PCD and text keep classification and GPS time as named fields).
TEST(Writers, PcdAndTextRoundTripKeepCoordinatesBitForBitAndEveryAttribute) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const PointCloud src = io::read_point_cloud(p);
  for (const char* ext : {".pcd", ".xyz", ".csv", ".txt"}) {
    const fs::path out = temp_dir() / (std::string("autzen_rt") + ext);
    io::write_point_cloud(out, src);
    io::FileInfo info;
    const PointCloud back = io::read_point_cloud(out, {}, &info);
    EXPECT_EQ(info.format, std::string(ext) == ".pcd" ? "PCD" : "text") << ext;
    ASSERT_EQ(back.size(), src.size()) << ext;
    EXPECT_EQ(back.positions, src.positions) << ext;
    EXPECT_EQ(back.rgb, src.rgb) << ext;
    std::vector<std::string> names = {"intensity", "classification", "gps_time"};
    for (const ScalarField& f : src.scalars) names.push_back(f.name);
    for (const std::string& n : names) {
      const std::vector<double> want = values_of(src, n);
      ASSERT_FALSE(want.empty()) << n;
      EXPECT_EQ(values_of(back, n), want) << ext << " " << n;
    }
    fs::remove(out);
  }
}

/// The header lines of a PLY file (up to end_header) or a PCD file (up to DATA), from its bytes.
std::vector<std::string> header_lines(const fs::path& p, const std::string& last) {
  std::ifstream in(p, std::ios::binary);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) {
    lines.push_back(l);
    if (l.rfind(last, 0) == 0) break;
  }
  return lines;
}

// The descriptions a LAS output puts in its Extra Bytes descriptors (LasWriteOptions::extra_bytes)
// reach PLY and PCD as header comments naming each field as the file names it; a field without a
// description gets none; text keeps its one header line of column names. Oracle: the files' own
// header lines; the readers still read every value and keep the comments.
TEST(Writers, PlyAndPcdDescribeFieldsInHeaderComments) {
  PointCloud src;
  src.positions = {Vec3(1.5, 2.0, 3.0), Vec3(-4.0, 5.25, 6.0)};
  src.scalars = {{"solar_global", {12.5, 0.0}}, {"visible distance", {7.0, -1.0}}, {"plain", {1.0, 2.0}}};
  io::LasWriteOptions opt;
  opt.extra_bytes["solar_global"] = {"global irradiation, kWh/m2", {}};
  opt.extra_bytes["visible distance"] = {"distance to\nnearest observer", -1.0};
  const fs::path ply = temp_dir() / "described.ply", pcd = temp_dir() / "described.pcd",
                 csv = temp_dir() / "described.csv";
  io::write_point_cloud(ply, src, opt);
  io::write_point_cloud(pcd, src, opt);
  io::write_point_cloud(csv, src, opt);

  const std::vector<std::string> ph = header_lines(ply, "end_header");
  const auto has = [](const std::vector<std::string>& h, const std::string& l) {
    return std::find(h.begin(), h.end(), l) != h.end();
  };
  EXPECT_TRUE(has(ph, "comment field scalar_solar_global: global irradiation, kWh/m2"));
  EXPECT_TRUE(has(ph, "comment field scalar_visible_distance: distance to nearest observer; no data -1"));
  EXPECT_TRUE(has(ph, "property double scalar_visible_distance"));
  const auto comments = [](const std::vector<std::string>& h, const std::string& start) {
    return std::count_if(h.begin(), h.end(), [&](const std::string& l) { return l.rfind(start, 0) == 0; });
  };
  EXPECT_EQ(comments(ph, "comment field "), 2);  // none for "plain"
  // PLY comments belong before the element they describe (PLY 1.0 header order).
  const auto at = [&](const std::string& l) { return std::find(ph.begin(), ph.end(), l) - ph.begin(); };
  EXPECT_LT(at("comment field scalar_solar_global: global irradiation, kWh/m2"), at("element vertex 2"));

  const std::vector<std::string> dh = header_lines(pcd, "DATA");
  ASSERT_GE(dh.size(), 4u);
  EXPECT_EQ(dh[0], "# .PCD v0.7 - Point Cloud Data file format");
  EXPECT_EQ(dh[1], "# field solar_global: global irradiation, kWh/m2");
  EXPECT_EQ(dh[2], "# field visible_distance: distance to nearest observer; no data -1");
  EXPECT_EQ(dh[3], "VERSION 0.7");
  EXPECT_EQ(comments(dh, "# field "), 2);

  for (const fs::path& p : {ply, pcd}) {
    io::FileInfo info;
    const PointCloud back = io::read_point_cloud(p, {}, &info);
    EXPECT_EQ(back.positions, src.positions) << p;
    for (const ScalarField& f : src.scalars) {
      const std::string name = f.name == "visible distance" ? "visible_distance" : f.name;  // as written
      ASSERT_NE(back.scalar(name), nullptr) << p << " " << name;
      EXPECT_EQ(back.scalar(name)->values, f.values) << p << " " << name;
    }
    const std::string want = p == ply ? "comment field scalar_solar_global: global irradiation, kWh/m2"
                                      : "# field solar_global: global irradiation, kWh/m2";
    EXPECT_TRUE(has(info.comments, want)) << p;  // the whole line, as `rayscan info` prints it
  }

  // Text: the column header alone (PDAL's readers.text and QGIS take the first line as names).
  std::ifstream t(csv);
  std::string first;
  std::getline(t, first);
  EXPECT_EQ(first, "x,y,z,solar_global,visible_distance,plain");
  for (const fs::path& p : {ply, pcd, csv}) fs::remove(p);
}

// Normals written by the text writer (columns nx ny nz) read back as normals, bit for bit (the
// float values as the writer printed them); one or two normal-like columns alone stay scalars.
// Oracle: the normals put into the cloud.
TEST(Writers, TextNormalsReadBackAsNormals) {
  PointCloud src;
  src.positions = {Vec3(1, 2, 3), Vec3(4, 5, 6), Vec3(-7, 8.5, 0.25)};
  src.normals = {glm::vec3(0, 0, 1), glm::vec3(0.6f, -0.8f, 0), glm::vec3(0.267261f, 0.534522f, 0.801784f)};
  for (const char* ext : {".xyz", ".csv", ".txt"}) {
    const fs::path out = temp_dir() / (std::string("normals_rt") + ext);
    io::write_point_cloud(out, src);
    const PointCloud back = io::read_point_cloud(out);
    EXPECT_EQ(back.positions, src.positions) << ext;
    EXPECT_EQ(back.normals, src.normals) << ext;
    EXPECT_TRUE(back.scalars.empty()) << ext;
    fs::remove(out);
  }
  const fs::path two = temp_dir() / "two_normal_columns.csv";
  std::ofstream(two) << "x,y,z,NormalX,ny\n1,2,3,0.5,0.25\n";
  const PointCloud b2 = io::read_point_cloud(two);
  EXPECT_TRUE(b2.normals.empty());
  ASSERT_NE(b2.scalar("NormalX"), nullptr);
  EXPECT_EQ(b2.scalar("NormalX")->values, std::vector<double>{0.5});
  fs::remove(two);
}

// A scalar whose name the text reader takes for a column of its own (an Extra Bytes field
// "Intensity" beside LAS intensity; "X"; "red") or moves into a dedicated field ("gpstime",
// "Classification" with integral values) is written under a suffix, so the file reads back with
// every field as it was. Oracle: the values put into the cloud, and the header line written.
TEST(Writers, TextScalarsNamedLikeTheReadersColumnsReadBackUnderASuffix) {
  PointCloud src;
  src.positions = {Vec3(1, 2, 3), Vec3(4, 5, 6)};
  src.intensity = {10, 20};
  src.scalars = {{"Intensity", {0.5, 7}}, {"X", {1, 2}},       {"red", {3, 4}},
                 {"gpstime", {5, 6}},     {"Classification", {1, 2}}, {"other", {9, 8}}};
  const fs::path out = temp_dir() / "reserved_names.csv";
  io::write_point_cloud(out, src);
  const std::vector<std::uint8_t> bytes = slurp(out);
  const std::string text(bytes.begin(), bytes.end());
  EXPECT_EQ(text.substr(0, text.find('\n')), "x,y,z,intensity,Intensity_1,X_1,red_1,gpstime_1,Classification_1,other");
  const PointCloud back = io::read_point_cloud(out);
  EXPECT_EQ(back.positions, src.positions);
  EXPECT_EQ(back.intensity, src.intensity);
  EXPECT_TRUE(back.rgb.empty());
  EXPECT_TRUE(back.classification.empty());
  EXPECT_TRUE(back.gps_time.empty());
  ASSERT_EQ(back.scalars.size(), src.scalars.size());
  for (std::size_t k = 0; k < src.scalars.size(); ++k) {
    const std::string want = src.scalars[k].name == "other" ? "other" : src.scalars[k].name + "_1";
    EXPECT_EQ(back.scalars[k].name, want);
    EXPECT_EQ(back.scalars[k].values, src.scalars[k].values) << want;
  }
  fs::remove(out);
}

// PCD as text does: a scalar whose name the PCD reader takes for a position, normal or colour
// ("nx", "normal_y", "red", "B", "rgb", "x"), for PCL's padding ("_") or for a dedicated field
// ("intensity") is written under a suffix, so the file reads back with no scalar turned into
// normals, colour or intensity; text gives nx, ny, nz (which it would read as normals) a suffix
// too. Oracle: the file's own bytes (PCD's FIELDS line and its binary records of doubles; the text
// header and rows) and the values put into the cloud.
TEST(Writers, PcdAndTextScalarsNamedLikeAnAttributeReadBackUnderASuffix) {
  PointCloud src;
  src.positions = {Vec3(0.1, 2, 3), Vec3(4, 5.3, 6)};  // not floats: PCD writes them as F 8
  src.scalars = {{"nx", {0.5, -0.5}}, {"ny", {1, 2}},    {"nz", {3, 4}},     {"normal_y", {0.25, 7}},
                 {"red", {200, 3}},   {"B", {9, 10}},    {"rgb", {1e6, 2}},  {"x", {11, 12}},
                 {"_", {13, 14}},     {"intensity", {15, 16}}, {"other", {17, 18}}};
  const std::vector<std::string> pcd_names = {"nx_1",    "ny_1", "nz_1", "normal_y_1", "red_1", "B_1",
                                              "rgb_1",   "x_1",  "__1",  "intensity_1", "other"};
  const std::vector<std::string> text_names = {"nx_1", "ny_1", "nz_1", "normal_y", "red_1", "B_1",
                                               "rgb",  "x_1",  "_",    "intensity_1", "other"};
  auto check_back = [&](const fs::path& p, const std::vector<std::string>& names) {
    const PointCloud back = io::read_point_cloud(p);
    EXPECT_EQ(back.positions, src.positions) << p;
    EXPECT_TRUE(back.normals.empty()) << p;
    EXPECT_TRUE(back.rgb.empty()) << p;
    EXPECT_TRUE(back.intensity.empty()) << p;
    ASSERT_EQ(back.scalars.size(), src.scalars.size()) << p;
    for (std::size_t k = 0; k < src.scalars.size(); ++k) {
      EXPECT_EQ(back.scalars[k].name, names[k]) << p;
      EXPECT_EQ(back.scalars[k].values, src.scalars[k].values) << p << " " << names[k];
    }
  };

  const fs::path pcd = temp_dir() / "reserved_names.pcd";
  io::write_point_cloud(pcd, src);
  const std::vector<std::uint8_t> bytes = slurp(pcd);
  const std::string text(bytes.begin(), bytes.end());
  std::string fields = "FIELDS x y z";
  for (const std::string& n : pcd_names) fields += " " + n;
  EXPECT_NE(text.find("\n" + fields + "\n"), std::string::npos) << text.substr(0, 300);
  const std::size_t body = text.find("DATA binary\n") + 12;
  const std::size_t record = 8 * (3 + src.scalars.size());
  ASSERT_EQ(bytes.size(), body + 2 * record);
  for (std::size_t i = 0; i < 2; ++i)
    for (std::size_t k = 0; k < src.scalars.size(); ++k)
      EXPECT_EQ(load_at<double>(bytes, body + i * record + 8 * (3 + k)), src.scalars[k].values[i]) << pcd_names[k];
  check_back(pcd, pcd_names);
  fs::remove(pcd);

  // Text keeps "normal_y", "rgb" and "_", which are no text column names.
  for (const char* ext : {".csv", ".xyz"}) {
    const fs::path out = temp_dir() / (std::string("reserved_names") + ext);
    io::write_point_cloud(out, src);
    const std::vector<std::uint8_t> t = slurp(out);
    const std::string sep = std::string(ext) == ".csv" ? "," : " ";
    std::string header = "x" + sep + "y" + sep + "z";
    for (const std::string& n : text_names) header += sep + n;
    EXPECT_EQ(std::string(t.begin(), t.end()).substr(0, header.size() + 1), header + "\n");
    check_back(out, text_names);
    fs::remove(out);
  }
}

/// The colour fields of every record, as stored (ASPRS LAS 1.4 R15 section 2.6: red, green, blue
/// at byte 20 of PDRF 2, 28 of PDRF 3 and 5, 30 of PDRF 7, 8 and 10).
std::vector<std::uint16_t> stored_rgb(const io::LasRecords& r) {
  const std::size_t at = r.pdrf == 2 ? 20 : (r.pdrf == 3 || r.pdrf == 5) ? 28 : 30;
  std::vector<std::uint16_t> v;
  for (std::uint64_t i = 0; i < r.count; ++i)
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint8_t* q = r.records.data() + i * r.record_length + at + 2 * k;
      v.push_back(static_cast<std::uint16_t>(q[0] | q[1] << 8));
    }
  return v;
}

// LAS -> PLY / PCD / text -> LAS: the last LAS holds the source's coordinates bit for bit (the
// writer finds the source's 0.01-unit grid instead of its 0.001 default), the source's own colour
// values (autzen_trim.las holds 8-bit values, max 236, in its 16-bit fields: PLY's uchar, PCD's
// packed rgb and the text columns carry them, and the LAS written from those stores them again,
// as PDAL does) and, through PLY, every standard attribute (the source is the oracle: its records'
// bytes, and the cloud read back by the same LAS reader).
TEST(Writers, LasThroughPlyPcdAndTextBackToLasIsBitExact) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  io::FileInfo src_info;
  const PointCloud src = io::read_point_cloud(p, {}, &src_info);
  const std::vector<std::uint16_t> own_rgb = stored_rgb(io::read_las_records(p));
  ASSERT_EQ(own_rgb.size(), 3 * src.size());
  ASSERT_EQ(*std::max_element(own_rgb.begin(), own_rgb.end()), 236);
  for (const char* ext : {".ply", ".pcd", ".xyz"}) {
    const fs::path mid = temp_dir() / (std::string("autzen_mid") + ext), las = temp_dir() / "autzen_back.las";
    io::write_point_cloud(mid, src);
    io::write_point_cloud(las, io::read_point_cloud(mid));
    io::FileInfo info;
    const PointCloud back = io::read_point_cloud(las, {}, &info);
    EXPECT_EQ(back.positions, src.positions) << ext;
    EXPECT_EQ(*info.scale, *src_info.scale) << ext;
    EXPECT_EQ(back.rgb, src.rgb) << ext;
    EXPECT_TRUE(stored_rgb(io::read_las_records(las)) == own_rgb) << ext;
    if (std::string(ext) == ".ply") {
      EXPECT_EQ(back.intensity, src.intensity);
      EXPECT_EQ(back.classification, src.classification);
      EXPECT_EQ(back.gps_time, src.gps_time);
      EXPECT_EQ(back.crs_wkt, src.crs_wkt);
    }
    fs::remove(mid);
    fs::remove(las);
  }
}

// Coordinates given as decimal text (a cloud that came from LAS through write_text) that the
// reader's arithmetic X * scale + offset does not give bit for bit: the writer still finds their
// grid (x 2 decimals, y 3, z 1) and stores the decimals' own integers, where an exact-only search
// falls back to 0.001 for x and z. Oracle: the integers the decimals were made from.
TEST(Writers, LasFindsTheGridOfDecimalTextThatTheReadersArithmeticMisses) {
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<std::int64_t> qx(0, 99999999), qy(0, 999999999), qz(0, 99999);
  PointCloud pc;
  std::vector<std::array<std::int64_t, 3>> q;
  auto decimal = [](std::int64_t n, int dec) {  // n / 10^dec as text, then the double nearest it
    long long p = 1;
    for (int d = 0; d < dec; ++d) p *= 10;
    char t[48];
    std::snprintf(t, sizeof t, "%lld.%0*lld", static_cast<long long>(n) / p, dec, static_cast<long long>(n) % p);
    return std::strtod(t, nullptr);
  };
  // Whether the reader's value of some coordinate's integer on the grid `step` (offset 0) is
  // another double than the coordinate, on the axis' own grid and every finer one the writer tries.
  bool inexact[3][3] = {};
  const double steps[3] = {0.01, 0.001, 0.1}, tried[3] = {0.1, 0.01, 0.001};
  for (int i = 0; i < 2000; ++i) {
    q.push_back({qx(rng), qy(rng), qz(rng)});
    pc.positions.emplace_back(decimal(q.back()[0], 2), decimal(q.back()[1], 3), decimal(q.back()[2], 1));
    for (int k = 0; k < 3; ++k)
      for (int t = 0; t < 3; ++t) {
        const double v = pc.positions.back()[k];
        inexact[k][t] |= std::round(v / tried[t]) * tried[t] != v;
      }
  }
  pc.positions.emplace_back(0.0, 0.0, 0.0);  // the box starts at 0: the automatic offset is 0 too
  q.push_back({0, 0, 0});
  for (int k = 0; k < 3; ++k)
    for (int t = 0; t < 3; ++t)
      if (tried[t] <= steps[k]) {
        ASSERT_TRUE(inexact[k][t]) << "axis " << k << " step " << tried[t];
      }
  const fs::path out = temp_dir() / "decimal_text.las";
  io::write_las(out, pc);
  io::FileInfo info;
  const PointCloud back = io::read_point_cloud(out, {}, &info);
  EXPECT_EQ(*info.scale, Vec3(0.01, 0.001, 0.1));
  EXPECT_EQ(*info.offset, Vec3(0.0));
  ASSERT_EQ(back.size(), q.size());
  for (std::size_t i = 0; i < q.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(std::llround(back.positions[i][k] / steps[k]), q[i][k]) << i << " " << k;
  fs::remove(out);
}

// write_text with the LAS grid of the cloud's source prints an axis whose coordinates all lie on
// it with the grid's decimals (scale 0.00025: 5; offset 0.125 with scale 0.01: 3, the offset's),
// an axis with one point off the grid, or a grid of 1/3, in the shortest form that reads back bit
// for bit. Oracle: the integers the coordinates were made from.
TEST(Writers, TextPrintsGridCoordinatesWithTheGridsDecimals) {
  io::LasWriteOptions grid;
  grid.scale = Vec3(0.00025, 0.01, 1.0 / 3);
  grid.offset = Vec3(500.0, 0.125, 7.0);
  grid.has_offset = true;
  PointCloud pc;
  for (int i = 0; i < 50; ++i) {  // as the LAS reader computes them: integer x scale + offset
    const double q = 1000.0 + 37.0 * i;
    pc.positions.emplace_back(q * grid.scale.x + grid.offset.x, q * grid.scale.y + grid.offset.y,
                              q * grid.scale.z + grid.offset.z);
  }
  const fs::path out = temp_dir() / "grid_decimals.xyz";
  io::write_text(out, pc, grid);
  const PointCloud back = io::read_point_cloud(out);
  const std::vector<std::uint8_t> bytes = slurp(out);
  std::istringstream in(std::string(bytes.begin(), bytes.end()));
  std::string line;
  std::getline(in, line);
  for (int i = 0; std::getline(in, line); ++i) {
    std::istringstream v(line);
    std::string x, y, z;
    v >> x >> y >> z;
    EXPECT_EQ(x.size() - x.find('.') - 1, 5u) << line;
    EXPECT_EQ(y.size() - y.find('.') - 1, 3u) << line;
    const double q = 1000.0 + 37.0 * i;
    EXPECT_EQ(std::llround((back.positions[i].x - 500.0) / 0.00025), q) << line;
    EXPECT_EQ(std::llround((back.positions[i].y - 0.125) / 0.01), q) << line;
    EXPECT_EQ(back.positions[i].z, pc.positions[i].z) << line;  // 1/3: shortest, bit for bit
  }
  pc.positions[7].y += 0.001;  // off the grid: the whole axis in the shortest form
  io::write_text(out, pc, grid);
  const PointCloud moved = io::read_point_cloud(out);
  for (std::size_t i = 0; i < pc.size(); ++i) EXPECT_EQ(moved.positions[i].y, pc.positions[i].y) << i;
  fs::remove(out);
}

// PDAL names the LAS fields ReturnNumber, NumberOfReturns, ScanAngleRank, ... (readers.las; its
// writers.pcd/.ply/.text write those names): a PCD, PLY or text file with those names, or their
// snake_case forms, gives a LAS file that stores them in the standard fields of the point records,
// not as extra bytes. Oracle: the values written into the input, and the LAS records' own bytes
// (ASPRS LAS 1.4 R15 table 15, PDRF 6).
TEST(Writers, PdalNamesOfLasFieldsBecomeTheStandardLasFields) {
  struct Point {
    int ret, nret, scan_dir, edge, cls, user, psid;
    double angle;  // degrees: a whole number of 0.006-degree units
  };
  const Point pts[] = {{2, 3, 1, 0, 6, 7, 4321, -12.0}, {3, 3, 0, 1, 2, 255, 65535, 30.0}, {1, 1, 0, 0, 1, 0, 0, 0.0}};
  auto row = [](const Point& p, int i, const char* sep) {
    std::ostringstream o;
    o << i << sep << 2 * i << sep << 0.5 << sep << p.ret << sep << p.nret << sep << p.scan_dir << sep << p.edge << sep
      << p.cls << sep << p.angle << sep << p.user << sep << p.psid << "\n";
    return o.str();
  };
  std::string pcd =
      "VERSION 0.7\nFIELDS X Y Z ReturnNumber NumberOfReturns ScanDirectionFlag EdgeOfFlightLine Classification "
      "ScanAngleRank UserData PointSourceId\nSIZE 8 8 8 1 1 1 1 1 4 1 2\nTYPE F F F U U U U U F U U\n"
      "COUNT 1 1 1 1 1 1 1 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";
  std::string csv =
      "x,y,z,return_number,number_of_returns,scan_direction_flag,edge_of_flight_line,classification,"
      "scan_angle_rank,user_data,point_source_id\n";
  std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
      "property uchar scalar_ReturnNumber\nproperty uchar scalar_NumberOfReturns\nproperty uchar "
      "scalar_ScanDirectionFlag\nproperty uchar scalar_EdgeOfFlightLine\nproperty uchar classification\n"
      "property float scalar_ScanAngleRank\nproperty uchar scalar_UserData\nproperty ushort scalar_PointSourceId\n"
      "end_header\n";
  for (int i = 0; i < 3; ++i) pcd += row(pts[i], i, " "), csv += row(pts[i], i, ","), ply += row(pts[i], i, " ");
  for (const auto& [name, text] : {std::pair<std::string, std::string>{"pdal_names.pcd", pcd},
                                   {"pdal_names.csv", csv}, {"pdal_names.ply", ply}}) {
    SCOPED_TRACE(name);
    const fs::path in = temp_dir() / name, las = temp_dir() / "pdal_names.las";
    std::ofstream(in, std::ios::binary) << text;
    io::FileInfo info;
    io::write_point_cloud(las, io::read_point_cloud(in, {}, &info));
    const io::LasRecords r = io::read_las_records(las);
    ASSERT_EQ(r.pdrf, 6);
    EXPECT_EQ(r.record_length, 30);  // no extra bytes: every field has its place in the record
    ASSERT_EQ(r.count, 3u);
    for (int i = 0; i < 3; ++i) {
      const Point& p = pts[i];
      const std::uint8_t* b = r.records.data() + static_cast<std::size_t>(i) * r.record_length;
      EXPECT_EQ(b[14] & 15, p.ret) << i;
      EXPECT_EQ(b[14] >> 4, p.nret) << i;
      EXPECT_EQ((b[15] >> 6) & 1, p.scan_dir) << i;
      EXPECT_EQ(b[15] >> 7, p.edge) << i;
      EXPECT_EQ(b[16], p.cls) << i;
      EXPECT_EQ(b[17], p.user) << i;
      EXPECT_EQ(io::detail::load_le<std::int16_t>(b + 18), std::lround(p.angle / 0.006)) << i;
      EXPECT_EQ(io::detail::load_le<std::uint16_t>(b + 20), p.psid) << i;
    }
    fs::remove(in);
    fs::remove(las);
  }
}

TEST(Writers, FailedWriteLeavesNoFile) {
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 1, 1)};
  pc.intensity = {1};  // wrong length: validate() fails
  const fs::path out = temp_dir() / "bad.las";
  // temp_dir() is per process id: a reused id can find another test's bad.las (test_info_cli).
  fs::remove(out);
  EXPECT_THROW(io::write_las(out, pc), std::invalid_argument);
  EXPECT_THROW(io::write_ply(out, pc), std::invalid_argument);
  EXPECT_FALSE(fs::exists(out));
  pc.intensity.clear();
  EXPECT_THROW(io::write_ply("/nonexistent-dir/x.ply", pc), std::runtime_error);
  io::LasWriteOptions opt;
  opt.scale = Vec3(1e-9);  // 1 unit = 1e-9: coordinates of 1 do not fit 32-bit integers
  opt.has_offset = true;
  pc.positions[1] = Vec3(10, 10, 10);
  EXPECT_THROW(io::write_las(out, pc, opt), std::invalid_argument);
  EXPECT_FALSE(fs::exists(out));
  for (const auto& de : fs::directory_iterator(temp_dir()))
    EXPECT_EQ(de.path().string().find(".tmp."), std::string::npos) << de.path();
}

// The writers hold the readers' coordinate bound (rayscan::kMaxCoordinate, 1e9 world units,
// inclusive), so that what they write reads back: a position beyond it, a LAS offset beyond it,
// or a LAS coordinate rounded onto its grid beyond it is refused with one line before any file
// exists. Oracle: the written files read back (positions at exactly +-1e9 equal), the header's
// own offset bytes, and the LAS arithmetic on the values chosen here (999999999 / 6 =
// 166666666.5 rounds to 166666667, x 6 = 1000000002).
TEST(Writers, NothingBeyondTheCoordinateBoundIsWritten) {
  const std::string tail = " (expected within +-1e+09, the coordinate bound in world units)";
  auto error_of = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  PointCloud pc;
  pc.positions = {Vec3(1e9, -1e9, 0), Vec3(0, 2e9, 0)};
  for (const char* name : {"beyond.las", "beyond.laz", "beyond.ply", "beyond.pcd", "beyond.xyz", "beyond.csv"}) {
    const fs::path out = temp_dir() / name;
    fs::remove(out);
    EXPECT_EQ(error_of([&] { io::write_point_cloud(out, pc); }), out.string() + ": point 1: Y coordinate is 2e+09" + tail);
    EXPECT_FALSE(fs::exists(out)) << name;
    pc.positions[1] = Vec3(0, 0, 1e9);
    io::write_point_cloud(out, pc);
    EXPECT_EQ(io::read_point_cloud(out).positions, pc.positions) << name;
    pc.positions[1] = Vec3(0, 2e9, 0);
  }

  const fs::path las = temp_dir() / "beyond_grid.las";
  fs::remove(las);
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 2, 3)};
  io::LasWriteOptions opt;
  opt.scale = Vec3(10);
  opt.offset = Vec3(5e9, 0, 0);  // the stored integers (-5e8) would fit, the header would not read
  opt.has_offset = true;
  EXPECT_EQ(error_of([&] { io::write_las(las, pc, opt); }), las.string() + ": offset X is 5e+09" + tail);
  EXPECT_FALSE(fs::exists(las));
  pc.positions = {Vec3(0, 0, 0), Vec3(999999999, 0, 0)};
  opt.scale = Vec3(6);
  opt.offset = Vec3(0.0);
  EXPECT_EQ(error_of([&] { io::write_las(las, pc, opt); }),
            las.string() + ": point 1: X coordinate is 1000000002 (stored integer 166666667 x scale 6 + offset 0, from "
                           "999999999; expected within +-1e+09, the coordinate bound in world units)");
  EXPECT_FALSE(fs::exists(las));

  // An automatic offset near -1e9 on a scale of 7 (1000 steps: 7000) rounds towards zero instead
  // of down past the bound: floor(-999999997 / 7000) x 7000 = -1000006000, trunc -999999000.
  pc.positions = {Vec3(-999999997, 0, 0), Vec3(0, 0, 0)};
  opt.scale = Vec3(7);
  opt.has_offset = false;
  io::write_las(las, pc, opt);
  EXPECT_EQ(load_at<double>(slurp(las), 155), -999999000.0);
  const PointCloud back = io::read_point_cloud(las);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back.positions[0].x, -999999994.0);  // -999999000 + round(-997 / 7) x 7
}

// PLY as PCD and text: the reader strips a property's "scalar_" prefix and then takes another
// spelling of intensity, classification or GPS time for that field, so a cloud's own scalar so
// named ("gpstime", "GPSTime", "Intensity" beside the cloud's intensity, "classification") is
// written under a suffix and reads back as a scalar; names PLY keeps ("nx", "red") stay as they
// are. Oracle: the file's own header lines and records of doubles, and the values put in.
TEST(Writers, PlyScalarsNamedLikeADedicatedFieldReadBackUnderASuffix) {
  PointCloud src;
  src.positions = {Vec3(0.5, 2, 3), Vec3(4, 5, 6)};
  src.intensity = {10, 20};
  src.scalars = {{"gpstime", {5.5, 6}}, {"GPSTime", {7, 8}},  {"Intensity", {3, 4}},
                 {"classification", {1, 2}}, {"nx", {0.25, -1}}, {"red", {200, 3}}};
  const std::vector<std::string> written = {"scalar_gpstime_1", "scalar_GPSTime_1", "scalar_Intensity_1",
                                            "scalar_classification_1", "scalar_nx", "scalar_red"};
  const fs::path out = temp_dir() / "reserved_names.ply";
  io::write_point_cloud(out, src);
  const std::vector<std::uint8_t> bytes = slurp(out);
  const std::string text(bytes.begin(), bytes.end());
  const std::size_t end = text.find("end_header\n");
  ASSERT_NE(end, std::string::npos);
  std::string props = "property float scalar_intensity\n";
  for (const std::string& n : written) props += "property double " + n + "\n";
  EXPECT_NE(text.find(props + "end_header\n"), std::string::npos) << text.substr(0, end);
  const std::size_t body = end + 11, record = 24 + 4 + 8 * src.scalars.size();
  ASSERT_EQ(bytes.size(), body + 2 * record);
  for (std::size_t i = 0; i < 2; ++i)
    for (std::size_t k = 0; k < src.scalars.size(); ++k)
      EXPECT_EQ(load_at<double>(bytes, body + i * record + 28 + 8 * k), src.scalars[k].values[i]) << written[k];

  const PointCloud back = io::read_point_cloud(out);
  EXPECT_EQ(back.positions, src.positions);
  EXPECT_EQ(back.intensity, src.intensity);
  EXPECT_TRUE(back.gps_time.empty());
  EXPECT_TRUE(back.classification.empty());
  EXPECT_TRUE(back.normals.empty());
  EXPECT_TRUE(back.rgb.empty());
  ASSERT_EQ(back.scalars.size(), src.scalars.size());
  for (std::size_t k = 0; k < src.scalars.size(); ++k) {
    EXPECT_EQ(back.scalars[k].name, written[k].substr(7));
    EXPECT_EQ(back.scalars[k].values, src.scalars[k].values) << written[k];
  }
  fs::remove(out);
}

// A CRS is stored only as WKT that GDAL reads: a cloud whose WKT GDAL cannot read (one with an
// infinite false easting, as a unit of 1e-305 m made it) is refused by every writer that stores a
// CRS, with one line, before any file exists; GDAL's own reading of the text is the oracle.
TEST(Writers, ACrsGdalCannotReadIsNotWritten) {
  const std::string bad =
      "PROJCS[\"x\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
      "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],"
      "PARAMETER[\"false_easting\",Inf],UNIT[\"unknown\",1E-305]]";
  {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    OGRSpatialReference gdal;
    const OGRErr err = gdal.importFromWkt(bad.c_str());
    CPLPopErrorHandler();
    ASSERT_NE(err, OGRERR_NONE) << "GDAL reads the WKT: no case to test";
  }
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 1, 1)};
  pc.crs_wkt = bad;
  for (const char* name : {"bad_crs.las", "bad_crs.laz", "bad_crs.ply"}) {
    const fs::path out = temp_dir() / name;
    fs::remove(out);
    try {
      io::write_point_cloud(out, pc);
      ADD_FAILURE() << name << " written";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), out.string() + ": the CRS is WKT that GDAL cannot read ('" + bad.substr(0, 40) +
                                           "...'); expected a CRS GDAL reads, or none");
    }
    EXPECT_FALSE(fs::exists(out)) << name;
  }
  // The same cloud with WKT GDAL reads is written and read back with it.
  pc.crs_wkt = crs_wkt("EPSG:32610");
  ASSERT_FALSE(pc.crs_wkt.empty());
  const fs::path ply = temp_dir() / "good_crs.ply";
  io::write_point_cloud(ply, pc);
  EXPECT_EQ(io::read_point_cloud(ply).crs_wkt, pc.crs_wkt);
  fs::remove(ply);
}

// The default LAS scale is in the CRS's units: a geographic cloud's longitude and latitude are
// degrees, where 0.001 (a metre rule) is about 100 m and merges points 2e-7 degrees (2 cm)
// apart; they are written at 1e-7 degrees and the height, metres, at 0.001. The same numbers in a
// projected CRS (metres) keep 0.001 on every axis. Oracles: the input doubles and the header's
// own scale bytes (LAS 1.4 R15 table 3, offset 131).
TEST(Writers, LasDefaultScaleOfAGeographicCloudIsATenMillionthOfADegree) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> jitter(0.0, 0.4e-7), height(0.0, 30.0);
  PointCloud pc;
  for (int i = 0; i < 1000; ++i)  // 2e-7 degrees apart on a line, each off its step by < 0.4e-7
    pc.positions.emplace_back(-122.41 + 2e-7 * i + jitter(rng), 37.77 + 2e-7 * i + jitter(rng), height(rng));
  auto header_scale = [](const fs::path& f) {
    const std::vector<std::uint8_t> b = slurp(f);
    return Vec3(load_at<double>(b, 131), load_at<double>(b, 139), load_at<double>(b, 147));
  };
  const fs::path out = temp_dir() / "geographic.las";
  pc.crs_wkt = crs_wkt("EPSG:4326");
  io::write_las(out, pc);
  EXPECT_EQ(header_scale(out), Vec3(1e-7, 1e-7, 0.001));
  const PointCloud back = io::read_point_cloud(out);
  ASSERT_EQ(back.size(), pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    for (int k = 0; k < 2; ++k)  // half a step, and the rounding of the reader's X * scale + offset
      ASSERT_LE(std::abs(back.positions[i][k] - pc.positions[i][k]), 0.5e-7 + 1e-12) << i << " " << k;
    ASSERT_LE(std::abs(back.positions[i][2] - pc.positions[i][2]), 0.0005 + 1e-12) << i;
    if (i > 0) {
      ASSERT_NE(back.positions[i].x, back.positions[i - 1].x) << i;  // still distinct points
    }
  }
  // A geographic cloud from LAS on a coarser grid of degrees (1e-6, through PLY or PCD) keeps it.
  PointCloud grid = pc;
  for (Vec3& p : grid.positions)
    for (int k = 0; k < 2; ++k) p[k] = std::round(p[k] / 1e-6) * 1e-6;  // the reader's X * scale (offset 0)
  io::write_las(out, grid);
  EXPECT_EQ(header_scale(out), Vec3(1e-6, 1e-6, 0.001));
  const PointCloud grid_back = io::read_point_cloud(out);
  ASSERT_EQ(grid_back.size(), grid.size());
  for (std::size_t i = 0; i < grid.size(); ++i)
    for (int k = 0; k < 2; ++k) ASSERT_EQ(grid_back.positions[i][k], grid.positions[i][k]) << i << " " << k;
  // The same numbers as metres of UTM zone 10N: a millimetre grid.
  pc.crs_wkt = crs_wkt("EPSG:32610");
  io::write_las(out, pc);
  EXPECT_EQ(header_scale(out), Vec3(0.001));
  fs::remove(out);
}

// The Extra Bytes VLR's record length is 16 bit (LAS 1.4 R15 section 2.5.6): 341 descriptors of
// 192 bytes fit, 342 do not; the writer says so before writing anything.
TEST(Writers, LasRefusesMoreExtraFieldsThanTheExtraBytesVlrHolds) {
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 1, 1)};
  for (int i = 0; i < 341; ++i) {
    std::string name = "f";  // (appended, not "f" + ...: GCC 12's -Wrestrict misfires on that)
    name += std::to_string(i);
    pc.scalars.push_back({name, {1.0, 2.0}});
  }
  const fs::path out = temp_dir() / "extra341.las";
  fs::remove(out);
  io::write_las(out, pc);
  {
    const PointCloud back = io::read_point_cloud(out);  // (it also holds the PDRF's own fields)
    std::size_t ours = 0;
    for (const ScalarField& f : back.scalars)
      if (f.name.size() > 1 && f.name[0] == 'f' && f.name.find_first_not_of("0123456789", 1) == std::string::npos) {
        ++ours;
        EXPECT_EQ(f.values, (std::vector<double>{1.0, 2.0})) << f.name;
      }
    EXPECT_EQ(ours, 341u);
  }
  pc.scalars.push_back({"f341", {1.0, 2.0}});
  const fs::path bad = temp_dir() / "extra342.las";
  fs::remove(bad);
  try {
    io::write_las(bad, pc);
    ADD_FAILURE() << "342 extra fields were written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at most 341"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad));
}

}  // namespace
}  // namespace rayscan::test
