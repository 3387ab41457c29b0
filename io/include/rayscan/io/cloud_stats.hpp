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

}  // namespace rayscan::io
