// The render job (rayscan/render/render_job.hpp): what `rayscan render` and rayscan.render() run.
#include "rayscan/render/render_job.hpp"

#include "rayscan/io/camera_file.hpp"
#include "rayscan/render/colmap.hpp"
#include "rayscan/io/index_file.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/surfel_setup.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <utility>

namespace rayscan::render {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string num17(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

}  // namespace

void apply_overrides(Scene& scene, const SceneOverrides& o) {
  if (!o.camera_file.empty()) {
    scene.camera = io::load_camera(o.camera_file);
    scene.camera_file = o.camera_file;
  }
  if (!o.colmap_dir.empty()) {
    if (o.colmap_image.empty()) throw std::invalid_argument("--colmap: give the photo with --image NAME");
    scene.camera = load_colmap_camera(o.colmap_dir, o.colmap_image);
    scene.camera_file = o.colmap_dir / "images.txt";
  } else if (!o.colmap_image.empty()) {
    throw std::invalid_argument("--image: needs --colmap DIR");
  }
  if (!o.primitive.empty()) {
    if (o.primitive != "sphere" && o.primitive != "surfel")
      throw std::invalid_argument("--primitive '" + o.primitive + "': expected sphere or surfel");
    scene.primitive = o.primitive == "surfel" ? Primitive::surfel : Primitive::sphere;
  }
  if (o.spp) {
    if (*o.spp < 1 || *o.spp > (1u << 20)) throw std::invalid_argument("--spp: expected an integer in [1, 1048576]");
    scene.spp = *o.spp;
  }
  if (o.seed) scene.seed = *o.seed;
  if (!o.out.empty()) {
    if (!is_image_file_name(o.out))
      throw std::invalid_argument("--out '" + o.out.string() + "': " + image_file_name_expected());
    scene.output.image = o.out;
  }
  for (const std::string& a : o.aovs) {
    const std::optional<Aov> v = parse_aov(a);
    if (!v) throw std::invalid_argument("--aov '" + a + "': " + aov_names_expected());
    if (std::find(scene.output.aovs.begin(), scene.output.aovs.end(), *v) == scene.output.aovs.end())
      scene.output.aovs.push_back(*v);
  }
  if (o.width || o.height) {
    if (!scene.camera) throw std::invalid_argument("--width/--height: the scene has no camera");
    // In double, then checked: a 1x65536 camera with --width 65536 asks for a height of 2^32,
    // which must be an error, not a wrapped 32-bit integer (issue 8).
    const Camera& c = *scene.camera;
    const double w = o.width ? double(*o.width) : std::round(double(c.width()) * *o.height / c.height());
    const double h = o.height ? double(*o.height) : std::round(double(c.height()) * *o.width / c.width());
    for (const auto& [v, name] : {std::pair{w, "width"}, std::pair{h, "height"}})
      if (!(v >= 1.0 && v <= 65536.0))
        throw std::invalid_argument("the camera's aspect ratio " + std::to_string(c.width()) + ":" +
                                    std::to_string(c.height()) + " gives an image " + name + " of " +
                                    std::to_string(static_cast<long long>(std::min(v, 1e18))) +
                                    " pixels, expected 1 to 65536; give both --width and --height");
    scene.camera = c.resized(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
  }
}

RenderJobResult run_render(const RenderJobOptions& o) {
  Scene scene = o.scene;  // small: the camera may be replaced by camera_for_cloud
  const std::string f = scene.file.empty() ? std::string("(scene)") : scene.file.string();
  if (!scene.camera && !o.camera_for_cloud) throw SceneError(f + ": /camera: not set; give a camera in the scene or a camera file");
  if (o.write && scene.output.image.empty())
    throw SceneError(f + ": /output/image: not set; give it in the scene or with --out");
  const JobControl& ctl = o.control;
  RenderJobResult r;
  char buf[512];

  // Only positions, colour, intensity and classification are used: skip the other scalars.
  auto t0 = std::chrono::steady_clock::now();
  PointCloud owned;
  // An index file (.rsi): the tree is mapped, not built; centres and colours come from its stored
  // points in original order (MappedIndex::to_point_cloud).
  std::optional<io::MappedIndex> mapped;
  if (!o.cloud && io::is_index_file(scene.cloud)) {
    mapped.emplace(io::MappedIndex::open(scene.cloud));
    owned = mapped->to_point_cloud();
    if (owned.empty()) throw SceneError(f + ": /cloud: the point cloud has no points");
  } else if (!o.cloud) {
    owned = load_cloud(scene, io::ReadOptions{.scalars = false});
  }
  else if (o.cloud->empty()) throw SceneError(f + ": /cloud: the point cloud has no points");
  const PointCloud& cloud = o.cloud ? *o.cloud : owned;
  r.points = cloud.size();
  if (!o.cloud) {
    r.read_seconds = seconds_since(t0);
    std::snprintf(buf, sizeof buf, "read %zu points from %s in %.2f s", cloud.size(), scene.cloud.string().c_str(),
                  r.read_seconds);
    ctl.info(buf);
  }
  r.crs_wkt = cloud.crs_wkt;
  if (o.camera_for_cloud) scene.camera = o.camera_for_cloud(cloud);
  std::vector<Color> albedo;
  try {
    albedo = compute_albedo(cloud, scene.material, scene.up);
  } catch (const std::invalid_argument& e) {
    throw SceneError(f + ": /material/color: " + e.what());
  }
  t0 = std::chrono::steady_clock::now();
  AnyIndex index = [&] {
    if (mapped) return AnyIndex(BruteForceIndex(std::span<const Vec3>{}));  // unused: the mapped tree is
    try {
      return make_index(cloud.positions, scene.index);
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /index: " + e.what());
    }
  }();
  r.index_seconds = seconds_since(t0);
  if (mapped)
    std::snprintf(buf, sizeof buf, "mapped index file %s (%zu nodes)", scene.cloud.string().c_str(),
                  static_cast<std::size_t>(mapped->node_count()));
  else
    std::snprintf(buf, sizeof buf, "built %s index in %.2f s", scene.index.type.c_str(), r.index_seconds);
  ctl.info(buf);
  SurfelAttributes surfels;
  if (scene.primitive == Primitive::surfel) {
    // Surfel normals and radii: kNN over the mapped or the built in-memory index (scene_surfels).
    t0 = std::chrono::steady_clock::now();
    try {
      surfels = mapped ? scene_surfels(scene, *mapped, cloud) : scene_surfels(scene, index, cloud);
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /surfel: " + e.what());
    }
    r.radius.radius = surfels.median_radius;
    const std::string normals = cloud.normals.empty()
                                    ? "by PCA over " + std::to_string(scene.surfel.k_normal) + " neighbours"
                                    : std::string("from the file");
    std::snprintf(buf, sizeof buf,
                  "surfels: normals %s, radius %.3g x distance to neighbour %u: median %.6g, max %.6g "
                  "(clamped to %.3g x median), in %.2f s",
                  normals.c_str(), scene.surfel.radius_factor, scene.surfel.k_radius, surfels.median_radius,
                  surfels.max_radius, scene.surfel.max_radius_factor, seconds_since(t0));
    ctl.info(buf);
  } else {
    try {
      r.radius = mapped ? choose_radius(scene.radius, scene.auto_radius_factor,
                                        [&] { return median_nn_spacing_of(*mapped, cloud.positions); })
                        : choose_radius(index, cloud.positions, scene.radius, scene.auto_radius_factor);
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /radius: " + e.what());
    }
    if (r.radius.automatic) {
      std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x factor %.3g = %.6g",
                    r.radius.spacing, r.radius.factor, r.radius.radius);
      ctl.info(buf);
    }
  }

  RenderSettings settings = make_settings(scene, cloud.positions, albedo, r.radius.radius);
  if (scene.primitive == Primitive::surfel) use_surfels(settings, surfels);
  const Camera& cam = settings.camera;
  const std::uint64_t tiles = std::uint64_t((cam.width() + 15) / 16) * ((cam.height() + 15) / 16);
  Progress progress(tiles, ctl.progress && Progress::stderr_is_terminal());
  RenderOptions ropt;
  ropt.threads = ctl.threads;
  ropt.progress = &progress;
  r.stats = mapped ? render_image(*mapped, settings, r.image, ropt) : render_image(index, settings, r.image, ropt);

  r.metadata = {{"rayscan:scene", scene.file.string()},
                {"rayscan:cloud", o.cloud ? std::string("(memory)") : scene.cloud.string()},
                {"rayscan:spp", std::to_string(scene.spp)},
                {"rayscan:seed", std::to_string(scene.seed)},
                {"rayscan:radius", num17(r.radius.radius)},
                {"rayscan:primitive", scene.primitive == Primitive::surfel ? "surfel" : "sphere"}};
  // No render time in the file (issue 8): two renders of the same scene and seed are identical
  // byte for byte (`cmp`); the time is in RenderJobResult::stats and the log.
  if (!scene.camera_file.empty()) r.metadata.emplace_back("rayscan:camera", scene.camera_file.string());
  if (o.write && !scene.output.image.empty()) r.written = write_image(r.image, scene.output, r.metadata);

  const RenderStats& st = r.stats;
  std::snprintf(buf, sizeof buf,
                "%.2f s, %u threads, %llux%llu px, %u spp, %llu primary rays, %llu ray queries, "
                "%.3g queries/s (%.3g per thread)",
                st.seconds, st.threads, (unsigned long long)cam.width(), (unsigned long long)cam.height(),
                scene.spp, (unsigned long long)st.primary_rays, (unsigned long long)st.queries,
                double(st.queries) / st.seconds, double(st.queries) / st.seconds / st.threads);
  ctl.info(buf);
  return r;
}

}  // namespace rayscan::render
