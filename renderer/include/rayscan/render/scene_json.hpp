// Scene parsing from an in-memory JSON document (private to the renderer: the public API reads
// files, load_scene, or resolves command lines, resolve_scene in quick_look.hpp).
#pragma once

#include "rayscan/render/scene.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace rayscan::render {

/// What parse_scene_json may leave out, and how its errors name the scene.
struct SceneParseOptions {
  /// Without it a scene without "camera" is valid (Scene::camera unset: resolve_scene gives it
  /// the overview camera).
  bool camera_required = true;
  /// Without it a scene without "cloud" is valid (Scene::cloud empty: the caller supplies the
  /// points, e.g. RenderJobOptions::cloud).
  bool cloud_required = true;
  /// What errors call the scene ("scene dict: /camera: ..."); "" = the file name.
  std::string name;
};

/// Parse scene JSON `j` as if read from `file` (relative paths resolve against its folder; errors
/// name `file`, or options.name, and the JSON pointer). Same rules and errors as load_scene,
/// except for what `options` lets a scene leave out.
Scene parse_scene_json(const nlohmann::json& j, const std::filesystem::path& file, const SceneParseOptions& options = {});

}  // namespace rayscan::render
