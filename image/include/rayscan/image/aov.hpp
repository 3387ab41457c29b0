// Arbitrary output variables (AOVs): the one list of their names and file
// channel names, used by scene files, `rayscan render --aov`, the renderer's EXR writer, the
// compare job's channel aliases and the Python module. In the core so that analysis needs no
// renderer to read a render's channels.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan {

/// Extra per-pixel outputs of a render, written next to the beauty image.
enum class Aov { depth, normal, position, index, albedo, cost };

/// Every AOV in its canonical order (depth, normal, position, index, albedo, cost).
const std::vector<Aov>& all_aovs();

/// The name of an AOV as used in scene files, options and reports ("depth", "normal", ...).
const char* to_string(Aov aov);

/// The AOV called `name` (exact, lower case), or nullopt.
std::optional<Aov> parse_aov(std::string_view name);

/// "expected depth, normal, position, index, albedo or cost": the error text for a bad AOV name.
std::string aov_names_expected();

/// The EXR channel names of an AOV (image_output.hpp): depth {"Z"}, normal {"N.X","N.Y","N.Z"},
/// position {"P.X","P.Y","P.Z"}, index {"id"} (uint32, kNoPoint for a miss), albedo
/// {"albedo.R","albedo.G","albedo.B"}, cost {"cost"}.
const std::vector<std::string>& aov_channels(Aov aov);

}  // namespace rayscan
