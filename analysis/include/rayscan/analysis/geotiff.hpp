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
  /// The band holds lengths in the CRS's linear unit (a DSM's elevations, distances): the unit is
  /// that unit's name from the WKT ("metre", "foot", "US survey foot"), none without a CRS.
  bool unit_is_crs_length = false;
};

/// The unit write_geotiff gives the band for `options`: options.unit, or with unit_is_crs_length
/// the CRS's linear unit as GDAL names it from options.crs_wkt ("metre", "foot", "US survey
/// foot"; "" without a CRS or for a WKT GDAL cannot read). For a picture's legend or a log line
/// that must name the same unit as the file.
std::string geotiff_band_unit(const GeoTiffOptions& options);

/// The name of a length in a cloud of CRS `crs_wkt` (WKT1 or WKT2): the CRS's linear unit as
/// GDAL names it, as a GeoTIFF band of lengths carries it (geotiff_band_unit: "metre", "foot",
/// "US survey foot"), or "world units" without a CRS or for a WKT GDAL cannot read. For logs,
/// legends and field descriptions that must name the unit where the file may have none.
std::string crs_length_unit(const std::string& crs_wkt);

/// Writes `raster` as a single-band Float32 GeoTIFF: geotransform from raster.grid (north-up,
/// pixel-is-area), the CRS from options.crs_wkt (GDALDataset::SetSpatialRef after
/// OGRSpatialReference::importFromWkt, traditional GIS axis order), NaN cells as options.nodata
/// (declared with GDALRasterBand::SetNoDataValue), raster.name as the band description, the unit
/// (options.unit or unit_is_crs_length) as the band's unit type, DEFLATE
/// compression with floating-point predictor (3) and 256 x 256 tiles. Written to a temporary
/// sibling "<path>.tmp.<pid>" and renamed into place, so a failure never leaves a partial file.
/// Throws std::runtime_error "<path>: <GDAL's message>" on failure, std::invalid_argument
/// "crs: ..." when the WKT cannot be parsed.
void write_geotiff(const std::filesystem::path& path, const Raster& raster, const GeoTiffOptions& options);

/// The file name extensions of a GeoTIFF output, lower case with the dot: {".tif", ".tiff"} (for
/// has_extension / extensions_expected in rayscan/base/file_names.hpp).
const std::vector<std::string>& geotiff_extensions();

}  // namespace rayscan::analysis
