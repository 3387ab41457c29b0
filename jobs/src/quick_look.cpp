// The overview camera and command-line scene resolution (rayscan/jobs/quick_look.hpp).
#include "rayscan/jobs/quick_look.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/scene_json.hpp"
#include "rayscan/site/index_file.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace rayscan::jobs {

using namespace rayscan::render;  // the renderer library's types, which this job speaks in
using namespace rayscan::io;

namespace {

using nlohmann::json;

}  // namespace

LookAtParams overview_view(const AABB& bounds, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0) throw std::invalid_argument("overview camera: image size must be at least 1x1");
  const Vec3 lo = bounds.lo, hi = bounds.hi;
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) || !std::isfinite(lo.x + lo.y + lo.z + hi.x + hi.y + hi.z))
    throw std::invalid_argument("overview camera: the cloud's bounding box is empty or not finite");
  const Vec3 c = 0.5 * (lo + hi);
  Vec3 half = 0.5 * (hi - lo);
  if (glm::length(half) == 0.0) half = Vec3(0.5);
  const double deg = std::numbers::pi / 180.0;
  const double az = kOverviewBearingDeg * deg, el = kOverviewPitchDeg * deg;
  // Forward f (towards the target), right r, camera up u (right-handed, u has +z component).
  const Vec3 f(std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), -std::sin(el));
  const Vec3 r = glm::normalize(glm::cross(f, Vec3(0.0, 0.0, 1.0)));
  const Vec3 u = glm::cross(r, f);
  const double tv = std::tan(0.5 * kOverviewVfovDeg * deg);
  const double th = tv * double(width) / double(height);
  // The eye is c - D f. Corner p projects inside when |x| <= z th and |y| <= z tv with
  // x = (p - c).r, y = (p - c).u, z = (p - c).f + D: D >= |x| / th - (p - c).f, likewise for y.
  double D = 0.0;
  for (int k = 0; k < 8; ++k) {
    const Vec3 p = c + Vec3((k & 1) ? half.x : -half.x, (k & 2) ? half.y : -half.y, (k & 4) ? half.z : -half.z);
    const Vec3 v = p - c;
    const double z0 = glm::dot(v, f);
    D = std::max({D, std::abs(glm::dot(v, r)) / th - z0, std::abs(glm::dot(v, u)) / tv - z0});
  }
  // 2% margin. Every corner then lies in front of the eye (z >= |x| / th >= 0), so the eye is
  // outside the box.
  D = 1.02 * D;
  LookAtParams p;
  p.position = c - D * f;
  p.look_at = c;
  p.up = Vec3(0.0, 0.0, 1.0);
  p.vfov_deg = kOverviewVfovDeg;
  return p;
}

std::optional<CloudSummary> summary_in_place(const std::filesystem::path& path) {
  if (io::is_index_file(path)) {
    io::IndexOpenOptions o;
    o.verify = io::IndexOpenOptions::Verify::metadata_only;  // the header is all that is read here
    const io::MappedIndex m = io::MappedIndex::open(path, o);
    return CloudSummary{m.bounds(), !m.rgb().empty()};
  }
  return std::nullopt;
}

bool is_cloud_input(const std::filesystem::path& input) {
  if (io::is_index_file(input)) return true;
  try {
    (void)io::format_from_extension(input);
    return true;
  } catch (const io::FormatError&) {
    return false;
  }
}

std::filesystem::path quick_look_image_name(const std::filesystem::path& cloud) {
  std::string stem = cloud.stem().string();
  if (lower_extension(stem) == ".copc") stem = std::filesystem::path(stem).stem().string();
  return stem + ".png";
}

ResolvedScene resolve_scene(const std::filesystem::path& input, const SceneOverrides& ov,
                            const std::function<CloudSummary(const std::filesystem::path&)>& cloud) {
  namespace fs = std::filesystem;
  ResolvedScene res;
  // A point cloud by its extension (io::format_from_extension); anything else is read as a scene,
  // so its errors (not JSON, a device, missing) are the scene file's.
  const bool is_scene = !is_cloud_input(input);
  const fs::path base = fs::absolute(input);
  json j;
  if (is_scene) {
    j = io::parse_json_file(input);
    if (!j.is_object()) io::json_fail(input.string(), "", "expected a JSON object (a scene)");
  } else {
    j = {{"cloud", base.lexically_normal().string()},
         {"radius", "auto"},
         {"material", {{"color", cloud(base).has_rgb ? "rgb" : "elevation"}}}};
  }
  // A camera from the command line replaces the scene's, which is then not read at all.
  if (!ov.camera_file.empty() || !ov.colmap_dir.empty()) j.erase("camera");
  // Parsed once (one parser for scene files and quick looks); a scene may lack a camera here.
  const fs::path as_file = is_scene ? base : base.parent_path() / (base.filename().string() + ".scene.json");
  res.scene = parse_scene_json(j, as_file, /*camera_required=*/false);
  if (!is_scene) res.scene.file = fs::path();
  SceneOverrides rest = ov;
  if (!res.scene.camera && ov.camera_file.empty() && ov.colmap_dir.empty()) {
    // The overview camera, at the size the flags ask for (fit_image_size keeps its 3:2 aspect).
    const ImageSize size = fit_image_size({kOverviewWidth, kOverviewHeight}, ov.width, ov.height);
    const LookAtParams p = overview_view(cloud(res.scene.cloud).bounds, size.width, size.height);
    res.scene.camera = Camera::look_at(p, size.width, size.height);
    res.overview = true;
    rest.width.reset();
    rest.height.reset();
  }
  res.scene.apply(rest);
  res.json = res.scene.to_json();
  return res;
}

}  // namespace rayscan::jobs
