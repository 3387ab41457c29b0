#include "rayscan/analysis/site_location.hpp"

#include "rayscan/io/crs.hpp"

#include <cpl_error.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace rayscan::analysis {

namespace {


struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
using Transform = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

// CPL's message of the last error, or a generic one.
std::string gdal_error() {
  const char* m = CPLGetLastErrorMsg();
  return (m && *m) ? std::string(m) : std::string("no message");
}

}  // namespace

void check_site_crs(const std::string& crs_wkt) {
  if (crs_wkt.empty()) throw std::invalid_argument("the cloud has no CRS: give the site's latitude and longitude");
  OGRSpatialReference src;
  CPLErrorReset();
  if (src.importFromWkt(crs_wkt.c_str()) != OGRERR_NONE)
    throw std::invalid_argument("the cloud's CRS: GDAL cannot parse its WKT (" + gdal_error() + ")");
  refuse_unprojected_crs(crs_wkt, "sun directions");
  // A local (engineering) frame may well be x east, y north, but has no place on the Earth.
  if (!src.IsProjected())
    throw std::invalid_argument("the cloud's CRS is not projected: no place on the Earth to find the sun from; "
                                "give the site's latitude and longitude");
}

SiteLocation locate_site(const std::string& crs_wkt, const Vec3& point) {
  check_site_crs(crs_wkt);
  OGRSpatialReference src;
  src.importFromWkt(crs_wkt.c_str());
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);  // x = longitude, y = latitude
  const Transform to_geo(OGRCreateCoordinateTransformation(&src, &wgs84));
  const Transform to_grid(OGRCreateCoordinateTransformation(&wgs84, &src));
  if (!to_geo || !to_grid)
    throw std::invalid_argument("the cloud's CRS: PROJ has no transformation to WGS 84 (" + gdal_error() + ")");
  SiteLocation loc;
  double x = point.x, y = point.y;
  if (!to_geo->Transform(1, &x, &y) || !std::isfinite(x) || !std::isfinite(y))
    throw std::invalid_argument("the cloud's CRS: PROJ cannot transform the site centre to WGS 84");
  loc.longitude_deg = x;
  loc.latitude_deg = y;
  // A short step due north, back in the grid: its bearing is the convergence.
  double nx = x, ny = std::min(90.0, y + 1e-5);
  if (!to_grid->Transform(1, &nx, &ny))
    throw std::invalid_argument("the cloud's CRS: PROJ cannot transform a point near the site back to the grid");
  loc.convergence_deg = std::atan2(nx - point.x, ny - point.y) / kDegree;
  const std::optional<io::LengthUnit> horizontal = io::crs_horizontal_unit(crs_wkt);
  const std::optional<io::LengthUnit> vertical = io::crs_vertical_unit(crs_wkt);
  loc.metres_per_unit = horizontal ? horizontal->metres : 1.0;
  loc.elevation_m = point.z * (vertical ? vertical->metres : 1.0);
  return loc;
}

void refuse_unprojected_crs(const std::string& crs_wkt, const std::string& need) {
  // Degrees are no frame for a length or a direction wherever the site is, so the remedy is a
  // projected CRS: the cloud reprojected, or, where the coordinates are projected already and the
  // file names the wrong CRS, the right one written in its place.
  if (is_unprojected_crs(crs_wkt))
    throw std::invalid_argument("the cloud's CRS is geographic or geocentric: " + need +
                                " need a projected CRS (x east, y north, z up); reproject the cloud (e.g. pdal "
                                "translate with filters.reprojection), or, if its coordinates are projected and "
                                "only the CRS is wrong, assign the right one (e.g. pdal translate with "
                                "--writers.las.a_srs)");
}

bool is_unprojected_crs(const std::string& crs_wkt) {
  if (crs_wkt.empty()) return false;
  OGRSpatialReference src;
  return src.importFromWkt(crs_wkt.c_str()) == OGRERR_NONE && (src.IsGeographic() || src.IsGeocentric());
}

Vec3 direction_from_azimuth(double azimuth_deg, double elevation_deg, double convergence_deg) {
  const double a = (azimuth_deg + convergence_deg) * kDegree, e = elevation_deg * kDegree;
  return {std::sin(a) * std::cos(e), std::cos(a) * std::cos(e), std::sin(e)};
}

}  // namespace rayscan::analysis
