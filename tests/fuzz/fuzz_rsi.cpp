// libFuzzer target for the index file (.rsi, docs/index-format.md): MappedIndex::open must either
// throw IndexError (one line) or return an index on which ray queries, kNN, radius search, the
// per-slot accessors, the surfel set-up and to_point_cloud() never read outside the mapping (ASan
// checks the mapping's bounds through the file copy below, which is exactly the mutated input's
// size). Anything else is a bug.
//
// CRC-32C fix-up: a mutated file almost never keeps valid section checksums, so the fuzzer would
// only ever exercise the CRC check. Like PNG fuzz harnesses, the target recomputes every section's
// CRC (for sections inside the input) and then the header CRC before opening (fix_index_crcs,
// tests/common/index_crcs.hpp, which the replay of the findings shares), so the structural
// checks behind the CRCs (section table, node ranges, sources) are what gets fuzzed; the first
// inputs whose size is 15 modulo 16 keep their checksums as they are (so the CRC path stays covered).
// Built and run by tests/fuzz/run.sh.
#include "../common/index_crcs.hpp"
#include "rayscan/octree/batch.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"


#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool keep_crcs = size % 16 == 15;  // 1 in 16 inputs: the raw checksums
  std::vector<std::uint8_t> b(data, data + size);
  if (!keep_crcs) rayscan::test::fix_index_crcs(b);

  static const std::string path = "/tmp/fuzz-rsi-" + std::to_string(::getpid()) + ".rsi";
  if (std::FILE* f = std::fopen(path.c_str(), "wb")) {
    const bool ok = b.empty() || std::fwrite(b.data(), 1, b.size(), f) == b.size();
    std::fclose(f);
    if (!ok) return 0;
  } else {
    return 0;
  }
  try {
    rayscan::io::IndexOpenOptions opt;
    // A third of the inputs open with every check (`info --verify`), a third as a large file
    // (node records checked, no CRCs or ids: the default above 256 MiB), a third with no record
    // checks at all (the node accessors must keep every query inside the mapping on their own).
    switch (size % 3) {
      case 0: opt.verify = rayscan::io::IndexOpenOptions::Verify::always; break;
      case 1: opt.deep_check_bytes = 0; break;
      default: opt.verify = rayscan::io::IndexOpenOptions::Verify::metadata_only; break;
    }
    opt.check_sources = false;  // the seeds name files of the machine that built them
    const rayscan::io::MappedIndex m = rayscan::io::MappedIndex::open(path, opt);
    if (m.empty()) return 0;
    rayscan::AABB box = m.node_bounds(m.root());
    // Unverified node bounds may be anything (NaN, inverted, huge): query arguments from a sane
    // box, so that an exception here is the library's and not the harness's.
    bool sane = true;
    for (int a = 0; a < 3; ++a)
      sane = sane && std::isfinite(box.lo[a]) && std::isfinite(box.hi[a]) && box.lo[a] <= box.hi[a] &&
             box.hi[a] - box.lo[a] < 1e12;
    if (!sane) box = rayscan::AABB{rayscan::Vec3(0.0), rayscan::Vec3(1.0)};
    const rayscan::Vec3 c = (box.lo + box.hi) * 0.5;
    std::vector<rayscan::Ray> rays;
    rays.emplace_back(box.lo - rayscan::Vec3(1.0), (box.hi - box.lo) + rayscan::Vec3(1e-3));
    rays.emplace_back(rayscan::Vec3(c.x, c.y, box.hi.z + 1.0), rayscan::Vec3(0.0, 0.0, -1.0));
    for (rayscan::RayOrder order : {rayscan::RayOrder::ray, rayscan::RayOrder::sphere_hit}) {
      rayscan::RayQuery q;
      q.order = order;
      q.radius = 0.05 * (box.hi.x - box.lo.x) + 1e-3;
      q.k = 8;
      (void)rayscan::ray_query_batch(m, rays, q);
    }
    (void)rayscan::knn(m, c, 5);
    (void)rayscan::radius_search(m, c, 0.1 * (box.hi.x - box.lo.x) + 1e-3);
    const rayscan::PointCloud pc = m.to_point_cloud();  // checks every id (IndexError) whether verified or not
    (void)m.points_per_level();
    for (std::size_t s = 0; s < m.positions().size() && s < 64; ++s) {  // the per-slot accessors
      (void)m.positions()[s];
      if (!m.rgb().empty()) (void)m.rgb()[s];
      (void)m.ids()[s];
    }
    // The surfel set-up (kNN of every point; a corrupted root once made it read past an empty
    // neighbour list): an error, never a crash. Only on opens that checked the node records, whose
    // work is bounded (without them a corrupted family can make the walk exponential).
    if (size % 3 != 2 && pc.size() >= 2 && pc.size() <= 4096) {
      try {
        (void)rayscan::estimate_surfels_over(m, std::span<const rayscan::Vec3>(pc.positions), rayscan::SurfelOptions{});
      } catch (const std::runtime_error& e) {
        if (std::string(e.what()).find("surfels:") == std::string::npos) throw;
      }
    }
  } catch (const rayscan::io::IndexError&) {
  }
  return 0;
}
