// The unit GeoKeys of a LAS file's GeoKeyDirectoryTag (io/src/crs.cpp): ProjLinearUnitsGeoKey,
// ProjLinearUnitSizeGeoKey, GeogAngularUnitsGeoKey and VerticalUnitsGeoKey; and the CRS codes of
// ProjectedCSTypeGeoKey and VerticalCSTypeGeoKey, which must name a CRS of their kind. Oracle: GDAL itself,
// reading a 1 x 1 GeoTIFF whose GeoKeyDirectoryTag and GeoDoubleParamsTag hold the very bytes given
// to the LAS reader's crs_from_geokeys; and PROJ's database for the one case where rayscan reads
// the keys as GDAL 3.6 does not (a vertical unit beside an EPSG vertical CRS).
#include "io_test_util.hpp"
#include "readers.hpp"

#include "../common/run_command.hpp"
#include "rayscan/analysis/site_location.hpp"

#include <gdal.h>
#include <cpl_conv.h>
#include <ogr_spatialref.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::test {
namespace geokeys_test {

/// One GeoKey entry {KeyID, TIFFTagLocation, Count, Value_Offset} (GeoTIFF 1.0 section 2.4).
struct Key {
  std::uint16_t id, location, count, value;
};

/// A GeoKeyDirectoryTag as stored: header {1, 1, 0, NumberOfKeys} then the keys in id order.
std::vector<std::uint16_t> directory(std::vector<Key> keys) {
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) { return a.id < b.id; });
  std::vector<std::uint16_t> d = {1, 1, 0, static_cast<std::uint16_t>(keys.size())};
  for (const Key& k : keys) d.insert(d.end(), {k.id, k.location, k.count, k.value});
  return d;
}

template <typename T>
std::vector<std::uint8_t> bytes_of(const std::vector<T>& v) {  // little-endian host (x86-64, arm64)
  std::vector<std::uint8_t> b(v.size() * sizeof(T));
  if (!v.empty()) std::memcpy(b.data(), v.data(), b.size());
  return b;
}

/// A 1 x 1 8-bit GeoTIFF (TIFF 6.0, little-endian, one strip) whose GeoKeyDirectoryTag (34735) and,
/// when given, GeoDoubleParamsTag (34736) and GeoAsciiParamsTag (34737) are `dir`, `doubles` and
/// `ascii` (with its terminating NUL).
void write_geotiff(const fs::path& p, const std::vector<std::uint16_t>& dir, const std::vector<double>& doubles,
                   const std::vector<std::uint8_t>& ascii = {}) {
  struct Tag {
    std::uint16_t id, type;
    std::uint32_t count;
    std::vector<std::uint8_t> payload;
  };
  auto short_tag = [](std::uint16_t id, std::uint16_t v) {
    return Tag{id, 3, 1, bytes_of(std::vector<std::uint16_t>{v})};
  };
  auto long_tag = [](std::uint16_t id, std::uint32_t v) {
    return Tag{id, 4, 1, bytes_of(std::vector<std::uint32_t>{v})};
  };
  std::vector<Tag> tags = {short_tag(256, 1), short_tag(257, 1), short_tag(258, 8), short_tag(259, 1),
                           short_tag(262, 1), long_tag(273, 0), short_tag(277, 1), short_tag(278, 1),
                           long_tag(279, 1),
                           {33550, 12, 3, bytes_of(std::vector<double>{1, 1, 0})},
                           {33922, 12, 6, bytes_of(std::vector<double>{0, 0, 0, 2000000, 1270000, 0})},
                           {34735, 3, static_cast<std::uint32_t>(dir.size()), bytes_of(dir)}};
  if (!doubles.empty()) tags.push_back({34736, 12, static_cast<std::uint32_t>(doubles.size()), bytes_of(doubles)});
  if (!ascii.empty()) tags.push_back({34737, 2, static_cast<std::uint32_t>(ascii.size()), ascii});
  const std::uint32_t ifd = 8, data_at = ifd + 2 + 12 * static_cast<std::uint32_t>(tags.size()) + 4;
  std::vector<std::uint8_t> data = {0};  // the one pixel, first in the data area
  tags[5].payload = bytes_of(std::vector<std::uint32_t>{data_at});
  std::vector<std::uint8_t> out = {'I', 'I', 42, 0, 8, 0, 0, 0};
  auto put = [&out](auto v) {
    const auto b = bytes_of(std::vector<decltype(v)>{v});
    out.insert(out.end(), b.begin(), b.end());
  };
  put(static_cast<std::uint16_t>(tags.size()));
  for (const Tag& t : tags) {
    put(t.id);
    put(t.type);
    put(t.count);
    if (t.payload.size() <= 4) {
      std::vector<std::uint8_t> v = t.payload;
      v.resize(4, 0);
      out.insert(out.end(), v.begin(), v.end());
    } else {
      if (data.size() % 2) data.push_back(0);  // TIFF values start on a word boundary
      put(static_cast<std::uint32_t>(data_at + data.size()));
      data.insert(data.end(), t.payload.begin(), t.payload.end());
    }
  }
  put(std::uint32_t{0});
  out.insert(out.end(), data.begin(), data.end());
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(out.data()), static_cast<std::streamsize>(out.size()));
}

/// The CRS GDAL reads from `p`'s GeoKeys; `compound`: with GTIFF_REPORT_COMPD_CS=YES, under which
/// GDAL reports the vertical keys too.
OGRSpatialReference gdal_crs(const fs::path& p, bool compound) {
  GDALAllRegister();
  // GDAL's warnings on keys it reads otherwise than the registry (a GeographicTypeGeoKey beside
  // other geodetic keys) are no failure of the test.
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLSetThreadLocalConfigOption("GTIFF_REPORT_COMPD_CS", compound ? "YES" : nullptr);
  OGRSpatialReference srs;
  if (GDALDatasetH ds = GDALOpen(p.c_str(), GA_ReadOnly)) {
    if (const OGRSpatialReferenceH h = GDALGetSpatialRef(ds)) srs = *OGRSpatialReference::FromHandle(h);
    GDALClose(ds);
  }
  CPLSetThreadLocalConfigOption("GTIFF_REPORT_COMPD_CS", nullptr);
  CPLPopErrorHandler();
  return srs;
}

/// What rayscan reads from the same GeoKeys: the WKT and the FileInfo it fills.
struct Ours {
  std::string wkt;
  io::FileInfo info;
  OGRSpatialReference srs;
};

Ours ours(const std::vector<std::uint16_t>& dir, const std::vector<double>& doubles) {
  Ours r;
  const std::vector<std::uint8_t> d = bytes_of(dir), g = bytes_of(doubles);
  r.wkt = io::detail::crs_from_geokeys(d.data(), d.size(), r.info, {g.empty() ? nullptr : g.data(), g.size()});
  r.srs.importFromWkt(r.wkt.c_str());
  return r;
}

/// GDAL's and rayscan's readings of the same keys, the GeoTIFF written under `name`.
std::pair<OGRSpatialReference, Ours> both(const std::string& name, const std::vector<Key>& keys,
                                          const std::vector<double>& doubles = {}, bool compound = true) {
  const fs::path tif = temp_dir() / (name + ".tif");
  write_geotiff(tif, directory(keys), doubles);
  return {gdal_crs(tif, compound), ours(directory(keys), doubles)};
}

/// The horizontal linear unit's name and size in metres.
std::pair<std::string, double> linear_unit(const OGRSpatialReference& s, const char* node = nullptr) {
  const char* name = nullptr;
  const double size = node ? s.GetTargetLinearUnits(node, &name) : s.GetLinearUnits(&name);
  return {name ? name : "", size};
}

constexpr double kUsFoot = 1200.0 / 3937.0;  // EPSG 9003, US survey foot in metres

TEST(GeoKeys, ProjLinearUnitFootOverridesTheMetreOfTheProjectedCrsAsGdalReadsIt) {
  // NAD83 / Mississippi West (metres) with ProjLinearUnitsGeoKey and VerticalUnitsGeoKey = US
  // survey foot: the keys of /work/shared/data/las/mvk-thin.las.
  const auto [gdal, r] = both("ft", {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 9003}, {4099, 0, 1, 9003}});
  ASSERT_FALSE(r.wkt.empty()) << testing::PrintToString(r.info.notes);
  ASSERT_TRUE(gdal.IsCompound()) << "GDAL read no vertical part";
  EXPECT_TRUE(r.srs.IsSame(&gdal)) << r.wkt;
  EXPECT_EQ(linear_unit(r.srs), linear_unit(gdal));
  EXPECT_EQ(linear_unit(r.srs).first, "US survey foot");
  EXPECT_NEAR(linear_unit(r.srs).second, kUsFoot, 1e-15);
  // False easting 700 km, in feet as GDAL has it.
  EXPECT_NEAR(r.srs.GetProjParm(SRS_PP_FALSE_EASTING), gdal.GetProjParm(SRS_PP_FALSE_EASTING), 1e-6);
  EXPECT_NEAR(r.srs.GetProjParm(SRS_PP_FALSE_EASTING), 700000.0 / kUsFoot, 1e-6);
  EXPECT_EQ(linear_unit(r.srs, "VERT_CS"), linear_unit(gdal, "VERT_CS"));
  // Not EPSG:26995 any more (metres): no code, as GDAL gives none.
  EXPECT_EQ(r.info.epsg, 0);
  EXPECT_EQ(gdal.GetAuthorityCode("PROJCS"), nullptr);
  EXPECT_EQ(r.srs.GetAuthorityCode("PROJCS"), nullptr);
}

TEST(GeoKeys, ProjLinearUnitEqualToTheCrsOwnChangesNothing) {
  const auto [gdal, r] = both("metre", {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 9001}});
  EXPECT_TRUE(r.srs.IsSame(&gdal)) << r.wkt;
  OGRSpatialReference epsg;
  ASSERT_EQ(epsg.importFromEPSG(26995), OGRERR_NONE);
  EXPECT_TRUE(r.srs.IsSame(&epsg)) << r.wkt;
  EXPECT_EQ(r.info.epsg, 26995);
  EXPECT_STREQ(r.srs.GetAuthorityCode("PROJCS"), "26995");
  EXPECT_EQ(linear_unit(r.srs), linear_unit(gdal));
  EXPECT_TRUE(r.info.notes.empty()) << testing::PrintToString(r.info.notes);
}

TEST(GeoKeys, UserDefinedLinearUnitTakesItsSizeFromProjLinearUnitSizeGeoKey) {
  // ProjLinearUnitsGeoKey 32767 and ProjLinearUnitSizeGeoKey 0.5 m, the first GeoDoubleParamsTag entry.
  const std::vector<Key> keys = {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 32767}, {3077, 34736, 1, 0}};
  const auto [gdal, r] = both("half_metre", keys, {0.5});
  EXPECT_TRUE(r.srs.IsSame(&gdal)) << r.wkt;
  EXPECT_EQ(linear_unit(r.srs), linear_unit(gdal));
  EXPECT_EQ(linear_unit(r.srs).second, 0.5);
  EXPECT_NEAR(r.srs.GetProjParm(SRS_PP_FALSE_EASTING), gdal.GetProjParm(SRS_PP_FALSE_EASTING), 1e-6);
  EXPECT_EQ(r.info.epsg, 0);
  // Without the doubles the size is unknown: the CRS keeps its metre, and a note says so.
  const Ours bare = ours(directory(keys), {});
  EXPECT_EQ(linear_unit(bare.srs).second, 1.0) << bare.wkt;
  EXPECT_EQ(bare.info.epsg, 26995);
  ASSERT_EQ(bare.info.notes.size(), 1u);
  EXPECT_NE(bare.info.notes[0].find("ProjLinearUnitSizeGeoKey"), std::string::npos) << bare.info.notes[0];
}

/// A LAS 1.2 file (PDRF 0, one point at the origin; ASPRS LAS 1.4 R15 table 3 offsets) whose
/// VLRs are the GeoKeyDirectoryTag `dir` ("LASF_Projection" 34735) and, when given, the
/// GeoDoubleParamsTag `doubles` (34736), section 2.5.2.
std::vector<std::uint8_t> las_with_geokeys(const std::vector<std::uint16_t>& dir, const std::vector<double>& doubles) {
  std::vector<std::vector<std::uint8_t>> vlrs = {bytes_of(dir)};
  if (!doubles.empty()) vlrs.push_back(bytes_of(doubles));
  std::vector<std::uint8_t> b(227, 0);
  std::memcpy(&b[0], "LASF", 4);
  b[24] = 1, b[25] = 2;
  store_at<std::uint16_t>(b, 94, 227);                                    // header size
  store_at<std::uint32_t>(b, 100, static_cast<std::uint32_t>(vlrs.size()));  // number of VLRs
  b[104] = 0;                                                             // PDRF 0
  store_at<std::uint16_t>(b, 105, 20);                                    // record length
  store_at<std::uint32_t>(b, 107, 1);                                     // legacy point count
  store_at<std::uint32_t>(b, 111, 1);                                     // one first return
  for (int k = 0; k < 3; ++k) store_at<double>(b, 131 + 8 * k, 0.01);    // scale; offset and bounds 0
  const std::uint16_t ids[2] = {34735, 34736};
  for (std::size_t v = 0; v < vlrs.size(); ++v) {
    const std::size_t at = b.size();
    b.resize(at + 54, 0);
    std::memcpy(&b[at + 2], "LASF_Projection", 15);
    store_at<std::uint16_t>(b, at + 18, ids[v]);
    store_at<std::uint16_t>(b, at + 20, static_cast<std::uint16_t>(vlrs[v].size()));
    b.insert(b.end(), vlrs[v].begin(), vlrs[v].end());
  }
  store_at<std::uint32_t>(b, 96, static_cast<std::uint32_t>(b.size()));  // offset to point data
  b.resize(b.size() + 20, 0);                                             // the point (0, 0, 0)
  b[b.size() - 20 + 14] = 0x09;                                           // return 1 of 1
  return b;
}

// The LAS reader hands the GeoDoubleParamsTag VLR to the GeoKeys: ProjLinearUnitsGeoKey 32767 with
// ProjLinearUnitSizeGeoKey 0.5 (its first double) reads as a unit of 0.5 m, as GDAL reads a GeoTIFF
// holding the same keys and doubles; without that VLR the CRS keeps its metre, with a note.
TEST(GeoKeys, LasReaderTakesTheUnitSizeFromItsGeoDoubleParamsVlr) {
  const std::vector<Key> keys = {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 32767}, {3077, 34736, 1, 0}};
  const fs::path tif = temp_dir() / "las_half_metre.tif";
  write_geotiff(tif, directory(keys), {0.5});
  const OGRSpatialReference gdal = gdal_crs(tif, false);
  ASSERT_EQ(linear_unit(gdal).second, 0.5) << "GDAL did not read the user-defined unit";

  io::FileInfo info;
  const PointCloud pc = io::read_point_cloud(las_with_geokeys(directory(keys), {0.5}), io::Format::las,
                                             "half_metre.las", {}, &info);
  ASSERT_EQ(pc.size(), 1u);
  EXPECT_EQ(info.crs_source, "GeoKeys");
  OGRSpatialReference srs;
  ASSERT_EQ(srs.importFromWkt(pc.crs_wkt.c_str()), OGRERR_NONE) << pc.crs_wkt;
  EXPECT_TRUE(srs.IsSame(&gdal)) << pc.crs_wkt;
  EXPECT_EQ(linear_unit(srs), linear_unit(gdal));
  EXPECT_NEAR(srs.GetProjParm(SRS_PP_FALSE_EASTING), gdal.GetProjParm(SRS_PP_FALSE_EASTING), 1e-6);
  EXPECT_EQ(info.epsg, 0);

  io::FileInfo bare_info;
  const PointCloud bare = io::read_point_cloud(las_with_geokeys(directory(keys), {}), io::Format::las,
                                               "no_doubles.las", {}, &bare_info);
  OGRSpatialReference bare_srs;
  ASSERT_EQ(bare_srs.importFromWkt(bare.crs_wkt.c_str()), OGRERR_NONE) << bare.crs_wkt;
  EXPECT_EQ(linear_unit(bare_srs).second, 1.0) << bare.crs_wkt;
  EXPECT_EQ(bare_info.epsg, 26995);
  EXPECT_TRUE(std::any_of(bare_info.notes.begin(), bare_info.notes.end(),
                          [](const std::string& n) { return n.find("ProjLinearUnitSizeGeoKey") != std::string::npos; }))
      << testing::PrintToString(bare_info.notes);
}

TEST(GeoKeys, GeogAngularUnitReplacesTheDegreeAsGdalReadsIt) {
  // NAD83 geographic in grads (EPSG 9105).
  const auto [gdal, r] = both("grad", {{1024, 0, 1, 2}, {2048, 0, 1, 4269}, {2054, 0, 1, 9105}});
  const char* ours_name = nullptr;
  const char* gdal_name = nullptr;
  const double ours_size = r.srs.GetAngularUnits(&ours_name), gdal_size = gdal.GetAngularUnits(&gdal_name);
  ASSERT_NE(gdal_name, nullptr);
  ASSERT_NE(ours_name, nullptr) << r.wkt;
  EXPECT_STREQ(ours_name, gdal_name);
  EXPECT_STREQ(ours_name, "grad");
  EXPECT_NEAR(ours_size, gdal_size, 1e-15);
}

TEST(GeoKeys, VerticalUnitOverridesTheUnitOfAnEpsgVerticalCrs) {
  // NAVD88 height (EPSG:5703, metres) with VerticalUnitsGeoKey = US survey foot. GDAL 3.6 keeps
  // the metre here; the heights are in feet, which is NAVD88 height (ftUS), EPSG:6360, in PROJ's
  // database: the oracle of this case.
  const Ours r = ours(directory({{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {4096, 0, 1, 5703}, {4099, 0, 1, 9003}}), {});
  ASSERT_TRUE(r.srs.IsCompound()) << r.wkt;
  EXPECT_EQ(r.info.epsg, 26995);
  EXPECT_EQ(r.info.vertical_epsg, 0);
  OGRSpatialReference ftus;
  ASSERT_EQ(ftus.importFromEPSG(6360), OGRERR_NONE);
  EXPECT_EQ(linear_unit(r.srs, "VERT_CS").first, linear_unit(ftus).first);
  EXPECT_NEAR(linear_unit(r.srs, "VERT_CS").second, linear_unit(ftus).second, 1e-15);
  EXPECT_STREQ(r.srs.GetAttrValue("VERT_DATUM"), ftus.GetAttrValue("VERT_DATUM"));
  // The same unit as the vertical CRS's own: EPSG:26995 + EPSG:5703 as they are.
  const Ours same = ours(directory({{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {4096, 0, 1, 5703}, {4099, 0, 1, 9001}}), {});
  OGRSpatialReference registered;
  ASSERT_EQ(registered.SetFromUserInput("EPSG:26995+5703"), OGRERR_NONE);
  EXPECT_TRUE(same.srs.IsSame(&registered)) << same.wkt;
  EXPECT_EQ(same.info.vertical_epsg, 5703);
}

TEST(GeoKeys, UnitCodesThatAreNoLinearUnitKeepTheCrsUnitWithANote) {
  // 9102 is the degree (angular), 1 no unit at all.
  for (const std::uint16_t code : {9102, 1}) {
    const Ours r = ours(directory({{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, code}}), {});
    EXPECT_EQ(linear_unit(r.srs), (std::pair<std::string, double>{"metre", 1.0})) << code;
    EXPECT_EQ(r.info.epsg, 26995);
    ASSERT_EQ(r.info.notes.size(), 1u) << code;
    EXPECT_NE(r.info.notes[0].find("ProjLinearUnitsGeoKey " + std::to_string(code) + " is not an EPSG linear unit"),
              std::string::npos)
        << r.info.notes[0];
  }
}

// ProjLinearUnitSizeGeoKey outside 1e-6 .. 1e6 m is no unit but a corrupt double: 1e-305 m would
// turn the false easting into infinity (WKT that GDAL cannot read back), 1e300 m put the points
// beyond the Earth. The CRS keeps its metre with the note a zero or NaN size gets; its WKT is then
// EPSG:26995's own (the oracle). Sizes at the range's ends are read as GDAL reads them.
TEST(GeoKeys, UserDefinedLinearUnitSizeOutsideTheRangeKeepsTheCrsUnit) {
  const std::vector<Key> keys = {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 32767}, {3077, 34736, 1, 0}};
  OGRSpatialReference epsg;
  ASSERT_EQ(epsg.importFromEPSG(26995), OGRERR_NONE);
  for (const double size : {5e-324, 1e-305, 1e-300, 1e-9, 9.99e-7, 1.001e6, 1e9, 1e300, 0.0, -1.0,
                            std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    const Ours r = ours(directory(keys), {size});
    OGRSpatialReference back;
    ASSERT_EQ(back.importFromWkt(r.wkt.c_str()), OGRERR_NONE) << size << ": " << r.wkt;
    EXPECT_TRUE(r.srs.IsSame(&epsg)) << size << ": " << r.wkt;
    EXPECT_EQ(linear_unit(r.srs), (std::pair<std::string, double>{"metre", 1.0})) << size;
    EXPECT_EQ(r.info.epsg, 26995) << size;
    ASSERT_EQ(r.info.notes.size(), 1u) << size;
    EXPECT_NE(r.info.notes[0].find("without a ProjLinearUnitSizeGeoKey of 1e-06 to 1e+06 m"), std::string::npos)
        << r.info.notes[0];
    EXPECT_NE(r.info.notes[0].find("the unit of EPSG:26995 kept"), std::string::npos) << r.info.notes[0];
  }
  for (const double size : {1e-6, 1e6}) {
    const auto [gdal, r] = both("size_" + std::to_string(size), keys, {size});
    EXPECT_EQ(linear_unit(r.srs).second, size) << r.wkt;
    EXPECT_TRUE(r.srs.IsSame(&gdal)) << r.wkt;
    EXPECT_NEAR(r.srs.GetProjParm(SRS_PP_FALSE_EASTING), gdal.GetProjParm(SRS_PP_FALSE_EASTING),
                1e-9 * std::abs(gdal.GetProjParm(SRS_PP_FALSE_EASTING)));
    EXPECT_EQ(r.info.epsg, 0);
  }
}

/// `b` written to `name` in the test's folder.
fs::path write_file(const std::string& name, const std::vector<std::uint8_t>& b) {
  const fs::path p = temp_dir() / name;
  std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  return p;
}

/// `rayscan info --json` of `p`, parsed.
nlohmann::json info_json(const fs::path& p) {
  const CommandResult info = run_command(std::string(RAYSCAN_EXE) + " info --json " + quoted(p), false);
  EXPECT_EQ(info.code, 0) << info.out;
  return nlohmann::json::parse(info.out);
}

// The LAS file of a 1e-305 m unit through the CLI: info reports EPSG:26995 in metres with the
// note, and translate writes a COPC file whose WKT GDAL reads as EPSG:26995.
TEST(GeoKeys, TranslateOfATinyUnitWritesWktGdalReads) {
  const std::vector<Key> keys = {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 32767}, {3077, 34736, 1, 0}};
  const fs::path las = write_file("tiny_unit.las", las_with_geokeys(directory(keys), {1e-305}));
  const nlohmann::json j = info_json(las);
  EXPECT_EQ(j["crs"]["epsg"], 26995) << j["crs"].dump();
  EXPECT_EQ(j["crs"]["horizontal_unit"], "metre") << j["crs"].dump();
  const fs::path copc = temp_dir() / "tiny_unit.copc.laz";
  const CommandResult t = run_command(std::string(RAYSCAN_EXE) + " translate -q " + quoted(las) + " " + quoted(copc));
  ASSERT_EQ(t.code, 0) << t.out;
  const nlohmann::json c = info_json(copc);
  OGRSpatialReference written, epsg;
  ASSERT_EQ(written.importFromWkt(c["crs"]["wkt"].get<std::string>().c_str()), OGRERR_NONE) << c["crs"].dump();
  ASSERT_EQ(epsg.importFromEPSG(26995), OGRERR_NONE);
  EXPECT_TRUE(written.IsSame(&epsg)) << c["crs"]["wkt"];
}

// A VerticalCSTypeGeoKey that names no vertical CRS (1: no CRS at all; 4326: a geographic one) is
// ignored with a note: the CRS is the projected one alone, as GDAL reads the same keys (with
// GTIFF_REPORT_COMPD_CS=YES, under which it reads a valid vertical code).
TEST(GeoKeys, VerticalCodeOfNoVerticalCrsIsIgnoredAsGdalIgnoresIt) {
  for (const std::uint16_t code : {1, 4326, 26995}) {
    const auto [gdal, r] = both("vert_" + std::to_string(code), {{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {4096, 0, 1, code}});
    ASSERT_FALSE(r.wkt.empty()) << code;
    EXPECT_FALSE(gdal.IsCompound()) << code;
    EXPECT_FALSE(r.srs.IsCompound()) << code << ": " << r.wkt;
    EXPECT_TRUE(r.srs.IsSame(&gdal)) << code << ": " << r.wkt;
    EXPECT_EQ(r.info.epsg, 26995);
    EXPECT_EQ(r.info.vertical_epsg, 0) << code;
    ASSERT_EQ(r.info.notes.size(), 1u) << code;
    EXPECT_EQ(r.info.notes[0].rfind("GeoKeys: VerticalCSTypeGeoKey " + std::to_string(code) + " ", 0), 0u)
        << r.info.notes[0];
    EXPECT_NE(r.info.notes[0].find(code == 1 ? "is unknown to the PROJ database: ignored" : "not a vertical one: ignored"),
              std::string::npos)
        << r.info.notes[0];
  }
}

// A ProjectedCSTypeGeoKey that names no projected CRS (5703, NAVD88 height: vertical, as PROJ's
// database has it; 65000: unknown) is ignored with a note: the CRS is GeographicTypeGeoKey's when
// there is one (EPSG:4269), else there is none and no EPSG code.
TEST(GeoKeys, ProjectedCodeOfNoProjectedCrsIsIgnored) {
  OGRSpatialReference navd88, nad83;
  ASSERT_EQ(navd88.importFromEPSG(5703), OGRERR_NONE);
  ASSERT_TRUE(navd88.IsVertical() && !navd88.IsProjected());
  ASSERT_EQ(nad83.importFromEPSG(4269), OGRERR_NONE);
  for (const std::uint16_t code : {5703, 65000}) {
    const Ours alone = ours(directory({{1024, 0, 1, 1}, {3072, 0, 1, code}}), {});
    EXPECT_EQ(alone.wkt, "") << code;
    EXPECT_EQ(alone.info.epsg, 0) << code;
    ASSERT_EQ(alone.info.notes.size(), 1u) << code;
    EXPECT_EQ(alone.info.notes[0].rfind("GeoKeys: ProjectedCSTypeGeoKey " + std::to_string(code) + " ", 0), 0u)
        << alone.info.notes[0];
    const Ours geog = ours(directory({{1024, 0, 1, 1}, {2048, 0, 1, 4269}, {3072, 0, 1, code}}), {});
    EXPECT_TRUE(geog.srs.IsSame(&nad83)) << geog.wkt;
    EXPECT_EQ(geog.info.epsg, 4269);
  }
}

// The same keys through the CLI: the text report, the JSON and the WKT translate writes all give
// the CRS without the ignored part ('NAD83 / Mississippi West (EPSG:26995)', no vertical_epsg,
// no VERT_CS), where they gave 'EPSG:26995 + EPSG:4326 vertical'; with ProjectedCSTypeGeoKey 5703,
// no CRS at all.
TEST(GeoKeys, IgnoredCodesAreLeftOutOfTheReportsAndTheWrittenWkt) {
  const fs::path las = write_file(
      "vert_geog.las", las_with_geokeys(directory({{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {4096, 0, 1, 4326}}), {}));
  const CommandResult text = run_command(std::string(RAYSCAN_EXE) + " info " + quoted(las), false);
  ASSERT_EQ(text.code, 0) << text.out;
  EXPECT_NE(text.out.find("CRS:               NAD83 / Mississippi West (EPSG:26995) from GeoKeys\n"), std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("VerticalCSTypeGeoKey 4326 (WGS 84) is a geographic CRS, not a vertical one: ignored"),
            std::string::npos)
      << text.out;
  const nlohmann::json j = info_json(las);
  EXPECT_EQ(j["crs"]["epsg"], 26995);
  EXPECT_FALSE(j["crs"].contains("vertical_epsg")) << j["crs"].dump();
  const fs::path copc = temp_dir() / "vert_geog.copc.laz";
  const CommandResult t = run_command(std::string(RAYSCAN_EXE) + " translate -q " + quoted(las) + " " + quoted(copc));
  ASSERT_EQ(t.code, 0) << t.out;
  OGRSpatialReference written, epsg;
  ASSERT_EQ(written.importFromWkt(info_json(copc)["crs"]["wkt"].get<std::string>().c_str()), OGRERR_NONE);
  ASSERT_EQ(epsg.importFromEPSG(26995), OGRERR_NONE);
  EXPECT_FALSE(written.IsCompound());
  EXPECT_TRUE(written.IsSame(&epsg));

  const fs::path vert = write_file("proj_vert.las", las_with_geokeys(directory({{1024, 0, 1, 1}, {3072, 0, 1, 5703}}), {}));
  const CommandResult none = run_command(std::string(RAYSCAN_EXE) + " info " + quoted(vert), false);
  ASSERT_EQ(none.code, 0) << none.out;
  EXPECT_NE(none.out.find("CRS:               none\n"), std::string::npos) << none.out;
  EXPECT_NE(none.out.find("ProjectedCSTypeGeoKey 5703 (NAVD88 height) is a vertical CRS, not a projected one: ignored"),
            std::string::npos)
      << none.out;
}

/// The GeoKeyDirectoryTag, GeoDoubleParamsTag and GeoAsciiParamsTag VLR payloads of a LAS file
/// (LAS 1.4 R15 section 2.5.2), read from its own bytes.
struct LasGeoKeys {
  std::vector<std::uint16_t> dir;
  std::vector<double> doubles;
  std::vector<std::uint8_t> ascii;
};

LasGeoKeys las_geokeys(const fs::path& p) {
  const std::vector<std::uint8_t> b = slurp(p);
  LasGeoKeys g;
  auto& [dir, doubles, ascii] = g;
  std::size_t at = load_at<std::uint16_t>(b, 94);
  const std::uint32_t n = load_at<std::uint32_t>(b, 100);
  for (std::uint32_t i = 0; i < n && at + 54 <= b.size(); ++i) {
    const char* user_id = reinterpret_cast<const char*>(&b[at + 2]);
    const std::string user(user_id, strnlen(user_id, 16));
    const std::uint16_t id = load_at<std::uint16_t>(b, at + 18), len = load_at<std::uint16_t>(b, at + 20);
    if (user == "LASF_Projection" && id == 34735)
      for (std::size_t k = 0; k < len / 2u; ++k) dir.push_back(load_at<std::uint16_t>(b, at + 54 + 2 * k));
    if (user == "LASF_Projection" && id == 34736)
      for (std::size_t k = 0; k < len / 8u; ++k) doubles.push_back(load_at<double>(b, at + 54 + 8 * k));
    if (user == "LASF_Projection" && id == 34737) ascii.assign(b.begin() + at + 54, b.begin() + at + 54 + len);
    at += 54 + len;
  }
  return g;
}

// mvk-thin.las: NAD83 / Mississippi West with its coordinates and heights in US survey feet
// (ProjLinearUnitsGeoKey, VerticalUnitsGeoKey 9003). `info` reports feet, and the site lies where
// PROJ puts the file's centre under GDAL's reading of the same keys: in Mississippi, not 700 km
// east of the false origin read as metres.
TEST(GeoKeys, MississippiFileInUsSurveyFeet) {
  RAYSCAN_REQUIRE_FILE(las, "las/mvk-thin.las");
  const CommandResult info = run_command(std::string(RAYSCAN_EXE) + " info --json " + quoted(las), false);
  ASSERT_EQ(info.code, 0) << info.out;
  const nlohmann::json j = nlohmann::json::parse(info.out);
  EXPECT_EQ(j["crs"]["source"], "GeoKeys");
  EXPECT_EQ(j["crs"]["horizontal_unit"], "US survey foot") << j["crs"].dump();
  EXPECT_EQ(j["crs"]["vertical_unit"], "US survey foot") << j["crs"].dump();
  EXPECT_FALSE(j["crs"].contains("epsg")) << j["crs"].dump();
  const Vec3 centre(0.5 * (j["bounds"]["min"][0].get<double>() + j["bounds"]["max"][0].get<double>()),
                    0.5 * (j["bounds"]["min"][1].get<double>() + j["bounds"]["max"][1].get<double>()), 0.0);

  // GDAL's reading of the file's own GeoKeys, and the centre's latitude and longitude under it.
  const LasGeoKeys keys = las_geokeys(las);
  ASSERT_FALSE(keys.dir.empty());
  const fs::path tif = temp_dir() / "mvk_keys.tif";
  write_geotiff(tif, keys.dir, keys.doubles, keys.ascii);
  OGRSpatialReference gdal = gdal_crs(tif, false), wgs84;
  ASSERT_EQ(wgs84.importFromEPSG(4326), OGRERR_NONE);
  gdal.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> to_geo(OGRCreateCoordinateTransformation(&gdal, &wgs84));
  ASSERT_NE(to_geo, nullptr);
  double lon = centre.x, lat = centre.y;
  ASSERT_TRUE(to_geo->Transform(1, &lon, &lat));
  EXPECT_NEAR(lat, 32.99, 0.05);
  EXPECT_NEAR(lon, -91.15, 0.05);

  const analysis::SiteLocation site = analysis::locate_site(j["crs"]["wkt"].get<std::string>(), centre);
  EXPECT_NEAR(site.latitude_deg, lat, 1e-9);
  EXPECT_NEAR(site.longitude_deg, lon, 1e-9);
  EXPECT_NEAR(site.metres_per_unit, kUsFoot, 1e-15);
}

// A COPC file translated from mvk-thin.las carries the foot CRS in its WKT VLR.
TEST(GeoKeys, TranslateWritesTheFootUnitIntoTheWkt) {
  RAYSCAN_REQUIRE_FILE(las, "las/mvk-thin.las");
  const fs::path copc = temp_dir() / "mvk-thin.copc.laz";
  const CommandResult t = run_command(std::string(RAYSCAN_EXE) + " translate -q " + quoted(las) + " " + quoted(copc));
  ASSERT_EQ(t.code, 0) << t.out;
  const CommandResult info = run_command(std::string(RAYSCAN_EXE) + " info --json " + quoted(copc), false);
  ASSERT_EQ(info.code, 0) << info.out;
  const nlohmann::json j = nlohmann::json::parse(info.out);
  EXPECT_EQ(j["crs"]["source"], "WKT VLR");
  OGRSpatialReference written;
  ASSERT_EQ(written.importFromWkt(j["crs"]["wkt"].get<std::string>().c_str()), OGRERR_NONE);
  EXPECT_EQ(linear_unit(written), (std::pair<std::string, double>{"US survey foot", linear_unit(written).second}));
  EXPECT_NEAR(linear_unit(written).second, kUsFoot, 1e-15);
  EXPECT_EQ(linear_unit(written, "VERT_CS").first, "US survey foot");
}

}  // namespace geokeys_test
}  // namespace rayscan::test
