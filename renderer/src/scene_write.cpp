// Scene::to_json: the scene as scene-file JSON with every value explicit (scenes/README.md), the
// inverse of parse_scene_json.
#include "rayscan/render/scene.hpp"

#include "rayscan/camera/camera_file.hpp"
#include "rayscan/image/color_ramp.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <stdexcept>
#include <system_error>

namespace rayscan::render {

namespace {

using ojson = nlohmann::ordered_json;

ojson vec3(const Vec3& v) { return ojson::array({v.x, v.y, v.z}); }

// A float as the shortest decimal that reads back (as a double, then cast) to the same float:
// 0.7f is written 0.7, not 0.699999988079071.
double short_float(float f) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf - 1, f);
  if (ec != std::errc()) return f;
  *end = '\0';
  const double d = std::strtod(buf, nullptr);
  return static_cast<float>(d) == f ? d : double(f);
}

ojson color(const Color& c) { return ojson::array({short_float(c.r), short_float(c.g), short_float(c.b)}); }

// nlohmann's dump with arrays of numbers and strings on one line ("up": [0.0, 0.0, 1.0]).
void dump_compact(const ojson& j, int depth, std::string& out) {
  const std::string pad(2 * (depth + 1), ' '), end_pad(2 * depth, ' ');
  const bool flat = j.is_array() && std::none_of(j.begin(), j.end(), [](const ojson& e) {
                      return e.is_object() || (e.is_array() && !e.empty() && (e[0].is_array() || e[0].is_object()));
                    });
  if (j.is_object() && !j.empty()) {
    out += "{\n";
    bool first = true;
    for (const auto& [k, v] : j.items()) {
      out += first ? "" : ",\n";
      first = false;
      out += pad + ojson(k).dump() + ": ";
      dump_compact(v, depth + 1, out);
    }
    out += "\n" + end_pad + "}";
  } else if (j.is_array() && !j.empty() && !flat) {
    out += "[\n";
    for (std::size_t i = 0; i < j.size(); ++i) {
      out += (i ? ",\n" : "") + pad;
      dump_compact(j[i], depth + 1, out);
    }
    out += "\n" + end_pad + "]";
  } else if (j.is_array() && !j.empty()) {
    out += "[";
    for (std::size_t i = 0; i < j.size(); ++i) out += (i ? ", " : "") + j[i].dump();
    out += "]";
  } else {
    out += j.dump();
  }
}

std::string absolute_path(const std::filesystem::path& p) { return std::filesystem::absolute(p).lexically_normal().string(); }

std::string ramp_name(Ramp r) {
  for (const std::string& n : ramp_names())
    if (parse_ramp(n) == r) return n;
  throw std::logic_error("scene: a ramp without a name");
}

ojson surfel_json(const Scene& s) {
  const SurfelOptions& so = s.surfel;
  ojson j;
  j["k_normal"] = so.k_normal;
  j["k_radius"] = so.k_radius;
  j["radius_factor"] = so.radius_factor;
  j["max_radius_factor"] = so.max_radius_factor;
  if (s.surfel_orient_camera) j["orient"] = "camera";
  else if (so.orientation.viewpoint) j["orient"] = vec3(*so.orientation.viewpoint);
  else j["orient"] = "up";
  return j;
}

ojson index_json(const Scene& s) {
  const IndexOptions& x = s.index;
  ojson j;
  j["node_distance"] = s.node_distance == NodeDistance::exact ? "exact" : "eq3";
  // Only the options the index uses: the parser refuses the others (check_applicable).
  if (const std::optional<OctreeLayout> layout = octree_layout_of(x.type)) {
    j["type"] = "octree";
    j["layout"] = to_string(*layout);
  } else {
    j["type"] = x.type;
  }
  if (index_option_applies(x.type, IndexOption::depth)) j["depth"] = x.depth;
  if (index_option_applies(x.type, IndexOption::max_depth)) j["max_depth"] = x.max_depth;
  if (index_option_applies(x.type, IndexOption::insertion)) j["build"] = x.insertion ? "insertion" : "bulk";
  if (index_option_applies(x.type, IndexOption::capacity)) j["capacity"] = index_capacity(x);
  return j;
}

ojson material_json(const MaterialDesc& m) {
  ojson j;
  switch (m.mode) {
    case ColorMode::rgb: j["color"] = "rgb"; break;
    case ColorMode::intensity: j["color"] = "intensity"; break;
    case ColorMode::elevation: j["color"] = "elevation"; break;
    case ColorMode::classification: j["color"] = "classification"; break;
    case ColorMode::constant: j["color"] = color(m.constant); break;
  }
  // The parser refuses ramp and range with the other modes (they would be silently unused).
  if (m.mode == ColorMode::intensity || m.mode == ColorMode::elevation) {
    j["ramp"] = ramp_name(m.ramp);
    if (m.range) j["range"] = ojson::array({(*m.range)[0], (*m.range)[1]});
  }
  j["albedo_scale"] = short_float(m.albedo_scale);
  return j;
}

ojson background_json(const BackgroundDesc& b) {
  ojson j;
  j["type"] = b.gradient ? "gradient" : "constant";
  if (b.gradient) {
    j["horizon"] = color(b.horizon);
    j["zenith"] = color(b.zenith);
  } else {
    j["color"] = color(b.color);
  }
  j["intensity"] = short_float(b.intensity);
  return j;
}

ojson output_json(const OutputDesc& o) {
  ojson j;
  if (!o.image.empty()) j["image"] = absolute_path(o.image);
  j["bit_depth"] = o.bit_depth;
  j["exr_pixel_type"] = o.exr_half ? "half" : "float";
  j["exposure"] = o.exposure;
  ojson a = ojson::array();
  for (Aov v : o.aovs) a.push_back(std::string(to_string(v)));
  j["aovs"] = a;
  return j;
}

}  // namespace

std::string Scene::to_json() const {
  if (!camera) throw std::invalid_argument("scene: no camera to write");
  ojson j;
  if (!cloud.empty()) j["cloud"] = absolute_path(cloud);  // none for points given in memory
  if (radius) j["radius"] = *radius;
  else j["radius"] = "auto";
  j["auto_radius_factor"] = auto_radius_factor;
  j["hit"] = hit == HitMode::sphere ? "sphere" : "closest_point";
  j["primitive"] = primitive == Primitive::surfel ? "surfel" : "sphere";
  j["surfel"] = surfel_json(*this);
  j["index"] = index_json(*this);
  j["material"] = material_json(material);
  j["up"] = vec3(up);
  j["background"] = background_json(background);
  if (sun.enabled)
    j["sun"] = {{"direction", vec3(sun.direction)},
                {"angular_diameter_deg", sun.angular_diameter_deg},
                {"irradiance", short_float(sun.irradiance)},
                {"color", color(sun.color)}};
  j["camera"] = io::camera_to_json(*camera);
  j["spp"] = spp;
  j["max_depth"] = max_depth;
  j["russian_roulette_depth"] = russian_roulette_depth;
  j["seed"] = seed;
  j["ray_offset"] = ray_offset;
  j["output"] = output_json(output);
  std::string text;
  dump_compact(j, 0, text);
  return text;
}

}  // namespace rayscan::render
