// Scene::apply: the command line's changes to a loaded scene, each checked with an error that
// names the SceneOverrides field (the CLI writes it as its flag).
#include "rayscan/render/scene.hpp"

#include "rayscan/base/option_error.hpp"
#include "rayscan/camera/colmap.hpp"

#include <algorithm>

namespace rayscan::render {

void Scene::apply(const SceneOverrides& o) {
  if (!o.camera_file.empty()) {
    camera = io::load_camera(o.camera_file);
    camera_file = o.camera_file;
  }
  if (!o.colmap_dir.empty()) {
    if (o.colmap_image.empty())
      throw OptionError({option("colmap_dir"), ": give the photo with ", option("colmap_image"), " NAME"});
    camera = load_colmap_camera(o.colmap_dir, o.colmap_image);
    camera_file = o.colmap_dir / "images.txt";
  } else if (!o.colmap_image.empty()) {
    throw OptionError({option("colmap_image"), ": needs ", option("colmap_dir"), " DIR"});
  }
  if (!o.primitive.empty()) {
    if (o.primitive != "sphere" && o.primitive != "surfel")
      throw OptionError({option("primitive"), " '" + o.primitive + "': expected sphere or surfel"});
    primitive = o.primitive == "surfel" ? Primitive::surfel : Primitive::sphere;
  }
  if (o.spp) {
    if (*o.spp < 1 || *o.spp > (1u << 20)) throw OptionError({option("spp"), ": expected an integer in [1, 1048576]"});
    spp = *o.spp;
  }
  if (o.seed) seed = *o.seed;
  if (!o.out.empty()) {
    if (!is_image_file_name(o.out))
      throw OptionError({option("out"), " '" + o.out.string() + "': " + image_file_name_expected()});
    output.image = o.out;
  }
  for (const std::string& a : o.aovs) {
    const std::optional<Aov> v = parse_aov(a);
    if (!v) throw OptionError({option("aovs"), " '" + a + "': " + aov_names_expected()});
    if (std::find(output.aovs.begin(), output.aovs.end(), *v) == output.aovs.end()) output.aovs.push_back(*v);
  }
  if (o.width || o.height) {
    if (!camera) throw OptionError({option("width"), "/", option("height"), ": the scene has no camera"});
    camera = camera->resized(o.width, o.height);
    camera_file.clear();  // no longer the file's camera (image metadata names the file only when it is)
  }
}

}  // namespace rayscan::render
