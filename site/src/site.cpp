// Site::open: the storage chosen from the file (site.hpp).
#include "rayscan/site/site.hpp"

#include <chrono>
#include <optional>

namespace rayscan {

namespace {

/// The storage an owning Site keeps alive (heap-allocated: the index holds spans into `cloud`).
struct SiteStore {
  PointCloud cloud;
  std::optional<AnyIndex> index;
  std::optional<io::MappedIndex> mapped;
  std::unique_ptr<io::CopcIndex> copc;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::size_t Site::size() const {
  switch (storage_) {
    case SiteStorage::index_file: return mapped_->positions().size();
    case SiteStorage::copc: return static_cast<std::size_t>(copc_->info().point_count);
    case SiteStorage::memory: break;
  }
  return std::visit([](const auto& i) -> std::size_t { return i.positions().size(); }, *memory_);
}

Site Site::in_memory(PointCloud cloud, const IndexOptions& index) {
  auto store = std::make_shared<SiteStore>();
  store->cloud = std::move(cloud);
  store->index.emplace(make_index(store->cloud.positions, index));
  Site s;
  s.storage_ = SiteStorage::memory;
  s.memory_ = &*store->index;
  s.cloud_ = &store->cloud;
  s.owned_ = std::move(store);
  return s;
}

Site Site::over(const PointCloud& cloud, const IndexOptions& index) {
  auto store = std::make_shared<SiteStore>();
  store->index.emplace(make_index(cloud.positions, index));
  Site s;
  s.storage_ = SiteStorage::memory;
  s.memory_ = &*store->index;
  s.cloud_ = &cloud;
  s.owned_ = std::move(store);
  return s;
}

Site Site::open(const std::filesystem::path& path, const SiteOptions& options, SiteOpenTimes* times) {
  SiteOpenTimes t;
  auto t0 = std::chrono::steady_clock::now();
  Site s;
  if (io::is_index_file(path)) {
    auto store = std::make_shared<SiteStore>();
    store->mapped.emplace(io::MappedIndex::open(path, options.index_file));
    s.storage_ = SiteStorage::index_file;
    s.mapped_ = &*store->mapped;
    s.owned_ = std::move(store);
    t.read_seconds = seconds_since(t0);
  } else if (options.copc_in_place && io::is_copc_file(path)) {
    auto store = std::make_shared<SiteStore>();
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

}  // namespace rayscan
