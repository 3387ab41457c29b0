// The names of point fields shared by the readers, the writers and the Python bindings: the other
// spellings of the LAS fields that rayscan's LAS reader gives as named scalars.
#pragma once

#include <string>
#include <string_view>
#include <utility>

namespace rayscan::io {

/// The scalar name that rayscan's LAS reader gives a standard LAS point field, and write_las stores
/// in that field, for a field called `name` in a PLY, PCD or text file or a NumPy structured array;
/// nullptr for any other name. Matched ignoring ASCII case and '_', so that PDAL's dimension names
/// (ReturnNumber, NumberOfReturns, ScanDirectionFlag, EdgeOfFlightLine, ScanAngleRank, UserData,
/// PointSourceId, ScanChannel, Infrared: PDAL's Dimension.json, as readers.las names them and
/// writers.pcd, writers.ply and writers.text write them), their snake_case forms (laspy's
/// scan_angle_rank) and rayscan's own names all match. PDAL's ScanAngleRank is in degrees, as
/// rayscan's scan_angle is.
[[nodiscard]] inline const char* las_standard_scalar_name(std::string_view name) {
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

}  // namespace rayscan::io
