// The process group of one `rayscan` run: one process, or the ranks of `mpirun -n N rayscan ...`
// (rayscan::mpi, docs/mpi.md). Commands that can be distributed (render, visibility, solar, query) hand
// distributor() to their job; only the root prints and writes.
#pragma once

#include "rayscan/base/work_distributor.hpp"

#include <string>

namespace rayscan::cli {

/// The work distributor of this run (MPI with more than one rank), or nullptr.
WorkDistributor* distributor();
/// True on the process that prints results and writes outputs (always, without MPI).
bool is_root();
/// Ranks in this run (1 without MPI).
int process_count();
/// Refuses (UsageError) a command that cannot be distributed when there is more than one rank:
/// N copies would write the same outputs.
void require_single_process(const std::string& command);
/// Under MPI with several ranks, on the root: one line with the traffic of the run so far
/// ("mpi: 2 ranks, 412 messages, 1.23 MB (1.2 MB results), rank 0 computed 97 of 204 items");
/// "" otherwise.
std::string traffic_summary();
/// Names the command in the distributor's fault messages ("rayscan render").
void set_command_name(const std::string& name);

}  // namespace rayscan::cli
