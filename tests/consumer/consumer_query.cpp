// Links rayscan::octree from an installed package and runs a ray query (paper Algorithm 1) on a
// small grid, checking the answer against brute force over the same points. Exit 0 = correct.
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <cstdio>
#include <vector>

int main() {
  using namespace rayscan;
  std::vector<Vec3> pts;
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 20; ++y) pts.emplace_back(x, y, 0.1 * ((x * 7 + y * 3) % 5));
  const AnyIndex index = make_index(pts, IndexOptions{});
  const BruteForceIndex brute(pts);
  RayQuery q;
  q.k = 5;
  q.radius = 0.75;
  q.order = RayOrder::sphere_hit;
  const Ray ray(Vec3(-1.0, 5.2, 0.1), Vec3(1.0, 0.05, 0.0));
  std::vector<RayHit> a, b;
  std::visit([&](const auto& idx) { ray_query(idx, ray, q, a); }, index);
  ray_query(brute, ray, q, b);
  if (a.empty() || a.size() != b.size()) {
    std::fprintf(stderr, "consumer: %zu hits from the octree, %zu from brute force\n", a.size(), b.size());
    return 1;
  }
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].index != b[i].index) {
      std::fprintf(stderr, "consumer: hit %zu is point %u, brute force says %u\n", i, a[i].index, b[i].index);
      return 1;
    }
  std::printf("consumer: %zu hits, first point %u at t = %.6f (matches brute force)\n", a.size(), a[0].index, a[0].t);
  return 0;
}
