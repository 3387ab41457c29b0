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
