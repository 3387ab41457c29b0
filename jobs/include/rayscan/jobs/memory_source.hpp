// The name the jobs give data handed to them in memory rather than as a file.
#pragma once

#include <string_view>

namespace rayscan::jobs {

/// How a job names points or an image given in memory (VisibilityJobOptions::cloud,
/// SolarJobOptions::cloud, RenderJobOptions::cloud, CompareJobOptions::reference / image) where it
/// would name a file: at the start of a message ("(memory): the point cloud has no points"), in
/// its log lines, its report and its outputs' metadata ("rayscan:cloud", RAYSCAN_SOURCE). The
/// point jobs take another name instead in their options (`source_label`), as the Python module
/// gives the keyword that passed the points ("cloud: the point cloud has no points").
inline constexpr std::string_view kMemorySource = "(memory)";

}  // namespace rayscan::jobs
