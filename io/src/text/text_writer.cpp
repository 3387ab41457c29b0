// XYZ / CSV / TXT writer: the column layout the text reader (text_reader.cpp), CloudCompare,
// PDAL's readers.text and LAStools' txt2las read: a header line naming the columns, then one
// point per line. Coordinates that lie on the LAS grid of their source (a LAS point's coordinate
// is the double X * scale + offset, e.g. 849087.7000000001 for scale 0.01) are printed with the
// grid's decimals (849087.70), as las2txt and lasinfo print them: the text a surveyor expects,
// and the LAS writer finds the grid again from the decimals (detail::OnGrid::decimal) and stores
// the same integers. Every other value is the shortest decimal that reads back as the same double
// (std::to_chars), so a round trip keeps it bit for bit. Colour is written as the source held it:
// 16-bit values, or the 8-bit values of a source whose colour the reader scaled by 257
// (PointCloud::rgb_from_8bit_las, as write_las does), which the text reader scales by 257 again.
// A scalar whose name the reader would take for another field (scalar_read_back_as: an extra-bytes
// field "Intensity" beside the intensity column, a scalar "nx") is written with a suffix,
// "Intensity_1", "nx_1", so that the file reads back with no scalar turned into another attribute.
#include "rayscan/io/point_io.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/grid_text.hpp"

#include "atomic_writer.hpp"
#include "field_names.hpp"
#include "las/las_grid.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <set>
#include <string>

namespace rayscan::io {

namespace {

/// How to print the coordinates of `cloud`: per axis, the text of the grid of `grid`
/// (GridText) when it has a scale and offset and every coordinate of the axis lies on that grid
/// exactly (a value straight from the LAS reader); the shortest round-trip form otherwise, e.g.
/// for a scale such as 1/3 or a cloud moved off it.
GridText text_of(const PointCloud& cloud, const LasWriteOptions& grid) {
  if (!grid.has_offset) return {};
  GridText g = GridText::of(grid.scale, grid.offset);
  for (std::size_t k = 0; k < 3; ++k)
    if (g.decimals[k] >= 0)
      for (const Vec3& p : cloud.positions)
        if (!detail::on_las_grid(p[int(k)], grid.scale[int(k)], grid.offset[int(k)], detail::OnGrid::exact)) {
          g.decimals[k] = -1;
          break;
        }
  return g;
}

}  // namespace

void write_text(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& grid) {
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
    h += sep, h += detail::unique_field_name("", s.name, used, detail::scalar_name_reserved<Format::text>);
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
  // Coordinate k of a point: with the grid's decimals when the text reads back onto the same grid
  // integer (beyond about 15 significant digits it might not), else shortest.
  const GridText grid_text = text_of(cloud, grid);
  auto coord = [&](double v, int k) { grid_text.append(line, v, k); };
  const bool colour_8bit = cloud.rgb_from_8bit_las;
  auto colour = [&](std::uint16_t v) -> unsigned { return colour_8bit ? detail::colour_to_8bit(v) : v; };
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    line.clear();
    coord(cloud.positions[i].x, 0);
    line += sep;
    coord(cloud.positions[i].y, 1);
    line += sep;
    coord(cloud.positions[i].z, 2);
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
