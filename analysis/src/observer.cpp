#include "rayscan/analysis/observer.hpp"
#include "site_dispatch.hpp"

#include "rayscan/base/ascii_case.hpp"
#include "rayscan/base/file_names.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/octree/point_query.hpp"

#include <type_traits>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

namespace rayscan::analysis {

namespace {

std::string trim(std::string_view s) {
  std::size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return std::string(s.substr(a, b - a));
}

std::vector<std::string> split(std::string_view s, char sep) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= s.size(); ++i)
    if (i == s.size() || s[i] == sep) {
      out.push_back(trim(s.substr(start, i - start)));
      start = i + 1;
    }
  return out;
}

// Parses the whole string as a finite double; nullopt otherwise.
std::optional<double> to_number(const std::string& s) {
  if (s.empty()) return std::nullopt;
  double v = 0;
  const char* b = s.data();
  const char* e = b + s.size();
  if (*b == '+') ++b;
  const auto r = std::from_chars(b, e, v);
  if (r.ec != std::errc() || r.ptr != e || !std::isfinite(v)) return std::nullopt;
  return v;
}

bool angle_ok(double a) { return a >= 0.0 && a <= 360.0; }

// A coordinate or eye height within +-kMaxObserverCoordinate (false for NaN), and the expectation
// every message about one states: "a finite number in [-1e+09, 1e+09] (world units)".
bool coordinate_ok(double v) { return std::abs(v) <= kMaxObserverCoordinate; }
std::string coordinate_expected() {
  char buf[96];
  std::snprintf(buf, sizeof buf, "a finite number in [%g, %g] (world units)", -kMaxObserverCoordinate,
                kMaxObserverCoordinate);
  return buf;
}

Observer from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw ObserverError(where + ": expected an object with \"position\"");
  Observer o;
  auto number = [&](const nlohmann::json& v, const std::string& ptr) {
    if (!v.is_number()) throw ObserverError(where + "/" + ptr + ": expected a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) throw ObserverError(where + "/" + ptr + ": expected a finite number");
    return d;
  };
  auto coordinate = [&](const nlohmann::json& v, const std::string& ptr) {
    const double d = number(v, ptr);
    if (!coordinate_ok(d)) throw ObserverError(where + "/" + ptr + ": expected " + coordinate_expected());
    return d;
  };
  auto pair = [&](const nlohmann::json& v, const std::string& ptr) {
    if (!v.is_array() || v.size() != 2)
      throw ObserverError(where + "/" + ptr + ": expected an array of two numbers [lo, hi] in degrees");
    return AngleRange{number(v[0], ptr + "/0"), number(v[1], ptr + "/1")};
  };
  for (const auto& [key, v] : j.items()) {
    if (key == "name") {
      if (!v.is_string()) throw ObserverError(where + "/name: expected a string");
      o.name = v.get<std::string>();
    } else if (key == "position") {
      if (!v.is_array() || v.size() < 2 || v.size() > 3)
        throw ObserverError(where + "/position: expected [x, y, z] or [x, y] (with \"height\")");
      o.position.x = coordinate(v[0], "position/0");
      o.position.y = coordinate(v[1], "position/1");
      if (v.size() == 3) {
        o.position.z = coordinate(v[2], "position/2");
        o.has_z = true;
      }
    } else if (key == "height") {
      o.height = coordinate(v, "height");
    } else if (key == "azimuth") {
      o.azimuth = pair(v, "azimuth");
    } else if (key == "elevation") {
      o.elevation = pair(v, "elevation");
    } else if (key == "max_distance") {
      o.max_distance = number(v, "max_distance");
    } else {
      throw ObserverError(where + "/" + key +
                          ": unknown key (expected name, position, height, azimuth, elevation, max_distance)");
    }
  }
  if (!j.contains("position")) throw ObserverError(where + "/position: missing");
  validate_observer(o, where);
  o.source = where;
  return o;
}

std::vector<Observer> read_json(const std::filesystem::path& path, const std::string& text) {
  nlohmann::json doc;
  try {
    doc = io::parse_json_text(text, path.string());  // syntax, numbers beyond double, duplicate keys
  } catch (const io::JsonFileError& e) {
    throw ObserverError(e.what());
  }
  std::string base;
  const nlohmann::json* list = &doc;
  if (doc.is_object()) {
    if (!doc.contains("observers") || doc.size() != 1)
      throw ObserverError(path.string() + ": expected an array of observers or {\"observers\": [...]}");
    list = &doc["observers"];
    base = "/observers";
  }
  if (!list->is_array())
    throw ObserverError(path.string() + ":" + (base.empty() ? std::string(" /") : " " + base) +
                        ": expected an array of observers");
  std::vector<Observer> out;
  for (std::size_t i = 0; i < list->size(); ++i)
    out.push_back(from_json((*list)[i], path.string() + ": " + base + "/" + std::to_string(i)));
  return out;
}

std::vector<Observer> read_csv(const std::filesystem::path& path, const std::string& text) {
  static const char* known[] = {"x", "y", "z", "height", "name", "azimuth_from", "azimuth_to",
                                "elevation_min", "elevation_max", "max_distance"};
  std::istringstream in(text);
  std::string line;
  std::vector<std::string> header;
  std::vector<Observer> out;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::string where = path.string() + ": line " + std::to_string(lineno);
    std::vector<std::string> cells = split(t, ',');
    if (header.empty()) {
      for (std::string& c : cells) {
        c = ascii_lower(c);
        if (std::find(std::begin(known), std::end(known), c) == std::end(known))
          throw ObserverError(where + ": unknown column '" + c +
                              "' (expected x, y, z, height, name, azimuth_from, azimuth_to, "
                              "elevation_min, elevation_max, max_distance)");
        if (std::count(cells.begin(), cells.end(), c) > 1)
          throw ObserverError(where + ": column '" + c + "' appears twice");
      }
      header = cells;
      if (std::find(header.begin(), header.end(), "x") == header.end() ||
          std::find(header.begin(), header.end(), "y") == header.end())
        throw ObserverError(where + ": the header line must name columns x and y");
      continue;
    }
    if (cells.size() != header.size())
      throw ObserverError(where + ": expected " + std::to_string(header.size()) + " columns, got " +
                          std::to_string(cells.size()));
    std::map<std::string, std::string> row;
    for (std::size_t c = 0; c < header.size(); ++c) row[header[c]] = cells[c];
    auto num = [&](const char* col, bool coordinate = false) -> std::optional<double> {
      const auto it = row.find(col);
      if (it == row.end() || it->second.empty()) return std::nullopt;
      const auto v = to_number(it->second);
      if (!v || (coordinate && !coordinate_ok(*v)))
        throw ObserverError(where + ": column '" + col + "': expected " +
                            (coordinate ? coordinate_expected() : std::string("a finite number")) + ", got '" +
                            it->second + "'");
      return v;
    };
    Observer o;
    const auto x = num("x", true), y = num("y", true), z = num("z", true);
    if (!x || !y) throw ObserverError(where + ": columns x and y must not be empty");
    o.position = Vec3(*x, *y, z.value_or(0.0));
    o.has_z = z.has_value();
    o.height = num("height", true);
    if (row.count("name")) o.name = row["name"];
    const auto a0 = num("azimuth_from"), a1 = num("azimuth_to");
    if (a0.has_value() != a1.has_value())
      throw ObserverError(where + ": give both azimuth_from and azimuth_to, or neither");
    if (a0) o.azimuth = AngleRange{*a0, *a1};
    const auto e0 = num("elevation_min"), e1 = num("elevation_max");
    if (e0.has_value() != e1.has_value())
      throw ObserverError(where + ": give both elevation_min and elevation_max, or neither");
    if (e0) o.elevation = AngleRange{*e0, *e1};
    o.max_distance = num("max_distance");
    validate_observer(o, where);
    o.source = where;
    out.push_back(std::move(o));
  }
  if (header.empty()) throw ObserverError(path.string() + ": empty file: expected a header line (x,y,z,...)");
  return out;
}

}  // namespace

void validate_observer(const Observer& o, const std::string& where) {
  // The readers check each value where they parse it (naming its JSON pointer or CSV column); this
  // covers observers built in code (the Python module's arrays), whose far coordinates would
  // otherwise fail inside a ray without naming the observer.
  auto check = [&](double v, const char* what) {
    if (coordinate_ok(v)) return;
    throw ObserverError(where + ": " + what + ": expected " + coordinate_expected() + ", got " + shortest_text(v));
  };
  check(o.position.x, "x");
  check(o.position.y, "y");
  check(o.position.z, "z");
  if (o.has_z && o.height)
    throw ObserverError(where + ": give either z (absolute eye position) or height (above the local "
                        "ground), not both");
  if (o.height) check(*o.height, "height");
  if (o.azimuth && (!angle_ok(o.azimuth->lo) || !angle_ok(o.azimuth->hi)))
    throw ObserverError(where + ": azimuth: expected degrees in [0, 360] (clockwise from north, +Y)");
  if (o.elevation && !(o.elevation->lo >= -90.0 && o.elevation->hi <= 90.0 &&
                       o.elevation->lo <= o.elevation->hi))
    throw ObserverError(where + ": elevation: expected -90 <= min <= max <= 90 degrees");
  if (o.max_distance && !(*o.max_distance >= 0.0))
    throw ObserverError(where + ": max_distance: expected a number >= 0");
}

std::vector<Observer> read_observers(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_text_file(path);  // the input policy: regular file, size cap
  } catch (const InputFileError& e) {
    throw ObserverError(e.what());
  }
  const std::string ext = lower_extension(path);
  std::vector<Observer> out;
  if (ext == ".json")
    out = read_json(path, text);
  else if (ext == ".csv" || ext == ".txt")
    out = read_csv(path, text);
  else
    throw ObserverError(path.string() + ": unknown observer file type '" + ext +
                        "' (expected .json, .csv or .txt)");
  if (out.empty()) throw ObserverError(path.string() + ": the file lists no observer");
  return out;
}

Observer parse_observer(std::string_view text, std::string source) {
  const std::vector<std::string> parts = split(text, ',');
  const std::string where = source.empty() ? "observer '" + std::string(text) + "'" : std::move(source);
  if (parts.size() < 2 || parts.size() > 3)
    throw ObserverError({where + ": expected X,Y,Z (absolute) or X,Y (eye at the default height, ", option("height"),
                         ", above the ground)"});
  Observer o;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const auto v = to_number(parts[i]);
    if (!v) throw ObserverError(where + ": '" + parts[i] + "' is not a finite number");
    if (!coordinate_ok(*v))
      throw ObserverError(where + ": " + "xyz"[i] + ": expected " + coordinate_expected() + ", got '" + parts[i] + "'");
    o.position[static_cast<int>(i)] = *v;
  }
  o.has_z = parts.size() == 3;
  o.source = where;
  return o;
}

// The lowest point within `radius` of (x, y) among the points whose z lies in [z_lo, z_hi] (the
// cloud's z range: every point), ground class 2 preferred; NaN when there is none. The box query
// returns original ids; positions and classes are read from `cloud` (original order).
template <class Index>
double local_ground_in(const Index& index, const PointCloud& cloud, double x, double y, double radius, double z_lo,
                       double z_hi) {
  const AABB cyl{Vec3(x - radius, y - radius, z_lo), Vec3(x + radius, y + radius, z_hi)};
  std::vector<PointIndex> ids;
  visit_index(
      [&](const auto& idx) {
        [[maybe_unused]] const auto scope = detail::chunk_scope(idx);  // the ids outlive it, no position
        box_query(idx, cyl, ids);
      },
      index);
  const bool classified = cloud.classification.size() == cloud.size();
  const double r2 = radius * radius;
  double lowest_any = kInf, lowest_ground = kInf;
  for (const PointIndex i : ids) {
    const Vec3& p = cloud.positions[i];
    if ((p.x - x) * (p.x - x) + (p.y - y) * (p.y - y) > r2) continue;
    if (classified) {
      const std::uint8_t c = cloud.classification[i];
      if (c == 7 || c == 18) continue;
      if (c == 2) lowest_ground = std::min(lowest_ground, p.z);
    }
    lowest_any = std::min(lowest_any, p.z);
  }
  if (lowest_ground < kInf) return lowest_ground;
  if (lowest_any < kInf) return lowest_any;
  return std::numeric_limits<double>::quiet_NaN();
}

template <class Index>
double local_ground_over(const Index& index, const PointCloud& cloud, double x, double y, double radius) {
  if (cloud.empty()) return std::numeric_limits<double>::quiet_NaN();
  const AABB b = cloud.bounds();
  return local_ground_in(index, cloud, x, y, radius, b.lo.z, b.hi.z);
}

template <class Index>
void place_observers_over(std::vector<Observer>& observers, const Index& index, const PointCloud& cloud,
                     const GroundOptions& options) {
  if (!(options.radius > 0.0) || !std::isfinite(options.radius))
    throw ObserverError("ground radius must be a finite number > 0");
  // A NaN eye height would put every eye at NaN (no point seen, no error); infinity or a huge
  // height would fail later in a ray without naming the option.
  if (options.default_height && !coordinate_ok(*options.default_height)) {
    throw ObserverError({option("height"), ": expected an eye height above the local ground, " +
                                               coordinate_expected() + ", got " + shortest_text(*options.default_height)});
  }
  std::optional<AABB> bounds;  // the cloud's z range, computed once (an O(N) pass), when needed
  for (std::size_t k = 0; k < observers.size(); ++k) {
    Observer& o = observers[k];
    if (o.has_z) continue;
    const std::optional<double> h = o.height ? o.height : options.default_height;
    if (!h)
      throw ObserverError({observer_where(o, k + 1) + ": no z and no height; give z, a height, or a default height (",
                           option("height"), ")"});
    if (!bounds && !cloud.empty()) bounds = cloud.bounds();
    auto ground_within = [&](double radius) {
      return cloud.empty() ? std::numeric_limits<double>::quiet_NaN()
                           : local_ground_in(index, cloud, o.position.x, o.position.y, radius, bounds->lo.z,
                                             bounds->hi.z);
    };
    double g = std::numeric_limits<double>::quiet_NaN();
    if (options.inner_radius && *options.inner_radius > 0.0 && *options.inner_radius < options.radius)
      g = ground_within(*options.inner_radius);
    if (std::isnan(g)) g = ground_within(options.radius);
    if (std::isnan(g)) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": no point within the ground radius %.6g of (%.6f, %.6f) to put the "
                    "eye above; move it or raise ", options.radius, o.position.x, o.position.y);
      throw ObserverError({observer_where(o, k + 1) + buf, option("ground_radius")});
    }
    o.ground_z = g;
    o.height = *h;
    o.position.z = g + *h;
  }
}

double local_ground(const Site& site, const PointCloud& cloud, double x, double y, double radius) {
  return detail::over_site<double>(site,
                                   [&](const auto& index) { return local_ground_over(index, cloud, x, y, radius); });
}
void place_observers(std::vector<Observer>& observers, const Site& site, const PointCloud& cloud,
                     const GroundOptions& options) {
  detail::over_site<void>(site, [&](const auto& index) { place_observers_over(observers, index, cloud, options); });
}

bool within_angle_limits(const Observer& o, const Vec3& dir) {
  const double horiz = std::hypot(dir.x, dir.y);
  if (o.elevation) {
    const double el = std::atan2(dir.z, horiz) * (180.0 / 3.14159265358979323846);
    if (el < o.elevation->lo || el > o.elevation->hi) return false;
  }
  if (o.azimuth && horiz > 0.0) {
    const double span = std::fmod(o.azimuth->hi - o.azimuth->lo + 720.0, 360.0);
    if (span == 0.0 && o.azimuth->hi != o.azimuth->lo) return true;  // full circle
    double az = std::atan2(dir.x, dir.y) * (180.0 / 3.14159265358979323846);  // clockwise from +Y
    const double rel = std::fmod(az - o.azimuth->lo + 720.0, 360.0);
    if (rel > span) return false;
  }
  return true;
}

bool within_view_limits(const Observer& o, double max_distance, const Vec3& v, double length) {
  if (!(length <= o.max_distance.value_or(max_distance))) return false;
  return !(o.azimuth || o.elevation) || within_angle_limits(o, v);
}

std::string observer_label(const Observer& o, std::size_t number) {
  return o.name.empty() ? "observer " + std::to_string(number) : "observer '" + o.name + "'";
}

std::string observer_where(const Observer& o, std::size_t number) {
  return o.source.empty() ? observer_label(o, number) : o.source + ": " + observer_label(o, number);
}

}  // namespace rayscan::analysis
