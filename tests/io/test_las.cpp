// LAS reader behaviour on real files, checked against independent oracles: other files holding
// the same points, the file's own header and VLR bytes, and the shared-data README.
#include "io_test_util.hpp"
#include "../common/run_command.hpp"

#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_reader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <tuple>

namespace rayscan::test {
namespace {

TEST(Las, Pdrf0To3ParitySetYieldsIdenticalXyzAndMatchesThePcdCopy) {
  RAYSCAN_REQUIRE_FILE(p0, "las/conformance/point10.las");
  const PointCloud ref = read(p0);
  ASSERT_EQ(ref.size(), 1065u);
  for (const char* rel : {"las/conformance/point-time.las", "las/conformance/point-color.las",
                          "las/conformance/point-color-time.las"}) {
    io::FileInfo info;
    const PointCloud pc = read(data_file(rel), &info);
    ASSERT_EQ(pc.size(), ref.size()) << rel;
    EXPECT_TRUE(std::equal(pc.positions.begin(), pc.positions.end(), ref.positions.begin())) << rel;
    EXPECT_EQ(pc.intensity, ref.intensity) << rel;
    EXPECT_EQ(pc.classification, ref.classification) << rel;
    EXPECT_EQ(!pc.gps_time.empty(), info.point_format == 1 || info.point_format == 3) << rel;
    EXPECT_EQ(!pc.rgb.empty(), info.point_format == 2 || info.point_format == 3) << rel;
  }
  // autzen-utm.pcd stores the same points as float64 PCD fields (README "same-data groups").
  const PointCloud pcd = read(data_file("pcd/autzen-utm.pcd"));
  ASSERT_EQ(pcd.size(), ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(pcd.positions[i][k], ref.positions[i][k], 1e-6) << i;
  EXPECT_EQ(pcd.intensity, ref.intensity);
  EXPECT_EQ(pcd.classification, ref.classification);
}

TEST(Las, AutzenPdrf3AndPdrf7YieldIdenticalPoints) {
  RAYSCAN_REQUIRE_FILE(p3, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(p7, "las/conformance/autzen_trim_7.las");
  io::FileInfo i3, i7;
  const PointCloud a = read(p3, &i3), b = read(p7, &i7);
  EXPECT_EQ(i3.point_format, 3);
  EXPECT_EQ(i7.point_format, 7);
  EXPECT_EQ(i3.version, "1.2");
  EXPECT_EQ(i7.version, "1.4");
  ASSERT_EQ(a.size(), 110000u);
  ASSERT_EQ(b.size(), a.size());
  EXPECT_TRUE(std::equal(a.positions.begin(), a.positions.end(), b.positions.begin()));
  EXPECT_EQ(a.intensity, b.intensity);
  EXPECT_EQ(a.classification, b.classification);
  EXPECT_EQ(a.gps_time, b.gps_time);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_EQ(a.scalar("return_number")->values, b.scalar("return_number")->values);
  EXPECT_EQ(a.scalar("number_of_returns")->values, b.scalar("number_of_returns")->values);
}

TEST(Las, FirstRecordDecodedByHandFromTheFileBytes) {
  // Oracle: the raw bytes of record 0 of autzen_trim.las, decoded here independently of the
  // reader from the header's offset, scale and offset fields (LAS 1.4 R15 table 3 / table 10).
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const auto bytes = slurp(p);
  auto u32 = [&](std::size_t o) { std::uint32_t v; std::memcpy(&v, &bytes[o], 4); return v; };
  auto i32 = [&](std::size_t o) { std::int32_t v; std::memcpy(&v, &bytes[o], 4); return v; };
  auto u16 = [&](std::size_t o) { std::uint16_t v; std::memcpy(&v, &bytes[o], 2); return v; };
  auto f64 = [&](std::size_t o) { double v; std::memcpy(&v, &bytes[o], 8); return v; };
  const std::size_t off = u32(96);
  const PointCloud pc = read(p);
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(pc.positions[0][k], i32(off + 4 * k) * f64(131 + 8 * k) + f64(155 + 8 * k));
  EXPECT_EQ(pc.intensity[0], u16(off + 12));
  EXPECT_EQ(pc.classification[0], bytes[off + 15] & 31);
  EXPECT_EQ(pc.gps_time[0], f64(off + 20));
  EXPECT_EQ(pc.rgb[0].r, u16(off + 28) * 257);  // 8-bit values in 16-bit fields: scaled by 257
}

TEST(Las, EveryCoordinateIsScaleTimesXRoundedThenPlusOffsetRounded) {
  // Oracle: the LAS specification's double arithmetic (LAS 1.4 R15 section 2.4) on the file's own
  // bytes, X * scale rounded, then + offset rounded; the product goes through a volatile so that
  // no compiler fuses the oracle itself. A reader whose multiply-add is fused into an FMA (one
  // rounding: what GCC and Clang emit for a * b + c on an FMA target without -ffp-contract=off)
  // differs in the last bit wherever std::fma does: on 5% of this file's coordinates (non-zero
  // offsets; with offset 0 both round alike), counted here so that the test tells them apart.
  RAYSCAN_REQUIRE_FILE(p, "las/Haystack_Rock.las");
  const auto bytes = slurp(p);
  auto u32 = [&](std::size_t o) { std::uint32_t v; std::memcpy(&v, &bytes[o], 4); return v; };
  auto i32 = [&](std::size_t o) { std::int32_t v; std::memcpy(&v, &bytes[o], 4); return v; };
  auto u16 = [&](std::size_t o) { std::uint16_t v; std::memcpy(&v, &bytes[o], 2); return v; };
  auto f64 = [&](std::size_t o) { double v; std::memcpy(&v, &bytes[o], 8); return v; };
  const std::size_t off = u32(96), len = u16(105), n = u32(107);
  const PointCloud pc = read(p);
  ASSERT_EQ(pc.size(), n);
  std::size_t fused_differs = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const double x = i32(off + i * len + 4 * k), scale = f64(131 + 8 * k), offset = f64(155 + 8 * k);
      volatile double product = x * scale;
      const double expect = product + offset;
      ASSERT_EQ(pc.positions[i][k], expect) << "point " << i << " axis " << k;
      if (std::fma(x, scale, offset) != expect) ++fused_differs;
    }
  EXPECT_GT(fused_differs, n / 100);
}

TEST(Las, EightBitColourIsScaledSixteenBitKeptAllZeroDropped) {
  RAYSCAN_REQUIRE_FILE(autzen, "las/autzen_trim.las");
  io::FileInfo info;
  const PointCloud a = read(autzen, &info);
  std::uint16_t mx = 0;
  for (const Rgb16& c : a.rgb) mx = std::max({mx, c.r, c.g, c.b});
  EXPECT_EQ(mx, 236 * 257);  // README: values 0..236 in the 16-bit fields
  RAYSCAN_REQUIRE_FILE(warsaw, "las/warsaw_small.las");
  const PointCloud w = read(warsaw);
  mx = 0;
  for (const Rgb16& c : w.rgb) mx = std::max({mx, c.r, c.g, c.b});
  EXPECT_EQ(mx, 53760);  // README: 16-bit colour, max 53760, used as stored
  RAYSCAN_REQUIRE_FILE(crop, "las/4_6_crop.las");
  io::FileInfo ci;
  const PointCloud c = read(crop, &ci);
  EXPECT_TRUE(c.rgb.empty());  // README: colour format, all fields 0
  EXPECT_EQ(ci.point_format, 3);
}

TEST(Las, EmptyFileGivesAnEmptyCloud) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/no-points-1.3.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_TRUE(pc.empty());
  EXPECT_EQ(info.version, "1.3");
  EXPECT_EQ(info.point_format, 0);
}

TEST(Las, LotsOfVlrSkipsAll390VlrsAndReadsThePoint) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/lots_of_vlr.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_EQ(info.vlrs.size(), 390u);
  ASSERT_EQ(pc.size(), 1u);
  EXPECT_NEAR(pc.positions[0].x, 715001.346, 1e-9);
  EXPECT_NEAR(pc.positions[0].y, 839349.171, 1e-9);
  EXPECT_NEAR(pc.positions[0].z, 17.275, 1e-9);
  EXPECT_EQ(pc.intensity[0], 105);
  EXPECT_EQ(pc.classification[0], 1);
}

TEST(Las, EvlrAfterThePointsIsListedAndPointsEqualTest14) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/1_4_w_evlr.las");
  RAYSCAN_REQUIRE_FILE(q, "las/conformance/test1_4.las");
  io::FileInfo info;
  const PointCloud a = read(p, &info), b = read(q);
  ASSERT_EQ(a.size(), 1000u);
  EXPECT_TRUE(std::equal(a.positions.begin(), a.positions.end(), b.positions.begin()));
  EXPECT_EQ(a.gps_time, b.gps_time);
  const auto evlrs = std::count_if(info.vlrs.begin(), info.vlrs.end(), [](const io::VlrInfo& v) { return v.extended; });
  EXPECT_EQ(evlrs, 1);
  EXPECT_EQ(info.point_format, 6);
  EXPECT_EQ(info.crs_source, "WKT VLR");
}

TEST(Las, HeaderBoundsAreNeverTrusted) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/simple1_3.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  ASSERT_TRUE(info.header_bounds.has_value());
  // README: the header stores the box unscaled (min x = -235434519); the cloud's box is recomputed.
  EXPECT_NEAR(info.header_bounds->lo.x, -235434519.0, 1.0);
  EXPECT_NEAR(pc.bounds().lo.x, -235434.519, 1e-6);
  EXPECT_EQ(info.point_format, 4);
  EXPECT_EQ(info.record_length, 57);
}

TEST(Las, RecordLengthFromTheHeaderAndExtraBytesExposed) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/extrabytes.las");
  RAYSCAN_REQUIRE_FILE(q, "las/conformance/simple1_1.las");
  io::FileInfo info;
  const PointCloud a = read(p, &info), b = read(q);
  EXPECT_EQ(info.record_length, 61);
  EXPECT_EQ(info.extra_bytes_per_point, 27);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE(std::equal(a.positions.begin(), a.positions.end(), b.positions.begin()));
  // The Extra Bytes VLR describes the 27 bytes: they appear as named scalars.
  const std::size_t standard = 9;  // return_number, number_of_returns, scan_angle, user_data, point_source_id, 4 flag fields
  EXPECT_GT(a.scalars.size(), standard);
  const auto with_scalars_off = io::read_point_cloud(p, io::ReadOptions{false});
  EXPECT_TRUE(with_scalars_off.scalars.empty());
  EXPECT_TRUE(std::equal(with_scalars_off.positions.begin(), with_scalars_off.positions.end(), b.positions.begin()));
}

TEST(Las, Pdrf8ClassesAbove31AndNir) {
  RAYSCAN_REQUIRE_FILE(p, "las/derived/append-bug.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_EQ(info.point_format, 8);
  EXPECT_EQ(info.record_length, 41);
  EXPECT_NE(std::find(pc.classification.begin(), pc.classification.end(), 65), pc.classification.end());
  ASSERT_NE(pc.scalar("nir"), nullptr);
  std::uint16_t mx = 0;
  for (const Rgb16& c : pc.rgb) mx = std::max({mx, c.r, c.g, c.b});
  EXPECT_EQ(mx, 65280);  // README: 16-bit colour, max 65280
  EXPECT_EQ(info.epsg, 2154);
}

TEST(Las, CrsFromGeoKeysBecomesEpsgAndWkt) {
  RAYSCAN_REQUIRE_FILE(p, "las/Haystack_Rock.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_EQ(info.crs_source, "GeoKeys");
  EXPECT_EQ(info.epsg, 3645);          // README: GeoKeys EPSG:3645
  EXPECT_EQ(info.vertical_epsg, 5703);  // + vertical NAVD88
  EXPECT_NE(pc.crs_wkt.find("NAVD88"), std::string::npos);
  RAYSCAN_REQUIRE_FILE(m, "las/mvk-thin.las");
  // EPSG:26995 (metres) in US survey feet by its ProjLinearUnitsGeoKey: no EPSG code
  // (test_geokeys.cpp).
  io::FileInfo mi;
  read(m, &mi);
  EXPECT_EQ(mi.epsg, 0);
}

TEST(Las, WktVlrPreferredOverGeoKeysWhenBothPresent) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/file_with_both_wkt_and_geotiff_vlrs.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_EQ(info.crs_source, "WKT VLR");
  // README: GeoKeys EPSG:32104, with ProjLinearUnitsGeoKey US survey foot: Nebraska in feet as
  // the WKT says, a CRS without an EPSG code (test_geokeys.cpp), and the WKT names none either.
  EXPECT_EQ(info.epsg, 0);
  EXPECT_NE(pc.crs_wkt.find("Nebraska"), std::string::npos);
}

TEST(Las, EmptyWktVlrIsSurvivedWithNoCrs) {
  RAYSCAN_REQUIRE_FILE(p, "las/warsaw_small.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_TRUE(pc.crs_wkt.empty());
  EXPECT_EQ(info.epsg, 0);
  EXPECT_EQ(pc.size(), 3000u);
}

TEST(Las, LegacyCountThatDiffersFromThe64BitCountIsNoted) {
  // Oracle: the header's own counts (LAS 1.4 R15 table 3: byte 107 legacy, byte 247 64-bit) on a
  // copy of a real 1.4 file whose two counts agree (1000): the 64-bit one is read, the
  // disagreement is noted as lasinfo warns of it.
  RAYSCAN_REQUIRE_FILE(p, "las/test1_4.las");
  auto bytes = slurp(p);
  io::FileInfo info;
  EXPECT_EQ(io::read_point_cloud(bytes, io::Format::las, "x.las", {}, &info).size(), 1000u);
  for (const std::string& note : info.notes) EXPECT_EQ(note.find("legacy point count"), std::string::npos) << note;
  const std::uint32_t legacy = 999;
  std::memcpy(bytes.data() + 107, &legacy, 4);
  io::FileInfo info2;
  EXPECT_EQ(io::read_point_cloud(bytes, io::Format::las, "x.las", {}, &info2).size(), 1000u);
  bool noted = false;
  for (const std::string& note : info2.notes)
    noted |= note.find("legacy point count 999 (byte 107) differs from the point count 1000 (byte 247)") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(Las, CompressionBitWithoutLaszipVlrIsRefused) {
  // Oracle: the compression bit of the PDRF byte (LASzip sets bit 7) on a copy of a real file
  // that has no LASzip VLR: LAZ is detected by the VLR, so the bit alone is an inconsistency.
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/point10.las");
  auto bytes = slurp(p);
  bytes[104] |= 0x80;
  try {
    io::read_point_cloud(bytes, io::Format::las, "x.laz");
    FAIL() << "inconsistent compression bit accepted";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("no LASzip VLR"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("x.laz: byte 104", 0), 0u) << e.what();
  }
}

// ---- Derived LAS files: header fields, normals and Extra Bytes names.

/// The Extra Bytes descriptors of a LAS file, from its own bytes (LAS 1.4 R15 table 24): data type
/// and the 32-byte name of each, over every "LASF_Spec"/4 VLR in file order.
struct LasEbDescriptor {
  int type = 0;
  std::string name;
};
std::vector<LasEbDescriptor> las_eb_descriptors(const std::vector<std::uint8_t>& b) {
  std::vector<LasEbDescriptor> out;
  std::size_t pos = load_at<std::uint16_t>(b, 94);
  const std::uint32_t n = load_at<std::uint32_t>(b, 100);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::string user(reinterpret_cast<const char*>(&b[pos + 2]), strnlen(reinterpret_cast<const char*>(&b[pos + 2]), 16));
    const std::uint16_t id = load_at<std::uint16_t>(b, pos + 18), len = load_at<std::uint16_t>(b, pos + 20);
    if (user == "LASF_Spec" && id == 4)
      for (std::size_t k = 0; k + 192 <= len; k += 192) {
        const char* nm = reinterpret_cast<const char*>(&b[pos + 54 + k + 4]);
        out.push_back({b[pos + 54 + k + 2], std::string(nm, strnlen(nm, 32))});
      }
    pos += 54 + len;
  }
  return out;
}

TEST(LasDerived, KeepsTheSourcesGpsTimeTypeAndProjectGuid) {
  // Oracle: the source file's own header bytes (global encoding bit 0 at byte 6, GUID bytes
  // 8-23): test1_4 says adjusted standard GPS time (17), vegetation_1_3 has a GUID.
  for (const char* rel : {"las/test1_4.las", "las/vegetation_1_3.las"}) {
    const fs::path src = data_file(rel);
    ASSERT_FALSE(src.empty()) << rel;
    io::FileInfo info;
    const PointCloud pc = read(src, &info);
    const auto a = slurp(src);
    for (const char* ext : {".las", ".laz"}) {
      const fs::path out = temp_dir() / (fs::path(rel).stem().string() + "_derived" + ext);
      io::write_point_cloud(out, pc, io::las_grid_of(info));
      const auto b = slurp(out);  // the LAZ header is the LAS one (translate copies it)
      EXPECT_EQ(b[6] & 1, a[6] & 1) << out;
      EXPECT_TRUE(std::equal(a.begin() + 8, a.begin() + 24, b.begin() + 8)) << out << ": GUID";
      EXPECT_EQ(b[6] & 0x10, 0x10) << out << ": WKT bit";
    }
  }
  // Through the command that writes derived clouds (`visibility -o`, write_result_cloud).
  for (const auto& [rel, observer] : {std::pair{"las/test1_4.las", "1694300,1816495"},
                                      std::pair{"las/vegetation_1_3.las", "-98449,-55972"}}) {
    const fs::path src = data_file(rel), out = temp_dir() / "vis_derived.las";
    const CommandResult r = run_command(std::string("'") + RAYSCAN_EXE + "' visibility -q '" + src.string() +
                                        "' --observer " + observer + " --height 2 -o '" + out.string() + "'");
    ASSERT_EQ(r.code, 0) << r.out;
    const auto a = slurp(src), b = slurp(out);
    EXPECT_EQ(b[6] & 1, a[6] & 1) << rel;
    EXPECT_TRUE(std::equal(a.begin() + 8, a.begin() + 24, b.begin() + 8)) << rel << ": GUID";
  }
  // A cloud with no LAS source: GPS week time (bit 0 clear), zero GUID.
  PointCloud pc;
  pc.positions = {Vec3(1, 2, 3)};
  const fs::path out = temp_dir() / "no_source.las";
  io::write_las(out, pc);
  const auto b = slurp(out);
  EXPECT_EQ(load_at<std::uint16_t>(b, 6), 16u);
  EXPECT_TRUE(std::all_of(b.begin() + 8, b.begin() + 24, [](std::uint8_t c) { return c == 0; }));
}

TEST(LasDerived, NormalsAreWrittenAsPdalExtraBytesAndReadBack) {
  // cloud_bin_0.pcd (3903 points with normal_x/y/z) written as LAS and LAZ. Oracles: the file's
  // own Extra Bytes descriptors (PDAL's dimension names NormalX/Y/Z, type 10 = double) and record
  // bytes, and the PCD's normals for the read back.
  RAYSCAN_REQUIRE_FILE(pcd, "pcd/cloud_bin_0.pcd");
  PointCloud pc = read(pcd);
  ASSERT_EQ(pc.normals.size(), pc.size());
  pc.scalars.push_back({"visible_count", std::vector<double>(pc.size(), 2.0)});
  for (const char* ext : {".las", ".laz"}) {
    const fs::path out = temp_dir() / (std::string("normals") + ext);
    io::write_las(out, pc);
    const io::LasRecords recs = io::read_las_records(out);
    const auto b = slurp(out);
    const auto eb = las_eb_descriptors(b);
    ASSERT_EQ(eb.size(), 4u);
    const char* names[3] = {"NormalX", "NormalY", "NormalZ"};
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(eb[a].name, names[a]);
      EXPECT_EQ(eb[a].type, 10);
    }
    const std::size_t rec = load_at<std::uint16_t>(b, 105), core = rec - 8 * 4;
    ASSERT_EQ(recs.records.size(), rec * pc.size());
    for (std::size_t i = 0; i < pc.size(); ++i)
      for (int a = 0; a < 3; ++a) {
        double v;
        std::memcpy(&v, recs.records.data() + i * rec + core + 8 * a, 8);
        ASSERT_EQ(v, static_cast<double>(pc.normals[i][a])) << ext << " point " << i;
      }
    const PointCloud back = read(out);
    EXPECT_TRUE(back.normals == pc.normals) << ext;
    EXPECT_EQ(back.scalar("NormalX"), nullptr);
    ASSERT_NE(back.scalar("visible_count"), nullptr);
    // Normals alone, without the scalars, as a renderer asks for them.
    auto r = io::open_point_reader(out, io::AttributeSet::none().add(io::Attribute::normals), io::ReadOptions{.scalars = false});
    PointCloud chunk;
    ASSERT_EQ(r->read(chunk, pc.size()), pc.size());
    EXPECT_TRUE(chunk.normals == pc.normals) << ext;
  }
  // COPC built from the PCD (`rayscan translate`, through write_las): the same normals, reordered.
  const fs::path copc = temp_dir() / "normals.copc.laz";
  const CommandResult r = run_command(std::string("'") + RAYSCAN_EXE + "' translate -q '" + pcd.string() + "' '" + copc.string() + "'");
  ASSERT_EQ(r.code, 0) << r.out;
  const PointCloud c = read(copc);
  auto sorted = [](std::vector<glm::vec3> v) {
    std::sort(v.begin(), v.end(), [](const glm::vec3& p, const glm::vec3& q) {
      return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
    });
    return v;
  };
  ASSERT_EQ(c.normals.size(), pc.size());
  EXPECT_TRUE(sorted(c.normals) == sorted(pc.normals));
}

TEST(LasDerived, ExtraBytesNamesLongerThan32BytesStayDistinct) {
  // Oracle: the descriptors' 32-byte name fields in the file; the read back by those names.
  PointCloud pc;
  pc.positions = {Vec3(1, 2, 3), Vec3(4, 5, 6)};
  pc.scalars = {{"this_is_a_very_long_attribute_name_one", {1, 2}},
                {"this_is_a_very_long_attribute_name_two", {3, 4}},
                {"short", {5, 6}},
                {"short", {7, 8}},
                {"this_is_a_very_long_attribute_~1", {9, 10}}};  // a real name equal to a candidate
  const fs::path out = temp_dir() / "long_names.las";
  io::write_las(out, pc);
  const auto eb = las_eb_descriptors(slurp(out));
  ASSERT_EQ(eb.size(), 5u);
  const std::vector<std::string> want = {"this_is_a_very_long_attribute_~2", "this_is_a_very_long_attribute_~3", "short",
                                         "short~1", "this_is_a_very_long_attribute_~1"};
  for (std::size_t k = 0; k < want.size(); ++k) {
    EXPECT_EQ(eb[k].name, want[k]);
    EXPECT_LE(eb[k].name.size(), 32u);
  }
  const PointCloud back = read(out);
  for (std::size_t k = 0; k < want.size(); ++k) {
    const ScalarField* f = back.scalar(want[k]);
    ASSERT_NE(f, nullptr) << want[k];
    EXPECT_EQ(f->values, pc.scalars[k].values) << want[k];
  }
}

TEST(Las, ExtraBytesDescribedByTwoVlrsKeepTheirOffsets) {
  // append-bug.las (PDRF 8, 41-byte records: 3 extra bytes) describes its extra bytes in two
  // Extra Bytes VLRs: Deviation (uint16, bytes 38-39) and confidence (uint8, byte 40). Its extra
  // bytes are all zero, so a copy gets distinct values there. Oracle: the record bytes at those
  // offsets.
  RAYSCAN_REQUIRE_FILE(p, "las/append-bug.las");
  auto b = slurp(p);
  ASSERT_EQ(load_at<std::uint16_t>(b, 105), 41u);
  const std::size_t off = load_at<std::uint32_t>(b, 96);
  const std::size_t n = load_at<std::uint64_t>(b, 247);
  for (std::size_t i = 0; i < n; ++i) {
    store_at<std::uint16_t>(b, off + i * 41 + 38, static_cast<std::uint16_t>(1000 + i));
    b[off + i * 41 + 40] = static_cast<std::uint8_t>(i * 7 + 3);
  }
  io::FileInfo info;
  const PointCloud pc = io::read_point_cloud(b, io::Format::las, "append-bug.las", {}, &info);
  const ScalarField* dev = pc.scalar("Deviation");
  const ScalarField* conf = pc.scalar("confidence");
  ASSERT_NE(dev, nullptr);
  ASSERT_NE(conf, nullptr);
  ASSERT_EQ(pc.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(dev->values[i], load_at<std::uint16_t>(b, off + i * 41 + 38)) << "point " << i;
    ASSERT_EQ(conf->values[i], b[off + i * 41 + 40]) << "point " << i;
  }
  for (const std::string& note : info.notes) EXPECT_EQ(note.find("Extra Bytes"), std::string::npos) << note;
}

}  // namespace
}  // namespace rayscan::test
