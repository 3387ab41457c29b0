// `rayscan render`: path-trace a scanned site from a JSON scene (paper section 5.3); the job is
// render::run_render (rayscan/render/render_job.hpp).
#include "commands.hpp"

#include "rayscan/render/render_job.hpp"

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

int run_render(const RenderCliOptions& o) {
  using namespace rayscan::render;
  RenderJobOptions job;
  job.scene = load_scene(o.scene);
  SceneOverrides ov;
  ov.camera_file = o.camera;
  ov.spp = o.spp;
  ov.width = o.width;
  ov.height = o.height;
  ov.seed = o.seed;
  ov.out = o.out;
  ov.aovs = o.aovs;
  apply_overrides(job.scene, ov);
  job.control.threads = o.threads;
  job.control.progress = !o.quiet;
  if (!o.quiet) job.control.log = [](const std::string& s) { std::cerr << "rayscan render: " << s << "\n"; };
  const RenderJobResult r = run_render(job);
  for (const auto& f : r.written) std::cout << "wrote " << f.string() << "\n";
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
                "(default: the scene's value, 0 if unset)")
      ->check([](const std::string& v) {  // CLI11 would wrap "-1" to 2^64-1
        return v.find_first_not_of("0123456789") == std::string::npos && !v.empty()
                   ? std::string()
                   : "expected an unsigned 64-bit integer, got '" + v + "'";
      });
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
