// PCD v0.7 writer (Point Cloud Library, "The PCD (Point Cloud Data) file format",
// pointclouds.org/documentation/tutorials/pcd_file_format.html): an unorganised cloud (HEIGHT 1),
// DATA binary (the array-of-structs layout: one record of every field per point, little-endian).
// A scalar whose name the reader would take for another field (scalar_read_back_as: "nx",
// "red", "intensity") is written with a suffix, "nx_1", so that the file reads back with no
// scalar turned into another attribute.
#include "rayscan/io/point_io.hpp"

#include "atomic_writer.hpp"
#include "field_names.hpp"
#include "rayscan/base/number_text.hpp"

#include <array>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace rayscan::io {

namespace {

/// One FIELDS entry: its name, SIZE and TYPE (COUNT is always 1).
struct PcdOut {
  std::string name;
  int size;
  char type;
};

}  // namespace

void write_pcd(const std::filesystem::path& path, const PointCloud& cloud,
               const std::map<std::string, ExtraBytesInfo>& descriptions) {
  detail::validate_for_writing(path, cloud);
  const std::size_t n = cloud.size();
  std::set<std::string> used = {"x", "y", "z"};
  // Positions as float (F 4, what PCL's point types and Open3D's legacy reader take) when every
  // coordinate is a float exactly (a depth camera's cloud), else as double (F 8: a float holds a
  // UTM northing only to half a metre; PCL's PCLPointCloud2 and Open3D's tensor reader read it).
  bool as_float = true;
  for (std::size_t i = 0; i < n && as_float; ++i)
    for (int k = 0; k < 3; ++k) as_float = as_float && double(float(cloud.positions[i][k])) == cloud.positions[i][k];
  const int ps = as_float ? 4 : 8;
  std::vector<PcdOut> f = {{"x", ps, 'F'}, {"y", ps, 'F'}, {"z", ps, 'F'}};
  if (!cloud.normals.empty()) {
    f.insert(f.end(), {{"normal_x", 4, 'F'}, {"normal_y", 4, 'F'}, {"normal_z", 4, 'F'}});
    used.insert({"normal_x", "normal_y", "normal_z"});
  }
  // PCL's packed colour: the bits 0x00RRGGBB of a float field named rgb (8 bit per channel).
  if (!cloud.rgb.empty()) f.push_back({"rgb", 4, 'F'}), used.insert("rgb");
  if (!cloud.intensity.empty()) f.push_back({detail::unique_field_name("", "intensity", used), 4, 'F'});
  if (!cloud.classification.empty()) f.push_back({detail::unique_field_name("", "classification", used), 1, 'U'});
  if (!cloud.gps_time.empty()) f.push_back({detail::unique_field_name("", "gps_time", used), 8, 'F'});
  // What a field is and its unit, as '#' comment lines (PCD has no field for a unit; PCL's and
  // Open3D's header parsers skip any line whose first word starts with '#').
  std::string comments;
  for (const ScalarField& s : cloud.scalars) {
    f.push_back({detail::unique_field_name("", s.name, used, detail::scalar_name_reserved<Format::pcd>), 8, 'F'});
    if (const auto it = descriptions.find(s.name); it != descriptions.end())
      if (const std::string c = detail::field_comment(f.back().name, it->second); !c.empty())
        comments += "# ", comments += c, comments += '\n';
  }

  // Built by appending (`" " + std::to_string(...)` sets off GCC 12's -Wrestrict false positive
  // at -O3 when this file is compiled alone).
  std::string h = "# .PCD v0.7 - Point Cloud Data file format\n";
  h += comments;
  h += "VERSION 0.7\nFIELDS";
  for (const PcdOut& o : f) h += ' ', h += o.name;
  h += "\nSIZE";
  for (const PcdOut& o : f) h += ' ', h += std::to_string(o.size);
  h += "\nTYPE";
  for (const PcdOut& o : f) h += ' ', h += o.type;
  h += "\nCOUNT";
  for (std::size_t k = 0; k < f.size(); ++k) h += " 1";
  h += "\nWIDTH ", h += std::to_string(n);
  h += "\nHEIGHT 1\nVIEWPOINT";
  // The source's pose as it was read (shortest decimals, which read back bit for bit), else PCL's
  // default, the identity.
  for (const double v : cloud.viewpoint.value_or(std::array<double, 7>{0, 0, 0, 1, 0, 0, 0}))
    h += ' ', h += shortest_text(v);
  h += "\nPOINTS ", h += std::to_string(n);
  h += "\nDATA binary\n";

  detail::AtomicWriter w(path);
  w.write(h.data(), h.size());
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      if (as_float)
        w.put(static_cast<float>(cloud.positions[i][k]));
      else
        w.put(cloud.positions[i][k]);
    }
    if (!cloud.normals.empty()) {
      w.put(cloud.normals[i].x);
      w.put(cloud.normals[i].y);
      w.put(cloud.normals[i].z);
    }
    if (!cloud.rgb.empty()) {
      const std::uint32_t packed = (std::uint32_t(detail::colour_to_8bit(cloud.rgb[i].r)) << 16) |
                                   (std::uint32_t(detail::colour_to_8bit(cloud.rgb[i].g)) << 8) |
                                   std::uint32_t(detail::colour_to_8bit(cloud.rgb[i].b));
      w.put(packed);  // the float's bits, written as the 4 bytes they are
    }
    if (!cloud.intensity.empty()) w.put(static_cast<float>(cloud.intensity[i]));  // exact: < 2^24
    if (!cloud.classification.empty()) w.put(cloud.classification[i]);
    if (!cloud.gps_time.empty()) w.put(cloud.gps_time[i]);
    for (const ScalarField& s : cloud.scalars) w.put(s.values[i]);
  }
  w.commit();
}

}  // namespace rayscan::io
