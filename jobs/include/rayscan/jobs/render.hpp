// The render job: a scene (file or built in code) and its cloud (file or in memory) to an image
// with AOVs, as one library call (paper section 5.3). `rayscan render` and the Python module's
// rayscan.render() are thin wrappers over run_render(); `rayscan render --ortho-map` and
// rayscan.ortho_map() over run_ortho_map().
#pragma once

#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/site.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/image/aov.hpp"
#include "rayscan/render/image_output.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"
#include "rayscan/octree/spacing.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The renderer types this job's options and results are made of.
using render::Framebuffer;
using render::ImageMetadata;
using render::RenderStats;
using render::Scene;
using render::SceneOverrides;  // applied by Scene::apply

/// Inputs of run_render(). Start from load_scene(file) or a Scene built in code (then set
/// scene.camera, and scene.cloud or `cloud`).
struct RenderJobOptions {
  Scene scene;                         ///< the render description (scenes/README.md)
  const PointCloud* cloud = nullptr;   ///< in-memory points instead of scene.cloud (not copied)
  /// `cloud` holds the points of the file scene.cloud, read by the caller (`rayscan render`
  /// reads a quick look's cloud once for its summary and the render): the image metadata then
  /// names that file instead of "(memory)".
  bool cloud_read_from_scene = false;
  /// With cloud_read_from_scene: the seconds the caller took to read `cloud` (CloudSummary::
  /// read_seconds). The job logs them as its read ("read N points from <file> in T s") and counts
  /// them in its time to the first traced tile, as when it reads the file itself.
  double cloud_read_seconds = 0.0;
  bool write = true;                   ///< write scene.output.image (+ AOVs) when it is set
  /// When set, called once with the cloud's exact bounds (the AABB of its points) as soon as they
  /// are known: right after the read (or the index file's mapping, or for a COPC file one streamed
  /// pass over its positions), before the albedo statistics, the index, the radius and the surfel
  /// estimate. A job whose camera follows from the bounds (camera_for_cloud, later given the same
  /// bounds) refuses there what needs no reach, such as a map too large for its side limit or
  /// memory, so that the error comes in seconds rather than after that work. Exceptions it throws
  /// propagate unchanged.
  std::function<void(const AABB& bounds)> bounds_read;
  /// When set, called once with the cloud's CRS (WKT, "" for none) as soon as it is known: a
  /// COPC file's header, else right after the read (or the index file's mapping), before
  /// bounds_read. A job that writes the CRS (run_ortho_map's GeoTIFFs) refuses there one it
  /// cannot write. Exceptions it throws propagate unchanged.
  std::function<void(const std::string& crs_wkt)> crs_read;
  /// When set, called once the cloud is read and the points' primitives are set up, with its exact
  /// bounds (the AABB of its points) and the reach of the primitives (as after_trace has it); the
  /// camera it returns replaces scene.camera (the scene then needs no camera; surfels oriented
  /// towards "the camera" face the scene's camera, if any, as they are estimated before this
  /// call). E.g. a top-down map over the cloud's extent whose rays start above all that can be
  /// hit (analysis::ortho_map, as run_ortho_map sets it). Exceptions it throws propagate unchanged.
  std::function<Camera(const AABB& bounds, double reach)> camera_for_cloud;
  JobControl control;                  ///< threads, progress bar, log lines
  /// COPC input (sphere mode): bytes of decoded nodes kept resident (`--cache`; trimmed as each
  /// 4x4 pixel block ends, plus the nodes of the blocks in flight).
  std::size_t cache_bytes = io::kCopcDefaultCacheBytes;
  /// Rays per pixel of the albedo AOV (render::RenderSettings::albedo_samples: 1 = the ray through
  /// the pixel centre, n > 1 = the mean over n stratified rays); run_ortho_map sets it.
  std::uint32_t albedo_samples = 1;
  /// The image's product is the albedo AOV, the beauty traced only because the renderer traces it
  /// (run_ortho_map sets it for its albedo colour): the product's rays per pixel are
  /// albedo_samples, which the image metadata records as rayscan:spp and the stats line states
  /// before the beauty's spp.
  bool albedo_map = false;
  /// When set, called once the image is traced, before it is written (on the root only of a
  /// distributed render), with the site it was traced over, the reach of the points' primitives
  /// (world units: the sphere radius, or for surfels the largest disc radius; no farther from its
  /// point is a primitive hit) and the traced image: run_ortho_map makes its DSM there, bounded
  /// by the points (analysis::bound_dsm). Exceptions it throws propagate.
  std::function<void(const Site& site, double reach, const Framebuffer& image)> after_trace;
  /// An index over `cloud` that the caller already holds (Site::over of `cloud`, or the index file
  /// whose MappedIndex::to_point_cloud() `cloud` is): traced over instead of building
  /// scene.index, which is then not used. Needs `cloud`, of the site's point count. Not owned
  /// (a copy shares its storage).
  const Site* site = nullptr;
  /// With scene.primitive surfel: the discs of `cloud` (by original index) that the caller already
  /// estimated, used as they are instead of scene_surfels' estimate; they must have one normal and
  /// radius a point. Not owned; must outlive the call.
  const SurfelAttributes* surfels = nullptr;
};

/// Output of run_render().
struct RenderJobResult {
  Framebuffer image;                   ///< beauty + requested AOVs (Framebuffer)
  RenderStats stats;                   ///< rays, queries, seconds, threads
  RadiusChoice radius;                 ///< the sphere radius used and how it was chosen (surfels:
                                       ///< the median disc radius, automatic = false)
  std::string crs_wkt;                 ///< the cloud's CRS (PointCloud::crs_wkt), "" if unknown
  std::size_t points = 0;              ///< points in the cloud
  double read_seconds = 0.0;           ///< reading the cloud or opening the index file (for an
                                       ///< in-memory cloud its cloud_read_seconds)
  double index_seconds = 0.0;          ///< building the index (0 for an index file)
  double first_tile_seconds = 0.0;     ///< from the call to the first traced tile (run_render)
  std::uint64_t copc_decodes = 0;      ///< COPC input traced in place: node decodes (re-decodes after
                                       ///< eviction included); 0 otherwise
  std::size_t copc_peak_cache_bytes = 0;  ///< COPC input traced in place: the most bytes of decoded
                                          ///< nodes resident at once (CopcIndex::peak_resident_bytes)
  ImageMetadata metadata;              ///< what was (or would be) stored in the image header
                                       ///< (scenes/README.md, "Image metadata")
  std::vector<std::filesystem::path> written;  ///< files written (beauty first)
};

/// Renders `options.scene`: reads the cloud (skipping unused scalar fields), computes the albedo,
/// builds the index, chooses the radius (choose_radius with the scene's auto factor) or, for
/// scene.primitive surfel, the per-point normals and disc radii (scene_surfels), traces the
/// image (render_image) and, when `write` and scene.output.image are set, writes it (write_image).
/// Throws SceneError "<scene file>: <JSON pointer>: <what was expected>" for a missing camera or
/// cloud, an unreadable or empty cloud, a bad material range or index option, or an impossible
/// auto radius, "<scene file>: /surfel: ..." when surfels cannot be estimated; std::runtime_error naming the file when an image cannot be written;
/// OptionError naming width and height, with the estimate in GiB, before the image's buffers are
/// allocated when they would exceed the memory the process can allocate (check_image_memory; per
/// pixel the framebuffer of beauty and AOVs plus, when writing, the writer's copies: docs/cli.md,
/// render).
/// With options.control.distributor over several processes (MPI, docs/mpi.md) every process calls
/// it with the same options; the tiles are handed out by the distributor, only the root's `image`
/// is complete and only the root writes (stats: ray queries summed over the processes).
RenderJobResult run_render(const RenderJobOptions& options);

/// Refuses, before anything is allocated, an image of `width` x `height` pixels whose buffers of
/// `bytes_per_pixel` (a lower bound of what the job holds per pixel) exceed the memory this process
/// can allocate: the machine's physical memory (sysconf) or, when lower, the process's
/// address-space limit (RLIMIT_AS, `ulimit -v`). Such a job would end in std::bad_alloc or, with
/// overcommit, in the kernel's OOM killer part way through. Throws OptionError "<lead>an image of
/// W x H pixels<detail> needs about N GiB of buffers, more than this machine's M GiB of memory
/// (or: the M GiB of address space this process may use (ulimit -v)); give a smaller <remedy>".
void check_image_memory(std::uint32_t width, std::uint32_t height, std::uint64_t bytes_per_pixel,
                        std::vector<OptionError::Part> remedy, const std::string& lead = "",
                        const std::string& detail = "");

/// Inputs of run_ortho_map(): a render through a top-down camera over the cloud's exact XY extent.
struct OrthoMapJobOptions {
  /// The scene, its cloud (file or `cloud` in memory), control and cache as for run_render(). The
  /// scene's camera is not used (the map's replaces it); camera_for_cloud and bounds_read must be
  /// unset (the job sets them). With `write`, scene.output.image is the orthophoto (.tif or .tiff); the depth AOV
  /// is added to scene.output.aovs when missing (the DSM and the alpha band come from it), and
  /// for the albedo colour the albedo AOV.
  RenderJobOptions render;
  double ortho_map = 0.0;      ///< the map's cell size (analysis::ortho_map's res), world units per pixel, > 0
  std::filesystem::path dsm;   ///< with render.write: also the DSM GeoTIFF here (.tif or .tiff); "" = none
  /// What the orthophoto's cells show: the unshaded material colour of the surface (albedo, the
  /// default: the points' RGB, else the scene's material), the mean over scene.spp stratified rays
  /// per cell of the first surface each hits (render.albedo_samples; 1 = the cell-centre ray, one
  /// point's colour exactly), or the path-traced beauty (shaded). For albedo no light is traced:
  /// the beauty runs at 1 sample per pixel and one ray per path (scene.spp and max_depth are set
  /// so), since only its AOVs are used; the image metadata's spp is the albedo's.
  analysis::OrthoColour ortho_colour = analysis::OrthoColour::albedo;
};

/// Output of run_ortho_map().
struct OrthoMapJobResult {
  RenderJobResult render;      ///< the render through map.camera (image: beauty, depth and the
                               ///< requested AOVs, albedo too for the albedo colour; written: the
                               ///< orthophoto, then the DSM)
  /// The grid over the cloud's exact bounds and its camera: set whenever run_ortho_map returns
  /// (optional only because a Camera has no empty state).
  std::optional<analysis::OrthoMap> map;
  analysis::Raster dsm;        ///< elevation per cell (analysis::dsm_from_depth; NaN = no surface)
                               ///< within the heights of the points in reach of the cell centre
                               ///< (analysis::bound_dsm); empty on the non-root processes
                               ///< of a distributed render
  double dsm_reach = 0.0;      ///< the reach bound_dsm used, world units (the sphere radius
                               ///< or the largest disc radius); 0 on the non-root processes
  analysis::DsmBounding dsm_bounding;  ///< the cells bound_dsm lowered and raised
  analysis::OrthoColour ortho_colour = analysis::OrthoColour::albedo;  ///< options.ortho_colour

  /// The orthophoto's colour per cell, linear RGB, row-major from the north-west cell: the albedo
  /// AOV (0 where the ray missed) or the beauty, as ortho_colour says (a view of render.image);
  /// complete on the root only of a distributed render.
  [[nodiscard]] std::span<const render::Color> colour() const {
    return ortho_colour == analysis::OrthoColour::albedo ? std::span<const render::Color>(render.image.albedo)
                                                         : std::span<const render::Color>(render.image.beauty);
  }
  /// For the shaded colour: 1 per cell where the cell-centre ray hit (finite render.image.depth)
  /// and 0 elsewhere, row-major as colour(), set by run_ortho_map; empty for albedo.
  std::vector<float> shaded_coverage;

  /// The orthophoto's alpha per cell in [0, 1], row-major as colour(): for albedo the share of
  /// the cell its rays found covered (render::Framebuffer::coverage, the rays the colour is the
  /// mean of), for shaded 1 where the cell-centre ray hit (finite depth) and 0 elsewhere
  /// (shaded_coverage), since the beauty's missed samples hold the sky, not a share of the cell
  /// (a view of render.image or shaded_coverage). Complete on the root only of a distributed
  /// render.
  [[nodiscard]] std::span<const float> coverage() const {
    return ortho_colour == analysis::OrthoColour::albedo ? std::span<const float>(render.image.coverage)
                                                         : std::span<const float>(shaded_coverage);
  }
};

/// Renders a true orthophoto and digital surface model (`rayscan render --ortho-map RES [--dsm F]
/// [--ortho-colour albedo|shaded]`, rayscan.ortho_map()): run_render() with the camera
/// analysis::ortho_map(bounds, ortho_map, reach) over the cloud's exact bounds (logged as "ortho
/// map: C x R cells, top-down, colour albedo"; its rays start a cell above the primitives' reach
/// over the cloud's top) and the scene's up set to +z, the axis that camera looks down (the sky
/// gradient and the elevation ramp along it, whatever up the scene or a quick look of a cloud
/// without a CRS gives; surfels oriented towards "the camera" face +z), the DSM from the depth
/// AOV of the cell-centre ray bounded by the heights of the points within reach of the cell
/// centre (analysis::bound_dsm, logged as "dsm: N cells lowered ..."), the colour from the albedo
/// AOV or the beauty (ortho_colour), the alpha from the share of the colour's rays that hit
/// (OrthoMapJobResult::coverage) and, when render.write, the files (analysis::write_ortho_map: the
/// RGBA orthophoto at scene.output.image, the Float32 DSM at `dsm` when set, both with the cloud's
/// CRS and the render's metadata), written on the root only and all or nothing (one
/// OutputTransaction: a failure of either leaves both old files); crs_warnings about that CRS are
/// logged ("warning: ..."), as the files copy it unchanged. This is the one definition of a
/// cloud's DSM on a grid (the visibility job's DSM viewshed calls it too). The outputs' names and
/// folders are checked before the render. Throws OptionError naming `ortho_map` for a cell size
/// that is not finite and > 0 or that gives too large a grid (analysis::ortho_grid's message) or a
/// grid whose buffers exceed memory, both checked as soon as the cloud's bounds are read (before
/// the index and the primitives: RenderJobOptions::bounds_read), naming `ortho_map` and `out` for
/// an orthophoto name that is not a GeoTIFF, `dsm` for such a DSM name; OutputFileError
/// (require_outputs) for an output that cannot be written, is an input or is the other output;
/// std::invalid_argument when render.camera_for_cloud or render.bounds_read is set; otherwise as
/// run_render() and analysis::write_ortho_map.
OrthoMapJobResult run_ortho_map(const OrthoMapJobOptions& options);

/// Output of run_render_frames().
struct RenderFramesResult {
  RenderJobResult job;     ///< shared values (points, radius, metadata); stats summed over frames;
                           ///< `image` is the last frame when frames were rendered one by one
                           ///< (empty when whole frames were distributed); `written` every file
  std::size_t frames = 0;  ///< frames rendered
  /// Every frame in camera order, only when options.write is false (in-memory use; on the root).
  std::vector<Framebuffer> images;
};

/// Renders one image per camera over one prepared scene (the cloud is read, the index built and
/// the radius chosen once): an animation or fly-through, `rayscan render --frames CAMERAS.json`.
/// Frame f is written to frame_file_name(scene.output.image, f). With a distributor
/// (JobControl::distributor, MPI) of N processes: more frames than processes -> whole frames are
/// the work items of the queue (each rank renders a frame with its own threads, the root writes
/// it as it arrives); otherwise frame after frame with tiles distributed. Images are identical to
/// run_render() with each camera. The frames are written all or nothing: each to a temporary
/// sibling, all renamed into place after the last, so a failure at any frame leaves the old files
/// and none of the run's. Throws like run_render() (the memory check for every camera and the
/// check of every frame's output name before the cloud is read), and std::invalid_argument for
/// an empty camera list.
RenderFramesResult run_render_frames(const RenderJobOptions& options, std::span<const Camera> cameras);

/// Reads a camera list (a fly-through): a JSON array whose elements are camera objects (the
/// camera file schema, scenes/README.md) or camera file names (relative to the list's folder), or
/// {"cameras": [...]} of the same. The list and the camera files are read as every JSON input
/// (io::parse_json_file: a regular file, at most 256 MiB). Throws SceneError "<file>: <JSON
/// pointer>: <expected>", or "<file>: <reason>" for a file that is missing or not a regular file.
std::vector<Camera> load_camera_list(const std::filesystem::path& file);

/// The output name of frame `frame`: "<stem>_<frame, 4+ digits><extension>" beside `image`
/// (out.png -> out_0000.png, out_0001.png, ...).
std::filesystem::path frame_file_name(const std::filesystem::path& image, std::size_t frame);

}  // namespace rayscan::jobs
