// A quick look without writing JSON: `rayscan render CLOUD.las --out view.png`
// frames the whole cloud with an automatic overview camera, and `--print-scene` prints the
// effective scene as JSON that `rayscan render` reads back.
#pragma once

#include "rayscan/camera/camera.hpp"
#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/render/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace rayscan::jobs {

// The renderer types this job's options and results are made of.
using render::Scene;

/// Image size of the overview camera when neither --width nor --height is given, pixels.
inline constexpr std::uint32_t kOverviewWidth = 600, kOverviewHeight = 400;
/// Overview view angles: the camera looks north-east (bearing 45 degrees, i.e. it stands
/// south-west of the cloud) and down at 35 degrees below the horizontal, with a 40 degree vertical
/// field of view; +z is up.
inline constexpr double kOverviewBearingDeg = 45.0, kOverviewPitchDeg = 35.0, kOverviewVfovDeg = 40.0;

/// The automatic overview camera of a viewer's "zoom to extent": a look-at camera aimed at the
/// centre of `bounds` from the direction above (kOverviewBearingDeg, kOverviewPitchDeg), at the
/// smallest distance at which all 8 corners of the box project inside a width x height image
/// (pinhole, vfov kOverviewVfovDeg, square pixels; exact per-corner fit, then 2% margin), up = +z.
/// World coordinates and units of the cloud. A box of zero size is treated as a 1-unit cube.
/// Throws std::invalid_argument for a zero width or height or an empty/non-finite box.
LookAtParams overview_view(const AABB& bounds, std::uint32_t width, std::uint32_t height);

/// What resolve_scene needs of a point cloud file: its exact bounds (world units) and whether it
/// stores colours (the quick look's material).
struct CloudSummary {
  AABB bounds;
  bool has_rgb = false;
};

/// The summary of an index file from its checked header (exact bounds, stored colour), without
/// reading its points; nullopt for any other file, whose points must be read (a COPC file too:
/// its quick look renders the points read whole). Throws io::IndexError for a bad index file.
std::optional<CloudSummary> summary_in_place(const std::filesystem::path& path);

/// True when `input` names a point cloud rather than a scene: an extension the io library reads
/// (io::format_from_extension) or an index file (.rsi). The one rule of resolve_scene and the CLI.
bool is_cloud_input(const std::filesystem::path& input);

/// The image a quick look of `cloud` writes when no output is given: "<stem>.png" in the working
/// directory, the stem without a ".copc" ("lone-star.copc.laz" -> "lone-star.png").
std::filesystem::path quick_look_image_name(const std::filesystem::path& cloud);

/// The scene a `rayscan render INPUT [flags]` command line means, and its JSON.
struct ResolvedScene {
  Scene scene;       ///< parsed and with every override applied (what the render job runs)
  std::string json;  ///< the effective scene as JSON (Scene::to_json), re-readable by `rayscan render`
  bool overview = false;  ///< the camera is the automatic overview camera
};

/// Resolve a command line's scene. `input` is a point cloud file when its extension is one the io
/// library reads (io::format_from_extension) or an index file (.rsi), else a scene file; for a cloud the scene is {"cloud": input, "radius": "auto",
/// "material": {"color": "rgb" if the cloud has colours else "elevation"}} with the default sky
/// and sun. When the scene has no camera (a cloud, or a scene file without "camera"), the camera
/// is overview_view() of the cloud's bounds at width x height (default 600 x 400; one of them
/// keeps the 3:2 aspect, fit_image_size). The other overrides are applied by Scene::apply, and the
/// JSON is the result's Scene::to_json. `cloud` returns the summary of the file it is given (the
/// input, or the scene's "cloud"; summary_in_place for an index file, else from its
/// points, which the caller may keep for the render) and is called only when needed (a cloud
/// input or a missing camera). Throws SceneError (bad scene file), OptionError (bad override),
/// and what `cloud` throws (io errors).
ResolvedScene resolve_scene(const std::filesystem::path& input, const SceneOverrides& overrides,
                            const std::function<CloudSummary(const std::filesystem::path&)>& cloud);

}  // namespace rayscan::jobs
