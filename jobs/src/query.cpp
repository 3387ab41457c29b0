// The ray-query job (rayscan/jobs/query.hpp).
#include "rayscan/jobs/query.hpp"

#include "rayscan/site/site.hpp"
#include "rayscan/io/rays.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <type_traits>
#include <unordered_map>

namespace rayscan::jobs {

using namespace rayscan::io;  // the io library's types, which this job speaks in

namespace {

constexpr std::uint64_t kRaysPerItem = 256;  // rays per block: the unit of the progress bar and of the MPI queue

// Answers the ray blocks [b0, b1) (kRaysPerItem rays each, counted from rays[0]) in parallel, one
// ray_query_each per block (bit for bit the single ray_query calls, so the hits do not depend on
// the split), each block counted on `progress` when done.
template <class I>
void answer_blocks(const I& idx, const std::vector<Ray>& rays, const RayQuery& q, std::uint64_t b0, std::uint64_t b1,
                   std::vector<std::vector<RayHit>>& hits, Progress& progress) {
  const std::uint64_t n = rays.size();
  tbb::parallel_for(tbb::blocked_range<std::uint64_t>(b0, b1, 1), [&](const tbb::blocked_range<std::uint64_t>& r) {
    for (std::uint64_t b = r.begin(); b != r.end(); ++b) {
      const std::uint64_t first = b * kRaysPerItem, count = std::min(n, first + kRaysPerItem) - first;
      ray_query_each(idx, std::span<const Ray>(rays).subspan(first, count), q,
                     std::span<std::vector<RayHit>>(hits).subspan(first, count));
      progress.tile_done(count);
    }
  });
}

// Every ray's hits, over TBB on `threads` threads, or, with a distributor of several processes,
// blocks of kRaysPerItem rays handed out by it and gathered to the root (hit lists serialised as
// count + RayHits). The progress bar (JobControl::progress) counts the blocks: on the root its own
// and those it unpacks.
template <class I>
void answer_rays(const I& idx, const std::vector<Ray>& rays, const RayQuery& q, unsigned threads, bool show_progress,
                 WorkDistributor* dist, std::vector<std::vector<RayHit>>& hits) {
  q.validate();
  const std::uint64_t n = rays.size();
  const std::uint64_t blocks = (n + kRaysPerItem - 1) / kRaysPerItem;
  // "ray blocks", not "blocks of 256 rays": the bar must fit the 90 columns Progress::finish clears.
  Progress progress(blocks, show_progress, ProgressUnits{"ray blocks", "rays/s", 1.0, 0});
  tbb::task_arena arena(static_cast<int>(threads));
  hits.assign(n, {});
  if (!dist || dist->size() <= 1) {
    arena.execute([&] { answer_blocks(idx, rays, q, 0, blocks, hits, progress); });
    progress.finish();
    return;
  }
  auto range = [&](std::uint64_t first, std::uint64_t count) {
    return std::pair{first * kRaysPerItem, std::min(n, (first + count) * kRaysPerItem)};
  };
  WorkStage stage;
  stage.items = blocks;
  stage.batch = threads;
  stage.compute = [&](std::uint64_t first, std::uint64_t count) {
    arena.execute([&] { answer_blocks(idx, rays, q, first, first + count, hits, progress); });
  };
  stage.pack = [&](std::uint64_t first, std::uint64_t count) {
    const auto [a, b] = range(first, count);
    std::vector<std::byte> out;
    for (std::uint64_t i = a; i < b; ++i) {
      const std::uint64_t k = hits[i].size();
      append_bytes(out, std::span<const std::uint64_t>(&k, 1));
      append_bytes(out, std::span<const RayHit>(hits[i]));
    }
    return out;
  };
  stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
    const auto [a, b] = range(first, count);
    std::size_t off = 0;
    for (std::uint64_t i = a; i < b; ++i) {
      std::uint64_t k = 0;
      read_values(bytes, off, std::span<std::uint64_t>(&k, 1));
      if (k > (bytes.size() - off) / sizeof(RayHit)) throw std::runtime_error("query: ray block message is short");
      hits[i].resize(k);
      read_values(bytes, off, std::span<RayHit>(hits[i]));
    }
    if (off != bytes.size()) throw std::runtime_error("query: ray block message has trailing bytes");
    for (std::uint64_t c = first; c < first + count; ++c)
      progress.tile_done(std::min(n, (c + 1) * kRaysPerItem) - c * kRaysPerItem);  // the block's rays
  };
  dist->run(stage);
  progress.finish();
}

}  // namespace

QueryJobResult run_query(const QueryJobOptions& o) {
  o.query.validate();
  QueryJobResult r;
  // Rays first: a malformed rays file is reported before a large cloud is read.
  r.rays = o.rays.empty() && !o.rays_file.empty() ? read_rays(o.rays_file) : o.rays;
  if (!o.allow_unbounded && o.query.k == kAllPoints && !(o.query.radius < kInf) && !o.query.any_hit)
    throw OptionError({"neither ", option("k"), " nor a finite ", option("radius"),
                       ": every ray would return every point; give ", option("k"), ", ", option("radius"), ", or ",
                       option("all"), " to ask for all of them"});
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<Site> site;
  if (!o.cloud && (is_index_file(o.cloud_file) || is_copc_file(o.cloud_file))) {
    // An index file or a COPC file is queried in place: the queries run on the memory map or the
    // file's hierarchy (only the nodes the rays reach are decoded).
    SiteOptions so;
    so.copc_cache_bytes = o.cache_bytes;
    site.emplace(Site::open(o.cloud_file, so));
  } else {
    if (!o.cloud) r.cloud = read_point_cloud(o.cloud_file, ReadOptions{.scalars = false});
    const PointCloud& cloud = o.cloud ? *o.cloud : r.cloud;
    char buf[256];
    std::snprintf(buf, sizeof buf, "read %zu points and %zu rays in %.2f s", cloud.size(), r.rays.size(),
                  seconds_since(t0));
    o.control.info(buf);
    const auto t_build = std::chrono::steady_clock::now();
    site.emplace(Site::over(cloud, o.index));
    std::snprintf(buf, sizeof buf, "%s index built in %.2f s", o.index.type.c_str(), seconds_since(t_build));
    o.control.info(buf);
  }
  r.threads = resolve_threads(o.control.threads);
  const auto t_query = std::chrono::steady_clock::now();
  site->visit([&](auto& idx) {
    using I = std::remove_cvref_t<decltype(idx)>;
    if constexpr (std::is_same_v<I, CopcIndex>) {
      // The batch runs here (no distributed work queue for COPC files).
      answer_rays(idx, r.rays, o.query, r.threads, o.control.progress, nullptr, r.hits);
      for (const auto& h : r.hits)
        for (const RayHit& x : h) r.hit_positions.push_back(idx.position_of(x.index));
      r.copc_decodes = idx.decodes();
      r.copc_nodes = idx.node_count();
      char msg[256];
      std::snprintf(msg, sizeof msg, "COPC: %llu of %llu nodes decoded, %zu rays in %.2f s",
                    static_cast<unsigned long long>(r.copc_decodes), static_cast<unsigned long long>(r.copc_nodes),
                    r.rays.size(), seconds_since(t0));
      o.control.info(msg);
    } else if constexpr (std::is_same_v<I, MappedIndex>) {
      answer_rays(idx, r.rays, o.query, r.threads, o.control.progress, o.control.distributor, r.hits);
      if (o.control.distributor && !o.control.distributor->is_root()) return;
      // Positions of the hits by one sequential scan of the ids (no inverse permutation in memory).
      std::unordered_map<PointIndex, Vec3> hit_pos;
      for (const auto& h : r.hits)
        for (const RayHit& x : h) hit_pos.emplace(x.index, Vec3(0.0));
      const IdView ids = idx.ids();
      const auto pos = idx.positions();
      if (ids.is_identity())  // an index without ids: a hit's index is its slot
        for (auto& [id, p] : hit_pos) p = pos[id];
      for (std::size_t s = 0; s < ids.size() && !ids.is_identity() && !hit_pos.empty(); ++s)
        if (auto it = hit_pos.find(ids[s]); it != hit_pos.end()) it->second = pos[s];
      for (const auto& h : r.hits)
        for (const RayHit& x : h) r.hit_positions.push_back(hit_pos.at(x.index));
    } else {
      // Positions from the cloud in memory.
      answer_rays(idx, r.rays, o.query, r.threads, o.control.progress, o.control.distributor, r.hits);
    }
  });
  r.query_seconds = seconds_since(t_query);
  return r;
}

namespace {

/// One CSV row "ray,rank,index,x,y,z,t,distance", each number the shortest text that reads back
/// as the same double (shortest_text): exact, and an input coordinate 636500.92 prints as such.
void write_hit_row(std::ostream& os, std::size_t ray, std::size_t rank, const RayHit& h, const Vec3& p) {
  os << ray << ',' << rank << ',' << h.index << ',' << shortest_text(p.x) << ',' << shortest_text(p.y) << ','
     << shortest_text(p.z) << ',' << shortest_text(h.t) << ',' << shortest_text(h.distance) << '\n';
}

constexpr const char* kHitsHeader = "ray,rank,index,x,y,z,t,distance\n";

}  // namespace

void write_hits_csv(std::ostream& os, std::span<const Vec3> positions,
                    const std::vector<std::vector<RayHit>>& hits) {
  os << kHitsHeader;
  for (std::size_t r = 0; r < hits.size(); ++r)
    for (std::size_t k = 0; k < hits[r].size(); ++k) write_hit_row(os, r, k, hits[r][k], positions[hits[r][k].index]);
}

void write_hits_csv(std::ostream& os, const QueryJobResult& r) {
  if (r.hit_positions.empty()) return write_hits_csv(os, r.cloud.positions, r.hits);
  // Index-file input: hit_positions follows hits flattened (ray by ray, best first).
  os << kHitsHeader;
  std::size_t slot = 0;
  for (std::size_t k = 0; k < r.hits.size(); ++k)
    for (std::size_t j = 0; j < r.hits[k].size(); ++j) write_hit_row(os, k, j, r.hits[k][j], r.hit_positions[slot++]);
}

}  // namespace rayscan::jobs
