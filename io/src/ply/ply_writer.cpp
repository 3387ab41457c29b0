// PLY 1.0 writer, binary_little_endian (PLY format description, G. Turk 1994): one "vertex"
// element with double positions so UTM-sized coordinates survive, read by CloudCompare, PDAL,
// MeshLab and Open3D.
#include "rayscan/io/point_io.hpp"

#include "rayscan/base/version.hpp"

#include "atomic_writer.hpp"
#include "field_names.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <string_view>

namespace rayscan::io {

namespace {
/// "scalar_<name>" (docs/formats.md "PLY property names"): CloudCompare loads extra properties
/// only under this prefix (and shows them without it); Open3D takes any name.
std::string property_name(const std::string& name, std::set<std::string>& used) {
  return detail::unique_field_name("scalar_", name, used);
}

/// True when the reader would not give the property `written` (prefixed "scalar_") back as the
/// scalar of its name: the reader strips the prefix, then takes another spelling of a dedicated
/// field for it (scalar_read_back_as: "scalar_gpstime" reads as the gps_time attribute).
bool reserved_property(std::string_view written) {
  if (written.rfind("scalar_", 0) == 0) written.remove_prefix(7);
  return detail::scalar_name_reserved<Format::ply>(written);
}

/// The property of the cloud's own scalar `name`: property_name, with a suffix where the reader
/// would take it for a dedicated field (scalar_gpstime_1, as the PCD and text writers write
/// gpstime_1), so that it reads back as a scalar.
std::string scalar_property_name(const std::string& name, std::set<std::string>& used) {
  return detail::unique_field_name("scalar_", name, used, reserved_property);
}
}  // namespace

void write_ply(const std::filesystem::path& path, const PointCloud& cloud,
               const std::map<std::string, ExtraBytesInfo>& descriptions) {
  detail::validate_for_writing(path, cloud);
  const std::size_t n = cloud.size();
  std::set<std::string> used = {"x", "y", "z"};
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment written by " + software_name() + "\n";
  if (!cloud.crs_wkt.empty()) {
    std::string one_line = cloud.crs_wkt;
    std::replace(one_line.begin(), one_line.end(), '\n', ' ');
    std::replace(one_line.begin(), one_line.end(), '\r', ' ');
    h += "comment crs " + one_line + "\n";
  }
  std::string props = "property double x\nproperty double y\nproperty double z\n";
  if (!cloud.normals.empty())
    props += "property float nx\nproperty float ny\nproperty float nz\n", used.insert({"nx", "ny", "nz"});
  if (!cloud.rgb.empty())
    props += "property uchar red\nproperty uchar green\nproperty uchar blue\n", used.insert({"red", "green", "blue"});
  // Types both CloudCompare and Open3D (0.16: uchar, float, double; not ushort) load.
  if (!cloud.intensity.empty()) props += "property float " + property_name("intensity", used) + "\n";
  if (!cloud.classification.empty()) props += "property uchar " + property_name("classification", used) + "\n";
  if (!cloud.gps_time.empty()) props += "property double " + property_name("gps_time", used) + "\n";
  for (const ScalarField& f : cloud.scalars) {
    const std::string name = scalar_property_name(f.name, used);
    props += "property double " + name + "\n";
    // A comment, not a property: PLY has no field for a unit, and readers skip comments.
    if (const auto it = descriptions.find(f.name); it != descriptions.end())
      if (const std::string c = detail::field_comment(name, it->second); !c.empty()) h += "comment " + c + "\n";
  }
  h += "element vertex " + std::to_string(n) + "\n" + props + "end_header\n";

  detail::AtomicWriter w(path);
  w.write(h.data(), h.size());
  auto to8 = [](std::uint16_t v) { return detail::colour_to_8bit(v); };
  for (std::size_t i = 0; i < n; ++i) {
    w.put(cloud.positions[i].x);
    w.put(cloud.positions[i].y);
    w.put(cloud.positions[i].z);
    if (!cloud.normals.empty()) {
      w.put(cloud.normals[i].x);
      w.put(cloud.normals[i].y);
      w.put(cloud.normals[i].z);
    }
    if (!cloud.rgb.empty()) {
      w.put(to8(cloud.rgb[i].r));
      w.put(to8(cloud.rgb[i].g));
      w.put(to8(cloud.rgb[i].b));
    }
    if (!cloud.intensity.empty()) w.put(static_cast<float>(cloud.intensity[i]));  // exact: < 2^24
    if (!cloud.classification.empty()) w.put(cloud.classification[i]);
    if (!cloud.gps_time.empty()) w.put(cloud.gps_time[i]);
    for (const ScalarField& f : cloud.scalars) w.put(f.values[i]);
  }
  w.commit();
}

}  // namespace rayscan::io
