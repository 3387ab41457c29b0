#include "rayscan/octree/any_index.hpp"

#include <stdexcept>

namespace rayscan {

std::uint32_t index_capacity(const IndexOptions& opts) {
  if (opts.capacity) return *opts.capacity;
  if (opts.type.rfind("octree-", 0) == 0) return default_capacity(parse_octree_layout(opts.type.substr(7)));
  if (opts.type == "kdtree") return kDefaultKdTreeLeaf;
  return 0;
}

AnyIndex make_index(std::span<const Vec3> positions, const IndexOptions& opts) {
  const std::string& t = opts.type;
  if (t.rfind("octree-", 0) == 0) {
    OctreeConfig c = OctreeConfig::for_layout(parse_octree_layout(t.substr(7)));
    c.capacity = opts.capacity.value_or(c.capacity);  // (index_capacity, without parsing the layout again)
    c.depth = opts.depth;
    c.max_depth = opts.max_depth;
    return opts.insertion ? Octree::build_by_insertion(positions, c)
                          : Octree::build_bulk(positions, c);
  }
  if (t == "kdtree") return KdTree(positions, index_capacity(opts));
  if (t == "brute") return BruteForceIndex(positions);
  throw std::invalid_argument("index type '" + t +
                              "': expected octree-adaptive, octree-layered, octree-fixed, kdtree or "
                              "brute");
}

std::size_t index_memory_bytes(const AnyIndex& index) {
  return std::visit([](const auto& i) { return i.memory_bytes(); }, index);
}

}  // namespace rayscan
