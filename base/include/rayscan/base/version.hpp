// The version of rayscan, defined once: CMake's project(VERSION), compiled into rayscan_base.
#pragma once

#include <string>

namespace rayscan {

/// The project version, "MAJOR.MINOR.PATCH" (CMakeLists.txt, project(VERSION)).
[[nodiscard]] const char* version();

/// "rayscan MAJOR.MINOR.PATCH": what the writers put in a file's software field (LAS System
/// Identifier, PLY comment, image "Software" metadata).
[[nodiscard]] std::string software_name();

}  // namespace rayscan
