// The visibility job: which points of a cloud can be seen from where, as one
// library call -- line of sight from observers, sky view factor, camera marks; per-point fields,
// a copy of the cloud with them (any point format rayscan writes), a GeoTIFF map and its PNG
// preview. `rayscan visibility` and the Python module's rayscan.visibility() are thin wrappers
// over run_visibility().
#pragma once

#include "rayscan/site/copc.hpp"
#include "rayscan/analysis/observer.hpp"
#include "rayscan/analysis/raster.hpp"
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/io/file_info.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/jobs/memory_source.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/spacing.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The analysis library types this job's options and results are made of.
using analysis::AngleRange;
using analysis::Observer;
using analysis::Raster;
using analysis::SkyWeighting;
using analysis::VisibilityOptions;
using analysis::VisibilityResult;

/// Inputs of run_visibility(). An invalid option throws OptionError naming the fields
/// (`raster_value`), which the CLI writes as its flags (`--raster-value`).
struct VisibilityJobOptions {
  // ---- Input cloud.
  std::filesystem::path cloud_file;     ///< point cloud to read (LAS, LAZ, COPC, PLY, PCD, text) or index file (.rsi)
  const PointCloud* cloud = nullptr;    ///< in-memory points instead of cloud_file (copied into the result)
  /// The name of `cloud` where a file would be named: messages, log lines, the report's "cloud"
  /// and the rasters' RAYSCAN_SOURCE (the Python module gives the keyword, "cloud").
  std::string source_label{kMemorySource};
  IndexOptions index;                   ///< index type (default octree-adaptive)
  /// COPC input (a LAS/LAZ file with the COPC info VLR): query the file's own octree in place
  /// (io::CopcIndex: nodes decoded as the queries reach them, no tree built, `index` ignored) or,
  /// when false, read it whole and build `index` over it (SiteOptions::copc_in_place). The points
  /// are read whole either way, in file order (the output cloud); the results are the same.
  bool copc_in_place = true;
  /// COPC input in place: bytes of decoded nodes kept resident (`--cache`; trimmed as each chunk
  /// of points or image row ends, plus the nodes of the chunks in flight).
  std::size_t cache_bytes = io::kCopcDefaultCacheBytes;
  std::optional<double> radius;         ///< sphere radius, world units; nullopt = auto
  double radius_factor = kDefaultAutoRadiusFactor;  ///< auto radius = factor x median NN spacing
                                                    ///< (choose_radius; range: auto_radius_factor_problem)
  std::string primitive = "surfel";     ///< "surfel" (oriented discs: PCA normals, per-point radii,
                                        ///< estimate_surfels with `surfel`; with the surfel defaults of
                                        ///< tolerance and target height 0 the GIS viewshed protocol, so
                                        ///< the default agrees with gdal_viewshed on rayscan's DSM) or
                                        ///< "sphere" (the paper's model: the true 3-D answer, which sees
                                        ///< under tree crowns and through gaps)
  SurfelOptions surfel;                 ///< surfel normals and radii (orientation: +z up unless set)

  // ---- Observers (line of sight, VisibilityOptions / is_visible).
  std::vector<Observer> observers;      ///< given in code or parsed with parse_observer()
  std::filesystem::path observers_file; ///< read_observers(); these come first
  std::optional<double> height;         ///< eye height above ground for observers without z
  std::optional<double> ground_radius;  ///< local-ground search radius (default 5 x radius)
  std::optional<AngleRange> azimuth;    ///< limit for observers without one
  std::optional<AngleRange> elevation;  ///< limit for observers without one
  std::optional<double> tolerance;      ///< along-ray tolerance (default 2 x radius; surfels: 0)
  std::optional<double> target_height;  ///< aim height above each point (default 1 x radius; surfels: 0)
  std::optional<double> max_distance;   ///< viewing range (default unlimited)
  bool distance = false;                ///< add the field visible_distance

  // ---- Sky view (compute_sky_view).
  std::uint32_t sky_rays = 0;           ///< directions per point; 0 = off
  SkyWeighting sky_weighting = SkyWeighting::uniform;
  std::optional<double> sky_lift;       ///< ray start above the point (default 2 x radius)
  std::uint64_t seed = 0;               ///< sky direction rotation seed

  // ---- Camera marks (camera_first_hits).
  std::optional<Camera> camera;         ///< a camera given in code
  std::filesystem::path camera_file;    ///< or a camera file (scenes/README.md schema)

  // ---- Outputs (each written through AtomicFile; "" = not written).
  std::filesystem::path out;            ///< the cloud with the result fields (io::point_cloud_output_extensions)
  std::filesystem::path raster;         ///< top-down GeoTIFF (.tif/.tiff); needs `cell`
  std::optional<double> cell;           ///< raster cell edge, world units
  std::string raster_value;             ///< viewshed|viewshed-points|fraction|count|distance|sky|camera; "" = viewshed
                                        ///< with observers, else sky, else camera
  std::filesystem::path preview;        ///< PNG preview ("" = the raster's name with .png)
  bool write_preview = true;            ///< write the preview next to the raster
  /// The result's cloud and per-observer counts are used as they are (the Python module returns
  /// them; the CLI's --json states them): the line of sight over the points always runs with
  /// observers. false (the CLI otherwise): it runs only when an output uses its fields -- `out`,
  /// or a raster of viewshed-points, fraction, count or distance; the DSM viewshed needs only the
  /// observers' places, and `line_of_sight` is then left empty.
  bool all_fields = true;

  JobControl control;                   ///< threads, progress bar, log lines
};

/// Output of run_visibility().
struct VisibilityJobResult {
  PointCloud cloud;                     ///< the input with fields visible_count, visible_distance,
                                        ///< sky_view, camera_hits (those computed)
  io::FileInfo info;                    ///< what the reader found (format, scale, offset) for cloud_file
  std::string source;                   ///< cloud_file, or source_label for points in memory
  RadiusChoice radius;                  ///< radius used (spheres; with surfels the ground search and sky lift scale)
  std::string primitive = "sphere";     ///< "sphere" or "surfel"
  double surfel_median_radius = 0.0;    ///< median disc radius (surfels)
  double surfel_max_radius = 0.0;       ///< largest disc radius (surfels)
  double tolerance = 0.0, target_height = 0.0, max_distance = kInf;  ///< line-of-sight values used
  std::vector<Observer> observers;      ///< placed on the ground (z resolved)
  VisibilityResult line_of_sight;       ///< per point / per observer counts (empty without observers,
                                        ///< or when no output uses them: all_fields)
  std::vector<double> sky_view;         ///< per point (empty unless sky_rays > 0)
  double sky_seconds = 0.0;             ///< wall time of the sky view
  std::uint64_t sky_queries = 0;        ///< ray queries of the sky view
  std::vector<std::uint32_t> camera_hits;  ///< pixels whose first hit is each point (empty without camera)
  double camera_seconds = 0.0;          ///< wall time of the camera marks
  std::optional<Raster> raster;         ///< the map (when `raster` was given)
  std::string raster_value;             ///< what the map shows
  std::vector<std::filesystem::path> written;  ///< files written, in order
  std::uint64_t copc_decodes = 0;       ///< COPC input in place: node decodes (re-decodes after
                                        ///< eviction included); 0 otherwise
  std::size_t copc_peak_cache_bytes = 0;  ///< COPC input in place: the most bytes of decoded nodes
                                          ///< resident at once (CopcIndex::peak_resident_bytes)
};

/// Checks the options' values alone, as run_visibility does first, before it touches a file: the
/// outputs' extensions and the raster's options, that something is computed and the combinations
/// (raster_value against what is computed, distance without observers), ground_radius, radius
/// (given: finite, > 0), radius_factor, tolerance and target_height (finite, >= 0), max_distance
/// (>= 0), primitive, and the observers given in code (validate_observer with the default angle
/// limits, numbered from 1) when no observers_file comes before them. Left to the run: the files
/// (output folders and replacement, observers_file, camera_file, the cloud's CRS) and what needs
/// the points (an eye's ground and height, the automatic radius). Throws OptionError naming the
/// field (ObserverError for an observer).
void check_options(const VisibilityJobOptions& options);

/// Checks every option (before any work: extensions, output folders, value/input combinations),
/// reads the cloud, builds the index (none for an index file or a COPC file queried in place:
/// copc_in_place), chooses the radius, runs the requested analyses and writes
/// the outputs. A LAS output keeps the source's scale and offset; a GeoTIFF copies the cloud's CRS
/// unchanged and logs crs_warnings about it ("warning: ..."). Throws std::invalid_argument (bad
/// option, message naming it; check_image_memory's OptionError, before the cloud is read, for a
/// camera whose marks, 4 bytes a pixel, exceed the memory), ObserverError, SceneError (camera
/// file), io::FormatError (cloud), std::runtime_error (I/O).
/// With options.control.distributor over several processes (MPI, docs/mpi.md) every process calls
/// it with the same options; point chunks (and camera rows) are handed out by the distributor,
/// and only the root's result is complete and only the root writes the outputs.
VisibilityJobResult run_visibility(const VisibilityJobOptions& options);

/// The pdal-info-style JSON report of a run (cloud, points, radius, seconds, observers, sky view,
/// camera, the result fields with their unit, description and no-data value, written files), as
/// printed by `rayscan visibility --json`, indented by 2.
std::string visibility_report_json(const VisibilityJobResult& result);

}  // namespace rayscan::jobs
