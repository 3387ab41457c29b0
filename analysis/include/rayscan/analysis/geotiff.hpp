// Georeferenced GeoTIFF output of a Raster through GDAL's GTiff driver.
#pragma once

#include "rayscan/analysis/raster.hpp"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::analysis {

/// Options of write_geotiff().
struct GeoTiffOptions {
  std::string crs_wkt;   ///< the cloud's CRS (PointCloud::crs_wkt, WKT1 or WKT2); "" = none written
  double nodata = -9999.0;  ///< value stored for NaN cells and declared as the band's NoData value
  std::vector<std::pair<std::string, std::string>> metadata;  ///< dataset metadata items (key, value)
  /// The band's unit (GDALRasterBand::SetUnitType, which gdalinfo prints and QGIS shows), e.g.
  /// "kWh/m2", "W/m2", "h", "1" for a ratio or a flag; "" = none.
  std::string unit;
  /// The band holds lengths in the CRS's horizontal linear unit (distances): the unit is that
  /// unit's name from the WKT (io::crs_horizontal_unit: "metre", "foot", "US survey foot"), none
  /// without a CRS or for a geographic one.
  bool unit_is_crs_length = false;
  /// The band holds heights (a DSM's elevations): the unit is the CRS's vertical unit
  /// (io::crs_vertical_unit: of a compound CRS its vertical part's, so "metre" for EPSG:2992+5703
  /// whose x and y are in feet; else the linear unit), none without a CRS. Takes precedence over
  /// unit_is_crs_length and unit.
  bool unit_is_crs_height = false;
};

/// The unit write_geotiff gives the band for `options`: with unit_is_crs_height the CRS's vertical
/// unit, else with unit_is_crs_length its horizontal linear unit, as GDAL names them from
/// options.crs_wkt ("metre", "foot", "US survey foot"; "" without a CRS, for a WKT GDAL cannot
/// read or a CRS without that unit), else options.unit. For a picture's legend or a log line that
/// must name the same unit as the file.
std::string geotiff_band_unit(const GeoTiffOptions& options);

/// The name of a length in a cloud of CRS `crs_wkt` (WKT1 or WKT2): the CRS's horizontal linear
/// unit as GDAL names it, as a GeoTIFF band of lengths carries it (geotiff_band_unit with
/// unit_is_crs_length: "metre", "foot", "US survey foot"), or "world units" where that has none.
/// For logs, legends and field descriptions that must name the unit where the file may have none.
std::string crs_length_unit(const std::string& crs_wkt);

/// The name of a height (z, an elevation) in a cloud of CRS `crs_wkt`: the CRS's vertical unit, as
/// a DSM's band carries it (geotiff_band_unit with unit_is_crs_height: "metre" for
/// EPSG:2992+5703, "foot" for a projected CRS in feet without a vertical part), or "world units"
/// where that has none. For logs and legends of heights, which must name the DSM's unit.
std::string crs_height_unit(const std::string& crs_wkt);

/// Writes `raster` as a single-band Float32 GeoTIFF: geotransform from raster.grid (north-up,
/// pixel-is-area), the CRS from options.crs_wkt (GDALDataset::SetSpatialRef after
/// OGRSpatialReference::importFromWkt, traditional GIS axis order), NaN cells as options.nodata
/// (declared with GDALRasterBand::SetNoDataValue), raster.name as the band description, the unit
/// (geotiff_band_unit) as the band's unit type, DEFLATE
/// compression with floating-point predictor (3) and 256 x 256 tiles. Written to a temporary
/// sibling "<path>.tmp.<pid>" and renamed into place, so a failure never leaves a partial file;
/// an old raster's GDAL sidecars "<path>.aux.xml" (statistics) and "<path>.ovr" (overviews) are
/// removed first, as GDAL's Create does (an OutputFileError when that fails).
/// Throws OutputFileError "<path>: <what>: <cause>" (rayscan/base/atomic_file.hpp) when the file
/// cannot be created, written or closed: the cause is the system's, with its errno as code()
/// (ENOSPC for a full disk), where GDAL reported a failed system call, else GDAL's message;
/// std::runtime_error when GDAL has no GTiff driver, std::invalid_argument "crs: ..." when the
/// WKT cannot be parsed.
void write_geotiff(const std::filesystem::path& path, const Raster& raster, const GeoTiffOptions& options);

/// The file name extensions of a GeoTIFF output, lower case with the dot: {".tif", ".tiff"} (for
/// has_extension / extensions_expected in rayscan/base/file_names.hpp).
const std::vector<std::string>& geotiff_extensions();

}  // namespace rayscan::analysis
