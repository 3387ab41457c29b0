// libFuzzer target for the COPC info VLR and hierarchy walk (cycles, offsets, keys) followed by
// decoding every node's chunk, then the same bytes opened in place (io::CopcIndex, from a file:
// it maps its input) and walked through the SpatialIndex interface, every node decoded with its
// ancestors and its points pushed down, plus position_of and one ray query: FormatError or
// success, nothing else. Built by run.sh.
#include "rayscan/site/copc.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace {

// The in-place index over the input, walked whole (bounded: at most 4096 handles).
void walk_in_place(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("rayscan-fuzz-copc-" + std::to_string(::getpid()) + ".copc.laz");
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  rayscan::io::CopcIndex idx(file, std::size_t{64} << 20);
  if (idx.empty()) return;
  std::vector<rayscan::io::CopcIndex::Node> todo{idx.root()};
  std::size_t seen = 0;
  while (!todo.empty() && seen < 4096) {
    const rayscan::io::CopcIndex::Node n = todo.back();
    todo.pop_back();
    ++seen;
    const rayscan::SlotRange s = idx.node_points(n);
    for (std::uint32_t k = s.begin; k < s.end; ++k) (void)idx.positions()[k];
    for (unsigned c = 0; c < idx.child_count(n); ++c) todo.push_back(idx.child(n, c));
  }
  const std::uint64_t count = idx.info().point_count;
  if (count > 0) {
    (void)idx.position_of(0);
    (void)idx.position_of(static_cast<rayscan::PointIndex>(count - 1));
  }
  const rayscan::AABB b = idx.node_bounds(idx.root());
  std::vector<rayscan::RayHit> hits;
  rayscan::RayQuery q;
  q.k = 4;
  q.radius = b.max_extent() / 16 + 1e-9;
  rayscan::ray_query(idx, rayscan::Ray(b.lo - rayscan::Vec3(1.0), rayscan::Vec3(1.0, 1.0, 1.0)), q, hits);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const rayscan::io::CopcInfo c = rayscan::io::read_copc_info({data, size}, "fuzz-input");
    (void)c;
    (void)rayscan::io::read_las_records({data, size}, "fuzz-input", rayscan::io::las_layers::z);
    walk_in_place(data, size);
  } catch (const rayscan::io::FormatError&) {
  }
  return 0;
}
