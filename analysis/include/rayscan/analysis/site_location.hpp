// Where on Earth a scanned site lies, from its CRS: the latitude and longitude the sun position
// needs, and the angle between grid north and true north (the meridian convergence) that turns a
// compass azimuth into a direction in the cloud's own x, y frame.
#pragma once

#include "rayscan/analysis/angles.hpp"
#include "rayscan/octree/geometry.hpp"

#include <numbers>
#include <string>

namespace rayscan::analysis {

/// A site's place on the WGS 84 ellipsoid and the orientation of its projected grid there.
struct SiteLocation {
  double latitude_deg = 0.0;    ///< WGS 84 latitude, degrees north
  double longitude_deg = 0.0;   ///< WGS 84 longitude, degrees east
  double elevation_m = 0.0;     ///< the given z in metres, from the CRS's vertical unit (io::crs_vertical_unit)
  /// Meridian convergence: the clockwise angle, degrees, from grid north (+y) to true north at the
  /// site. A compass azimuth A is the grid bearing A + convergence_deg.
  double convergence_deg = 0.0;
  /// The CRS's horizontal linear unit in metres (io::crs_horizontal_unit; US survey foot: 0.3048006).
  double metres_per_unit = 1.0;
};

/// Checks that `crs_wkt` (OGC WKT 1 or 2) can place a site, from the WKT alone: no point is needed,
/// so a job can check a cloud's CRS from its file's header before reading its points. Throws
/// std::invalid_argument (one line) when the WKT is empty or unparseable, when the CRS is
/// geographic or geocentric (refuse_unprojected_crs with "sun directions"), or when it is
/// otherwise not projected (a local frame: no place on the Earth).
void check_site_crs(const std::string& crs_wkt);

/// Throws std::invalid_argument (one line) when `crs_wkt` is geographic or geocentric
/// (is_unprojected_crs): x and y in degrees, or from the Earth's centre, are no frame for `need`
/// (what is measured, plural: "sun directions", "line-of-sight heights and distances"), which
/// takes x east, y north and z up in one linear unit. The text names the remedies: reprojecting
/// the cloud, or assigning the right CRS where only the file's CRS is wrong. Nothing for any other
/// CRS, or none (""). The one wording of that refusal (check_site_crs's, and the jobs' through
/// their option errors).
void refuse_unprojected_crs(const std::string& crs_wkt, const std::string& need);

/// The location of the point (x, y, z), given in the projected CRS `crs_wkt` (OGC WKT 1 or 2 as
/// the cloud's file carries it), transformed to WGS 84 (EPSG:4326) with GDAL/PROJ. The convergence
/// comes from the grid bearing of a short step due north (1e-5 degrees of latitude).
/// Throws std::invalid_argument (one line) for a CRS check_site_crs refuses, or when PROJ cannot
/// transform the point.
SiteLocation locate_site(const std::string& crs_wkt, const Vec3& point);

/// True when `crs_wkt` parses as a geographic or geocentric CRS (coordinates in degrees or from the
/// earth's centre: no x east, y north, z up frame for sun or view directions); false for a
/// projected, a local, an empty or an unparseable one. The one statement of that rule (locate_site
/// refuses by it).
bool is_unprojected_crs(const std::string& crs_wkt);

/// The unit vector, in the cloud's frame (x grid east, y grid north, z up), towards a body at
/// compass azimuth `azimuth_deg` (clockwise from true north) and elevation `elevation_deg` above
/// the horizon, seen from a site with meridian convergence `convergence_deg` (SiteLocation).
Vec3 direction_from_azimuth(double azimuth_deg, double elevation_deg, double convergence_deg = 0.0);

}  // namespace rayscan::analysis
