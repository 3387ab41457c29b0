// XYZ/CSV/TXT reader (no formal specification; the common ASCII column layout that CloudCompare,
// PDAL's text reader and LAStools' txt2las read): one point per line, values separated by
// whitespace, commas or semicolons; '#' starts a comment line; an optional first line naming the
// columns (x, y, z, r/red, g/green, b/blue, i/intensity in any order, case-insensitive; other
// names become scalars). Without a header the columns are x y z, then scalars col4, col5, ...
// Every value is parsed as double (a float32 cannot hold UTM northings to the centimetre).
#include "readers.hpp"

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

enum class Col { skip, x, y, z, r, g, b, intensity, scalar };

}  // namespace

PointCloud read_text(const Input& in, const ReadOptions& opt, FileInfo& info) {
  const auto* d = reinterpret_cast<const char*>(in.bytes.data());
  const std::string& nm = in.name;
  info.format = "text";
  PointCloud pc;
  std::vector<Col> cols;
  std::vector<std::size_t> scalar_of;
  std::vector<float> colour;
  bool colour_float = false, has_rgb = false;
  std::size_t ncols_min = 3;
  bool first = true;
  std::vector<std::string_view> f;
  std::uint64_t pos = 0, lineno = 0;
  pc.positions.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(in.size() / 16, 1u << 20)));
  auto setup = [&](const std::vector<std::string>& names) {
    cols.assign(names.size(), Col::skip);
    scalar_of.assign(names.size(), 0);
    int have = 0;
    for (std::size_t i = 0; i < names.size(); ++i) {
      const std::string n = lower(names[i]);
      Col c = Col::scalar;
      if (n == "x" || n == "//x") c = Col::x, have |= 1;
      else if (n == "y") c = Col::y, have |= 2;
      else if (n == "z") c = Col::z, have |= 4;
      else if (n == "r" || n == "red") c = Col::r;
      else if (n == "g" || n == "green") c = Col::g;
      else if (n == "b" || n == "blue") c = Col::b;
      else if (n == "i" || n == "intensity") c = Col::intensity;
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
      for (std::size_t i = 3; i < f.size(); ++i) names.push_back("col" + std::to_string(i + 1));
      setup(names);
      ncols_min = 3;
    }
    if (f.size() < ncols_min)
      fail_line(nm, lineno, "expected " + std::to_string(ncols_min) + " columns, got " + std::to_string(f.size()));
    double x = 0, y = 0, z = 0, c3[3] = {0, 0, 0};
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
        case Col::intensity: pc.intensity.push_back(to_u16(v)); break;
        case Col::scalar: pc.scalars[scalar_of[k]].values.push_back(v); break;
        case Col::skip: break;
      }
    }
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
      fail_line(nm, lineno, "non-finite coordinate (expected finite x, y, z)");
    pc.positions.emplace_back(x, y, z);
    if (has_rgb) colour.insert(colour.end(), {to_f32(c3[0]), to_f32(c3[1]), to_f32(c3[2])});
  }
  info.header_point_count = pc.positions.size();
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
