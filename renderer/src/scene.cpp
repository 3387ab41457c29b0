// Scene/camera JSON parsing. Every value is read through Obj, which records the JSON pointer of
// what it reads so that an error names the exact field, and rejects keys it was not asked about.
#include "rayscan/render/scene.hpp"
#include "rayscan/render/scene_json.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/camera/camera_file.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/base/option_error.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string_view>

namespace rayscan::render {

namespace {

using nlohmann::json;

using Obj = io::JsonObject;

[[noreturn]] void fail(const std::string& file, const std::string& ptr, const std::string& what) {
  io::json_fail(file, ptr, what);
}

json parse_file(const std::filesystem::path& file) { return io::parse_json_file(file); }

std::filesystem::path resolve(const std::filesystem::path& base_file, const std::string& p) {
  std::filesystem::path path(p);
  if (path.is_relative()) path = base_file.parent_path() / path;
  return path.lexically_normal();
}

/// "surfel": {"k_normal", "k_radius", "radius_factor", "max_radius_factor", "orient"}.
void parse_surfel(Obj& parent, Scene& s) {
  if (!parent.has("surfel")) return;
  Obj o(parent.at("surfel"), parent.file(), parent.ptr("surfel"));
  SurfelOptions& so = s.surfel;
  so.k_normal = static_cast<unsigned>(o.integer("k_normal", so.k_normal, 3, 256));
  so.k_radius = static_cast<unsigned>(o.integer("k_radius", so.k_radius, 1, 256));
  so.radius_factor = o.number("radius_factor", so.radius_factor, 0.0, 100.0, true, false);
  so.max_radius_factor = o.number("max_radius_factor", so.max_radius_factor, 0.0, 1000.0, true, false);
  if (o.has("orient")) {
    const json& v = o.at("orient");
    if (v.is_array()) {
      so.orientation.viewpoint = o.vec3_at(v, o.ptr("orient"), false);
      s.surfel_orient_camera = false;
    } else {
      const std::string m = o.string_at(v, o.ptr("orient"), {"camera", "up"});
      s.surfel_orient_camera = m == "camera";
    }
  }
  o.finish();
}

/// The scene key of an index option (IndexOption's field, as OptionError names it).
std::string index_option_key(std::string_view field) { return field == "insertion" ? "build" : std::string(field); }

/// Refuses an octree key the layout does not use (capacity or max_depth with "fixed", depth with
/// "adaptive" or "layered") by the rule `rayscan query`, `rayscan index` and Python apply
/// (check_applicable), as a JsonFileError at the key: "FILE: /index/capacity: applies to "layout":
/// "adaptive" and "layered" only (got "layout": "fixed")". The kd-tree and brute force do not read
/// the octree's keys, so finish() refuses those as unknown.
void check_octree_keys(const Obj& o, const std::string& type) {
  GivenIndexOptions given;
  given.capacity = o.present("capacity");
  given.max_depth = o.present("max_depth");
  given.depth = o.present("depth");
  given.insertion = o.present("build");
  IndexChoiceWords words;
  words.option = "\"layout\": ";
  words.layouts = true;
  words.quote = "\"";
  try {
    check_applicable(type, given, words);
  } catch (const OptionError& e) {
    std::string key;
    std::string what = e.spelled([&](std::string_view field) {
      if (key.empty()) key = index_option_key(field);
      return std::string();
    });
    // The pointer names the key, so the message starts after the option's (empty) name.
    what.erase(0, what.find_first_not_of(' '));
    fail(o.file(), o.ptr(key), what);
  }
}

IndexOptions parse_index(Obj& parent, const std::string& key, NodeDistance& nd) {
  IndexOptions opt;
  opt.type = "octree-adaptive";
  if (!parent.has(key)) return opt;
  Obj o(parent.at(key), parent.file(), parent.ptr(key));
  nd = o.string("node_distance", "exact", {"exact", "eq3"}) == "exact" ? NodeDistance::exact
                                                                       : NodeDistance::eq3;
  const std::string type = o.string("type", "octree", {"octree", "kdtree", "brute"});
  if (type == "octree") {
    opt.type = octree_index_type(
        parse_octree_layout(o.string("layout", to_string(OctreeLayout::adaptive), octree_layout_names())));
    check_octree_keys(o, opt.type);
    opt.depth = static_cast<unsigned>(o.integer("depth", 6, 0, 21));
    opt.max_depth = static_cast<unsigned>(o.integer("max_depth", 21, 1, 21));
    opt.insertion = o.string("build", "bulk", {"bulk", "insertion"}) == "insertion";
  } else {
    opt.type = type;
  }
  if (type != "brute")
    opt.capacity = static_cast<std::uint32_t>(o.integer("capacity", index_capacity(opt), 1, 1u << 20));
  o.finish();
  return opt;
}

MaterialDesc parse_material(Obj& parent) {
  MaterialDesc m;
  if (!parent.has("material")) return m;
  Obj o(parent.at("material"), parent.file(), parent.ptr("material"));
  if (o.has("color")) {
    const json& c = o.at("color");
    if (c.is_array()) {
      m.mode = ColorMode::constant;
      m.constant = o.color_at(c, o.ptr("color"), 1.0f);
    } else {
      const std::string s = o.string_at(c, o.ptr("color"),
                                        {"rgb", "intensity", "elevation", "classification"});
      m.mode = s == "rgb" ? ColorMode::rgb
               : s == "intensity" ? ColorMode::intensity
               : s == "elevation" ? ColorMode::elevation
                                  : ColorMode::classification;
    }
  }
  // ramp and range only shape the scalar modes; anywhere else they would be silently unused.
  if (m.mode != ColorMode::intensity && m.mode != ColorMode::elevation) {
    const std::string color = !o.present("color") ? "\"rgb\" (the default)"
                              : o.at("color").is_array() ? "a constant [r, g, b]"
                                                         : "\"" + o.at("color").get<std::string>() + "\"";
    for (const char* k : {"ramp", "range"})
      if (o.present(k))
        fail(o.file(), o.ptr(k), std::string("only used with color \"intensity\" or \"elevation\"; color is ") + color);
  }
  if (o.has("ramp")) m.ramp = parse_ramp(o.string("ramp", "viridis", ramp_names()));
  if (o.has("range")) {
    const json& r = o.at("range");
    if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number() ||
        !(r[0].get<double>() < r[1].get<double>()) || !std::isfinite(r[0].get<double>()) ||
        !std::isfinite(r[1].get<double>()))
      fail(o.file(), o.ptr("range"), "expected [low, high] with finite low < high");
    m.range = std::array<double, 2>{r[0].get<double>(), r[1].get<double>()};
  }
  m.albedo_scale = static_cast<float>(o.number("albedo_scale", 1.0, 0.0, 10.0, false, false));
  o.finish();
  return m;
}

BackgroundDesc parse_background(Obj& parent) {
  BackgroundDesc b;
  if (!parent.has("background")) return b;
  Obj o(parent.at("background"), parent.file(), parent.ptr("background"));
  b.gradient = o.string("type", "gradient", {"gradient", "constant"}) == "gradient";
  if (b.gradient) {
    b.horizon = o.color("horizon", b.horizon, 1e6f);
    b.zenith = o.color("zenith", b.zenith, 1e6f);
  } else {
    b.color = o.color("color", b.color, 1e6f);
  }
  b.intensity = static_cast<float>(o.number("intensity", 1.0, 0.0, 1e6, false, false));
  o.finish();
  return b;
}

SunDesc parse_sun(Obj& parent, const Vec3& up) {
  SunDesc s;
  if (!parent.has("sun")) return s;
  if (parent.at("sun").is_null()) return s;
  Obj o(parent.at("sun"), parent.file(), parent.ptr("sun"));
  s.enabled = true;
  const bool has_dir = o.has("direction");
  const bool has_angles = o.has("azimuth_deg") || o.has("elevation_deg");
  if (has_dir && has_angles)
    fail(o.file(), o.ptr("direction"), "give either direction or azimuth_deg/elevation_deg, not both");
  if (has_dir) {
    s.direction = glm::normalize(o.vec3("direction", Vec3(0, 0, 1), true));
  } else {
    // Azimuth clockwise from +y (grid north) in the plane orthogonal to `up`.
    const double az = o.number("azimuth_deg", 135.0, -360.0, 360.0, false, false) * M_PI / 180.0;
    const double el = o.number("elevation_deg", 45.0, -90.0, 90.0, false, false) * M_PI / 180.0;
    const Vec3 u = glm::normalize(up);
    Vec3 north = Vec3(0, 1, 0) - glm::dot(Vec3(0, 1, 0), u) * u;
    if (glm::length(north) < 1e-6) north = Vec3(1, 0, 0) - glm::dot(Vec3(1, 0, 0), u) * u;
    north = glm::normalize(north);
    const Vec3 east = glm::cross(north, u);
    s.direction = glm::normalize(std::cos(el) * (std::cos(az) * north + std::sin(az) * east) + std::sin(el) * u);
  }
  s.angular_diameter_deg = o.number("angular_diameter_deg", 0.53, 0.0, 20.0, false, false);
  s.irradiance = static_cast<float>(o.number("irradiance", 3.0, 0.0, 1e6, false, false));
  s.color = o.color("color", s.color, 1e6f);
  o.finish();
  return s;
}

OutputDesc parse_output(Obj& parent, const std::filesystem::path& scene_file) {
  OutputDesc out;
  if (!parent.has("output")) return out;
  Obj o(parent.at("output"), parent.file(), parent.ptr("output"));
  if (o.has("image")) {
    const std::string img = o.string("image", "");
    if (!is_image_file_name(img)) fail(o.file(), o.ptr("image"), image_file_name_expected());
    out.image = resolve(scene_file, img);
  }
  out.bit_depth = static_cast<unsigned>(o.integer("bit_depth", 8, 8, 16));
  if (out.bit_depth != 8 && out.bit_depth != 16) fail(o.file(), o.ptr("bit_depth"), "expected 8 or 16");
  if (out.bit_depth == 16 && is_jpeg_file_name(out.image))
    fail(o.file(), o.ptr("bit_depth"), "expected 8 with a JPEG image (8 bits per channel); 16 needs a .png or .tif image");
  out.exr_half = o.string("exr_pixel_type", "half", {"half", "float"}) == "half";
  out.exposure = o.number("exposure", 0.0, -30.0, 30.0, false, false);
  if (o.has("aovs")) {
    const json& a = o.at("aovs");
    if (!a.is_array()) fail(o.file(), o.ptr("aovs"), "expected an array of AOV names");
    for (std::size_t i = 0; i < a.size(); ++i) {
      std::vector<std::string> names;
      for (Aov x : all_aovs()) names.emplace_back(to_string(x));
      const std::string s = o.string_at(a[i], o.ptr("aovs") + "/" + std::to_string(i), names);
      const Aov v = *parse_aov(s);
      if (std::find(out.aovs.begin(), out.aovs.end(), v) != out.aovs.end())
        fail(o.file(), o.ptr("aovs") + "/" + std::to_string(i), "duplicate AOV \"" + s + "\"");
      out.aovs.push_back(v);
    }
  }
  o.finish();
  return out;
}

}  // namespace

PointCloud load_cloud(const Scene& scene, const io::ReadOptions& options) {
  const std::string f = scene.file.empty() ? std::string("(scene)") : scene.file.string();
  PointCloud cloud;
  try {
    cloud = io::read_point_cloud(scene.cloud, options);
  } catch (const std::exception& e) {
    fail(f, "/cloud", e.what());
  }
  if (cloud.empty()) fail(f, "/cloud", scene.cloud.string() + ": the point cloud has no points");
  return cloud;
}

const std::vector<std::string>& image_extensions() {
  static const std::vector<std::string> exts{".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr"};
  return exts;
}

bool is_image_file_name(const std::filesystem::path& file) { return has_extension(file, image_extensions()); }

bool is_jpeg_file_name(const std::filesystem::path& file) { return has_extension(file, {".jpg", ".jpeg"}); }

std::string image_file_name_expected() { return extensions_expected(image_extensions()); }

Scene load_scene(const std::filesystem::path& file) { return parse_scene_json(parse_file(file), file); }

Scene parse_scene_json(const nlohmann::json& j, const std::filesystem::path& file, const SceneParseOptions& options) {
  const std::string f = options.name.empty() ? file.string() : options.name;
  Obj o(j, f, "");
  Scene s;
  s.file = file;
  if (o.has("cloud")) {
    const std::string cloud = o.string("cloud", "");
    if (cloud.empty()) fail(f, "/cloud", "expected a non-empty file name");
    s.cloud = resolve(file, cloud);
  } else if (options.cloud_required) {
    fail(f, "/cloud", "required: point cloud file (string, relative to the scene file)");
  }
  if (o.has("radius")) {
    const json& r = o.at("radius");
    if (r.is_string() && r.get<std::string>() == "auto") {
      s.radius.reset();
    } else {
      // A non-number is refused with the range's own wording (nan is out of every range).
      const std::string why = sphere_radius_problem(r.is_number() ? r.get<double>() : std::nan(""));
      if (!why.empty()) fail(f, "/radius", why);
      s.radius = r.get<double>();
    }
  }
  if (o.has("auto_radius_factor")) {
    const json& v = o.at("auto_radius_factor");
    // A non-number is refused with the range's own wording (nan is out of every range).
    const std::string why = auto_radius_factor_problem(v.is_number() ? v.get<double>() : std::nan(""));
    if (!why.empty()) fail(f, "/auto_radius_factor", why);
    s.auto_radius_factor = v.get<double>();
  }
  s.hit = o.string("hit", "sphere", {"sphere", "closest_point"}) == "sphere" ? HitMode::sphere
                                                                             : HitMode::closest_point;
  s.primitive = o.string("primitive", "sphere", {"sphere", "surfel"}) == "surfel" ? Primitive::surfel
                                                                                 : Primitive::sphere;
  // Discs are hit exactly (first_surfel_hit); the naive closest-point order is a sphere mode.
  if (s.hit == HitMode::closest_point && s.primitive == Primitive::surfel)
    fail(f, "/hit", "\"closest_point\" applies to primitive \"sphere\" only; primitive is \"surfel\" (discs are hit exactly)");
  parse_surfel(o, s);
  s.index = parse_index(o, "index", s.node_distance);
  s.material = parse_material(o);
  s.up = glm::normalize(o.vec3("up", Vec3(0, 0, 1), true));
  s.background = parse_background(o);
  s.sun = parse_sun(o, s.up);
  if (!o.has("camera")) {
    if (options.camera_required)
      fail(f, "/camera", "required: a camera file name (relative to the scene file) or a camera object");
  } else if (const json& cam = o.at("camera"); cam.is_string()) {
    s.camera_file = resolve(file, cam.get<std::string>());
    s.camera = load_camera(s.camera_file);
  } else if (cam.is_object()) {
    s.camera = io::parse_camera(cam, f, "/camera");
  } else {
    fail(f, "/camera", "expected a camera file name or a camera object");
  }
  s.spp = static_cast<std::uint32_t>(o.integer("spp", 16, 1, kMaxSpp));
  s.max_depth = static_cast<std::uint32_t>(o.integer("max_depth", 4, 1, 1000));
  s.russian_roulette_depth = static_cast<std::uint32_t>(o.integer("russian_roulette_depth", 0, 0, 1000));
  s.seed = o.integer("seed", 0, 0, std::numeric_limits<std::uint64_t>::max());
  s.ray_offset = o.number("ray_offset", 1e-3, 0.0, 1.0, false, false);
  s.output = parse_output(o, file);
  o.finish();
  return s;
}

}  // namespace rayscan::render
