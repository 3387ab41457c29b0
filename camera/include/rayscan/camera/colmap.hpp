// COLMAP sparse-model import (COLMAP documentation, "Output Format", text files cameras.txt and
// images.txt; camera models in src/colmap/sensor/models.h): the camera of one registered photo.
#pragma once

#include "rayscan/camera/camera.hpp"

#include <filesystem>
#include <string>

namespace rayscan::render {

/// The camera that took image `image_name` of the COLMAP text model in `dir` (cameras.txt,
/// images.txt). Models: SIMPLE_PINHOLE (f cx cy), PINHOLE (fx fy cx cy), SIMPLE_RADIAL (f cx cy k),
/// RADIAL (f cx cy k1 k2), OPENCV (fx fy cx cy k1 k2 p1 p2). The pose QW QX QY QZ TX TY TZ is the
/// world-to-camera rotation (unit quaternion) and translation. COLMAP puts the centre of the
/// top-left pixel at (0.5, 0.5), rayscan (OpenCV) at (0, 0): the principal point is moved by -0.5.
/// The two files are read under the input policy (rayscan/base/input_file.hpp: regular files of at
/// most 256 MiB). The camera's WIDTH and HEIGHT must be integers in [1, 65536] and every parameter
/// a finite number. Throws io::JsonFileError (render::SceneError) "<file>:<line>: <what was
/// expected>" for a malformed line or field, an unknown image or camera id, or an unsupported
/// model, and "<file>: <reason>" for a file that is missing or not a regular file.
Camera load_colmap_camera(const std::filesystem::path& dir, const std::string& image_name);

}  // namespace rayscan::render
