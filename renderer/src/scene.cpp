// Scene/camera JSON parsing. Every value is read through Obj, which records the JSON pointer of
// what it reads so that an error names the exact field, and rejects keys it was not asked about.
#include "rayscan/render/scene.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace rayscan::render {

namespace {

using nlohmann::json;

[[noreturn]] void fail(const std::string& file, const std::string& ptr, const std::string& what) {
  throw SceneError(file + ": " + (ptr.empty() ? "/" : ptr) + ": " + what);
}

std::string escape_key(const std::string& k) {  // RFC 6901 escaping
  std::string s;
  for (char c : k) {
    if (c == '~') s += "~0";
    else if (c == '/') s += "~1";
    else s += c;
  }
  return s;
}

json parse_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SceneError(file.string() + ": cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return json::parse(ss.str());
  } catch (const json::parse_error& e) {
    throw SceneError(file.string() + ": byte " + std::to_string(e.byte) +
                     ": invalid JSON (" + std::string(e.what()) + ")");
  }
}

/// A JSON object being read: typed getters with range checks, and finish() to reject unknown keys.
class Obj {
 public:
  Obj(const json& j, std::string file, std::string ptr) : j_(j), file_(std::move(file)), ptr_(std::move(ptr)) {
    if (!j_.is_object()) fail(file_, ptr_, "expected an object");
  }
  bool has(const std::string& k) {
    seen_.insert(k);
    return j_.contains(k);
  }
  /// Whether `k` is present, without making it an allowed key (finish() still rejects it unless
  /// a getter asks for it).
  bool present(const std::string& k) const { return j_.contains(k); }
  const json& at(const std::string& k) { seen_.insert(k); return j_.at(k); }
  std::string ptr(const std::string& k) const { return ptr_ + "/" + escape_key(k); }
  const std::string& file() const { return file_; }

  double number(const std::string& k, double def, double lo, double hi, bool lo_open, bool hi_open) {
    if (!has(k)) return def;
    return number_at(j_.at(k), ptr(k), lo, hi, lo_open, hi_open);
  }
  double number_at(const json& v, const std::string& p, double lo, double hi, bool lo_open,
                   bool hi_open) const {
    const bool ok = v.is_number() && std::isfinite(v.get<double>()) &&
                    (lo_open ? v.get<double>() > lo : v.get<double>() >= lo) &&
                    (hi_open ? v.get<double>() < hi : v.get<double>() <= hi);
    if (!ok) fail(file_, p, "expected a number in " + range_text(lo, hi, lo_open, hi_open));
    return v.get<double>();
  }
  std::uint64_t integer(const std::string& k, std::uint64_t def, std::uint64_t lo, std::uint64_t hi) {
    if (!has(k)) return def;
    const json& v = j_.at(k);
    if (!v.is_number_integer() || (v.is_number_integer() && !v.is_number_unsigned() && v.get<std::int64_t>() < 0) ||
        v.get<std::uint64_t>() < lo || v.get<std::uint64_t>() > hi)
      fail(file_, ptr(k), "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return v.get<std::uint64_t>();
  }
  bool boolean(const std::string& k, bool def) {
    if (!has(k)) return def;
    if (!j_.at(k).is_boolean()) fail(file_, ptr(k), "expected true or false");
    return j_.at(k).get<bool>();
  }
  std::string string(const std::string& k, const std::string& def, const std::vector<std::string>& allowed = {}) {
    if (!has(k)) return def;
    return string_at(j_.at(k), ptr(k), allowed);
  }
  std::string string_at(const json& v, const std::string& p, const std::vector<std::string>& allowed) const {
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + ("\"" + a + "\"");
    if (!v.is_string()) fail(file_, p, allowed.empty() ? "expected a string" : "expected one of " + list);
    const std::string s = v.get<std::string>();
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), s) == allowed.end())
      fail(file_, p, "expected one of " + list + ", got \"" + s + "\"");
    return s;
  }
  Vec3 vec3(const std::string& k, const Vec3& def, bool nonzero = false) {
    if (!has(k)) return def;
    return vec3_at(j_.at(k), ptr(k), nonzero);
  }
  Vec3 vec3_at(const json& v, const std::string& p, bool nonzero) const {
    const char* what = nonzero ? "expected an array of 3 finite numbers, not all zero"
                               : "expected an array of 3 finite numbers";
    if (!v.is_array() || v.size() != 3) fail(file_, p, what);
    Vec3 r;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) fail(file_, p + "/" + std::to_string(i), what);
      r[i] = v[i].get<double>();
    }
    if (nonzero && r == Vec3(0.0)) fail(file_, p, what);
    return r;
  }
  Color color(const std::string& k, const Color& def, float hi) {
    if (!has(k)) return def;
    return color_at(j_.at(k), ptr(k), hi);
  }
  Color color_at(const json& v, const std::string& p, float hi) const {
    const std::string what = "expected an array of 3 numbers (linear RGB) in [0, " + num(hi) + "]";
    if (!v.is_array() || v.size() != 3) fail(file_, p, what);
    Color c;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !(v[i].get<double>() >= 0.0) || !(v[i].get<double>() <= hi))
        fail(file_, p + "/" + std::to_string(i), what);
      c[i] = v[i].get<float>();
    }
    return c;
  }
  /// Rejects keys that no getter asked about.
  void finish() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (seen_.count(it.key())) continue;
      std::string list;
      for (const auto& s : seen_) list += (list.empty() ? "" : ", ") + s;
      fail(file_, ptr(it.key()), "unknown key (allowed here: " + list + ")");
    }
  }

  static std::string num(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
  }
  static std::string range_text(double lo, double hi, bool lo_open, bool hi_open) {
    auto s = [](double v) { return std::isinf(v) ? (v > 0 ? std::string("inf") : std::string("-inf")) : num(v); };
    return std::string(lo_open ? "(" : "[") + s(lo) + ", " + s(hi) + (hi_open ? ")" : "]");
  }

 private:
  const json& j_;
  std::string file_, ptr_;
  std::set<std::string> seen_;
};

std::filesystem::path resolve(const std::filesystem::path& base_file, const std::string& p) {
  std::filesystem::path path(p);
  if (path.is_relative()) path = base_file.parent_path() / path;
  return path.lexically_normal();
}

std::array<std::array<double, 3>, 3> mat3_at(const Obj& o, const json& v, const std::string& p) {
  const char* what = "expected a 3x3 array of finite numbers (row-major)";
  if (!v.is_array() || v.size() != 3) fail(o.file(), p, what);
  std::array<std::array<double, 3>, 3> m{};
  for (int r = 0; r < 3; ++r) {
    const std::string pr = p + "/" + std::to_string(r);
    if (!v[r].is_array() || v[r].size() != 3) fail(o.file(), pr, what);
    for (int c = 0; c < 3; ++c) {
      if (!v[r][c].is_number() || !std::isfinite(v[r][c].get<double>()))
        fail(o.file(), pr + "/" + std::to_string(c), what);
      m[r][c] = v[r][c].get<double>();
    }
  }
  return m;
}

Camera parse_camera(const json& j, const std::string& file, const std::string& ptr) {
  Obj o(j, file, ptr);
  const auto width = static_cast<std::uint32_t>(o.integer("width", 0, 1, 65536));
  const auto height = static_cast<std::uint32_t>(o.integer("height", 0, 1, 65536));
  if (!o.has("width")) fail(file, o.ptr("width"), "required: image width in pixels (integer in [1, 65536])");
  if (!o.has("height")) fail(file, o.ptr("height"), "required: image height in pixels (integer in [1, 65536])");
  // `K` only selects the default model; it is an allowed key only when the model is pinhole, so
  // a look-at camera with K/R/t is rejected by finish() as an unknown key.
  const std::string type = o.string("type", "pinhole", {"pinhole", "orthographic", "equirectangular"});
  if (type != "pinhole") {
    if (!o.has("position")) fail(file, o.ptr("position"), "required: camera position [x, y, z] (world units)");
    if (!o.has("look_at")) fail(file, o.ptr("look_at"), "required: point looked at [x, y, z] (world units)");
    const Vec3 pos = o.vec3("position", Vec3(0.0)), at = o.vec3("look_at", Vec3(0.0));
    if (at == pos) fail(file, o.ptr("look_at"), "expected a point different from /position");
    const Vec3 up = o.vec3("up", Vec3(0, 0, 1), true);
    try {
      if (type == "orthographic") {
        if (!o.has("view_height"))
          fail(file, o.ptr("view_height"), "required for type \"orthographic\": image height in world units");
        const double vh = o.number("view_height", 1.0, 0.0, kInf, true, true);
        o.finish();
        return Camera::orthographic(OrthographicParams{pos, at, up, vh}, width, height);
      }
      o.finish();
      return Camera::equirectangular(EquirectangularParams{pos, at - pos, up}, width, height);
    } catch (const std::invalid_argument& e) {
      const std::string w = e.what();
      fail(file, o.ptr("up"), w.substr(w.find(':') + 2));
    }
  }
  const bool is_pinhole = o.present("K");
  const std::string model =
      o.string("model", is_pinhole ? "pinhole" : "look_at", {"look_at", "pinhole"});
  try {
    if (model == "pinhole") {
      if (!o.has("K")) fail(file, o.ptr("K"), "required for model \"pinhole\": 3x3 intrinsic matrix in pixels");
      if (!o.has("R")) fail(file, o.ptr("R"), "required for model \"pinhole\": 3x3 world-to-camera rotation");
      if (!o.has("t")) fail(file, o.ptr("t"), "required for model \"pinhole\": world-to-camera translation");
      PinholeParams p;
      p.K = mat3_at(o, o.at("K"), o.ptr("K"));
      p.R = mat3_at(o, o.at("R"), o.ptr("R"));
      p.t = o.vec3("t", Vec3(0.0));
      LensDistortion k;
      if (o.has("distortion")) {
        const json& dv = o.at("distortion");
        const char* what = "expected [k1, k2, p1, p2, k3] (OpenCV order, finite numbers)";
        if (!dv.is_array() || dv.size() != 5) fail(file, o.ptr("distortion"), what);
        double c[5];
        for (int i = 0; i < 5; ++i) c[i] = o.number_at(dv[i], o.ptr("distortion") + "/" + std::to_string(i), -kInf, kInf, true, true);
        k = LensDistortion{c[0], c[1], c[2], c[3], c[4]};
      }
      o.finish();
      try {
        if (k.any()) return Camera::pinhole_distorted(p, k, width, height);
        return Camera::pinhole(p, width, height);
      } catch (const std::invalid_argument& e) {
        const std::string w = e.what();
        fail(file, o.ptr(w.find("R ") != std::string::npos ? "R" : "K"), w.substr(w.find(':') + 2));
      }
    }
    LookAtParams p;
    if (!o.has("position")) fail(file, o.ptr("position"), "required: camera position [x, y, z] (world units)");
    if (!o.has("look_at")) fail(file, o.ptr("look_at"), "required: point looked at [x, y, z] (world units)");
    p.position = o.vec3("position", Vec3(0.0));
    p.look_at = o.vec3("look_at", Vec3(0.0));
    if (p.look_at == p.position) fail(file, o.ptr("look_at"), "expected a point different from /position");
    p.up = o.vec3("up", Vec3(0, 0, 1), true);
    p.vfov_deg = o.number("vfov_deg", 40.0, 0.0, 180.0, true, true);
    p.aperture = o.number("aperture", 0.0, 0.0, kInf, false, true);
    p.focus_distance = o.number("focus_distance", 0.0, 0.0, kInf, false, true);
    o.finish();
    try {
      return Camera::look_at(p, width, height);
    } catch (const std::invalid_argument& e) {
      const std::string w = e.what();
      fail(file, o.ptr("up"), w.substr(w.find(':') + 2));
    }
  } catch (const SceneError&) {
    throw;
  }
}

/// "surfel": {"k_normal", "k_radius", "radius_factor", "max_radius_factor", "orient"} (issue 16).
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

IndexOptions parse_index(Obj& parent, const std::string& key, NodeDistance& nd) {
  IndexOptions opt;
  opt.type = "octree-adaptive";
  if (!parent.has(key)) return opt;
  Obj o(parent.at(key), parent.file(), parent.ptr(key));
  nd = o.string("node_distance", "exact", {"exact", "eq3"}) == "exact" ? NodeDistance::exact
                                                                       : NodeDistance::eq3;
  const std::string type = o.string("type", "octree", {"octree", "kdtree", "brute"});
  if (type == "octree") {
    opt.type = "octree-" + o.string("layout", "adaptive", {"adaptive", "layered", "fixed"});
    opt.depth = static_cast<unsigned>(o.integer("depth", 6, 0, 21));
    opt.max_depth = static_cast<unsigned>(o.integer("max_depth", 21, 0, 21));
    opt.insertion = o.string("build", "bulk", {"bulk", "insertion"}) == "insertion";
  } else {
    opt.type = type;
  }
  if (type != "brute") opt.capacity = static_cast<std::uint32_t>(o.integer("capacity", 32, 1, 1u << 20));
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
  if (o.has("ramp")) m.ramp = parse_ramp(o.string("ramp", "viridis", {"viridis", "terrain", "grey"}));
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
  out.exr_half = o.string("exr_pixel_type", "half", {"half", "float"}) == "half";
  out.exposure = o.number("exposure", 0.0, -30.0, 30.0, false, false);
  if (o.has("aovs")) {
    const json& a = o.at("aovs");
    if (!a.is_array()) fail(o.file(), o.ptr("aovs"), "expected an array of AOV names");
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string s = o.string_at(a[i], o.ptr("aovs") + "/" + std::to_string(i),
                                        {"depth", "normal", "position", "index", "albedo", "cost"});
      const Aov v = s == "depth" ? Aov::depth : s == "normal" ? Aov::normal : s == "position" ? Aov::position
                    : s == "index" ? Aov::index : s == "albedo" ? Aov::albedo : Aov::cost;
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

bool is_image_file_name(const std::filesystem::path& file) {
  std::string ext;
  for (char c : file.extension().string()) ext += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const auto& exts = image_extensions();
  return std::find(exts.begin(), exts.end(), ext) != exts.end();
}

std::string image_file_name_expected() {
  const auto& exts = image_extensions();
  std::string s = "expected a file name ending in ";
  for (std::size_t i = 0; i < exts.size(); ++i)
    s += (i == 0 ? "" : i + 1 == exts.size() ? " or " : ", ") + exts[i];
  return s;
}

const char* to_string(Aov aov) {
  switch (aov) {
    case Aov::depth: return "depth";
    case Aov::normal: return "normal";
    case Aov::position: return "position";
    case Aov::index: return "index";
    case Aov::albedo: return "albedo";
    case Aov::cost: return "cost";
  }
  return "?";
}

Camera load_camera(const std::filesystem::path& file) {
  const json j = parse_file(file);
  return parse_camera(j, file.string(), "");
}

Scene load_scene(const std::filesystem::path& file) {
  const json j = parse_file(file);
  const std::string f = file.string();
  Obj o(j, f, "");
  Scene s;
  s.file = file;
  if (!o.has("cloud")) fail(f, "/cloud", "required: point cloud file (string, relative to the scene file)");
  const std::string cloud = o.string("cloud", "");
  if (cloud.empty()) fail(f, "/cloud", "expected a non-empty file name");
  s.cloud = resolve(file, cloud);
  if (o.has("radius")) {
    const json& r = o.at("radius");
    if (r.is_string() && r.get<std::string>() == "auto") s.radius.reset();
    else if (r.is_number() && std::isfinite(r.get<double>()) && r.get<double>() > 0.0) s.radius = r.get<double>();
    else fail(f, "/radius", "expected \"auto\" or a number in (0, inf) (world units)");
  }
  s.auto_radius_factor = o.number("auto_radius_factor", 1.0, 0.0, 100.0, true, false);
  s.hit = o.string("hit", "sphere", {"sphere", "closest_point"}) == "sphere" ? HitMode::sphere
                                                                             : HitMode::closest_point;
  s.primitive = o.string("primitive", "sphere", {"sphere", "surfel"}) == "surfel" ? Primitive::surfel
                                                                                 : Primitive::sphere;
  parse_surfel(o, s);
  s.index = parse_index(o, "index", s.node_distance);
  s.material = parse_material(o);
  s.up = glm::normalize(o.vec3("up", Vec3(0, 0, 1), true));
  s.background = parse_background(o);
  s.sun = parse_sun(o, s.up);
  if (!o.has("camera"))
    fail(f, "/camera", "required: a camera file name (relative to the scene file) or a camera object");
  const json& cam = o.at("camera");
  if (cam.is_string()) {
    s.camera_file = resolve(file, cam.get<std::string>());
    s.camera = load_camera(s.camera_file);
  } else if (cam.is_object()) {
    s.camera = parse_camera(cam, f, "/camera");
  } else {
    fail(f, "/camera", "expected a camera file name or a camera object");
  }
  s.spp = static_cast<std::uint32_t>(o.integer("spp", 16, 1, 1u << 20));
  s.max_depth = static_cast<std::uint32_t>(o.integer("max_depth", 4, 1, 1000));
  s.russian_roulette_depth = static_cast<std::uint32_t>(o.integer("russian_roulette_depth", 0, 0, 1000));
  s.seed = o.integer("seed", 0, 0, std::numeric_limits<std::uint64_t>::max());
  s.ray_offset = o.number("ray_offset", 1e-3, 0.0, 1.0, false, false);
  s.output = parse_output(o, file);
  o.finish();
  return s;
}

}  // namespace rayscan::render
