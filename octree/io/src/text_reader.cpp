#include "text_reader.hpp"

#include <cctype>
#include <charconv>
#include <fstream>
#include <vector>

namespace rayscan::io {

namespace {
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',' || c == ' ' || c == '\t' || c == ';' || c == '\r') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur.push_back(c);
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

bool parse_double(const std::string& s, double& v) {
  const char* b = s.data();
  const char* e = s.data() + s.size();
  if (b != e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e;
}
}  // namespace

PointCloud read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path.string() + ": cannot open file");
  PointCloud pc;
  std::string line;
  std::size_t lineno = 0;
  int cx = 0, cy = 1, cz = 2, cr = -1, cg = -1, cb = -1, ci = -1;
  std::size_t ncols_min = 3;
  bool first = true;
  const std::string where = path.string() + ": line ";
  while (std::getline(in, line)) {
    ++lineno;
    const auto f = split(line);
    if (f.empty() || f[0][0] == '#') continue;
    if (first) {
      first = false;
      double tmp;
      if (!parse_double(f[0], tmp)) {  // a header naming columns
        cx = cy = cz = -1;
        for (std::size_t i = 0; i < f.size(); ++i) {
          std::string n = f[i];
          for (char& c : n) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
          const int ii = static_cast<int>(i);
          if (n == "x") cx = ii;
          else if (n == "y") cy = ii;
          else if (n == "z") cz = ii;
          else if (n == "r" || n == "red") cr = ii;
          else if (n == "g" || n == "green") cg = ii;
          else if (n == "b" || n == "blue") cb = ii;
          else if (n == "intensity" || n == "i") ci = ii;
        }
        if (cx < 0 || cy < 0 || cz < 0)
          throw FormatError(where + std::to_string(lineno) +
                            ": header must name columns x, y and z, got '" + line + "'");
        ncols_min = static_cast<std::size_t>(std::max({cx, cy, cz, cr, cg, cb, ci})) + 1;
        continue;
      }
    }
    if (f.size() < ncols_min)
      throw FormatError(where + std::to_string(lineno) + ": expected at least " +
                        std::to_string(ncols_min) + " columns, got " + std::to_string(f.size()));
    double v[3];
    const int cols[3] = {cx, cy, cz};
    for (int k = 0; k < 3; ++k) {
      if (!parse_double(f[static_cast<std::size_t>(cols[k])], v[k]) || !std::isfinite(v[k]))
        throw FormatError(where + std::to_string(lineno) + ": column " + std::to_string(cols[k] + 1) +
                          ": expected a finite number, got '" + f[static_cast<std::size_t>(cols[k])] + "'");
    }
    pc.positions.emplace_back(v[0], v[1], v[2]);
  }
  (void)cr; (void)cg; (void)cb; (void)ci;
  return pc;
}

}  // namespace rayscan::io
