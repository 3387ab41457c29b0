// The visibility job (rayscan/jobs/visibility.hpp): what `rayscan visibility` and
// rayscan.visibility() run.
#include "rayscan/jobs/visibility.hpp"

#include "cloud_site.hpp"

#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/analysis/dsm_viewshed.hpp"
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/analysis/raster_preview.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/camera/camera_file.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/info.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/render/scene_json.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

namespace rayscan::jobs {

using namespace rayscan::analysis;  // the analysis library's types, which this job speaks in
using namespace rayscan::io;

using detail::check_output_folder;
using detail::set_scalar;

namespace {

/// The per-point values a raster shows (VisibilityJobOptions::raster_value), how a cell reduces
/// them, the legend's name and the preview's colour range.
struct RasterValues {
  std::vector<double> values;
  CellReduce reduce = CellReduce::mean;
  std::string name;
  double lo = 0.0, hi = 1.0;
};

/// Observer `ob`, number `number` (1-based) of the run, with `o`'s default angle limits where it
/// has none, checked (validate_observer; throws ObserverError).
Observer checked_observer(const VisibilityJobOptions& o, Observer ob, std::size_t number) {
  if (!ob.azimuth && o.azimuth) ob.azimuth = o.azimuth;
  if (!ob.elevation && o.elevation) ob.elevation = o.elevation;
  validate_observer(ob, observer_where(ob, number));
  return ob;
}

/// jobs::check_options's checks of `o`, in order; returns the raster value, resolved (the default
/// from what is computed).
std::string checked_raster_value(const VisibilityJobOptions& o) {
  if (!o.out.empty())
    if (const std::string why = io::point_cloud_output_problem(o.out); !why.empty())
      throw OptionError({option("out"), " '" + o.out.string() + "': " + why});
  detail::check_raster_options(o.raster, o.cell, o.raster_value, o.preview);
  const bool have_observers = !o.observers_file.empty() || !o.observers.empty();
  const bool have_camera = o.camera || !o.camera_file.empty();
  if (!have_observers && o.sky_rays == 0 && !have_camera)
    throw OptionError({"nothing to compute: give observers (", option("observers_file"), " or ",
                       option("observers"), "), a sky view (", option("sky_rays"), " > 0) or a camera (",
                       option("camera_file"), ")"});
  if (o.distance && !have_observers) throw OptionError({option("distance"), " needs observers"});
  // Checked here, not only where an eye is placed, so that every front end refuses it up front
  // and whether or not an observer needs the ground.
  if (o.ground_radius && !(*o.ground_radius > 0.0 && std::isfinite(*o.ground_radius)))
    throw OptionError({option("ground_radius"), ": expected a finite number > 0 (world units), got " +
                                                    shortest_text(*o.ground_radius)});
  detail::check_sight_lengths({o.radius, o.radius_factor, o.tolerance, o.target_height, o.max_distance});
  if (o.primitive != "sphere" && o.primitive != "surfel")
    throw OptionError({option("primitive"), " '" + o.primitive + "': expected sphere or surfel"});
  std::string value = o.raster_value;
  if (value.empty()) value = have_observers ? "viewshed" : o.sky_rays ? "sky" : "camera";
  static const char* values[] = {"viewshed", "viewshed-points", "fraction", "count", "distance", "sky", "camera"};
  if (std::find(std::begin(values), std::end(values), value) == std::end(values))
    throw OptionError({option("raster_value"), " '" + value +
                                                 "': expected viewshed, viewshed-points, fraction, count, distance, "
                                                 "sky or camera"});
  if ((value == "fraction" || value == "viewshed" || value == "viewshed-points" || value == "count" ||
       value == "distance") &&
      !have_observers)
    throw OptionError({option("raster_value"), " " + value + " needs observers"});
  if (value == "sky" && o.sky_rays == 0)
    throw OptionError({option("raster_value"), " sky needs ", option("sky_rays"), " N"});
  if (value == "camera" && !have_camera)
    throw OptionError({option("raster_value"), " camera needs ", option("camera_file")});
  // The observers given in code, numbered as the run numbers them when no file comes first (a
  // file's are checked, with them, once it is read: gather_observers).
  if (o.observers_file.empty())
    for (std::size_t k = 0; k < o.observers.size(); ++k) checked_observer(o, o.observers[k], k + 1);
  return value;
}

/// One run_visibility call: the steps in order, sharing the options, the result being filled and
/// the site. Not movable (references into `r`).
struct VisibilityRun {
  const VisibilityJobOptions& o;
  const JobControl& ctl;
  char buf[512];
  VisibilityJobResult r;
  std::string value;  // the raster value, resolved
  bool have_observers = false, have_camera = false;
  std::vector<Observer>& observers = r.observers;
  std::optional<Camera> camera;
  detail::CloudSite cs;  // the cloud and the site over it; the cloud moves to r.cloud at the end
  std::optional<Site>& site = cs.site;
  PointCloud& cloud = cs.cloud;
  double radius = 0.0;
  bool surfel = false;
  SurfelAttributes surfels;
  VisibilityResult& vis = r.line_of_sight;
  std::filesystem::path preview;  // the PNG preview to write (detail::preview_path), "" for none
  std::chrono::steady_clock::time_point t0;

  explicit VisibilityRun(const VisibilityJobOptions& options) : o(options), ctl(options.control) {}
  VisibilityRun(const VisibilityRun&) = delete;

  /// Every option checked before any work: the values (checked_raster_value, what
  /// jobs::check_options checks), then the output files; resolves `value` and `preview`.
  void check_options() {
    value = checked_raster_value(o);
    have_observers = !o.observers_file.empty() || !o.observers.empty();
    have_camera = o.camera || !o.camera_file.empty();
    check_output_folder("out", o.out);
    check_output_folder("raster", o.raster);
    if (o.write_preview) {
      // Resolved here, the default beside the raster too, so that the path the write uses is
      // the one checked before the computation.
      preview = detail::preview_path(o.raster, o.preview);
      check_output_folder("preview", preview);
      load_image_io();  // the preview's writer, before the computation rather than after it
    }
    // The output policy up front: every output path must be absent or a regular file.
    const std::filesystem::path outs[] = {o.out, o.raster, preview};
    const std::filesystem::path ins[] = {o.cloud_file, o.observers_file, o.camera_file};
    require_outputs(outs, ins);
  }

  /// What in this run needs the cloud in a projected CRS, "" for nothing. The line of sight
  /// (observers, and the raster viewshed over them) adds an eye height to z and measures a ground
  /// radius, tolerances and ranges across x, y and z at once, so degrees in x, y against metres in
  /// z give neither a length nor an angle. The sky view's rays are unit-free directions, but only
  /// in a frame of one unit: with x, y in degrees a metre across measures about 1e-5, so every
  /// horizon would read near vertical (and its lift and range are lengths). The camera's marks
  /// stay allowed: they are the first hits of the image `rayscan render` makes with the same
  /// camera in any frame, and a map of them in degrees is a legitimate GIS raster, as the render's
  /// --ortho-map is.
  std::string needs_projected_crs() const {
    if (have_observers) return "line-of-sight heights and distances";
    if (o.sky_rays > 0) return "sky view directions";
    return {};
  }

  /// Refuses a geographic or geocentric CRS (refuse_unprojected_crs, as `rayscan solar` does)
  /// when needs_projected_crs() names a need: the cloud's in memory, or the file's from its header
  /// before the points are read and indexed (header_crs). A format whose CRS comes only with its
  /// points is checked in open_site(). A GeoTIFF (--raster) carries the cloud's CRS, so one GDAL
  /// cannot read is refused here, naming the input, rather than by the writer after the run.
  void check_header_crs() const {
    if (!o.raster.empty()) detail::require_readable_header_crs(o.cloud_file, o.cloud, o.source_label);
    const std::string need = needs_projected_crs();
    if (need.empty()) return;
    if (o.cloud) detail::refuse_unprojected_crs(o.cloud->crs_wkt, need);
    else if (const std::optional<std::string> wkt = detail::header_crs(o.cloud_file))
      detail::refuse_unprojected_crs(*wkt, need);
  }

  /// The observers (file, then command line) with the default angle limits; the camera.
  void gather_observers() {
    r.raster_value = value;
    if (!o.observers_file.empty()) observers = read_observers(o.observers_file);
    observers.insert(observers.end(), o.observers.begin(), o.observers.end());
    for (std::size_t k = 0; k < observers.size(); ++k) observers[k] = checked_observer(o, observers[k], k + 1);
    camera = o.camera;
    if (!camera && !o.camera_file.empty()) camera = io::load_camera(o.camera_file);
    // The camera marks hold one 4-byte point index a pixel (camera_first_hits): refused up front
    // when that cannot be allocated, as a render's image is, rather than failing after the cloud
    // is read.
    if (camera) {
      const bool file = !o.camera && !o.camera_file.empty();
      check_image_memory(camera->width(), camera->height(), sizeof(std::uint32_t),
                         {file ? "width and height in the camera file" : "camera width and height"},
                         file ? o.camera_file.string() + ": " : std::string("camera: "),
                         " (a 4-byte point index a pixel)");
    }
  }

  /// The cloud, its index (or the mapped index file), the radius and the surfels.
  void open_site() {
    detail::open_cloud_site(cs, o.cloud_file, o.cloud, o.source_label, o.index, o.radius, o.radius_factor, ctl,
                            {o.copc_in_place, o.cache_bytes});
    if (!o.raster.empty()) io::require_readable_crs(cs.source, cloud.crs_wkt);
    if (const std::string need = needs_projected_crs(); !need.empty())
      detail::refuse_unprojected_crs(cloud.crs_wkt, need);
    r.info = cs.info;
    r.source = cs.source;
    r.radius = cs.radius;
    radius = r.radius.radius;
    surfel = o.primitive == "surfel";
    r.primitive = o.primitive;
    r.tolerance = o.tolerance.value_or(surfel ? 0.0 : 2.0 * radius);
    r.target_height = o.target_height.value_or(surfel ? 0.0 : radius);
    if (surfel) {
      surfels = detail::estimate_analysis_surfels(cs, o.surfel, ctl);
      r.surfel_median_radius = surfels.median_radius;
      r.surfel_max_radius = surfels.max_radius;
    }
    r.max_distance = o.max_distance.value_or(kInf);
  }

  /// The result field the raster maps ("" for the viewshed: the DSM's, no field).
  std::string raster_field() const {
    if (value == "viewshed-points" || value == "fraction" || value == "count") return "visible_count";
    if (value == "distance") return "visible_distance";
    if (value == "sky") return "sky_view";
    if (value == "camera") return "camera_hits";
    return {};
  }

  /// True when an output uses result field `name` (VisibilityJobOptions::all_fields): the cloud
  /// output writes every field, the raster its own.
  bool field_used(const std::string& name) const {
    return detail::result_field_used(name, o.all_fields, !o.out.empty(), o.raster.empty() ? std::string() : raster_field());
  }

  /// The per-point line of sight feeds visible_count and visible_distance alone.
  bool line_of_sight_needed() const { return field_used("visible_count") || field_used("visible_distance"); }

  /// Line of sight from every observer (placed on the ground either way).
  void line_of_sight() {
    if (have_observers) {
      GroundOptions g;
      g.radius = o.ground_radius.value_or(5.0 * radius);
      // Surfels: the ground is the surface right under the eye (within the median disc radius) when
      // it is sampled there, as a DSM's cell under the observer is.
      if (surfel && !o.ground_radius) g.inner_radius = surfels.median_radius;
      g.default_height = o.height;
      place_observers(observers, *site, cloud, g);  // the DSM viewshed's eyes too
      if (!line_of_sight_needed()) {
        ctl.info("line of sight over the points not run: no output uses visible_count or visible_distance (" +
                 value + " map)");
        return;
      }
      VisibilityOptions vo;
      vo.radius = radius;
      vo.tolerance = r.tolerance;
      vo.target_height = r.target_height;
      vo.max_distance = r.max_distance;
      if (surfel) vo.surfels = &surfels;
      vo.threads = ctl.threads;
      vo.progress = ctl.progress;
      vo.distributor = ctl.distributor;
      vo.cancel = ctl.cancel;
      vis = compute_visibility(*site, cloud.positions, observers, vo);
      std::uint64_t seen = 0;
      for (std::uint32_t c : vis.count) seen += c > 0;
      std::snprintf(buf, sizeof buf,
                    "line of sight: %zu points x %s in %.2f s (%u threads): %.4g points/s, "
                    "%.4g observer-point pairs/s; %llu points (%.1f %%) seen by at least one observer",
                    cloud.size(), count_text(observers.size(), "observer").c_str(), vis.seconds, vis.threads, double(cloud.size()) / vis.seconds,
                    double(vis.pairs) / vis.seconds, static_cast<unsigned long long>(seen),
                    100.0 * double(seen) / double(cloud.size()));
      ctl.info(buf);
      set_scalar(cloud, "visible_count", std::vector<double>(vis.count.begin(), vis.count.end()));
      if (o.distance) set_scalar(cloud, "visible_distance", vis.nearest);
    }
  }

  /// The sky view factor of every point.
  void sky_view() {
    if (o.sky_rays > 0) {
      SkyViewOptions so;
      so.rays = o.sky_rays;
      so.weighting = o.sky_weighting;
      so.radius = radius;
      so.lift = o.sky_lift.value_or(2.0 * radius);
      so.max_distance = r.max_distance;
      so.seed = o.seed;
      so.threads = ctl.threads;
      so.progress = ctl.progress;
      so.distributor = ctl.distributor;
      so.cancel = ctl.cancel;
      t0 = std::chrono::steady_clock::now();
      r.sky_view = compute_sky_view(*site, cloud.positions, so, &r.sky_queries);
      r.sky_seconds = seconds_since(t0);
      double mean = 0;
      for (double v : r.sky_view) mean += v;
      mean /= double(r.sky_view.size());
      std::snprintf(buf, sizeof buf, "sky view: %u %s rays per point in %.2f s (%.4g ray queries/s); mean %.4f",
                    o.sky_rays, o.sky_weighting == SkyWeighting::cosine ? "cosine" : "uniform", r.sky_seconds,
                    double(r.sky_queries) / r.sky_seconds, mean);
      ctl.info(buf);
      set_scalar(cloud, "sky_view", r.sky_view);
    }
  }

  /// The points the camera sees.
  void camera_marks() {
    if (camera) {
      t0 = std::chrono::steady_clock::now();
      const std::vector<std::uint32_t> px =
          camera_first_hits(*site, *camera, radius, r.max_distance, ctl.threads, ctl.progress, ctl.distributor,
                            ctl.cancel);
      r.camera_hits = count_pixel_hits(px, cloud.size());
      r.camera_seconds = seconds_since(t0);
      std::uint64_t seen = 0;
      for (std::uint32_t c : r.camera_hits) seen += c > 0;
      std::snprintf(buf, sizeof buf, "camera %ux%u: %llu points seen in %.2f s", camera->width(), camera->height(),
                    static_cast<unsigned long long>(seen), r.camera_seconds);
      ctl.info(buf);
      set_scalar(cloud, "camera_hits", std::vector<double>(r.camera_hits.begin(), r.camera_hits.end()));
    }
  }

  /// The values of `value` per point for the raster.
  RasterValues raster_values() const {
    RasterValues out;
    std::vector<double>& v = out.values;
    v.resize(cloud.size());
    CellReduce& red = out.reduce;
    std::string& name = out.name;
    double& hi = out.hi;
    if (value == "fraction") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i] > 0;
      name = "fraction of points visible from at least one observer";
    } else if (value == "viewshed-points") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i] > 0;
      red = CellReduce::max;
      name = "viewshed of the points (a cell is visible when some point in it is)";
    } else if (value == "count") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i];
      red = CellReduce::max;
      hi = double(observers.size());
      name = "observers that see the cell (max over its points)";
    } else if (value == "distance") {
      hi = 0.0;
      for (std::size_t i = 0; i < v.size(); ++i) {
        v[i] = vis.nearest[i] >= 0.0 ? vis.nearest[i] : std::nan("");
        if (v[i] > hi) hi = v[i];
      }
      red = CellReduce::min;
      name = "distance to the nearest observer that sees the cell";
    } else if (value == "sky") {
      v = r.sky_view;
      name = std::string("sky view factor (") + (o.sky_weighting == SkyWeighting::cosine ? "cosine" : "uniform") +
             ", mean over the cell)";
    } else {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = r.camera_hits[i] > 0;
      name = "fraction of points seen by the camera";
    }
    return out;
  }

  /// The target height of the DSM viewshed: --target-height, else 0 (gdal_viewshed's -tz 0).
  double dsm_target_height() const { return o.target_height.value_or(0.0); }

  /// The GIS viewshed: rayscan's own DSM of the cloud on `grid` (run_ortho_map over the quick
  /// look's surfels, exactly what `render --ortho-map CELL --dsm` writes), then an exact line of
  /// sight over it from every observer's eye (dsm_viewshed, R3).
  Raster viewshed_on_dsm(const GridSpec& grid) {
    const auto t = std::chrono::steady_clock::now();
    OrthoMapJobOptions mo;
    RenderJobOptions& ro = mo.render;
    // The quick look's geometry over this job's points (`cloud`); only the DSM is used.
    const nlohmann::json quick_look = {
        {"radius", "auto"}, {"primitive", "surfel"}, {"spp", 1}, {"material", {{"color", "elevation"}}}};
    render::SceneParseOptions po;
    po.camera_required = false;
    po.cloud_required = false;
    po.name = (o.cloud_file.empty() ? std::string("points in memory") : o.cloud_file.string()) + " (DSM)";
    ro.scene = render::parse_scene_json(quick_look, o.cloud_file, po);
    ro.cloud = &cloud;
    // One index and one surfel estimate a job: the DSM is traced over the job's site (a COPC file
    // in place excepted: the render traces surfels only over points in memory or an index file)
    // with the job's surfels when they are the discs the DSM's scene would estimate (the same
    // neighbours and factors; their orientation and thickness change no first hit nor reach).
    if (site->storage() != SiteStorage::copc) ro.site = &*site;
    const SurfelOptions& dsm_discs = ro.scene.surfel;
    if (surfel && o.surfel.k_normal == dsm_discs.k_normal && o.surfel.k_radius == dsm_discs.k_radius &&
        o.surfel.radius_factor == dsm_discs.radius_factor && o.surfel.max_radius_factor == dsm_discs.max_radius_factor)
      ro.surfels = &surfels;
    ro.write = false;
    ro.control.log = [this](const std::string& line) { ctl.info("DSM: " + line); };
    ro.control.threads = ctl.threads;
    ro.control.progress = ctl.progress;  // the DSM's render takes seconds to minutes on a large grid
    ro.control.cancel = ctl.cancel;
    mo.ortho_map = grid.cell;
    OrthoMapJobResult dr;
    try {
      dr = run_ortho_map(mo);
    } catch (const OptionError& e) {  // the map's cell size is this job's `cell`
      std::vector<OptionError::Part> parts = e.parts();
      for (OptionError::Part& p : parts)
        if (OptionName* n = std::get_if<OptionName>(&p); n && n->field == "ortho_map") n->field = "cell";
      throw OptionError(std::move(parts));
    }
    const Raster& dsm = dr.dsm;
    if (dsm.grid.cols != grid.cols || dsm.grid.rows != grid.rows || dsm.grid.x0 != grid.x0 || dsm.grid.y_top != grid.y_top)
      throw std::logic_error("visibility: the DSM's grid is not the raster's");
    // The observers' ranges and angle limits as the per-point line of sight applies them.
    Raster v = dsm_viewshed(dsm, observers, r.max_distance, dsm_target_height(), ctl.threads, ctl.progress);
    std::snprintf(buf, sizeof buf, "viewshed on the DSM (%ux%u cells of %.6g): %.2f s", grid.cols, grid.rows,
                  grid.cell, seconds_since(t));
    ctl.info(buf);
    return v;
  }

  /// The GeoTIFF map and its preview.
  void write_raster() {
    const AABB bounds = cloud.bounds();
    GridSpec grid;
    try {
      grid = grid_over(bounds, *o.cell);
    } catch (const std::invalid_argument& e) {
      throw OptionError({option("cell"), std::string(": ") + e.what()});
    }
    GeoTiffOptions go;
    go.crs_wkt = cloud.crs_wkt;
    go.metadata = {{"RAYSCAN_VALUE", value}, {"RAYSCAN_SOURCE", r.source}, {"RAYSCAN_RADIUS", std::to_string(radius)}};
    // Distances in the cloud's units; the other values are counts, 0/1 flags or fractions.
    if (value == "distance") go.unit_is_crs_length = true;
    else go.unit = value == "count" ? "observers" : "1";
    RasterValues rv;
    if (value == "viewshed") {
      r.raster = viewshed_on_dsm(grid);
      rv.name = r.raster->name;
    } else {
      rv = raster_values();
      // A length names its unit in the band description, the preview's legend and the log: the
      // band's own unit (the CRS's linear unit), and without a CRS why the band has none.
      if (go.unit_is_crs_length) {
        const std::string unit = crs_length_unit(go.crs_wkt);
        rv.name += " (" + (go.crs_wkt.empty() ? unit + "; the cloud has no CRS" : unit) + ")";
      }
      r.raster = rasterize(cloud.positions, rv.values, grid, rv.reduce, rv.name);
    }
    if (value == "viewshed") {
      go.metadata.emplace_back("RAYSCAN_SURFACE", "DSM (render --ortho-map " + std::to_string(grid.cell) + " --dsm)");
      go.metadata.emplace_back("RAYSCAN_TARGET_HEIGHT", std::to_string(dsm_target_height()));
    } else if (have_observers) {
      go.metadata.emplace_back("RAYSCAN_TOLERANCE", std::to_string(r.tolerance));
      go.metadata.emplace_back("RAYSCAN_TARGET_HEIGHT", std::to_string(r.target_height));
    }
    write_geotiff(o.raster, *r.raster, go);
    r.written.push_back(o.raster);
    if (cloud.crs_wkt.empty()) ctl.info("the cloud has no CRS; the GeoTIFF has a geotransform but no CRS");
    for (const std::string& w : crs_warnings(cloud.crs_wkt, bounds))  // `rayscan info`'s doubts, as it is copied
      ctl.info("warning: " + w + "; the GeoTIFF carries it as it is");
    std::snprintf(buf, sizeof buf, "raster %ux%u cells of %.6g, origin (%.6f, %.6f)", grid.cols, grid.rows, grid.cell,
                  grid.x0, grid.y_top);
    ctl.info(buf);
    if (!preview.empty()) {
      PreviewStyle style;
      style.crs_wkt = cloud.crs_wkt;
      if (value == "viewshed" || value == "viewshed-points")  // binary: a categorical legend, not a ramp
        style.categories = {{1.0f, "visible", {1.0f, 0.8f, 0.1f}}, {0.0f, "not visible", {0.3f, 0.3f, 0.3f}}};
      if (have_observers && value != "sky" && value != "camera")
        for (const Observer& ob : observers) style.markers.push_back(ob.position);
      const std::string legend = write_raster_preview(preview, *r.raster, rv.lo, rv.hi, rv.name, style);
      ctl.info("preview legend: " + legend);
      r.written.push_back(preview);
    }
  }

  /// The cloud with its fields and the raster, as one transaction.
  void write_outputs() {
    // One transaction, so a failing raster leaves the old cloud output intact.
    // Over several processes (MPI) only the root holds the gathered fields and writes.
    if (ctl.distributor && !ctl.distributor->is_root()) return;
    OutputTransaction tx;
    if (!o.out.empty()) {
      detail::write_result_cloud(o.out, cloud, r.info);
      r.written.push_back(o.out);
    }
    if (!o.raster.empty()) write_raster();
    tx.commit();
  }
};

}  // namespace

void check_options(const VisibilityJobOptions& o) { checked_raster_value(o); }

VisibilityJobResult run_visibility(const VisibilityJobOptions& o) {
  VisibilityRun run(o);
  run.check_options();
  run.check_header_crs();
  run.gather_observers();
  run.open_site();
  // Between the stages too: the surfels' estimate (open_site) has no check of its own.
  o.control.check_cancel();
  run.line_of_sight();
  run.sky_view();
  run.camera_marks();
  o.control.check_cancel();
  detail::copc_cache_stats(run.cs, o.control, run.r.copc_decodes, run.r.copc_peak_cache_bytes);
  run.write_outputs();
  run.r.cloud = std::move(run.cloud);
  return std::move(run.r);
}

std::string visibility_report_json(const VisibilityJobResult& r) {
  nlohmann::json report;
  report["cloud"] = r.source;
  report["points"] = r.cloud.size();
  report["radius"] = r.radius.radius;
  report["seconds"] = nlohmann::json::object();
  const VisibilityResult& vis = r.line_of_sight;
  if (!vis.count.empty()) {
    std::uint64_t seen = 0;
    for (std::uint32_t c : vis.count) seen += c > 0;
    report["primitive"] = r.primitive;
    if (r.primitive == "surfel")
      report["surfel_radius"] = {{"median", r.surfel_median_radius}, {"max", r.surfel_max_radius}};
    report["tolerance"] = r.tolerance;
    report["target_height"] = r.target_height;
    report["max_distance"] = std::isfinite(r.max_distance) ? nlohmann::json(r.max_distance) : nlohmann::json("inf");
    report["seconds"]["line_of_sight"] = vis.seconds;
    report["points_per_second"] = double(r.cloud.size()) / vis.seconds;
    report["pairs_per_second"] = double(vis.pairs) / vis.seconds;
    report["visible_points"] = seen;
    nlohmann::json arr = nlohmann::json::array();
    for (std::size_t k = 0; k < r.observers.size(); ++k) {
      const Observer& ob = r.observers[k];
      nlohmann::json j;
      j["name"] = ob.name.empty() ? "observer " + std::to_string(k + 1) : ob.name;
      j["position"] = {ob.position.x, ob.position.y, ob.position.z};
      if (!std::isnan(ob.ground_z)) j["ground_z"] = ob.ground_z;
      j["visible_points"] = vis.per_observer[k];
      arr.push_back(j);
    }
    report["observers"] = arr;
  }
  if (!r.sky_view.empty()) {
    double mean = 0;
    for (double v : r.sky_view) mean += v;
    report["seconds"]["sky_view"] = r.sky_seconds;
    report["sky_view_mean"] = mean / double(r.sky_view.size());
  }
  if (!r.camera_hits.empty()) {
    std::uint64_t seen = 0;
    for (std::uint32_t c : r.camera_hits) seen += c > 0;
    report["seconds"]["camera"] = r.camera_seconds;
    report["camera_points"] = seen;
  }
  // The result fields the output carries, each with the unit, meaning and no-data value the
  // output file's LAS descriptor or PLY/PCD comment gives it (the fields of the source cloud have
  // none), as solar --json lists its own.
  report["fields"] = nlohmann::json::object();
  const detail::ResultFields described(r.cloud.crs_wkt);
  for (const ScalarField& f : r.cloud.scalars)
    if (const auto d = described.info(f.name)) {
      nlohmann::json& field = report["fields"][f.name];
      field = {{"unit", described.unit(f.name).value_or("")},
               {"description", d->description}};
      if (d->no_data) field["no_data"] = *d->no_data;
    }
  nlohmann::json written = nlohmann::json::array();
  for (const auto& f : r.written) written.push_back(f.string());
  report["written"] = written;
  return report.dump(2);
}

}  // namespace rayscan::jobs
