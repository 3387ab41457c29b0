// Internal: what the point writers (LAS, PLY, PCD, text) share: the check of the cloud before
// anything is written, the names they give its fields, the 8-bit colour rule.
#pragma once

#include "rayscan/octree/point_cloud.hpp"

#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>

namespace rayscan::io::detail {

/// cloud.validate(), its message prefixed with the output `path` ("<path>: <what is wrong>").
/// Throws std::invalid_argument.
inline void validate_for_writing(const std::filesystem::path& path, const PointCloud& cloud) {
  try {
    cloud.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
}

/// `prefix` + `name` with every character other than [A-Za-z0-9_] replaced by '_' ("field" for an
/// empty name), made unique among `used` by a suffix _1, _2, ... and added to it. PLY, PCD and the
/// text header all take such a name as one token.
inline std::string unique_field_name(const std::string& prefix, const std::string& name, std::set<std::string>& used) {
  std::string s = prefix + (name.empty() ? std::string("field") : name);
  for (char& c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) c = '_';
  std::string out = s;
  for (int k = 1; used.count(out) != 0; ++k) out = s + "_" + std::to_string(k);
  used.insert(out);
  return out;
}

/// 16-bit colour to 8 bit (the nearest of v / 257), as the 8-bit formats store it.
inline unsigned char colour_to_8bit(unsigned v) { return static_cast<unsigned char>((v + 128u) / 257u); }

}  // namespace rayscan::io::detail
