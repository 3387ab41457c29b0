// `rayscan visibility`: which points can be seen from where (issue 5 section 2). Per-point
// visible-from counts (and distance, sky view, camera hits) as scalar fields of a LAS/PLY copy of
// the cloud, and a top-down GeoTIFF map with a PNG preview.
#include "commands.hpp"

#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/observer.hpp"
#include "rayscan/analysis/raster.hpp"
#include "rayscan/analysis/raster_preview.hpp"
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/io/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace rayscan::cli {

namespace {

namespace an = rayscan::analysis;

struct VisibilityCli {
  std::string cloud, out, observers_file, radius = "auto", raster, preview, camera, raster_value;
  std::string sky_weighting = "uniform", index_type = "octree-adaptive";
  std::vector<std::string> observer_args;
  std::optional<double> height, ground_radius, tolerance, target_height, max_distance, cell, sky_lift;
  std::vector<double> azimuth, elevation;
  double radius_factor = 1.0;
  std::uint32_t sky_rays = 0;
  std::uint64_t seed = 0;
  unsigned threads = 0;
  bool distance = false, no_preview = false, json = false, quiet = false;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string lower_ext(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

void set_scalar(PointCloud& cloud, const std::string& name, std::vector<double> values) {
  for (ScalarField& f : cloud.scalars)
    if (f.name == name) {
      f.values = std::move(values);
      return;
    }
  cloud.scalars.push_back({name, std::move(values)});
}

int run_visibility(const VisibilityCli& o) {
  auto log = [&](const std::string& s) {
    if (!o.quiet) std::cerr << "rayscan visibility: " << s << "\n";
  };
  char buf[512];

  // ---- Check every option before any work.
  if (!o.out.empty() && lower_ext(o.out) != ".las" && lower_ext(o.out) != ".ply")
    throw UsageError("--out '" + o.out + "': expected a file name ending in .las or .ply");
  if (!o.raster.empty()) {
    if (lower_ext(o.raster) != ".tif" && lower_ext(o.raster) != ".tiff")
      throw UsageError("--raster '" + o.raster + "': expected a file name ending in .tif (GeoTIFF)");
    if (!o.cell) throw UsageError("--raster needs --cell SIZE (cell edge in the cloud's units)");
  } else if (o.cell || !o.raster_value.empty() || !o.preview.empty()) {
    throw UsageError("--cell, --raster-value and --preview need --raster OUT.tif");
  }
  // Output folders must exist before the (possibly long) computation; outputs are written to a
  // temporary sibling and renamed there, so a missing folder would only fail at the very end.
  auto check_output_folder = [](const char* option, const std::string& path) {
    if (path.empty()) return;
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_directory(fs::status(path, ec)))
      throw UsageError(std::string(option) + " '" + path + "': is a folder, expected a file name");
    const fs::path dir = fs::path(path).parent_path();
    if (dir.empty()) return;  // the current folder
    const fs::file_status st = fs::status(dir, ec);
    if (!fs::exists(st))
      throw UsageError(std::string(option) + " '" + path + "': folder '" + dir.string() + "' does not exist");
    if (!fs::is_directory(st))
      throw UsageError(std::string(option) + " '" + path + "': '" + dir.string() + "' is not a folder");
  };
  check_output_folder("--out", o.out);
  check_output_folder("--raster", o.raster);
  if (!o.no_preview) check_output_folder("--preview", o.preview);  // default: next to --raster
  const bool have_observers = !o.observers_file.empty() || !o.observer_args.empty();
  if (!have_observers && o.sky_rays == 0 && o.camera.empty())
    throw UsageError("nothing to compute: give observers (--observers FILE or --observer X,Y[,Z]), "
                     "--sky-view N or --from-camera CAMERA.json");
  if (o.distance && !have_observers) throw UsageError("--distance needs observers");
  if (o.sky_weighting != "uniform" && o.sky_weighting != "cosine")
    throw UsageError("--sky-weighting '" + o.sky_weighting + "': expected uniform or cosine");
  if (!o.azimuth.empty() && o.azimuth.size() != 2)
    throw UsageError("--azimuth: expected FROM,TO in degrees clockwise from north");
  if (!o.elevation.empty() && o.elevation.size() != 2)
    throw UsageError("--elevation: expected MIN,MAX in degrees above the horizontal");
  std::string value = o.raster_value;
  if (value.empty()) value = have_observers ? "fraction" : o.sky_rays ? "sky" : "camera";
  static const char* values[] = {"fraction", "viewshed", "count", "distance", "sky", "camera"};
  if (std::find(std::begin(values), std::end(values), value) == std::end(values))
    throw UsageError("--raster-value '" + value + "': expected fraction, viewshed, count, distance, sky or camera");
  if ((value == "fraction" || value == "viewshed" || value == "count" || value == "distance") && !have_observers)
    throw UsageError("--raster-value " + value + " needs observers");
  if (value == "sky" && o.sky_rays == 0) throw UsageError("--raster-value sky needs --sky-view N");
  if (value == "camera" && o.camera.empty()) throw UsageError("--raster-value camera needs --from-camera");

  std::vector<an::Observer> observers;
  try {
    if (!o.observers_file.empty()) observers = an::read_observers(o.observers_file);
    for (const std::string& s : o.observer_args) observers.push_back(an::parse_observer(s));
    for (std::size_t k = 0; k < observers.size(); ++k) {
      an::Observer& ob = observers[k];
      if (!ob.azimuth && !o.azimuth.empty()) ob.azimuth = an::AngleRange{o.azimuth[0], o.azimuth[1]};
      if (!ob.elevation && !o.elevation.empty()) ob.elevation = an::AngleRange{o.elevation[0], o.elevation[1]};
      an::validate_observer(ob, an::observer_where(ob, k + 1));
    }
  } catch (const an::ObserverError& e) {
    throw UsageError(e.what());
  }
  std::optional<render::Camera> camera;
  if (!o.camera.empty()) {
    try {
      camera = render::load_camera(o.camera);
    } catch (const render::SceneError& e) {
      throw UsageError(e.what());
    }
  }

  // ---- Cloud, index, radius.
  auto t0 = std::chrono::steady_clock::now();
  io::FileInfo info;
  // An index file gives its points in the sources' original order (tiles concatenated in build
  // order), so the per-point fields line up with the sources; the tree is rebuilt in memory.
  PointCloud cloud = io::is_index_file(o.cloud) ? io::MappedIndex::open(o.cloud).to_point_cloud()
                                                : io::read_point_cloud(o.cloud, {}, &info);
  if (cloud.empty()) throw UsageError(o.cloud + ": the point cloud has no points");
  std::snprintf(buf, sizeof buf, "read %zu points from %s in %.2f s", cloud.size(), o.cloud.c_str(),
                seconds_since(t0));
  log(buf);
  t0 = std::chrono::steady_clock::now();
  IndexOptions iopt;
  iopt.type = o.index_type;
  AnyIndex index = [&] {
    try {
      return make_index(cloud.positions, iopt);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--index: ") + e.what());
    }
  }();
  std::snprintf(buf, sizeof buf, "built %s index in %.2f s", o.index_type.c_str(), seconds_since(t0));
  log(buf);
  double radius;
  if (o.radius == "auto") {
    const double spacing = render::median_nn_spacing(index, cloud.positions);
    if (!(spacing > 0.0)) throw UsageError("--radius auto needs at least two distinct points; give a number");
    radius = o.radius_factor * spacing;
    std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x %.3g = %.6g", spacing,
                  o.radius_factor, radius);
    log(buf);
  } else {
    char* end = nullptr;
    radius = std::strtod(o.radius.c_str(), &end);
    if (end == o.radius.c_str() || *end || !(radius > 0.0) || !std::isfinite(radius))
      throw UsageError("--radius '" + o.radius + "': expected a number > 0 or auto");
  }
  const double tolerance = o.tolerance.value_or(2.0 * radius);
  const double target_height = o.target_height.value_or(radius);
  const double max_distance = o.max_distance.value_or(kInf);

  nlohmann::json report;
  report["cloud"] = o.cloud;
  report["points"] = cloud.size();
  report["radius"] = radius;
  report["seconds"] = nlohmann::json::object();

  // ---- Observers.
  an::VisibilityResult vis;
  if (have_observers) {
    try {
      an::GroundOptions g;
      g.radius = o.ground_radius.value_or(5.0 * radius);
      g.default_height = o.height;
      an::place_observers(observers, index, cloud, g);
    } catch (const an::ObserverError& e) {
      throw UsageError(e.what());
    }
    an::VisibilityOptions vo;
    vo.radius = radius;
    vo.tolerance = tolerance;
    vo.target_height = target_height;
    vo.max_distance = max_distance;
    vo.threads = o.threads;
    vo.progress = !o.quiet;
    vis = an::compute_visibility(index, cloud.positions, observers, vo);
    std::uint64_t seen = 0;
    for (std::uint32_t c : vis.count) seen += c > 0;
    std::snprintf(buf, sizeof buf,
                  "line of sight: %zu points x %zu observers in %.2f s (%u threads): %.4g points/s, "
                  "%.4g observer-point pairs/s; %llu points (%.1f %%) seen by at least one observer",
                  cloud.size(), observers.size(), vis.seconds, vis.threads,
                  double(cloud.size()) / vis.seconds, double(vis.pairs) / vis.seconds,
                  static_cast<unsigned long long>(seen), 100.0 * double(seen) / double(cloud.size()));
    log(buf);
    report["tolerance"] = tolerance;
    report["target_height"] = target_height;
    report["max_distance"] = std::isfinite(max_distance) ? nlohmann::json(max_distance) : nlohmann::json("inf");
    report["seconds"]["line_of_sight"] = vis.seconds;
    report["points_per_second"] = double(cloud.size()) / vis.seconds;
    report["pairs_per_second"] = double(vis.pairs) / vis.seconds;
    report["visible_points"] = seen;
    nlohmann::json arr = nlohmann::json::array();
    for (std::size_t k = 0; k < observers.size(); ++k) {
      const an::Observer& ob = observers[k];
      nlohmann::json j;
      j["name"] = ob.name.empty() ? "observer " + std::to_string(k + 1) : ob.name;
      j["position"] = {ob.position.x, ob.position.y, ob.position.z};
      if (!std::isnan(ob.ground_z)) j["ground_z"] = ob.ground_z;
      j["visible_points"] = vis.per_observer[k];
      arr.push_back(j);
    }
    report["observers"] = arr;
    set_scalar(cloud, "visible_count", std::vector<double>(vis.count.begin(), vis.count.end()));
    if (o.distance) set_scalar(cloud, "visible_distance", vis.nearest);
  }

  // ---- Sky view.
  std::vector<double> sky;
  if (o.sky_rays > 0) {
    an::SkyViewOptions so;
    so.rays = o.sky_rays;
    so.weighting = o.sky_weighting == "cosine" ? an::SkyWeighting::cosine : an::SkyWeighting::uniform;
    so.radius = radius;
    so.lift = o.sky_lift.value_or(2.0 * radius);
    so.max_distance = max_distance;
    so.seed = o.seed;
    so.threads = o.threads;
    so.progress = !o.quiet;
    t0 = std::chrono::steady_clock::now();
    std::uint64_t q = 0;
    try {
      sky = an::compute_sky_view(index, cloud.positions, so, &q);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    const double s = seconds_since(t0);
    double mean = 0;
    for (double v : sky) mean += v;
    mean /= double(sky.size());
    std::snprintf(buf, sizeof buf, "sky view: %u %s rays per point in %.2f s (%.4g ray queries/s); mean %.4f",
                  o.sky_rays, o.sky_weighting.c_str(), s, double(q) / s, mean);
    log(buf);
    report["seconds"]["sky_view"] = s;
    report["sky_view_mean"] = mean;
    set_scalar(cloud, "sky_view", sky);
  }

  // ---- Camera.
  std::vector<std::uint32_t> cam_hits;
  if (camera) {
    t0 = std::chrono::steady_clock::now();
    const std::vector<std::uint32_t> px =
        an::camera_first_hits(index, *camera, radius, max_distance, o.threads, !o.quiet);
    cam_hits = an::count_pixel_hits(px, cloud.size());
    std::uint64_t seen = 0;
    for (std::uint32_t c : cam_hits) seen += c > 0;
    std::snprintf(buf, sizeof buf, "camera %ux%u: %llu points seen in %.2f s", camera->width(), camera->height(),
                  static_cast<unsigned long long>(seen), seconds_since(t0));
    log(buf);
    report["seconds"]["camera"] = seconds_since(t0);
    report["camera_points"] = seen;
    set_scalar(cloud, "camera_hits", std::vector<double>(cam_hits.begin(), cam_hits.end()));
  }

  // ---- Outputs.
  nlohmann::json written = nlohmann::json::array();
  if (!o.out.empty()) {
    if (lower_ext(o.out) == ".las") {
      io::LasWriteOptions lo;
      if ((info.format == "LAS" || info.format == "LAZ" || info.format == "COPC") && info.scale && info.offset) {  // keep the source's integer grid
        lo.scale = *info.scale;
        lo.offset = *info.offset;
        lo.has_offset = true;
      }
      io::write_las(o.out, cloud, lo);
    } else {
      io::write_ply(o.out, cloud);
    }
    written.push_back(o.out);
  }
  if (!o.raster.empty()) {
    an::GridSpec grid;
    try {
      grid = an::grid_over(cloud.bounds(), *o.cell);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--cell: ") + e.what());
    }
    std::vector<double> v(cloud.size());
    an::CellReduce red = an::CellReduce::mean;
    std::string name;
    double lo = 0.0, hi = 1.0;
    if (value == "fraction") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i] > 0;
      name = "fraction of points visible from at least one observer";
    } else if (value == "viewshed") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i] > 0;
      red = an::CellReduce::max;
      name = "viewshed (1 = some point of the cell is visible)";
    } else if (value == "count") {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = vis.count[i];
      red = an::CellReduce::max;
      hi = double(observers.size());
      name = "observers that see the cell (max over its points)";
    } else if (value == "distance") {
      hi = 0.0;
      for (std::size_t i = 0; i < v.size(); ++i) {
        v[i] = vis.nearest[i] >= 0.0 ? vis.nearest[i] : std::nan("");
        if (v[i] > hi) hi = v[i];
      }
      red = an::CellReduce::min;
      name = "distance to the nearest observer that sees the cell";
    } else if (value == "sky") {
      v = sky;
      name = std::string("sky view factor (") + o.sky_weighting + ", mean over the cell)";
    } else {
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = cam_hits[i] > 0;
      name = "fraction of points seen by the camera";
    }
    const an::Raster raster = an::rasterize(cloud.positions, v, grid, red, name);
    an::GeoTiffOptions go;
    go.crs_wkt = cloud.crs_wkt;
    go.metadata = {{"RAYSCAN_VALUE", value},
                   {"RAYSCAN_SOURCE", o.cloud},
                   {"RAYSCAN_RADIUS", std::to_string(radius)}};
    if (have_observers) {
      go.metadata.emplace_back("RAYSCAN_TOLERANCE", std::to_string(tolerance));
      go.metadata.emplace_back("RAYSCAN_TARGET_HEIGHT", std::to_string(target_height));
    }
    an::write_geotiff(o.raster, raster, go);
    written.push_back(o.raster);
    if (cloud.crs_wkt.empty()) log("the cloud has no CRS; the GeoTIFF has a geotransform but no CRS");
    std::snprintf(buf, sizeof buf, "raster %ux%u cells of %.6g, origin (%.6f, %.6f)", grid.cols, grid.rows,
                  grid.cell, grid.x0, grid.y_top);
    log(buf);
    if (!o.no_preview) {
      std::string pv = o.preview;
      if (pv.empty()) pv = std::filesystem::path(o.raster).replace_extension(".png").string();
      const std::string legend = an::write_raster_preview(pv, raster, lo, hi, value + ": " + name);
      log("preview legend: " + legend);
      written.push_back(pv);
    }
  }
  report["written"] = written;
  if (o.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    if (have_observers)
      for (std::size_t k = 0; k < observers.size(); ++k) {
        const an::Observer& ob = observers[k];
        std::snprintf(buf, sizeof buf, "%-24s eye (%.3f, %.3f, %.3f)%s sees %llu points (%.1f %%)",
                      an::observer_label(ob, k + 1).c_str(), ob.position.x, ob.position.y, ob.position.z,
                      std::isnan(ob.ground_z) ? "" : (" ground " + std::to_string(ob.ground_z)).c_str(),
                      static_cast<unsigned long long>(vis.per_observer[k]),
                      100.0 * double(vis.per_observer[k]) / double(cloud.size()));
        std::cout << buf << "\n";
      }
    for (const auto& f : written) std::cout << "wrote " << f.get<std::string>() << "\n";
  }
  return 0;
}

}  // namespace

Runner add_visibility_command(CLI::App& app) {
  auto o = std::make_shared<VisibilityCli>();
  CLI::App* c = app.add_subcommand(
      "visibility",
      "Which points can be seen from where: per-point visible-from counts from observers (line of "
      "sight through the point spheres), sky view factor, points seen by a camera; written as "
      "scalar fields to LAS/PLY and as a GeoTIFF map with a PNG preview (analysis/README.md).");
  c->add_option("cloud", o->cloud, "Point cloud (LAS, PLY, PCD, text)")->required();
  c->add_option("-o,--out", o->out, "Write the cloud with the result fields here (.las or .ply)");
  c->add_option("--observers", o->observers_file, "Observer list (.json or .csv; see analysis/README.md)");
  c->add_option("--observer", o->observer_args,
                "An observer X,Y,Z (absolute eye) or X,Y (eye at --height above the local ground); world units "
                "(the cloud's coordinates); repeatable")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  c->add_option("--height", o->height, "Eye height above the local ground for observers without z (world units; default: none, so "
                "such observers need their own height)")
      ->check(CLI::Range(-1e9, 1e9));
  c->add_option("--ground-radius", o->ground_radius,
                "Local ground = lowest (class-2 if classified) point within this horizontal distance "
                "(default 5 x radius)")
      ->check(CLI::PositiveNumber);
  c->add_option("--radius", o->radius, "Sphere radius of each point (world units) or auto")->capture_default_str();
  c->add_option("--radius-factor", o->radius_factor, "auto radius = factor x median nearest-neighbour spacing")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  c->add_option("--tolerance", o->tolerance,
                "A point counts as seen when the first sphere the ray meets lies at most this far before "
                "it along the ray (default 2 x radius)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--target-height", o->target_height,
                "Rays aim this far above each point (GIS target height; keeps grazing views of level "
                "ground open; default 1 x radius, 0 = aim at the point)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--max-distance", o->max_distance, "Maximum viewing distance (world units; default unlimited)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--azimuth", o->azimuth,
                "Horizontal limit FROM,TO for observers without one: degrees clockwise from north (+Y), "
                "may wrap (315,45); default: no limit")
      ->delimiter(',')
      ->expected(2);
  c->add_option("--elevation", o->elevation,
                "Vertical limit MIN,MAX for observers without one: degrees above the horizontal (-90..90); "
                "default: no limit")
      ->delimiter(',')
      ->expected(2);
  c->add_flag("--distance", o->distance, "Add the field visible_distance (nearest observer that sees the point, -1 none)");
  c->add_option("--sky-view", o->sky_rays, "Sky view factor with N rays per point (field sky_view; default: off)")
      ->check(CLI::Range(1u, 1u << 20));
  c->add_option("--sky-weighting", o->sky_weighting, "uniform (solid angle) or cosine (irradiance)")
      ->capture_default_str();
  c->add_option("--sky-lift", o->sky_lift, "Sky rays start this far above the point (default 2 x radius)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--seed", o->seed, "Seed of the per-point rotation of the sky directions")->capture_default_str();
  c->add_option("--from-camera", o->camera,
                "Camera file (JSON, scenes/README.md): count the pixels whose centre ray first hits each "
                "point (field camera_hits)");
  c->add_option("--raster", o->raster, "Write a top-down GeoTIFF map here (.tif)");
  c->add_option("--cell", o->cell, "Raster cell size (world units; required with --raster)")->check(CLI::PositiveNumber);
  c->add_option("--raster-value", o->raster_value,
                "fraction | viewshed | count | distance | sky | camera (default: fraction with observers, "
                "else sky, else camera)");
  c->add_option("--preview", o->preview, "PNG preview of the raster (default: the raster's name with .png)");
  c->add_flag("--no-preview", o->no_preview, "Do not write the PNG preview");
  c->add_option("--index", o->index_type, "Index: octree-adaptive, octree-layered, octree-fixed, kdtree, brute")
      ->capture_default_str();
  c->add_option("--threads", o->threads, "Worker threads (default: all cores; results are identical)")
      ->check(CLI::Range(0u, 1024u));
  c->add_flag("--json", o->json, "Print a JSON report on stdout");
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");
  return [o] { return run_visibility(*o); };
}

}  // namespace rayscan::cli
