// The index job: builds the index file (.rsi, docs/index-format.md) of one or more point cloud
// files out of core (a site delivered as tiles is one index). `rayscan index` runs it.
#pragma once

#include "rayscan/base/job.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/site/copc_writer.hpp"
#include "rayscan/site/index_file.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::jobs {

// The site library types this job's options and result are made of.
using io::IndexBuildStats;
using io::IndexProgress;

/// Inputs of run_index().
struct IndexJobOptions {
  /// The point cloud files (any format the io readers read; tiles of one site in one CRS). Their
  /// points get ids 0, 1, ... in this order.
  std::vector<std::filesystem::path> inputs;
  /// The index file to write; its name must end in .rsi (any case), or in .copc.laz
  /// (io::is_copc_output) for a COPC 1.0 file instead (one input; io::write_copc with `memory`,
  /// `temp_dir`, `progress` and `control`; the other options do not apply).
  std::filesystem::path output;
  /// Attributes stored besides positions, comma-separated names in lower case as
  /// io::AttributeSet::parse lists them ("id,rgb,intensity,classification,gps_time", "none");
  /// exactly "all" means every attribute an index stores (io::kIndexAttributes). `id` stores the
  /// original point ids (4 bytes per point).
  std::string attributes = "none";
  /// Memory budget of the external sort, a byte size as parse_byte_size reads it ("4G", "512M",
  /// "65536"); at least 1M.
  std::string memory = "4G";
  OctreeConfig config;             ///< layout (adaptive or fixed) and its capacity / depth / max_depth
  bool compact_positions = true;   ///< the most compact exact position encoding, else always float64
  std::filesystem::path temp_dir;  ///< folder for the sort runs; empty = the output's folder
  /// Called every few million points in every phase ("read", "sort", ...; done and total in
  /// points, total 0 when unknown) and once more before the output is renamed into place; may be
  /// empty. An exception it throws stops the build: the temporary output and the sort runs are
  /// removed and the exception reaches the caller unchanged (how a front end cancels).
  IndexProgress progress;
  JobControl control;  ///< threads of the build's parallel stages (0 = all cores); log and progress bar unused
};

/// Output of run_index().
struct IndexJobResult {
  std::filesystem::path output;  ///< the index file written
  IndexBuildStats stats;         ///< points, nodes, depth, sort runs, bytes, encodings, notes for the user (.rsi)
  std::optional<io::CopcWriteResult> copc;  ///< set instead of `stats` when a COPC file was written
};

/// Checks the options, then builds the index file (io::build_index_file: an external sort by Morton
/// code within the memory budget, written to a temporary file renamed into place). Throws
/// OptionError naming "memory" for a malformed memory budget, "attributes" for a name an index
/// does not store or one not in lower case (listing those it stores), "temp_dir" for a temporary folder that does not exist,
/// and OptionError for an input given twice (the same file, however spelled), for
/// an output name without .rsi and for the build's own
/// option checks (naming "layout", "memory_bytes" or "attributes"), io::FormatError for a
/// malformed input, io::IndexError when the inputs disagree, std::runtime_error for I/O failures;
/// on any error nothing is left behind.
IndexJobResult run_index(const IndexJobOptions& options);

}  // namespace rayscan::jobs
