// Links rayscan::mpi from an installed package (find_package(rayscan COMPONENTS mpi)) and runs one
// work-queue stage: items [0, 64) each compute item * item + 1; the root checks that it holds
// every item's value (the oracle: the formula) and that the ranks' item counts sum to 64. Run
// alone (one process, no distributor) and under `mpirun -n 2`. Exit 0 = correct.
#include "rayscan/mpi/session.hpp"

#include <cstdint>
#include <cstdio>
#include <span>
#include <vector>

int main(int argc, char** argv) {
  rayscan::mpi::Session session(argc, argv, 60.0);
  constexpr std::uint64_t n = 64;
  std::vector<std::uint64_t> value(n, 0);
  std::uint64_t mine[1] = {0};
  rayscan::WorkStage stage;
  stage.items = n;
  stage.compute = [&](std::uint64_t first, std::uint64_t count) {
    for (std::uint64_t i = first; i < first + count; ++i) value[i] = i * i + 1;
    mine[0] += count;
  };
  stage.pack = [&](std::uint64_t first, std::uint64_t count) {
    std::vector<std::byte> out;
    rayscan::append_bytes(out, std::span<const std::uint64_t>(value.data() + first, count));
    return out;
  };
  stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
    std::size_t off = 0;
    rayscan::read_values(bytes, off, std::span<std::uint64_t>(value.data() + first, count));
  };
  if (rayscan::mpi::QueueDistributor* q = session.distributor()) {
    q->run(stage);
    q->sum_to_root(mine);
  } else {
    stage.compute(0, n);
  }
  int bad = 0;
  if (session.is_root()) {
    for (std::uint64_t i = 0; i < n; ++i) bad += value[i] != i * i + 1;
    if (mine[0] != n) ++bad;
    std::printf("consumer_mpi: %d rank(s), %d wrong\n", session.size(), bad);
  }
  session.finish();
  return bad ? 1 : 0;
}
