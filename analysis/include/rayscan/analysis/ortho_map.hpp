// True orthophotos and digital surface models from the renderer: a top-down
// orthographic camera whose pixels are the cells of a north-up grid over the cloud's XY extent,
// the colour of each cell (the points' own colour by default, OrthoColour) written as a
// georeferenced RGBA GeoTIFF and the depth AOV as elevations.
#pragma once

#include "rayscan/analysis/raster.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/site/site.hpp"

#include <glm/vec3.hpp>

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rayscan::analysis {

/// The grid and the camera of a top-down map.
struct OrthoMap {
  GridSpec grid;         ///< north-up cells (grid_over(bounds, res))
  Camera camera;         ///< orthographic, pointing to -z: a pixel per cell (its spp samples jittered within the cell)
  double z_top = 0.0;    ///< height of the ray origins, above all the primitives reach, world units
  double z_bottom = 0.0; ///< as far below the cloud's bottom as z_top is above its top, world units
};

/// The north-up grid of the map of `bounds`' XY extent at `res` world units per pixel
/// (grid_over(bounds, res)), a pixel per cell. Only the XY extent and the cell decide it, not the
/// points' reach, so a job can check the map's size and memory as soon as the bounds are read,
/// before the index and the primitives (ortho_map builds its camera on this same grid). Throws
/// std::invalid_argument as grid_over() (bad res, empty box, too many cells) and for a grid wider
/// or taller than 65536 pixels (rayscan::kMaxImageSide).
GridSpec ortho_grid(const AABB& bounds, double res);

/// The map of `bounds`' XY extent at `res` world units per pixel (ortho_grid): pixel (col, row) shoots a ray
/// down (-z) through the centre of cell (col, row) from z_top = bounds.hi.z + reach + res, a cell
/// above the highest surface the points' primitives can show (z_bottom: as far below bounds.lo.z).
/// `reach`: how far from its point a primitive can be hit, world units (the sphere radius, or the
/// largest disc radius: a disc standing on its edge rises that far above its point); a ray from
/// lower down would start inside a tall disc or sphere and miss its top. Throws
/// std::invalid_argument as grid_over() (bad res, empty box, too many cells), for a grid wider or
/// taller than 65536 pixels, or for a `reach` that is not finite and >= 0.
OrthoMap ortho_map(const AABB& bounds, double res, double reach);

/// What an orthophoto's cells show.
enum class OrthoColour {
  /// The material colour of the surface seen from above (the render's albedo AOV), unshaded: a
  /// point's own RGB for a cloud with colours (8-bit sRGB, as stored), else the scene's material
  /// (a quick look: the elevation ramp), the mean over the scene's spp rays per cell
  /// (render::RenderSettings::albedo_samples; 1 = the point under the cell centre). What PDAL's
  /// writers.gdal `mean` over Red/Green/Blue or CloudCompare's rasterize give: a map of the points'
  /// colours.
  albedo,
  /// The path-traced beauty (sky light, sun, shading; the scene's spp and exposure): a picture
  /// seen from above rather than a map of colours.
  shaded,
};

/// "albedo" or "shaded" (the CLI's and Python's value).
const char* to_string(OrthoColour colour);

/// The OrthoColour called `name` (exact, lower case), or nullopt.
std::optional<OrthoColour> parse_ortho_colour(std::string_view name);

/// The digital surface model: elevation z_top - depth per cell, NaN where the ray missed (no
/// surface). `depth` is the depth AOV of the render (row-major, grid.cols x grid.rows).
/// Throws std::invalid_argument when its size differs from the grid.
Raster dsm_from_depth(const OrthoMap& map, std::span<const float> depth);

/// Cells bound_dsm changed.
struct DsmBounding {
  std::size_t lowered = 0;  ///< cells above the highest point within reach, set to its height
  std::size_t raised = 0;   ///< cells below the lowest point within reach, set to its height
};

/// Bounds the surface a render through map.camera found (`dsm`: dsm_from_depth of its depth AOV,
/// changed in place) by the heights of the points that can reach each cell: the primitives
/// (spheres, or discs at any tilt) interpolate between the points, but a steep disc or a sphere's
/// cap also reaches above and below them. Cell (col, row)'s elevation is clamped into
/// [float(z_min), float(z_max)], the lowest and highest point of `site` within `reach` (world
/// units: the sphere radius, or the largest disc radius; no farther from its point is a
/// primitive hit) of the vertical line through the cell centre: PDAL's writers.gdal min and max
/// with radius = reach over the same points. Two ray queries per cell (order time, k = 1: the
/// first point down from z_top, the first up from z_bottom, within `reach` of the line); NaN cells
/// stay NaN. `threads` as JobControl::threads (0 = all cores). Throws std::invalid_argument when
/// the raster's size differs from the grid or `reach` is not finite and > 0.
DsmBounding bound_dsm(const Site& site, const OrthoMap& map, double reach, Raster& dsm, unsigned threads);

/// Writes the orthophoto `colour` (linear RGB per cell: the albedo AOV or the beauty image) as a
/// 4-band Byte GeoTIFF: RGB (sRGB-encoded after 2^exposure, photometric RGB; an 8-bit sRGB colour
/// converted to linear by the renderer comes back as itself) plus an alpha band (TIFF
/// ExtraSamples unassociated alpha, GDAL's GCI_AlphaBand): round(255 x `coverage`), the fraction
/// of the cell that the rays behind its colour found covered (render::Framebuffer::coverage; 1 or
/// 0 for one ray), clamped to [0, 1] (NaN: 0). Unassociated: the colour is the mean over the rays
/// that hit, not scaled by the coverage. DEFLATE, on map.grid with the CRS
/// `crs_wkt` ("" = none) and the dataset metadata items `metadata` (keys without ':', which GDAL
/// reads as the end of a key); atomically (temporary file, then rename). Throws
/// std::runtime_error "<path>: <GDAL's message>", std::invalid_argument for a size mismatch or an
/// unparsable CRS.
void write_ortho_geotiff(const std::filesystem::path& path, const OrthoMap& map,
                         std::span<const glm::vec3> colour, std::span<const float> coverage, double exposure,
                         const std::string& crs_wkt,
                         const std::vector<std::pair<std::string, std::string>>& metadata = {});

/// The outputs of `rayscan render --ortho-map RES --out ortho.tif [--dsm dsm.tif]` from a render
/// through map.camera: the orthophoto of `colour` (write_ortho_geotiff, alpha from `coverage`, with
/// the item RAYSCAN_ORTHO_COLOUR = to_string(kind)) at `image` and, when `dsm` is not empty, the
/// DSM `elevation` (dsm_from_depth, bound_dsm; Float32 GeoTIFF) at `dsm`, both with the CRS
/// `crs_wkt` and the render's image `metadata` as GDAL items ("rayscan:spp" -> "RAYSCAN_SPP").
/// `coverage`: per cell in [0, 1], the share of the colour's rays that hit; `exposure` applies
/// to the shaded colour only (an albedo is written as it is).
/// The files are one output (an OutputTransaction, joining the caller's if one is open): both are
/// written to temporaries first and renamed into place only when both are complete, so a failure
/// of either (a full disk at the DSM) leaves both old files as they were and no temporary.
/// Returns the files written, orthophoto first. Throws as write_ortho_geotiff and write_geotiff,
/// std::invalid_argument when `elevation` differs in size from `coverage` (before writing).
std::vector<std::filesystem::path> write_ortho_map(const OrthoMap& map, OrthoColour kind,
                                                   std::span<const glm::vec3> colour,
                                                   std::span<const float> coverage, double exposure,
                                                   const std::string& crs_wkt,
                                                   const std::filesystem::path& image,
                                                   const std::filesystem::path& dsm, const Raster& elevation,
                                                   const std::vector<std::pair<std::string, std::string>>& metadata);

/// Whether `path` names a GeoTIFF by its extension (.tif, .tiff, any case), as --ortho-map needs.
bool is_geotiff_name(const std::filesystem::path& path);

}  // namespace rayscan::analysis
