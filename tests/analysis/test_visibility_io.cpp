// Visibility inputs and outputs: observer files, local ground, raster grid and reductions, the
// GeoTIFF read back through GDAL (geotransform, CRS, NoData, values), the PNG preview, and
// `rayscan visibility` end to end (fields in LAS/PLY, exit codes, no partial files).
#include "../common/crs_wkt.hpp"
#include "../common/file_size_limit.hpp"
#include "../common/sanitizers.hpp"
#include "../common/temp_dir.hpp"
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/analysis/observer.hpp"
#include "rayscan/analysis/raster.hpp"
#include "rayscan/analysis/raster_preview.hpp"
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/camera/camera_file.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/jobs/visibility.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "../common/run_command.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>
#include <sys/wait.h>

using namespace rayscan;
using namespace rayscan::analysis;
namespace fs = std::filesystem;

namespace {

fs::path tmpdir() {
  static const fs::path d = rayscan::test::process_temp_dir("rayscan_vis_test");
  return d;
}

fs::path write_text(const std::string& name, const std::string& text) {
  const fs::path p = tmpdir() / name;
  std::ofstream(p) << text;
  return p;
}

std::string error_of(const fs::path& p) {
  try {
    read_observers(p);
  } catch (const ObserverError& e) {
    return e.what();
  }
  return "";
}

using RunResult = rayscan::test::CommandResult;

/// Runs a shell command, capturing standard output and error.
RunResult run_cmd(const std::string& cmd) { return rayscan::test::run_command(cmd); }

// Removes the temporary folder when the test program ends.
class RemoveTmp : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(tmpdir(), ec);
  }
};
[[maybe_unused]] ::testing::Environment* const remove_tmp = ::testing::AddGlobalTestEnvironment(new RemoveTmp);

/// The Extra Bytes descriptors (LAS 1.4 R15 table 24, 192 bytes each) of the LAS file `las`, by
/// field name, read from the file's own bytes: its header's VLR offset and count, then each
/// LASF_Spec record 4.
std::map<std::string, std::string> extra_bytes_descriptors(const fs::path& las) {
  std::ifstream fin(las, std::ios::binary);
  const std::string b((std::istreambuf_iterator<char>(fin)), std::istreambuf_iterator<char>());
  const auto u32 = [&](std::size_t at) { std::uint32_t v; std::memcpy(&v, b.data() + at, 4); return v; };
  const auto u16 = [&](std::size_t at) { std::uint16_t v; std::memcpy(&v, b.data() + at, 2); return v; };
  std::map<std::string, std::string> desc;  // field name -> its 192-byte descriptor
  std::size_t pos = u16(94);
  for (std::uint32_t i = 0, n = u32(100); i < n; ++i) {
    const std::uint16_t len = u16(pos + 20);
    if (b.compare(pos + 2, 10, std::string("LASF_Spec\0", 10)) == 0 && u16(pos + 18) == 4)
      for (std::size_t k = 0; k + 192 <= len; k += 192) {
        const std::string d = b.substr(pos + 54 + k, 192);
        desc[std::string(d.c_str() + 4, strnlen(d.c_str() + 4, 32))] = d;
      }
    pos += 54 + len;
  }
  return desc;
}

/// The description of an Extra Bytes descriptor: bytes 160-191, NUL-padded (all 32 may be text).
std::string descriptor_description(const std::string& d) { return std::string(d.c_str() + 160, strnlen(d.c_str() + 160, 32)); }

bool has_temp_files(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(Observers, JsonAndCsv) {
  const fs::path j = write_text("obs.json", R"({"observers": [
    {"name": "mast", "position": [10, 20, 30], "azimuth": [315, 45], "elevation": [-10, 20]},
    {"position": [1.5, -2], "height": 1.7, "max_distance": 500}]})");
  const std::vector<Observer> o = read_observers(j);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[0].name, "mast");
  EXPECT_EQ(o[0].position, Vec3(10, 20, 30));
  EXPECT_TRUE(o[0].has_z);
  EXPECT_EQ(o[0].azimuth->lo, 315);
  EXPECT_EQ(o[0].elevation->hi, 20);
  EXPECT_FALSE(o[1].has_z);
  EXPECT_EQ(*o[1].height, 1.7);
  EXPECT_EQ(*o[1].max_distance, 500);
  EXPECT_EQ(read_observers(write_text("bare.json", R"([{"position": [1, 2, 3]}])")).size(), 1u);

  const fs::path c = write_text("obs.csv",
                                "# eyes\nname,x,y,z,height,azimuth_from,azimuth_to\n"
                                "a,1,2,3,,,\n\nb,4,5,,1.5,90,180\r\n");
  const std::vector<Observer> oc = read_observers(c);
  ASSERT_EQ(oc.size(), 2u);
  EXPECT_EQ(oc[0].position, Vec3(1, 2, 3));
  EXPECT_TRUE(oc[0].has_z);
  EXPECT_FALSE(oc[0].azimuth);
  EXPECT_EQ(oc[1].name, "b");
  EXPECT_FALSE(oc[1].has_z);
  EXPECT_EQ(*oc[1].height, 1.5);
  EXPECT_EQ(oc[1].azimuth->hi, 180);

  const Observer p = parse_observer("636480.5, 849020,12");
  EXPECT_EQ(p.position, Vec3(636480.5, 849020, 12));
  EXPECT_TRUE(p.has_z);
  EXPECT_FALSE(parse_observer("1,2").has_z);
}

TEST(Observers, ErrorsNameFileAndPlace) {
  auto err = [](const char* name, const char* text) { return error_of(write_text(name, text)); };
  EXPECT_NE(err("e1.csv", "x,y,z\n1,2,3\n1,abc,3\n")
                .find("e1.csv: line 3: column 'y': expected a finite number in [-1e+09, 1e+09] (world units), got 'abc'"),
            std::string::npos);
  EXPECT_NE(err("e2.csv", "x,y,zz\n").find("unknown column 'zz'"), std::string::npos);
  EXPECT_NE(err("e3.csv", "x,y,z\n1,2\n").find("line 2: expected 3 columns, got 2"), std::string::npos);
  EXPECT_NE(err("e4.csv", "x,y,z,height\n1,2,3,4\n").find("not both"), std::string::npos);
  EXPECT_NE(err("e5.json", R"([{"position": [1, 2, 3], "heigth": 2}])").find("/0/heigth: unknown key"),
            std::string::npos);
  EXPECT_NE(err("e6.json", R"([{"position": [1, 2, 3], "azimuth": [0, 400]}])").find("azimuth"), std::string::npos);
  EXPECT_NE(err("e7.json", R"([{"position": [1, 2, 3], "elevation": [30, 10]}])").find("elevation"),
            std::string::npos);
  EXPECT_EQ(err("e8.json", "[{\"position\": [1, 2, 3]}").rfind((tmpdir() / "e8.json").string() + ": byte 25: invalid JSON", 0), 0u)
      << err("e8.json", "[{\"position\": [1, 2, 3]}");
  EXPECT_NE(err("e9.json", "[]").find("lists no observer"), std::string::npos);
  EXPECT_NE(err("e10.json", R"([{"position": [1]}])").find("/0/position: expected"), std::string::npos);
  EXPECT_NE(err("e11.txt", "").find("empty file"), std::string::npos);
  EXPECT_NE(err("e12.yaml", "x").find("unknown observer file type"), std::string::npos);
  EXPECT_NE(error_of(tmpdir() / "missing.json").find("cannot open"), std::string::npos);
  EXPECT_THROW(parse_observer("1,2,3,4"), ObserverError);
  EXPECT_THROW(parse_observer("1,nan"), ObserverError);
}

// A key given twice is refused like an unknown one (the last would otherwise win silently), named
// by its JSON pointer.
TEST(Observers, DuplicateJsonKeysNameTheirPointer) {
  const fs::path a = write_text("dup.json", R"([{"position": [0.5, 0.5, 3], "position": [9, 9, 9]}])");
  EXPECT_EQ(error_of(a), a.string() + ": /0/position: duplicate key (given twice in the object /0; expected each key once)");
  const fs::path b = write_text("dup_list.json", R"({"observers": [{"position": [1, 2, 3]}, {"position": [1, 2],
    "height": 1, "name": "a", "name": "b"}]})");
  EXPECT_EQ(error_of(b),
            b.string() + ": /observers/1/name: duplicate key (given twice in the object /observers/1; expected each key once)");
  const fs::path c = write_text("dup_root.json", R"({"observers": [{"position": [1, 2, 3]}], "observers": []})");
  EXPECT_EQ(error_of(c), c.string() + ": /observers: duplicate key (given twice in the object /; expected each key once)");
}

// Coordinates and heights beyond +-1e9 (kMaxObserverCoordinate, --height's bound) are refused where
// they are read, naming the JSON pointer, the CSV line and column or the coordinate, rather than
// failing later inside a ray. 1e9 itself is accepted.
TEST(Observers, FarCoordinatesNameTheirField) {
  ASSERT_EQ(kMaxObserverCoordinate, 1e9);
  const std::string range = "expected a finite number in [-1e+09, 1e+09] (world units)";
  const fs::path j = write_text("far.json", R"([{"position": [1, 2, 3]}, {"position": [0.5, 1e300, 3]}])");
  EXPECT_EQ(error_of(j), j.string() + ": /1/position/1: " + range);
  const fs::path jh = write_text("far_h.json", R"({"observers": [{"position": [1, 2], "height": -2e9}]})");
  EXPECT_EQ(error_of(jh), jh.string() + ": /observers/0/height: " + range);
  const fs::path c = write_text("far.csv", "x,y,z\n1,2,3\n0.5,1e300,3\n");
  EXPECT_EQ(error_of(c), c.string() + ": line 3: column 'y': " + range + ", got '1e300'");
  const fs::path ch = write_text("far_h.csv", "x,y,height\n0.5,0.5,1e10\n");
  EXPECT_EQ(error_of(ch), ch.string() + ": line 2: column 'height': " + range + ", got '1e10'");
  EXPECT_EQ(read_observers(write_text("edge.csv", "x,y,z\n-1e9,1e9,1e9\n"))[0].position, Vec3(-1e9, 1e9, 1e9));
  try {
    parse_observer("0.5,1e160,3", "--observer '0.5,1e160,3'");
    ADD_FAILURE() << "no error";
  } catch (const ObserverError& e) {
    EXPECT_EQ(std::string(e.what()), "--observer '0.5,1e160,3': y: " + range + ", got '1e160'");
  }
  // Observers built in code (the Python module's arrays) are checked by validate_observer.
  Observer o;
  o.position = Vec3(0, 0, -1e12);
  o.has_z = true;
  try {
    validate_observer(o, "observers[0]");
    ADD_FAILURE() << "no error";
  } catch (const ObserverError& e) {
    EXPECT_EQ(std::string(e.what()), "observers[0]: z: " + range + ", got -1e+12");
  }
}

TEST(Observers, LocalGroundPrefersClassTwoAndSkipsNoise) {
  PointCloud c;
  c.positions = {{0, 0, 10}, {1, 0, 8}, {0, 1, 5}, {3, 0, 1}, {0.5, 0.5, 12}};
  c.classification = {2, 2, 7, 2, 5};  // the 5 is low noise; (3,0) is outside a radius of 2
  const AnyIndex idx = make_index(c.positions, IndexOptions{});
  EXPECT_EQ(local_ground(idx, c, 0, 0, 2.0), 8.0);
  c.classification = {1, 1, 7, 1, 5};  // no class 2 in reach: the lowest non-noise point
  EXPECT_EQ(local_ground(idx, c, 0, 0, 2.0), 8.0);
  c.classification.clear();  // unclassified: the lowest point
  EXPECT_EQ(local_ground(idx, c, 0, 0, 2.0), 5.0);
  EXPECT_TRUE(std::isnan(local_ground(idx, c, 50, 50, 2.0)));

  std::vector<Observer> obs{parse_observer("0,0"), parse_observer("0,0,100")};
  obs[0].height = 1.5;
  place_observers(obs, idx, c, GroundOptions{2.0, std::nullopt, std::nullopt});
  EXPECT_EQ(obs[0].position.z, 6.5);
  EXPECT_EQ(obs[0].ground_z, 5.0);
  EXPECT_EQ(obs[1].position.z, 100.0);
  std::vector<Observer> far{parse_observer("50,50")};
  try {
    place_observers(far, idx, c, GroundOptions{2.0, 1.7, std::nullopt});
    FAIL() << "expected ObserverError";
  } catch (const ObserverError& e) {
    EXPECT_NE(std::string(e.what()).find("observer 1: no point within the ground radius"), std::string::npos);
  }
  std::vector<Observer> no_height{parse_observer("0,0")};
  EXPECT_THROW(place_observers(no_height, idx, c, GroundOptions{2.0, std::nullopt, std::nullopt}), ObserverError);

  // Errors found while placing name the observer's file and JSON pointer / CSV line.
  auto place_error = [&](std::vector<Observer> v, std::optional<double> height) {
    try {
      place_observers(v, idx, c, GroundOptions{2.0, height, std::nullopt});
    } catch (const ObserverError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const fs::path pj = write_text("place.json", R"({"observers": [{"position": [0, 0, 9]}, {"position": [0, 0]}]})");
  EXPECT_EQ(place_error(read_observers(pj), std::nullopt).rfind(pj.string() + ": /observers/1: observer 2: no z and no height", 0), 0u)
      << place_error(read_observers(pj), std::nullopt);
  const fs::path pc = write_text("place.csv", "# eyes\nname,x,y,z\ntop,0,0,9\n\ntree,50,50,\n");
  EXPECT_EQ(place_error(read_observers(pc), 1.7).rfind(pc.string() + ": line 5: observer 'tree': no point within the ground radius", 0), 0u)
      << place_error(read_observers(pc), 1.7);
  EXPECT_EQ(place_error({parse_observer("0,0")}, std::nullopt).rfind("observer '0,0': observer 1: no z and no height", 0), 0u);
}

TEST(Raster, GridSnapsToCellMultiplesAndReduces) {
  const AABB box{Vec3(10.3, 20.1, 0), Vec3(14.9, 23.0, 5)};
  const GridSpec g = grid_over(box, 2.0);
  EXPECT_EQ(g.x0, 10.0);
  EXPECT_EQ(g.y_top, 24.0);  // floor(23 / 2) = 11 -> north edge 24; a point at y = 23 is in row 0
  EXPECT_EQ(g.cols, 3u);     // columns 10-12, 12-14, 14-16
  EXPECT_EQ(g.rows, 2u);     // rows 22-24, 20-22
  EXPECT_EQ(g.geotransform(), (std::array<double, 6>{10, 2, 0, 24, 0, -2}));
  const std::vector<Vec3> pts{{10.3, 23.0, 0}, {11.9, 22.0, 0}, {12.0, 21.9, 0}, {14.9, 20.1, 0}, {14.0, 20.5, 0}};
  const std::vector<double> v{1, 3, 5, 2, std::nan("")};
  Raster r = rasterize(pts, v, g, CellReduce::mean, "t");
  // (10.3,23) and (11.9,22) -> row 0 col 0; (12,21.9) -> row 1 col 1; (14.9,20.1), (14,20.5) -> row 1 col 2.
  EXPECT_EQ(r.values[0], 2.0f);
  EXPECT_TRUE(std::isnan(r.values[1]));
  EXPECT_TRUE(std::isnan(r.values[2]));
  EXPECT_EQ(r.values[4], 5.0f);
  EXPECT_EQ(r.values[5], 2.0f);  // NaN values are skipped
  EXPECT_EQ(rasterize(pts, v, g, CellReduce::max, "t").values[0], 3.0f);
  EXPECT_EQ(rasterize(pts, v, g, CellReduce::min, "t").values[0], 1.0f);
  // top: the value of the cell's highest point (a roof over the ground), whatever the order.
  const std::vector<Vec3> stacked{{10.3, 23.0, 1.0}, {10.5, 23.0, 7.0}, {11.0, 22.5, 3.0}, {10.4, 22.1, 7.0}};
  const std::vector<double> sv{10, 20, 30, 40};
  EXPECT_EQ(rasterize(stacked, sv, g, CellReduce::top, "t").values[0], 20.0f);  // z 7 first in point order
  EXPECT_THROW(grid_over(box, 0.0), std::invalid_argument);
  EXPECT_THROW(grid_over(box, 1e-6), std::invalid_argument);  // 4.6e6 x 2.9e6 cells
  EXPECT_THROW(rasterize(pts, std::vector<double>{1}, g, CellReduce::mean, "t"), std::invalid_argument);
}

TEST(GeoTiff, BandUnitIsTheGivenOneOrTheCrsLengthUnit) {
  // gdalinfo's "Unit Type" and QGIS's band unit: autzen's WKT says international feet, so a DSM's
  // elevations and a visibility distance are in "foot"; a given unit is written as given; without
  // a CRS a length has no unit to name.
  const PointCloud cloud = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las");
  const GridSpec g = grid_over(cloud.bounds(), 100.0);
  const Raster r = rasterize(cloud.positions, std::vector<double>(cloud.size(), 1.0), g, CellReduce::max, "v");
  GDALAllRegister();
  const auto unit_of = [&](const GeoTiffOptions& go) {
    const fs::path out = tmpdir() / "unit.tif";
    write_geotiff(out, r, go);
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(out.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    return ds ? std::string(ds->GetRasterBand(1)->GetUnitType()) : std::string("(not opened)");
  };
  GeoTiffOptions go;
  go.crs_wkt = cloud.crs_wkt;
  go.unit_is_crs_length = true;
  EXPECT_EQ(unit_of(go), "foot");
  go.unit_is_crs_length = false;
  go.unit = "kWh/m2";
  EXPECT_EQ(unit_of(go), "kWh/m2");
  go.unit.clear();
  EXPECT_EQ(unit_of(go), "");
  go.crs_wkt.clear();
  go.unit_is_crs_length = true;
  EXPECT_EQ(unit_of(go), "");
}

TEST(GeoTiff, BandOfHeightsCarriesTheCrsVerticalUnit) {
  // EPSG:2992+5703 (EPSG registry): x and y in international feet, NAVD88 heights in metres. A
  // band of heights (a DSM) is in metres, one of lengths (a distance) in feet; without a vertical
  // part the heights are in the one unit the CRS names. GDAL reads the unit back from the file.
  GridSpec g;
  g.cols = 2;
  g.rows = 1;
  g.cell = 3;
  const Raster r{g, {1.0f, 2.0f}, "z"};
  GDALAllRegister();
  const auto unit_of = [&](const GeoTiffOptions& go) {
    const fs::path out = tmpdir() / "height_unit.tif";
    write_geotiff(out, r, go);
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(out.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    return ds ? std::string(ds->GetRasterBand(1)->GetUnitType()) : std::string("(not opened)");
  };
  GeoTiffOptions go;
  go.crs_wkt = rayscan::test::crs_wkt("EPSG:2992+5703");
  go.unit_is_crs_height = true;
  EXPECT_EQ(unit_of(go), "metre");
  EXPECT_EQ(crs_height_unit(go.crs_wkt), "metre");
  go.unit_is_crs_height = false;
  go.unit_is_crs_length = true;
  EXPECT_EQ(unit_of(go), "foot");
  EXPECT_EQ(crs_length_unit(go.crs_wkt), "foot");
  go.crs_wkt = rayscan::test::crs_wkt("EPSG:2992");
  go.unit_is_crs_height = true;  // before unit_is_crs_length
  EXPECT_EQ(unit_of(go), "foot");
  EXPECT_EQ(crs_height_unit(go.crs_wkt), "foot");
  go.crs_wkt.clear();
  EXPECT_EQ(unit_of(go), "");
  EXPECT_EQ(crs_height_unit(""), "world units");
}

TEST(GeoTiff, ReopensWithGeotransformCrsNoDataAndValues) {
  const PointCloud cloud = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las");
  ASSERT_FALSE(cloud.crs_wkt.empty());
  const GridSpec g = grid_over(cloud.bounds(), 25.0);
  std::vector<double> z(cloud.size());
  for (std::size_t i = 0; i < z.size(); ++i) z[i] = cloud.positions[i].z;
  const Raster r = rasterize(cloud.positions, z, g, CellReduce::max, "highest z");
  const fs::path out = tmpdir() / "z.tif";
  GeoTiffOptions go;
  go.crs_wkt = cloud.crs_wkt;
  go.metadata = {{"RAYSCAN_VALUE", "z"}};
  write_geotiff(out, r, go);
  EXPECT_FALSE(has_temp_files(tmpdir()));

  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(out.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  ASSERT_TRUE(ds);
  EXPECT_STREQ(ds->GetDriverName(), "GTiff");
  EXPECT_EQ(ds->GetRasterXSize(), int(g.cols));
  EXPECT_EQ(ds->GetRasterYSize(), int(g.rows));
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  // autzen: x 636001.76..637179.22, y 848935.20..849497.90 ft -> snapped to 25 ft cells.
  EXPECT_EQ(gt[0], 636000.0);
  EXPECT_EQ(gt[1], 25.0);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[3], 849500.0);
  EXPECT_EQ(gt[4], 0.0);
  EXPECT_EQ(gt[5], -25.0);
  EXPECT_EQ(g.cols, 48u);  // 636000..637200
  EXPECT_EQ(g.rows, 23u);  // 848925..849500
  // GeoTIFF stores a CRS as GeoKeys (EPSG codes and projection parameters), so the datum comes
  // back under its EPSG name ("NAD83 (High Accuracy Reference Network)" for the file's
  // "NAD83_High_Accuracy_Regional_Network", both EPSG:6152): compare what defines the CRS.
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  ASSERT_TRUE(srs);
  OGRSpatialReference expect;
  ASSERT_EQ(expect.importFromWkt(cloud.crs_wkt.c_str()), OGRERR_NONE);
  ASSERT_TRUE(srs->IsProjected());
  EXPECT_STREQ(srs->GetAttrValue("PROJECTION"), expect.GetAttrValue("PROJECTION"));
  EXPECT_STREQ(srs->GetAttrValue("PROJECTION"), "Lambert_Conformal_Conic_2SP");
  for (const char* parm : {SRS_PP_STANDARD_PARALLEL_1, SRS_PP_STANDARD_PARALLEL_2, SRS_PP_LATITUDE_OF_ORIGIN,
                           SRS_PP_CENTRAL_MERIDIAN, SRS_PP_FALSE_EASTING, SRS_PP_FALSE_NORTHING})
    EXPECT_NEAR(srs->GetProjParm(parm, -1), expect.GetProjParm(parm, -2), 1e-9 * (1 + std::abs(expect.GetProjParm(parm)))) << parm;
  EXPECT_EQ(srs->GetLinearUnits(), 0.3048);  // international foot, as in the LAS file's WKT
  EXPECT_EQ(srs->GetLinearUnits(), expect.GetLinearUnits());
  EXPECT_STREQ(srs->GetAuthorityCode("GEOGCS|DATUM"), "6152");
  EXPECT_STREQ(srs->GetAuthorityCode("GEOGCS|DATUM"), expect.GetAuthorityCode("GEOGCS|DATUM"));
  EXPECT_NEAR(srs->GetSemiMajor(), expect.GetSemiMajor(), 1e-6);
  EXPECT_NEAR(srs->GetInvFlattening(), expect.GetInvFlattening(), 1e-9);
  EXPECT_EQ(srs->GetPrimeMeridian(), expect.GetPrimeMeridian());
  EXPECT_STREQ(ds->GetMetadataItem("RAYSCAN_VALUE"), "z");
  GDALRasterBand* band = ds->GetRasterBand(1);
  EXPECT_EQ(band->GetRasterDataType(), GDT_Float32);
  int has_nd = 0;
  EXPECT_EQ(band->GetNoDataValue(&has_nd), -9999.0);
  EXPECT_TRUE(has_nd);
  EXPECT_STREQ(band->GetDescription(), "highest z");
  std::vector<float> back(std::size_t(g.cols) * g.rows);
  ASSERT_EQ(band->RasterIO(GF_Read, 0, 0, int(g.cols), int(g.rows), back.data(), int(g.cols), int(g.rows),
                           GDT_Float32, 0, 0),
            CE_None);
  std::size_t nodata = 0;
  for (std::size_t k = 0; k < back.size(); ++k) {
    if (std::isnan(r.values[k])) {
      EXPECT_EQ(back[k], -9999.0f);
      ++nodata;
    } else {
      EXPECT_EQ(back[k], r.values[k]);
    }
  }
  EXPECT_GT(nodata, 0u);  // the trimmed site is not rectangular
  // The cell of the highest point holds its z (independent check of the row/column mapping).
  const auto top = std::max_element(z.begin(), z.end()) - z.begin();
  const Vec3 p = cloud.positions[std::size_t(top)];
  const int col = int(std::floor((p.x - gt[0]) / gt[1])), row = int(std::floor((p.y - gt[3]) / gt[5]));
  EXPECT_EQ(back[std::size_t(row) * g.cols + std::size_t(col)], float(p.z));

  // No CRS: geotransform only. A bad WKT is an error and leaves no file.
  write_geotiff(tmpdir() / "nocrs.tif", r, GeoTiffOptions{});
  std::unique_ptr<GDALDataset> d2(GDALDataset::Open((tmpdir() / "nocrs.tif").c_str(), GDAL_OF_RASTER));
  ASSERT_TRUE(d2);
  EXPECT_EQ(d2->GetSpatialRef(), nullptr);
  GeoTiffOptions bad;
  bad.crs_wkt = "PROJCS[garbage";
  EXPECT_THROW(write_geotiff(tmpdir() / "bad.tif", r, bad), std::invalid_argument);
  EXPECT_FALSE(fs::exists(tmpdir() / "bad.tif"));
  EXPECT_THROW(write_geotiff(tmpdir() / "no_such_dir" / "x.tif", r, go), std::runtime_error);
  EXPECT_FALSE(has_temp_files(tmpdir()));
}

TEST(RasterPreview, ColoursFollowTheRampAndNoData) {
  GridSpec g;
  g.cols = 3;
  g.rows = 2;
  g.cell = 1;
  Raster r{g, {0.0f, 0.5f, 1.0f, std::nanf(""), 2.0f, -1.0f}, "t"};
  const fs::path out = tmpdir() / "p.png";
  const std::string legend = write_raster_preview(out, r, 0.0, 1.0, "test");
  EXPECT_NE(legend.find("black 0"), std::string::npos);
  const Image img = read_image(out.string());
  const int s = 1024 / 3;  // px per cell
  EXPECT_EQ(img.height, 2 * s + 70);
  auto px = [&](int col, int row, int ch) { return img.at(col * s + s / 2, row * s + s / 2, ch); };
  EXPECT_EQ(px(0, 0, 0), 0.0f);                                  // 0 -> black
  EXPECT_NEAR(px(1, 0, 0), 1.0f, 1 / 255.0);                     // 0.5 -> between red and yellow
  EXPECT_NEAR(px(1, 0, 1), 0.5f, 1 / 255.0);
  EXPECT_EQ(px(2, 0, 2), 1.0f);                                  // 1 -> white
  EXPECT_NEAR(px(0, 1, 2), kNoDataRgb[2], 1 / 255.0);            // no data -> blue
  EXPECT_EQ(px(1, 1, 2), 1.0f);                                  // above the range clamps to white
  EXPECT_EQ(px(2, 1, 0), 0.0f);                                  // below clamps to black
  EXPECT_THROW(write_raster_preview(out, r, 1.0, 0.0, "t"), std::invalid_argument);
}

// Rewriting a GeoTIFF drops GDAL's sidecars of the old raster, as GDAL's Create does: the
// statistics gdalinfo -stats stored in path.aux.xml and the overviews gdaladdo -ro stored in
// path.ovr would otherwise be shown for the new values. Oracle: gdalinfo's own statistics.
TEST(GeoTiff, RewritingDropsTheOldRastersStatisticsAndOverviews) {
  GridSpec g;
  g.cols = 4;
  g.rows = 3;
  g.cell = 1;
  const fs::path tif = tmpdir() / "sidecar.tif";
  const fs::path aux = tif.string() + ".aux.xml", ovr = tif.string() + ".ovr";
  fs::remove(aux);
  fs::remove(ovr);
  const auto stats_mean = [&] {
    const RunResult r = rayscan::test::run_command("gdalinfo -json -stats '" + tif.string() + "'", false);
    EXPECT_EQ(r.code, 0) << r.out;
    return nlohmann::json::parse(r.out)["bands"][0]["mean"].get<double>();
  };
  write_geotiff(tif, Raster{g, std::vector<float>(12, 2.5f), "old"}, GeoTiffOptions{});
  EXPECT_DOUBLE_EQ(stats_mean(), 2.5);
  ASSERT_TRUE(fs::exists(aux));  // gdalinfo -stats stored them
  ASSERT_EQ(rayscan::test::run_command("gdaladdo -q -ro '" + tif.string() + "' 2", false).code, 0);
  ASSERT_TRUE(fs::exists(ovr));
  write_geotiff(tif, Raster{g, std::vector<float>(12, 7.0f), "new"}, GeoTiffOptions{});
  EXPECT_FALSE(fs::exists(aux));
  EXPECT_FALSE(fs::exists(ovr));
  EXPECT_DOUBLE_EQ(stats_mean(), 7.0);
  // A sidecar that cannot be removed (a folder of that name) fails the write and keeps the old file.
  fs::remove(aux);
  fs::create_directories(aux / "x");
  EXPECT_THROW(write_geotiff(tif, Raster{g, std::vector<float>(12, 9.0f), "new"}, GeoTiffOptions{}), OutputFileError);
  fs::remove_all(aux);
  EXPECT_DOUBLE_EQ(stats_mean(), 7.0);
  EXPECT_FALSE(has_temp_files(tmpdir()));
  fs::remove(aux);
}

// A GeoTIFF that cannot be written (a file-size limit: EFBIG, as a full disk gives ENOSPC) fails
// with one OutputFileError "<output>: <what>: <the system's cause>" whose code() is the errno,
// whatever GDAL said last (at 100 bytes "TIFFRewriteDirectory:Error fetching directory count",
// which has no cause; at 64 KiB a tile's failed write). The old file is kept and no temporary
// left. Oracle: strerror of the errno the limit gives.
TEST(GeoTiff, AFailedWriteNamesTheOutputAndTheSystemsCause) {
  GridSpec g;
  g.cols = 512;
  g.rows = 512;
  g.cell = 1;
  Raster r{g, std::vector<float>(std::size_t(g.cols) * g.rows), "noise"};
  std::uint32_t seed = 1;
  for (float& v : r.values) v = float((seed = seed * 1664525u + 1013904223u) >> 8);  // incompressible
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_geotiff_fail"), out = dir / "n.tif";
  for (const rlim_t limit : {rlim_t{100}, rlim_t{4096}, rlim_t{64 << 10}}) {
    SCOPED_TRACE(limit);
    std::ofstream(out) << "OLD";
    int code = 0;
    const std::string error = rayscan::test::error_within_file_size(limit, [&] {
      try {
        write_geotiff(out, r, GeoTiffOptions{});
      } catch (const OutputFileError& e) {
        code = e.code().value();
        throw;
      }
    });
    EXPECT_EQ(code, EFBIG) << error;
    EXPECT_EQ(rayscan::test::failure_names_only_output(error, out, ""), "");
  }
  fs::remove_all(dir);
}

// A constant map (lo == hi: an all-zero map of a polar night) is drawn in the colour its legend
// gives that value: the legend text's "black <lo>", the colour bar's first pixel (read from the
// same image; its pixels sample the ramp at their middles, hence 1/255); a value above it clamps
// to the bar's last.
TEST(RasterPreview, AConstantMapHasTheLegendsColourOfItsValue) {
  GridSpec g;
  g.cols = 2;
  g.rows = 1;
  g.cell = 1;
  for (const double lo : {0.0, 3.0}) {
    const Raster r{g, {float(lo), float(lo) + 1.0f}, "t"};
    const fs::path out = tmpdir() / "constant.png";
    const std::string legend = write_raster_preview(out, r, lo, lo, "constant");
    EXPECT_NE(legend.find(lo == 0.0 ? "black 0 " : "black 3 "), std::string::npos) << legend;
    const Image img = read_image(out.string());
    const int s = 1024 / 2, bar_y = int(g.rows) * s + kLegendBarTop + kLegendBarHeight / 2;
    const int bar_last = kLegendBarX + legend_bar_width(img.width) - 1;
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_EQ(img.at(s / 2, s / 2, ch), 0.0f) << lo << " " << ch;  // black
      EXPECT_NEAR(img.at(s / 2, s / 2, ch), img.at(kLegendBarX, bar_y, ch), 1.01 / 255) << lo << " " << ch;
      EXPECT_NEAR(img.at(s + s / 2, s / 2, ch), img.at(bar_last, bar_y, ch), 1.01 / 255) << lo << " " << ch;
    }
  }
}

// The legend names the cell size in the unit the GeoTIFF's band would (GDAL's name of the CRS's
// linear unit): US survey feet for EPSG:2255, "world units" without a CRS.
TEST(RasterPreview, CellSizeIsInTheCrsLinearUnit) {
  GridSpec g;
  g.cols = 2;
  g.rows = 1;
  g.cell = 3;
  const Raster r{g, {0.0f, 1.0f}, "t"};
  OGRSpatialReference srs;
  ASSERT_EQ(srs.importFromEPSG(2255), OGRERR_NONE);
  PreviewStyle style;
  style.crs_wkt = rayscan::test::srs_wkt(srs);
  ASSERT_FALSE(style.crs_wkt.empty());
  const char* unit = nullptr;
  srs.GetLinearUnits(&unit);
  const std::string feet = write_raster_preview(tmpdir() / "u.png", r, 0.0, 1.0, "t", style);
  EXPECT_NE(feet.find(" px per cell of 3 " + std::string(unit)), std::string::npos) << feet;
  EXPECT_EQ(std::string(unit), "US survey foot");
  const std::string none = write_raster_preview(tmpdir() / "n.png", r, 0.0, 1.0, "t");
  EXPECT_NE(none.find(" px per cell of 3 world units"), std::string::npos) << none;
  // The one statement of a length's unit name: GDAL's, or "world units" where it has none.
  EXPECT_EQ(crs_length_unit(style.crs_wkt), unit);
  EXPECT_EQ(crs_length_unit(""), "world units");
  EXPECT_EQ(crs_length_unit("not a WKT"), "world units");
}

// ---- `rayscan visibility` end to end.

class VisibilityCli : public ::testing::Test {
 protected:
  static std::string bin() { return RAYSCAN_BIN; }
  // A small scene as a PLY: 21 x 21 ground at spacing 1 (z = 0) and a 3-high wall at x = 5.
  static fs::path scene() {
    static const fs::path p = [] {
      PointCloud c;
      for (int x = -10; x <= 10; ++x)
        for (int y = -10; y <= 10; ++y) c.positions.push_back(Vec3(x, y, 0));
      for (int y = -10; y <= 10; ++y)
        for (int z = 1; z <= 3; ++z) c.positions.push_back(Vec3(5, y, z));
      const fs::path out = tmpdir() / "scene.ply";
      io::write_ply(out, c);
      return out;
    }();
    return p;
  }
};

// A distance map of a cloud without a CRS: the band has no unit (GDAL reads back none), and its
// description says in what the distances are and why.
TEST_F(VisibilityCli, DistanceMapWithoutCrsNamesWorldUnits) {
  const fs::path tif = tmpdir() / "no_crs_distance.tif";
  const RunResult r = run_cmd(bin() + " visibility " + scene().string() +
                              " --observer 0,0,2 --raster-value distance --cell 2 -q --raster " + tif.string());
  ASSERT_EQ(r.code, 0) << r.out;
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  ASSERT_TRUE(ds);
  EXPECT_STREQ(ds->GetRasterBand(1)->GetUnitType(), "");
  EXPECT_STREQ(ds->GetRasterBand(1)->GetDescription(),
               "distance to the nearest observer that sees the cell (world units; the cloud has no CRS)");
}

TEST_F(VisibilityCli, FieldsInLasAndPlyMatchTheLibrary) {
  const fs::path csv = write_text("cli_obs.csv", "x,y,height\n0,0,1.7\n-8,8,1.7\n");
  const fs::path las = tmpdir() / "out.las", ply = tmpdir() / "out.ply", tif = tmpdir() / "vis.tif";
  const std::string common = bin() + " visibility " + scene().string() + " --observers " + csv.string() +
                             " --radius 0.8 --primitive sphere --distance --sky-view 16 -q";
  RunResult r = run_cmd(common + " -o " + las.string() + " --raster " + tif.string() + " --cell 2 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\"visible_points\""), std::string::npos) << r.out;
  r = run_cmd(common + " -o " + ply.string());
  ASSERT_EQ(r.code, 0) << r.out;
  // -o .laz: the same LAS records through the LAZ (layered, LASzip 3) writer
  const fs::path laz = tmpdir() / "out.laz";
  r = run_cmd(common + " -o " + laz.string());
  ASSERT_EQ(r.code, 0) << r.out;
  {
    const io::LasRecords zl = io::read_las_records(laz), pl = io::read_las_records(las);
    EXPECT_TRUE(zl.compressed);
    EXPECT_FALSE(pl.compressed);
    EXPECT_EQ(zl.pdrf, pl.pdrf);
    EXPECT_TRUE(zl.records == pl.records);
    EXPECT_LT(fs::file_size(laz), fs::file_size(las));
  }
  EXPECT_TRUE(fs::exists(tmpdir() / "vis.png"));
  EXPECT_FALSE(has_temp_files(tmpdir()));

  // The library on the same input: ground under the eyes, then the line of sight.
  const PointCloud in = io::read_point_cloud(scene());
  const AnyIndex idx = make_index(in.positions, IndexOptions{});
  std::vector<Observer> obs = read_observers(csv);
  place_observers(obs, idx, in, GroundOptions{4.0, std::nullopt, std::nullopt});
  EXPECT_EQ(obs[0].position.z, 1.7);
  VisibilityOptions vo;
  vo.radius = 0.8;
  vo.tolerance = 1.6;
  vo.target_height = 0.8;
  const VisibilityResult res = compute_visibility(idx, in.positions, obs, vo);
  // Known answer: ground behind the 3-high wall (x > 6, |y| < 3) is hidden from the eye at the
  // origin, 1.7 above the ground.
  const VisibilityResult first = compute_visibility(idx, in.positions, std::span(obs.data(), 1), vo);
  for (std::size_t i = 0; i < in.size(); ++i)
    if (in.positions[i].z == 0 && in.positions[i].x > 6 && std::abs(in.positions[i].y) < 3) {
      EXPECT_EQ(first.count[i], 0u) << in.positions[i].x << "," << in.positions[i].y;
    }
  for (const fs::path& f : {las, ply, laz}) {
    const PointCloud out = io::read_point_cloud(f);
    ASSERT_EQ(out.size(), in.size()) << f;
    const ScalarField* cnt = out.scalar("visible_count");
    const ScalarField* dist = out.scalar("visible_distance");
    const ScalarField* sky = out.scalar("sky_view");
    ASSERT_TRUE(cnt && dist && sky) << f;
    std::size_t hidden = 0;
    for (std::size_t i = 0; i < in.size(); ++i) {
      EXPECT_EQ(cnt->values[i], res.count[i]) << f << " point " << i;
      EXPECT_DOUBLE_EQ(dist->values[i], res.nearest[i]) << f << " point " << i;
      EXPECT_GE(sky->values[i], 0.0);
      hidden += res.count[i] == 0;
    }
    EXPECT_GT(hidden, 0u);
  }

  // The LAS file describes its result fields (LAS 1.4 R15 table 24, from the file's own bytes):
  // visible_distance declares -1, the value of the points no observer sees, as its no-data value.
  std::map<std::string, std::string> desc = extra_bytes_descriptors(las);
  ASSERT_TRUE(desc.count("visible_distance") && desc.count("visible_count") && desc.count("sky_view"));
  const std::string& vd = desc["visible_distance"];
  EXPECT_EQ(vd[3] & 1, 1) << "no_data bit";
  double nd;
  std::memcpy(&nd, vd.data() + 40, 8);
  EXPECT_EQ(nd, -1.0);
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (res.count[i] == 0) {
      EXPECT_EQ(res.nearest[i], nd) << "point " << i;
    }
  }
  // The scene has no CRS: its lengths are in world units.
  EXPECT_EQ(descriptor_description(vd), "observer dist., world units");
  EXPECT_EQ(desc["visible_count"][3] & 1, 0) << "every count is a value";
  EXPECT_EQ(descriptor_description(desc["sky_view"]), "sky view factor, 0-1");
}

// `--json` lists the result fields the output carries, each with the unit, the description and
// the no-data value the output file gives it, as `solar --json` does; a field of the source cloud
// is no result field. Oracle: the PLY's own header (its "comment field" lines and properties) and the units as
// docs/visibility.md gives them.
TEST_F(VisibilityCli, JsonListsTheResultFieldsTheOutputFileDescribes) {
  PointCloud c = io::read_point_cloud(scene());
  std::vector<double> reflectance(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) reflectance[i] = double(i % 7);
  c.scalars.push_back({"reflectance", reflectance});
  const fs::path in = tmpdir() / "json_fields_in.ply", ply = tmpdir() / "json_fields.ply";
  io::write_ply(in, c);
  const RunResult r = rayscan::test::run_command(bin() + " visibility -q " + in.string() +
                                                     " --observer 0,0,1.7 --radius 0.8 --primitive sphere --distance "
                                                     "--sky-view 8 --json -o " + ply.string(),
                                                 false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  // The header: "comment field scalar_NAME: DESCRIPTION" for each described field, and which
  // scalar properties the file holds.
  std::map<std::string, std::string> described;
  std::vector<std::string> properties;
  std::ifstream f(ply, std::ios::binary);
  for (std::string line; std::getline(f, line) && line != "end_header";) {
    const std::string comment = "comment field scalar_", property = "property double scalar_";
    if (line.rfind(comment, 0) == 0) {
      const std::size_t colon = line.find(": ", comment.size());
      ASSERT_NE(colon, std::string::npos) << line;
      described[line.substr(comment.size(), colon - comment.size())] = line.substr(colon + 2);
    } else if (line.rfind(property, 0) == 0) {
      properties.push_back(line.substr(property.size()));
    }
  }
  EXPECT_EQ(properties, (std::vector<std::string>{"reflectance", "visible_count", "visible_distance", "sky_view"}));
  ASSERT_EQ(described.size(), 3u);
  ASSERT_TRUE(j.contains("fields")) << r.out;
  ASSERT_EQ(j["fields"].size(), described.size()) << r.out;
  for (const auto& [name, description] : described) {
    ASSERT_TRUE(j["fields"].contains(name)) << name << "\n" << r.out;
    // The comment is the descriptor's description, then "; no data -1" for visible_distance, the
    // one field with a no-data value.
    const bool no_data = name == "visible_distance";
    EXPECT_EQ(j["fields"][name]["description"].get<std::string>() + (no_data ? "; no data -1" : ""), description)
        << name;
    if (no_data) EXPECT_EQ(j["fields"][name]["no_data"], -1.0);
    else EXPECT_FALSE(j["fields"][name].contains("no_data")) << name;
  }
  EXPECT_FALSE(j["fields"].contains("reflectance"));
  EXPECT_EQ(j["fields"]["visible_count"]["unit"], "observers");
  EXPECT_EQ(j["fields"]["visible_distance"]["unit"], "world units");  // a length in a cloud without a CRS
  EXPECT_EQ(j["fields"]["sky_view"]["unit"], "1");
}

TEST_F(VisibilityCli, UserErrorsExitTwoAndWriteNothing) {
  const fs::path out = tmpdir() / "never.las";
  auto expect_error = [&](const std::string& args, const std::string& msg) {
    const RunResult r = run_cmd(bin() + " visibility " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(msg), std::string::npos) << args << "\n" << r.out;
    EXPECT_FALSE(fs::exists(out));
  };
  const std::string s = scene().string();
  expect_error(s + " -o " + out.string(), "nothing to compute");
  expect_error(s + " --observer 0,0,2 -o " + (tmpdir() / "x.e57").string(), "expected a file name ending in .las, .laz, .ply, .pcd, .xyz, .csv or .txt");
  expect_error(s + " --observer 0,0 -o " + out.string(), "--observer '0,0': observer 1: no z and no height");
  expect_error(s + " --observer 50,50 --height 2 -o " + out.string(), "no point within the ground radius");
  expect_error(s + " --observer 0,0,x -o " + out.string(), "is not a finite number");
  expect_error(s + " --observer 0.5,1e160,3 -o " + out.string(),
               "rayscan visibility: --observer '0.5,1e160,3': y: expected a finite number in [-1e+09, 1e+09] (world "
               "units), got '1e160'\n");
  expect_error(s + " --observers " + write_text("far_cli.csv", "x,y,z\n0.5,1e300,3\n").string() + " -o " + out.string(),
               "far_cli.csv: line 2: column 'y': expected a finite number in [-1e+09, 1e+09]");
  expect_error(s + " --observers " + write_text("dup_cli.json", R"([{"position": [0.5, 0.5, 3], "position": [9, 9, 9]}])").string() +
                   " -o " + out.string(),
               "dup_cli.json: /0/position: duplicate key");
  expect_error(s + " --observer 0,0 --height 1e10 -o " + out.string(), "--height: ");
  expect_error(s + " --observer 0,0,2 --raster " + (tmpdir() / "m.tif").string() + " -o " + out.string(), "--cell");
  expect_error(s + " --observer 0,0,2 --raster-value sky --raster " + (tmpdir() / "m.tif").string() +
                   " --cell 1 -o " + out.string(),
               "needs --sky-view");
  expect_error(s + " --observer 0,0,2 --radius -3 -o " + out.string(), "--radius: expected a finite number > 0");
  expect_error(s + " --observer 0,0,2 --cache lots -o " + out.string(), "--cache: ");
  expect_error((tmpdir() / "missing.las").string() + " --observer 0,0,2 -o " + out.string(), "missing.las");
  expect_error(s + " --from-camera " + (tmpdir() / "nocam.json").string() + " -o " + out.string(), "nocam.json");
  EXPECT_FALSE(fs::exists(tmpdir() / "m.tif"));
}

// `rayscan visibility --radius` and `rayscan solar --radius` refuse a radius with the line the
// jobs' own check gives for that value (check_options, the library call), its field written as the
// flag: one rule and one message whichever path refuses it. Before the cloud is read (it does not
// exist here). Text that is no number is named as given.
TEST_F(VisibilityCli, RadiusIsRefusedInTheJobsWords) {
  const std::string cloud = (tmpdir() / "radius_never_read.ply").string();
  const std::string out = (tmpdir() / "radius_never.las").string();
  const auto job_line = [](const std::string& command, const std::function<void()>& check) {
    try {
      check();
    } catch (const OptionError& e) {
      return "rayscan " + command + ": " + e.spelled([](std::string_view f) { return "--" + std::string(f); }) + "\n";
    }
    return std::string("(the job accepts it)");
  };
  const std::pair<const char*, double> values[] = {{"-3", -3.0}, {"0", 0.0}, {"-0.50", -0.5}, {"1e999", HUGE_VAL}};
  for (const auto& v : values) {
    jobs::VisibilityJobOptions vis;
    vis.cloud_file = cloud;
    vis.sky_rays = 4;
    vis.radius = v.second;
    const RunResult rv = run_cmd(bin() + " visibility " + cloud + " --sky-view 4 -o " + out + " --radius " + v.first);
    EXPECT_EQ(rv.code, 2) << v.first;
    EXPECT_EQ(rv.out, job_line("visibility", [&] { jobs::check_options(vis); })) << v.first;
    jobs::SolarJobOptions sol;
    sol.cloud_file = cloud;
    sol.latitude = 48.0;
    sol.longitude = 11.0;
    sol.at = "2026-06-21T12:00Z";
    sol.radius = v.second;
    const RunResult rs = run_cmd(bin() + " solar " + cloud + " --latitude 48 --longitude 11 --at 2026-06-21T12:00Z -o " +
                                 out + " --radius " + v.first);
    EXPECT_EQ(rs.code, 2) << v.first;
    EXPECT_EQ(rs.out, job_line("solar", [&] { jobs::check_options(sol); })) << v.first;
  }
  const RunResult text = run_cmd(bin() + " visibility " + cloud + " --sky-view 4 -o " + out + " --radius wide");
  EXPECT_EQ(text.code, 2);
  EXPECT_EQ(text.out, "rayscan visibility: --radius: expected a finite number > 0 (world units) or auto, got 'wide'\n");
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(VisibilityCli, OutputFoldersAreCheckedBeforeComputing) {
  const std::string s = scene().string();
  const fs::path missing = tmpdir() / "no_such_folder";
  fs::remove_all(missing);
  const fs::path file = write_text("plain_file.txt", "x");  // a file where a folder is expected
  auto expect_error = [&](const std::string& args, const std::string& msg) {
    // --sky-view 20000 on 500 points would take a while: the error must come first, and
    // "rayscan visibility:" progress lines must not appear.
    const RunResult r = run_cmd(bin() + " visibility " + s + " --sky-view 20000 " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(msg), std::string::npos) << args << "\n" << r.out;
    EXPECT_EQ(r.out.find("sky view"), std::string::npos) << args << "\n" << r.out;
  };
  expect_error("-o " + (missing / "v.las").string(), "-o '" + (missing / "v.las").string() + "': folder '" +
                                                          missing.string() + "' does not exist");  // (as given)
  expect_error("-o " + (file / "v.las").string(), "is not a folder");
  fs::create_directories(tmpdir() / "a_folder.las");
  expect_error("-o " + (tmpdir() / "a_folder.las").string(), "is a folder, expected a file name");
  expect_error("--raster " + (missing / "m.tif").string() + " --cell 1", "--raster '");
  expect_error("--raster " + (tmpdir() / "m2.tif").string() + " --cell 1 --preview " + (missing / "p.png").string(),
               "--preview '" + (missing / "p.png").string() + "': folder");
  EXPECT_FALSE(fs::exists(missing));
  EXPECT_FALSE(fs::exists(tmpdir() / "m2.tif"));
}

// The preview's default path (the raster's name with .png) is checked with the other outputs
// before any work: a folder there is refused before the DSM and the viewshed are computed, so the
// run logs none of their phases and writes no GeoTIFF. The same path given as --preview, and
// --no-preview, which writes no preview and so does not refuse the folder, frame it.
TEST_F(VisibilityCli, DefaultPreviewPathIsCheckedBeforeComputing) {
  const fs::path dir = tmpdir() / "default_preview";
  fs::remove_all(dir);
  fs::create_directories(dir / "viewshed.png");  // a folder where the default preview goes
  const fs::path tif = dir / "viewshed.tif", png = dir / "viewshed.png";
  const std::string base =
      bin() + " visibility " + scene().string() + " --observer 0,0,1.7 --cell 0.5 --raster " + tif.string();
  for (const std::string& extra : {std::string(), " --preview " + png.string()}) {
    const RunResult r = run_cmd(base + extra);
    EXPECT_EQ(r.code, 2) << extra << "\n" << r.out;
    EXPECT_NE(r.out.find("--preview '" + png.string() + "': is a folder, expected a file name"), std::string::npos)
        << extra << "\n" << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << extra << "\n" << r.out;
    EXPECT_EQ(r.out.find("DSM"), std::string::npos) << extra << "\n" << r.out;
    EXPECT_EQ(r.out.find("progress:"), std::string::npos) << extra << "\n" << r.out;
    EXPECT_FALSE(fs::exists(tif)) << extra;
  }
  const RunResult ok = run_cmd(base + " --no-preview -q");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::is_regular_file(tif));
  EXPECT_TRUE(fs::is_directory(png));
  fs::remove_all(dir);
}

TEST_F(VisibilityCli, FromCameraMarksThePointsItSees) {
  const fs::path cam = write_text("cam.json", R"({"width": 64, "height": 48, "position": [-9, 0, 4],
    "look_at": [5, 0, 1], "up": [0, 0, 1], "vfov_deg": 50})");
  const fs::path out = tmpdir() / "cam.ply";
  const RunResult r = run_cmd(bin() + " visibility " + scene().string() + " --from-camera " + cam.string() +
                          " --radius 0.6 -q -o " + out.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const PointCloud in = io::read_point_cloud(scene());
  const PointCloud pc = io::read_point_cloud(out);
  const ScalarField* hits = pc.scalar("camera_hits");
  ASSERT_TRUE(hits);
  const AnyIndex idx = make_index(in.positions, IndexOptions{});
  const std::vector<std::uint32_t> expect =
      count_pixel_hits(camera_first_hits(idx, io::load_camera(cam), 0.6), in.size());
  double total = 0;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    EXPECT_EQ(hits->values[i], expect[i]) << i;
    total += hits->values[i];
    // Nothing behind the wall (x > 5.5, low) is seen.
    if (in.positions[i].x > 5.5 && std::abs(in.positions[i].y) < 2) {
      EXPECT_EQ(hits->values[i], 0.0);
    }
  }
  EXPECT_GT(total, 64 * 48 / 4);
}

// The raster viewshed's two long phases report progress as the line of sight does: into a pipe
// (not a terminal) plain lines, the last at 100% -- the DSM's render ("tiles") and the viewshed
// over its rows ("rows", as many as the grid has, read from the job's own log line).
TEST_F(VisibilityCli, RasterViewshedReportsTheDsmAndViewshedProgress) {
  const fs::path tif = tmpdir() / "progress.tif";
  const RunResult r = run_cmd(bin() + " visibility " + scene().string() + " --observer 0,0,1.7 --raster " +
                              tif.string() + " --cell 0.5 --no-preview");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find('\r'), std::string::npos) << r.out;
  unsigned cols = 0, rows = 0;
  const std::size_t at = r.out.find("viewshed on the DSM (");
  ASSERT_NE(at, std::string::npos) << r.out;
  ASSERT_EQ(std::sscanf(r.out.c_str() + at, "viewshed on the DSM (%ux%u cells", &cols, &rows), 2) << r.out;
  const std::size_t tiles = std::size_t((cols + 15) / 16) * ((rows + 15) / 16);  // the render's 16 x 16 tiles
  const std::string n = std::to_string(tiles), m = std::to_string(rows);
  EXPECT_NE(r.out.find("progress: " + n + "/" + n + " tiles 100.0%"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("progress: " + m + "/" + m + " rows 100.0%"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(" cells/s  done in "), std::string::npos) << r.out;
  // -q: none of it.
  const RunResult q = run_cmd(bin() + " visibility -q " + scene().string() + " --observer 0,0,1.7 --raster " +
                              tif.string() + " --cell 0.5 --no-preview");
  ASSERT_EQ(q.code, 0) << q.out;
  EXPECT_EQ(q.out.find("progress:"), std::string::npos) << q.out;
}

// visible_distance's description names its unit, the CRS's linear unit: autzen's CRS is in
// international feet ("foot", as GDAL names the unit of its WKT: the oracle), within the
// descriptor's 32 bytes; --json gives the same unit and description, and the PLY the same comment.
TEST(VisibilityCliData, DistanceDescriptionNamesTheCrsUnit) {
  const fs::path las = tmpdir() / "autzen_vd.las", ply = tmpdir() / "autzen_vd.ply";
  const std::string cloud = std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las";
  std::string unit;
  {
    OGRSpatialReference srs;
    ASSERT_EQ(srs.importFromWkt(io::read_point_cloud(cloud).crs_wkt.c_str()), OGRERR_NONE);
    const char* name = nullptr;
    srs.GetLinearUnits(&name);
    ASSERT_NE(name, nullptr);
    unit = name;
  }
  EXPECT_EQ(unit, "foot");
  const std::string common = std::string(RAYSCAN_BIN) + " visibility -q " + cloud +
                             " --observer 636226.5,849106.5 --height 6 --distance --json -o ";
  RunResult r = rayscan::test::run_command(common + las.string(), false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const std::map<std::string, std::string> desc = extra_bytes_descriptors(las);
  ASSERT_TRUE(desc.count("visible_distance"));
  const std::string described = descriptor_description(desc.at("visible_distance"));
  EXPECT_EQ(described, "observer dist., " + unit);
  EXPECT_LE(described.size(), 32u);
  EXPECT_EQ(j["fields"]["visible_distance"]["unit"], unit);
  EXPECT_EQ(j["fields"]["visible_distance"]["description"], described);
  r = rayscan::test::run_command(common + ply.string(), false);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream f(ply, std::ios::binary);
  bool found = false;
  for (std::string line; std::getline(f, line) && line != "end_header";)
    found = found || line == "comment field scalar_visible_distance: " + described + "; no data -1";
  EXPECT_TRUE(found);
}

// A distance map names its unit where the GeoTIFF does: autzen's CRS is in international feet, and
// the band's unit as GDAL reads it back ("foot") ends the band description, the preview legend
// (the log line and the PNG's own bytes, where the legend is its description).
TEST(VisibilityCliData, DistanceMapNamesTheCrsUnitInItsLegend) {
  const fs::path tif = tmpdir() / "autzen_distance.tif", png = tmpdir() / "autzen_distance.png";
  const RunResult r = run_cmd(std::string(RAYSCAN_BIN) + " visibility " + RAYSCAN_TEST_DATA +
                              "/las/autzen_trim.las --observer 636226.5,849106.5 --height 6 --raster-value "
                              "distance --raster " + tif.string() + " --cell 20");
  ASSERT_EQ(r.code, 0) << r.out;
  GDALAllRegister();
  std::string unit, description;
  {
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(ds);
    unit = ds->GetRasterBand(1)->GetUnitType();
    description = ds->GetRasterBand(1)->GetDescription();
  }
  EXPECT_EQ(unit, "foot");
  const std::string title = "distance to the nearest observer that sees the cell (" + unit + ")";
  EXPECT_EQ(description, title);
  EXPECT_NE(r.out.find("preview legend: " + title + ": black 0 -> "), std::string::npos) << r.out;
  std::ifstream in(png, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(bytes.find(title + ": black 0 -> "), std::string::npos);
  EXPECT_EQ(r.out.find("warning:"), std::string::npos) << r.out;  // a CRS that fits the coordinates
}

// A CRS that cannot describe the coordinates (geographic WGS 84 over coordinates in the millions)
// is copied into the GeoTIFFs of `visibility --raster` (camera marks: a line of sight refuses a
// geographic CRS) and `render --ortho-map` with the warning `rayscan info` gives for the file, word
// for word (the oracle: info's own "warning:" line).
TEST_F(VisibilityCli, ImplausibleCrsIsWarnedAsInfoWarnsIt) {
  PointCloud c = io::read_point_cloud(scene());
  for (Vec3& p : c.positions) p += Vec3(515000.0, 4918000.0, 0.0);
  c.crs_wkt = rayscan::test::crs_wkt("EPSG:4326");
  ASSERT_FALSE(c.crs_wkt.empty());
  const fs::path ply = tmpdir() / "wgs84_projected.ply";
  io::write_ply(ply, c);
  const RunResult info = run_cmd(bin() + " info " + ply.string());
  ASSERT_EQ(info.code, 0) << info.out;
  const std::size_t w = info.out.find("warning:");
  ASSERT_NE(w, std::string::npos) << info.out;
  const std::size_t text = info.out.find_first_not_of(' ', w + 8);
  const std::string warning = info.out.substr(text, info.out.find('\n', text) - text);
  EXPECT_NE(warning.find("the CRS is geographic"), std::string::npos) << warning;
  const fs::path cam = write_text("cam_wgs84.json", R"({"width": 32, "height": 24, "position": [514991, 4918000, 4],
    "look_at": [515005, 4918000, 1], "up": [0, 0, 1], "vfov_deg": 50})");
  const RunResult vis = run_cmd(bin() + " visibility " + ply.string() + " --from-camera " + cam.string() +
                                " --raster " + (tmpdir() / "wgs84_vis.tif").string() + " --cell 1 --no-preview");
  ASSERT_EQ(vis.code, 0) << vis.out;
  EXPECT_NE(vis.out.find("rayscan visibility: warning: " + warning + "; the GeoTIFF carries it as it is\n"),
            std::string::npos) << vis.out;
  const RunResult ortho = run_cmd(bin() + " render " + ply.string() + " --ortho-map 1 --out " +
                                  (tmpdir() / "wgs84_ortho.tif").string());
  ASSERT_EQ(ortho.code, 0) << ortho.out;
  EXPECT_NE(ortho.out.find("rayscan render: warning: " + warning + "; the GeoTIFF carries it as it is\n"),
            std::string::npos) << ortho.out;
  // Without a GeoTIFF nothing copies the CRS: no warning.
  const RunResult las = run_cmd(bin() + " visibility " + ply.string() + " --from-camera " + cam.string() + " -o " +
                                (tmpdir() / "wgs84_vis.las").string());
  ASSERT_EQ(las.code, 0) << las.out;
  EXPECT_EQ(las.out.find("warning:"), std::string::npos) << las.out;
}

// A line of sight and a sky view need x east, y north and z up in one unit: on a cloud whose CRS
// is geographic (EPSG:4326: x, y in degrees, z in metres) `rayscan visibility` refuses them in one
// line, from the LAS header before any point is read (its x scale is made 1e308 after writing, so
// reading a point would fail: `rayscan info` is the oracle for that), with `rayscan solar`'s
// wording on the same file but for what it needs; from a PLY, whose CRS comes with its points,
// after reading them. The same points in UTM zone 10N (EPSG:32610, transformed by GDAL/PROJ) run,
// and their viewshed carries that CRS as gdalinfo's library reads it back. Camera marks, the
// render's first hits, run on the geographic cloud too.
TEST_F(VisibilityCli, AGeographicCrsIsRefusedForLinesOfSightAndSkyView) {
  PointCloud utm = io::read_point_cloud(scene());
  for (Vec3& p : utm.positions) p += Vec3(494500.0, 4877500.0, 120.0);
  OGRSpatialReference utm_srs, wgs84;
  ASSERT_EQ(utm_srs.importFromEPSG(32610), OGRERR_NONE);
  ASSERT_EQ(wgs84.importFromEPSG(4326), OGRERR_NONE);
  utm_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);  // x = longitude, y = latitude
  utm.crs_wkt = rayscan::test::srs_wkt(utm_srs);
  PointCloud geo = utm;
  geo.crs_wkt = rayscan::test::srs_wkt(wgs84);
  {
    std::unique_ptr<OGRCoordinateTransformation> to_geo(OGRCreateCoordinateTransformation(&utm_srs, &wgs84));
    ASSERT_TRUE(to_geo);
    for (Vec3& p : geo.positions) {
      double x = p.x, y = p.y;
      ASSERT_TRUE(to_geo->Transform(1, &x, &y));
      p.x = x;
      p.y = y;
    }
  }
  ASSERT_NEAR(geo.positions[0].x, -123.07, 0.01);
  ASSERT_NEAR(geo.positions[0].y, 44.05, 0.01);
  const fs::path geo_las = tmpdir() / "geographic.las", poisoned = tmpdir() / "geographic_poisoned.las",
                 geo_ply = tmpdir() / "geographic.ply", utm_las = tmpdir() / "utm.las";
  io::LasWriteOptions degrees;  // 1e-7 degrees is about a centimetre; the default would be coarser
  degrees.scale = Vec3(1e-7, 1e-7, 0.001);
  io::write_point_cloud(geo_las, geo, degrees);
  io::write_point_cloud(poisoned, geo, degrees);
  io::write_ply(geo_ply, geo);
  io::write_point_cloud(utm_las, utm);
  {
    std::fstream f(poisoned, std::ios::in | std::ios::out | std::ios::binary);
    const double scale = 1e308;
    f.seekp(131);  // the header's x scale factor (LAS 1.2-1.4), little-endian float64
    f.write(reinterpret_cast<const char*>(&scale), sizeof scale);
  }
  const RunResult info = run_cmd(bin() + " info " + poisoned.string());
  ASSERT_EQ(info.code, 2) << info.out;
  ASSERT_NE(info.out.find("the coordinate bound"), std::string::npos) << info.out;

  const fs::path out = tmpdir() / "geographic_out.las", tif = tmpdir() / "geographic_vs.tif";
  const std::string eye = " --observer " + std::to_string(geo.positions[0].x) + "," +
                          std::to_string(geo.positions[0].y) + " --height 1.7";
  const std::string refusal = "the cloud's CRS is geographic or geocentric: ";
  const std::string lines = "line-of-sight heights and distances", sky = "sky view directions";
  // {arguments, what is named as needing a projected CRS, whether the header tells the CRS}
  const std::tuple<std::string, std::string, bool> refused[] = {
      {poisoned.string() + eye + " --raster " + tif.string() + " --cell 1", lines, true},
      {poisoned.string() + eye + " -o " + out.string(), lines, true},
      {poisoned.string() + eye + " --sky-view 8 -o " + out.string(), lines, true},
      {poisoned.string() + " --sky-view 8 -o " + out.string(), sky, true},
      {geo_ply.string() + eye + " -o " + out.string(), lines, false},
      {geo_ply.string() + " --sky-view 8 --raster " + tif.string() + " --cell 1", sky, false}};
  // The wording is solar's, need for need: its refusal of the same file with "sun directions".
  const RunResult solar = run_cmd(bin() + " solar " + poisoned.string() + " --at 2026-06-21T12:00Z -o " + out.string());
  ASSERT_EQ(solar.code, 2) << solar.out;
  const std::string solar_prefix = "rayscan solar: " + refusal + "sun directions";
  ASSERT_EQ(solar.out.rfind(solar_prefix, 0), 0u) << solar.out;
  const std::string remedy = solar.out.substr(solar_prefix.size());
  EXPECT_NE(remedy.find(" need a projected CRS (x east, y north, z up); reproject the cloud"), std::string::npos)
      << remedy;
  for (const auto& [args, need, from_header] : refused) {
    const RunResult r = run_cmd(bin() + " visibility " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    const std::string line = "rayscan visibility: " + refusal + need + remedy;
    // From the header the refusal is all there is; from a PLY it follows the read's log lines.
    if (from_header) EXPECT_EQ(r.out, line) << args;
    else EXPECT_TRUE(r.out.size() > line.size() && r.out.ends_with("\n" + line)) << args << "\n" << r.out;
    EXPECT_FALSE(fs::exists(out)) << args;
    EXPECT_FALSE(fs::exists(tif)) << args;
  }

  // The same points in UTM: the viewshed runs and carries EPSG:32610.
  const RunResult u = run_cmd(bin() + " visibility " + utm_las.string() + " --observer 494500,4877500 --height 1.7 " +
                              "--sky-view 8 --raster " + tif.string() + " --cell 1 --no-preview -o " + out.string());
  ASSERT_EQ(u.code, 0) << u.out;
  EXPECT_EQ(u.out.find("CRS is geographic"), std::string::npos) << u.out;
  GDALAllRegister();
  {
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(ds);
    const OGRSpatialReference* srs = ds->GetSpatialRef();
    ASSERT_TRUE(srs);
    ASSERT_NE(srs->GetAuthorityCode(nullptr), nullptr);
    EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "32610");
  }
  ASSERT_TRUE(io::read_point_cloud(out).scalar("sky_view"));

  // Camera marks on the geographic cloud: the first hits of the render's image, allowed as it is.
  fs::remove(out);
  const fs::path cam = write_text("cam_geographic.json", R"({"width": 32, "height": 24, "position": [)" +
                                                              std::to_string(geo.positions[0].x) + ", " +
                                                              std::to_string(geo.positions[0].y) +
                                                              R"(, 130], "look_at": [)" +
                                                              std::to_string(geo.positions[300].x) + ", " +
                                                              std::to_string(geo.positions[300].y) +
                                                              R"(, 120], "up": [0, 0, 1], "vfov_deg": 50})");
  const RunResult c = run_cmd(bin() + " visibility -q " + geo_las.string() + " --from-camera " + cam.string() + " -o " +
                              out.string());
  ASSERT_EQ(c.code, 0) << c.out;
  ASSERT_TRUE(io::read_point_cloud(out).scalar("camera_hits"));
}

// A camera whose marks cannot be allocated (4 bytes a pixel: 16 GiB for 65536 x 65536) is refused
// before the cloud is read, naming the camera file, as `render` refuses such an image: here under
// a 4000000 KiB address-space limit (ulimit -v), which is 3.8 GiB.
TEST_F(VisibilityCli, FromCameraRefusesMarksBeyondTheMemoryLimit) {
  if (rayscan::test::kSanitized) GTEST_SKIP() << "a sanitizer reserves its shadow memory beyond any ulimit -v";
  const fs::path cam = write_text("cam_huge.json", R"({"width": 65536, "height": 65536, "position": [-9, 0, 4],
    "look_at": [5, 0, 1], "up": [0, 0, 1], "vfov_deg": 50})");
  const fs::path out = tmpdir() / "cam_huge.ply";
  const RunResult r = run_cmd("ulimit -v 4000000 && " + bin() + " visibility " + scene().string() +
                              " --from-camera " + cam.string() + " -o " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan visibility: " + cam.string() +
                       ": an image of 65536 x 65536 pixels (a 4-byte point index a pixel) needs about 16.0 GiB of "
                       "buffers, more than the 3.8 GiB of address space this process may use (ulimit -v); give a "
                       "smaller width and height in the camera file\n");
  EXPECT_FALSE(fs::exists(out));
}

TEST(Observers, InnerGroundRadiusKeepsTheEyeOnASlope) {
  // A 1:2 slope z = x / 2 (points every 0.5): the lowest point within 4.9 of (10, 0) lies downhill
  // at x = 5.5 (z 2.75); with an inner radius of 0.3 the ground is the point under the eye (z 5).
  // An inner radius holding no point (between the samples) falls back to the outer radius.
  PointCloud c;
  for (int a = 0; a <= 40; ++a)
    for (int b = -4; b <= 4; ++b) c.positions.push_back({0.5 * a, 0.5 * b, 0.25 * a});
  const AnyIndex idx = make_index(c.positions, IndexOptions{});
  std::vector<Observer> obs{parse_observer("10,0")};
  obs[0].height = 1.5;
  std::vector<Observer> outer = obs, inner = obs, fallback{parse_observer("10.25,0.25")};
  fallback[0].height = 1.5;
  place_observers(outer, idx, c, GroundOptions{4.9, std::nullopt, std::nullopt});
  EXPECT_DOUBLE_EQ(outer[0].ground_z, 2.75);
  place_observers(inner, idx, c, GroundOptions{4.9, std::nullopt, 0.3});
  EXPECT_DOUBLE_EQ(inner[0].ground_z, 5.0);
  EXPECT_DOUBLE_EQ(inner[0].position.z, 6.5);
  place_observers(fallback, idx, c, GroundOptions{4.9, std::nullopt, 0.3});  // nearest point 0.35 away
  EXPECT_DOUBLE_EQ(fallback[0].ground_z, 2.75);  // lowest within 4.9 of (10.25, 0.25): x = 5.5
}
