// Site::open (the storage chosen from the file) and the queries every consumer of a site needs
// whatever its storage: the auto radius spacing and the surfel estimate (site.hpp).
#include "rayscan/site/site.hpp"

#include "rayscan/base/job.hpp"
#include "rayscan/octree/morton_sort.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/spacing.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>
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

bool Site::opens_in_place(const std::filesystem::path& path, const SiteOptions& options) {
  return io::is_index_file(path) || (options.copc_in_place && io::is_copc_file(path));
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
  } else if (opens_in_place(path, options)) {  // in place and no index file: a COPC file
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

namespace {

// median_nn_spacing_of's sample and rule (the points i * N / n of the file-order `positions`, the
// nearest at a non-zero distance among each one's 8 nearest) answered by the COPC file's own
// hierarchy: kNN answers do not depend on the index (sorted by distance, then id) and the median
// not on the order the samples are queried in, so the result is the whole-file path's bit for
// bit. The samples are queried in copc_point_order (neighbours share nodes) by
// median_nn_spacing_of itself, 1024 at a time with the cache trimmed between batches, so the
// decoded nodes stay within the cache budget plus one batch's.
double copc_spacing(io::CopcIndex& copc, std::span<const Vec3> positions) {
  if (positions.size() < 2) return 0.0;
  const std::size_t n = std::min(kSpacingSamples, positions.size());
  std::vector<Vec3> samples(n);
  for (std::size_t i = 0; i < n; ++i) samples[i] = positions[i * positions.size() / n];
  const std::vector<PointIndex> order = copc_point_order(samples);
  std::vector<Vec3> ordered(n);
  for (std::size_t k = 0; k < n; ++k) ordered[k] = samples[order[k]];
  return median_nn_spacing_of(copc, std::span<const Vec3>(ordered), n, 1024, [&] { copc.trim_cache(); });
}

// estimate_surfels_over's per-point step (detail::SurfelEstimator) over a COPC file in place, the
// points visited in copc_point_order (the index's slots hold only decoded nodes), each block of
// 1024 points in a QueryScope; positions are read from the file-order `positions`. The same
// attributes as in memory: the kNN answers are the same (sorted by distance, then id) and each
// point's arithmetic is the same.
SurfelAttributes copc_surfels(const io::CopcIndex& copc, std::span<const Vec3> positions, const SurfelOptions& o,
                              std::span<const glm::vec3> file_normals) {
  const std::size_t n = static_cast<std::size_t>(copc.info().point_count);
  detail::check_surfel_arguments(n, positions, o, file_normals);
  if (o.measure_thickness)
    throw std::invalid_argument(
        "surfels: the thickness measure needs the points in storage order; read the COPC file into memory");
  detail::SurfelEstimator est(n, positions, o, file_normals);
  const std::vector<PointIndex> order = copc_point_order(positions);
  detail::SurfelProgressCount progress(o, n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
    const io::CopcIndex::QueryScope scope(copc);
    std::vector<Neighbor> nb;
    for (std::size_t s = range.begin(); s != range.end(); ++s) est.estimate(copc, positions[order[s]], order[s], nb);
    progress.add(range.size());
  });
  detail::finish_surfel_radii(est.out, o);
  progress.finish();
  return std::move(est.out);
}

}  // namespace

std::vector<PointIndex> copc_point_order(std::span<const Vec3> positions) {
  const std::size_t n = positions.size();
  std::vector<PointIndex> order(n);
  if (n == 0) return order;
  AABB box;
  for (const Vec3& p : positions) box.expand(p);
  // The octree builders' quantisation and Morton sort (the same codes and (code, id) order).
  const OctreeRules::Quantizer qz(OctreeRules::root_cell(box).lo, OctreeRules::root_side(box));
  std::vector<MortonKey> keys(n);
  sort_morton_keys(n, [&](std::size_t i) { return qz.code(positions[i]); }, keys.data());
  for (std::size_t i = 0; i < n; ++i) order[i] = keys[i].idx;
  return order;
}

double median_nn_spacing(const Site& site, std::span<const Vec3> positions) {
  switch (site.storage()) {
    case SiteStorage::index_file: return site.index_file()->median_nn_spacing();
    case SiteStorage::copc: {
      io::CopcIndex& copc = *site.copc();
      if (!positions.empty() && positions.size() == copc.info().point_count) return copc_spacing(copc, positions);
      const std::vector<Vec3> samples = copc.spacing_samples(kCopcSpacingSamples);
      return median_nn_spacing_of(copc, std::span<const Vec3>(samples), samples.size());
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
  return copc_surfels(*site.copc(), positions, options, file_normals);
}

}  // namespace rayscan
