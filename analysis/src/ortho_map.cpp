#include "rayscan/analysis/ortho_map.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/image/color_ramp.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "site_dispatch.hpp"

#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <mutex>
#include <stdexcept>

namespace rayscan::analysis {

namespace {

// A render's image metadata keys ("rayscan:spp") as GDAL metadata keys ("RAYSCAN_SPP"): GDAL
// splits an item at its first ':' or '=', so "rayscan:spp" would become the item "rayscan" and
// every render item would overwrite the one before.
std::vector<std::pair<std::string, std::string>> gdal_metadata_items(
    const std::vector<std::pair<std::string, std::string>>& metadata) {
  std::vector<std::pair<std::string, std::string>> out;
  out.reserve(metadata.size());
  for (const auto& [key, value] : metadata) {
    std::string k = key;
    for (char& c : k) c = c == ':' || c == '=' ? '_' : char(std::toupper(static_cast<unsigned char>(c)));
    out.emplace_back(std::move(k), value);
  }
  return out;
}

}  // namespace

const char* to_string(OrthoColour colour) { return colour == OrthoColour::shaded ? "shaded" : "albedo"; }

std::optional<OrthoColour> parse_ortho_colour(std::string_view name) {
  if (name == "albedo") return OrthoColour::albedo;
  if (name == "shaded") return OrthoColour::shaded;
  return std::nullopt;
}

GridSpec ortho_grid(const AABB& bounds, double res) {
  const GridSpec g = grid_over(bounds, res);
  if (g.cols > kMaxImageSide || g.rows > kMaxImageSide)
    throw std::invalid_argument("ortho map: " + std::to_string(g.cols) + " x " + std::to_string(g.rows) +
                                " pixels; at most " + std::to_string(kMaxImageSide) +
                                " per side (use a larger resolution)");
  return g;
}

namespace {
/// The XY centre of cell (col, row) of `g`, where the map's camera places that cell's ray: one
/// formula for the camera's first origin and for bound_dsm's rays, so the two cannot drift apart.
Vec3 cell_centre(const GridSpec& g, std::uint32_t col, std::uint32_t row, double z) {
  return Vec3(g.x0 + 0.5 * g.cell + col * g.cell, g.y_top - 0.5 * g.cell - row * g.cell, z);
}
}  // namespace

OrthoMap ortho_map(const AABB& bounds, double res, double reach) {
  const GridSpec g = ortho_grid(bounds, res);
  if (!(reach >= 0.0) || !std::isfinite(reach))
    throw std::invalid_argument("ortho map: the reach of the points must be a finite number >= 0, got " +
                                std::to_string(reach));
  // No primitive reaches farther than `reach` from its point, so nothing can be hit above
  // bounds.hi.z + reach; the extra cell keeps the origins clear of a surface at that height.
  const double margin = reach + g.cell;
  const double z_top = bounds.hi.z + margin;
  const Vec3 o00 = cell_centre(g, 0, 0, z_top);
  return {g, Camera::orthographic_grid(o00, Vec3(g.cell, 0, 0), Vec3(0, -g.cell, 0), Vec3(0, 0, -1),
                                               g.cols, g.rows),
          z_top, bounds.lo.z - margin};
}

DsmBounding bound_dsm(const Site& site, const OrthoMap& map, double reach, Raster& dsm, unsigned threads) {
  const GridSpec& g = map.grid;
  if (dsm.values.size() != std::size_t(g.cols) * g.rows || dsm.grid.cols != g.cols || dsm.grid.rows != g.rows)
    throw std::invalid_argument("dsm: raster size differs from the grid");
  if (!(reach > 0.0) || !std::isfinite(reach))
    throw std::invalid_argument("dsm: the reach of the points must be a finite number > 0");
  RayQuery q;
  q.k = 1;
  q.radius = reach;
  q.order = RayOrder::time;  // along a vertical ray: the highest (down) or the lowest (up) point within reach
  q.validate();
  std::atomic<std::size_t> lowered{0}, raised{0};
  detail::over_site<int>(site, [&](const auto& index) {
    tbb::task_arena arena(static_cast<int>(resolve_threads(threads)));
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, g.rows), [&](const auto& rows) {
        [[maybe_unused]] const auto scope = detail::chunk_scope(index);  // positions()[slot] valid within it
        std::size_t down = 0, up = 0;
        for (std::uint32_t row = rows.begin(); row != rows.end(); ++row)
          for (std::uint32_t col = 0; col < g.cols; ++col) {
            float& z = dsm.values[std::size_t(row) * g.cols + col];
            if (std::isnan(z)) continue;
            const auto hi = ray_first_hit(index, Ray(cell_centre(g, col, row, map.z_top), Vec3(0.0, 0.0, -1.0)), q);
            const auto lo = ray_first_hit(index, Ray(cell_centre(g, col, row, map.z_bottom), Vec3(0.0, 0.0, 1.0)), q);
            if (!hi || !lo) continue;  // (a surface was hit, so its point lies within reach)
            const float z_max = float(index.positions()[hi->slot].z), z_min = float(index.positions()[lo->slot].z);
            if (z > z_max) {
              z = z_max;
              ++down;
            } else if (z < z_min) {
              z = z_min;
              ++up;
            }
          }
        lowered += down;
        raised += up;
      });
    });
    return 0;
  });
  return {lowered.load(), raised.load()};
}

Raster dsm_from_depth(const OrthoMap& map, std::span<const float> depth) {
  const std::size_t n = std::size_t(map.grid.cols) * map.grid.rows;
  if (depth.size() != n) throw std::invalid_argument("dsm: depth AOV size differs from the grid");
  Raster r{map.grid, std::vector<float>(n), "elevation"};
  for (std::size_t i = 0; i < n; ++i)
    r.values[i] = std::isfinite(depth[i]) ? float(map.z_top - double(depth[i])) : std::nanf("");
  return r;
}

void write_ortho_geotiff(const std::filesystem::path& path, const OrthoMap& map,
                         std::span<const glm::vec3> colour, std::span<const float> coverage, double exposure,
                         const std::string& crs_wkt,
                         const std::vector<std::pair<std::string, std::string>>& metadata) {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  const GridSpec& g = map.grid;
  const std::size_t n = std::size_t(g.cols) * g.rows;
  if (colour.size() != n) throw std::invalid_argument(path.string() + ": image size differs from the grid");
  if (coverage.size() != n) throw std::invalid_argument(path.string() + ": coverage size differs from the grid");
  CPLPushErrorHandler(CPLQuietErrorHandler);
  struct Pop { ~Pop() { CPLPopErrorHandler(); } } pop;
  auto fail = [&](const std::string& what) {
    const char* m = CPLGetLastErrorMsg();
    throw std::runtime_error(path.string() + ": " + what + ": " + (m && *m ? m : "GDAL failure"));
  };
  OGRSpatialReference srs;
  if (!crs_wkt.empty()) {
    if (srs.importFromWkt(crs_wkt.c_str()) != OGRERR_NONE)
      throw std::invalid_argument("crs: GDAL cannot parse the cloud's WKT");
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!drv) throw std::runtime_error(path.string() + ": GDAL has no GTiff driver");
  AtomicFile file(path);
  CPLStringList co;
  co.SetNameValue("COMPRESS", "DEFLATE");
  co.SetNameValue("PHOTOMETRIC", "RGB");
  co.SetNameValue("ALPHA", "NON-PREMULTIPLIED");  // band 4: the TIFF ExtraSamples tag marks it as alpha
  co.SetNameValue("TILED", "YES");
  GDALDataset* ds = drv->Create(file.temp().string().c_str(), int(g.cols), int(g.rows), 4, GDT_Byte, co.List());
  if (!ds) fail("cannot create GeoTIFF");
  std::array<double, 6> gt = g.geotransform();
  bool ok = ds->SetGeoTransform(gt.data()) == CE_None;
  if (!crs_wkt.empty()) ok = ok && ds->SetSpatialRef(&srs) == CE_None;
  ds->SetMetadataItem("AREA_OR_POINT", "Area");
  for (const auto& [key, value] : metadata) ok = ok && ds->SetMetadataItem(key.c_str(), value.c_str()) == CE_None;
  const float scale = float(std::exp2(exposure));
  std::vector<std::uint8_t> band(n);
  for (int b = 0; b < 3 && ok; ++b) {
    for (std::size_t i = 0; i < n; ++i)
      band[i] = std::uint8_t(std::lround(255.0f * linear_to_srgb(colour[i][b] * scale)));
    ok = ds->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, int(g.cols), int(g.rows), band.data(), int(g.cols),
                                            int(g.rows), GDT_Byte, 0, 0) == CE_None;
  }
  // Alpha: the share of the cell its colour's rays found covered, so GIS tools show holes as holes
  // instead of the sky colour and a cell on the cloud's edge as partly transparent. The colour is
  // the mean over the rays that hit (unassociated alpha: not scaled by the coverage).
  for (std::size_t i = 0; i < n; ++i)
    band[i] = coverage[i] > 0.0f ? std::uint8_t(std::lround(255.0f * std::min(coverage[i], 1.0f))) : 0;
  ok = ok && ds->GetRasterBand(4)->SetColorInterpretation(GCI_AlphaBand) == CE_None;
  ok = ok && ds->GetRasterBand(4)->RasterIO(GF_Write, 0, 0, int(g.cols), int(g.rows), band.data(), int(g.cols),
                                            int(g.rows), GDT_Byte, 0, 0) == CE_None;
  if (!ok) {
    GDALClose(ds);
    fail("writing GeoTIFF failed");
  }
  CPLErrorReset();
  GDALClose(ds);
  if (CPLGetLastErrorType() >= CE_Failure) fail("closing GeoTIFF failed");
  file.commit();
}

std::vector<std::filesystem::path> write_ortho_map(const OrthoMap& map, OrthoColour kind,
                                                   std::span<const glm::vec3> colour,
                                                   std::span<const float> coverage, double exposure,
                                                   const std::string& crs_wkt,
                                                   const std::filesystem::path& image,
                                                   const std::filesystem::path& dsm, const Raster& elevation,
                                                   const std::vector<std::pair<std::string, std::string>>& metadata) {
  if (!dsm.empty() && elevation.values.size() != coverage.size())
    throw std::invalid_argument(dsm.string() + ": DSM size differs from the grid");
  std::vector<std::filesystem::path> written;
  const std::vector<std::pair<std::string, std::string>> items = gdal_metadata_items(metadata);
  std::vector<std::pair<std::string, std::string>> ortho_items = items;
  ortho_items.emplace_back("RAYSCAN_ORTHO_COLOUR", to_string(kind));
  // The orthophoto and the DSM describe one render: renamed together once both are written, so a
  // failed DSM never leaves a new orthophoto beside the old DSM.
  OutputTransaction tx;
  // Exposure is a scale of light; an albedo is a reflectance and is written as it is.
  write_ortho_geotiff(image, map, colour, coverage, kind == OrthoColour::shaded ? exposure : 0.0, crs_wkt, ortho_items);
  written.push_back(image);
  if (!dsm.empty()) {
    GeoTiffOptions go;
    go.crs_wkt = crs_wkt;
    go.metadata = items;
    go.unit_is_crs_height = true;  // elevations, in the CRS's vertical unit
    write_geotiff(dsm, elevation, go);
    written.push_back(dsm);
  }
  tx.commit();
  return written;
}

bool is_geotiff_name(const std::filesystem::path& path) { return has_extension(path, geotiff_extensions()); }

}  // namespace rayscan::analysis
