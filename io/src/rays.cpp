// Ray files (rayscan/io/rays.hpp): CSV with header ox,oy,oz,dx,dy,dz, or headerless .f64.
#include "rayscan/io/rays.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/io/point_io.hpp"

#include <charconv>
#include <cstring>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace rayscan::io {

namespace {

bool parse_num(const std::string& s, double& v) {
  const char* b = s.data();
  const char* e = b + s.size();
  while (b < e && (*b == ' ' || *b == '\t')) ++b;
  while (e > b && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) --e;
  if (b < e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && b != e;
}

}  // namespace

std::vector<Ray> read_rays(const std::filesystem::path& file) {
  const std::string path = file.string();
  std::vector<Ray> rays;
  auto make = [&](const double* v, const std::string& where) {
    try {
      rays.emplace_back(Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5]));
    } catch (const std::invalid_argument& e) {
      throw FormatError(path + ": " + where + ": " + e.what());
    }
  };
  if (lower_extension(file) == ".f64") {
    const InputFile f(file);  // the input policy: regular file, reads bounded by its size
    const std::uint64_t size = f.size();
    if (size % 48)
      throw FormatError(path + ": byte " + std::to_string(size - size % 48) + ": size " +
                        std::to_string(size) + " is not a multiple of 48 (6 float64 per ray)");
    const std::vector<std::uint8_t> bytes = f.read_all();
    double v[6];
    for (std::uint64_t i = 0; i < size / 48; ++i) {
      std::memcpy(v, bytes.data() + 48 * i, 48);
      make(v, "ray " + std::to_string(i));
    }
    return rays;
  }
  std::istringstream in(read_text_file(file));  // the input policy: regular file, size cap
  std::string line;
  if (!std::getline(in, line)) throw FormatError(path + ": line 1: expected header ox,oy,oz,dx,dy,dz");
  std::string hdr;
  for (char c : line)
    if (c != ' ' && c != '\r' && c != '\t') hdr.push_back(c);
  if (hdr != "ox,oy,oz,dx,dy,dz")
    throw FormatError(path + ": line 1: expected header ox,oy,oz,dx,dy,dz, got '" + line + "'");
  std::size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::stringstream ss(line);
    std::string cell;
    double v[6];
    int n = 0;
    while (std::getline(ss, cell, ',')) {
      if (n == 6 || !parse_num(cell, v[n]))
        throw FormatError(path + ": line " + std::to_string(lineno) +
                          ": expected 6 comma-separated numbers ox,oy,oz,dx,dy,dz, got '" + line + "'");
      ++n;
    }
    if (n != 6)
      throw FormatError(path + ": line " + std::to_string(lineno) + ": expected 6 values, got " +
                        std::to_string(n));
    make(v, "line " + std::to_string(lineno));
  }
  return rays;
}

}  // namespace rayscan::io
