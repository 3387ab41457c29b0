#include "rayscan/camera/camera_file.hpp"

#include "rayscan/base/json_object.hpp"

namespace rayscan::io {

namespace {

std::array<std::array<double, 3>, 3> mat3_at(const JsonObject& o, const json& v, const std::string& p) {
  const char* what = "expected a 3x3 array of finite numbers (row-major)";
  if (!v.is_array() || v.size() != 3) json_fail(o.file(), p, what);
  std::array<std::array<double, 3>, 3> m{};
  for (int r = 0; r < 3; ++r) {
    const std::string pr = p + "/" + std::to_string(r);
    if (!v[r].is_array() || v[r].size() != 3) json_fail(o.file(), pr, what);
    for (int c = 0; c < 3; ++c) {
      if (!v[r][c].is_number() || !std::isfinite(v[r][c].get<double>()))
        json_fail(o.file(), pr + "/" + std::to_string(c), what);
      m[r][c] = v[r][c].get<double>();
    }
  }
  return m;
}

}  // namespace

Camera parse_camera(const json& j, const std::string& file, const std::string& ptr) {
  JsonObject o(j, file, ptr);
  const auto width = static_cast<std::uint32_t>(o.integer("width", 0, 1, kMaxImageSide));
  const auto height = static_cast<std::uint32_t>(o.integer("height", 0, 1, kMaxImageSide));
  if (!o.has("width")) json_fail(file, o.ptr("width"), "required: image width in pixels (integer in [1, 65536])");
  if (!o.has("height")) json_fail(file, o.ptr("height"), "required: image height in pixels (integer in [1, 65536])");
  // `K` only selects the default model; it is an allowed key only when the model is pinhole, so
  // a look-at camera with K/R/t is rejected by finish() as an unknown key.
  const std::string type = o.string("type", "pinhole", {"pinhole", "orthographic", "equirectangular"});
  if (type != "pinhole") {
    if (!o.has("position")) json_fail(file, o.ptr("position"), "required: camera position [x, y, z] (world units)");
    if (!o.has("look_at")) json_fail(file, o.ptr("look_at"), "required: point looked at [x, y, z] (world units)");
    const Vec3 pos = o.vec3("position", Vec3(0.0)), at = o.vec3("look_at", Vec3(0.0));
    if (at == pos) json_fail(file, o.ptr("look_at"), "expected a point different from /position");
    const Vec3 up = o.vec3("up", Vec3(0, 0, 1), true);
    try {
      if (type == "orthographic") {
        if (!o.has("view_height"))
          json_fail(file, o.ptr("view_height"), "required for type \"orthographic\": image height in world units");
        const double vh = o.number("view_height", 1.0, 0.0, kInf, true, true);
        o.finish();
        return Camera::orthographic(OrthographicParams{pos, at, up, vh}, width, height);
      }
      o.finish();
      return Camera::equirectangular(EquirectangularParams{pos, at, up}, width, height);
    } catch (const std::invalid_argument& e) {
      const std::string w = e.what();
      json_fail(file, o.ptr("up"), w.substr(w.find(':') + 2));
    }
  }
  const bool is_pinhole = o.present("K");
  const std::string model =
      o.string("model", is_pinhole ? "pinhole" : "look_at", {"look_at", "pinhole"});
  try {
    if (model == "pinhole") {
      if (!o.has("K")) json_fail(file, o.ptr("K"), "required for model \"pinhole\": 3x3 intrinsic matrix in pixels");
      if (!o.has("R")) json_fail(file, o.ptr("R"), "required for model \"pinhole\": 3x3 world-to-camera rotation");
      if (!o.has("t")) json_fail(file, o.ptr("t"), "required for model \"pinhole\": world-to-camera translation");
      PinholeParams p;
      p.K = mat3_at(o, o.at("K"), o.ptr("K"));
      p.R = mat3_at(o, o.at("R"), o.ptr("R"));
      p.t = o.vec3("t", Vec3(0.0));
      LensDistortion k;
      if (o.has("distortion")) {
        const json& dv = o.at("distortion");
        const char* what = "expected [k1, k2, p1, p2, k3] (OpenCV order, finite numbers)";
        if (!dv.is_array() || dv.size() != 5) json_fail(file, o.ptr("distortion"), what);
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
        json_fail(file, o.ptr(w.find("R ") != std::string::npos ? "R" : "K"), w.substr(w.find(':') + 2));
      }
    }
    LookAtParams p;
    if (!o.has("position")) json_fail(file, o.ptr("position"), "required: camera position [x, y, z] (world units)");
    if (!o.has("look_at")) json_fail(file, o.ptr("look_at"), "required: point looked at [x, y, z] (world units)");
    p.position = o.vec3("position", Vec3(0.0));
    p.look_at = o.vec3("look_at", Vec3(0.0));
    if (p.look_at == p.position) json_fail(file, o.ptr("look_at"), "expected a point different from /position");
    p.up = o.vec3("up", Vec3(0, 0, 1), true);
    p.vfov_deg = o.number("vfov_deg", 40.0, 0.0, 180.0, true, true);
    p.aperture = o.number("aperture", 0.0, 0.0, kInf, false, true);
    p.focus_distance = o.number("focus_distance", 0.0, 0.0, kInf, false, true);
    o.finish();
    try {
      return Camera::look_at(p, width, height);
    } catch (const std::invalid_argument& e) {
      const std::string w = e.what();
      json_fail(file, o.ptr("up"), w.substr(w.find(':') + 2));
    }
  } catch (const JsonFileError&) {
    throw;
  }
}

namespace {

using ojson = nlohmann::ordered_json;

ojson vec3_json(const Vec3& v) { return ojson::array({v.x, v.y, v.z}); }

ojson mat3_json(const std::array<std::array<double, 3>, 3>& m) {
  ojson a = ojson::array();
  for (const auto& row : m) a.push_back(ojson::array({row[0], row[1], row[2]}));
  return a;
}

// The "type", "position", "look_at" and "up" keys of the orthographic and equirectangular models.
void set_frame(ojson& j, const char* type, const Vec3& position, const Vec3& look_at, const Vec3& up) {
  j["type"] = type;
  j["position"] = vec3_json(position);
  j["look_at"] = vec3_json(look_at);
  j["up"] = vec3_json(up);
}

}  // namespace

nlohmann::ordered_json camera_to_json(const Camera& camera) {
  const CameraDescription& d = camera.description();
  nlohmann::ordered_json j;
  j["width"] = camera.width();
  j["height"] = camera.height();
  switch (d.model) {
    case CameraModel::look_at:
      j["position"] = vec3_json(d.look_at.position);
      j["look_at"] = vec3_json(d.look_at.look_at);
      j["up"] = vec3_json(d.look_at.up);
      j["vfov_deg"] = d.look_at.vfov_deg;
      if (d.look_at.aperture != 0.0) j["aperture"] = d.look_at.aperture;
      if (d.look_at.focus_distance != 0.0) j["focus_distance"] = d.look_at.focus_distance;
      return j;
    case CameraModel::pinhole:
      j["K"] = mat3_json(d.pinhole.K);
      j["R"] = mat3_json(d.pinhole.R);
      j["t"] = vec3_json(d.pinhole.t);
      if (d.distortion.any()) {
        const LensDistortion& k = d.distortion;
        j["distortion"] = ojson::array({k.k1, k.k2, k.p1, k.p2, k.k3});
      }
      return j;
    case CameraModel::orthographic:
      set_frame(j, "orthographic", d.orthographic.position, d.orthographic.look_at, d.orthographic.up);
      j["view_height"] = d.orthographic.view_height;
      return j;
    case CameraModel::equirectangular:
      set_frame(j, "equirectangular", d.equirectangular.position, d.equirectangular.look_at, d.equirectangular.up);
      return j;
    case CameraModel::orthographic_grid: break;
  }
  throw std::invalid_argument("camera: a per-pixel orthographic grid has no camera-file form");
}

Camera load_camera(const std::filesystem::path& file) {
  const json j = parse_json_file(file);
  return parse_camera(j, file.string(), "");
}

}  // namespace rayscan::io
