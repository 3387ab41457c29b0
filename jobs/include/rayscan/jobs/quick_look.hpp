// A quick look without writing JSON: `rayscan render CLOUD.las --out view.png`
// frames the whole cloud with an automatic overview camera, and `--print-scene` prints the
// effective scene as JSON that `rayscan render` reads back.
#pragma once

#include "rayscan/camera/camera.hpp"
#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/jobs/memory_source.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/render/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The renderer types this job's options and results are made of.
using render::Scene;

/// Image size of the overview camera when neither --width nor --height is given, pixels.
inline constexpr std::uint32_t kOverviewWidth = 600, kOverviewHeight = 400;
/// Overview view angles: the camera looks north-east (bearing 45 degrees, i.e. it stands
/// south-west of the cloud) and down at 45 degrees below the horizontal, with a 40 degree vertical
/// field of view. "North" is +y and "down" is -up (the cloud's up axis, CloudSummary::up).
inline constexpr double kOverviewBearingDeg = 45.0, kOverviewPitchDeg = 45.0, kOverviewVfovDeg = 40.0;
/// At most this many points frame the overview camera and estimate the up axis: enough for the
/// extent of any cloud to within its sampling. They are the points with the smallest hash of their
/// coordinates' bits, a uniform sample that is the same whatever order the points are stored in
/// (a cloud file and its index file give the same camera and up axis).
inline constexpr std::size_t kOverviewSample = 65536;

/// The automatic overview camera of a viewer's "zoom to extent": a look-at camera aimed at the
/// centre of `bounds` from the direction above (kOverviewBearingDeg, kOverviewPitchDeg), at the
/// smallest distance at which all 8 corners of the box project inside a width x height image
/// (pinhole, vfov kOverviewVfovDeg, square pixels; exact per-corner fit, then 2% margin), up = +z.
/// World coordinates and units of the cloud. A box of zero size is treated as a 1-unit cube.
/// Throws std::invalid_argument for a zero width or height or an empty/non-finite box.
LookAtParams overview_view(const AABB& bounds, std::uint32_t width, std::uint32_t height);

/// The up axis of a cloud for the overview camera, and how it was found (printed by the CLI).
struct UpAxis {
  Vec3 up{0.0, 0.0, 1.0};      ///< unit vector, world frame
  std::string how;             ///< e.g. "+z (georeferenced: the CRS's vertical)"
  std::optional<Vec3> facing;  ///< scans with a scanner position: from it towards the points (the
                               ///< overview looks along it instead of north-east)
};

/// The overview camera over the points themselves, as a viewer's "zoom to extent": seen from
/// kOverviewPitchDeg above the horizontal about the unit axis `axis.up`, looking along
/// `axis.facing` when set, else along bearing kOverviewBearingDeg from the projection of +y on the
/// plane normal to the up axis (+x when up is +-y), aimed so that the points'
/// projection is centred in the image, at the smallest distance at which every point projects
/// inside it (exact per point), then a 2% margin: the points' projected extent spans about 98% of
/// the image along one axis (framing the points, not their box, whose empty corners would push the
/// camera back). World coordinates and units. Points that all coincide are framed as a 1-unit
/// cube around them.
/// Throws std::invalid_argument for a zero width or height, no points, non-finite points or a zero
/// or non-finite up axis.
LookAtParams overview_view(std::span<const Vec3> points, const UpAxis& axis, std::uint32_t width,
                           std::uint32_t height);

/// The up axis of a point cloud: +z when it is georeferenced (`georeferenced`: it has a CRS);
/// -y for a depth camera's cloud (a `sensor` position with the points' centroid ahead of it,
/// within 45 degrees of +z: the camera's optical frame, x right, y down, z forward, ROS REP 103;
/// not a georeferenced PCD's default identity VIEWPOINT far from its points), refined to the dominant
/// plane's normal when that lies within 20 degrees of it (a tilted camera); else estimated from
/// `sample` (points of the cloud, world units): the normal of the dominant
/// plane, i.e. the PCA normal (16 nearest neighbours) direction shared by the most sample points
/// within 10 degrees, refined as their mean, its sign chosen so that `sensor` (the scanner
/// position: a PCD VIEWPOINT's translation, unless it is the origin of a cloud that is not a
/// camera's view) or else the sample's centroid lies above the most
/// populated plane of that orientation (a floor or the ground: the scanner and the scene stand on
/// it). When that point lies within the plane's thickness (3 x the median distance of the points
/// of that orientation from the plane, at least 0.1% of the sample's bounding-box diagonal), as
/// for a flat cloud, the points cannot tell up from down and the sign is the convention of
/// scanners and meshes (+z up, else +y, else +x): the normal's largest-magnitude component
/// positive, ties going to z, then y. Falls back to +z when fewer than 20% of the sample share an
/// orientation or the sample has fewer than 64 points. With a `sensor`, `facing` is the direction
/// from it to the centroid.
UpAxis estimate_up_axis(std::span<const Vec3> sample, bool georeferenced, const std::optional<Vec3>& sensor);

/// What resolve_scene needs of a point cloud file: its exact bounds (world units), whether it
/// stores colours (the quick look's material), a sample of its points and its up axis (the
/// overview camera's framing and orientation), and whether a quick look can size its points.
struct CloudSummary {
  AABB bounds;
  bool has_rgb = false;
  std::vector<Vec3> sample;  ///< at most kOverviewSample points, chosen by their coordinates alone
  UpAxis up;
  std::uint64_t points = 0;  ///< the number of points
  /// At least 2 of the points lie at distinct positions: a quick look sizes its surfels (or its
  /// spheres' "auto" radius) from their spacing, which fewer have none of.
  bool distinct = false;
  /// summarize_cloud_file: seconds spent reading the file's points (0 when none were read: an
  /// index file, or points the caller had already read).
  double read_seconds = 0.0;
};

/// The summary of a cloud's points (any order, the same summary for every order):
/// bounds_of(positions), the sample (kOverviewSample; one pass over the positions) and
/// estimate_up_axis(sample, georeferenced, sensor). Throws std::invalid_argument for no points.
CloudSummary summarize_cloud(std::span<const Vec3> positions, bool has_rgb, bool georeferenced,
                             const std::optional<Vec3>& sensor);

/// The summary of an index file from its checked header (exact bounds, stored colour) and one
/// pass over its mapped positions (the sample: equal to summarize_cloud's of the source cloud);
/// nullopt for any other file, whose points must be read (a COPC file too: its quick look renders
/// the points read whole). Throws io::IndexError for a bad index file.
std::optional<CloudSummary> summary_in_place(const std::filesystem::path& path);

/// The summary of the point cloud file `file`, as `rayscan render` takes it for resolve_scene:
/// summary_in_place for an index file; else the points are read (no scalar fields) into `points`,
/// which the caller may keep for the render (RenderJobOptions::cloud), and summarised
/// (summarize_cloud: georeferenced when the file has a CRS, a PCD VIEWPOINT's translation as the
/// scanner position), with the read's time in read_seconds. Throws the reader's errors and std::invalid_argument "<file>: the point
/// cloud has no points".
CloudSummary summarize_cloud_file(const std::filesystem::path& file, std::optional<PointCloud>& points);

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
  UpAxis up;              ///< the overview camera's up axis and how it was found (overview only)
};

/// Resolve a command line's scene. `input` is a point cloud file when its extension is one the io
/// library reads (io::format_from_extension) or an index file (.rsi), else a scene file; for a cloud the scene is {"cloud": input, "radius": "auto",
/// "primitive": "surfel", "material": {"color": "rgb" if the cloud has colours else
/// "elevation"}, "up": the summary's up axis (the elevation ramp's, the sky's and the overview
/// camera's)} with the default sky gradient and no sun (surfels: the primitive that measures best on the
/// fidelity scenes, docs/fidelity.md; --primitive sphere for the paper's). When the scene has no
/// camera (a cloud, or a scene file without "camera"), the camera is overview_view() of the
/// summary's sample about its up axis at width x height (default 600 x 400; one of them
/// keeps the 3:2 aspect, fit_image_size). The other overrides are applied by Scene::apply, and the
/// JSON is the result's Scene::to_json. `cloud` returns the summary of the file it is given (the
/// input, or the scene's "cloud"; summary_in_place for an index file, else from its
/// points, which the caller may keep for the render) and is called only when needed (a cloud
/// input or a missing camera). Throws SceneError (bad scene file), OptionError (bad override),
/// std::invalid_argument "<input>: a quick look needs at least 2 distinct points ..." for a cloud
/// input without them (CloudSummary::distinct), and what `cloud` throws (io errors).
/// With `cloud_given` the caller supplies the points (RenderJobOptions::cloud, or Scene::cloud set
/// afterwards): a scene file without "cloud" is valid, and `cloud` is asked for the summary with
/// the scene's "cloud" (empty when it has none) and should summarise the supplied points.
ResolvedScene resolve_scene(const std::filesystem::path& input, const SceneOverrides& overrides,
                            const std::function<CloudSummary(const std::filesystem::path&)>& cloud,
                            bool cloud_given = false);

/// resolve_scene for scene JSON given as text instead of a file (the Python module's scene dict):
/// relative file names resolve against the working directory, errors name the scene `name`
/// ("scene dict: /camera: ..."), and Scene::file is `name`. `cloud` and `cloud_given` as for
/// resolve_scene. Throws SceneError (invalid JSON, not an object, a bad scene), OptionError, and
/// what `cloud` throws.
ResolvedScene resolve_scene_text(const std::string& json, const std::string& name, const SceneOverrides& overrides,
                                 const std::function<CloudSummary(const std::filesystem::path&)>& cloud,
                                 bool cloud_given = false);

/// The quick look of points in memory (no file): the scene resolve_scene makes of a point cloud
/// file, without "cloud" (render it with RenderJobOptions::cloud), its overview camera framing
/// `summary` (summarize_cloud of those points). Throws OptionError (bad override), and
/// std::invalid_argument "<source_label>: a quick look needs at least 2 distinct points ..." for
/// points without them (CloudSummary::distinct); `source_label` names the points (kMemorySource,
/// or the Python keyword that gave them).
ResolvedScene resolve_quick_look(const CloudSummary& summary, const SceneOverrides& overrides,
                                 std::string_view source_label = kMemorySource);

}  // namespace rayscan::jobs
