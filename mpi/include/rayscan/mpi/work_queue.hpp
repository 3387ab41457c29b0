// The dynamic work queue over MPI (docs/mpi.md): rank 0 hands out the items of a job's
// stage (render tiles, visibility point chunks, query ray blocks, animation frames) in small
// batches on request; every rank computes its batches with its own TBB threads and returns the
// results with its next request; rank 0 unpacks them into the full result and is the only writer.
// The master/worker task farm (OSPRay's MPI offload device, IceT-style tile farms); a rank that
// meets a dense part of the site simply asks less often, so no static split holds the others back.
//
// Messages (MPI_BYTE, point to point on MPI_COMM_WORLD; docs/mpi.md for the volume):
//  request  worker -> root  [stage, first, count, want] (4 x uint64) + the packed results of
//                            items [first, first + count) (count = 0 on the first request)
//  assign   root -> worker  [stage, first, count] (3 x uint64); count = 0: the stage is done
//  sum      worker -> root  [stage] + values (uint64) of sum_to_root
//  fail     worker -> root  one line of text (Session::fail)
//  bye      worker -> root  [stage] at the normal end (Session::finish)
// The root serves requests on its main thread (the only thread calling MPI: MPI_THREAD_FUNNELED)
// while a second thread computes the root's own batches, so rank 0 works like the others.
#pragma once

#include "rayscan/base/work_distributor.hpp"

#include <cstdint>
#include <functional>
#include <string>

namespace rayscan::mpi {

/// Counters of the traffic of a QueueDistributor (root: received + sent; workers: their own).
struct TrafficStats {
  std::uint64_t messages = 0;       ///< point-to-point messages sent and received by this rank
  std::uint64_t bytes = 0;          ///< their payload bytes (headers included)
  std::uint64_t result_bytes = 0;   ///< of which packed results (WorkStage::pack output)
  std::uint64_t batches = 0;        ///< batches computed by this rank
  std::uint64_t items = 0;          ///< items computed by this rank
};

/// The MPI WorkDistributor: a master/worker queue on MPI_COMM_WORLD. Created by Session (which
/// owns MPI's lifetime); not copyable. Every rank must call run()/sum_to_root() in the same order.
class QueueDistributor final : public WorkDistributor {
 public:
  /// `timeout_seconds`: the longest the root waits for a message from a rank that owes one (its
  /// first request, the results of a batch, a sum), and a worker for its next assignment, before
  /// it ends the job with "<prefix>: rank R sent nothing for T s" and MPI_Abort.
  /// `root_computes` = false makes rank 0 only serve the queue (a dedicated master, as on a
  /// cluster's login-node rank; tests use it to force every item through the messages).
  QueueDistributor(int rank, int size, double timeout_seconds, bool root_computes = true);
  [[nodiscard]] int size() const override { return size_; }
  [[nodiscard]] int rank() const override { return rank_; }
  /// The work queue of one stage (see the file comment). Throws std::runtime_error for a
  /// malformed message; rethrows an exception of the root's own compute thread.
  void run(const WorkStage& stage) override;
  /// Workers send their values to the root; the root adds them (uint64, exact).
  void sum_to_root(std::span<std::uint64_t> values) override;
  /// Traffic so far on this rank.
  [[nodiscard]] const TrafficStats& traffic() const { return traffic_; }
  /// The prefix of the root's fault messages ("rayscan render"), set by the CLI.
  void set_error_prefix(std::string prefix) { prefix_ = std::move(prefix); }
  [[nodiscard]] const std::string& error_prefix() const { return prefix_; }

  // Used by Session.
  /// Root: wait for every worker's bye (or failure). Workers: send the bye.
  void finish();
  /// Root: print `line`, remove the temporaries marked for removal (remove_marked_paths) and
  /// MPI_Abort(2). Never returns.
  [[noreturn]] void abort_with(const std::string& line) const;
  /// Root: a pending fail message from any worker -> abort_with; returns otherwise.
  void check_failures();
  /// Root: waits for one message with `tag` from every worker rank, calling `receive(source,
  /// bytes)` once a message is probed (the callback receives it with MPI_Recv); aborts naming the
  /// silent rank (`what`, e.g. "owing a sum") after the timeout, and on a rank's failure message.
  void receive_from_every_worker(int tag, const char* what, const std::function<void(int source, int bytes)>& receive);

 private:
  int rank_, size_;
  double timeout_;
  bool root_computes_;
  std::uint64_t seq_ = 0;  // collective operations so far: the stage number in messages and tags
  std::string prefix_ = "rayscan";
  TrafficStats traffic_;
};

}  // namespace rayscan::mpi
