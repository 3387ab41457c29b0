// `rayscan visibility`: which points can be seen from where. Per-point
// visible-from counts (and distance, sky view, camera hits) as scalar fields of a LAS/PLY copy of
// the cloud, and a top-down GeoTIFF map with a PNG preview. The job is jobs::run_visibility
// (rayscan/jobs/visibility.hpp); this file parses options and prints.
#include "commands.hpp"
#include "option_names.hpp"
#include "processes.hpp"

#include "rayscan/base/byte_size.hpp"

#include "rayscan/jobs/visibility.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>

namespace rayscan::cli {

namespace {

namespace an = rayscan::analysis;

struct VisibilityCli {
  jobs::VisibilityJobOptions job;  // options of the same type bind straight to the job
  std::string cloud, out, observers_file, radius = "auto", raster, preview, camera, cache = "2G";
  std::string sky_weighting = "uniform";
  std::vector<std::string> observer_args;
  std::vector<double> azimuth, elevation;
  bool no_preview = false, json = false, quiet = false;
};

int run_visibility(VisibilityCli& o) {
  jobs::VisibilityJobOptions& job = o.job;
  job.radius = parse_radius(o.radius);
  if (!o.azimuth.empty() && o.azimuth.size() != 2)
    throw UsageError("--azimuth: expected FROM,TO in degrees clockwise from north");
  if (!o.elevation.empty() && o.elevation.size() != 2)
    throw UsageError("--elevation: expected MIN,MAX in degrees above the horizontal");
  if (!o.azimuth.empty()) job.azimuth = an::AngleRange{o.azimuth[0], o.azimuth[1]};
  if (!o.elevation.empty()) job.elevation = an::AngleRange{o.elevation[0], o.elevation[1]};
  job.sky_weighting = o.sky_weighting == "cosine" ? an::SkyWeighting::cosine : an::SkyWeighting::uniform;  // (one_of checked the name)
  for (const std::string& s : o.observer_args) job.observers.push_back(an::parse_observer(s, "--observer '" + s + "'"));
  job.cloud_file = o.cloud;
  job.observers_file = o.observers_file;
  job.camera_file = o.camera;
  job.out = o.out;
  job.raster = o.raster;
  job.preview = o.preview;
  job.write_preview = !o.no_preview;
  job.all_fields = o.json;  // the report states each observer's points; else only the outputs' fields
  try {
    job.cache_bytes = static_cast<std::size_t>(rayscan::parse_byte_size(o.cache));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--cache: ") + e.what());
  }
  // MPI (docs/mpi.md): point chunks over the ranks; only rank 0 logs, prints and writes.
  job.control.distributor = distributor();
  const bool talk = !o.quiet && is_root();
  job.control.progress = talk;
  if (talk) job.control.log = [](const std::string& s) { std::cerr << "rayscan visibility: " << s << "\n"; };

  const jobs::VisibilityJobResult r = jobs::run_visibility(job);
  if (!is_root()) return 0;
  if (talk && !traffic_summary().empty()) std::cerr << "rayscan visibility: " << traffic_summary() << "\n";
  if (o.json) {
    std::cout << jobs::visibility_report_json(r) << "\n";
    return 0;
  }
  char buf[512];
  for (std::size_t k = 0; k < r.observers.size(); ++k) {
    const an::Observer& ob = r.observers[k];
    std::snprintf(buf, sizeof buf, "%-24s eye (%.3f, %.3f, %.3f)%s", an::observer_label(ob, k + 1).c_str(),
                  ob.position.x, ob.position.y, ob.position.z,
                  std::isnan(ob.ground_z) ? "" : (" ground " + std::to_string(ob.ground_z)).c_str());
    std::cout << buf;
    // No line of sight over the points when no output needed it (the DSM viewshed alone).
    if (k < r.line_of_sight.per_observer.size()) {
      const std::uint64_t seen = r.line_of_sight.per_observer[k];
      std::snprintf(buf, sizeof buf, " sees %llu points (%.1f %%)", static_cast<unsigned long long>(seen),
                    100.0 * double(seen) / double(r.cloud.size()));
      std::cout << buf;
    }
    std::cout << "\n";
  }
  for (const auto& f : r.written) std::cout << "wrote " << f.string() << "\n";
  return 0;
}

}  // namespace

Runner add_visibility_command(CLI::App& app) {
  auto o = std::make_shared<VisibilityCli>();
  CLI::App* c = app.add_subcommand(
      "visibility",
      "Which points can be seen from where: per-point visible-from counts from observers (line of "
      "sight over the surface the points sample, as a GIS viewshed; --primitive sphere for the true "
      "3-D answer), sky view factor, points seen by a camera; written as scalar fields to LAS/PLY "
      "and as a GeoTIFF map with a PNG preview (docs/visibility.md).");
  c->add_option("cloud", o->cloud, "Point cloud (LAS, LAZ, COPC, PLY, PCD, text) or index file (.rsi)")->required();
  c->add_option("-o,--out", o->out, "Write the cloud with the result fields here (.las, .laz, .ply, .pcd, .xyz, .csv or .txt)");
  c->add_option("--observers", o->observers_file, "Observer list (.json or .csv; see docs/visibility.md)");
  c->add_option("--observer", o->observer_args,
                "An observer X,Y,Z (absolute eye) or X,Y (eye at --height above the local ground); world units "
                "(the cloud's coordinates, each -1e9..1e9); repeatable")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  c->add_option("--height", o->job.height, "Eye height above the local ground for observers without z (world units; default: none, so "
                "such observers need their own height)")
      ->check(finite_number(-an::kMaxObserverCoordinate, an::kMaxObserverCoordinate));
  c->add_option("--ground-radius", o->job.ground_radius,
                "Local ground = lowest (class-2 if classified) point within this horizontal distance, world units "
                "(default 5 x radius)")
      ->check(positive());
  c->add_option("--radius", o->radius, "Sphere radius of each point (world units) or auto")->capture_default_str();
  // Range checked by the job (auto_radius_factor_problem), in the words of a scene's auto_radius_factor.
  c->add_option("--radius-factor", o->job.radius_factor, "auto radius = factor x median nearest-neighbour spacing")
      ->capture_default_str();
  c->add_option("--primitive", o->job.primitive,
                "Geometry of each point for line of sight: surfel (oriented disc, PCA normal, radius from "
                "the local spacing; with target height 0 the GIS viewshed of the sampled surface, as "
                "gdal_viewshed computes on a DSM) or sphere (the paper's model, one radius: the true 3-D "
                "answer, which sees under tree crowns); sky view and camera marks use spheres")
      ->capture_default_str()
      ->check(one_of(kPrimitiveNames));
  c->add_option("--tolerance", o->job.tolerance,
                "A point counts as seen when the first sphere the ray meets lies at most this far before "
                "it along the ray, world units (default 2 x radius; surfels: 0)")
      ->check(non_negative());
  c->add_option("--target-height", o->job.target_height,
                "Rays aim this far above each point, world units (GIS target height; keeps grazing views of level "
                "ground open; default 1 x radius, surfels 0; 0 = aim at the point)")
      ->check(non_negative());
  c->add_option("--max-distance", o->job.max_distance, "Maximum viewing distance (world units; default unlimited)")
      ->check(non_negative());
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
  c->add_flag("--distance", o->job.distance, "Add the field visible_distance (nearest observer that sees the point, -1 none)");
  c->add_option(option_names("visibility", "sky_rays"), o->job.sky_rays,
                "Sky view factor with N rays per point (field sky_view; default: off)")
      ->transform(integer_in(1, 1 << 20));
  c->add_option("--sky-weighting", o->sky_weighting, "uniform (solid angle) or cosine (irradiance)")
      ->check(one_of({"uniform", "cosine"}))
      ->capture_default_str();
  c->add_option("--sky-lift", o->job.sky_lift, "Sky rays start this far above the point, world units (default 2 x radius)")
      ->check(non_negative());
  c->add_option("--seed", o->job.seed, "Seed of the per-point rotation of the sky directions, unsigned 64-bit integer")
      ->capture_default_str()
      ->transform(random_seed());
  c->add_option("--from-camera", o->camera,
                "Camera file (JSON, scenes/README.md): count the pixels whose centre ray first hits each "
                "point (field camera_hits)");
  c->add_option("--raster", o->raster, "Write a top-down GeoTIFF map here (.tif)");
  c->add_option("--cell", o->job.cell, "Raster cell size (world units; required with --raster)")->check(positive());
  c->add_option("--raster-value", o->job.raster_value,
                "viewshed (the GIS viewshed: rayscan's DSM of the cloud, as render --ortho-map CELL --dsm "
                "writes it, and an exact line of sight over it to each cell centre; 1 = seen by an observer, "
                "0 = not) | viewshed-points (1 = some point of the cell is seen, by the line of sight over the "
                "points, --primitive) | fraction (of the cell's points seen) | count (observers that see the "
                "cell) | distance | sky | camera (default: viewshed with observers, else sky, else camera)");
  c->add_option("--preview", o->preview, "PNG preview of the raster (default: the raster's name with .png)");
  c->add_flag("--no-preview", o->no_preview, "Do not write the PNG preview");
  c->add_option("--cache", o->cache,
                "COPC input: bound on decoded node data kept in memory (LRU, trimmed as each chunk of points "
                "ends; plus the nodes of the chunks in flight; e.g. 2G, 512M). A COPC file is queried on its own "
                "octree, decoding only the nodes the rays reach (its points are still read, as the output cloud)")
      ->capture_default_str();
  add_index_option(*c, o->job.index.type);
  add_threads_option(*c, o->job.control.threads, "the results are identical for any count");
  c->add_flag("--json", o->json, "Print a JSON report on stdout");
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");
  return [o] { return run_visibility(*o); };
}

}  // namespace rayscan::cli
