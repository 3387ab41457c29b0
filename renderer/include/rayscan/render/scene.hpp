// Scene and camera files: the JSON description of a render (schema in scenes/README.md).
#pragma once

#include "rayscan/octree/any_index.hpp"
#include "rayscan/image/aov.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/render/color.hpp"
#include "rayscan/camera/camera_file.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/spacing.hpp"
#include "rayscan/octree/surfel.hpp"
#include "rayscan/io/point_io.hpp"

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::render {

/// The geometry each point stands for.
enum class Primitive {
  sphere,  ///< the paper's model: a sphere of one global radius, shaded with the sphere normal
  surfel   ///< an oriented disc with a per-point normal and radius
};

/// A malformed scene or camera file. what() is one line: "<file>: <JSON pointer>: <what was
/// expected>", e.g. "scenes/x.json: /camera/vfov_deg: expected a number in (0, 180)".
/// The JSON file error of the io library (rayscan/base/json_object.hpp), shared with camera files.
using SceneError = io::JsonFileError;

/// How a ray hits the point spheres (paper section 5.3).
enum class HitMode {
  sphere,        ///< exact: the sphere with the smallest entry parameter (RayOrder::sphere_hit)
  closest_point  ///< the paper's naive mode: the point with the smallest t within r
                 ///< (RayOrder::time), then the entry into that point's sphere
};

/// Where a point's albedo comes from.
enum class ColorMode { rgb, intensity, elevation, classification, constant };

/// Lambertian material of every point.
struct MaterialDesc {
  ColorMode mode = ColorMode::rgb;
  Color constant{0.7f};               ///< albedo for ColorMode::constant, linear, each in [0,1]
  Ramp ramp = Ramp::viridis;          ///< ramp for intensity and elevation
  std::optional<std::array<double, 2>> range;  ///< scalar range mapped to [0,1]; default: 2nd-98th percentile
  float albedo_scale = 1.0f;          ///< multiplies every albedo (then clamped to [0,1])
};

/// Environment radiance for rays that leave the scene.
struct BackgroundDesc {
  bool gradient = true;              ///< RTIOW sky gradient (true) or a constant colour
  Color horizon{1.0f, 1.0f, 1.0f};   ///< gradient colour at and below the horizon (linear)
  Color zenith{0.5f, 0.7f, 1.0f};    ///< gradient colour straight up (linear)
  Color color{1.0f};                 ///< constant radiance when !gradient
  float intensity = 1.0f;            ///< multiplies the background radiance
};

/// A distant sun: a disk of given angular diameter, sampled with shadow rays.
struct SunDesc {
  bool enabled = false;
  Vec3 direction{0.0, 0.0, 1.0};      ///< unit vector from the scene towards the sun
  double angular_diameter_deg = 0.53; ///< apparent diameter of the disk, degrees, in [0, 20]
  float irradiance = 3.0f;            ///< irradiance on a surface facing the sun (relative units)
  Color color{1.0f, 0.95f, 0.85f};    ///< tint multiplying the irradiance (linear)
};

/// Arbitrary output variables: defined once in the core, rayscan/image/aov.hpp.
using rayscan::Aov;
using rayscan::all_aovs;
using rayscan::aov_channels;
using rayscan::parse_aov;
using rayscan::to_string;

/// Output file(s).
struct OutputDesc {
  std::filesystem::path image;        ///< beauty image; format from the extension (.png .jpg .tif .exr)
  unsigned bit_depth = 8;             ///< PNG/TIFF: 8 or 16 (JPEG: 8 only; EXR: exr_half instead)
  bool exr_half = true;               ///< OpenEXR pixel type: half (true) or float
  std::vector<Aov> aovs;              ///< extra outputs
  double exposure = 0.0;              ///< stops: pixel values are multiplied by 2^exposure
};

/// The most samples per pixel a render takes: the bound that a scene file's /spp,
/// SceneOverrides::spp (`rayscan render --spp`, the Python module's render(spp=)) all check.
inline constexpr std::uint32_t kMaxSpp = 1u << 20;

/// The usual command-line changes to a loaded scene (`rayscan render` flags, the Python module's
/// render() arguments), applied by Scene::apply. Unset members change nothing.
struct SceneOverrides {
  std::filesystem::path camera_file;  ///< camera file replacing the scene's camera (scenes/README.md)
  std::filesystem::path colmap_dir;   ///< COLMAP text model folder (cameras.txt, images.txt)
  std::string colmap_image;           ///< NAME of the photo in images.txt (required with colmap_dir)
  std::string primitive;              ///< "sphere" | "surfel"; "" keeps the scene's
  std::optional<std::uint32_t> spp;   ///< samples per pixel, [1, kMaxSpp]
  std::optional<std::uint32_t> width, height;  ///< image size, pixels (fit_image_size)
  std::optional<std::uint64_t> seed;  ///< sampler seed
  std::filesystem::path out;          ///< output image (is_image_file_name)
  std::vector<std::string> aovs;      ///< extra AOVs by name (parse_aov), each at most once; one the
                                      ///< scene already lists is kept once
  std::optional<double> exposure;     ///< output.exposure, stops in [-30, 30]
};

/// A fully parsed render description. Paths are absolute or relative to the working directory
/// (already resolved against the scene file's folder).
struct Scene {
  std::filesystem::path file;                 ///< the scene file ("" when built in code)
  std::filesystem::path cloud;                ///< point cloud file
  std::optional<double> radius;               ///< sphere radius (world units); nullopt = "auto"
  double auto_radius_factor = kDefaultAutoRadiusFactor;  ///< "auto": radius = factor x median NN spacing
  HitMode hit = HitMode::sphere;
  Primitive primitive = Primitive::sphere;    ///< "primitive": "sphere" (the paper's) or "surfel"
  SurfelOptions surfel;                       ///< "surfel": {k_normal, k_radius, radius_factor, ...}
  bool surfel_orient_camera = true;           ///< "surfel"/"orient": "camera" (default) flips normals
                                              ///< towards the camera centre; "up" or [x,y,z] otherwise
  IndexOptions index;                         ///< index type and organisation
  NodeDistance node_distance = NodeDistance::exact;  ///< node pruning bound of the ray query
  MaterialDesc material;
  BackgroundDesc background;
  SunDesc sun;
  Vec3 up{0.0, 0.0, 1.0};                     ///< world up: sky gradient axis, sun elevation axis
  std::optional<Camera> camera;               ///< required in files
  std::filesystem::path camera_file;          ///< where the camera came from ("" = inline)
  std::uint32_t spp = 16;                     ///< samples per pixel
  std::uint32_t max_depth = 4;                ///< path vertices: 1 = direct light only
  std::uint32_t russian_roulette_depth = 0;   ///< start RR at this depth; 0 = off
  std::uint64_t seed = 0;
  double ray_offset = 1e-3;                   ///< bounce-ray origin offset along n, fraction of r
  OutputDesc output;

  /// Applies `overrides`, checking each: a camera file (replaces the camera), the camera of a
  /// COLMAP photo (load_colmap_camera(colmap_dir, colmap_image)), the primitive, samples per
  /// pixel, seed, output image, exposure, extra AOVs, and an image size (Camera::resized: one of
  /// width and height given, the other follows the camera's aspect ratio; the field of view is
  /// kept; the camera is then inline, camera_file "").
  /// Throws SceneError (camera file, COLMAP model) or OptionError naming the field of
  /// SceneOverrides ("aovs 'x': expected ...", written by the CLI as its flag, "--aov 'x': ..."):
  /// a camera file and a COLMAP photo together, an AOV named twice, an exposure outside
  /// [-30, 30], primitive surfel over the scene's hit "closest_point" (a sphere mode), a JPEG
  /// `out` over the scene's output.bit_depth 16.
  void apply(const SceneOverrides& overrides);

  /// The scene as scene-file JSON (2-space indent), every value explicit: load_scene of the text
  /// gives this scene back (camera inline, bit for bit; paths absolute, so the file works from
  /// any folder; no "cloud" when it is empty: points given in memory). What `rayscan render
  /// --print-scene` prints. Throws std::invalid_argument when the camera has no camera-file form
  /// (an orthographic grid, io::camera_to_json) or is unset.
  [[nodiscard]] std::string to_json() const;
};

/// Parse a scene file. Relative paths in it (cloud, camera, output) resolve against its folder.
/// Throws SceneError (file unreadable, JSON syntax, wrong type/range, unknown key) naming the
/// file and the JSON pointer of the offending value.
Scene load_scene(const std::filesystem::path& file);

/// Read the scene's point cloud (io::read_point_cloud with `options`). Throws SceneError
/// "<scene file>: /cloud: <reader's message>" when the file is missing, unreadable or malformed,
/// and "<scene file>: /cloud: <cloud file>: the point cloud has no points" when it is empty.
PointCloud load_cloud(const Scene& scene, const io::ReadOptions& options = {});

/// Parse a camera file (schema in scenes/README.md: look-at or K/[R|t]). Throws SceneError.
/// Defined in the io library (rayscan/camera/camera_file.hpp) so analysis reads cameras without the
/// renderer.
using io::load_camera;

/// The image file extensions write_image() accepts (lower case, with the dot): .png .jpg .jpeg
/// .tif .tiff .exr. The one list behind `output.image` in scene files and `rayscan render --out`.
const std::vector<std::string>& image_extensions();

/// True when `file` ends in one of image_extensions() (case-insensitive).
bool is_image_file_name(const std::filesystem::path& file);

/// True when `file` ends in .jpg or .jpeg (case-insensitive): an image of 8 bits per channel only.
bool is_jpeg_file_name(const std::filesystem::path& file);

/// The error text for a name failing is_image_file_name():
/// "expected a file name ending in .png, .jpg, .jpeg, .tif, .tiff or .exr".
std::string image_file_name_expected();


}  // namespace rayscan::render
