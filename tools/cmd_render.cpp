// `rayscan render`: path-trace a scanned site from a JSON scene (paper section 5.3).
#include "commands.hpp"

#include "rayscan/io/point_io.hpp"
#include "rayscan/render/image_output.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"

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
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
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
  if (o.width || o.height) {
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
  // An index file (.rsi): the tree is mapped, not built; centres and colours come from its
  // stored points in original order.
  std::optional<io::MappedIndex> mapped;
  if (io::is_index_file(scene.cloud)) mapped.emplace(io::MappedIndex::open(scene.cloud));
  const PointCloud cloud = [&] {
    if (mapped) return mapped->to_point_cloud();
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
  std::vector<Color> albedo;
  try {
    albedo = compute_albedo(cloud, scene.material, scene.up);
  } catch (const std::invalid_argument& e) {
    throw UsageError(o.scene + ": /material/color: " + e.what());
  }
  t0 = std::chrono::steady_clock::now();
  AnyIndex index = [&] {
    if (mapped) return AnyIndex(BruteForceIndex(std::span<const Vec3>{}));  // unused
    try {
      return make_index(cloud.positions, scene.index);
    } catch (const std::invalid_argument& e) {
      throw UsageError(o.scene + ": /index: " + e.what());
    }
  }();
  if (mapped)
    std::snprintf(buf, sizeof buf, "mapped index file %s (%zu nodes)", scene.cloud.string().c_str(), mapped->node_count());
  else
    std::snprintf(buf, sizeof buf, "built %s index in %.2f s", scene.index.type.c_str(), seconds_since(t0));
  log(buf);
  double radius;
  if (scene.radius) {
    radius = *scene.radius;
  } else {
    const double spacing = mapped ? median_nn_spacing(*mapped, cloud.positions) : median_nn_spacing(index, cloud.positions);
    if (!(spacing > 0.0))
      throw UsageError(o.scene + ": /radius: \"auto\" needs at least two distinct points; give a number");
    radius = scene.auto_radius_factor * spacing;
    std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x factor %.3g = %.6g",
                  spacing, scene.auto_radius_factor, radius);
    log(buf);
  }

  const RenderSettings settings = make_settings(scene, cloud.positions, albedo, radius);
  const Camera& cam = settings.camera;
  const std::uint64_t tiles = std::uint64_t((cam.width() + 15) / 16) * ((cam.height() + 15) / 16);
  Progress progress(tiles, !o.quiet && Progress::stderr_is_terminal());
  RenderOptions ropt;
  ropt.threads = o.threads;
  ropt.progress = &progress;
  Framebuffer fb;
  const RenderStats st = mapped ? rayscan::render::render_image(*mapped, settings, fb, ropt)
                                : rayscan::render::render_image(index, settings, fb, ropt);

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
                     {"rayscan:render_time_s", num(st.seconds)}};
  if (!scene.camera_file.empty()) meta.emplace_back("rayscan:camera", scene.camera_file.string());
  const auto files = write_image(fb, scene.output, meta);

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
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");
  return [o] { return run_render(*o); };
}

}  // namespace rayscan::cli
