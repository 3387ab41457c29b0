// Site::open (the storage chosen from the file) and the queries every consumer of a site needs
// whatever its storage: the auto radius spacing and the surfel estimate (site.hpp).
#include "rayscan/site/site.hpp"

#include "rayscan/base/job.hpp"
#include "rayscan/octree/spacing.hpp"

#include <chrono>
#include <optional>
#include <stdexcept>
#include <vector>

namespace rayscan {

/// The storage an owning Site keeps alive (heap-allocated: the index holds spans into `cloud`).
struct Site::Store {
  PointCloud cloud;  // the points, when the site owns them
  std::optional<AnyIndex> index;
  std::optional<io::MappedIndex> mapped;
  std::unique_ptr<io::CopcIndex> copc;
};

std::size_t Site::size() const {
  switch (storage_) {
    case SiteStorage::index_file: return mapped_->positions().size();
    case SiteStorage::copc: return static_cast<std::size_t>(copc_->info().point_count);
    case SiteStorage::memory: break;
  }
  return std::visit([](const auto& i) -> std::size_t { return i.positions().size(); }, *memory_);
}

Site Site::in_memory_over(std::shared_ptr<Store> store, const PointCloud& cloud, const IndexOptions& index) {
  store->index.emplace(make_index(cloud.positions, index));
  Site s;
  s.storage_ = SiteStorage::memory;
  s.memory_ = &*store->index;
  s.cloud_ = &cloud;
  s.owned_ = std::move(store);
  return s;
}

Site Site::in_memory(PointCloud cloud, const IndexOptions& index) {
  auto store = std::make_shared<Store>();
  store->cloud = std::move(cloud);
  const PointCloud& points = store->cloud;
  return in_memory_over(std::move(store), points, index);
}

Site Site::over(const PointCloud& cloud, const IndexOptions& index) {
  return in_memory_over(std::make_shared<Store>(), cloud, index);
}

Site Site::open(const std::filesystem::path& path, const SiteOptions& options, SiteOpenTimes* times) {
  SiteOpenTimes t;
  auto t0 = std::chrono::steady_clock::now();
  Site s;
  if (io::is_index_file(path)) {
    auto store = std::make_shared<Store>();
    store->mapped.emplace(io::MappedIndex::open(path, options.index_file));
    s.storage_ = SiteStorage::index_file;
    s.mapped_ = &*store->mapped;
    s.owned_ = std::move(store);
    t.read_seconds = seconds_since(t0);
  } else if (options.copc_in_place && io::is_copc_file(path)) {
    auto store = std::make_shared<Store>();
    store->copc = std::make_unique<io::CopcIndex>(path, options.copc_cache_bytes);
    s.storage_ = SiteStorage::copc;
    s.copc_ = store->copc.get();
    s.owned_ = std::move(store);
    t.read_seconds = seconds_since(t0);
  } else {
    PointCloud cloud = io::read_point_cloud(path, options.read);
    t.read_seconds = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    s = in_memory(std::move(cloud), options.index);
    t.index_seconds = seconds_since(t0);
  }
  if (times) *times = t;
  return s;
}

double median_nn_spacing(const Site& site, std::span<const Vec3> positions) {
  switch (site.storage()) {
    case SiteStorage::index_file: return site.index_file()->median_nn_spacing();
    case SiteStorage::copc: {
      const std::vector<Vec3> samples = site.copc()->spacing_samples(kCopcSpacingSamples);
      return median_nn_spacing_of(*site.copc(), std::span<const Vec3>(samples), samples.size());
    }
    case SiteStorage::memory: break;
  }
  return median_nn_spacing(*site.memory_index(), positions);
}

SurfelAttributes estimate_surfels(const Site& site, std::span<const Vec3> positions, const SurfelOptions& options,
                                  std::span<const glm::vec3> file_normals) {
  switch (site.storage()) {
    case SiteStorage::memory:  // the library's instances over AnyIndex (octree/src/query/normals.cpp)
      return estimate_surfels(*site.memory_index(), positions, options, file_normals);
    case SiteStorage::index_file: return estimate_surfels_over(*site.index_file(), positions, options, file_normals);
    case SiteStorage::copc: break;
  }
  throw std::invalid_argument("surfels: a COPC file queried in place is not supported; read it into memory");
}

}  // namespace rayscan
