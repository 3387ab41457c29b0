// Camera files: the JSON description of a camera (schema in scenes/README.md: look-at, K/[R|t]
// with optional OpenCV "distortion", or "type" orthographic / equirectangular), read by scene
// files, `rayscan render --camera` and `rayscan visibility --from-camera`.
#pragma once

#include "rayscan/camera/camera.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <string>

namespace rayscan::io {

/// Parse a camera file. Throws JsonFileError (render::SceneError) "<file>: <JSON pointer>: <what
/// was expected>" for an unreadable file, bad JSON, a missing, mistyped or out-of-range value or
/// an unknown key.
Camera load_camera(const std::filesystem::path& file);

/// Parse the camera object `j` found at JSON pointer `ptr` of `file` (for error messages; a scene
/// file's inline "/camera"). Throws JsonFileError.
Camera parse_camera(const nlohmann::json& j, const std::string& file, const std::string& ptr);

/// The camera-file form of `camera` (the inverse of parse_camera: parse_camera(camera_to_json(c))
/// builds the same camera bit for bit), from Camera::description(): look-at, K/[R|t] (with
/// "distortion" when it has any), orthographic or equirectangular; doubles written with enough
/// digits to round-trip. Throws std::invalid_argument for an orthographic grid (a top-down map's
/// camera), which has no camera-file form.
nlohmann::ordered_json camera_to_json(const Camera& camera);

}  // namespace rayscan::io
