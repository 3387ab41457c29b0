// `rayscan render`: path-trace a scanned site from a JSON scene (paper section 5.3).
#include "commands.hpp"

#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/colmap.hpp"
#include "rayscan/render/image_output.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"
#include "rayscan/render/surfel_setup.hpp"

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

namespace rayscan::cli {

namespace {

struct RenderCliOptions {
  std::string scene, camera, out;
  std::optional<std::uint32_t> spp, width, height;
  std::optional<std::uint64_t> seed;
  unsigned threads = 0;
  std::vector<std::string> aovs;
  std::string primitive;
  std::string colmap_dir, colmap_image;
  std::optional<double> ortho_res;
  std::string dsm;
  bool quiet = false;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int run_render(const RenderCliOptions& o) {
  using namespace rayscan::render;
  Scene scene;
  try {
    scene = load_scene(o.scene);
    if (!o.camera.empty()) {
      scene.camera = load_camera(o.camera);
      scene.camera_file = o.camera;
    }
    if (!o.colmap_dir.empty()) {
      if (o.colmap_image.empty()) throw UsageError("--colmap: give the photo with --image NAME");
      scene.camera = load_colmap_camera(o.colmap_dir, o.colmap_image);
      scene.camera_file = std::filesystem::path(o.colmap_dir) / "images.txt";
    }
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
  if (o.ortho_res) {
    const std::string ext = std::filesystem::path(o.out).extension().string();
    if (o.out.empty() || (ext != ".tif" && ext != ".tiff")) throw UsageError("--ortho-map: --out must name a GeoTIFF (.tif, .tiff)");
    if (o.width || o.height || !o.colmap_dir.empty())
      throw UsageError("--ortho-map: the map's size comes from RES; do not give --width, --height or --colmap");
    if (std::find(scene.output.aovs.begin(), scene.output.aovs.end(), Aov::depth) == scene.output.aovs.end())
      scene.output.aovs.push_back(Aov::depth);
  } else if (!o.dsm.empty()) {
    throw UsageError("--dsm: needs --ortho-map RES");
  }
  if (!o.primitive.empty())
    scene.primitive = o.primitive == "surfel" ? Primitive::surfel : Primitive::sphere;
  if (o.spp) scene.spp = *o.spp;
  if (o.seed) scene.seed = *o.seed;
  if (!o.out.empty()) {
    if (!is_image_file_name(o.out)) throw UsageError("--out '" + o.out + "': " + image_file_name_expected());
    scene.output.image = o.out;
  }
  if (scene.output.image.empty())
    throw UsageError(o.scene + ": /output/image: not set; give it in the scene or with --out");
  for (const std::string& a : o.aovs) {
    static const char* names[] = {"depth", "normal", "position", "index", "albedo", "cost"};
    bool found = false;
    for (int i = 0; i < 6; ++i)
      if (a == names[i]) {
        found = true;
        const Aov v = static_cast<Aov>(i);
        if (std::find(scene.output.aovs.begin(), scene.output.aovs.end(), v) == scene.output.aovs.end())
          scene.output.aovs.push_back(v);
      }
    if (!found)
      throw UsageError("--aov '" + a + "': expected depth, normal, position, index, albedo or cost");
  }
  if ((o.width || o.height) && !o.ortho_res) {
    const Camera& c = *scene.camera;
    const std::uint32_t w = o.width ? *o.width
                                    : std::max(1u, static_cast<std::uint32_t>(std::lround(
                                                       double(c.width()) * *o.height / c.height())));
    const std::uint32_t h = o.height ? *o.height
                                     : std::max(1u, static_cast<std::uint32_t>(std::lround(
                                                        double(c.height()) * *o.width / c.width())));
    scene.camera = c.resized(w, h);
  }

  auto log = [&](const std::string& s) {
    if (!o.quiet) std::cerr << "rayscan render: " << s << "\n";
  };
  auto t0 = std::chrono::steady_clock::now();
  // Only positions, colour, intensity and classification are used: skip the other scalars.
  const PointCloud cloud = [&] {
    try {
      return load_cloud(scene, io::ReadOptions{.scalars = false});
    } catch (const SceneError& e) {
      throw UsageError(e.what());
    }
  }();
  char buf[512];
  std::snprintf(buf, sizeof buf, "read %zu points from %s in %.2f s", cloud.size(),
                scene.cloud.string().c_str(), seconds_since(t0));
  log(buf);
  std::optional<analysis::OrthoMap> ortho;
  if (o.ortho_res) {
    try {
      ortho = analysis::ortho_map(cloud.bounds(), *o.ortho_res);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--ortho-map: ") + e.what());
    }
    scene.camera = ortho->camera;
    std::snprintf(buf, sizeof buf, "ortho map: %u x %u cells of %.6g, top-down", ortho->grid.cols,
                  ortho->grid.rows, *o.ortho_res);
    log(buf);
  }
  std::vector<Color> albedo;
  try {
    albedo = compute_albedo(cloud, scene.material, scene.up);
  } catch (const std::invalid_argument& e) {
    throw UsageError(o.scene + ": /material/color: " + e.what());
  }
  t0 = std::chrono::steady_clock::now();
  AnyIndex index = [&] {
    try {
      return make_index(cloud.positions, scene.index);
    } catch (const std::invalid_argument& e) {
      throw UsageError(o.scene + ": /index: " + e.what());
    }
  }();
  std::snprintf(buf, sizeof buf, "built %s index in %.2f s", scene.index.type.c_str(), seconds_since(t0));
  log(buf);
  double radius;
  SurfelAttributes surfels;
  if (scene.primitive == Primitive::surfel) {
    t0 = std::chrono::steady_clock::now();
    try {
      surfels = scene_surfels(scene, index, cloud);
    } catch (const std::invalid_argument& e) {
      throw UsageError(o.scene + ": /surfel: " + e.what());
    }
    radius = surfels.median_radius;
    std::snprintf(buf, sizeof buf,
                  "surfels: normals %s, radius %.3g x distance to neighbour %u: median %.6g, max %.6g "
                  "(clamped to %.3g x median), in %.2f s",
                  cloud.normals.empty() ? ("by PCA over " + std::to_string(scene.surfel.k_normal) +
                                           " neighbours").c_str()
                                        : "from the file",
                  scene.surfel.radius_factor, scene.surfel.k_radius, surfels.median_radius,
                  surfels.max_radius, scene.surfel.max_radius_factor, seconds_since(t0));
    log(buf);
  } else if (scene.radius) {
    radius = *scene.radius;
  } else {
    const double spacing = median_nn_spacing(index, cloud.positions);
    if (!(spacing > 0.0))
      throw UsageError(o.scene + ": /radius: \"auto\" needs at least two distinct points; give a number");
    radius = scene.auto_radius_factor * spacing;
    std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x factor %.3g = %.6g",
                  spacing, scene.auto_radius_factor, radius);
    log(buf);
  }

  RenderSettings settings = make_settings(scene, cloud.positions, albedo, radius);
  if (scene.primitive == Primitive::surfel) use_surfels(settings, surfels);
  const Camera& cam = settings.camera;
  const std::uint64_t tiles = std::uint64_t((cam.width() + 15) / 16) * ((cam.height() + 15) / 16);
  Progress progress(tiles, !o.quiet && Progress::stderr_is_terminal());
  RenderOptions ropt;
  ropt.threads = o.threads;
  ropt.progress = &progress;
  Framebuffer fb;
  const RenderStats st = rayscan::render::render_image(index, settings, fb, ropt);

  auto num = [](double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.17g", v);
    return std::string(b);
  };
  ImageMetadata meta{{"rayscan:scene", scene.file.string()},
                     {"rayscan:cloud", scene.cloud.string()},
                     {"rayscan:spp", std::to_string(scene.spp)},
                     {"rayscan:seed", std::to_string(scene.seed)},
                     {"rayscan:radius", num(radius)},
                     {"rayscan:primitive", scene.primitive == Primitive::surfel ? "surfel" : "sphere"},
                     {"rayscan:render_time_s", num(st.seconds)}};
  if (!scene.camera_file.empty()) meta.emplace_back("rayscan:camera", scene.camera_file.string());
  std::vector<std::filesystem::path> files;
  if (ortho) {
    try {
      analysis::write_ortho_geotiff(scene.output.image, *ortho, fb.beauty, scene.output.exposure, cloud.crs_wkt);
      files.push_back(scene.output.image);
      if (!o.dsm.empty()) {
        analysis::GeoTiffOptions go;
        go.crs_wkt = cloud.crs_wkt;
        go.metadata = meta;
        analysis::write_geotiff(o.dsm, analysis::dsm_from_depth(*ortho, fb.depth), go);
        files.push_back(o.dsm);
      }
    } catch (const std::exception& e) {
      throw UsageError(e.what());
    }
  } else {
    files = write_image(fb, scene.output, meta);
  }

  std::snprintf(buf, sizeof buf,
                "%.2f s, %u threads, %llux%llu px, %u spp, %llu primary rays, %llu ray queries, "
                "%.3g queries/s (%.3g per thread)",
                st.seconds, st.threads, (unsigned long long)cam.width(), (unsigned long long)cam.height(),
                scene.spp, (unsigned long long)st.primary_rays, (unsigned long long)st.queries,
                double(st.queries) / st.seconds, double(st.queries) / st.seconds / st.threads);
  log(buf);
  for (const auto& f : files) std::cout << "wrote " << f.string() << "\n";
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderCliOptions>();
  CLI::App* c = app.add_subcommand(
      "render",
      "Path-trace a point cloud described by a JSON scene (schema: scenes/README.md). Each point is "
      "a sphere hit through the octree ray query; writes PNG/JPEG/TIFF/EXR with optional AOVs.");
  c->add_option("scene", o->scene, "Scene file (JSON)")->required();
  c->add_option("--camera", o->camera, "Camera file (JSON), replaces the scene's camera");
  c->add_option("--out", o->out, "Output image (.png .jpg .jpeg .tif .tiff .exr), replaces /output/image");
  c->add_option("--spp", o->spp, "Samples per pixel, integer in [1, 1048576] (default: the scene's value, 16 if unset)")->check(CLI::Range(1u, 1u << 20));
  c->add_option("--seed", o->seed, "Random seed, unsigned 64-bit integer; the image is a pure function of it "
                "(default: the scene's value, 0 if unset)");
  c->add_option("--threads", o->threads, "Worker threads, 0 = all cores; the image is identical for any count "
                "(default: all cores)")
      ->check(CLI::Range(0u, 1024u));
  c->add_option("--width", o->width, "Image width in pixels, in [1, 65536]; keeps the field of view, and the height "
                "follows the aspect ratio unless given (default: the camera's size)")
      ->check(CLI::Range(1u, 65536u));
  c->add_option("--height", o->height, "Image height in pixels, in [1, 65536]; keeps the field of view, and the width "
                "follows the aspect ratio unless given (default: the camera's size)")
      ->check(CLI::Range(1u, 65536u));
  c->add_option("--aov", o->aovs, "Extra output: depth, normal, position, index, albedo, cost (repeatable)");
  c->add_option("--primitive", o->primitive, "Geometry of each point: sphere (the paper's model, one "
                "radius) or surfel (oriented disc with a PCA normal and a radius from the local "
                "spacing); replaces /primitive")
      ->check(CLI::IsMember({"sphere", "surfel"}));
  c->add_option("--colmap", o->colmap_dir, "COLMAP text model folder (cameras.txt, images.txt): render the "
                "view of the photo given with --image (PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)");
  c->add_option("--image", o->colmap_image, "Image NAME in the COLMAP model's images.txt (with --colmap)");
  c->add_option("--ortho-map", o->ortho_res, "Top-down orthophoto over the cloud's XY extent at RES world "
                "units per pixel, written as a georeferenced RGB GeoTIFF (--out .tif) with the cloud's CRS")
      ->check(CLI::PositiveNumber);
  c->add_option("--dsm", o->dsm, "With --ortho-map: also write the digital surface model (elevation of the "
                "first surface per cell, NoData where the ray missed) as a Float32 GeoTIFF");
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");
  return [o] { return run_render(*o); };
}

}  // namespace rayscan::cli
