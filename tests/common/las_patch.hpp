// Test helpers for LAS-family files whose header is patched after they are written: a cloud on
// the unit grid, its X scale factor set in place, and the LAS reader's refusal of the result.
#pragma once

#include "rayscan/io/point_io.hpp"

#include <bit>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace rayscan::test {

/// Writes `cloud` as LAS at `path` on the unit grid (scale 1 and offset 0 on every axis): each
/// stored integer is the coordinate itself, so a patched scale multiplies it exactly.
inline void write_unit_grid_las(const std::filesystem::path& path, const PointCloud& cloud) {
  io::LasWriteOptions grid;
  grid.scale = Vec3(1.0);
  grid.offset = Vec3(0.0);
  grid.has_offset = true;
  io::write_las(path, cloud, grid);
}

/// Sets the X scale factor of the LAS, LAZ or COPC file `path` to `scale` in place (header byte
/// 131, a little-endian double: ASPRS LAS 1.4 R15 table 3; outside any compressed chunk) and
/// returns the value it replaced. Throws std::runtime_error when the bytes cannot be read or
/// written there.
inline double patch_las_x_scale(const std::filesystem::path& path, double scale) {
  static_assert(std::endian::native == std::endian::little, "the header's doubles are stored little-endian");
  constexpr std::streamoff kXScaleAt = 131;
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  double old = 0;
  if (!f.seekg(kXScaleAt) || !f.read(reinterpret_cast<char*>(&old), sizeof old))
    throw std::runtime_error(path.string() + ": cannot read the X scale factor at byte 131");
  if (!f.seekp(kXScaleAt) || !f.write(reinterpret_cast<const char*>(&scale), sizeof scale) || !f.flush())
    throw std::runtime_error(path.string() + ": cannot write the X scale factor at byte 131");
  return old;
}

/// The FormatError text with which io::read_point_cloud refuses `path`; "" when it reads it.
inline std::string reader_error(const std::filesystem::path& path) {
  try {
    (void)io::read_point_cloud(path);
  } catch (const io::FormatError& e) {
    return e.what();
  }
  return {};
}

}  // namespace rayscan::test
