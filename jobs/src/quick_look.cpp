// The overview camera and command-line scene resolution (rayscan/jobs/quick_look.hpp).
#include "rayscan/jobs/quick_look.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/scene_json.hpp"

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

json vec(const Vec3& v) { return json::array({v.x, v.y, v.z}); }

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

ResolvedScene resolve_scene(const std::filesystem::path& input, const SceneOverrides& ov,
                            const std::function<const PointCloud&(const std::filesystem::path&)>& cloud) {
  namespace fs = std::filesystem;
  ResolvedScene res;
  json j;
  // A point cloud by its extension (io::format_from_extension); anything else is read as a scene,
  // so its errors (not JSON, a device, missing) are the scene file's.
  bool is_scene = false;
  try {
    (void)io::format_from_extension(input);
  } catch (const io::FormatError&) {
    is_scene = true;
  }
  const fs::path base = fs::absolute(input);
  if (is_scene) {
    j = io::parse_json_file(input);
    if (!j.is_object()) io::json_fail(input.string(), "", "expected a JSON object (a scene)");
    // Relative paths become absolute, so the printed scene works from any folder.
    if (j.contains("cloud") && j["cloud"].is_string())
      j["cloud"] = (fs::path(j["cloud"].get<std::string>()).is_relative() ? base.parent_path() / j["cloud"].get<std::string>()
                                                                          : fs::path(j["cloud"].get<std::string>()))
                       .lexically_normal()
                       .string();
    if (j.contains("camera") && j["camera"].is_string()) {
      const fs::path cf = fs::path(j["camera"].get<std::string>()).is_relative()
                              ? base.parent_path() / j["camera"].get<std::string>()
                              : fs::path(j["camera"].get<std::string>());
      j["camera"] = cf.lexically_normal().string();
    }
    if (j.contains("output") && j["output"].is_object() && j["output"].contains("image") &&
        j["output"]["image"].is_string() && fs::path(j["output"]["image"].get<std::string>()).is_relative())
      j["output"]["image"] = (base.parent_path() / j["output"]["image"].get<std::string>()).lexically_normal().string();
  } else {
    const PointCloud& pc = cloud(base);
    j = json::object();
    j["cloud"] = base.lexically_normal().string();
    j["radius"] = "auto";
    j["material"] = {{"color", pc.rgb.empty() ? "elevation" : "rgb"}};
  }
  // A camera file replaces the scene's camera before parsing (a scene may have none); the other
  // overrides are applied (and checked, with their own messages) by apply_overrides on the parsed
  // scene and written into the JSON afterwards.
  if (!ov.camera_file.empty()) j["camera"] = fs::absolute(ov.camera_file).lexically_normal().string();
  SceneOverrides rest = ov;  // what is left for apply_overrides
  bool printable = ov.colmap_dir.empty();  // a COLMAP view is not a camera JSON
  if (!j.contains("camera")) {  // (a COLMAP view replaces it in apply_overrides)
    std::uint32_t w = kOverviewWidth, h = kOverviewHeight;
    if (ov.width && ov.height) {
      w = *ov.width;
      h = *ov.height;
    } else if (ov.width) {
      w = *ov.width;
      h = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::lround(w * double(kOverviewHeight) / kOverviewWidth)));
    } else if (ov.height) {
      h = *ov.height;
      w = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::lround(h * double(kOverviewWidth) / kOverviewHeight)));
    }
    if (!j.contains("cloud") || !j["cloud"].is_string())
      io::json_fail(input.string(), "/cloud", "required: point cloud file (string, relative to the scene file)");
    const LookAtParams p = overview_view(cloud(fs::path(j["cloud"].get<std::string>())).bounds(), w, h);
    j["camera"] = {{"width", w}, {"height", h}, {"position", vec(p.position)}, {"look_at", vec(p.look_at)},
                   {"up", vec(p.up)}, {"vfov_deg", p.vfov_deg}};
    res.overview = true;
    rest.width.reset();
    rest.height.reset();
  } else if (ov.width || ov.height) {
    // Inline a camera file, then state the new size when the camera is a look-at one (its field of
    // view is kept, as apply_overrides does); a K/[R|t] camera's resize cannot be written as JSON.
    if (j.contains("camera") && j["camera"].is_string()) j["camera"] = io::parse_json_file(j["camera"].get<std::string>());
    json& cam = j["camera"];
    if (cam.is_object() && !cam.contains("K") && cam.contains("width") && cam.contains("height") &&
        cam["width"].is_number_unsigned() && cam["height"].is_number_unsigned()) {
      const double cw = cam["width"].get<double>(), ch = cam["height"].get<double>();
      const double w = ov.width ? double(*ov.width) : std::round(cw * *ov.height / ch);
      const double h = ov.height ? double(*ov.height) : std::round(ch * *ov.width / cw);
      if (w >= 1 && w <= 65536 && h >= 1 && h <= 65536) {
        cam["width"] = static_cast<std::uint32_t>(w);
        cam["height"] = static_cast<std::uint32_t>(h);
      }
    } else {
      printable = false;  // a resized K/[R|t] camera
    }
  }
  // Parse the JSON as the scene (one parser for files, quick looks and printed scenes).
  const fs::path as_file = is_scene ? base : base.parent_path() / (base.filename().string() + ".scene.json");
  res.scene = parse_scene_json(j, as_file);
  if (!is_scene) res.scene.file = fs::path();
  apply_overrides(res.scene, rest);
  if (!ov.primitive.empty()) j["primitive"] = ov.primitive;
  if (ov.spp) j["spp"] = *ov.spp;
  if (ov.seed) j["seed"] = *ov.seed;
  if (!ov.out.empty() || !ov.aovs.empty()) {
    if (!j.contains("output") || !j["output"].is_object()) j["output"] = json::object();
    if (!ov.out.empty()) j["output"]["image"] = fs::absolute(ov.out).lexically_normal().string();
    if (!ov.aovs.empty()) {
      json& a = j["output"]["aovs"];
      if (!a.is_array()) a = json::array();
      for (const std::string& name : ov.aovs)
        if (std::find(a.begin(), a.end(), json(name)) == a.end()) a.push_back(name);
    }
  }
  res.json = printable ? j.dump(2) : std::string();
  return res;
}

}  // namespace rayscan::jobs
