// Internal: what the point writers (LAS, PLY, PCD, text) share: the check of the cloud before
// anything is written, the names they give its fields and the comments that describe them, the
// 8-bit colour rule; and which scalar names the PCD and text writers must rename (the rules
// themselves are public, rayscan/io/field_names.hpp, which the Python bindings share).
#pragma once

#include "bytes.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/field_names.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rayscan::io::detail {

/// cloud.validate(), its message prefixed with the output `path` ("<path>: <what is wrong>"),
/// every position within +-kMaxCoordinate and a CRS that GDAL reads (require_readable_crs): a file is
/// written only if the readers will read it back ("<path>: point N: X coordinate is V (expected
/// within +-1e+09, ...)", the readers' text), and its CRS with GDAL, PDAL or QGIS. Throws
/// std::invalid_argument before anything is written.
inline void validate_for_writing(const std::filesystem::path& path, const PointCloud& cloud) {
  try {
    cloud.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
  for (std::size_t i = 0; i < cloud.positions.size(); ++i) {
    const Vec3& p = cloud.positions[i];
    if (!within_coordinate_bound(p.x, p.y, p.z))
      throw std::invalid_argument(path.string() + ": " + beyond_coordinate_bound(i, p.x, p.y, p.z));
  }
  require_readable_crs(path.string(), cloud.crs_wkt);
}

/// `prefix` + `name` with every character other than [A-Za-z0-9_] replaced by '_' ("field" for an
/// empty name), made unique among `used` by a suffix _1, _2, ... and added to it. PLY, PCD and the
/// text header all take such a name as one token. A name for which `reserved` (when given) is true
/// takes a suffix too: a scalar whose name the format's reader would take for another field.
inline std::string unique_field_name(const std::string& prefix, const std::string& name, std::set<std::string>& used,
                                     bool (*reserved)(std::string_view) = nullptr) {
  std::string s = prefix + (name.empty() ? std::string("field") : name);
  for (char& c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) c = '_';
  std::string out = s;
  for (int k = 1; used.count(out) != 0 || (reserved != nullptr && reserved(out)); ++k) out = s + "_" + std::to_string(k);
  used.insert(out);
  return out;
}

/// The header comment describing the field that a file names `written_name` (after
/// unique_field_name), from the description the LAS writer puts in the field's Extra Bytes
/// descriptor: "field scalar_solar_global: global irradiation, kWh/m2", and "; no data -1" when
/// `info` declares a no-data value; line breaks in the description become spaces, so it stays
/// one line. "" when `info` says nothing. PLY writes it after "comment ", PCD after "# ": the free
/// text each format allows in its header, which PCL, Open3D, CloudCompare and rayscan's readers
/// skip.
inline std::string field_comment(const std::string& written_name, const ExtraBytesInfo& info) {
  std::string d = info.description;
  for (char& c : d)
    if (c == '\n' || c == '\r') c = ' ';
  if (info.no_data) d += (d.empty() ? "" : "; ") + std::string("no data ") + shortest_text(*info.no_data);
  return d.empty() ? std::string() : "field " + written_name + ": " + d;
}

/// 16-bit colour to 8 bit (the nearest of v / 257), as the 8-bit formats store it.
inline unsigned char colour_to_8bit(unsigned v) { return static_cast<unsigned char>((v + 128u) / 257u); }

/// The names the readers take for a dedicated field (rayscan/io/field_names.hpp), also for code
/// of this namespace that names them detail::.
using io::dedicated_field_name;

/// True when a scalar that the `format` writer stores under `name` would not read back as that
/// scalar (scalar_read_back_as): the PCD and text writers give it a suffix (unique_field_name).
template <Format format>
bool scalar_name_reserved(std::string_view name) {
  return scalar_read_back_as(format, name) != nullptr;
}

}  // namespace rayscan::io::detail
