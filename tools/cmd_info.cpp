// `rayscan info FILE [--json]`: what `pdal info` reports for a point cloud file - format,
// version, point data record format, point counts (and dropped non-finite points), recomputed
// bounds (and the header's where they differ), attributes with their ranges, scale/offset, CRS.
#include "commands.hpp"

#include "rayscan/io/cloud_stats.hpp"
#include "rayscan/io/index_file.hpp"
#include "rayscan/io/copc.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/point_reader.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>

namespace rayscan::cli {

namespace {

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

/// `rayscan info SITE.rsi`: the index file's tree and sources.
int index_info(const std::string& file, bool json, bool verify) {
  io::IndexOpenOptions oo;
  if (verify) oo.verify = io::IndexOpenOptions::Verify::always;
  const io::MappedIndex m = io::MappedIndex::open(file, oo);
  const auto levels = m.points_per_level();
  const double bpp = m.empty() ? 0.0 : static_cast<double>(m.file_bytes()) / static_cast<double>(m.positions().size());
  nlohmann::ordered_json j;
  j["filename"] = file;
  j["format"] = "rayscan index";
  j["count"] = m.positions().size();
  j["layout"] = to_string(m.config().layout);
  j["capacity"] = m.config().capacity;
  j["nodes"] = m.node_count();
  j["depth"] = m.depth();
  j["points_per_level"] = levels;
  j["file_bytes"] = m.file_bytes();
  j["bytes_per_point"] = bpp;
  j["attributes"] = m.attributes().to_string();
  j["root_cell"] = {{"min", vec_json(m.root_cell().lo)}, {"max", vec_json(m.root_cell().hi)}};
  if (!m.empty()) {
    const AABB b = m.node_bounds(m.root());
    j["bounds"] = {{"min", vec_json(b.lo)}, {"max", vec_json(b.hi)}};
  }
  j["checksums"] = verify || m.file_bytes() <= (256u << 20) ? "all sections verified" : "header, nodes and metadata verified";
  nlohmann::ordered_json src = nlohmann::ordered_json::array();
  for (const io::IndexSource& s : m.sources())
    src.push_back({{"path", s.path}, {"format", s.format}, {"points", s.points}, {"first_id", s.first_id}, {"bytes", s.size}});
  j["sources"] = src;
  j["crs"] = {{"wkt", m.crs_wkt()}};
  if (json) {
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::ostream& o = std::cout;
  o << "file:              " << file << "\n";
  o << "format:            rayscan index (" << to_string(m.config().layout) << " octree, capacity " << m.config().capacity << ")\n";
  o << "points:            " << m.positions().size() << "\n";
  o << "nodes:             " << m.node_count() << ", depth " << m.depth() << "\n";
  o << "points per level: ";
  for (std::size_t d = 0; d < levels.size(); ++d)
    if (levels[d]) o << " " << d << ":" << levels[d];
  o << "\n";
  o << "file size:         " << m.file_bytes() << " bytes (" << num(bpp) << " bytes/point)\n";
  o << "attributes:        " << (m.attributes().bits ? m.attributes().to_string() : std::string("positions only")) << "\n";
  o << "checksums:         " << j["checksums"].get<std::string>() << "\n";
  o << "CRS:               " << (m.crs_wkt().empty() ? std::string("none") : m.crs_wkt().substr(0, 100)) << "\n";
  for (const io::IndexSource& s : m.sources())
    o << "source:            " << s.path << " (" << s.format << ", " << s.points << " points)\n";
  return 0;
}

}  // namespace

Runner add_info_command(CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Describe a point cloud file (like `pdal info`): format, "
                                         "counts, recomputed bounds, attributes and their ranges, CRS");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  sub->add_option("FILE", *file, "point cloud file (.las .laz .copc.laz .ply .pcd .xyz .csv .txt .f64) or index file (.rsi)")->required();
  sub->add_flag("--json", *json, "print one JSON object instead of text");
  auto verify = std::make_shared<bool>(false);
  sub->add_flag("--verify", *verify, "index files: verify the checksum of every section");
  return [file, json, verify]() -> int {
    if (io::is_index_file(*file)) return index_info(*file, *json, *verify);
    // Streaming: one chunk in memory at a time, whatever the file size.
    const auto reader = io::open_point_reader(*file);
    const io::CloudStats stats = io::scan_point_cloud(*reader);
    const io::FileInfo& info = reader->info();
    struct {
      std::uint64_t n;
      const std::string& crs_wkt;
      [[nodiscard]] std::uint64_t size() const { return n; }
      [[nodiscard]] bool empty() const { return n == 0; }
    } pc{stats.count, reader->crs_wkt()};
    const AABB box = stats.bounds;
    const auto& ranges = stats.ranges;
    const bool header_differs =
        info.header_bounds && !pc.empty() && !same_box(*info.header_bounds, box, info.scale);
    const auto& classes = stats.classification_counts;

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
      for (const io::AttributeRange& r : ranges) attrs.push_back({{"name", r.name}, {"min", r.lo}, {"max", r.hi}});
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
      for (const io::AttributeRange& r : ranges) {
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
