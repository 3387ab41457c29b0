// Internal: what the point writers (LAS, PLY, PCD, text) share: the check of the cloud before
// anything is written, the names they give its fields, the 8-bit colour rule; and the other
// spellings of the LAS fields' names that the PLY, PCD and text readers take.
#pragma once

#include "rayscan/octree/point_cloud.hpp"

#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

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

/// The scalar name that write_las stores in a standard LAS point field (the name rayscan's LAS
/// reader gives the field) for the field `name` of a PLY, PCD or text file, or nullptr for
/// another name. Matched ignoring case and '_', so that PDAL's dimension names (ReturnNumber,
/// NumberOfReturns, ScanDirectionFlag, EdgeOfFlightLine, ScanAngleRank, UserData, PointSourceId,
/// ScanChannel, Infrared: PDAL's Dimension.json, as readers.las names them and writers.pcd,
/// writers.ply and writers.text write them), their snake_case forms and rayscan's own names all
/// match. PDAL's ScanAngleRank is in degrees, as rayscan's scan_angle is.
inline const char* las_standard_scalar_name(std::string_view name) {
  std::string key;
  for (char c : name)
    if (c != '_') key += (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
  static constexpr std::pair<std::string_view, const char*> kNames[] = {
      {"returnnumber", "return_number"},
      {"numberofreturns", "number_of_returns"},
      {"scandirectionflag", "scan_direction_flag"},
      {"edgeofflightline", "edge_of_flight_line"},
      {"scanangle", "scan_angle"},
      {"scananglerank", "scan_angle"},
      {"userdata", "user_data"},
      {"pointsourceid", "point_source_id"},
      {"scannerchannel", "scanner_channel"},
      {"scanchannel", "scanner_channel"},
      {"classificationflags", "classification_flags"},
      {"nir", "nir"},
      {"infrared", "nir"},
  };
  for (const auto& [k, scalar] : kNames)
    if (key == k) return scalar;
  return nullptr;
}

}  // namespace rayscan::io::detail
