// Scene::apply: the command line's changes to a loaded scene, each checked with an error that
// names the SceneOverrides field (the CLI writes it as its flag).
#include "rayscan/render/scene.hpp"

#include "rayscan/base/option_error.hpp"
#include "rayscan/camera/colmap.hpp"

#include <algorithm>

namespace rayscan::render {

void Scene::apply(const SceneOverrides& o) {
  if (!o.camera_file.empty() && !o.colmap_dir.empty())
    throw OptionError({option("colmap_dir"), ": the camera is the COLMAP photo's; do not give ", option("camera_file"),
                       " too"});
  if (!o.camera_file.empty()) {
    camera = io::load_camera(o.camera_file);
    camera_file = std::filesystem::absolute(o.camera_file).lexically_normal();  // image metadata names it
  }
  if (!o.colmap_dir.empty()) {
    if (o.colmap_image.empty())
      throw OptionError({option("colmap_dir"), ": give the photo with ", option("colmap_image"), " NAME"});
    camera = load_colmap_camera(o.colmap_dir, o.colmap_image);
    camera_file = std::filesystem::absolute(o.colmap_dir / "images.txt").lexically_normal();
  } else if (!o.colmap_image.empty()) {
    throw OptionError({option("colmap_image"), ": needs ", option("colmap_dir"), " DIR"});
  }
  if (!o.primitive.empty()) {
    if (o.primitive != "sphere" && o.primitive != "surfel")
      throw OptionError({option("primitive"), " '" + o.primitive + "': expected sphere or surfel"});
    primitive = o.primitive == "surfel" ? Primitive::surfel : Primitive::sphere;
    if (primitive == Primitive::surfel && hit == HitMode::closest_point)
      throw OptionError({option("primitive"), " 'surfel': the scene's /hit \"closest_point\" applies to spheres only"});
  }
  if (o.spp) {
    if (*o.spp < 1 || *o.spp > kMaxSpp) throw OptionError({option("spp"), ": expected an integer in [1, " + std::to_string(kMaxSpp) + "]"});
    spp = *o.spp;
  }
  if (o.seed) seed = *o.seed;
  if (!o.out.empty()) {
    if (!is_image_file_name(o.out))
      throw OptionError({option("out"), " '" + o.out.string() + "': " + image_file_name_expected()});
    if (output.bit_depth == 16 && is_jpeg_file_name(o.out))
      throw OptionError({option("out"), " '" + o.out.string() +
                                            "': a JPEG image has 8 bits per channel; the scene's /output/bit_depth is 16"});
    output.image = o.out;
  }
  if (o.exposure) {
    if (!(*o.exposure >= -30.0 && *o.exposure <= 30.0))
      throw OptionError({option("exposure"), ": expected a number in [-30, 30] (stops)"});
    output.exposure = *o.exposure;
  }
  // Each AOV at most once, as in a scene file's output.aovs (all checked before any is added);
  // one the scene already lists is kept once.
  std::vector<Aov> given;
  for (const std::string& a : o.aovs) {
    const std::optional<Aov> v = parse_aov(a);
    if (!v) throw OptionError({option("aovs"), " '" + a + "': " + aov_names_expected()});
    if (std::find(given.begin(), given.end(), *v) != given.end())
      throw OptionError({option("aovs"), " '" + a + "': given twice"});
    given.push_back(*v);
  }
  for (Aov v : given)
    if (std::find(output.aovs.begin(), output.aovs.end(), v) == output.aovs.end()) output.aovs.push_back(v);
  if (o.width || o.height) {
    if (!camera) throw OptionError({option("width"), "/", option("height"), ": the scene has no camera"});
    camera = camera->resized(o.width, o.height);
    camera_file.clear();  // no longer the file's camera (image metadata names the file only when it is)
  }
}

}  // namespace rayscan::render
