// print_copc_summary(): see copc_summary.hpp.
#include "copc_summary.hpp"

#include <cstdio>
#include <iostream>

namespace rayscan::cli {

void print_copc_summary(const std::string& command, const std::string& out, const io::CopcWriteResult& r, bool quiet) {
  if (!quiet)
    for (const std::string& n : r.notes) std::cerr << command << ": note: " << n << "\n";
  std::printf("%s: %llu points, COPC 1.0 (PDRF %d, %u bytes/record), %llu nodes, depth %d, %llu hierarchy pages, "
              "%llu bytes (input %llu bytes)\n",
              out.c_str(), static_cast<unsigned long long>(r.points), r.pdrf, static_cast<unsigned>(r.record_length),
              static_cast<unsigned long long>(r.nodes), r.depth, static_cast<unsigned long long>(r.pages),
              static_cast<unsigned long long>(r.out_bytes), static_cast<unsigned long long>(r.in_bytes));
  for (std::size_t l = 0; l < r.nodes_per_level.size(); ++l)
    std::printf("  level %zu: %llu nodes, %llu points\n", l, static_cast<unsigned long long>(r.nodes_per_level[l]),
                static_cast<unsigned long long>(r.points_per_level[l]));
  std::fflush(stdout);
}

}  // namespace rayscan::cli
