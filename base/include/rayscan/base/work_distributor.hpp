// Work distribution over processes: the hook through which a job's parallel stage --
// the render's image tiles, the visibility's point chunks, the query's ray blocks, the frames of
// an animation -- is spread over several processes (MPI ranks) instead of the threads of one.
// The jobs only see this interface; rayscan::mpi (mpi/, docs/mpi.md) implements it with a dynamic
// work queue over Open MPI, so the renderer, analysis and io libraries do not depend on MPI.
//
// Model (the master/worker task farm of OSPRay's MPI offload device and of IceT's tile renderers):
// every process runs the same job on the same inputs (the same index file, mapped by each); one
// stage's items [0, n) are handed out in small batches; each process computes its items into
// its own full-size buffers; non-root processes pack the results of each batch into bytes that
// the root unpacks into its buffers. Because every item's result depends only on the item (pixel
// samples are seeded by (pixel, sample, seed), visibility by the point), the root's buffers are
// bit-identical to a single-process run whatever the split.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace rayscan {

/// One parallel stage of a job, as handed to WorkDistributor::run(). Items are indices [0, items).
struct WorkStage {
  std::uint64_t items = 0;  ///< number of work items (tiles, point chunks, ray blocks, frames)
  /// Items per request a process asks for (>= 1), e.g. its thread count so that one batch keeps
  /// every thread of the rank busy; the distributor may hand out fewer near the end.
  std::uint64_t batch = 1;
  /// Computes items [first, first + count) into this process's own buffers (using TBB inside).
  /// On the root it is called from a worker thread, concurrently with `unpack`, which always
  /// touches other items. Must be set.
  std::function<void(std::uint64_t first, std::uint64_t count)> compute;
  /// Non-root processes: the results of items [first, first + count), just computed, as bytes
  /// (native byte order; the ranks of one job run the same binary on the same architecture).
  std::function<std::vector<std::byte>(std::uint64_t first, std::uint64_t count)> pack;
  /// Root: stores the results of items [first, first + count) computed elsewhere (`bytes` as
  /// produced by `pack`). Throws std::runtime_error when the size is not the expected one.
  std::function<void(std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes)> unpack;
};

/// Spreads the stages of a job over processes. Every process of the job must make the same
/// sequence of collective calls (run, sum_to_root) with the same item counts. Implemented by
/// rayscan::mpi::QueueDistributor (mpi/include/rayscan/mpi/work_queue.hpp); a job given none
/// (JobControl::distributor == nullptr) runs every item itself.
class WorkDistributor {
 public:
  virtual ~WorkDistributor() = default;
  /// Number of processes taking part (>= 1).
  [[nodiscard]] virtual int size() const = 0;
  /// This process's number in [0, size()); 0 is the root.
  [[nodiscard]] virtual int rank() const = 0;
  /// True on the process that gathers the results and writes the outputs (rank 0).
  [[nodiscard]] bool is_root() const { return rank() == 0; }
  /// Collective: runs the stage. Returns when every item has been computed somewhere and, on the
  /// root, unpacked. Throws std::runtime_error on a protocol error; a failed or silent process
  /// ends the whole job (see rayscan::mpi, faults).
  virtual void run(const WorkStage& stage) = 0;
  /// Collective: element-wise sum of `values` over all processes, left in `values` on the root
  /// (other processes keep their own values). Sums of integers, so exact and order-free.
  virtual void sum_to_root(std::span<std::uint64_t> values) = 0;
};

/// Packs trivially copyable values into a byte buffer (WorkStage::pack helpers).
template <class T>
void append_bytes(std::vector<std::byte>& out, std::span<const T> values) {
  const auto* p = reinterpret_cast<const std::byte*>(values.data());
  out.insert(out.end(), p, p + values.size_bytes());
}

/// Reads `values.size()` trivially copyable values from `bytes` at `offset` and advances it.
/// Throws std::runtime_error when the buffer is too short.
void read_bytes(std::span<const std::byte> bytes, std::size_t& offset, std::span<std::byte> values);

/// Typed form of read_bytes().
template <class T>
void read_values(std::span<const std::byte> bytes, std::size_t& offset, std::span<T> values) {
  read_bytes(bytes, offset, std::as_writable_bytes(values));
}

}  // namespace rayscan
