// `rayscan info FILE [--json]`: what `pdal info` reports for a point cloud file - format,
// version, point data record format, point counts (and dropped non-finite points), recomputed
// bounds (and the header's where they differ), attributes with their ranges, scale/offset, CRS.
#include "commands.hpp"

#include "rayscan/io/copc.hpp"
#include "rayscan/io/point_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>

namespace rayscan::cli {

namespace {

struct Range {
  std::string name;
  double lo = 0, hi = 0;
};

template <class V, class F>
Range range_of(const std::string& name, const V& v, F get) {
  Range r{name, 0, 0};
  if (v.empty()) return r;
  r.lo = r.hi = static_cast<double>(get(v[0]));
  for (const auto& e : v) {
    const double x = static_cast<double>(get(e));
    r.lo = std::min(r.lo, x);
    r.hi = std::max(r.hi, x);
  }
  return r;
}

std::vector<Range> attribute_ranges(const PointCloud& pc) {
  std::vector<Range> out;
  if (pc.empty()) return out;
  out.push_back(range_of("X", pc.positions, [](const Vec3& p) { return p.x; }));
  out.push_back(range_of("Y", pc.positions, [](const Vec3& p) { return p.y; }));
  out.push_back(range_of("Z", pc.positions, [](const Vec3& p) { return p.z; }));
  if (!pc.intensity.empty()) out.push_back(range_of("intensity", pc.intensity, [](auto v) { return v; }));
  if (!pc.classification.empty())
    out.push_back(range_of("classification", pc.classification, [](auto v) { return v; }));
  if (!pc.gps_time.empty()) out.push_back(range_of("gps_time", pc.gps_time, [](auto v) { return v; }));
  if (!pc.rgb.empty()) {
    out.push_back(range_of("red", pc.rgb, [](const Rgb16& c) { return c.r; }));
    out.push_back(range_of("green", pc.rgb, [](const Rgb16& c) { return c.g; }));
    out.push_back(range_of("blue", pc.rgb, [](const Rgb16& c) { return c.b; }));
  }
  if (!pc.normals.empty()) {
    out.push_back(range_of("normal_x", pc.normals, [](const glm::vec3& n) { return n.x; }));
    out.push_back(range_of("normal_y", pc.normals, [](const glm::vec3& n) { return n.y; }));
    out.push_back(range_of("normal_z", pc.normals, [](const glm::vec3& n) { return n.z; }));
  }
  for (const ScalarField& f : pc.scalars) out.push_back(range_of(f.name, f.values, [](double v) { return v; }));
  return out;
}

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}
/// A coordinate printed to the file's resolution: the decimals of the LAS scale, else 10
/// significant digits.
std::string coord(double v, const std::optional<Vec3>& scale, int axis) {
  char buf[64];
  if (scale && (*scale)[axis] > 0) {
    const int dec = std::clamp(static_cast<int>(std::ceil(-std::log10((*scale)[axis]) - 1e-9)), 0, 12);
    std::snprintf(buf, sizeof buf, "%.*f", dec, v);
  } else {
    std::snprintf(buf, sizeof buf, "%.10g", v);
  }
  return buf;
}

nlohmann::ordered_json vec_json(const Vec3& v) { return {v.x, v.y, v.z}; }

bool same_box(const AABB& a, const AABB& b, const std::optional<Vec3>& scale) {
  for (int k = 0; k < 3; ++k) {
    const double tol = scale ? 0.5 * std::abs((*scale)[k]) : 1e-9 * std::max(1.0, std::abs(a.hi[k]));
    if (std::abs(a.lo[k] - b.lo[k]) > tol || std::abs(a.hi[k] - b.hi[k]) > tol) return false;
  }
  return true;
}

}  // namespace

Runner add_info_command(CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Describe a point cloud file (like `pdal info`): format, "
                                         "counts, recomputed bounds, attributes and their ranges, CRS");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  sub->add_option("FILE", *file, "point cloud file (.las .ply .pcd .xyz .csv .txt .f64)")->required();
  sub->add_flag("--json", *json, "print one JSON object instead of text");
  return [file, json]() -> int {
    io::FileInfo info;
    const PointCloud pc = io::read_point_cloud(*file, io::ReadOptions{}, &info);
    const AABB box = pc.bounds();
    const auto ranges = attribute_ranges(pc);
    const bool header_differs =
        info.header_bounds && !pc.empty() && !same_box(*info.header_bounds, box, info.scale);
    std::map<int, std::uint64_t> classes;
    for (std::uint8_t c : pc.classification) ++classes[c];

    if (*json) {
      nlohmann::ordered_json j;
      j["filename"] = *file;
      j["format"] = info.format;
      if (!info.version.empty()) j["version"] = info.version;
      if (!info.encoding.empty()) j["encoding"] = info.encoding;
      if (info.point_format >= 0) {
        j["point_data_record_format"] = info.point_format;
        j["point_record_length"] = info.record_length;
        j["extra_bytes_per_point"] = info.extra_bytes_per_point;
        j["global_encoding"] = info.global_encoding;
        j["system_id"] = info.system_id;
        j["software"] = info.software;
        j["creation"] = {{"year", info.creation_year}, {"day_of_year", info.creation_day}};
      }
      j["count"] = pc.size();
      j["header_count"] = info.header_point_count;
      j["dropped_nonfinite"] = info.dropped_nonfinite;
      if (!pc.empty()) j["bounds"] = {{"min", vec_json(box.lo)}, {"max", vec_json(box.hi)}};
      if (info.header_bounds)
        j["header_bounds"] = {{"min", vec_json(info.header_bounds->lo)},
                              {"max", vec_json(info.header_bounds->hi)},
                              {"differs", header_differs}};
      if (info.scale) j["scale"] = vec_json(*info.scale);
      if (info.offset) j["offset"] = vec_json(*info.offset);
      if (info.width != 0) j["width"] = info.width, j["height"] = info.height;
      if (info.viewpoint) j["viewpoint"] = *info.viewpoint;
      nlohmann::ordered_json crs = nlohmann::ordered_json::object();
      if (!info.crs_source.empty()) crs["source"] = info.crs_source;
      if (info.epsg != 0) crs["epsg"] = info.epsg;
      if (info.vertical_epsg != 0) crs["vertical_epsg"] = info.vertical_epsg;
      crs["wkt"] = pc.crs_wkt;
      j["crs"] = crs;
      nlohmann::ordered_json attrs = nlohmann::ordered_json::array();
      for (const Range& r : ranges) attrs.push_back({{"name", r.name}, {"min", r.lo}, {"max", r.hi}});
      j["attributes"] = attrs;
      if (!classes.empty()) {
        nlohmann::ordered_json cj = nlohmann::ordered_json::object();
        for (auto [c, n] : classes) cj[std::to_string(c)] = n;
        j["classification_counts"] = cj;
      }
      j["fields"] = info.fields;
      nlohmann::ordered_json vl = nlohmann::ordered_json::array();
      for (const io::VlrInfo& v : info.vlrs)
        vl.push_back({{"user_id", v.user_id}, {"record_id", v.record_id}, {"description", v.description},
                      {"length", v.length}, {"offset", v.offset}, {"extended", v.extended}});
      if (info.format == "LAS" || info.format == "LAZ" || info.format == "COPC") j["vlrs"] = vl;
      if (info.format == "COPC") {
        const io::CopcInfo c = io::read_copc_info(*file);
        const AABB cube = c.node_cube(io::CopcNode{});
        j["copc"] = {{"root_cube", {{"min", vec_json(cube.lo)}, {"max", vec_json(cube.hi)}}},
                     {"spacing", c.spacing}, {"depth", c.depth}, {"nodes", c.nodes.size()},
                     {"hierarchy_pages", c.hierarchy_pages}, {"nodes_per_level", c.nodes_per_level},
                     {"points_per_level", c.points_per_level}};
      }
      j["comments"] = info.comments;
      j["notes"] = info.notes;
      std::cout << j.dump(2) << "\n";
      return 0;
    }
    std::ostream& o = std::cout;
    o << "file:              " << *file << "\n";
    o << "format:            " << info.format;
    if (!info.version.empty()) o << " " << info.version;
    if (!info.encoding.empty()) o << " (" << info.encoding << ")";
    o << "\n";
    if (info.point_format >= 0) {
      o << "point format:      " << info.point_format << " (" << info.record_length << "-byte records, "
        << info.extra_bytes_per_point << " extra bytes)\n";
      o << "system / software: " << info.system_id << " / " << info.software << "\n";
      o << "created:           day " << info.creation_day << " of " << info.creation_year << "\n";
    }
    o << "points:            " << pc.size();
    if (info.header_point_count != pc.size()) o << " (header: " << info.header_point_count << ")";
    o << "\n";
    if (info.dropped_nonfinite > 0) o << "dropped:           " << info.dropped_nonfinite << " non-finite points\n";
    if (info.width != 0) o << "width x height:    " << info.width << " x " << info.height << "\n";
    if (info.viewpoint) {
      o << "viewpoint:         ";
      for (double v : *info.viewpoint) o << num(v) << " ";
      o << "(tx ty tz qw qx qy qz; reported, not applied)\n";
    }
    if (!pc.empty()) {
      o << "bounds min:        " << coord(box.lo.x, info.scale, 0) << " " << coord(box.lo.y, info.scale, 1) << " "
        << coord(box.lo.z, info.scale, 2) << "\n";
      o << "bounds max:        " << coord(box.hi.x, info.scale, 0) << " " << coord(box.hi.y, info.scale, 1) << " "
        << coord(box.hi.z, info.scale, 2) << "\n";
    }
    if (header_differs) {
      const AABB& h = *info.header_bounds;
      o << "header bounds min: " << num(h.lo.x) << " " << num(h.lo.y) << " " << num(h.lo.z) << "  (differs)\n";
      o << "header bounds max: " << num(h.hi.x) << " " << num(h.hi.y) << " " << num(h.hi.z) << "\n";
    }
    if (info.scale) o << "scale:             " << num(info.scale->x) << " " << num(info.scale->y) << " " << num(info.scale->z) << "\n";
    if (info.offset) o << "offset:            " << num(info.offset->x) << " " << num(info.offset->y) << " " << num(info.offset->z) << "\n";
    o << "CRS:               ";
    if (info.crs_source.empty()) o << "none";
    else {
      o << (info.epsg ? "EPSG:" + std::to_string(info.epsg) : std::string("(no EPSG code)"));
      if (info.vertical_epsg) o << " + EPSG:" << info.vertical_epsg << " (vertical)";
      o << " from " << info.crs_source;
    }
    o << "\n";
    if (!pc.crs_wkt.empty()) o << "WKT:               " << pc.crs_wkt.substr(0, 100) << (pc.crs_wkt.size() > 100 ? "..." : "") << "\n";
    if (!ranges.empty()) {
      o << "attributes:\n";
      for (const Range& r : ranges) {
        char line[256];
        std::snprintf(line, sizeof line, "  %-20s %18s %18s\n", r.name.c_str(), num(r.lo).c_str(), num(r.hi).c_str());
        o << line;
      }
    }
    if (!classes.empty()) {
      o << "classes:          ";
      for (auto [c, n] : classes) o << " " << c << ":" << n;
      o << "\n";
    }
    if (!info.vlrs.empty()) {
      o << "VLRs:\n";
      for (const io::VlrInfo& v : info.vlrs)
        o << "  " << (v.extended ? "EVLR " : "VLR  ") << v.user_id << " " << v.record_id << " \"" << v.description
          << "\" " << v.length << " bytes\n";
    }
    if (info.format == "COPC") {
      const io::CopcInfo c = io::read_copc_info(*file);
      const AABB cube = c.node_cube(io::CopcNode{});
      o << "COPC octree:       root cube " << num(cube.lo.x) << " " << num(cube.lo.y) << " " << num(cube.lo.z) << " / "
        << num(cube.hi.x) << " " << num(cube.hi.y) << " " << num(cube.hi.z) << ", spacing " << num(c.spacing)
        << ", depth " << c.depth << ", " << c.nodes.size() << " nodes in " << c.hierarchy_pages << " hierarchy page(s)\n";
      for (std::size_t l = 0; l < c.nodes_per_level.size(); ++l)
        o << "  level " << l << ": " << c.nodes_per_level[l] << " nodes, " << c.points_per_level[l] << " points\n";
    }
    for (const std::string& c : info.comments) o << "comment:           " << c << "\n";
    for (const std::string& n : info.notes) o << "note:              " << n << "\n";
    return 0;
  };
}

}  // namespace rayscan::cli
