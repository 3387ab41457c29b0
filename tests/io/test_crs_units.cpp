// The units of a CRS's lengths and heights (io::crs_horizontal_unit, io::crs_vertical_unit), for
// CRSs of every kind as GDAL builds them from the EPSG database, and a site's elevation in metres
// from them (analysis::locate_site). Oracle: the EPSG registry's units
// of those CRSs (the international foot is 0.3048 m, the US survey foot 1200/3937 m; EPSG:5703
// NAVD88 height and EPSG:5773 EGM96 height are in metres, EPSG:6360 NAVD88 height (ftUS) in US
// survey feet).
#include "rayscan/analysis/site_location.hpp"
#include "rayscan/io/crs.hpp"

#include "../common/crs_wkt.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <string>

namespace rayscan::test {
namespace crs_units_test {

constexpr double kFoot = 0.3048, kUsFoot = 1200.0 / 3937.0;

/// "name size" of a unit, "none" without one: one string for EXPECT_EQ's message.
std::string text(const std::optional<io::LengthUnit>& unit) {
  return unit ? unit->name + " " + std::to_string(unit->metres) : "none";
}

void expect_units(const std::string& wkt, const std::optional<io::LengthUnit>& horizontal,
                  const std::optional<io::LengthUnit>& vertical) {
  const std::optional<io::LengthUnit> h = io::crs_horizontal_unit(wkt), v = io::crs_vertical_unit(wkt);
  EXPECT_EQ(text(h), text(horizontal)) << wkt;
  EXPECT_EQ(text(v), text(vertical)) << wkt;
  if (h && horizontal) {
    EXPECT_NEAR(h->metres, horizontal->metres, 1e-15) << wkt;
  }
  if (v && vertical) {
    EXPECT_NEAR(v->metres, vertical->metres, 1e-15) << wkt;
  }
}

const io::LengthUnit kMetreUnit{"metre", 1.0}, kFootUnit{"foot", kFoot}, kUsFootUnit{"US survey foot", kUsFoot};

TEST(CrsUnits, ACompoundCrsHasTheHeightsInItsVerticalPartsUnit) {
  // x and y in feet, heights in metres; and the other way round, in US survey feet.
  expect_units(crs_wkt("EPSG:2992+5703"), kFootUnit, kMetreUnit);
  expect_units(crs_wkt("EPSG:32610+6360"), kMetreUnit, kUsFootUnit);
  // WKT2, which the writers keep as given: the same units.
  expect_units(crs_wkt("EPSG:2992+5703", "WKT2_2019"), kFootUnit, kMetreUnit);
}

TEST(CrsUnits, AProjectedCrsAloneHasTheHeightsInItsLinearUnit) {
  expect_units(crs_wkt("EPSG:2992"), kFootUnit, kFootUnit);
  expect_units(crs_wkt("EPSG:2255"), kUsFootUnit, kUsFootUnit);
  expect_units(crs_wkt("EPSG:32610"), kMetreUnit, kMetreUnit);
  expect_units(R"(LOCAL_CS["site",LOCAL_DATUM["site",0],UNIT["foot",0.3048],AXIS["E",EAST],AXIS["N",NORTH]])",
               kFootUnit, kFootUnit);
  expect_units(crs_wkt("EPSG:4978"), kMetreUnit, kMetreUnit);  // geocentric: x, y and z in metres
}

TEST(CrsUnits, DegreesAreNoLengthAndAVerticalCrsAloneHasNoHorizontalUnit) {
  expect_units(crs_wkt("EPSG:4326"), std::nullopt, std::nullopt);
  // 3D, ellipsoidal heights in metres (WKT2: GDAL writes no WKT1 of a 3D geographic CRS).
  expect_units(crs_wkt("EPSG:4979", "WKT2_2019"), std::nullopt, kMetreUnit);
  expect_units(crs_wkt("EPSG:4326+5773"), std::nullopt, kMetreUnit);
  expect_units(crs_wkt("EPSG:6360"), std::nullopt, kUsFootUnit);
}

TEST(CrsUnits, NoCrsTextGdalCannotReadAndAUnitOfNoSizeHaveNoUnit) {
  expect_units("", std::nullopt, std::nullopt);
  expect_units("not a WKT", std::nullopt, std::nullopt);
  // GDAL reads UNIT["foot",0] without complaint; a size of 0 is no unit to measure in.
  std::string zero = crs_wkt("EPSG:2992+5703");
  const std::string foot = R"(UNIT["foot",0.3048,)", metre = R"(UNIT["metre",1,)";
  ASSERT_NE(zero.find(foot), std::string::npos) << zero;
  ASSERT_NE(zero.rfind(metre), std::string::npos) << zero;
  zero.replace(zero.rfind(metre), metre.size(), R"(UNIT["metre",0,)");  // the vertical part's, the last
  expect_units(zero, kFootUnit, std::nullopt);
  // With the projected part's unit 0 too, GDAL cannot write the WKT1 it finds the vertical part in.
  zero.replace(zero.find(foot), foot.size(), R"(UNIT["foot",0,)");
  expect_units(zero, std::nullopt, std::nullopt);
  // The writers refuse to store such a CRS, naming the unit.
  std::string vertical_zero = crs_wkt("EPSG:2992+5703");
  vertical_zero.replace(vertical_zero.rfind(metre), metre.size(), R"(UNIT["metre",0,)");
  try {
    (void)io::crs_wkt_from_user_input(vertical_zero);
    ADD_FAILURE() << "a vertical unit of size 0 was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "the CRS has a vertical unit 'metre' of size 0 (expected a positive size)");
  }
}

TEST(CrsUnits, ASiteElevationIsTheHeightInTheVerticalUnit) {
  // z = 120 of a point of Oregon (EPSG:2992's area): 120 m under NAVD88 height, 120 ft without it.
  const Vec3 p(637000.0, 849000.0, 120.0);
  const analysis::SiteLocation compound = analysis::locate_site(crs_wkt("EPSG:2992+5703"), p);
  EXPECT_NEAR(compound.metres_per_unit, kFoot, 1e-15);
  EXPECT_NEAR(compound.elevation_m, 120.0, 1e-12);
  const analysis::SiteLocation projected = analysis::locate_site(crs_wkt("EPSG:2992"), p);
  EXPECT_NEAR(projected.metres_per_unit, kFoot, 1e-15);
  EXPECT_NEAR(projected.elevation_m, 120.0 * kFoot, 1e-12);
}

}  // namespace crs_units_test
}  // namespace rayscan::test
