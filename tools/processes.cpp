// The process group of a `rayscan` run (processes.hpp); the MPI session itself lives in main().
#include "processes.hpp"

#include "commands.hpp"

#ifdef RAYSCAN_HAVE_MPI
#include "rayscan/mpi/session.hpp"
#endif

#include <cstdio>

namespace rayscan::cli {

#ifdef RAYSCAN_HAVE_MPI
mpi::Session* g_session = nullptr;  // set by main()
WorkDistributor* distributor() { return g_session ? g_session->distributor() : nullptr; }
bool is_root() { return !g_session || g_session->is_root(); }
int process_count() { return g_session ? g_session->size() : 1; }
void set_command_name(const std::string& name) {
  if (g_session && g_session->distributor()) g_session->distributor()->set_error_prefix(name);
}
std::string traffic_summary() {
  if (!g_session || !g_session->distributor() || !g_session->is_root()) return "";
  const mpi::TrafficStats& t = g_session->distributor()->traffic();
  char b[256];
  std::snprintf(b, sizeof b, "mpi: %d ranks, %llu messages, %llu bytes (%llu bytes of results), rank 0 computed %llu items",
                g_session->size(), (unsigned long long)t.messages, (unsigned long long)t.bytes,
                (unsigned long long)t.result_bytes, (unsigned long long)t.items);
  return b;
}
#else
std::string traffic_summary() { return ""; }
WorkDistributor* distributor() { return nullptr; }
bool is_root() { return true; }
int process_count() { return 1; }
void set_command_name(const std::string&) {}
#endif

void require_single_process(const std::string& command) {
  if (process_count() > 1)
    throw UsageError("runs in one process; only render, visibility, solar and query run under mpirun -n " +
                     std::to_string(process_count()) + " (run '" + command + "' without mpirun or with -n 1)");
}

}  // namespace rayscan::cli
