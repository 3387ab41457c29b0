// A scanned site opened for ray and point queries, whatever its storage: one handle over the
// in-memory index (AnyIndex over a PointCloud), the memory-mapped index file (.rsi,
// docs/index-format.md) and the COPC file's own octree (copc.io 1.0). Every consumer (renderer,
// analysis, jobs, Python, MPI) takes a Site and calls visit() once; the concrete index type is
// then a template parameter of the consumer's own code, so the hot loops see no virtual call.
#pragma once

#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"

#include <cstddef>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

namespace rayscan {

/// Where a site's points and its spatial index live.
enum class SiteStorage {
  memory,      ///< an AnyIndex built over a PointCloud in memory
  index_file,  ///< a memory-mapped .rsi index file, queried in place
  copc         ///< a COPC file's own octree, nodes decoded as queries reach them
};

/// How Site::open reads a file.
struct SiteOptions {
  /// The index built over a point file read into memory (LAS, LAZ, PLY, PCD, text, and COPC
  /// when copc_in_place is false).
  IndexOptions index;
  /// The attributes read from a point file (all by default).
  io::ReadOptions read;
  /// How an index file (.rsi) is opened and checked.
  io::IndexOpenOptions index_file;
  /// COPC files: query the file's own hierarchy in place (true) or read every point into memory
  /// and build `index` over them (false).
  bool copc_in_place = true;
  /// COPC in place: the decoded-node cache budget, bytes (CopcIndex).
  std::size_t copc_cache_bytes = io::kCopcDefaultCacheBytes;
};

/// Seconds Site::open spent, for the caller's log.
struct SiteOpenTimes {
  double read_seconds = 0.0;   ///< reading the points, mapping the index file or the COPC hierarchy
  double index_seconds = 0.0;  ///< building the in-memory index (0 for the other storages)
};

/// A scanned site: the points and the spatial index that answers queries over them.
///
/// A Site either owns its storage (Site::open, Site::in_memory) or refers to an index the caller
/// keeps alive (the converting constructors, so that code holding an AnyIndex, a MappedIndex or a
/// CopcIndex passes it where a Site is expected). Copies share the storage. Query answers do not
/// depend on the storage: the index file and COPC models of SpatialIndex return what the
/// in-memory octree over the same points returns (docs/index-format.md, docs/library.md).
class Site {
 public:
  /// Refers to `index` (not owned; it must outlive the Site and its copies).
  Site(const AnyIndex& index) : storage_(SiteStorage::memory), memory_(&index) {}  // NOLINT: implicit by design
  /// Refers to the mapped index file `index` (not owned).
  Site(const io::MappedIndex& index) : storage_(SiteStorage::index_file), mapped_(&index) {}  // NOLINT
  /// Refers to the COPC file `index` (not owned). Queries decode nodes into its cache, hence the
  /// non-const reference.
  Site(io::CopcIndex& index) : storage_(SiteStorage::copc), copc_(&index) {}  // NOLINT

  /// Opens `path`, choosing the storage from the file: `.rsi` maps the index file, a LAS/LAZ file
  /// with the COPC info VLR opens its hierarchy (options.copc_in_place), any other point file is
  /// read (options.read) and indexed in memory (options.index). `times`, when given, receives the
  /// seconds spent. Throws io::IndexError, io::PointFileError (or the reader's error) for a bad
  /// file, std::invalid_argument for bad index options.
  static Site open(const std::filesystem::path& path, const SiteOptions& options = {},
                   SiteOpenTimes* times = nullptr);

  /// True when open(path, options) would query the file in place without reading its points: an
  /// index file (io::is_index_file, by its name) or, with options.copc_in_place, a COPC file
  /// (io::is_copc_file, by its header). Reads only the header; false for any other or unreadable
  /// file (open then reads it, or throws for it).
  static bool opens_in_place(const std::filesystem::path& path, const SiteOptions& options = {});

  /// A site over `cloud` (moved in, owned) with the index `index` built over its positions.
  /// Throws std::invalid_argument for bad index options.
  static Site in_memory(PointCloud cloud, const IndexOptions& index = {});

  /// A site over `cloud` (not owned: it must outlive the Site and its copies) with the index
  /// `index` built over its positions. Throws std::invalid_argument for bad index options.
  static Site over(const PointCloud& cloud, const IndexOptions& index = {});

  /// Which storage answers the queries.
  [[nodiscard]] SiteStorage storage() const { return storage_; }

  /// Number of points.
  [[nodiscard]] std::size_t size() const;
  [[nodiscard]] bool empty() const { return size() == 0; }

  /// The points in memory, in original order (Site::open of a point file, Site::in_memory,
  /// Site::over; nullptr for an index file, a COPC file in place, or a Site that refers to an
  /// index).
  [[nodiscard]] const PointCloud* cloud() const { return cloud_; }

  /// The concrete storage, or nullptr when the site is stored otherwise.
  [[nodiscard]] const AnyIndex* memory_index() const { return memory_; }
  [[nodiscard]] const io::MappedIndex* index_file() const { return mapped_; }
  [[nodiscard]] io::CopcIndex* copc() const { return copc_; }

  /// Calls f(index) with the concrete index: the alternative the in-memory AnyIndex holds (`const
  /// Octree&`, `const KdTree&`, `const BruteForceIndex&`), `const io::MappedIndex&` or
  /// `io::CopcIndex&`, and returns what f returns (every branch must return the same type).
  /// The one place a consumer dispatches on the storage: f is usually a generic lambda calling
  /// the consumer's template over the index type.
  template <class F>
  decltype(auto) visit(F&& f) const {
    switch (storage_) {
      case SiteStorage::index_file: return std::forward<F>(f)(*mapped_);
      case SiteStorage::copc: return std::forward<F>(f)(*copc_);
      case SiteStorage::memory: break;
    }
    return std::visit(std::forward<F>(f), *memory_);
  }

 private:
  struct Store;  // the storage of an owning Site (site.cpp)
  Site() = default;
  /// An in-memory site over `cloud` with `index` built over its positions into `store`, which the
  /// site keeps alive (and with it `cloud` when the store holds it).
  static Site in_memory_over(std::shared_ptr<Store> store, const PointCloud& cloud, const IndexOptions& index);
  SiteStorage storage_ = SiteStorage::memory;
  const AnyIndex* memory_ = nullptr;
  const io::MappedIndex* mapped_ = nullptr;
  io::CopcIndex* copc_ = nullptr;
  const PointCloud* cloud_ = nullptr;
  std::shared_ptr<void> owned_;  // the storage of an owning Site (shared by copies)
};

/// True when I (cv/ref-qualified or not) is io::CopcIndex: for the branch of a generic visit()
/// callback that a COPC file in place needs, e.g. `if constexpr (is_copc_index<decltype(index)>)`.
template <class I>
inline constexpr bool is_copc_index = std::is_same_v<std::remove_cvref_t<I>, io::CopcIndex>;

/// Points the auto radius samples on a COPC file in place: a kNN query on the COPC hierarchy tests
/// every point of the ancestor nodes (tens of thousands each), so a sample costs more than in
/// memory (median_nn_spacing's default of 20000).
inline constexpr std::size_t kCopcSpacingSamples = 2000;

/// The median nearest-neighbour spacing of the site's points, world units (the auto radius of
/// paper section 5.3; octree/spacing.hpp): in memory median_nn_spacing(index, positions), with
/// `positions` the site's points in original order; for an index file the spacing stored at build
/// (MappedIndex::median_nn_spacing; `positions` unused). For a COPC file in place given its
/// `positions` (all of them, in file order: read_point_cloud()) median_nn_spacing_of at the same
/// evenly spaced samples, their kNN answered by the file's hierarchy 1024 at a time with
/// CopcIndex::trim_cache() between batches (so no other query may run on it meanwhile), so the
/// value is the whole-file path's bit for bit; given no positions (a caller that does not read
/// the file), median_nn_spacing_of over kCopcSpacingSamples points of at most 64 nodes
/// (CopcIndex::spacing_samples). 0 when no two points differ.
[[nodiscard]] double median_nn_spacing(const Site& site, std::span<const Vec3> positions);

/// The order in which work over every point of a COPC file in place visits them (the analyses'
/// per-point loops, estimate_surfels): the original ids 0..N-1 of `positions`, sorted by the
/// Morton code of each position in the octree's root cell over their bounding box
/// (OctreeRules::Quantizer, sorted by sort_morton_keys: ties by id). The file
/// order would not do: a COPC node holds a subsample of its whole cube (the root's points are
/// spread over the site), so a block of consecutive file-order points would reach every node and
/// a cache smaller than the file would decode the same nodes over and over; in Morton order a
/// block's points are neighbours, as the slots of the other storages are. Results never depend
/// on it. O(N log N), parallel (TBB).
[[nodiscard]] std::vector<PointIndex> copc_point_order(std::span<const Vec3> positions);

/// Surfel normals and radii (estimate_surfels, octree/normals.hpp) of the site's points
/// `positions` in original order, oriented `file_normals` instead of PCA when given (N, or none):
/// the same attributes for the same points in memory, in an index file (estimate_surfels_over)
/// or in a COPC file in place (`positions`: every point in file order, read_point_cloud(); the
/// kNN answered by its hierarchy, blocks of 1024 points each in a CopcIndex::QueryScope). Throws
/// std::invalid_argument as estimate_surfels does, and for a COPC file in place with
/// options.measure_thickness (its patches are runs of storage slots, which a COPC file in place
/// does not hold: read it into memory, SiteOptions::copc_in_place = false).
[[nodiscard]] SurfelAttributes estimate_surfels(const Site& site, std::span<const Vec3> positions,
                                                const SurfelOptions& options,
                                                std::span<const glm::vec3> file_normals = {});

}  // namespace rayscan
