// The raw point cloud that every index is built over and every reader fills.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rayscan {

/// 16-bit RGB colour of a point, 0..65535 per channel (LAS convention, ASPRS LAS 1.4 R15
/// section 2.6 "Red/Green/Blue"). Readers normalise 8-bit sources to this range.
struct Rgb16 {
  std::uint16_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb16&, const Rgb16&) = default;
};

/// A named per-point scalar attribute that has no dedicated field (LAS extra bytes, PLY/PCD
/// properties such as "confidence" or "sid", a visibility count written by `rayscan visibility`).
struct ScalarField {
  std::string name;            ///< field name as in the source file
  std::vector<double> values;  ///< one value per point (same length as positions)
};

/// Axis-aligned bounding box of `points` (world coordinates); empty (AABB{}) when there is none.
AABB bounds_of(std::span<const Vec3> points);

/// A raw point cloud: positions in double-precision world coordinates plus optional per-point
/// attributes. An attribute vector is either empty (absent) or has exactly size() entries.
///
/// Precision choice: positions are stored and queried as double, in the
/// file's own world frame, so UTM / State Plane coordinates (1e6..1e7) keep sub-millimetre
/// resolution and every index answers exactly like the double-precision brute-force oracle.
struct PointCloud {
  std::vector<Vec3> positions;               ///< x, y, z in world units (the CRS's units)
  std::vector<Rgb16> rgb;                    ///< optional colour, 16 bit per channel
  std::vector<std::uint16_t> intensity;      ///< optional return intensity (LAS: raw 16-bit)
  std::vector<std::uint8_t> classification;  ///< optional ASPRS class code (0..255)
  std::vector<double> gps_time;              ///< optional GPS time (seconds, as in the file)
  std::vector<glm::vec3> normals;            ///< optional unit normals (PLY nx ny nz, PCD normal_*)
  std::vector<ScalarField> scalars;          ///< further named scalar attributes
  std::string crs_wkt;                       ///< coordinate reference system as WKT, "" if unknown
  /// True when the LAS reader found 8-bit values (all <= 255) in the 16-bit colour fields and
  /// scaled them by 257 (docs/formats.md); io::write_las divides by 257 again, so a LAS file
  /// derived from such a source keeps its colour values unchanged.
  bool rgb_from_8bit_las = false;
  /// A PCD source's VIEWPOINT tx ty tz qw qx qy qz (PCD v0.7: the acquisition pose, translation
  /// in the positions' units and frame, then a unit quaternion), as read; never applied to the
  /// positions. Kept with the cloud like crs_wkt so that io::write_pcd writes it back (PCD -> PCD
  /// keeps the sensor pose); the other writers have no place for it. None for other sources.
  std::optional<std::array<double, 7>> viewpoint;

  /// Number of points.
  [[nodiscard]] std::size_t size() const { return positions.size(); }
  /// True when the cloud holds no point.
  [[nodiscard]] bool empty() const { return positions.empty(); }
  /// Bounding box recomputed from the positions (never a header's stored box), bounds_of(positions).
  /// Empty for an empty cloud.
  [[nodiscard]] AABB bounds() const;
  /// Pointer to the scalar field called `name`, or nullptr.
  [[nodiscard]] const ScalarField* scalar(const std::string& name) const;
  /// Throws std::invalid_argument when an attribute vector is neither empty nor size() long, or a
  /// position is not finite (naming the first bad point's index).
  void validate() const;
};

}  // namespace rayscan
