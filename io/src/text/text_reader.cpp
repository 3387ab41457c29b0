// XYZ/CSV/TXT/PTS reader (no formal specification; the common ASCII column layout that
// CloudCompare, PDAL's text reader and LAStools' txt2las read): one point per line, values
// separated by whitespace, commas or semicolons; '#' starts a comment line; an optional first line
// naming the columns (text_named_field, rayscan/io/field_names.hpp: x, y, z, r/red, g/green,
// b/blue, i/intensity, nx/ny/nz in any order, case-insensitive; other names become scalars).
// Without a header the columns are x y z, then scalars col4, col5, ... A .pts file (Leica
// Cyclone's layout, as PDAL's readers.pts reads it) may start each scan with a line holding its
// point count; its rows are then x y z, x y z intensity or x y z intensity r g b, the intensity in
// -2048..2047 stored + 2048 as PDAL does.
// Every value is parsed as double (a float32 cannot hold UTM northings to the centimetre). A
// non-finite x, y or z is refused, and so is a finite one beyond +-kMaxCoordinate, as the LAS
// reader refuses it ("line L: point N: ...", N counting the rows read).
#include "readers.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/io/field_names.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace rayscan::io::detail {

namespace {

bool is_sep(char c) { return c == ',' || c == ' ' || c == '\t' || c == ';' || c == '\r'; }

bool parse_double(std::string_view s, double& v) {
  const char* b = s.data();
  const char* e = s.data() + s.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e;
}

enum class Col { skip, x, y, z, r, g, b, intensity, nx, ny, nz, scalar };

/// The column a header name names (text_named_field, which the text writer and rayscan.write
/// share to keep a scalar from reading back as one of these).
Col col_of(std::string_view name) {
  switch (text_named_field(name)) {
    case NamedField::x: return Col::x;
    case NamedField::y: return Col::y;
    case NamedField::z: return Col::z;
    case NamedField::red: return Col::r;
    case NamedField::green: return Col::g;
    case NamedField::blue: return Col::b;
    case NamedField::intensity: return Col::intensity;
    case NamedField::nx: return Col::nx;
    case NamedField::ny: return Col::ny;
    case NamedField::nz: return Col::nz;
    case NamedField::scalar:
    case NamedField::packed_rgb:
    case NamedField::padding: break;  // not text names
  }
  return Col::scalar;
}

/// True when `s` is a whole non-negative decimal integer (a PTS count line), stored in `v`.
bool parse_count(std::string_view s, std::uint64_t& v) {
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && p == s.data() + s.size();
}

}  // namespace

PointCloud read_text(const Input& in, const ReadOptions& opt, FileInfo& info) {
  const auto* d = reinterpret_cast<const char*>(in.bytes.data());
  const std::string& nm = in.name;
  info.format = "text";
  PointCloud pc;
  std::vector<Col> cols;
  std::vector<std::size_t> scalar_of;
  std::vector<float> colour;
  bool colour_float = false, has_rgb = false, has_normals = false;
  std::size_t ncols_min = 3;
  bool first = true;
  std::vector<std::string_view> f;
  std::uint64_t pos = 0, lineno = 0;
  // PTS: the sum of the count lines (one per scan) and how many there were.
  const bool pts = lower_extension(nm) == ".pts";
  std::uint64_t pts_count = 0, pts_count_lines = 0;
  double intensity_add = 0.0;  // PTS intensity: -2048..2047 stored as 0..4095 (PDAL readers.pts)
  pc.positions.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(in.size() / 16, 1u << 20)));
  auto setup = [&](const std::vector<std::string>& names) {
    cols.assign(names.size(), Col::skip);
    scalar_of.assign(names.size(), 0);
    // Normal columns are normals only as a set of three (the text writer's nx ny nz); one or two
    // of them are scalars like any other column.
    int nbits = 0;
    for (const std::string& n : names) {
      const Col t = col_of(n);
      nbits |= t == Col::nx ? 1 : t == Col::ny ? 2 : t == Col::nz ? 4 : 0;
    }
    has_normals = nbits == 7;
    int have = 0;
    for (std::size_t i = 0; i < names.size(); ++i) {
      Col c = col_of(names[i]);
      if (!has_normals && (c == Col::nx || c == Col::ny || c == Col::nz)) c = Col::scalar;
      have |= c == Col::x ? 1 : c == Col::y ? 2 : c == Col::z ? 4 : 0;
      if (c != Col::scalar)
        for (std::size_t j = 0; j < i; ++j)
          if (cols[j] == c)
            fail_line(nm, lineno, "columns " + std::to_string(j + 1) + " and " + std::to_string(i + 1) +
                                      " ('" + names[j] + "', '" + names[i] + "') name the same attribute");
      if (c == Col::scalar) {
        if (!opt.scalars) c = Col::skip;
        else {
          scalar_of[i] = pc.scalars.size();
          pc.scalars.push_back({names[i], {}});
        }
      }
      has_rgb |= c == Col::r || c == Col::g || c == Col::b;
      cols[i] = c;
      info.fields.push_back(names[i]);
    }
    return have == 7;
  };
  while (pos < in.size()) {
    std::uint64_t e = pos;
    while (e < in.size() && d[e] != '\n') ++e;
    const std::string_view line(d + pos, e - pos);
    pos = e + 1;
    ++lineno;
    f.clear();
    for (std::size_t i = 0; i < line.size();) {
      while (i < line.size() && is_sep(line[i])) ++i;
      std::size_t j = i;
      while (j < line.size() && !is_sep(line[j])) ++j;
      if (j > i) f.push_back(line.substr(i, j - i));
      i = j;
    }
    if (f.empty() || f[0][0] == '#') continue;
    if (pts && f.size() == 1) {  // a PTS count line: before the first row, and before each further scan
      std::uint64_t c = 0;
      if (parse_count(f[0], c)) {
        pts_count += c;
        ++pts_count_lines;
        continue;
      }
    }
    if (first) {
      first = false;
      double tmp;
      if (!parse_double(f[0], tmp)) {  // a header naming the columns
        std::vector<std::string> names(f.begin(), f.end());
        if (!setup(names))
          fail_line(nm, lineno, "header must name columns x, y and z, got '" +
                                    std::string(line.substr(0, 80)) + "'");
        ncols_min = names.size();
        continue;
      }
      std::vector<std::string> names = {"x", "y", "z"};
      if (pts_count_lines > 0 && (f.size() == 4 || f.size() == 7)) {  // PTS rows, as PDAL's readers.pts reads them
        names.push_back("intensity");
        if (f.size() == 7) names.insert(names.end(), {"red", "green", "blue"});
        intensity_add = 2048.0;
      }
      for (std::size_t i = names.size(); i < f.size(); ++i) names.push_back("col" + std::to_string(i + 1));
      setup(names);
      ncols_min = 3;
    }
    if (f.size() < ncols_min)
      fail_line(nm, lineno, "expected " + std::to_string(ncols_min) + " columns, got " + std::to_string(f.size()));
    double x = 0, y = 0, z = 0, c3[3] = {0, 0, 0}, n3[3] = {0, 0, 0};
    for (std::size_t k = 0; k < cols.size(); ++k) {
      if (cols[k] == Col::skip) continue;
      double v = 0;
      if (k >= f.size()) {  // missing trailing optional column (headerless files)
        v = 0;
      } else if (!parse_double(f[k], v)) {
        fail_line(nm, lineno, "column " + std::to_string(k + 1) + ": expected a finite number, got '" +
                                  std::string(f[k].substr(0, 40)) + "'");
      }
      switch (cols[k]) {
        case Col::x: x = v; break;
        case Col::y: y = v; break;
        case Col::z: z = v; break;
        case Col::r: c3[0] = v; colour_float |= f[k].find('.') != std::string_view::npos; break;
        case Col::g: c3[1] = v; colour_float |= f[k].find('.') != std::string_view::npos; break;
        case Col::b: c3[2] = v; colour_float |= f[k].find('.') != std::string_view::npos; break;
        case Col::intensity: pc.intensity.push_back(to_u16(v + intensity_add)); break;
        case Col::nx: n3[0] = v; break;
        case Col::ny: n3[1] = v; break;
        case Col::nz: n3[2] = v; break;
        case Col::scalar: pc.scalars[scalar_of[k]].values.push_back(v); break;
        case Col::skip: break;
      }
    }
    if (!within_coordinate_bound(x, y, z)) {  // one compare per axis; NaN and infinities too
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        fail_line(nm, lineno, "non-finite coordinate (expected finite x, y, z)");
      fail_line(nm, lineno, beyond_coordinate_bound(pc.positions.size(), x, y, z));
    }
    pc.positions.emplace_back(x, y, z);
    if (has_rgb) colour.insert(colour.end(), {to_f32(c3[0]), to_f32(c3[1]), to_f32(c3[2])});
    if (has_normals) pc.normals.emplace_back(to_f32(n3[0]), to_f32(n3[1]), to_f32(n3[2]));
  }
  info.header_point_count = pc.positions.size();
  if (pts_count_lines > 0 && pts_count != pc.positions.size())
    info.notes.push_back("the PTS count line" + std::string(pts_count_lines > 1 ? "s give " : " gives ") +
                         std::to_string(pts_count) + " points; " + std::to_string(pc.positions.size()) +
                         " rows read");
  if (has_rgb) {
    float mx = 0;
    for (float c : colour) mx = std::max(mx, c);
    std::string note;
    const double s = colour_scale(mx, colour_float, note);
    if (!note.empty()) info.notes.push_back(note);
    // 8-bit colour is kept as such by the writers that store 16-bit values (LAS, text): a text
    // file's 236 becomes 236 in a LAS file and in the text written back from it.
    pc.rgb_from_8bit_las = s == 257.0;
    pc.rgb.resize(pc.positions.size());
    for (std::size_t i = 0; i < pc.rgb.size(); ++i) {
      auto q = [&](float c) { return to_u16(c * s); };
      pc.rgb[i] = Rgb16{q(colour[3 * i]), q(colour[3 * i + 1]), q(colour[3 * i + 2])};
    }
  }
  return pc;
}

}  // namespace rayscan::io::detail
