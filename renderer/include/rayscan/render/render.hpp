// Rendering a scene: load the cloud, build the index, choose the radius, then trace every pixel
// in parallel over image tiles (TBB) with the path tracer (PathTracer, private to the renderer:
// renderer/src/integrator.hpp).
#pragma once

#include "rayscan/site/site.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/octree/surfel.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/render/scene.hpp"
#include "rayscan/octree/spacing.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <atomic>
#include <cstdint>
#include <vector>

namespace rayscan::render {

/// Everything the integrator reads, independent of the index type. Spans must outlive the
/// integrator. Sphere centres are read from the index itself (index.positions()[RayHit::slot]),
/// so an index file is traced without a copy of its points.
struct IntegratorInputs {
  std::span<const Vec3> centers;    ///< the cloud's positions by original index, world coordinates:
                                    ///< the disc centres of surfel mode (empty: sphere mode only)
  AlbedoSource albedo;              ///< per-point albedo, linear [0,1] (array or rule)
  double radius = 1.0;              ///< sphere radius r, world units (> 0)
  HitMode hit = HitMode::sphere;
  NodeDistance node_distance = NodeDistance::exact;  ///< node pruning bound of the ray query
  std::uint32_t max_depth = 4;      ///< rays per path (camera ray + bounces; shadow rays not
                                    ///< counted), as RTIOW's max_depth: 1 = sun light only
  std::uint32_t rr_depth = 0;       ///< Russian roulette from this depth on; 0 = off
  double ray_offset = 1e-3;         ///< offset of secondary ray origins along n, fraction of r
  Primitive primitive = Primitive::sphere;  ///< spheres of `radius` or the discs of `surfels`
  SurfelView surfels;               ///< per-point discs (Primitive::surfel only; centres = centers)
};

/// The rendered image and its AOVs, row-major from the top-left pixel. AOV vectors are empty
/// unless requested. AOVs describe the ray through the pixel centre (lens centre), not averaged
/// over samples, so they are exact per pixel; `cost` is averaged over all samples, and `albedo`
/// over RenderSettings::albedo_samples rays when that is above 1.
struct Framebuffer {
  std::uint32_t width = 0, height = 0;
  std::vector<Color> beauty;            ///< mean radiance over spp samples (linear)
  std::vector<float> depth;             ///< t of the first hit (world units), +inf for a miss
  std::vector<glm::vec3> normal;        ///< unit normal of the first hit, (0,0,0) for a miss
  std::vector<glm::vec3> position;      ///< first hit minus position_origin (float), 0 for a miss
  Vec3 position_origin{0.0};            ///< double origin subtracted from `position` (camera centre)
  std::vector<std::uint32_t> index;     ///< original point index hit, kNoPoint (0xFFFFFFFF, = -1) for a miss
  std::vector<Color> albedo;            ///< albedo at the first hit, 0 for a miss (linear; the mean
                                        ///< over the pixel's hits: RenderSettings::albedo_samples)
  /// With `albedo`: the fraction of the pixel its rays found covered, the stratum-area-weighted
  /// share of the RenderSettings::albedo_samples rays that hit (1 or 0 for the one AOV ray): the
  /// alpha of a map whose colour is that mean over the hits (analysis::write_ortho_geotiff).
  std::vector<float> coverage;
  std::vector<float> cost;              ///< index nodes visited per sample (all rays of the path)
};

/// Knobs of one render call that are not part of the scene.
struct RenderOptions {
  unsigned threads = 0;         ///< worker threads; 0 = all cores (the result is identical)
  unsigned tile_size = 16;      ///< tile edge, pixels
  bool time_queries = false;    ///< measure time inside ray_query (bench: cost split)
  /// Trace the camera rays of each 4x4 pixel block (one sample index at a time) as one packet,
  /// and their shadow rays as another (ray_first_hit_packet / ray_any_hit_packet; in surfel mode
  /// first_surfel_hit_packet). The image is bit-identical either way. Ignored (single rays) for the
  /// cost AOV, whose node visits are per pixel, and for COPC files.
  bool packets = true;
  Progress* progress = nullptr; ///< optional progress bar
  /// Spreads the tiles over processes (rayscan::mpi's work queue, docs/mpi.md); nullptr or a
  /// single process = all tiles here. With several, only the root's framebuffer is complete.
  WorkDistributor* distributor = nullptr;
  /// Checked before each tile: once set, render_image throws rayscan::Cancelled (base/job.hpp)
  /// after the tiles in flight; nullptr = never. JobControl::cancel of the job. Not owned.
  const std::atomic<bool>* cancel = nullptr;
};

/// Totals of one render.
struct RenderStats {
  double seconds = 0.0;             ///< wall time of the pixel loop
  std::uint64_t primary_rays = 0;   ///< camera rays (spp per pixel + 1 AOV ray when AOVs are on
                                    ///< + RenderSettings::albedo_samples when above 1 and the albedo AOV is on)
  std::uint64_t queries = 0;        ///< all ray queries (camera, bounce, shadow)
  std::uint64_t nodes_visited = 0;
  std::uint64_t points_tested = 0;
  double query_seconds = 0.0;       ///< summed over threads; only with RenderOptions::time_queries
  double first_tile_seconds = 0.0;  ///< wall time from the call to the first tile traced here
  unsigned threads = 0;             ///< threads used
};

/// Per-render constants: camera, light, sampling. Built from a Scene by make_settings().
struct RenderSettings {
  Camera camera;
  IntegratorInputs integrator;
  BackgroundDesc background;
  SunDesc sun;
  Vec3 up{0.0, 0.0, 1.0};
  std::uint32_t spp = 16;
  std::uint64_t seed = 0;
  std::vector<Aov> aovs;
  /// Rays per pixel of the albedo AOV, in [1, 2^20]. 1: the AOV ray through the pixel centre, so
  /// a pixel holds one point's albedo exactly. n > 1: the mean albedo of the first hits of n rays
  /// through stratified jittered points of the pixel (stratified_pixel_point), over the rays that
  /// hit (0 where none does), a map's colour per cell (jobs::run_ortho_map). The colours are
  /// averaged sRGB-encoded, as 8-bit colours are stored and as PDAL's writers.gdal `mean` and
  /// GDAL's `average` resampling average them, and returned linear; a pixel whose hits all show
  /// one albedo holds it exactly. The other AOVs keep the centre ray.
  std::uint32_t albedo_samples = 1;
};

/// The scene's settings for a loaded cloud, albedo (by original index) and radius (spans must
/// outlive the render).
RenderSettings make_settings(const Scene& scene, std::span<const Vec3> centers,
                             std::span<const Color> albedo, double radius);

/// The auto radius lives in the core (rayscan/octree/spacing.hpp); this keeps render::median_nn_spacing.
using rayscan::median_nn_spacing;

/// A point of a pixel as offsets from its centre, in pixels (x right, y down), and the area of
/// the stratum it was drawn in (a fraction of the pixel).
struct PixelSample {
  double dx = 0.0, dy = 0.0;  ///< in [-0.5, 0.5)
  double area = 1.0;          ///< in (0, 1]; the n strata of a pixel sum to 1
};

/// Point j of n stratified points of a pixel, at the jitter (ju, jv) in [0, 1)^2 within its stratum
/// (the albedo AOV's rays, RenderSettings::albedo_samples). The pixel is cut into r = floor(sqrt(n))
/// rows of equal height, the first r - n % r rows into n / r equal strata and the others into one
/// more (n = k^2: a k x k grid); point j lies in stratum j, row-major. Each stratum holding one
/// point, an edge across the pixel is found at its area fraction to within one row or column of
/// strata, where independent jitter leaves it to chance; weighting each point by its stratum's area
/// keeps the mean unbiased when the rows differ. Throws std::invalid_argument for n = 0 or j >= n.
PixelSample stratified_pixel_point(std::uint32_t j, std::uint32_t n, double ju, double jv);

/// Render into `fb` (resized to the camera). Pixels are traced in 16x16 tiles by tbb::parallel_for;
/// sample j of pixel (x, y) uses Sampler(seed, x, y, j) only, so the image is bit-identical for
/// any thread count and any storage of the same points. settings.integrator.centers (when not
/// empty) and settings.integrator.albedo describe the site's points by original index.
///  - In memory: `site`'s index must be built over the points settings.integrator.centers holds.
///  - An index file is traced in place: centres are read from the mapping by storage slot, the
///    albedo from settings.integrator.albedo (an array by original index or an AlbedoRule over the
///    file's slot-ordered attributes). settings.integrator.centers may be empty (sphere mode);
///    surfel mode needs it (the points in original order, MappedIndex::to_point_cloud()).
///  - A COPC file (io::CopcIndex, the file's own octree) is traced in place: nodes are decoded as
///    rays reach them; centres by storage slot, the albedo from an AlbedoRule over the index's slot
///    attributes (CopcIndex::set_attributes). Each tile is traced in a CopcIndex::QueryScope
///    whose end evicts least recently used nodes no tile in flight can reach, so the decoded
///    nodes stay within the cache budget plus the nodes of the tiles in flight.
///    Sphere mode only (settings.integrator.centers empty).
/// Throws std::invalid_argument when the index, centres and albedo sizes differ, for spp 0 or
/// albedo_samples outside [1, 2^20], and for a COPC site in surfel mode; rayscan::Cancelled when
/// options.cancel is set (fb then holds part of the image).
RenderStats render_image(const Site& site, const RenderSettings& settings, Framebuffer& fb,
                         const RenderOptions& options = {});

/// A framebuffer of the camera's size with beauty and the channels of `aovs` allocated and
/// cleared (misses: kNoPoint in `index`; `coverage` with `albedo`), position_origin = the camera centre.
Framebuffer empty_framebuffer(const Camera& camera, std::span<const Aov> aovs);

/// The pixels of tiles [first, first + count) of `fb` (tile grid of edge `tile_size`, row-major
/// tile order, as render_image traces them): for each tile, each channel in use (beauty, depth,
/// normal, position, index, albedo, cost, coverage) row by row, native byte order. The tile message of the
/// MPI work queue (docs/mpi.md: 12 bytes per pixel for beauty alone).
std::vector<std::byte> pack_tiles(Framebuffer& fb, unsigned tile_size, std::uint64_t first, std::uint64_t count);

/// Writes pack_tiles()'s bytes back into `fb` (same size and channels). Throws std::runtime_error
/// when `bytes` has not exactly the expected size.
void unpack_tiles(Framebuffer& fb, unsigned tile_size, std::uint64_t first, std::uint64_t count,
                  std::span<const std::byte> bytes);

}  // namespace rayscan::render
