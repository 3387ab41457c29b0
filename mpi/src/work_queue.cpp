// The MPI work queue (rayscan/mpi/work_queue.hpp).
#include "rayscan/mpi/work_queue.hpp"

#include "rayscan/base/interrupt.hpp"

#include <mpi.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace rayscan::mpi {

namespace {

constexpr int kTagFail = 1;
constexpr int kTagBye = 2;
// Tags of collective operation `seq` (MPI guarantees tags up to at least 32767).
constexpr int op_tag(std::uint64_t seq, int kind) { return 16 + int(seq % 4096) * 4 + kind; }
constexpr int kRequest = 0, kAssign = 1, kSum = 2;

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Sleep between polls: short against a tile's milliseconds, long enough not to steal a core.
void nap() { std::this_thread::sleep_for(std::chrono::microseconds(50)); }

// The master's poll interval backs off while no request arrives (50, 100, 200, 400 µs), and starts
// again at 50 µs after each request. A fixed 50 µs made ~18,000 wake-ups and probes per second,
// which on a 2-core machine took ~10% of the core that rank 0's compute thread needs (bench/mpi.sh:
// 2 ranks x 1 thread were 1.11x the wall of 1 rank x 2 threads; see bench/README.md).
void nap_backoff(unsigned& idle) {
  std::this_thread::sleep_for(std::chrono::microseconds(50u << idle));
  if (idle < 3) ++idle;
}

std::string silent_message(const std::string& prefix, int rank, int size, double timeout, const char* what) {
  char b[256];
  std::snprintf(b, sizeof b, ": rank %d of %d sent nothing for %.0f s while %s (dead, hung, or slower than "
                "RAYSCAN_MPI_TIMEOUT)", rank, size, timeout, what);
  return prefix + b;
}

}  // namespace

QueueDistributor::QueueDistributor(int rank, int size, double timeout_seconds, bool root_computes)
    : rank_(rank), size_(size), timeout_(timeout_seconds), root_computes_(root_computes) {}

void QueueDistributor::abort_with(const std::string& line) const {
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
  // MPI_Abort ends the process without unwinding, so no owner removes its temporary (rank 0's
  // output, opened before the stages): remove every marked one now.
  remove_marked_paths();
  MPI_Abort(MPI_COMM_WORLD, 2);
  std::abort();  // MPI_Abort does not return; keep the compiler and a broken MPI honest
}

void QueueDistributor::check_failures() {
  int flag = 0;
  MPI_Status st;
  MPI_Iprobe(MPI_ANY_SOURCE, kTagFail, MPI_COMM_WORLD, &flag, &st);
  if (!flag) return;
  int n = 0;
  MPI_Get_count(&st, MPI_CHAR, &n);
  std::string text(std::size_t(std::max(n, 0)), '\0');
  MPI_Recv(text.data(), n, MPI_CHAR, st.MPI_SOURCE, kTagFail, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  abort_with(text + " (rank " + std::to_string(st.MPI_SOURCE) + " of " + std::to_string(size_) + ")");
}

void QueueDistributor::run(const WorkStage& stage) {
  const std::uint64_t seq = seq_++;
  const int treq = op_tag(seq, kRequest), tassign = op_tag(seq, kAssign);
  const std::uint64_t want = std::max<std::uint64_t>(1, stage.batch);

  if (rank_ != 0) {
    // Worker: request, compute, return the results with the next request.
    std::vector<std::byte> msg(4 * sizeof(std::uint64_t));
    std::uint64_t head[4] = {seq, 0, 0, want};
    std::memcpy(msg.data(), head, sizeof head);
    for (;;) {
      MPI_Send(msg.data(), int(msg.size()), MPI_BYTE, 0, treq, MPI_COMM_WORLD);
      ++traffic_.messages;
      traffic_.bytes += msg.size();
      std::uint64_t a[3] = {0, 0, 0};
      MPI_Request rq;
      MPI_Irecv(a, int(sizeof a), MPI_BYTE, 0, tassign, MPI_COMM_WORLD, &rq);
      const auto t0 = Clock::now();
      for (int done = 0;;) {
        MPI_Test(&rq, &done, MPI_STATUS_IGNORE);
        if (done) break;
        if (seconds_since(t0) > timeout_) {
          char b[200];
          std::snprintf(b, sizeof b, ": rank %d of %d: rank 0 sent no work for %.0f s (dead or hung)", rank_, size_,
                        timeout_);
          abort_with(prefix_ + b);
        }
        nap();
      }
      ++traffic_.messages;
      traffic_.bytes += sizeof a;
      if (a[0] != seq) throw std::runtime_error("MPI work queue: assignment for stage " + std::to_string(a[0]) +
                                                " during stage " + std::to_string(seq));
      if (a[2] == 0) return;
      stage.compute(a[1], a[2]);
      ++traffic_.batches;
      traffic_.items += a[2];
      const std::vector<std::byte> res = stage.pack(a[1], a[2]);
      traffic_.result_bytes += res.size();
      head[1] = a[1];
      head[2] = a[2];
      msg.resize(sizeof head);
      std::memcpy(msg.data(), head, sizeof head);
      msg.insert(msg.end(), res.begin(), res.end());
      if (msg.size() > std::size_t(std::numeric_limits<int>::max()))
        throw std::runtime_error("MPI work queue: a result message of " + std::to_string(msg.size()) +
                                 " bytes exceeds MPI's 2 GiB message limit (fewer AOVs, or tiles instead of whole frames)");
    }
  }

  // Root: a compute thread takes batches like any worker; this thread serves the requests.
  std::mutex mu;
  std::uint64_t next = 0;
  auto take = [&](std::uint64_t n, std::uint64_t& first) {
    std::lock_guard lock(mu);
    first = next;
    const std::uint64_t c = std::min(n, stage.items - next);
    next += c;
    return c;
  };
  std::atomic<bool> local_done{false};
  std::atomic<std::uint64_t> local_batches{0}, local_items{0};
  std::exception_ptr local_error;
  std::thread local([&] {
    try {
      while (root_computes_) {
        std::uint64_t f = 0;
        const std::uint64_t c = take(want, f);
        if (c == 0) break;
        stage.compute(f, c);
        ++local_batches;
        local_items += c;
      }
    } catch (...) {
      local_error = std::current_exception();
    }
    local_done = true;
  });
  auto stop_local = [&] {
    {
      std::lock_guard lock(mu);
      next = stage.items;
    }
    local.join();
  };
  try {
    int open = size_ - 1;
    std::vector<Clock::time_point> heard(std::size_t(size_), Clock::now());
    std::vector<char> finished(std::size_t(size_), 0);
    std::vector<std::byte> buf;
    unsigned idle = 0;  // polls without a request since the last one (nap_backoff)
    while (open > 0 || !local_done) {
      if (local_done && local_error) break;
      check_failures();
      int flag = 0;
      MPI_Status st;
      MPI_Iprobe(MPI_ANY_SOURCE, treq, MPI_COMM_WORLD, &flag, &st);
      if (!flag) {
        for (int r = 1; r < size_; ++r)
          if (!finished[std::size_t(r)] && seconds_since(heard[std::size_t(r)]) > timeout_)
            abort_with(silent_message(prefix_, r, size_, timeout_, "owing work-queue results"));
        nap_backoff(idle);
        continue;
      }
      idle = 0;
      int n = 0;
      MPI_Get_count(&st, MPI_BYTE, &n);
      buf.resize(std::size_t(std::max(n, 0)));
      const int src = st.MPI_SOURCE;
      MPI_Recv(buf.data(), n, MPI_BYTE, src, treq, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      ++traffic_.messages;
      traffic_.bytes += buf.size();
      heard[std::size_t(src)] = Clock::now();
      std::uint64_t head[4];
      if (buf.size() < sizeof head) throw std::runtime_error("MPI work queue: short request from rank " + std::to_string(src));
      std::memcpy(head, buf.data(), sizeof head);
      if (head[0] != seq || head[1] > stage.items || head[2] > stage.items - head[1])
        throw std::runtime_error("MPI work queue: bad request from rank " + std::to_string(src));
      // The next batch is assigned before the results are unpacked, so that the worker computes it
      // while the root stores these (the query's unpack renders them as CSV text, which would
      // otherwise hold the worker for as long).
      std::uint64_t a[3] = {seq, 0, 0};
      a[2] = take(std::max<std::uint64_t>(1, head[3]), a[1]);
      MPI_Send(a, int(sizeof a), MPI_BYTE, src, tassign, MPI_COMM_WORLD);
      ++traffic_.messages;
      traffic_.bytes += sizeof a;
      if (a[2] == 0) {
        finished[std::size_t(src)] = 1;
        --open;
      }
      if (head[2] > 0) {
        traffic_.result_bytes += buf.size() - sizeof head;
        stage.unpack(head[1], head[2], std::span<const std::byte>(buf).subspan(sizeof head));
      }
    }
  } catch (...) {
    stop_local();
    throw;
  }
  local.join();
  traffic_.batches += local_batches;
  traffic_.items += local_items;
  if (local_error) std::rethrow_exception(local_error);
}

void QueueDistributor::sum_to_root(std::span<std::uint64_t> values) {
  const std::uint64_t seq = seq_++;
  const int tag = op_tag(seq, kSum);
  std::vector<std::uint64_t> msg(values.size() + 1);
  if (rank_ != 0) {
    msg[0] = seq;
    std::copy(values.begin(), values.end(), msg.begin() + 1);
    MPI_Send(msg.data(), int(msg.size() * sizeof(std::uint64_t)), MPI_BYTE, 0, tag, MPI_COMM_WORLD);
    ++traffic_.messages;
    traffic_.bytes += msg.size() * sizeof(std::uint64_t);
    return;
  }
  receive_from_every_worker(tag, "owing a sum", [&](int source, int n) {
    if (n != int(msg.size() * sizeof(std::uint64_t)))
      throw std::runtime_error("MPI work queue: sum of the wrong size from rank " + std::to_string(source));
    MPI_Recv(msg.data(), n, MPI_BYTE, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    ++traffic_.messages;
    traffic_.bytes += std::size_t(n);
    for (std::size_t k = 0; k < values.size(); ++k) values[k] += msg[k + 1];
  });
}

void QueueDistributor::receive_from_every_worker(int tag, const char* what,
                                                 const std::function<void(int source, int bytes)>& receive) {
  std::vector<char> got(std::size_t(size_), 0);
  const auto t0 = Clock::now();
  for (int received = 0; received < size_ - 1;) {
    check_failures();
    int flag = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, tag, MPI_COMM_WORLD, &flag, &st);
    if (!flag) {
      if (seconds_since(t0) > timeout_)
        for (int r = 1; r < size_; ++r)
          if (!got[std::size_t(r)]) abort_with(silent_message(prefix_, r, size_, timeout_, what));
      nap();
      continue;
    }
    int n = 0;
    MPI_Get_count(&st, MPI_BYTE, &n);
    receive(st.MPI_SOURCE, n);
    got[std::size_t(st.MPI_SOURCE)] = 1;
    ++received;
  }
}

void QueueDistributor::finish() {
  std::uint64_t seq = seq_;
  if (rank_ != 0) {
    MPI_Send(&seq, int(sizeof seq), MPI_BYTE, 0, kTagBye, MPI_COMM_WORLD);
    return;
  }
  receive_from_every_worker(kTagBye, "finishing", [&](int source, int) {
    std::uint64_t s = 0;
    MPI_Recv(&s, int(sizeof s), MPI_BYTE, source, kTagBye, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (s != seq)
      abort_with(prefix_ + ": rank " + std::to_string(source) + " ran " + std::to_string(s) +
                 " collective steps, rank 0 ran " + std::to_string(seq) + " (the ranks ran different jobs)");
  });
}

}  // namespace rayscan::mpi
