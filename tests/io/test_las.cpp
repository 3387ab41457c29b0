// LAS reader behaviour on real files, checked against independent oracles: other files holding
// the same points, the file's own header and VLR bytes, and the shared-data README.
#include "io_test_util.hpp"

#include <algorithm>
#include <cstring>

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
  io::FileInfo mi;
  read(m, &mi);
  EXPECT_EQ(mi.epsg, 26995);
}

TEST(Las, WktVlrPreferredOverGeoKeysWhenBothPresent) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/file_with_both_wkt_and_geotiff_vlrs.las");
  io::FileInfo info;
  const PointCloud pc = read(p, &info);
  EXPECT_EQ(info.crs_source, "WKT VLR");
  EXPECT_EQ(info.epsg, 32104);  // README: GeoKeys EPSG:32104
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

}  // namespace
}  // namespace rayscan::test
