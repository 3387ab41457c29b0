// The rayscan index file (.rsi): an octree over one or more point cloud files, built out of core
// (external sort by Morton code within a memory budget) and queried through a read-only memory
// map. Format: docs/index-format.md. The mapped index satisfies SpatialIndex, so the ray query
// (paper Algorithm 1), the point queries and the batch API run on it unchanged and return what
// the in-memory Octree::build_bulk over the same points returns, bit for bit.
#pragma once

#include "rayscan/io/point_reader.hpp"
#include "rayscan/octree.hpp"
#include "rayscan/spatial_index.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::io {

/// A malformed, truncated, corrupted or stale index file. what() is one line naming the file, the
/// section or byte offset and what was expected ("site.rsi: section positions (byte 8192):
/// checksum 1a2b3c4d, expected 5e6f7a8b").
struct IndexError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One source file of an index, as it was when the index was built.
struct IndexSource {
  std::string path;           ///< as given to build_index_file (absolute)
  std::uint64_t size = 0;     ///< bytes
  std::int64_t mtime_ns = 0;  ///< modification time, ns since the epoch
  std::uint64_t points = 0;   ///< points read from it; its points have ids [first_id, first_id + points)
  std::uint64_t first_id = 0;
  std::string format;         ///< "LAS 1.2", "PLY 1.0", ...
};

/// Progress of a build: `phase` is "scan", "sort", "merge" or "nodes"; `done` of `total` points.
using IndexProgress = std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)>;

/// Options of build_index_file().
struct IndexBuildOptions {
  /// Tree layout and parameters: adaptive or fixed (layered is not supported by the external
  /// build; std::invalid_argument).
  OctreeConfig config;
  /// Attributes stored besides positions: any of rgb, intensity, classification, gps_time.
  /// Attributes some input lacks are not stored (a note says which).
  AttributeSet attributes = AttributeSet::none();
  /// Memory budget of the sort runs and merge buffers (bytes); peak RSS stays within this plus a
  /// constant (one reader chunk, the node array: 48 bytes per node).
  std::uint64_t memory_bytes = std::uint64_t{4} << 30;
  /// Folder for the sort runs (default: the output's folder). Removed afterwards.
  std::filesystem::path temp_dir;
  IndexProgress progress;  ///< called every few million points (may be empty)
};

/// What a build did.
struct IndexBuildStats {
  std::uint64_t points = 0, nodes = 0, runs = 0, file_bytes = 0;
  unsigned depth = 0;
  AttributeSet attributes;         ///< stored
  std::vector<std::string> notes;  ///< decisions the user should know about
};

/// Builds the index of `inputs` (their points in this order get ids 0, 1, ...) into `output`:
/// pass 1 streams positions for the bounds and checks that the inputs agree on CRS; pass 2
/// streams points, Morton codes (OctreeRules) and sorts runs that fit the memory budget; the runs
/// are merged into the point sections and the nodes are built from the sorted codes exactly as
/// Octree::build_bulk does. Written to a temporary file and renamed (AtomicFile); on any error
/// the temporary and the runs are removed. Throws FormatError (an input), IndexError (inputs
/// disagree: names the file), std::invalid_argument (options), std::runtime_error (I/O, e.g. disk
/// full: names the file and errno text).
IndexBuildStats build_index_file(const std::vector<std::filesystem::path>& inputs,
                                 const std::filesystem::path& output, const IndexBuildOptions& options);

/// Options of MappedIndex::open().
struct IndexOpenOptions {
  /// Verify every section's CRC-32. Auto (default) verifies when the file is at most 256 MiB and
  /// otherwise only the header, node and metadata sections (so opening stays under a second);
  /// `rayscan info --verify` forces it.
  enum class Verify { automatic, always, metadata_only } verify = Verify::automatic;
  /// Fail when a source file still exists but its size or modification time changed.
  bool check_sources = true;
};

/// A read-only memory-mapped index file satisfying SpatialIndex. Node records, positions and ids
/// are used in place (no copy): opening costs the header checks and one pass over the node
/// records validating their ranges (never a read past the mapping afterwards).
class MappedIndex {
 public:
  using Node = std::uint32_t;

  /// Opens and validates `path`. Throws IndexError (one line: file, section/offset, expectation).
  static MappedIndex open(const std::filesystem::path& path, const IndexOpenOptions& options = {});

  // SpatialIndex concept ---------------------------------------------------------------------
  [[nodiscard]] bool empty() const { return points_ == 0; }
  [[nodiscard]] Node root() const { return 0; }
  [[nodiscard]] AABB node_bounds(Node n) const {
    const Octree::NodeRec& r = nodes_[n];
    return {cell_.lo + Vec3(r.lo), cell_.lo + Vec3(r.hi)};
  }
  [[nodiscard]] SlotRange node_points(Node n) const { return {nodes_[n].own_begin, nodes_[n].own_end}; }
  [[nodiscard]] unsigned child_count(Node n) const { return nodes_[n].child_count; }
  [[nodiscard]] Node child(Node n, unsigned i) const { return nodes_[n].first_child + i; }
  [[nodiscard]] std::span<const Vec3> positions() const { return {pos_, points_}; }
  [[nodiscard]] std::span<const PointIndex> ids() const { return {ids_, points_}; }

  // Index file specifics -----------------------------------------------------------------------
  /// The Warren & Salmon id of node n.
  [[nodiscard]] OctreeNodeId node_id(Node n) const { return OctreeNodeId::from_bits(nodes_[n].key); }
  [[nodiscard]] const AABB& root_cell() const { return cell_; }
  [[nodiscard]] std::size_t node_count() const { return node_count_; }
  [[nodiscard]] unsigned depth() const { return depth_; }
  [[nodiscard]] const OctreeConfig& config() const { return config_; }
  /// Points stored per depth (index = depth).
  [[nodiscard]] std::vector<std::uint64_t> points_per_level() const;
  /// Stored attributes, by slot (like positions()); empty spans when not stored.
  [[nodiscard]] std::span<const Rgb16> rgb() const { return rgb_; }
  [[nodiscard]] std::span<const std::uint16_t> intensity() const { return intensity_; }
  [[nodiscard]] std::span<const std::uint8_t> classification() const { return classification_; }
  [[nodiscard]] std::span<const double> gps_time() const { return gps_; }
  [[nodiscard]] AttributeSet attributes() const { return attrs_; }
  [[nodiscard]] const std::vector<IndexSource>& sources() const { return sources_; }
  [[nodiscard]] const std::string& crs_wkt() const { return crs_; }
  [[nodiscard]] std::uint64_t file_bytes() const;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// The stored points and attributes in the sources' original order (ids()), as read_point_cloud
  /// of the concatenated sources would return positions and the stored attributes. Allocates.
  [[nodiscard]] PointCloud to_point_cloud() const;

  MappedIndex(MappedIndex&&) noexcept;
  MappedIndex& operator=(MappedIndex&&) noexcept;
  MappedIndex(const MappedIndex&) = delete;
  MappedIndex& operator=(const MappedIndex&) = delete;
  ~MappedIndex();

 private:
  MappedIndex() = default;
  struct Map;
  std::unique_ptr<Map> map_;
  std::filesystem::path path_;
  OctreeConfig config_;
  AABB cell_;
  unsigned depth_ = 0;
  std::size_t points_ = 0, node_count_ = 0;
  const Octree::NodeRec* nodes_ = nullptr;
  const Vec3* pos_ = nullptr;
  const PointIndex* ids_ = nullptr;
  std::span<const Rgb16> rgb_;
  std::span<const std::uint16_t> intensity_;
  std::span<const std::uint8_t> classification_;
  std::span<const double> gps_;
  AttributeSet attrs_ = AttributeSet::none();
  std::vector<IndexSource> sources_;
  std::string crs_;
};

static_assert(SpatialIndex<MappedIndex>);

/// Parses a byte size "4G", "512M", "1.5G", "65536" (K/M/G/T binary multiples, optional "B" or
/// "iB"). Throws std::invalid_argument naming the text for anything else.
std::uint64_t parse_byte_size(const std::string& text);

/// True when `path` names an index file (extension .rsi, case-insensitive).
bool is_index_file(const std::filesystem::path& path);

}  // namespace rayscan::io
