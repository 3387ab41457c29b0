// `rayscan render`: path-trace a scanned site from a JSON scene (paper section 5.3); the job is
// jobs::run_render (rayscan/jobs/render.hpp), jobs::run_ortho_map for --ortho-map and
// jobs::run_render_frames for --frames.
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/image/aov.hpp"
#include "rayscan/jobs/quick_look.hpp"
#include "rayscan/jobs/render.hpp"

#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::cli {

namespace {

/// The names --aov takes: every AOV's (to_string) in the canonical order (all_aovs).
std::vector<std::string> aov_names() {
  std::vector<std::string> names;
  for (Aov a : all_aovs()) names.emplace_back(to_string(a));
  return names;
}

struct RenderCliOptions {
  std::string scene, camera, out;
  std::optional<std::uint32_t> spp, width, height;
  std::optional<std::uint64_t> seed;
  unsigned threads = 0;
  std::vector<std::string> aovs;
  std::string primitive, colmap_dir, colmap_image, dsm, frames, cache = "2G";
  std::optional<double> ortho_res, exposure;
  std::string ortho_colour = "albedo";
  CLI::Option* ortho_colour_option = nullptr;  // given or not: it needs --ortho-map
  bool quiet = false, print_scene = false;
};

int run_render(const RenderCliOptions& o) {
  using namespace rayscan::render;
  using namespace rayscan::jobs;
  if (o.ortho_colour_option->count() > 0 && !o.ortho_res) throw UsageError("--ortho-colour: needs --ortho-map RES");
  RenderJobOptions job;
  SceneOverrides ov;
  ov.camera_file = o.camera;
  ov.spp = o.spp;
  ov.width = o.width;
  ov.height = o.height;
  ov.seed = o.seed;
  ov.exposure = o.exposure;
  // A quick look without --out writes <stem>.png in the working directory ("wrote ..." says so).
  const bool default_out = o.out.empty() && !o.print_scene && !o.ortho_res && o.frames.empty() && is_cloud_input(o.scene);
  ov.out = default_out ? quick_look_image_name(o.scene).string() : o.out;
  ov.aovs = o.aovs;
  ov.primitive = o.primitive;
  ov.colmap_dir = o.colmap_dir;
  ov.colmap_image = o.colmap_image;
  // A cloud instead of a scene, or a scene without a camera: an index file is summarised from its
  // header (the render maps it); other points are read once, here, for the render too.
  std::optional<PointCloud> points;
  double read_seconds = 0.0;
  const ResolvedScene rs = resolve_scene(o.scene, ov, [&](const std::filesystem::path& f) {
    const CloudSummary s = summarize_cloud_file(f, points);
    read_seconds = s.read_seconds;
    return s;
  });
  if (o.print_scene) {
    if (o.ortho_res) throw UsageError("--print-scene: not with --ortho-map (the map camera is not a scene camera)");
    std::cout << rs.json << "\n";
    return 0;
  }
  job.scene = rs.scene;
  if (points) {
    job.cloud = &*points;  // read from rs.scene.cloud by summarize_cloud_file
    job.cloud_read_from_scene = true;
    job.cloud_read_seconds = read_seconds;
  }
  job.control.threads = o.threads;
  try {
    job.cache_bytes = static_cast<std::size_t>(rayscan::parse_byte_size(o.cache));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--cache: ") + e.what());
  }
  // MPI (docs/mpi.md): tiles or frames over the ranks; only rank 0 logs, prints and writes.
  job.control.distributor = distributor();
  const bool talk = !o.quiet && is_root();
  job.control.progress = talk;
  if (talk) job.control.log = [](const std::string& s) { std::cerr << "rayscan render: " << s << "\n"; };
  if (rs.overview && !o.ortho_res) {
    const Camera& c = *job.scene.camera;
    job.control.info("no camera given: overview camera " + std::to_string(c.width()) + "x" +
                     std::to_string(c.height()) + " from the south-west (or behind the scanner), " +
                     std::to_string(int(kOverviewPitchDeg)) + " degrees down, framing the whole cloud "
                     "(--print-scene prints it as a scene to edit)");
    job.control.info("up axis " + rs.up.how);
  }
  if (!o.frames.empty()) {
    if (o.ortho_res || !o.colmap_dir.empty() || !o.camera.empty())
      throw UsageError("--frames: the cameras come from the list; do not give --camera, --colmap or --ortho-map");
    std::vector<Camera> cams = load_camera_list(o.frames);
    if (o.width || o.height)
      for (Camera& c : cams) c = c.resized(o.width, o.height);
    const RenderFramesResult fr = run_render_frames(job, cams);
    if (talk && !traffic_summary().empty()) std::cerr << "rayscan render: " << traffic_summary() << "\n";
    if (is_root())
      for (const auto& f : fr.job.written) std::cout << "wrote " << f.string() << "\n";
    return 0;
  }
  if (o.ortho_res) {
    if (o.width || o.height || !o.colmap_dir.empty() || !o.camera.empty())
      throw UsageError("--ortho-map: the map's size comes from RES; do not give --width, --height, --camera or --colmap");
    OrthoMapJobOptions map;
    map.render = std::move(job);
    map.ortho_map = *o.ortho_res;
    map.dsm = o.dsm;
    map.ortho_colour = *analysis::parse_ortho_colour(o.ortho_colour);  // CLI11 checked the name
    const OrthoMapJobResult r = run_ortho_map(map);
    if (!is_root()) return 0;
    if (talk && !traffic_summary().empty()) std::cerr << "rayscan render: " << traffic_summary() << "\n";
    for (const auto& f : r.render.written) std::cout << "wrote " << f.string() << "\n";
    return 0;
  }
  if (!o.dsm.empty()) throw UsageError("--dsm: needs --ortho-map RES");
  RenderJobResult r = run_render(job);
  if (!is_root()) return 0;
  if (talk && !traffic_summary().empty()) std::cerr << "rayscan render: " << traffic_summary() << "\n";
  for (const auto& f : r.written) std::cout << "wrote " << f.string() << "\n";
  return 0;
}

}  // namespace

Runner add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderCliOptions>();
  CLI::App* c = app.add_subcommand(
      "render",
      "Path-trace a point cloud described by a JSON scene (schema: scenes/README.md), or a point cloud "
      "file directly (automatic overview camera). Each point is a sphere or surfel hit through the "
      "octree ray query; writes PNG/JPEG/TIFF/EXR with optional AOVs.");
  c->add_option("scene", o->scene, "Scene file (.json), or a point cloud file (LAS, LAZ, PLY, PCD, ...) for a quick "
                "look: surfels, radius auto, colour from RGB if present else elevation, the default sky gradient and no "
                "sun, and (as for a scene without a camera) an overview camera framing the whole cloud, 600x400 unless "
                "--width/--height")->required();
  c->add_option("--camera", o->camera, "Camera file (JSON), replaces the scene's camera");
  c->add_option("-o,--out", o->out, "Output image (.png .jpg .jpeg .tif .tiff .exr), replaces /output/image; a quick look of a "
                "cloud without it writes <stem>.png in the working directory");
  c->add_option("--spp", o->spp, "Samples per pixel, integer in [1, " + std::to_string(render::kMaxSpp) +
                "] (default: the scene's value, 16 if unset)")->transform(integer_in(1, render::kMaxSpp));
  c->add_option("--seed", o->seed, "Random seed, unsigned 64-bit integer; the image is a pure function of it "
                "(default: the scene's value, 0 if unset)")
      ->transform(random_seed());
  add_threads_option(*c, o->threads, "the image is identical for any count");
  const std::string side = "in pixels, in [1, " + std::to_string(kMaxImageSide) + "]; keeps the field of view, and the ";
  c->add_option("--width", o->width, "Image width " + side + "height follows the aspect ratio unless given (default: "
                "the camera's size)")
      ->transform(integer_in(1, kMaxImageSide));
  c->add_option("--height", o->height, "Image height " + side + "width follows the aspect ratio unless given (default: "
                "the camera's size)")
      ->transform(integer_in(1, kMaxImageSide));
  c->add_option("--cache", o->cache,
                "COPC input (sphere mode): bound on decoded node data (LRU, trimmed as each 4x4 pixel block ends; "
                "plus the nodes of the blocks in flight; e.g. 2G, 512M). A COPC file is traced in place, decoding only the "
                "nodes the rays reach")
      ->capture_default_str();
  c->add_option("--aov", o->aovs, "Extra output (repeatable, each name once)")->check(one_of(aov_names()));
  c->add_option("--exposure", o->exposure, "Exposure in stops, in [-30, 30]: pixel values x 2^EV before PNG/JPEG/TIFF "
                "clip them to [0, 1] (EXR keeps linear values); replaces /output/exposure (default: the scene's "
                "value, 0 if unset)")
      ->check(finite_number(-30, 30));
  c->add_option("--primitive", o->primitive, "Geometry of each point: sphere (the paper's model, one "
                "radius) or surfel (oriented disc with a PCA normal and a radius from the local "
                "spacing); replaces /primitive (default: the scene's value, sphere if unset; a cloud's quick look: surfel)")
      ->check(one_of(kPrimitiveNames));
  c->add_option("--colmap", o->colmap_dir, "COLMAP text model folder (cameras.txt, images.txt): render the "
                "view of the photo given with --image (PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV); replaces the scene's camera, not with --camera");
  c->add_option("--image", o->colmap_image, "Image NAME in the COLMAP model's images.txt (with --colmap)");
  c->add_option("--ortho-map", o->ortho_res, "Top-down orthophoto over the cloud's XY extent at RES world "
                "units per pixel, written as a georeferenced RGBA GeoTIFF (--out .tif; alpha 0 where no point was hit) with the cloud's CRS")
      ->check(positive());
  o->ortho_colour_option =
      c->add_option("--ortho-colour", o->ortho_colour, "With --ortho-map: what each cell shows: albedo (the unshaded "
                    "colour of the points seen from above, the mean over the cell of the first points hit by --spp "
                    "stratified rays, over those that hit; --spp 1: the point under the cell centre; a point's RGB as "
                    "stored in 8-bit sRGB, else the scene's material, for a quick look the elevation ramp; --exposure "
                    "does not apply) or shaded (the path-traced render: sky light and shading, --spp samples per cell)")
          ->check(one_of({analysis::to_string(analysis::OrthoColour::albedo),
                          analysis::to_string(analysis::OrthoColour::shaded)}))
          ->capture_default_str();
  c->add_option("--dsm", o->dsm, "With --ortho-map: also write the digital surface model (elevation of the "
                "first surface per cell, NoData where the ray missed) as a Float32 GeoTIFF");
  c->add_flag("--print-scene", o->print_scene, "Print the effective scene (after every flag, with the automatic "
              "camera when there is none) as JSON on stdout and exit without rendering; `rayscan render` reads it back");
  c->add_option("--frames", o->frames, "Camera list (JSON array of camera objects or camera files, e.g. a "
                "fly-through): render one image per camera, written as <out stem>_0000<ext>, _0001, ...; "
                "under mpirun whole frames are distributed when there are more frames than ranks");
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");
  return [o] { return run_render(*o); };
}

}  // namespace rayscan::cli
