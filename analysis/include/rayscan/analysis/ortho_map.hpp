// True orthophotos and digital surface models from the renderer: a top-down
// orthographic camera whose pixels are the cells of a north-up grid over the cloud's XY extent,
// the beauty image written as a georeferenced RGB GeoTIFF and the depth AOV as elevations.
#pragma once

#include "rayscan/analysis/raster.hpp"
#include "rayscan/camera/camera.hpp"

#include <glm/vec3.hpp>

#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::analysis {

/// The grid and the camera of a top-down map.
struct OrthoMap {
  GridSpec grid;         ///< north-up cells (grid_over(bounds, res))
  Camera camera;         ///< orthographic, pointing to -z: a pixel per cell (its spp samples jittered within the cell)
  double z_top = 0.0;    ///< height of the ray origins (above the cloud), world units
};

/// The map of `bounds`' XY extent at `res` world units per pixel: pixel (col, row) shoots a ray
/// down (-z) through the centre of cell (col, row) from 1% of the extent above bounds.hi.z.
/// Throws std::invalid_argument as grid_over() (bad res, empty box, too many cells) or for a grid
/// wider or taller than 65536 pixels.
OrthoMap ortho_map(const AABB& bounds, double res);

/// The digital surface model: elevation z_top - depth per cell, NaN where the ray missed (no
/// surface). `depth` is the depth AOV of the render (row-major, grid.cols x grid.rows).
/// Throws std::invalid_argument when its size differs from the grid.
Raster dsm_from_depth(const OrthoMap& map, std::span<const float> depth);

/// Writes the beauty image (linear RGB, the renderer's Color) as a 4-band Byte GeoTIFF: RGB
/// (sRGB-encoded after 2^exposure, photometric RGB) plus an alpha band (TIFF ExtraSamples
/// unassociated alpha, GDAL's GCI_AlphaBand): 255 where the cell's ray hit the cloud (finite
/// `depth`, the depth AOV), 0 where it missed; DEFLATE, on map.grid with the CRS `crs_wkt` ("" =
/// none); atomically (temporary file, then rename). Throws std::runtime_error "<path>: <GDAL's
/// message>", std::invalid_argument for a size mismatch or an unparsable CRS.
void write_ortho_geotiff(const std::filesystem::path& path, const OrthoMap& map,
                         std::span<const glm::vec3> beauty, std::span<const float> depth, double exposure,
                         const std::string& crs_wkt);

/// The outputs of `rayscan render --ortho-map RES --out ortho.tif [--dsm dsm.tif]` from a render
/// through map.camera: the orthophoto (write_ortho_geotiff, alpha from `depth`) at `image` and,
/// when `dsm` is not empty, the DSM (dsm_from_depth, Float32 GeoTIFF with `metadata`) at `dsm`, both with the CRS
/// `crs_wkt`. `depth` is the depth AOV (required). Returns the files written,
/// orthophoto first. Throws as write_ortho_geotiff, dsm_from_depth and write_geotiff.
std::vector<std::filesystem::path> write_ortho_map(const OrthoMap& map, std::span<const glm::vec3> beauty,
                                                   std::span<const float> depth, double exposure,
                                                   const std::string& crs_wkt,
                                                   const std::filesystem::path& image,
                                                   const std::filesystem::path& dsm,
                                                   const std::vector<std::pair<std::string, std::string>>& metadata);

/// Whether `path` names a GeoTIFF by its extension (.tif, .tiff, any case), as --ortho-map needs.
bool is_geotiff_name(const std::filesystem::path& path);

}  // namespace rayscan::analysis
