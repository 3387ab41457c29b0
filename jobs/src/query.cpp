// The ray-query job (rayscan/jobs/query.hpp).
#include "rayscan/jobs/query.hpp"

#include "rayscan/site/site.hpp"
#include "rayscan/io/grid_text.hpp"
#include "rayscan/io/rays.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace rayscan::jobs {

using namespace rayscan::io;  // the io library's types, which this job speaks in

namespace detail {

std::uint64_t query_run_rays(std::uint64_t typical_results, std::uint64_t bound) {
  const std::uint64_t typical =
      std::clamp<std::uint64_t>(kQueryHitsPerRun / std::max<std::uint64_t>(typical_results, 1), 1, kQueryRaysPerBlock);
  return std::min(typical, std::max<std::uint64_t>(1, kQueryMaxMessageResultBytes / query_reply_bytes(1, bound)));
}

}  // namespace detail

namespace {

using detail::query_reply_bytes;
constexpr std::uint64_t kRaysPerBlock = detail::kQueryRaysPerBlock;
constexpr std::uint64_t kHitsPerRun = detail::kQueryHitsPerRun;
constexpr std::uint64_t kMaxMessageResultBytes = detail::kQueryMaxMessageResultBytes;

/// What becomes of the answers of a run of consecutive rays.
struct RunSink {
  /// Called concurrently for disjoint runs: the output of the rays [first, first + hits.size())
  /// from their hits (best first): their CSV rows, or nothing once the hits are kept elsewhere
  /// (it may take them).
  std::function<std::string(std::uint64_t first, std::span<std::vector<RayHit>> hits)> render;
  /// Called one run at a time, in ray order, with render's output.
  std::function<void(const std::string&)> write;
};

/// The runs of `n` rays: each block of kRaysPerBlock rays is cut into runs of `rays` rays
/// (detail::query_run_rays), the block's last run shorter. Run i is the (i % per_block)-th of block
/// i / per_block, so consecutive runs are consecutive rays and no run straddles two blocks (the
/// progress bar counts blocks). The pipeline's unit in one process and the queue's item in several.
struct Runs {
  std::uint64_t n, rays, per_block;
  Runs(std::uint64_t n_rays, std::uint64_t typical_hits_per_ray, std::uint64_t max_hits_per_ray)
      : n(n_rays),
        rays(detail::query_run_rays(typical_hits_per_ray, max_hits_per_ray)),
        per_block((kRaysPerBlock + rays - 1) / rays) {}
  /// Blocks of kRaysPerBlock rays (the last may be short).
  [[nodiscard]] std::uint64_t blocks() const { return (n + kRaysPerBlock - 1) / kRaysPerBlock; }
  /// Rays in block b.
  [[nodiscard]] std::uint64_t block_rays(std::uint64_t b) const {
    return std::min(n, (b + 1) * kRaysPerBlock) - b * kRaysPerBlock;
  }
  /// Number of runs.
  [[nodiscard]] std::uint64_t count() const {
    return n == 0 ? 0 : (blocks() - 1) * per_block + (block_rays(blocks() - 1) + rays - 1) / rays;
  }
  /// The first ray of run i, and the ray after its last.
  [[nodiscard]] std::uint64_t first(std::uint64_t i) const { return i / per_block * kRaysPerBlock + i % per_block * rays; }
  [[nodiscard]] std::uint64_t end(std::uint64_t i) const {
    return std::min({n, first(i) + rays, (i / per_block + 1) * kRaysPerBlock});
  }
};

// The rays answered to size the runs of a query whose results per ray its bound (--k, the
// points) overstates: one ray in kBoundSampleStride, at least kBoundSampleRays, spread evenly over
// the whole file, so that one region's rays do not speak for all (on large ray sets 0.4 % more
// queries).
constexpr std::uint64_t kBoundSampleRays = 64, kBoundSampleStride = 256;

/// The most results a ray of `q` returns, as the runs are cut (Runs): `bound` (min(--k, the
/// points)) when every ray returns it (no radius, t interval or plane restricts the query) or when
/// it already leaves whole blocks; else the most results of a sample of `rays` spread evenly over
/// them (at least 1, at most `bound`), answered here on `arena`, one ray at a time per thread. A
/// radius query on a large cloud thus gets runs of about kHitsPerRun results, as a --k query does,
/// instead of a run (and under MPI a reply) per ray; a ray past the sample's most makes its run
/// longer, not its answer different, and Runs caps the rays of a run by `bound` so that even then
/// it fits one MPI message (detail::query_run_rays). The same on every rank: the rays, the index
/// and the answers are.
template <class I>
std::uint64_t results_per_ray(const I& idx, std::span<const Ray> rays, const RayQuery& q, tbb::task_arena& arena,
                              std::uint64_t bound) {
  const bool restricted = q.radius < kInf || q.t_min > -kInf || q.t_max < kInf || !q.planes.empty();
  if (!restricted || bound <= kHitsPerRun / kRaysPerBlock || rays.empty()) return bound;
  const std::uint64_t n = rays.size(), samples = std::min(n, std::max(kBoundSampleRays, n / kBoundSampleStride));
  std::vector<std::uint64_t> counts(samples, 0);
  arena.execute([&] {
    tbb::parallel_for(std::uint64_t{0}, samples, [&](std::uint64_t j) {
      std::vector<RayHit> hits[1];
      ray_query_each(idx, rays.subspan(j * n / samples, 1), q, std::span<std::vector<RayHit>>(hits));
      counts[j] = hits[0].size();
    });
  });
  return std::clamp<std::uint64_t>(*std::max_element(counts.begin(), counts.end()), 1, bound);
}

/// Answers every ray, over TBB on `threads` threads, handing each run of consecutive rays' hits to
/// `sink` as soon as it and the runs before it are answered, so that only the runs in flight are
/// held: a TBB pipeline of up to 2 x threads runs (Runs: each at most a block, kHitsPerRun
/// results by `max_hits_per_ray` or, for a radius or t interval, by results_per_ray's sample, at
/// least one ray, at most the rays whose `max_hits_per_ray` each fit one MPI message), answered
/// by ray_query_each (bit for bit the single ray_query calls, so the hits do not depend on the
/// split) and written in order. With a
/// distributor of several processes, the same runs are its items: handed out in batches of
/// `threads` runs and gathered to the root (hit lists serialised as count + RayHits), where each
/// run is rendered and written once the runs before it are (those ahead of it wait, as text).
/// The progress bar (JobControl::progress) counts the blocks: a block is done when its last run
/// is written (under MPI: on the root, its own and those it unpacks). Returns the results counted
/// (on the root: all of them). Throws OptionError when a batch's results exceed what one MPI
/// message carries (kMaxMessageResultBytes).
template <class I>
std::uint64_t answer_rays(const I& idx, const std::vector<Ray>& rays, const RayQuery& q, unsigned threads,
                          bool show_progress, WorkDistributor* dist, std::uint64_t max_hits_per_ray,
                          const RunSink& sink) {
  q.validate();
  const std::uint64_t n = rays.size();
  tbb::task_arena arena(static_cast<int>(threads));
  const Runs runs(n, results_per_ray(idx, std::span<const Ray>(rays), q, arena, max_hits_per_ray), max_hits_per_ray);
  // "ray blocks", not "blocks of 256 rays": the bar must fit the 90 columns Progress::finish clears.
  Progress progress(runs.blocks(), show_progress, ProgressUnits{"ray blocks", "rays/s", 1.0, 0});
  // After run i is written: the bar's block when the run was its last.
  const auto written = [&](std::uint64_t i) {
    const std::uint64_t end = runs.end(i);
    if (end % kRaysPerBlock == 0 || end == n) progress.tile_done(runs.block_rays((end - 1) / kRaysPerBlock));
  };
  const auto answer = [&](std::uint64_t i) {
    std::vector<std::vector<RayHit>> hits(runs.end(i) - runs.first(i));
    ray_query_each(idx, std::span<const Ray>(rays).subspan(runs.first(i), hits.size()), q,
                   std::span<std::vector<RayHit>>(hits));
    return hits;
  };
  const auto count_rows = [](std::span<const std::vector<RayHit>> hits) {
    std::uint64_t k = 0;
    for (const auto& h : hits) k += h.size();
    return k;
  };
  std::uint64_t rows = 0;
  if (!dist || dist->size() <= 1) {
    struct Run {
      std::uint64_t index = 0, rows = 0;
      std::string text;
    };
    std::uint64_t next = 0;
    arena.execute([&] {
      tbb::parallel_pipeline(
          2 * std::size_t{threads},
          tbb::make_filter<void, Run>(tbb::filter_mode::serial_in_order,
                                      [&](tbb::flow_control& fc) {
                                        Run run;
                                        if (next == runs.count()) fc.stop();
                                        else run.index = next++;
                                        return run;
                                      }) &
              tbb::make_filter<Run, Run>(tbb::filter_mode::parallel,
                                         [&](Run run) {
                                           std::vector<std::vector<RayHit>> hits = answer(run.index);
                                           run.rows = count_rows(hits);
                                           run.text = sink.render(runs.first(run.index), std::span<std::vector<RayHit>>(hits));
                                           return run;
                                         }) &
              tbb::make_filter<Run, void>(tbb::filter_mode::serial_in_order, [&](Run run) {
                sink.write(run.text);
                rows += run.rows;
                written(run.index);
              }));
    });
    progress.finish();
    return rows;
  }
  // Several processes. Root: runs answered (here or elsewhere) wait in `ahead` until the runs
  // before them are written. Others: the hits of the one batch being answered (its rays from
  // batch_first), until packed, so that a rank holds a batch, not a slot for every ray.
  std::mutex write_mutex;
  std::map<std::uint64_t, std::string> ahead;
  std::uint64_t next_run = 0;
  std::vector<std::vector<RayHit>> batch;
  std::uint64_t batch_first = 0;
  const auto done = [&](std::uint64_t i, std::span<std::vector<RayHit>> run_hits) {  // root
    const std::uint64_t k = count_rows(run_hits);
    std::string text = sink.render(runs.first(i), run_hits);
    const std::lock_guard<std::mutex> lock(write_mutex);
    rows += k;
    ahead.emplace(i, std::move(text));
    for (auto it = ahead.begin(); it != ahead.end() && it->first == next_run; it = ahead.erase(it), ++next_run) {
      sink.write(it->second);
      written(it->first);
    }
  };
  // The rays of runs [first, first + count): consecutive.
  auto range = [&](std::uint64_t first, std::uint64_t count) {
    return std::pair{runs.first(first), count == 0 ? runs.first(first) : runs.end(first + count - 1)};
  };
  WorkStage stage;
  stage.items = runs.count();
  stage.batch = threads;
  stage.compute = [&](std::uint64_t first, std::uint64_t count) {
    if (!dist->is_root()) {
      const auto [a, b] = range(first, count);
      batch_first = a;
      batch.assign(b - a, {});
    }
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::uint64_t>(first, first + count, 1),
                        [&](const tbb::blocked_range<std::uint64_t>& r) {
                          for (std::uint64_t i = r.begin(); i != r.end(); ++i) {
                            std::vector<std::vector<RayHit>> h = answer(i);
                            if (dist->is_root())
                              done(i, std::span<std::vector<RayHit>>(h));
                            else
                              std::move(h.begin(), h.end(),
                                        batch.begin() + static_cast<std::ptrdiff_t>(runs.first(i) - batch_first));
                          }
                        });
    });
  };
  stage.pack = [&](std::uint64_t first, std::uint64_t count) {  // the batch just computed (WorkStage)
    const auto [a, b] = range(first, count);
    if (a != batch_first || b - a != batch.size())
      throw std::logic_error("query: packing rays [" + std::to_string(a) + ", " + std::to_string(b) +
                             ") that are not the batch computed");
    // Each run holds about kHitsPerRun results and fits one message by the bound, but a batch is
    // `threads` runs and one ray may return the cloud's points: measured before a byte is copied.
    std::uint64_t results = 0;
    for (const std::vector<RayHit>& h : batch) results += h.size();
    const std::uint64_t size = query_reply_bytes(batch.size(), results);
    if (size > kMaxMessageResultBytes)
      throw OptionError({"rays [" + std::to_string(a) + ", " + std::to_string(b) + "), one rank's batch of ",
                         option("threads"), " runs, return " + count_text(results, "result") + " (" +
                             std::to_string(size) + " bytes; one MPI message carries at most " +
                             std::to_string(kMaxMessageResultBytes) + "): lower ",
                         option("threads"), ", ", option("k"), " or ", option("radius"), ", or run in one process"});
    std::vector<std::byte> out;
    out.reserve(size);
    for (std::vector<RayHit>& h : batch) {
      const std::uint64_t k = h.size();
      append_bytes(out, std::span<const std::uint64_t>(&k, 1));
      append_bytes(out, std::span<const RayHit>(h));
      std::vector<RayHit>().swap(h);  // sent: freed
    }
    return out;
  };
  stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
    std::size_t off = 0;
    for (std::uint64_t c = first; c < first + count; ++c) {
      std::vector<std::vector<RayHit>> h(runs.end(c) - runs.first(c));
      for (std::vector<RayHit>& ray_hits : h) {
        std::uint64_t k = 0;
        read_values(bytes, off, std::span<std::uint64_t>(&k, 1));
        if (k > (bytes.size() - off) / sizeof(RayHit)) throw std::runtime_error("query: ray run message is short");
        ray_hits.resize(k);
        read_values(bytes, off, std::span<RayHit>(ray_hits));
      }
      done(c, std::span<std::vector<RayHit>>(h));
    }
    if (off != bytes.size()) throw std::runtime_error("query: ray run message has trailing bytes");
  };
  dist->run(stage);
  progress.finish();
  return rows;
}

/// Appends one CSV row "ray,rank,index,x,y,z,t,distance" to `out`: x, y, z by `grid` (on the
/// source's LAS grid: its decimals), every other number the shortest text that reads back as the
/// same double (std::to_chars: exact).
void append_hit_row(std::string& out, std::uint64_t ray, std::uint64_t rank, const RayHit& h, const Vec3& p,
                    const io::GridText& grid) {
  char buf[32];  // the longest shortest form of a double is 24 characters
  const auto number = [&](auto v) { out.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr); };
  number(ray);
  out += ',';
  number(rank);
  out += ',';
  number(h.index);
  for (int k = 0; k < 3; ++k) {
    out += ',';
    grid.append(out, p[k], k);
  }
  out += ',';
  number(h.t);
  out += ',';
  number(h.distance);
  out += '\n';
}

constexpr const char* kHitsHeader = "ray,rank,index,x,y,z,t,distance\n";

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
    if (!o.cloud) {
      FileInfo info;
      r.cloud = read_point_cloud(o.cloud_file, ReadOptions{.scalars = false}, &info);
      // A LAS or LAZ file's coordinates print on its grid (las2txt's decimals).
      if (const LasWriteOptions g = las_grid_of(info); g.has_offset) r.grid = GridText::of(g.scale, g.offset);
    }
    const PointCloud& cloud = o.cloud ? *o.cloud : r.cloud;
    char buf[256];
    std::snprintf(buf, sizeof buf, " in %.2f s", seconds_since(t0));
    o.control.info("read " + count_text(cloud.size(), "point") + " and " + count_text(r.rays.size(), "ray") + buf);
    const auto t_build = std::chrono::steady_clock::now();
    site.emplace(Site::over(cloud, o.index));
    std::snprintf(buf, sizeof buf, "%s index built in %.2f s", o.index.type.c_str(), seconds_since(t_build));
    o.control.info(buf);
  }
  r.threads = resolve_threads(o.control.threads);
  WorkDistributor* const dist = o.control.distributor;
  const bool root = !dist || dist->is_root();
  // A rank other than the root of several keeps no hits: it sends each batch of runs to the
  // root once answered, and leaves a COPC file (not shared out over the ranks) to the root alone.
  const bool other_rank = dist && dist->size() > 1 && !root;
  // Streamed: only the runs of rays in flight are held (a query may return more than memory).
  const bool stream = o.csv && root;
  if (!stream && !other_rank) r.hits.assign(r.rays.size(), {});
  const PointCloud* const cloud = o.cloud ? o.cloud : &r.cloud;
  const auto t_query = std::chrono::steady_clock::now();
  site->visit([&](auto& idx) {
    using I = std::remove_cvref_t<decltype(idx)>;
    constexpr bool copc = std::is_same_v<I, CopcIndex>, mapped = std::is_same_v<I, MappedIndex>;
    const auto pos = idx.positions();
    // A COPC file's grid is its header's; an index file's the sources' when it stores their LAS
    // integers (positions las_int32; float64 positions have none).
    if constexpr (copc) r.grid = GridText::of(idx.info().scale, idx.info().offset);
    if constexpr (mapped)
      if (idx.position_encoding() == PositionEncoding::las_int32) r.grid = GridText::of(pos.scale(), pos.offset());
    // A hit's position: by its slot in an index file's storage, from the COPC file's decoded
    // node, or from the cloud in memory.
    const auto position = [&](const RayHit& h) -> Vec3 {
      if constexpr (copc) return idx.position_of(h.index);
      else if constexpr (mapped) return pos[h.slot];
      else return cloud->positions[h.index];
    };
    RunSink sink;
    if (stream) {
      sink.render = [&](std::uint64_t first, std::span<std::vector<RayHit>> hits) {
        std::string text;
        for (std::size_t i = 0; i < hits.size(); ++i)
          for (std::size_t k = 0; k < hits[i].size(); ++k)
            append_hit_row(text, first + i, k, hits[i][k], position(hits[i][k]), r.grid);
        return text;
      };
      sink.write = [&](const std::string& text) {
        if (!text.empty()) o.csv(text);
      };
      o.csv(kHitsHeader);
    } else {
      sink.render = [&](std::uint64_t first, std::span<std::vector<RayHit>> hits) {
        std::move(hits.begin(), hits.end(), r.hits.begin() + static_cast<std::ptrdiff_t>(first));
        return std::string();
      };
      sink.write = [](const std::string&) {};
    }
    const std::uint64_t max_hits = o.query.any_hit ? 1 : std::min<std::uint64_t>(o.query.k, pos.size());
    // A COPC file's batch runs here, on the root only (no distributed work queue for COPC files:
    // another rank would answer every ray again, and hold their hits, for nothing).
    if constexpr (copc)
      if (other_rank) return;
    r.rows = answer_rays(idx, r.rays, o.query, r.threads, o.control.progress, copc ? nullptr : dist, max_hits, sink);
    if (!stream && (copc || (mapped && root)))
      for (const auto& h : r.hits)
        for (const RayHit& x : h) r.hit_positions.push_back(position(x));
    if constexpr (copc) {
      r.copc_decodes = idx.decodes();
      r.copc_nodes = idx.node_count();
      char secs[64];
      std::snprintf(secs, sizeof secs, " in %.2f s", seconds_since(t0));
      o.control.info("COPC: " + std::to_string(r.copc_decodes) + " of " + count_text(r.copc_nodes, "node") +
                     " decoded, " + count_text(r.rays.size(), "ray") + secs);
    }
  });
  r.query_seconds = seconds_since(t_query);
  return r;
}

namespace {

/// The CSV of `hits` (hits[r]: ray r's, best first) to `os`: the header, then one row per hit, its
/// position position(hit, flat) (flat: its place in `hits` flattened, ray by ray).
template <class Position>
void write_rows(std::ostream& os, const std::vector<std::vector<RayHit>>& hits, const io::GridText& grid,
                const Position& position) {
  os << kHitsHeader;
  std::string row;
  std::size_t flat = 0;
  for (std::size_t r = 0; r < hits.size(); ++r)
    for (std::size_t k = 0; k < hits[r].size(); ++k, ++flat) {
      row.clear();
      append_hit_row(row, r, k, hits[r][k], position(hits[r][k], flat), grid);
      os << row;
    }
}

}  // namespace

void write_hits_csv(std::ostream& os, std::span<const Vec3> positions,
                    const std::vector<std::vector<RayHit>>& hits) {
  write_rows(os, hits, {}, [&](const RayHit& h, std::size_t) { return positions[h.index]; });
}

void write_hits_csv(std::ostream& os, const QueryJobResult& r) {
  // Index-file and COPC input: hit_positions follows hits flattened.
  if (r.hit_positions.empty())
    write_rows(os, r.hits, r.grid, [&](const RayHit& h, std::size_t) { return r.cloud.positions[h.index]; });
  else
    write_rows(os, r.hits, r.grid, [&](const RayHit&, std::size_t flat) { return r.hit_positions[flat]; });
}

}  // namespace rayscan::jobs
