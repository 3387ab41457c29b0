// Scene parsing from an in-memory JSON document (private to the renderer: the public API reads
// files, load_scene, or resolves command lines, resolve_scene in quick_look.hpp).
#pragma once

#include "rayscan/render/scene.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace rayscan::render {

/// Parse scene JSON `j` as if read from `file` (relative paths resolve against its folder; errors
/// name `file` and the JSON pointer). Same rules and errors as load_scene, except that without
/// `camera_required` a scene without "camera" is valid (Scene::camera unset: the command line's
/// quick look gives it the overview camera).
Scene parse_scene_json(const nlohmann::json& j, const std::filesystem::path& file, bool camera_required = true);

}  // namespace rayscan::render
