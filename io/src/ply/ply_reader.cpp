// PLY reader: "PLY - Polygon File Format" 1.0 (Greg Turk, 1994; the Stanford/paulbourke.net
// description): header keywords ply, format, comment, obj_info, element, property (scalar and
// list), end_header; formats ascii 1.0, binary_little_endian 1.0, binary_big_endian 1.0; scalar
// types char uchar short ushort int uint float double and their sized aliases int8 .. float64.
// The "vertex" element becomes the points; every other element (faces, edges, ...) is skipped.
// A vertex with a non-finite x, y or z is refused, and so is a finite one beyond +-kMaxCoordinate,
// as the LAS reader refuses it.
// read_ply's steps make their checks in a fixed order (the header, then the body in file order),
// which decides the error a file with several defects reports.
#include "readers.hpp"
#include "rayscan/io/field_names.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace rayscan::io::detail {

namespace {

enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64 };

bool parse_type(const std::string& s, PlyType& t) {
  static const std::pair<const char*, PlyType> names[] = {
      {"char", PlyType::i8},   {"int8", PlyType::i8},     {"uchar", PlyType::u8},
      {"uint8", PlyType::u8},  {"short", PlyType::i16},   {"int16", PlyType::i16},
      {"ushort", PlyType::u16}, {"uint16", PlyType::u16}, {"int", PlyType::i32},
      {"int32", PlyType::i32}, {"uint", PlyType::u32},    {"uint32", PlyType::u32},
      {"float", PlyType::f32}, {"float32", PlyType::f32}, {"double", PlyType::f64},
      {"float64", PlyType::f64}};
  for (const auto& [n, v] : names)
    if (s == n) {
      t = v;
      return true;
    }
  return false;
}
int type_size(PlyType t) {
  switch (t) {
    case PlyType::i8: case PlyType::u8: return 1;
    case PlyType::i16: case PlyType::u16: return 2;
    case PlyType::i32: case PlyType::u32: case PlyType::f32: return 4;
    case PlyType::f64: return 8;
  }
  return 1;
}
bool is_float(PlyType t) { return t == PlyType::f32 || t == PlyType::f64; }
const char* type_name(PlyType t) {
  static const char* n[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double"};
  return n[static_cast<int>(t)];
}

/// The least and greatest value of an integer type (PLY 1.0: char 1-byte signed ... uint 4-byte
/// unsigned); float types have no such range here (any number, as the binary body can hold).
bool integer_range(PlyType t, double& lo, double& hi) {
  switch (t) {
    case PlyType::i8: lo = -128.0, hi = 127.0; return true;
    case PlyType::u8: lo = 0.0, hi = 255.0; return true;
    case PlyType::i16: lo = -32768.0, hi = 32767.0; return true;
    case PlyType::u16: lo = 0.0, hi = 65535.0; return true;
    case PlyType::i32: lo = -2147483648.0, hi = 2147483647.0; return true;
    case PlyType::u32: lo = 0.0, hi = 4294967295.0; return true;
    default: return false;
  }
}

template <bool BigEndian>
double load(const std::uint8_t* p, PlyType t) {
  auto ld = [p]<class T>(T) { return BigEndian ? load_be<T>(p) : load_le<T>(p); };
  switch (t) {
    case PlyType::i8: return static_cast<std::int8_t>(*p);
    case PlyType::u8: return *p;
    case PlyType::i16: return ld(std::int16_t{});
    case PlyType::u16: return ld(std::uint16_t{});
    case PlyType::i32: return ld(std::int32_t{});
    case PlyType::u32: return ld(std::uint32_t{});
    case PlyType::f32: return ld(float{});
    case PlyType::f64: return ld(double{});
  }
  return 0.0;
}

struct Property {
  std::string name;
  PlyType type = PlyType::f32;
  bool is_list = false;
  PlyType count_type = PlyType::u8;
};
struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> props;
  std::uint64_t line = 0;
};

/// What a vertex property becomes in the PointCloud.
enum class Role { skip, x, y, z, nx, ny, nz, r, g, b, intensity, classification, gps, scalar };

Role role_of(const Property& p) {
  if (p.is_list) return Role::skip;
  std::string n = ascii_lower(p.name);
  // CloudCompare (and rayscan's writer) give scalar fields the prefix "scalar_": such a property
  // may still be the intensity, classification or GPS time both write under it, but never a
  // position, normal or colour channel (written unprefixed), nor the alpha that is dropped, so a
  // scalar field named "nx", "red" or "a" reads back as that scalar.
  const bool prefixed = n.rfind("scalar_", 0) == 0;
  if (prefixed) {
    n = n.substr(7);
  } else {
    if (n == "x") return Role::x;
    if (n == "y") return Role::y;
    if (n == "z") return Role::z;
    if (n == "nx" || n == "normal_x") return Role::nx;
    if (n == "ny" || n == "normal_y") return Role::ny;
    if (n == "nz" || n == "normal_z") return Role::nz;
    if (n == "red" || n == "r" || n == "diffuse_red") return Role::r;
    if (n == "green" || n == "g" || n == "diffuse_green") return Role::g;
    if (n == "blue" || n == "b" || n == "diffuse_blue") return Role::b;
    if (n == "alpha" || n == "a" || n == "diffuse_alpha") return Role::skip;
  }
  // Integer intensities (LAS-style, up to 16 bit) fill the intensity field; floating-point ones
  // (e.g. the Stanford scanner's 0..1 "intensity") stay a named scalar so no value is rounded.
  if (n == "intensity" && !is_float(p.type) && type_size(p.type) <= 2) return Role::intensity;
  if ((n == "classification" || n == "class") && p.type == PlyType::u8) return Role::classification;
  if (n == "gps_time" || n == "gpstime") return Role::gps;
  return Role::scalar;
}

/// Cursor over the ascii body: whitespace-separated tokens, counting lines for errors.
struct AsciiCursor {
  const Input& in;
  std::uint64_t pos;
  std::uint64_t line;
  std::string_view next(const char* what) {
    const auto* d = reinterpret_cast<const char*>(in.bytes.data());
    while (pos < in.size() && (d[pos] == ' ' || d[pos] == '\t' || d[pos] == '\r' || d[pos] == '\n')) {
      if (d[pos] == '\n') ++line;
      ++pos;
    }
    if (pos >= in.size()) fail_line(in.name, line, std::string("file ends, expected ") + what);
    const std::uint64_t b = pos;
    while (pos < in.size() && !(d[pos] == ' ' || d[pos] == '\t' || d[pos] == '\r' || d[pos] == '\n'))
      ++pos;
    return {d + b, pos - b};
  }
  double number(const Property& p, bool count) {
    const std::string what = "a value for property '" + p.name + "'";
    std::string_view t = next(what.c_str());
    double v = 0;
    const char* b = t.data();
    const char* e = t.data() + t.size();
    if (b != e && *b == '+') ++b;
    auto [q, ec] = std::from_chars(b, e, v);
    if (ec != std::errc() || q != e || (count && (v < 0 || v != std::floor(v))))
      fail_line(in.name, line, (count ? "expected a list count for '" : "expected a number for '") +
                                   p.name + "', got '" + std::string(t.substr(0, 40)) + "'");
    // A value of an integer property must be one its declared type holds (the binary body cannot
    // hold another): an integer in its range.
    double lo = 0, hi = 0;
    if (const PlyType ty = count ? p.count_type : p.type; integer_range(ty, lo, hi) && !(v >= lo && v <= hi && v == std::floor(v)))
      fail_line(in.name, line, std::string(count ? "the list count of '" : "property '") + p.name + "' is " +
                                   type_name(ty) + ": expected an integer in " +
                                   std::to_string(static_cast<long long>(lo)) + ".." +
                                   std::to_string(static_cast<long long>(hi)) + ", got '" +
                                   std::string(t.substr(0, 40)) + "'");
    return v;
  }
};

/// A parsed PLY header (PLY 1.0: "ply", format, comment/obj_info, element, property,
/// end_header).
struct PlyHeader {
  std::vector<Element> elems;  ///< in file order (the body stores them in this order)
  std::size_t vertex = 0;      ///< index in elems of the (last) element named "vertex"
  int format = -1;             ///< 0 ascii, 1 binary_little_endian, 2 binary_big_endian
  std::string crs_wkt;         ///< from a "comment crs <WKT>" line; "" when absent
  std::uint64_t line = 0;      ///< line number of end_header
  std::uint64_t body = 0;      ///< byte offset of the body (after the end_header line)
  [[nodiscard]] const Element& vertex_element() const { return elems[vertex]; }
};

/// Splits a header line at spaces and tabs.
std::vector<std::string> words(const std::string& s) {
  std::vector<std::string> w;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    std::size_t j = i;
    while (j < s.size() && s[j] != ' ' && s[j] != '\t') ++j;
    if (j > i) w.push_back(s.substr(i, j - i));
    i = j;
  }
  return w;
}

/// A "property <type> <name>" or "property list <count type> <type> <name>" line split into
/// words `w` (line `line` of the file, text `l`). Throws FormatError on an unknown type or form.
Property parse_property(const std::string& nm, std::uint64_t line, const std::vector<std::string>& w,
                        const std::string& l) {
  Property p;
  if (w.size() == 5 && w[1] == "list") {
    p.is_list = true;
    if (!parse_type(w[2], p.count_type) || is_float(p.count_type))
      fail_line(nm, line, "list count type '" + w[2] + "' is not an integer PLY type");
    if (!parse_type(w[3], p.type)) fail_line(nm, line, "unknown PLY type '" + w[3] + "'");
    p.name = w[4];
  } else if (w.size() == 3) {
    if (!parse_type(w[1], p.type))
      fail_line(nm, line, "unknown PLY type '" + w[1] +
                              "' (expected char, uchar, short, ushort, int, uint, float, double)");
    p.name = w[2];
  } else {
    fail_line(nm, line, "expected \"property <type> <name>\" or \"property list <count type> "
                        "<type> <name>\", got '" + l + "'");
  }
  return p;
}

/// Reads the header up to end_header: the magic line, the format (version 1.0 only), the
/// elements and their properties; comments go to info.comments. Lists the vertex properties in
/// info.fields ("x:float", "vertex_indices:list int") and sets info's encoding, version and
/// header point count. Throws FormatError "line N: ..." on the first defect, or when there is
/// no vertex element or it lacks x, y or z.
PlyHeader parse_ply_header(const Input& in, FileInfo& info) {
  const auto* d = reinterpret_cast<const char*>(in.bytes.data());
  const std::string& nm = in.name;
  PlyHeader h;
  std::uint64_t pos = 0;
  std::uint64_t& line = h.line;
  auto next_line = [&](std::string& out) {
    if (pos >= in.size()) return false;
    std::uint64_t e = pos;
    while (e < in.size() && d[e] != '\n') ++e;
    out.assign(d + pos, e - pos);
    if (!out.empty() && out.back() == '\r') out.pop_back();
    pos = e < in.size() ? e + 1 : e;
    ++line;
    return true;
  };
  std::string l;
  if (!next_line(l) || l != "ply") fail_line(nm, 1, "expected the magic line \"ply\"");
  std::vector<Element>& elems = h.elems;
  bool ended = false;
  while (next_line(l)) {
    const auto w = words(l);
    if (w.empty()) continue;
    if (w[0] == "comment" || w[0] == "obj_info") {
      info.comments.push_back(l);
      // "comment crs <WKT>": the convention rayscan's PLY writer uses to carry the CRS.
      if (w[0] == "comment" && w.size() > 2 && w[1] == "crs") h.crs_wkt = l.substr(l.find("crs") + 4);
    } else if (w[0] == "format") {
      if (w.size() != 3) fail_line(nm, line, "expected \"format <encoding> 1.0\", got '" + l + "'");
      if (w[1] == "ascii") h.format = 0;
      else if (w[1] == "binary_little_endian") h.format = 1;
      else if (w[1] == "binary_big_endian") h.format = 2;
      else
        fail_line(nm, line, "unknown PLY format '" + w[1] +
                                "' (expected ascii, binary_little_endian or binary_big_endian)");
      info.encoding = w[1];
      info.version = w[2];
      if (w[2] != "1.0") fail_line(nm, line, "unsupported PLY version '" + w[2] + "' (expected 1.0)");
    } else if (w[0] == "element") {
      if (w.size() != 3) fail_line(nm, line, "expected \"element <name> <count>\", got '" + l + "'");
      Element e;
      e.name = w[1];
      e.line = line;
      auto [p, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), e.count);
      if (ec != std::errc() || p != w[2].data() + w[2].size())
        fail_line(nm, line, "element count '" + w[2] + "' is not a non-negative integer");
      elems.push_back(e);
    } else if (w[0] == "property") {
      if (elems.empty()) fail_line(nm, line, "property before any element");
      elems.back().props.push_back(parse_property(nm, line, w, l));
    } else if (w[0] == "end_header") {
      ended = true;
      break;
    } else {
      fail_line(nm, line, "unknown header keyword '" + w[0] + "'");
    }
  }
  if (!ended) fail_line(nm, line, "file ends before \"end_header\"");
  if (h.format < 0) fail_line(nm, line, "no \"format\" line in the header");
  h.body = pos;
  bool found = false;
  for (std::size_t i = 0; i < elems.size(); ++i)
    if (elems[i].name == "vertex") h.vertex = i, found = true;
  if (!found) fail_line(nm, line, "no \"vertex\" element in the header");
  const Element& vertex = h.vertex_element();
  info.header_point_count = vertex.count;
  int have = 0;
  for (const Property& p : vertex.props) {
    info.fields.push_back(p.name + ":" + (p.is_list ? "list " : "") + type_name(p.type));
    const Role r = role_of(p);
    have |= r == Role::x ? 1 : r == Role::y ? 2 : r == Role::z ? 4 : 0;
  }
  if (have != 7) fail_line(nm, vertex.line, "vertex element lacks property x, y or z");
  return h;
}

/// What each vertex property becomes, and which outputs exist.
struct VertexRoles {
  std::vector<Role> of;                 ///< per vertex property
  bool has_n = false, has_rgb = false;  ///< normals (an nx property); colour (a red property)
  bool has_i = false, has_c = false, has_g = false;  ///< intensity, classification, GPS time
  bool rgb_float = false;               ///< some colour property is float (colour_scale's rule)
  std::vector<std::size_t> scalar_idx;  ///< per property: its index in PointCloud::scalars
  std::size_t nscalars = 0;
};

/// The roles of the vertex properties (role_of). A second property with an already taken role
/// becomes a named scalar; scalars are kept only with opt.scalars.
VertexRoles vertex_roles(const Element& vertex, const ReadOptions& opt) {
  const std::size_t np = vertex.props.size();
  VertexRoles v;
  v.of.resize(np);
  v.scalar_idx.assign(np, 0);
  std::vector<bool> taken(static_cast<std::size_t>(Role::scalar) + 1, false);
  for (std::size_t k = 0; k < np; ++k) {
    Role& r = v.of[k];
    r = role_of(vertex.props[k]);
    // A second property with the same role (e.g. "intensity" and "scalar_intensity") stays a
    // named scalar so that every attribute vector gets exactly one value per vertex.
    if (r != Role::skip && r != Role::scalar) {
      if (taken[static_cast<std::size_t>(r)]) r = Role::scalar;
      else taken[static_cast<std::size_t>(r)] = true;
    }
    v.has_n |= r == Role::nx;
    v.has_rgb |= r == Role::r;
    if (r == Role::r || r == Role::g || r == Role::b) v.rgb_float |= is_float(vertex.props[k].type);
    v.has_i |= r == Role::intensity;
    v.has_c |= r == Role::classification;
    v.has_g |= r == Role::gps;
    if (r == Role::scalar) {
      if (opt.scalars) v.scalar_idx[k] = v.nscalars++;
      else r = Role::skip;
    }
  }
  return v;
}

/// The body of a PLY file decoded into a PointCloud: the elements in header order, the vertex
/// element's values gathered per vertex in `vals` and emitted; the elements after it are not
/// read.
struct PlyBody {
  const Input& in;
  FileInfo& info;
  const PlyHeader& h;
  const Element& vertex;
  const VertexRoles& roles;
  PointCloud pc;
  std::vector<float> col;     ///< r, g, b per vertex (before colour_scale)
  std::vector<double> vals;   ///< the current vertex: one value per property (0 for lists)
  std::uint64_t vertex_index = 0;

  PlyBody(const Input& input, FileInfo& file_info, const PlyHeader& header, const VertexRoles& r)
      : in(input), info(file_info), h(header), vertex(header.vertex_element()), roles(r),
        vals(vertex.props.size()) {}

  /// Reserves the outputs, only what the file can hold (every vertex needs at least one byte
  /// per property), and names the scalars.
  void reserve_outputs() {
    const std::size_t np = vertex.props.size();
    const std::uint64_t remaining = in.size() - h.body;
    const std::uint64_t cap = std::min<std::uint64_t>(vertex.count, remaining / std::max<std::size_t>(np, 1));
    auto reserve = [&](auto& v, bool on) {
      if (on) v.reserve(static_cast<std::size_t>(cap));
    };
    reserve(pc.positions, true);
    reserve(pc.normals, roles.has_n);
    reserve(pc.intensity, roles.has_i);
    reserve(pc.classification, roles.has_c);
    reserve(pc.gps_time, roles.has_g);
    if (roles.has_rgb) col.reserve(static_cast<std::size_t>(cap) * 3);
    for (std::size_t k = 0; k < np; ++k)
      if (roles.of[k] == Role::scalar) {
        // CloudCompare's "scalar_" prefix (docs/formats.md) is not part of the field's name,
        // unless the property is a second one for a dedicated field ("scalar_intensity" beside
        // "intensity"), which keeps its full name.
        std::string name = vertex.props[k].name;
        if (name.size() > 7 && ascii_lower(name.substr(0, 7)) == "scalar_" && role_of(vertex.props[k]) == Role::scalar)
          name = name.substr(7);
        pc.scalars.push_back({name, {}});
        pc.scalars.back().values.reserve(static_cast<std::size_t>(cap));
      }
  }

  /// Appends the vertex in `vals`. Throws FormatError at `where` (a line when is_line, else the
  /// vertex's first byte) when x, y or z is not finite, or is finite but beyond +-kMaxCoordinate
  /// (beyond_coordinate_bound's "point N: ...", N the vertex's index), as the LAS reader refuses it.
  void emit(std::uint64_t where, bool is_line) {
    double x = 0, y = 0, z = 0, n3[3] = {0, 0, 0}, c3[3] = {0, 0, 0};
    const std::size_t np = vals.size();
    for (std::size_t k = 0; k < np; ++k) {
      const double a = vals[k];
      switch (roles.of[k]) {
        case Role::x: x = a; break;
        case Role::y: y = a; break;
        case Role::z: z = a; break;
        case Role::nx: n3[0] = a; break;
        case Role::ny: n3[1] = a; break;
        case Role::nz: n3[2] = a; break;
        case Role::r: c3[0] = a; break;
        case Role::g: c3[1] = a; break;
        case Role::b: c3[2] = a; break;
        case Role::intensity: pc.intensity.push_back(to_u16(a)); break;
        case Role::classification: pc.classification.push_back(to_u8(a)); break;
        case Role::gps: pc.gps_time.push_back(a); break;
        case Role::scalar: pc.scalars[roles.scalar_idx[k]].values.push_back(a); break;
        case Role::skip: break;
      }
    }
    if (!within_coordinate_bound(x, y, z)) {  // one compare per axis; NaN and infinities too
      const std::string what = !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)
                                   ? "vertex " + std::to_string(vertex_index) +
                                         " has a non-finite coordinate (expected finite x, y, z)"
                                   : beyond_coordinate_bound(vertex_index, x, y, z);
      if (is_line) fail_line(in.name, where, what);
      fail_at(in.name, where, what);
    }
    pc.positions.emplace_back(x, y, z);
    if (roles.has_n) pc.normals.emplace_back(to_f32(n3[0]), to_f32(n3[1]), to_f32(n3[2]));
    if (roles.has_rgb) col.insert(col.end(), {to_f32(c3[0]), to_f32(c3[1]), to_f32(c3[2])});
    ++vertex_index;
  }

  /// format ascii 1.0: whitespace-separated values, one item per line by convention (lines are
  /// not enforced). Throws FormatError "line N: ..." on a bad value or when an element announces
  /// more items than the bytes left could hold.
  void read_ascii_elements() {
    const std::string& nm = in.name;
    AsciiCursor cur{in, h.body, h.line + 1};
    for (const Element& e : h.elems) {
      const bool is_vertex = &e == &vertex;
      // Loops bounded by the file's size, not by the header's count: an element
      // without properties holds no data, and every item of one with properties takes at
      // least one byte.
      if (e.props.empty()) continue;
      if (e.count > in.size() - std::min<std::uint64_t>(cur.pos, in.size()))
        fail_line(nm, cur.line, "element '" + e.name + "' announces " + std::to_string(e.count) +
                                    " items but only " + std::to_string(in.size() - cur.pos) +
                                    " bytes remain");
      for (std::uint64_t i = 0; i < e.count; ++i) {
        for (std::size_t k = 0; k < e.props.size(); ++k) {
          const Property& p = e.props[k];
          if (p.is_list) {
            const double cnt = cur.number(p, true);
            if (cnt > static_cast<double>(in.size() - cur.pos))
              fail_line(nm, cur.line, "list count " + std::to_string(cnt) + " exceeds the file");
            for (std::uint64_t j = 0; j < static_cast<std::uint64_t>(cnt); ++j) cur.number(p, false);
            if (is_vertex) vals[k] = 0;
          } else {
            const double a = cur.number(p, false);
            if (is_vertex) vals[k] = a;
          }
        }
        if (is_vertex) emit(cur.line, true);
      }
      if (is_vertex) break;
    }
  }

  /// format binary_little_endian / binary_big_endian 1.0: each item's properties packed in
  /// header order, a list as its count then the values. Elements of fixed size before the
  /// vertex element are skipped whole. Throws FormatError "byte N: ..." when the data ends early
  /// or a list count is negative.
  void read_binary_elements() {
    const std::string& nm = in.name;
    const bool big = h.format == 2;
    auto ld = [big](const std::uint8_t* p, PlyType t) { return big ? load<true>(p, t) : load<false>(p, t); };
    const std::uint8_t* b = in.bytes.data();
    std::uint64_t p = h.body;
    for (const Element& e : h.elems) {
      const bool is_vertex = &e == &vertex;
      bool fixed = true;
      std::uint64_t stride = 0;
      for (const Property& q : e.props) {
        fixed &= !q.is_list;
        stride += static_cast<std::uint64_t>(type_size(q.is_list ? q.count_type : q.type));
      }
      if (fixed && stride > 0 && e.count > (in.size() - p) / stride)
        fail_at(nm, p, "element '" + e.name + "' announces " + std::to_string(e.count) + " items of " +
                           std::to_string(stride) + " bytes but only " + std::to_string(in.size() - p) +
                           " bytes remain");
      if (fixed && !is_vertex) {
        p += e.count * stride;
        continue;
      }
      for (std::uint64_t i = 0; i < e.count; ++i) {
        const std::uint64_t start = p;
        for (std::size_t k = 0; k < e.props.size(); ++k) {
          const Property& q = e.props[k];
          if (q.is_list) {
            const int cs = type_size(q.count_type);
            in.need(p, static_cast<std::uint64_t>(cs), "list count of '" + q.name + "'");
            const double cnt = ld(b + p, q.count_type);
            p += static_cast<std::uint64_t>(cs);
            if (cnt < 0) fail_at(nm, p - cs, "negative list count for '" + q.name + "'");
            const std::uint64_t bytes = static_cast<std::uint64_t>(cnt) * static_cast<std::uint64_t>(type_size(q.type));
            in.need(p, bytes, "list '" + q.name + "' of element '" + e.name + "'");
            p += bytes;
            if (is_vertex) vals[k] = 0;
          } else {
            const int s = type_size(q.type);
            in.need(p, static_cast<std::uint64_t>(s), "property '" + q.name + "' of element '" + e.name + "'");
            if (is_vertex) vals[k] = ld(b + p, q.type);
            p += static_cast<std::uint64_t>(s);
          }
        }
        if (is_vertex) {
          emit(start, false);
          if ((i + 1) % 65536 == 0) in.done(p);
        }
      }
      if (is_vertex) break;
    }
  }

  /// PointCloud::rgb from the colour properties, scaled by colour_scale() (its note added to
  /// info.notes); 8-bit colour (scaled by 257) is marked PointCloud::rgb_from_8bit_las.
  void finish_colour() {
    if (!roles.has_rgb) return;
    float mx = 0;
    for (float c : col) mx = std::max(mx, c);
    std::string note;
    const double s = colour_scale(mx, roles.rgb_float, note);
    if (!note.empty()) info.notes.push_back(note);
    // write_las stores 8-bit colour as those values, as PDAL's writers.las does with a PLY's
    // uchar red: LAS -> PLY -> LAS keeps the LAS file's own colour values.
    pc.rgb_from_8bit_las = s == 257.0;
    pc.rgb.resize(pc.positions.size());
    for (std::size_t i = 0; i < pc.rgb.size(); ++i) {
      auto q = [&](float c) { return to_u16(c * s); };
      pc.rgb[i] = Rgb16{q(col[3 * i]), q(col[3 * i + 1]), q(col[3 * i + 2])};
    }
  }
};

}  // namespace

PointCloud read_ply(const Input& in, const ReadOptions& opt, FileInfo& info) {
  info.format = "PLY";
  const PlyHeader h = parse_ply_header(in, info);
  const VertexRoles roles = vertex_roles(h.vertex_element(), opt);
  PlyBody body(in, info, h, roles);
  body.reserve_outputs();
  if (h.format == 0) body.read_ascii_elements();
  else body.read_binary_elements();
  body.finish_colour();
  body.pc.crs_wkt = h.crs_wkt;
  if (!h.crs_wkt.empty()) info.crs_source = "PLY comment crs";
  return std::move(body.pc);
}

}  // namespace rayscan::io::detail
