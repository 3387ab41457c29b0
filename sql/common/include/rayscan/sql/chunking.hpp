// Morton-ordered chunks of a point cloud: the storage layout of `rayscan db import` in both SQLite
// and PostgreSQL (paper section 4.2: chunks with min/max statistics that the bounds evaluation of
// dist_ray / dist_plane prunes).
#pragma once

#include "rayscan/octree/geometry.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <bit>
#include <cstdint>
#include <span>
#include <vector>

namespace rayscan::sql {

/// One point of the imported site: which source file it comes from and its index there.
struct PointRef {
  std::uint32_t source;  ///< 0-based position of the file on the import command line
  std::uint64_t index;   ///< the point's index in that file (the `point_index` column)
};

/// A chunk: a run of consecutive rows [first, first + count) in Morton order and their exact
/// double-precision bounding box (engines that store boxes in float must round outwards).
struct Chunk {
  std::uint64_t first = 0;  ///< first row (0-based) in `order`
  std::uint32_t count = 0;  ///< number of rows
  AABB box;                 ///< exact bounds of the chunk's positions
};

/// The import layout: every point of every cloud sorted by the Morton code of its cell in a
/// 2^21-per-axis grid over the union bounds (ties: source, then index), cut into chunks of
/// `chunk_size` consecutive points (the last may be shorter).
struct ChunkLayout {
  std::vector<PointRef> order;
  std::vector<Chunk> chunks;
};

/// One point of a chunk's packed BLOB (SQLite `chunk_points.data`: `count` of these, 40 bytes each,
/// little-endian, no padding): the exact double position, the point's index in its source file
/// and the source's position on the import command line. Read with memcpy (a BLOB need not be
/// 8-byte aligned). The `rayscan_meta` key "chunk_points" names this layout.
struct PackedPoint {
  double x, y, z;            ///< world coordinates as the reader produced them
  std::int64_t point_index;  ///< the `point_index` column
  std::int64_t source;       ///< the `source` column
};
static_assert(sizeof(PackedPoint) == 40, "PackedPoint must have no padding");
static_assert(std::endian::native == std::endian::little, "chunk_points BLOBs are little-endian");
/// Value of rayscan_meta "chunk_points" for the PackedPoint layout.
inline constexpr const char* kChunkPointsLayout = "x,y,z f64le; point_index,source i64le (40 bytes)";

/// Builds the layout for `clouds` (all in one world frame). Throws std::invalid_argument when
/// chunk_size is 0. Memory: 24 bytes per point besides the clouds.
/// Used only when the clouds are read whole (open_site in rayscan/sql/site_stream.hpp: scalar
/// fields an index file does not store); otherwise the import streams through an index file.
[[nodiscard]] ChunkLayout make_chunk_layout(std::span<const PointCloud* const> clouds,
                                            std::uint32_t chunk_size);

}  // namespace rayscan::sql
