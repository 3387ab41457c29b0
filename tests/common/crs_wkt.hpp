// Test helper for the tests that give a cloud, a raster or a parser a registered CRS: its WKT as
// GDAL writes it from its own EPSG database, not through rayscan's CRS code. Needs GDAL (GDAL::GDAL)
// and GoogleTest.
#pragma once

#include <cpl_conv.h>
#include <ogr_spatialref.h>

#include <gtest/gtest.h>

#include <string>

namespace rayscan::test {

/// The WKT of `srs` as OGRSpatialReference::exportToWkt writes it in `format` ("WKT1", GDAL's
/// default for a CRS WKT1 can express; "WKT2_2019" for one it cannot, such as EPSG:4979). The axis
/// mapping strategy is not part of it. A CRS GDAL cannot write so fails the calling test and
/// gives "".
inline std::string srs_wkt(const OGRSpatialReference& srs, const char* format = "WKT1") {
  const std::string option = std::string("FORMAT=") + format;
  const char* const options[] = {option.c_str(), nullptr};
  char* text = nullptr;
  EXPECT_EQ(srs.exportToWkt(&text, options), OGRERR_NONE) << format;
  std::string wkt = text != nullptr ? text : "";
  CPLFree(text);
  return wkt;
}

/// The WKT, in `format` (as srs_wkt), of the CRS `definition` names: anything
/// OGRSpatialReference::SetFromUserInput reads, such as "EPSG:32610" or the compound
/// "EPSG:2992+5703". A definition GDAL cannot read fails the calling test and gives "".
inline std::string crs_wkt(const std::string& definition, const char* format = "WKT1") {
  OGRSpatialReference srs;
  const OGRErr read = srs.SetFromUserInput(definition.c_str());
  EXPECT_EQ(read, OGRERR_NONE) << definition;
  return read == OGRERR_NONE ? srs_wkt(srs, format) : std::string();
}

}  // namespace rayscan::test
