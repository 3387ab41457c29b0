// XYZ / CSV / TXT writer: the column layout the text reader (text_reader.cpp), CloudCompare,
// PDAL's readers.text and LAStools' txt2las read: a header line naming the columns, then one
// point per line. Values are the shortest decimal that reads back as the same double
// (std::to_chars), so a round trip keeps every coordinate bit for bit: a LAS point's coordinate is
// the double X * scale + offset, which for scale 0.01 can be 849087.7000000001, not the double
// nearest 849087.70 (rounding it to the scale's decimals would read back as another double, and the
// LAS writer finds a source's grid only from the exact doubles). Colour is written as the
// source held it: 16-bit values, or the 8-bit values of a source whose colour the reader scaled by
// 257 (PointCloud::rgb_from_8bit_las, as write_las does), which the text reader scales by 257 again.
// A scalar whose name the reader would take for another field (text_name_reserved: an extra-bytes
// field "Intensity" beside the intensity column) is written with a suffix, "Intensity_1".
#include "rayscan/io/point_io.hpp"

#include "rayscan/base/file_names.hpp"

#include "atomic_writer.hpp"
#include "field_names.hpp"
#include "text_columns.hpp"

#include <charconv>
#include <set>
#include <string>

namespace rayscan::io {

void write_text(const std::filesystem::path& path, const PointCloud& cloud) {
  detail::validate_for_writing(path, cloud);
  const char sep = lower_extension(path) == ".csv" ? ',' : ' ';
  std::set<std::string> used = {"x", "y", "z"};
  std::string h = "x";
  h += sep, h += "y", h += sep, h += "z";
  auto col = [&](const std::string& name) { h += sep, h += detail::unique_field_name("", name, used); };
  if (!cloud.rgb.empty()) col("red"), col("green"), col("blue");
  if (!cloud.normals.empty()) col("nx"), col("ny"), col("nz");
  if (!cloud.intensity.empty()) col("intensity");
  if (!cloud.classification.empty()) col("classification");
  if (!cloud.gps_time.empty()) col("gps_time");
  for (const ScalarField& s : cloud.scalars)
    h += sep, h += detail::unique_field_name("", s.name, used, detail::text_name_reserved);
  h += '\n';

  detail::AtomicWriter w(path);
  w.write(h.data(), h.size());
  std::string line;
  char buf[32];
  auto num = [&](double v) {
    const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
    line.append(buf, r.ptr);
  };
  auto next = [&](double v) {
    line += sep;
    num(v);
  };
  const bool colour_8bit = cloud.rgb_from_8bit_las;
  auto colour = [&](std::uint16_t v) -> unsigned { return colour_8bit ? detail::colour_to_8bit(v) : v; };
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    line.clear();
    num(cloud.positions[i].x);
    next(cloud.positions[i].y);
    next(cloud.positions[i].z);
    if (!cloud.rgb.empty()) next(colour(cloud.rgb[i].r)), next(colour(cloud.rgb[i].g)), next(colour(cloud.rgb[i].b));
    if (!cloud.normals.empty()) next(cloud.normals[i].x), next(cloud.normals[i].y), next(cloud.normals[i].z);
    if (!cloud.intensity.empty()) next(cloud.intensity[i]);
    if (!cloud.classification.empty()) next(cloud.classification[i]);
    if (!cloud.gps_time.empty()) next(cloud.gps_time[i]);
    for (const ScalarField& s : cloud.scalars) next(s.values[i]);
    line += '\n';
    w.write(line.data(), line.size());
  }
  w.commit();
}

}  // namespace rayscan::io
