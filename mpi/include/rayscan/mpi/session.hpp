// One MPI job of the `rayscan` program (docs/mpi.md): MPI is initialised only when the
// process was started by an MPI launcher (`mpirun -n N rayscan ...`), so the same binary runs
// alone without one. Every rank runs the same command on the same inputs; rank 0 (the root)
// gathers the results and writes the outputs. Open MPI from Debian (libopenmpi-dev).
#pragma once

#include "rayscan/mpi/work_queue.hpp"

#include <memory>
#include <optional>
#include <string>

namespace rayscan::mpi {

/// True when the environment shows an MPI launcher (Open MPI's OMPI_COMM_WORLD_SIZE, or the
/// PMI_SIZE / PMIX_RANK of other launchers) with more than zero ranks.
bool launched_by_mpi();

/// What one rank's command-line parsing decided (Session::agree_on_start): go on with the command,
/// or end the run now, printing `out` (help or version text, to stdout) and `err` (a one-line usage
/// error without its newline, to stderr) and returning `code` (0 for --help/--version, 2 for an error).
struct StartOutcome {
  bool end = false;
  int code = 0;
  std::string out;
  std::string err;
};

/// The MPI environment of the process, alive for the whole run (RAII: MPI_Init_thread with
/// MPI_THREAD_FUNNELED in the constructor, MPI_Finalize in the destructor). Only one may exist.
/// Outside an MPI launcher it initialises nothing and reports one rank (size() == 1).
class Session {
 public:
  /// Initialises MPI when launched_by_mpi(). `timeout_seconds` bounds every wait for another
  /// rank (a rank that stays silent that long ends the job, see QueueDistributor); the environment
  /// variable RAYSCAN_MPI_TIMEOUT (seconds, > 0) overrides it. RAYSCAN_MPI_ROOT_COMPUTES=0 makes
  /// rank 0 a dedicated master that computes no items (QueueDistributor). Throws std::runtime_error when MPI
  /// cannot be initialised or does not offer MPI_THREAD_FUNNELED.
  Session(int& argc, char**& argv, double timeout_seconds = 600.0);
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  /// MPI_Finalize when initialised (after finish(), or immediately on an error path).
  ~Session();

  /// Number of ranks (1 without a launcher).
  [[nodiscard]] int size() const { return size_; }
  /// This process's rank (0 without a launcher).
  [[nodiscard]] int rank() const { return rank_; }
  /// True on rank 0, which prints and writes.
  [[nodiscard]] bool is_root() const { return rank_ == 0; }
  /// The work queue for a job's stages when size() > 1, else nullptr (the job runs alone).
  [[nodiscard]] QueueDistributor* distributor() { return queue_.get(); }
  /// The timeout in seconds (constructor value or RAYSCAN_MPI_TIMEOUT).
  [[nodiscard]] double timeout() const { return timeout_; }

  /// Collective, once, right after every rank parsed its command line: `--help`, `--version` and
  /// usage errors are printed once per job, by rank 0, not once per rank. Returns std::nullopt when
  /// no rank ends (go on with the command). Otherwise the job ends with the outcome of the lowest rank
  /// among those with the strongest outcome (a usage error beats help/version, which beats going on):
  /// rank 0 prints that rank's `out` and `err` (a worker's error gets " (rank R of N)" appended), the
  /// others print nothing, and every rank returns its exit code (main returns it; ~Session finalises
  /// MPI, so the job ends without MPI_Abort). One rank: prints `mine` and returns its code. Waits at
  /// most timeout() for the other ranks, then ends the job like fail().
  std::optional<int> agree_on_start(const StartOutcome& mine);

  /// Normal end, collective: workers tell the root they finished; the root waits for all of
  /// them (reporting a worker's failure message like fail() would). No-op for one rank.
  void finish();

  /// Ends the job after an error on this rank; `line` is the one-line message ("rayscan render:
  /// cannot open ..."). One rank: prints it and returns. Root: prints it to stderr and calls
  /// MPI_Abort(2), killing every rank (no output is written: outputs are only written after the
  /// last stage). Worker: sends it to the root, which prints "<line> (rank R of N)" and aborts; if
  /// the root does not act within min(timeout, 60 s) the worker prints it itself and aborts.
  /// Does not return when size() > 1.
  void fail(const std::string& line);

 private:
  int size_ = 1, rank_ = 0;
  bool initialised_ = false;
  double timeout_ = 600.0;
  std::unique_ptr<QueueDistributor> queue_;
};

}  // namespace rayscan::mpi
