// The names of point fields shared by the readers, the writers and the Python bindings: the other
// spellings of the LAS fields that rayscan's LAS reader gives as named scalars, the names the PLY,
// PCD and text readers take for a dedicated attribute, and so which scalar names a file of each
// format gives back under another name.
#pragma once

#include "rayscan/base/ascii_case.hpp"
#include "rayscan/io/point_io.hpp"

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
  std::string key = ascii_lower(name);
  std::erase(key, '_');
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

/// The PointCloud field that a PLY, PCD or text field called `name` is read into when its values
/// fit it (promote_scalars, point_reader.cpp): "intensity", "classification" or "gps_time" (also
/// spelt "gpstime"), matched ignoring ASCII case; nullptr for any other name.
[[nodiscard]] inline const char* dedicated_field_name(std::string_view name) {
  const std::string n = ascii_lower(name);
  if (n == "intensity") return "intensity";
  if (n == "classification") return "classification";
  if (n == "gps_time" || n == "gpstime") return "gps_time";
  return nullptr;
}

/// What a PCD or text reader makes of a field by its name: a coordinate, a normal component, a
/// colour channel, PCL's packed colour, the intensity column, PCL's padding (skipped), or a
/// scalar field of that name.
enum class NamedField { scalar, x, y, z, nx, ny, nz, red, green, blue, packed_rgb, intensity, padding };

/// The PCD reader's rule (pcd_reader.cpp), ignoring ASCII case: x, y, z; normal_x/nx, normal_y/ny,
/// normal_z/nz; rgb and rgba (packed colour, when SIZE 4 and COUNT 1); red/r, green/g, blue/b; "_"
/// is PCL's padding. A coordinate, normal or colour field of COUNT > 1 is a scalar all the same.
[[nodiscard]] inline NamedField pcd_named_field(std::string_view name) {
  const std::string n = ascii_lower(name);
  if (n == "_") return NamedField::padding;
  if (n == "x") return NamedField::x;
  if (n == "y") return NamedField::y;
  if (n == "z") return NamedField::z;
  if (n == "normal_x" || n == "nx") return NamedField::nx;
  if (n == "normal_y" || n == "ny") return NamedField::ny;
  if (n == "normal_z" || n == "nz") return NamedField::nz;
  if (n == "rgb" || n == "rgba") return NamedField::packed_rgb;
  if (n == "red" || n == "r") return NamedField::red;
  if (n == "green" || n == "g") return NamedField::green;
  if (n == "blue" || n == "b") return NamedField::blue;
  return NamedField::scalar;
}

/// The text reader's rule for a header name (text_reader.cpp), ignoring ASCII case: x (also
/// CloudCompare's "//x"), y, z, r/red, g/green, b/blue, i/intensity, nx/ny/nz (also PDAL's
/// NormalX/NormalY/NormalZ: normals when all three are there, else scalars).
[[nodiscard]] inline NamedField text_named_field(std::string_view name) {
  const std::string n = ascii_lower(name);
  if (n == "x" || n == "//x") return NamedField::x;
  if (n == "y") return NamedField::y;
  if (n == "z") return NamedField::z;
  if (n == "r" || n == "red") return NamedField::red;
  if (n == "g" || n == "green") return NamedField::green;
  if (n == "b" || n == "blue") return NamedField::blue;
  if (n == "i" || n == "intensity") return NamedField::intensity;
  if (n == "nx" || n == "normalx") return NamedField::nx;
  if (n == "ny" || n == "normaly") return NamedField::ny;
  if (n == "nz" || n == "normalz") return NamedField::nz;
  return NamedField::scalar;
}

/// What rayscan's reader of `format` fills from a scalar field that rayscan's writer of that
/// format stored under `name` (before the writer makes it a valid, unique name), where it does not
/// give it back as the scalar `name`: "the positions", "the normals", "the colour", "PCL's padding,
/// which is skipped" (PCD and text: a field so named is that attribute), or "the intensity
/// attribute", "the classification attribute", "the gps_time attribute" (PLY, PCD and text:
/// dedicated_field_name; the PLY writer's "scalar_" prefix keeps every other name). nullptr when it
/// reads back as that scalar, and for LAS and .f64. The PCD and text writers write such a scalar
/// with a suffix ("nx_1"); rayscan.write refuses it. A name las_standard_scalar_name renames is
/// another case, which the writers keep as it is.
[[nodiscard]] inline const char* scalar_read_back_as(Format format, std::string_view name) {
  if (format != Format::ply && format != Format::pcd && format != Format::text) return nullptr;
  if (const char* d = dedicated_field_name(name)) {
    std::string_view v(d);
    return v == "intensity" ? "the intensity attribute"
           : v == "classification" ? "the classification attribute"
                                   : "the gps_time attribute";
  }
  if (format == Format::ply) return nullptr;
  switch (format == Format::pcd ? pcd_named_field(name) : text_named_field(name)) {
    case NamedField::scalar: return nullptr;
    case NamedField::x:
    case NamedField::y:
    case NamedField::z: return "the positions";
    case NamedField::nx:
    case NamedField::ny:
    case NamedField::nz: return "the normals";
    case NamedField::red:
    case NamedField::green:
    case NamedField::blue:
    case NamedField::packed_rgb: return "the colour";
    case NamedField::intensity: return "the intensity attribute";
    case NamedField::padding: return "PCL's padding, which is skipped";
  }
  return nullptr;
}

}  // namespace rayscan::io
