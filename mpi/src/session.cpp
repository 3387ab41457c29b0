// The MPI session of a `rayscan` run (rayscan/mpi/session.hpp).
#include "rayscan/mpi/session.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace rayscan::mpi {

bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (const char* s = std::getenv(v); s && *s) return true;
  return false;
}

Session::Session(int& argc, char**& argv, double timeout_seconds) : timeout_(timeout_seconds) {
  if (const char* t = std::getenv("RAYSCAN_MPI_TIMEOUT"); t && *t) {
    char* end = nullptr;
    const double v = std::strtod(t, &end);
    if (end == t || *end || !(v > 0.0))
      throw std::runtime_error(std::string("RAYSCAN_MPI_TIMEOUT '") + t + "': expected a number of seconds > 0");
    timeout_ = v;
  }
  if (!launched_by_mpi()) return;
  int provided = 0;
  if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
    throw std::runtime_error("MPI_Init_thread failed");
  initialised_ = true;
  if (provided < MPI_THREAD_FUNNELED) {
    MPI_Finalize();
    initialised_ = false;
    throw std::runtime_error("MPI does not provide MPI_THREAD_FUNNELED");
  }
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  const char* rc = std::getenv("RAYSCAN_MPI_ROOT_COMPUTES");
  const bool root_computes = !(rc && std::string(rc) == "0");
  if (size_ > 1) queue_ = std::make_unique<QueueDistributor>(rank_, size_, timeout_, root_computes);
}

Session::~Session() {
  if (initialised_) MPI_Finalize();
}

namespace {

constexpr int kTagStart = 3;  // a worker's start outcome text for rank 0 (work_queue.cpp uses 1, 2, >= 16)

void print_outcome(const std::string& out, const std::string& err) {
  std::fwrite(out.data(), 1, out.size(), stdout);
  std::fflush(stdout);
  if (!err.empty()) std::fprintf(stderr, "%s\n", err.c_str());
  std::fflush(stderr);
}

// Receives one string with `tag` from `source` (length from MPI_Probe).
std::string recv_text(int source, int tag) {
  MPI_Status st;
  MPI_Probe(source, tag, MPI_COMM_WORLD, &st);
  int n = 0;
  MPI_Get_count(&st, MPI_CHAR, &n);
  std::string text(std::size_t(std::max(n, 0)), '\0');
  MPI_Recv(text.data(), n, MPI_CHAR, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return text;
}

}  // namespace

std::optional<int> Session::agree_on_start(const StartOutcome& mine) {
  if (!queue_) {
    if (!mine.end) return std::nullopt;
    print_outcome(mine.out, mine.err);
    return mine.code;
  }
  // Every rank's (strength, code): 0 go on, 1 help/version, 2 usage error. Non-blocking so that a
  // rank that never gets here ends the job after the timeout instead of hanging it.
  const int strength = !mine.end ? 0 : (mine.code == 0 ? 1 : 2);
  const int own[2] = {strength, mine.code};
  std::vector<int> all(2 * std::size_t(size_));
  MPI_Request rq;
  MPI_Iallgather(own, 2, MPI_INT, all.data(), 2, MPI_INT, MPI_COMM_WORLD, &rq);
  const auto t0 = std::chrono::steady_clock::now();
  for (int done = 0;;) {
    MPI_Test(&rq, &done, MPI_STATUS_IGNORE);
    if (done) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > timeout_) {
      char b[160];
      std::snprintf(b, sizeof b, "rayscan: rank %d of %d: another rank did not start within %.0f s "
                    "(RAYSCAN_MPI_TIMEOUT)", rank_, size_, timeout_);
      queue_->abort_with(b);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  int who = 0;
  for (int r = 1; r < size_; ++r)
    if (all[2 * std::size_t(r)] > all[2 * std::size_t(who)]) who = r;
  if (all[2 * std::size_t(who)] == 0) return std::nullopt;
  const int code = all[2 * std::size_t(who) + 1];
  if (who == 0) {
    if (rank_ == 0) print_outcome(mine.out, mine.err);
    return code;
  }
  // A worker's outcome (MPMD launches with different arguments per rank): rank 0 prints it.
  if (rank_ == who) {
    MPI_Send(mine.out.data(), int(mine.out.size()), MPI_CHAR, 0, kTagStart, MPI_COMM_WORLD);
    MPI_Send(mine.err.data(), int(mine.err.size()), MPI_CHAR, 0, kTagStart, MPI_COMM_WORLD);
  } else if (rank_ == 0) {
    const std::string out = recv_text(who, kTagStart);
    std::string err = recv_text(who, kTagStart);
    if (!err.empty()) err += " (rank " + std::to_string(who) + " of " + std::to_string(size_) + ")";
    print_outcome(out, err);
  }
  return code;
}

void Session::finish() {
  if (queue_) queue_->finish();
}

void Session::fail(const std::string& line) {
  if (!queue_) {
    std::fprintf(stderr, "%s\n", line.c_str());
    return;
  }
  if (rank_ == 0) queue_->abort_with(line);
  // Worker: the root prints the line (one line per job) and aborts every rank.
  MPI_Send(line.data(), int(line.size()), MPI_CHAR, 0, 1 /* kTagFail */, MPI_COMM_WORLD);
  const double wait = std::min(timeout_, 60.0);
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  queue_->abort_with(line + " (rank " + std::to_string(rank_) + " of " + std::to_string(size_) +
                     "; rank 0 did not end the job)");
}

}  // namespace rayscan::mpi
