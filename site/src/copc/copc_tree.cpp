// build_tree(): the root cube and the distribution of the points over the COPC octree, see
// copc_build.hpp. COPC 1.0 leaves the choice of a node's points to the writer ("each node holds
// a subset of the points of its subtree"); as untwine and PDAL's writers.copc do, a node keeps
// one point per cell of a grid over its cube (here the one nearest the cell centre; 64^3 cells,
// kCopcGridCells, where they use 128^3: why in copc_writer.hpp) and its children hold the rest,
// so each level is a subsample whose spacing halves per level and the info VLR's spacing (root
// edge / kCopcGridCells) is the root's.
#include "copc_build.hpp"

#include "bytes.hpp"
#include "rayscan/octree/morton.hpp"
#include "rayscan/octree/position_view.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace rayscan::io::copc {

namespace {

using detail::load_le;

constexpr int kBits = static_cast<int>(kMortonBits);  // 21 bits per axis
static_assert(kCopcMaxLevel + kCopcGridBits < kBits, "a level's grid cells must be resolved by the Morton bits");

/// Morton order, ties by record index (function objects, so that the sorts inline them).
struct MortonLess {
  bool operator()(const Slot& a, const Slot& b) const {
    const std::uint64_t ka = a.key, kb = b.key;
    return ka != kb ? ka < kb : a.index < b.index;
  }
};

/// Builds the subtree of the node at `level` with cell (x, y, z) over the Morton-sorted
/// slots [a, b); returns its nodes in pre-order with `begin` relative to `pts`. Reorders the
/// range: the node's own points first, the rest in Morton order (the writer orders each node's
/// records itself).
class Builder {
 public:
  Builder(std::vector<Slot>& pts, std::uint32_t leaf_points) : pts_(pts), leaf_(leaf_points) {}

  std::vector<Node> build(int level, std::uint32_t x, std::uint32_t y, std::uint32_t z, std::size_t a, std::size_t b) const {
    Node n;
    n.level = level;
    n.x = static_cast<std::int32_t>(x);
    n.y = static_cast<std::int32_t>(y);
    n.z = static_cast<std::int32_t>(z);
    n.begin = a;
    if (b - a <= leaf_ || level == kCopcMaxLevel) {
      n.count = static_cast<std::uint32_t>(b - a);
      return {n};
    }
    const std::size_t m = select(level, a, b);
    n.count = static_cast<std::uint32_t>(m);
    // Children: the rest [a + m, b) is in Morton order, so each child digit is a contiguous run.
    const int shift = 3 * (kBits - level - 1);
    std::array<std::size_t, 9> cut{};
    cut[0] = a + m;
    for (unsigned c = 0; c < 8; ++c) {
      const auto first = pts_.begin() + static_cast<std::ptrdiff_t>(cut[c]);
      const auto last = pts_.begin() + static_cast<std::ptrdiff_t>(b);
      cut[c + 1] = static_cast<std::size_t>(
          std::partition_point(first, last, [&](const Slot& p) { return ((p.key >> shift) & 7u) <= c; }) - pts_.begin());
    }
    std::array<std::vector<Node>, 8> kids;
    const auto child = [&](unsigned c) {
      if (cut[c + 1] == cut[c]) return;
      kids[c] = build(level + 1, 2 * x + (c & 1u), 2 * y + ((c >> 1) & 1u), 2 * z + ((c >> 2) & 1u), cut[c], cut[c + 1]);
    };
    if (b - a > (std::size_t{1} << 18)) {
      tbb::task_group g;
      for (unsigned c = 0; c < 8; ++c) g.run([&child, c] { child(c); });
      g.wait();
    } else {
      for (unsigned c = 0; c < 8; ++c) child(c);
    }
    std::vector<Node> out{n};
    for (std::vector<Node>& k : kids) out.insert(out.end(), k.begin(), k.end());
    return out;
  }

 private:
  /// Keeps in [a, b) the point nearest each cell centre of the node's grid (kCopcGridCells per
  /// axis; cells are the Morton prefixes kCopcGridBits levels down, contiguous runs of the sorted range; distances in Morton
  /// grid units, ties to the first in Morton order) and moves them to the front; the others keep
  /// their Morton order behind them. Returns their number.
  std::size_t select(int level, std::size_t a, std::size_t b) const {
    const int sub = kBits - level - kCopcGridBits;  // bits per axis below a cell: >= 1, as level < kCopcMaxLevel
    const int shift = 3 * sub;
    const std::int64_t half = std::int64_t{1} << sub;  // cell edge in grid units x 2 / 2
    std::vector<std::size_t> keep;
    std::size_t i = a;
    while (i < b) {
      const std::uint64_t cell = pts_[i].key >> shift;
      std::size_t best = i;
      std::int64_t best_d = std::numeric_limits<std::int64_t>::max();
      for (; i < b && (pts_[i].key >> shift) == cell; ++i) {
        // offset from the cell centre, doubled so the centre is an integer: 2 * low - edge
        const std::uint64_t low = pts_[i].key & ((std::uint64_t{1} << shift) - 1);
        const auto dx = 2 * static_cast<std::int64_t>(morton_compact(low)) - half;
        const auto dy = 2 * static_cast<std::int64_t>(morton_compact(low >> 1)) - half;
        const auto dz = 2 * static_cast<std::int64_t>(morton_compact(low >> 2)) - half;
        const std::int64_t dd = dx * dx + dy * dy + dz * dz;
        if (dd < best_d) best_d = dd, best = i;
      }
      keep.push_back(best);
    }
    // Pack the rest at the back (walking down keeps their order), then the kept at the front.
    std::vector<Slot> kept;
    kept.reserve(keep.size());
    for (std::size_t k : keep) kept.push_back(pts_[k]);
    std::size_t w = b, next = keep.size();
    for (std::size_t j = b; j-- > a;) {
      if (next > 0 && keep[next - 1] == j) {
        --next;
        continue;
      }
      pts_[--w] = pts_[j];
    }
    std::copy(kept.begin(), kept.end(), pts_.begin() + static_cast<std::ptrdiff_t>(a));
    return kept.size();
  }

  std::vector<Slot>& pts_;
  std::uint32_t leaf_;
};

}  // namespace

RecordStats record_stats(const Records& r) {
  const std::size_t rec = r.record_length;
  const std::uint8_t* d = r.bytes;
  struct Acc {
    RecordStats s;
    double tmin = std::numeric_limits<double>::infinity(), tmax = -std::numeric_limits<double>::infinity();
  };
  const Acc acc = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, static_cast<std::size_t>(r.count), 1 << 16), Acc{},
      [&](const tbb::blocked_range<std::size_t>& br, Acc a) {
        for (std::size_t i = br.begin(); i != br.end(); ++i) {
          const std::uint8_t* p = d + i * rec;
          for (int k = 0; k < 3; ++k) {
            const auto v = load_le<std::int32_t>(p + 4 * k);
            a.s.lo[k] = std::min(a.s.lo[k], v);
            a.s.hi[k] = std::max(a.s.hi[k], v);
          }
          const double t = load_le<double>(p + 22);
          if (t < a.tmin) a.tmin = t;  // (NaN times compare false: left out)
          if (t > a.tmax) a.tmax = t;
          const unsigned ret = p[14] & 15u;
          if (ret >= 1) ++a.s.by_return[ret - 1];
        }
        return a;
      },
      [](Acc a, const Acc& b) {
        for (int k = 0; k < 3; ++k) a.s.lo[k] = std::min(a.s.lo[k], b.s.lo[k]), a.s.hi[k] = std::max(a.s.hi[k], b.s.hi[k]);
        a.tmin = std::min(a.tmin, b.tmin);
        a.tmax = std::max(a.tmax, b.tmax);
        for (int k = 0; k < 15; ++k) a.s.by_return[k] += b.s.by_return[k];
        return a;
      });
  RecordStats s = acc.s;
  if (acc.tmin <= acc.tmax) s.gps_min = acc.tmin, s.gps_max = acc.tmax;
  return s;
}

Tree build_tree(const Records& r, const CopcWriteOptions& opt) {
  const std::size_t rec = r.record_length;
  const std::size_t n = static_cast<std::size_t>(r.count);
  const std::uint8_t* d = r.bytes;
  Tree t;
  t.stats = record_stats(r);
  // Bounds of the integer coordinates in file units (a negative scale swaps the ends).
  const std::int32_t* lo = t.stats.lo;
  const std::int32_t* hi = t.stats.hi;
  Vec3 wlo, whi;
  for (int k = 0; k < 3; ++k) {
    const double u = las_coordinate(lo[k], r.scale[k], r.offset[k]), v = las_coordinate(hi[k], r.scale[k], r.offset[k]);
    wlo[k] = std::min(u, v);
    whi[k] = std::max(u, v);
  }
  t.cube.center = (wlo + whi) * 0.5;
  double half = 0.5 * std::max({whi.x - wlo.x, whi.y - wlo.y, whi.z - wlo.z});
  // a single point (or one repeated) still needs a cube of positive size
  half = std::max(half, 0.5 * std::max({std::abs(r.scale.x), std::abs(r.scale.y), std::abs(r.scale.z)}));
  t.cube.halfsize = half;
  const Vec3 clo = t.cube.lo();
  const double cells = std::ldexp(1.0, kBits);
  const double to_grid = cells / (2.0 * half);

  std::vector<Slot> pts(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 16), [&](const tbb::blocked_range<std::size_t>& br) {
    for (std::size_t i = br.begin(); i != br.end(); ++i) {
      std::uint32_t g[3];
      for (int k = 0; k < 3; ++k) {
        const double w = las_coordinate(load_le<std::int32_t>(d + i * rec + 4 * k), r.scale[k], r.offset[k]);
        const double c = std::floor((w - clo[k]) * to_grid);
        g[k] = static_cast<std::uint32_t>(std::clamp(c, 0.0, cells - 1));
      }
      pts[i] = Slot{morton_encode(g[0], g[1], g[2]), static_cast<std::uint32_t>(i)};
    }
  });
  tbb::parallel_sort(pts.begin(), pts.end(), MortonLess{});
  if (opt.progress) opt.progress("tree", 0, r.count);
  const Builder b(pts, std::max<std::uint32_t>(1, opt.leaf_points));
  t.nodes = b.build(0, 0, 0, 0, 0, n);
  t.slots = std::move(pts);
  if (opt.progress) opt.progress("tree", r.count, r.count);
  return t;
}

}  // namespace rayscan::io::copc
