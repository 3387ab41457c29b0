// The info job (rayscan/jobs/info.hpp): what `pdal info` reports for a point cloud file.
#include "rayscan/jobs/info.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/grid_text.hpp"
#include "rayscan/io/point_reader.hpp"

#include <nlohmann/json.hpp>
#include <cpl_conv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <string_view>

namespace rayscan::jobs {

using namespace rayscan::io;  // the io library's types, which this job speaks in

namespace {

std::string decimal(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

/// How the report prints coordinates: to the file's LAS grid (io::GridText, the rule of the text
/// writer and the query CSV: the decimals of the scale, or of the offset when it has more, so that
/// scale 0.01 with offset 0.005 prints x.xx5) when it has a scale, else shortest text (no grid).
GridText grid_text_of(const FileInfo& info) {
  return info.scale ? GridText::of(*info.scale, info.offset.value_or(Vec3(0.0))) : GridText{};
}

/// Coordinate `axis` (0..2) of a point as `grid` prints it (GridText::append: a value off the
/// grid prints shortest).
std::string coord(double v, const GridText& grid, int axis) {
  std::string s;
  grid.append(s, v, axis);
  return s;
}

/// The three coordinates of `v`, space-separated (coord).
std::string coords(const Vec3& v, const GridText& grid) {
  return coord(v.x, grid, 0) + " " + coord(v.y, grid, 1) + " " + coord(v.z, grid, 2);
}

/// The three values of `v`, shortest text each (exact: a LAS offset as stored).
std::string exact3(const Vec3& v) { return shortest_text(v.x) + " " + shortest_text(v.y) + " " + shortest_text(v.z); }

nlohmann::ordered_json vec_json(const Vec3& v) { return {v.x, v.y, v.z}; }

/// The bounds as JSON {"min": [x, y, z], "max": [...]}, or null for no points (an empty box).
nlohmann::ordered_json bounds_json(const AABB& b, std::uint64_t count) {
  if (count == 0) return nullptr;
  return {{"min", vec_json(b.lo)}, {"max", vec_json(b.hi)}};
}

/// The one description of a CRS, for a cloud and an index file alike: fills the EPSG codes
/// (r.info.epsg, r.info.vertical_epsg: the GeoKeys' for a CRS from GeoKeys, else those
/// io::epsg_codes_from_wkt identifies in the WKT, as the LAS reader does a WKT VLR's), and
/// r.crs_name, r.crs_wkt2, r.crs_projjson, r.horizontal_unit, r.vertical_unit and r.warnings from
/// r.crs_wkt and r.bounds through GDAL's OGRSpatialReference (PROJ's unit names; the linear units
/// by io::crs_horizontal_unit and io::crs_vertical_unit). A WKT GDAL cannot parse leaves these
/// empty and has no codes of its own.
void describe_crs(InfoJobResult& r) {
  if (r.crs_wkt.empty()) return;
  // The codes of the CRS described. A CRS from GeoKeys keeps their codes; its WKT, made from them,
  // names the same ones, which is all an index file built from the file keeps. A CRS given as
  // text (a WKT VLR, a PLY comment, an index file) gets the codes identified in that text, not
  // those of GeoKeys a LAS file may carry besides, which can name another CRS.
  const io::EpsgCodes codes = io::epsg_codes_from_wkt(r.crs_wkt);
  if (r.info.crs_source != "GeoKeys") {
    r.info.epsg = codes.horizontal;
    r.info.vertical_epsg = codes.vertical;
  } else {
    if (r.info.epsg == 0) r.info.epsg = codes.horizontal;
    if (r.info.vertical_epsg == 0) r.info.vertical_epsg = codes.vertical;
  }
  OGRSpatialReference srs;
  if (srs.importFromWkt(r.crs_wkt.c_str()) != OGRERR_NONE) return;
  if (const char* name = srs.GetName()) r.crs_name = name;
  // The same CRS as WKT2 (ISO 19162:2019) and PROJJSON, as `pdal info` and `gdalsrsinfo` give it.
  {
    char* text = nullptr;
    const char* wkt2[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
    if (srs.exportToWkt(&text, wkt2) == OGRERR_NONE && text) r.crs_wkt2 = text;
    CPLFree(text);
    text = nullptr;
    if (srs.exportToPROJJSON(&text, nullptr) == OGRERR_NONE && text) r.crs_projjson = text;
    CPLFree(text);
  }
  // The units the other commands use (io's rules), but for a geographic CRS the angle of x and y,
  // which io has no length for, and a vertical unit only where the CRS has a vertical part (a
  // vertical CRS, or a compound one with one): without one io takes z in the horizontal unit,
  // which the file does not state.
  if (srs.IsGeographic()) {
    const char* name = nullptr;
    srs.GetAngularUnits(&name);
    if (name) r.horizontal_unit = name;
  } else if (const std::optional<io::LengthUnit> unit = io::crs_horizontal_unit(r.crs_wkt)) {
    r.horizontal_unit = unit->name;
  }
  if (srs.IsVertical())
    if (const std::optional<io::LengthUnit> unit = io::crs_vertical_unit(r.crs_wkt)) r.vertical_unit = unit->name;
  if (r.count == 0) return;
  const std::vector<std::string> w = crs_warnings(r.crs_wkt, r.bounds);
  r.warnings.insert(r.warnings.end(), w.begin(), w.end());
}

}  // namespace

std::vector<std::string> crs_warnings(const std::string& crs_wkt, const AABB& bounds) {
  std::vector<std::string> warnings;
  OGRSpatialReference srs;
  if (crs_wkt.empty() || srs.importFromWkt(crs_wkt.c_str()) != OGRERR_NONE) return warnings;
  const char* name = nullptr;
  if (srs.IsProjected()) srs.GetLinearUnits(&name);
  const std::string unit_name = name ? name : "";
  const bool degrees_like = std::abs(bounds.lo.x) <= 180.0 && std::abs(bounds.hi.x) <= 180.0 &&
                            std::abs(bounds.lo.y) <= 90.0 && std::abs(bounds.hi.y) <= 90.0;
  if (srs.IsGeographic() && !degrees_like)
    warnings.push_back("the CRS is geographic (degrees) but the coordinates reach beyond +-180 / +-90: they look "
                         "projected; the file's CRS is probably wrong");
  else if (srs.IsGeocentric()) {
    // Earth-centred coordinates of points on or near the surface lie 6,353-6,384 km from the
    // centre (the WGS 84 ellipsoid's semi-axes, +-10 km of terrain); the centre of the bounds of a
    // site does too.
    const double d = glm::length(0.5 * (bounds.lo + bounds.hi)) * srs.GetLinearUnits();
    if (d < 6.34e6 || d > 6.40e6)
      warnings.push_back("the CRS is geocentric (ECEF) but the points lie " + std::to_string(std::lround(d / 1000.0)) +
                           " km from the Earth's centre (expected about 6,370 km): they look projected; the file's "
                           "CRS is probably wrong");
  } else if (srs.IsProjected() && degrees_like)
    warnings.push_back("the CRS is projected (" + unit_name +
                         ") but every coordinate lies within +-180 / +-90: they look like degrees; the file's CRS is "
                         "probably wrong");
  return warnings;
}

InfoJobResult run_info(const InfoJobOptions& options) {
  InfoJobResult r;
  r.file = options.file.string();
  if (is_index_file(options.file)) {
    IndexOpenOptions oo;
    if (options.verify) oo.verify = IndexOpenOptions::Verify::always;
    const MappedIndex m = MappedIndex::open(options.file, oo);
    IndexFileSummary x;
    x.layout = to_string(m.config().layout);
    x.capacity = static_cast<std::uint32_t>(m.config().capacity);
    x.nodes = m.node_count();
    x.depth = m.depth();
    x.points_per_level = m.points_per_level();
    x.file_bytes = m.file_bytes();
    x.bytes_per_point =
        m.empty() ? 0.0 : static_cast<double>(m.file_bytes()) / static_cast<double>(m.positions().size());
    x.attributes = m.attributes().to_string();
    x.positions = to_string(m.position_encoding());
    if (m.position_encoding() == PositionEncoding::las_int32)
      x.positions += " (scale " + exact3(m.positions().scale()) + ", offset " + exact3(m.positions().offset()) + ")";
    x.ids = m.has_ids() ? "stored (original order)" : "not stored (points in index order)";
    if (!m.rgb().empty())
      x.rgb = m.rgb().multiplier() != 0
                  ? "8-bit x " + std::to_string(m.rgb().multiplier()) + " (3 bytes/point, exact)"
                  : std::string("16-bit (6 bytes/point)");
    x.root_cell = m.root_cell();
    x.checksums = m.verified() ? "all sections verified"
                               : "header and metadata verified (nodes and points: rayscan info --verify)";
    x.spacing = m.median_nn_spacing();
    x.sections = m.sections();
    x.sources = m.sources();
    r.index = std::move(x);
    r.info.format = "rayscan index";
    r.count = m.positions().size();
    if (!m.empty()) r.bounds = m.bounds();  // the header's exact bounds, not the root node's float box
    if (m.position_encoding() == PositionEncoding::las_int32) {
      r.info.scale = m.positions().scale();
      r.info.offset = m.positions().offset();
    }
    r.crs_wkt = m.crs_wkt();
    if (!r.crs_wkt.empty()) r.info.crs_source = "index file";
    describe_crs(r);
    return r;
  }
  // Streaming: one chunk in memory at a time, whatever the file size (cloud_stats.hpp). Colour as
  // stored, as `pdal info` reports it: an 8-bit LAS colour 0..236 is shown as 0..236, not as the
  // readers' 16-bit rendering of it (x 257).
  ReadOptions ro;
  ro.stored_colour = true;
  const auto reader = open_point_reader(options.file, AttributeSet::all(), ro);
  CloudStats stats = scan_point_cloud(*reader);
  r.info = reader->info();
  r.count = stats.count;
  r.bounds = stats.bounds;
  r.attributes = std::move(stats.ranges);
  r.stats = options.stats;
  r.classes = std::move(stats.classification_counts);
  r.header_differs = header_bounds_differ(r.info, r.bounds);
  r.crs_wkt = reader->crs_wkt();
  describe_crs(r);
  if (r.info.format == "COPC") r.copc = read_copc_info(options.file);
  return r;
}

namespace {

/// `j` as indented JSON. Strings read from the file (a WKT, a VLR description, a software name)
/// may hold bytes that are not UTF-8 (Latin-1 writers): each is then replaced by U+FFFD and a
/// "warnings" entry says so, rather than failing the whole report on one byte.
std::string dump_report(nlohmann::ordered_json j) {
  try {
    return j.dump(2);
  } catch (const nlohmann::json::type_error&) {
  }
  if (!j.contains("warnings")) j["warnings"] = nlohmann::ordered_json::array();
  j["warnings"].push_back("text fields of the file hold bytes that are not UTF-8; each was replaced by U+FFFD");
  return j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

/// `text` with each line passed through one_line (rayscan/base/input_file.hpp): control
/// characters from the file (an escape sequence in a VLR description, a carriage return in a WKT)
/// are written as \xNN and cannot move the cursor, recolour or clear the user's terminal.
std::string escape_controls(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  std::size_t b = 0;
  for (std::size_t e; (e = text.find('\n', b)) != std::string::npos; b = e + 1)
    out.append(one_line(text.substr(b, e - b))).push_back('\n');
  return out.append(one_line(text.substr(b)));
}

/// The "crs" object of the JSON reports: source, name, epsg, vertical_epsg, horizontal_unit,
/// vertical_unit, wkt, wkt2, projjson (each only when known; wkt always, "" for none).
nlohmann::ordered_json crs_json(const InfoJobResult& r) {
  nlohmann::ordered_json crs = nlohmann::ordered_json::object();
  if (!r.info.crs_source.empty()) crs["source"] = r.info.crs_source;
  if (!r.crs_name.empty()) crs["name"] = r.crs_name;
  if (r.info.epsg != 0) crs["epsg"] = r.info.epsg;
  if (r.info.vertical_epsg != 0) crs["vertical_epsg"] = r.info.vertical_epsg;
  if (!r.horizontal_unit.empty()) crs["horizontal_unit"] = r.horizontal_unit;
  if (!r.vertical_unit.empty()) crs["vertical_unit"] = r.vertical_unit;
  crs["wkt"] = r.crs_wkt;
  if (!r.crs_wkt2.empty()) crs["wkt2"] = r.crs_wkt2;
  if (!r.crs_projjson.empty()) {
    // PROJ's text, parsed to nest as an object (not when the file's CRS carries bytes that are
    // not UTF-8, which the JSON parser refuses: the WKT fields carry it then).
    nlohmann::ordered_json pj = nlohmann::ordered_json::parse(r.crs_projjson, nullptr, false);
    if (!pj.is_discarded()) crs["projjson"] = std::move(pj);
  }
  return crs;
}

/// The CRS in a few words: its name (GDAL's, from the WKT) and EPSG codes, e.g.
/// "NAD83(HARN) / Oregon GIC Lambert (ft) (EPSG:2994)", "unnamed (no EPSG code)".
std::string crs_label(const InfoJobResult& r) {
  std::string s = r.crs_name.empty() ? std::string("(unnamed)") : r.crs_name;
  s += r.info.epsg ? " (EPSG:" + std::to_string(r.info.epsg) : std::string(" (no EPSG code");
  if (r.info.vertical_epsg) s += " + EPSG:" + std::to_string(r.info.vertical_epsg) + " vertical";
  return s + ")";
}

/// The WKT's first 100 characters ("..." when longer).
std::string wkt_excerpt(const InfoJobResult& r) {
  return r.crs_wkt.substr(0, 100) + (r.crs_wkt.size() > 100 ? "..." : "");
}

/// The CRS lines of both text reports (a cloud's and an index file's): "CRS:" (crs_label and
/// where the CRS came from, or "none"), "units:", one "warning:" per warning, "WKT:".
std::string crs_text(const InfoJobResult& r) {
  std::ostringstream o;
  o << "CRS:               " << (r.info.crs_source.empty() ? std::string("none") : crs_label(r) + " from " + r.info.crs_source)
    << "\n";
  if (!r.horizontal_unit.empty())
    o << "units:             " << r.horizontal_unit << " (horizontal)"
      << (r.vertical_unit.empty() ? std::string() : ", " + r.vertical_unit + " (vertical)") << "\n";
  for (const std::string& w : r.warnings) o << "warning:           " << w << "\n";
  if (!r.crs_wkt.empty()) o << "WKT:               " << wkt_excerpt(r) << "\n";
  return o.str();
}

std::string index_report_json(const InfoJobResult& r) {
  const IndexFileSummary& x = *r.index;
  nlohmann::ordered_json j;
  j["filename"] = r.file;
  j["format"] = "rayscan index";
  j["count"] = r.count;
  j["layout"] = x.layout;
  j["capacity"] = x.capacity;
  j["nodes"] = x.nodes;
  j["depth"] = x.depth;
  j["points_per_level"] = x.points_per_level;
  j["file_bytes"] = x.file_bytes;
  j["bytes_per_point"] = x.bytes_per_point;
  j["attributes"] = x.attributes;
  j["positions"] = x.positions;
  j["ids"] = x.ids;
  if (!x.rgb.empty()) j["rgb"] = x.rgb;
  j["root_cell"] = {{"min", vec_json(x.root_cell.lo)}, {"max", vec_json(x.root_cell.hi)}};
  j["bounds"] = bounds_json(r.bounds, r.count);
  j["checksums"] = x.checksums;
  j["spacing"] = x.spacing;
  nlohmann::ordered_json secs = nlohmann::ordered_json::array();
  for (const IndexSectionInfo& s : x.sections)
    secs.push_back({{"name", s.name}, {"offset", s.offset}, {"bytes", s.bytes},
                    {"bytes_per_point", r.count ? static_cast<double>(s.bytes) / static_cast<double>(r.count) : 0.0}});
  j["sections"] = secs;
  nlohmann::ordered_json src = nlohmann::ordered_json::array();
  for (const IndexSource& s : x.sources)
    src.push_back({{"path", s.path}, {"format", s.format}, {"points", s.points}, {"first_id", s.first_id}, {"bytes", s.size}});
  j["sources"] = src;
  j["crs"] = crs_json(r);
  if (!r.warnings.empty()) j["warnings"] = r.warnings;
  return dump_report(j);
}

std::string index_report_text(const InfoJobResult& r) {
  const IndexFileSummary& x = *r.index;
  std::ostringstream o;
  o << "file:              " << r.file << "\n";
  o << "format:            rayscan index (" << x.layout << " octree, capacity " << x.capacity << ")\n";
  o << "points:            " << r.count << "\n";
  o << "nodes:             " << x.nodes << ", depth " << x.depth << "\n";
  o << "points per level: ";
  for (std::size_t d = 0; d < x.points_per_level.size(); ++d)
    if (x.points_per_level[d]) o << " " << d << ":" << x.points_per_level[d];
  o << "\n";
  o << "file size:         " << x.file_bytes << " bytes (" << decimal(x.bytes_per_point) << " bytes/point)\n";
  o << "attributes:        " << (x.attributes.empty() ? std::string("positions only") : x.attributes) << "\n";
  o << "positions:         " << x.positions << "\n";
  o << "ids:               " << x.ids << "\n";
  if (!x.rgb.empty()) o << "rgb:               " << x.rgb << "\n";
  if (r.count != 0) {
    const GridText grid = grid_text_of(r.info);
    o << "bounds min:        " << coords(r.bounds.lo, grid) << "\n";
    o << "bounds max:        " << coords(r.bounds.hi, grid) << "\n";
  }
  o << "sections:         ";
  for (const IndexSectionInfo& s : x.sections)
    o << " " << s.name << " " << decimal(r.count ? static_cast<double>(s.bytes) / static_cast<double>(r.count) : 0.0);
  o << " (bytes/point)\n";
  o << "spacing:           " << decimal(x.spacing) << " (median nearest-neighbour distance: the auto radius)\n";
  o << "checksums:         " << x.checksums << "\n";
  o << crs_text(r);
  for (const IndexSource& s : x.sources)
    o << "source:            " << s.path << " (" << s.format << ", " << s.points << " points)\n";
  return escape_controls(o.str());
}

}  // namespace

std::string info_report_json(const InfoJobResult& r) {
  if (r.index) return index_report_json(r);
  nlohmann::ordered_json j;
  j["filename"] = r.file;
  j["format"] = r.info.format;
  if (!r.info.version.empty()) j["version"] = r.info.version;
  if (!r.info.encoding.empty()) j["encoding"] = r.info.encoding;
  if (r.info.point_format >= 0) {
    j["point_data_record_format"] = r.info.point_format;
    j["point_record_length"] = r.info.record_length;
    j["extra_bytes_per_point"] = r.info.extra_bytes_per_point;
    j["global_encoding"] = r.info.global_encoding;
    j["system_id"] = r.info.system_id;
    j["software"] = r.info.software;
    j["creation"] = {{"year", r.info.creation_year}, {"day_of_year", r.info.creation_day}};
  }
  j["count"] = r.count;
  j["header_count"] = r.info.header_point_count;
  j["dropped_nonfinite"] = r.info.dropped_nonfinite;
  j["bounds"] = bounds_json(r.bounds, r.count);
  if (r.info.header_bounds)
    j["header_bounds"] = {{"min", vec_json(r.info.header_bounds->lo)},
                          {"max", vec_json(r.info.header_bounds->hi)},
                          {"differs", r.header_differs}};
  if (r.info.scale) j["scale"] = vec_json(*r.info.scale);
  if (r.info.offset) j["offset"] = vec_json(*r.info.offset);
  if (r.info.width != 0) j["width"] = r.info.width, j["height"] = r.info.height;
  if (r.info.viewpoint) j["viewpoint"] = *r.info.viewpoint;
  j["crs"] = crs_json(r);
  if (!r.warnings.empty()) j["warnings"] = r.warnings;
  nlohmann::ordered_json attrs = nlohmann::ordered_json::array();
  for (const AttributeRange& a : r.attributes) {
    nlohmann::ordered_json e = {{"name", a.name}, {"min", a.lo}, {"max", a.hi}};
    if (r.stats) e["count"] = a.count, e["mean"] = a.mean, e["stddev"] = a.stddev();
    attrs.push_back(e);
  }
  j["attributes"] = attrs;
  if (!r.classes.empty()) {
    nlohmann::ordered_json cj = nlohmann::ordered_json::object();
    for (auto [c, n] : r.classes) cj[std::to_string(c)] = n;
    j["classification_counts"] = cj;
  }
  j["fields"] = r.info.fields;
  nlohmann::ordered_json vl = nlohmann::ordered_json::array();
  for (const io::VlrInfo& v : r.info.vlrs)
    vl.push_back({{"user_id", v.user_id}, {"record_id", v.record_id}, {"description", v.description},
                  {"length", v.length}, {"offset", v.offset}, {"extended", v.extended}});
  if (r.info.format == "LAS" || r.info.format == "LAZ" || r.info.format == "COPC") j["vlrs"] = vl;
  if (r.copc) {
    const CopcInfo& c = *r.copc;
    const AABB cube = c.node_cube(CopcNode{});
    j["copc"] = {{"root_cube", {{"min", vec_json(cube.lo)}, {"max", vec_json(cube.hi)}}},
                 {"spacing", c.spacing}, {"depth", c.depth}, {"nodes", c.nodes.size()},
                 {"hierarchy_pages", c.hierarchy_pages}, {"nodes_per_level", c.nodes_per_level},
                 {"points_per_level", c.points_per_level}};
  }
  j["comments"] = r.info.comments;
  j["notes"] = r.info.notes;
  return dump_report(j);
}

std::string info_report_text(const InfoJobResult& r) {
  if (r.index) return index_report_text(r);
  std::ostringstream o;
  o << "file:              " << r.file << "\n";
  o << "format:            " << r.info.format;
  // A COPC file's version is the COPC specification's (1.0, the only one) over its LAS version.
  if (!r.info.version.empty())
    o << (r.info.format == "COPC" ? " 1.0 (LAS " + r.info.version + ")" : " " + r.info.version);
  if (!r.info.encoding.empty()) o << " (" << r.info.encoding << ")";
  o << "\n";
  if (r.info.point_format >= 0) {
    o << "point format:      " << r.info.point_format << " (" << r.info.record_length << "-byte records, "
      << r.info.extra_bytes_per_point << " extra bytes)\n";
    o << "system / software: " << r.info.system_id << " / " << r.info.software << "\n";
    o << "created:           day " << r.info.creation_day << " of " << r.info.creation_year << "\n";
  }
  o << "points:            " << r.count;
  if (r.info.header_point_count != r.count) o << " (header: " << r.info.header_point_count << ")";
  o << "\n";
  if (r.info.dropped_nonfinite > 0) o << "dropped:           " << r.info.dropped_nonfinite << " non-finite points\n";
  if (r.info.width != 0) o << "width x height:    " << r.info.width << " x " << r.info.height << "\n";
  if (r.info.viewpoint) {
    o << "viewpoint:         ";
    for (double v : *r.info.viewpoint) o << decimal(v) << " ";
    o << "(tx ty tz qw qx qy qz; reported, not applied)\n";
  }
  const GridText grid = grid_text_of(r.info);
  if (r.count != 0) {
    o << "bounds min:        " << coords(r.bounds.lo, grid) << "\n";
    o << "bounds max:        " << coords(r.bounds.hi, grid) << "\n";
  }
  if (r.header_differs) {
    // As stored (shortest text): the header's own values, which are off the grid.
    const AABB& h = *r.info.header_bounds;
    o << "header bounds min: " << exact3(h.lo) << "  (differs)\n";
    o << "header bounds max: " << exact3(h.hi) << "\n";
  }
  if (r.info.scale) o << "scale:             " << exact3(*r.info.scale) << "\n";
  if (r.info.offset) o << "offset:            " << exact3(*r.info.offset) << "\n";
  o << crs_text(r);
  if (!r.attributes.empty()) {
    o << (r.stats ? "attributes:                          min                max               mean             stddev\n"
                  : "attributes:\n");
    for (const AttributeRange& a : r.attributes) {
      // X, Y, Z to the file's resolution, as the bounds; the other minima and maxima are values of
      // the file's points (integers, GPS times), exact; means and deviations to 10 digits.
      const int axis = a.name == "X" ? 0 : a.name == "Y" ? 1 : a.name == "Z" ? 2 : -1;
      const std::string lo = axis >= 0 ? coord(a.lo, grid, axis) : shortest_text(a.lo);
      const std::string hi = axis >= 0 ? coord(a.hi, grid, axis) : shortest_text(a.hi);
      char line[1024];
      if (r.stats)
        std::snprintf(line, sizeof line, "  %-20s %18s %18s %18s %18s\n", a.name.c_str(), lo.c_str(), hi.c_str(),
                      decimal(a.mean).c_str(), decimal(a.stddev()).c_str());
      else
        std::snprintf(line, sizeof line, "  %-20s %18s %18s\n", a.name.c_str(), lo.c_str(), hi.c_str());
      o << line;
    }
  }
  if (!r.classes.empty()) {
    o << "classes:          ";
    for (auto [c, n] : r.classes) o << " " << c << ":" << n;
    o << "\n";
  }
  if (!r.info.vlrs.empty()) {
    o << "VLRs:\n";
    for (const io::VlrInfo& v : r.info.vlrs)
      o << "  " << (v.extended ? "EVLR " : "VLR  ") << v.user_id << " " << v.record_id << " \"" << v.description
        << "\" " << v.length << " bytes\n";
  }
  if (r.copc) {
    const CopcInfo& c = *r.copc;
    const AABB cube = c.node_cube(CopcNode{});
    o << "COPC octree:       root cube " << decimal(cube.lo.x) << " " << decimal(cube.lo.y) << " " << decimal(cube.lo.z) << " / "
      << decimal(cube.hi.x) << " " << decimal(cube.hi.y) << " " << decimal(cube.hi.z) << ", spacing " << decimal(c.spacing)
      << ", depth " << c.depth << ", " << c.nodes.size() << " nodes in " << c.hierarchy_pages << " hierarchy page(s)\n";
    for (std::size_t l = 0; l < c.nodes_per_level.size(); ++l)
      o << "  level " << l << ": " << c.nodes_per_level[l] << " nodes, " << c.points_per_level[l] << " points\n";
  }
  for (const std::string& c : r.info.comments) o << "comment:           " << c << "\n";
  for (const std::string& n : r.info.notes) o << "note:              " << n << "\n";
  return escape_controls(o.str());
}

}  // namespace rayscan::jobs
