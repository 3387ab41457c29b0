#include "rayscan/sql/chunking.hpp"

#include "rayscan/octree/morton.hpp"

#include <algorithm>
#include <stdexcept>

namespace rayscan::sql {

ChunkLayout make_chunk_layout(std::span<const PointCloud* const> clouds, std::uint32_t chunk_size) {
  if (chunk_size == 0) throw std::invalid_argument("chunk size must be at least 1 point");
  AABB all;
  std::size_t n = 0;
  for (const PointCloud* c : clouds) {
    all.expand(c->bounds());
    n += c->size();
  }
  ChunkLayout out;
  if (n == 0) return out;
  // Grid of 2^21 cells per axis over the cube around the union bounds (as the octree's root cell).
  constexpr double kCells = double(1u << kMortonBits);
  const double ext = std::max(all.max_extent(), 1e-300);
  const double scale = kCells / ext;
  auto cell = [&](double v, double lo) {
    const double f = (v - lo) * scale;
    if (!(f >= 0.0)) return std::uint32_t{0};
    if (f >= kCells - 1) return std::uint32_t((1u << kMortonBits) - 1);
    return static_cast<std::uint32_t>(f);
  };
  struct Keyed {
    std::uint64_t code;
    PointRef ref;
  };
  std::vector<Keyed> keyed;
  keyed.reserve(n);
  for (std::uint32_t s = 0; s < clouds.size(); ++s) {
    const auto& pos = clouds[s]->positions;
    for (std::uint64_t i = 0; i < pos.size(); ++i) {
      const Vec3& p = pos[i];
      keyed.push_back({morton_encode(cell(p.x, all.lo.x), cell(p.y, all.lo.y), cell(p.z, all.lo.z)),
                       {s, i}});
    }
  }
  std::sort(keyed.begin(), keyed.end(), [](const Keyed& a, const Keyed& b) {
    if (a.code != b.code) return a.code < b.code;
    if (a.ref.source != b.ref.source) return a.ref.source < b.ref.source;
    return a.ref.index < b.ref.index;
  });
  out.order.reserve(n);
  for (const Keyed& k : keyed) out.order.push_back(k.ref);
  keyed = {};
  for (std::uint64_t first = 0; first < n; first += chunk_size) {
    Chunk c;
    c.first = first;
    c.count = static_cast<std::uint32_t>(std::min<std::uint64_t>(chunk_size, n - first));
    for (std::uint64_t r = first; r < first + c.count; ++r)
      c.box.expand(clouds[out.order[r].source]->positions[out.order[r].index]);
    out.chunks.push_back(c);
  }
  return out;
}

}  // namespace rayscan::sql
