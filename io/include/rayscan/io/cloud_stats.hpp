// Streaming summary of a point cloud file: what `rayscan info` prints, computed chunk by chunk
// over a PointReader so memory stays bounded (PDAL `pdal info --stats` in streaming mode).
#pragma once

#include "rayscan/io/point_reader.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <cmath>
#include <vector>

namespace rayscan::io {

/// Statistics of one attribute over all points (X, Y, Z in world units): minimum, maximum, mean
/// and standard deviation (population: divided by the count), as `pdal info --stats` reports.
struct AttributeRange {
  std::string name;  ///< "X", "Y", "Z", "intensity", "red", "normal_x", a scalar's name
  double lo = 0, hi = 0;
  std::uint64_t count = 0;  ///< values summarised
  double mean = 0;          ///< arithmetic mean
  double m2 = 0;            ///< sum of squared deviations from the mean (Chan et al. 1979 merge)
  /// Population standard deviation sqrt(m2 / count); 0 for no values.
  [[nodiscard]] double stddev() const { return count ? std::sqrt(m2 / double(count)) : 0.0; }
};

/// Whole-file statistics gathered in one streaming pass.
struct CloudStats {
  std::uint64_t count = 0;                             ///< points delivered by the reader
  AABB bounds;                                         ///< recomputed from positions (empty if none)
  std::vector<AttributeRange> ranges;                  ///< X, Y, Z, then each attribute present
  std::map<int, std::uint64_t> classification_counts;  ///< class code -> points
};

/// Reads `reader` to its end in chunks of `chunk_points` and returns the statistics. Memory: one
/// chunk. Throws FormatError from the reader.
CloudStats scan_point_cloud(PointReader& reader, std::size_t chunk_points = kDefaultChunkPoints);

/// A header's bounding box on the file's integer grid (LAS/LAZ/COPC: coordinate = X * scale +
/// offset, ASPRS LAS 1.4 R15 section 2.4): each bound rounded to the nearest grid step and decoded
/// by las_coordinate, the readers' own expression. A header right to within half a step (a writer
/// that stored min/max as decimal text, or computed them in another order) gives exactly the box of
/// the points the readers deliver; a bound off the int32 grid, or not finite, is kept as stored.
[[nodiscard]] AABB header_box_on_grid(const AABB& header, const Vec3& scale, const Vec3& offset);

/// Whether a file's header bounding box misstates `points` (the box of its points as read): the
/// header box on the file's grid (header_box_on_grid, when the file has a scale and offset)
/// differs from `points`, exactly. False when the header states no box or there are no points.
/// The one rule of `rayscan info`'s "differs" and of the index build's trust in LAS headers.
[[nodiscard]] bool header_bounds_differ(const FileInfo& info, const AABB& points);

}  // namespace rayscan::io
