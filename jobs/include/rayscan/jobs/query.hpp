// The ray-query job (paper Algorithm 1 over a file or an in-memory cloud): what `rayscan query`
// runs, as one library call.
#pragma once

#include "rayscan/site/copc.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/io/grid_text.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <ostream>
#include <string_view>
#include <vector>

namespace rayscan::jobs {

namespace detail {

/// Rays per block: the unit of the progress bar; a run of rays is at most a block.
inline constexpr std::uint64_t kQueryRaysPerBlock = 256;
/// The results the rays of one run hold by their typical count (--k, else a sample's most): a run
/// is a whole block when its rays return few results each, down to one ray when each returns tens
/// of thousands, so that the runs in flight, not the whole answer, are held. The run is also the
/// MPI queue's item, so one reply carries about this many results per run (512 KiB of RayHits).
inline constexpr std::uint64_t kQueryHitsPerRun = std::uint64_t{1} << 14;
/// The most bytes of results one MPI message carries: MPI counts a message's bytes in an int, and
/// the work queue's head (docs/mpi.md) is to fit beside them.
inline constexpr std::uint64_t kQueryMaxMessageResultBytes = std::uint64_t(std::numeric_limits<int>::max()) - 4096;

/// The bytes `rays` rays returning `results` results in all take in an MPI reply: per ray its
/// count (8 B), then its RayHits (32 B each).
inline constexpr std::uint64_t query_reply_bytes(std::uint64_t rays, std::uint64_t results) {
  return rays * sizeof(std::uint64_t) + results * sizeof(RayHit);
}

/// The rays of one run (the query job's unit of work and of an MPI reply): kQueryHitsPerRun /
/// `typical_results` (the results a ray returns typically: the bound, or the most of a sample of
/// the rays) within [1, kQueryRaysPerBlock], capped so that the run fits one MPI message
/// (kQueryMaxMessageResultBytes) even when each of its rays returns `bound` results (min(--k,
/// the points)); one ray at least, whose reply may then still be refused.
[[nodiscard]] std::uint64_t query_run_rays(std::uint64_t typical_results, std::uint64_t bound);

}  // namespace detail

/// Inputs of run_query().
struct QueryJobOptions {
  std::filesystem::path cloud_file;      ///< point cloud to read (any format read_point_cloud reads), or an
                                         ///< index file (.rsi: queried on its memory map; `index` is ignored)
  const PointCloud* cloud = nullptr;     ///< in-memory points instead of cloud_file (not copied)
  std::filesystem::path rays_file;       ///< rays to read (read_rays) when `rays` is empty
  std::vector<Ray> rays;                 ///< rays given in memory
  RayQuery query;                        ///< k, radius, t interval, order (RayQuery::validate rules)
  IndexOptions index;                    ///< index type and parameters
  /// COPC input (a LAZ file with the COPC info VLR): the bound on decoded node data kept by the
  /// CopcIndex LRU cache, bytes (`--cache`). The query runs on the file's own hierarchy
  /// (io::CopcIndex, the paper's layered organisation); `index` is then ignored.
  std::size_t cache_bytes = io::kCopcDefaultCacheBytes;
  /// A query without k and without a finite radius returns every point for every ray (1e8 rows per
  /// ray on a 1e8-point site), almost never what is meant: false refuses it (OptionError, after the
  /// rays are read and before the cloud is), as `rayscan query` does unless --all.
  bool allow_unbounded = true;
  /// When set, the hits are not kept (QueryJobResult::hits and hit_positions stay empty) but
  /// written here as CSV text, as write_hits_csv writes them, while the rays are answered: the
  /// header once the cloud and index are ready, then the rows of each run of rays once it and the
  /// runs before it are answered, one call at a time, in ray order. Only the runs in flight are
  /// held: at most 2 x threads runs, each up to 256 rays and about 16,384 results by the bound of
  /// `query` (--k, the points; with a finite radius or t interval the most results of a sample of
  /// the rays), one ray at least, and never so many rays that their bound passes 2 GiB
  /// (detail::query_run_rays). With a distributor, only the root writes. An exception it throws
  /// (a failed write) ends the job.
  std::function<void(std::string_view)> csv;
  /// threads; progress: a bar over the blocks of 256 rays answered; log: the read and the index
  /// build (their sizes and seconds), COPC nodes decoded
  JobControl control;
};

/// Output of run_query().
struct QueryJobResult {
  PointCloud cloud;                          ///< the cloud read from cloud_file (empty for in-memory input)
  std::vector<Ray> rays;                     ///< the rays answered
  std::vector<std::vector<RayHit>> hits;     ///< hits[r]: the results of ray r, best first (empty with `csv`)
  std::uint64_t rows = 0;                    ///< the results of all rays (the CSV rows; with a distributor: on the root)
  /// Index-file input (.rsi, rayscan/site/index_file.hpp): the position of every hit, in the order
  /// of `hits` flattened (ray by ray, best first); `cloud` then stays empty. Empty otherwise.
  std::vector<Vec3> hit_positions;
  /// How the CSV prints x, y and z: on the LAS grid of a LAS, LAZ or COPC file (its header's scale
  /// and offset) or of an index file storing the sources' LAS integers; none for other input.
  io::GridText grid;
  /// COPC input: node chunks decoded (CopcIndex::decodes()) and nodes in the hierarchy; the
  /// hit positions are in `hit_positions` as for an index file. Both 0 otherwise.
  std::uint64_t copc_decodes = 0, copc_nodes = 0;
  unsigned threads = 0;      ///< worker threads per process that answered the rays (resolve_threads)
  double query_seconds = 0;  ///< wall-clock seconds answering the rays (after reading and indexing)
};

/// Reads the rays (first, so a malformed rays file is reported before a large cloud is read) and
/// the cloud, builds the index and answers every ray (ray_query_each over runs of rays in
/// parallel with TBB, identical for any thread count; control.progress draws a bar over the
/// blocks of 256 rays), keeping the hits in the result or, with options.csv, writing them as
/// they are answered. Throws std::invalid_argument for an invalid query or index option (e.g.
/// depth with another index than octree-fixed), io::FormatError for a malformed input file.
/// With options.control.distributor over several processes (MPI, docs/mpi.md), every process
/// calls it; the same runs of rays are handed out by the distributor (one message per batch of
/// runs; std::invalid_argument when a batch's hits exceed what one MPI message carries) and only
/// the root keeps `hits` (and `hit_positions`; the other ranks' stay empty), or only the root
/// writes the CSV (each run once the runs before it are written); a COPC file is answered by the
/// root alone.
QueryJobResult run_query(const QueryJobOptions& options);

/// Writes the hits as CSV "ray,rank,index,x,y,z,t,distance" to `out`, every number the shortest
/// text that reads back as the same double (exact; 636500.92, not 636500.92000000004);
/// `positions` are the positions of the cloud queried (to print x, y, z; no LAS grid).
void write_hits_csv(std::ostream& out, std::span<const Vec3> positions,
                    const std::vector<std::vector<RayHit>>& hits);

/// The same for a job's result: positions from `result.cloud`, or `result.hit_positions` for an
/// index-file or COPC input, x, y and z on `result.grid` (a LAS source's: with the grid's
/// decimals, 637173.82, not the reader's double 637173.8200000001; io::GridText); the bytes
/// QueryJobOptions::csv receives. (For in-memory input, use the overload above with the caller's
/// positions.)
void write_hits_csv(std::ostream& out, const QueryJobResult& result);


}  // namespace rayscan::jobs
