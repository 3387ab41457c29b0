// The index file (index_file.hpp): the external-memory build (several sorted runs, several input
// tiles) gives the node array, slot order and ids of Octree::build_bulk over the concatenated
// points, and the mmap'd index answers ray, kNN, radius, box and batch queries exactly like the
// in-memory octree and the brute-force oracle. Bad files: truncated, corrupted, wrong version,
// changed source, each a one-line IndexError naming the file.
#include "../io/io_test_util.hpp"
#include "../common/entry_search_guard.hpp"

#include "rayscan/octree/batch.hpp"
#include "rayscan/octree/brute_force.hpp"
#include "rayscan/base/crc32c.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_reader.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/spacing.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>

namespace rayscan::test {
namespace {

/// Writes positions as a headerless float64 file (.f64, read exactly by the f64 reader).
void write_f64(const fs::path& p, std::span<const Vec3> pts) {
  std::ofstream f(p, std::ios::binary);
  f.write(reinterpret_cast<const char*>(pts.data()), static_cast<std::streamsize>(pts.size() * sizeof(Vec3)));
}

/// Clustered points with exact duplicates (the adaptive duplicate guard) and a far outlier.
std::vector<Vec3> make_points(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> p;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 97 == 5 && !p.empty()) {
      p.push_back(p[i / 2]);
      continue;
    }
    const double c = (i % 3) * 40.0;
    p.emplace_back(4.0e5 + c + 5 * g(rng), 5.2e6 + 10 * u(rng), 100 + g(rng));
  }
  p.emplace_back(4.0e5 + 900, 5.2e6 - 300, 150);
  return p;
}

struct Site {
  fs::path dir, index;
  std::vector<Vec3> all;
};

/// Three tiles of make_points whose positions the index stores as `enc` (docs/index-format.md
/// "Positions"): float64 (.f64 tiles of doubles), float32 (.f64 tiles of float-exact doubles),
/// las_int32 (LAS tiles on one 1 mm grid; `all` is then what the LAS reader returns for them).
Site build_site(const std::string& name, OctreeConfig cfg, std::uint64_t memory,
                PositionEncoding enc = PositionEncoding::float64, bool ids = true) {
  Site s;
  s.dir = temp_dir() / name;
  fs::create_directories(s.dir);
  std::vector<fs::path> tiles;
  for (unsigned t = 0; t < 3; ++t) {
    auto pts = make_points(9000 + 1000 * t, 7 + t);
    if (enc == PositionEncoding::las_int32) {
      PointCloud c;
      c.positions = pts;
      io::LasWriteOptions lo;
      lo.scale = Vec3(0.001);
      lo.offset = Vec3(4.0e5, 5.2e6, 0.0);
      lo.has_offset = true;
      tiles.push_back(s.dir / ("tile" + std::to_string(t) + ".las"));
      io::write_las(tiles.back(), c, lo);
      pts = io::read_point_cloud(tiles.back()).positions;
    } else {
      if (enc == PositionEncoding::float32)
        for (Vec3& p : pts)
          for (int a = 0; a < 3; ++a) {
            const float f = static_cast<float>(p[a]);
            p[a] = static_cast<double>(f);
          }
      tiles.push_back(s.dir / ("tile" + std::to_string(t) + ".f64"));
      write_f64(tiles.back(), pts);
    }
    s.all.insert(s.all.end(), pts.begin(), pts.end());
  }
  s.index = s.dir / "site.rsi";
  io::IndexBuildOptions o;
  o.config = cfg;
  o.memory_bytes = memory;
  if (ids) o.attributes.add(io::Attribute::id);
  const io::IndexBuildStats st = io::build_index_file(tiles, s.index, o);
  EXPECT_EQ(io::MappedIndex::open(s.index).has_ids(), ids);
  EXPECT_EQ(st.points, s.all.size());
  EXPECT_EQ(io::MappedIndex::open(s.index).position_encoding(), enc);

  if (memory < (1u << 21)) {
    EXPECT_GT(st.runs, 1u);  // the merge of several runs is exercised
  } else {
    EXPECT_EQ(st.runs, 1u);  // everything fits: sorted and written from memory, no merge
  }
  return s;
}

/// The Warren & Salmon id of every node of a mapped index, derived as the format defines it
/// (IndexNodeRecord: the root is 1, a child is its parent's id times 8 plus its octant; parents
/// come before their children), to compare with Octree::node_id.
std::vector<std::uint64_t> mapped_node_keys(const io::MappedIndex& m) {
  std::vector<std::uint64_t> k(m.node_count(), 0);
  if (!k.empty()) k[0] = 1;
  for (std::uint32_t n = 0; n < m.node_count(); ++n)
    for (unsigned i = 0; i < m.child_count(n); ++i) k[m.child(n, i)] = (k[n] << 3) | m.node_octant(m.child(n, i));
  return k;
}

// The mapped index takes the SIMD child test of the ray and point queries, as the octree does.
static_assert(detail::FloatChildBoxes<io::MappedIndex>);

void expect_same_tree(const io::MappedIndex& m, const Octree& t) {
  ASSERT_EQ(m.node_count(), t.node_count());
  ASSERT_EQ(m.depth(), t.depth());
  EXPECT_TRUE(m.root_cell().lo == t.root_cell().lo && m.root_cell().hi == t.root_cell().hi);
  const std::vector<std::uint64_t> keys = mapped_node_keys(m);
  for (std::uint32_t n = 0; n < t.node_count(); ++n) {
    ASSERT_EQ(keys[n], t.node_id(n).bits()) << n;
    ASSERT_EQ(m.child_count(n), t.child_count(n)) << n;
    if (t.child_count(n)) {
      ASSERT_EQ(m.child(n, 0), t.child(n, 0)) << n;
    }
    // The same slots (an internal node holds none; the file does not keep where its empty range
    // would begin, the octree does: compare the ranges as sets).
    ASSERT_EQ(m.node_points(n).size(), t.node_points(n).size()) << n;
    if (t.node_points(n).size() > 0) {
      ASSERT_EQ(m.node_points(n).begin, t.node_points(n).begin) << n;
      ASSERT_EQ(m.node_points(n).end, t.node_points(n).end) << n;
    }
    const AABB a = m.node_bounds(n), b = t.node_bounds(n);
    ASSERT_TRUE(a.lo == b.lo && a.hi == b.hi) << n;  // bit-identical bounds
    // The SIMD child test's float boxes (FloatChildBoxes): the same floats and count (the stride
    // is each record's: 8 floats in the file, 12 in the octree; the kernels need >= 8).
    const simd::ChildBoxesF fm = m.child_boxes_f(n), ft = t.child_boxes_f(n);
    ASSERT_EQ(fm.count, ft.count) << n;
    ASSERT_GE(fm.stride, 8u) << n;
    for (unsigned c = 0; c < ft.count; ++c)
      ASSERT_EQ(0, std::memcmp(fm.base + c * fm.stride, ft.base + c * ft.stride, 6 * sizeof(float))) << n;
  }
  EXPECT_TRUE(m.float_origin() == t.float_origin());
  EXPECT_EQ(m.float_extent(), t.float_extent());
  // The entry grids (the entry-point search): built at open from the records, the octree's cells.
  const EntryGrid gm = m.entry_grid(), gt = t.entry_grid();
  ASSERT_EQ(gm.depth, gt.depth);
  ASSERT_EQ(gm.cells == nullptr, gt.cells == nullptr);
  EXPECT_TRUE(gm.quant.lo == gt.quant.lo);
  EXPECT_EQ(gm.quant.scale, gt.quant.scale);
  EXPECT_EQ(gm.side, gt.side);
  EXPECT_EQ(gm.first_hits, gt.first_hits);
  if (gt.cells != nullptr)
    for (std::size_t c = 0; c < EntryGrid::slot(gt.depth + 1, 0, 0, 0); ++c) {
      ASSERT_EQ(gm.cells[c].node, gt.cells[c].node) << "cell " << c;
      ASSERT_EQ(gm.cells[c].depth, gt.cells[c].depth) << "cell " << c;
    }
  ASSERT_EQ(m.positions().size(), t.positions().size());
  for (std::size_t i = 0; i < t.positions().size(); ++i) {  // decoded bit for bit
    const Vec3 a = m.positions()[i];
    ASSERT_EQ(0, std::memcmp(&a, &t.positions()[i], sizeof(Vec3))) << "slot " << i;
  }
  ASSERT_EQ(m.ids().size(), t.ids().size());
  for (std::size_t i = 0; i < t.ids().size(); ++i) ASSERT_EQ(m.ids()[i], t.ids()[i]) << "slot " << i;
}

/// The positions of an index by slot (an index without ids reports its points in this order).
std::vector<Vec3> slot_positions(const io::MappedIndex& m) {
  std::vector<Vec3> out(m.positions().size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = m.positions()[i];
  return out;
}

bool same_hits(const std::vector<RayHit>& a, const std::vector<RayHit>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].index != b[i].index || a[i].t != b[i].t || a[i].distance != b[i].distance || a[i].key != b[i].key)
      return false;
  return true;
}

/// Layout, the memory budget: 1 MiB (several sorted runs and the k-way merge) or 64 MiB (one
/// run: the in-memory sort writes the sections directly), the positions encoding, and whether the
/// ids section is stored (without it the index's original order is its slot order: the oracles
/// are then the in-memory octree and brute force over the points in slot order, whose ids are the
/// identity, and the original-order octree's answers mapped through its ids).
class IndexFile : public ::testing::TestWithParam<std::tuple<OctreeLayout, std::uint64_t, PositionEncoding, bool>> {};

TEST_P(IndexFile, ExternalBuildEqualsInMemoryOctreeAndQueriesEqualBruteForce) {
  OctreeConfig cfg;
  cfg.layout = std::get<0>(GetParam());
  cfg.capacity = 16;
  cfg.depth = 5;
  const std::uint64_t memory = std::get<1>(GetParam());
  const PositionEncoding enc = std::get<2>(GetParam());
  const bool with_ids = std::get<3>(GetParam());
  const Site s = build_site(std::string("site_") + to_string(cfg.layout) + "_" + std::to_string(memory) + "_" +
                                std::to_string(static_cast<int>(enc)) + (with_ids ? "_ids" : "_noids"),
                            cfg, memory, enc, with_ids);
  const io::MappedIndex m = io::MappedIndex::open(s.index);
  const Octree t_orig = Octree::build_bulk(s.all, cfg);
  // The reported order: the original one with ids, the slot order without (then m.ids() is the
  // identity and the octree over the slot-ordered points is the same tree with identity ids).
  const std::vector<Vec3> order = with_ids ? s.all : slot_positions(m);
  EXPECT_EQ(m.ids().is_identity(), !with_ids);
  const Octree t = Octree::build_bulk(order, cfg);
  expect_same_tree(m, t);
  if (!with_ids) {  // the same nodes as the original-order tree, which maps slots to ids
    for (std::size_t i = 0; i < t.ids().size(); ++i) ASSERT_EQ(t.ids()[i], i);
    for (std::size_t i = 0; i < order.size(); ++i)
      ASSERT_EQ(0, std::memcmp(&order[i], &s.all[t_orig.ids()[i]], sizeof(Vec3))) << "slot " << i;
  }
  const BruteForceIndex bf(order);

  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Ray> rays;
  for (int i = 0; i < 60; ++i) {
    const Vec3 o(4.0e5 - 50 + 10 * u(rng), 5.2e6 + 5 + 20 * u(rng), 100 + 5 * u(rng));
    rays.emplace_back(o, Vec3(1.0, 0.1 * u(rng), 0.05 * u(rng)));
  }
  std::size_t hits = 0;
  for (RayOrder order : {RayOrder::ray, RayOrder::time, RayOrder::sphere_hit}) {
    RayQuery q;
    q.order = order;
    q.radius = 0.5;
    q.k = order == RayOrder::time ? kAllPoints : 8;
    const auto mb = ray_query_batch(m, rays, q), tb = ray_query_batch(t, rays, q), bb = ray_query_batch(bf, rays, q);
    const auto ob = ray_query_batch(t_orig, rays, q);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      EXPECT_TRUE(same_hits(mb[i], tb[i])) << "ray " << i;
      EXPECT_TRUE(same_hits(mb[i], bb[i])) << "ray " << i;
      // The same points as the original-order octree: its hit indices are the slots' ids.
      ASSERT_EQ(mb[i].size(), ob[i].size()) << "ray " << i;
      std::multiset<PointIndex> got, want;
      for (std::size_t j = 0; j < mb[i].size(); ++j) {
        got.insert(with_ids ? mb[i][j].index : t_orig.ids()[mb[i][j].index]);
        want.insert(ob[i][j].index);
      }
      EXPECT_TRUE(got == want) << "ray " << i;
      hits += mb[i].size();
    }
  }
  EXPECT_GT(hits, 500u);  // the comparison is not vacuous
  {
    // First hits: the file's entry grid (built at open) starts them at the node of the cell where
    // each ray enters (forced: these clustered sites' grids are not for first hits, so by default
    // they start at the root); the same answers as without it and as brute force, with fewer
    // nodes.
    RayQuery q;
    q.order = RayOrder::sphere_hit;
    q.radius = 0.5;
    q.k = 1;
    const EntrySearchGuard guard;
    RayQueryStats on, off;
    std::size_t first_hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      set_entry_point_search(EntryPointSearch::always);
      const auto a = ray_first_hit(m, rays[i], q, &on);
      set_entry_point_search(false);
      const auto b = ray_first_hit(m, rays[i], q, &off);
      const auto c = ray_first_hit(bf, rays[i], q);
      ASSERT_EQ(a.has_value(), c.has_value()) << "ray " << i;
      ASSERT_EQ(b.has_value(), c.has_value()) << "ray " << i;
      if (!c) continue;
      ++first_hits;
      EXPECT_TRUE(a->index == c->index && a->t == c->t) << "ray " << i;
      EXPECT_TRUE(b->index == c->index && b->t == c->t) << "ray " << i;
    }
    EXPECT_GT(first_hits, 10u);  // (about a third of the 60 rays hit a sphere)
    if (cfg.layout == OctreeLayout::adaptive) {  // (the fixed layout's 5 levels: the grid is 4 deep)
      ASSERT_NE(m.entry_grid().cells, nullptr);
      EXPECT_FALSE(m.entry_grid().first_hits);  // (three clusters: most cells empty)
      EXPECT_LT(on.nodes_visited, off.nodes_visited);
    }
  }
  for (int i = 0; i < 40; ++i) {
    const Vec3 q = order[static_cast<std::size_t>(i) * 613 % order.size()] + Vec3(0.01 * u(rng));
    const auto a = knn(m, q, 10), b = knn(bf, q, 10);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t j = 0; j < a.size(); ++j) EXPECT_TRUE(a[j].index == b[j].index && a[j].distance == b[j].distance);
    const auto ra = radius_search(m, q, 0.7), rb = radius_search(bf, q, 0.7);
    ASSERT_EQ(ra.size(), rb.size());
    for (std::size_t j = 0; j < ra.size(); ++j) EXPECT_EQ(ra[j].index, rb[j].index);
    // Box range: the in-memory tree's answer in its order (the same walk over the same nodes),
    // and brute force's set.
    AABB qb;
    qb.expand(q + Vec3(2.0 * u(rng), 2.0 * u(rng), u(rng)));
    qb.expand(order[static_cast<std::size_t>(i) * 977 % order.size()]);
    std::vector<PointIndex> bm, bt, bb;
    box_query(m, qb, bm);
    box_query(t, qb, bt);
    box_query(bf, qb, bb);
    EXPECT_EQ(bm, bt) << "box " << i;
    std::sort(bm.begin(), bm.end());
    std::sort(bb.begin(), bb.end());
    EXPECT_EQ(bm, bb) << "box " << i;
  }
  // Original order back from the ids: exactly the concatenated tiles (slot order without ids).
  const PointCloud back = m.to_point_cloud();
  ASSERT_EQ(back.size(), order.size());
  EXPECT_EQ(0, std::memcmp(back.positions.data(), order.data(), order.size() * sizeof(Vec3)));
  ASSERT_EQ(m.sources().size(), 3u);
  EXPECT_EQ(m.sources()[1].first_id, 9001u);
  // Stored at build time: the auto radius (the renderer's own function, the same value bit for
  // bit) and the exact point bounds.
  EXPECT_GT(m.median_nn_spacing(), 0.0);
  EXPECT_EQ(m.median_nn_spacing(), median_nn_spacing_by_id(m));
  EXPECT_EQ(m.median_nn_spacing(), median_nn_spacing_of(t, std::span<const Vec3>(order)));
  const AABB bb = bounds_of(s.all);
  EXPECT_TRUE(m.bounds().lo == bb.lo && m.bounds().hi == bb.hi);
  EXPECT_TRUE(m.verified());  // small file: every section and record checked at open
  std::vector<std::uint64_t> levels(t.depth() + 1, 0);
  for (std::uint32_t n = 0; n < t.node_count(); ++n)
    levels[t.node_id(n).depth()] += t.node_points(n).end - t.node_points(n).begin;
  EXPECT_EQ(m.points_per_level(), levels);  // stored in the header
  fs::remove_all(s.dir);
}

INSTANTIATE_TEST_SUITE_P(Layouts, IndexFile,
                         ::testing::Values(
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{1} << 20, PositionEncoding::float64, true),
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{64} << 20, PositionEncoding::float64, true),
                             std::make_tuple(OctreeLayout::fixed, std::uint64_t{1} << 20, PositionEncoding::float64, true),
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{1} << 20, PositionEncoding::las_int32, true),
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{64} << 20, PositionEncoding::las_int32, true),
                             std::make_tuple(OctreeLayout::fixed, std::uint64_t{64} << 20, PositionEncoding::float32, true),
                             // without the ids section: slot order, the identity ids
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{1} << 20, PositionEncoding::float64, false),
                             std::make_tuple(OctreeLayout::adaptive, std::uint64_t{64} << 20, PositionEncoding::las_int32, false),
                             std::make_tuple(OctreeLayout::fixed, std::uint64_t{1} << 20, PositionEncoding::las_int32, false)));

TEST(IndexFileBuild, LasAttributesAreStoredExactlyBySlot) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "las_site";
  fs::create_directories(dir);
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id,rgb,intensity,classification,gps_time");
  o.memory_bytes = 4 << 20;
  const fs::path out = dir / "autzen.rsi";
  const auto st = io::build_index_file({p}, out, o);
  const io::MappedIndex m = io::MappedIndex::open(out);
  const PointCloud src = io::read_point_cloud(p);
  ASSERT_EQ(m.positions().size(), src.size());
  EXPECT_EQ(m.position_encoding(), PositionEncoding::las_int32);  // 12 bytes per point
  for (std::size_t k = 0; k < src.size(); ++k) {  // decoded by slot = the reader's value by id
    const Vec3 a = m.positions()[k];
    ASSERT_EQ(0, std::memcmp(&a, &src.positions[m.ids()[k]], sizeof(Vec3))) << "slot " << k;
  }
  EXPECT_EQ(m.attributes(), st.attributes);
  EXPECT_EQ(m.crs_wkt(), src.crs_wkt);
  const PointCloud back = m.to_point_cloud();
  EXPECT_EQ(0, std::memcmp(back.positions.data(), src.positions.data(), src.size() * sizeof(Vec3)));
  EXPECT_TRUE(back.rgb == src.rgb);
  EXPECT_TRUE(back.intensity == src.intensity);
  EXPECT_TRUE(back.classification == src.classification);
  EXPECT_TRUE(back.gps_time == src.gps_time);
  expect_same_tree(m, Octree::build_bulk(src.positions, OctreeConfig{}));
  fs::remove_all(dir);
}

// Sort runs store a position as the LAS int32 grid values while every point read so far lies on
// the sources' grid, and as float64 after that (docs/index-format.md "Build"). Two LAS tiles of
// autzen on different scales (0.01 and 0.001): the first tile's runs are grid runs, the second
// tile makes the grid impossible, so its runs hold float64 and the file stores float64. With a
// 1 MiB budget (several runs of each kind) the file equals, byte for byte, the one-run build of
// the same tiles, every position decodes to the reader's value of its id, the attributes follow
// their points, and the tree is build_bulk's over the concatenated points.
TEST(IndexFileBuild, GridRunsThenFloatRunsGiveTheOneRunFile) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "mixed_runs";
  fs::create_directories(dir);
  const PointCloud src = io::read_point_cloud(p);
  const std::size_t half = src.size() / 2;
  auto tile = [&](std::size_t b, std::size_t e, double scale, const fs::path& out) {
    PointCloud c;
    c.crs_wkt = src.crs_wkt;
    c.positions.assign(src.positions.begin() + static_cast<std::ptrdiff_t>(b), src.positions.begin() + static_cast<std::ptrdiff_t>(e));
    c.rgb.assign(src.rgb.begin() + static_cast<std::ptrdiff_t>(b), src.rgb.begin() + static_cast<std::ptrdiff_t>(e));
    io::LasWriteOptions w;
    w.scale = Vec3(scale);
    io::write_las(out, c, w);
  };
  tile(0, half, 0.01, dir / "a.las");
  tile(half, src.size(), 0.001, dir / "b.las");
  const PointCloud a = io::read_point_cloud(dir / "a.las"), b = io::read_point_cloud(dir / "b.las");
  std::vector<Vec3> all = a.positions;
  all.insert(all.end(), b.positions.begin(), b.positions.end());
  std::vector<Rgb16> rgb = a.rgb;
  rgb.insert(rgb.end(), b.rgb.begin(), b.rgb.end());
  ASSERT_EQ(rgb.size(), all.size());
  auto build = [&](std::uint64_t memory, const fs::path& out) {
    io::IndexBuildOptions o;
    o.attributes = io::AttributeSet::parse("id,rgb");
    o.memory_bytes = memory;
    return io::build_index_file({dir / "a.las", dir / "b.las"}, out, o);
  };
  const auto one = build(std::uint64_t{64} << 20, dir / "one.rsi");
  const auto many = build(std::uint64_t{1} << 20, dir / "many.rsi");
  EXPECT_EQ(one.runs, 1u);
  EXPECT_GE(many.runs, 4u);
  EXPECT_TRUE(slurp(dir / "one.rsi") == slurp(dir / "many.rsi"));
  const io::MappedIndex m = io::MappedIndex::open(dir / "many.rsi");
  EXPECT_EQ(m.position_encoding(), PositionEncoding::float64);
  const PointCloud back = m.to_point_cloud();  // original order (ids stored)
  ASSERT_EQ(back.size(), all.size());
  EXPECT_EQ(0, std::memcmp(back.positions.data(), all.data(), all.size() * sizeof(Vec3)));
  EXPECT_TRUE(back.rgb == rgb);
  expect_same_tree(m, Octree::build_bulk(all, OctreeConfig{}));
  fs::remove_all(dir);
}

// A float source (PCD, float32 x y z): stored as float32 (12 bytes per point), decoded bit for
// bit to what read_point_cloud returns; queries equal brute force over the reader's positions.
TEST(IndexFileBuild, FloatSourceIsStoredAsFloat32Exactly) {
  RAYSCAN_REQUIRE_FILE(p, "pcd/cloud_bin_0.pcd");
  const fs::path dir = temp_dir() / "f32_site";
  fs::create_directories(dir);
  const fs::path out = dir / "c.rsi";
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id");
  io::build_index_file({p}, out, o);
  const io::MappedIndex m = io::MappedIndex::open(out);
  const PointCloud src = io::read_point_cloud(p);
  ASSERT_EQ(m.positions().size(), src.size());
  EXPECT_EQ(m.position_encoding(), PositionEncoding::float32);
  EXPECT_EQ(m.sections()[2].name, "positions");
  EXPECT_EQ(m.sections()[2].bytes, 12 * src.size());
  for (std::size_t k = 0; k < src.size(); ++k) {
    const Vec3 a = m.positions()[k];
    ASSERT_EQ(0, std::memcmp(&a, &src.positions[m.ids()[k]], sizeof(Vec3))) << "slot " << k;
  }
  const PointCloud back = m.to_point_cloud();
  EXPECT_EQ(0, std::memcmp(back.positions.data(), src.positions.data(), src.size() * sizeof(Vec3)));
  const BruteForceIndex bf(src.positions);
  const AABB b = bounds_of(src.positions);
  std::size_t hits = 0;
  for (int i = 0; i < 40; ++i) {
    const Vec3 o = b.center() + Vec3(-2.0 * b.max_extent(), 0.01 * (i - 20) * b.max_extent(), 0.005 * i * b.max_extent());
    const Ray ray(o, b.center() + Vec3(0.0, 0.02 * (20 - i) * b.max_extent(), 0.0) - o);
    RayQuery q;
    q.order = RayOrder::sphere_hit;
    q.radius = 0.01 * b.max_extent();
    q.k = 4;
    std::vector<RayHit> a, c;
    ray_query(m, ray, q, a);
    ray_query(bf, ray, q, c);
    EXPECT_TRUE(same_hits(a, c)) << "ray " << i;
    hits += a.size();
  }
  EXPECT_GT(hits, 20u);
  fs::remove_all(dir);
}

// The key sort's per-bucket LSD radix pass (buckets of 64 .. n/8 keys): 64 small clusters 100 m
// apart (one top-16-bit Morton bucket each), their points interleaved in input order and every
// 5th an exact duplicate of an earlier point of its cluster (equal codes: the tie is the id), in
// one run and in several; the oracle is build_bulk's tree, slot order and ids.
TEST(IndexFileBuild, ClusteredBucketsWithDuplicatesSortLikeBuildBulk) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<Vec3> pts;
  for (std::size_t i = 0; i < 16500; ++i) {
    const std::size_t c = i % 64;
    if (i % 5 == 4 && i >= 640) {
      pts.push_back(pts[i - 64 * (1 + i % 7)]);  // same cluster, earlier point
      continue;
    }
    pts.emplace_back(5.0e5 + 100.0 * static_cast<double>(c % 8) + u(rng),
                     4.0e6 + 100.0 * static_cast<double>(c / 8) + u(rng), 20.0 + u(rng));
  }
  const fs::path dir = temp_dir() / "clustered_buckets";
  fs::create_directories(dir);
  write_f64(dir / "c.f64", pts);
  const Octree t = Octree::build_bulk(pts, OctreeConfig{});
  for (const std::uint64_t memory : {std::uint64_t{64} << 20, std::uint64_t{1} << 20}) {
    SCOPED_TRACE(memory);
    io::IndexBuildOptions o;
    o.attributes = io::AttributeSet::parse("id");  // the ids are compared with build_bulk's
    o.memory_bytes = memory;
    const auto st = io::build_index_file({dir / "c.f64"}, dir / "c.rsi", o);
    EXPECT_EQ(st.runs, memory == (std::uint64_t{1} << 20) ? 2u : 1u);
    expect_same_tree(io::MappedIndex::open(dir / "c.rsi"), t);
  }
  fs::remove_all(dir);
}

// The merge cuts a window of the run buffers at the least last code S of the runs with more on
// disk; when every buffered code is S (a point repeated more often than a buffer holds), it takes
// the S records of the lowest run first (the (code, id) tie order). 48,000 points alternating
// between two positions, then a few others: with a 1 MiB budget each run holds thousands of copies
// of each, more than a read buffer, so the merge has windows with nothing below S. Oracle:
// build_bulk's slot order and ids.
TEST(IndexFileBuild, RunsOfOneRepeatedPointMergeInIdOrder) {
  std::vector<Vec3> pts;
  for (std::size_t i = 0; i < 48000; ++i) pts.push_back(i % 2 == 0 ? Vec3(10.0, 20.0, 30.0) : Vec3(11.0, 21.0, 31.0));
  for (std::size_t i = 0; i < 500; ++i) pts.emplace_back(10.0 + 0.002 * static_cast<double>(i), 20.5, 30.5);
  const fs::path dir = temp_dir() / "repeated_point";
  fs::create_directories(dir);
  write_f64(dir / "r.f64", pts);
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id");
  o.memory_bytes = std::uint64_t{1} << 20;
  const auto st = io::build_index_file({dir / "r.f64"}, dir / "r.rsi", o);
  EXPECT_GE(st.runs, 3u);
  expect_same_tree(io::MappedIndex::open(dir / "r.rsi"), Octree::build_bulk(pts, OctreeConfig{}));
  fs::remove_all(dir);
}

// The one-run build reports its "write" phase every 2^22 points and at its end: 300,000 points
// (past the first gather block of 2^18, short of 2^22) end with a report of (300000, 300000), as
// the several-run build's "merge" does. Oracle: the number of points written to the file.
TEST(IndexFileBuild, WriteAndMergePhasesEndWithTheirTotal) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 100.0);
  std::vector<Vec3> pts(300000);
  for (Vec3& p : pts) p = Vec3(u(rng), u(rng), u(rng));
  const fs::path dir = temp_dir() / "write_progress";
  fs::create_directories(dir);
  write_f64(dir / "w.f64", pts);
  for (const auto& [memory, phase_name] : {std::pair<std::uint64_t, std::string>{std::uint64_t{256} << 20, "write"},
                                           std::pair<std::uint64_t, std::string>{std::uint64_t{4} << 20, "merge"}}) {
    // A plain copy: C++20 lambdas may not capture a structured binding under Clang 14.
    const std::string phase = phase_name;
    SCOPED_TRACE(phase);
    std::vector<std::pair<std::uint64_t, std::uint64_t>> reports;
    io::IndexBuildOptions o;
    o.memory_bytes = memory;
    o.progress = [&](const char* ph, std::uint64_t done, std::uint64_t total) {
      if (ph == phase) reports.emplace_back(done, total);
    };
    const auto st = io::build_index_file({dir / "w.f64"}, dir / "w.rsi", o);
    EXPECT_EQ(st.runs > 1, phase == "merge");
    const std::uint64_t n = io::MappedIndex::open(dir / "w.rsi").positions().size();
    ASSERT_EQ(n, pts.size());
    ASSERT_FALSE(reports.empty());
    EXPECT_EQ(reports.back(), std::make_pair(n, n));
  }
  fs::remove_all(dir);
}

// The node records are written in place into a shared map of the output's nodes section that is
// extended (posix_fallocate + mremap) while the tree grows and released behind the depth-first
// pass, and the codes and positions maps are released behind it too: with capacity 1 the tree has
// more nodes than points (the first reservation is points / 8), and the 1 MiB budget releases
// every 2048 points. Oracle: Octree::build_bulk.
TEST(IndexFileBuild, GrowingNodeSectionAndReleasedMapsGiveTheBuildBulkTree) {
  const std::vector<Vec3> pts = make_points(30000, 21);
  const fs::path dir = temp_dir() / "growing_nodes";
  fs::create_directories(dir);
  write_f64(dir / "g.f64", pts);
  OctreeConfig cfg;
  cfg.capacity = 1;
  const Octree t = Octree::build_bulk(pts, cfg);
  ASSERT_GT(t.node_count(), pts.size());  // several extensions of the first reservation
  for (const std::uint64_t memory : {std::uint64_t{64} << 20, std::uint64_t{1} << 20}) {
    SCOPED_TRACE(memory);
    io::IndexBuildOptions o;
    o.attributes = io::AttributeSet::parse("id");  // the ids are compared with build_bulk's
    o.config = cfg;
    o.memory_bytes = memory;
    o.node_stage_pages = memory < (std::uint64_t{2} << 20) ? 1 : 1024;  // (see NodesBuiltInTheMerge...)
    const auto st = io::build_index_file({dir / "g.f64"}, dir / "g.rsi", o);
    EXPECT_EQ(st.nodes, t.node_count());
    const io::MappedIndex m = io::MappedIndex::open(dir / "g.rsi");
    EXPECT_TRUE(m.verified());  // the nodes section's CRC and every record checked at open
    expect_same_tree(m, t);
  }
  fs::remove_all(dir);
}

// A build in several runs builds the nodes during the merge when the read pass's points per cell
// decide the upper tree (uniform points), and from the written positions when they cannot (a
// dense cluster inside one cell, far outliers stretching the root cell): both give build_bulk's
// tree (the oracle), ids included, and a verified nodes section (its CRC is combined from pages
// written out of order, checked against the bytes at open).
TEST(IndexFileBuild, NodesBuiltInTheMergeOrAfterItGiveTheBuildBulkTree) {
  const fs::path dir = temp_dir() / "fused_nodes";
  fs::create_directories(dir);
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> uniform(200000), cluster;
  for (Vec3& q : uniform) q = Vec3(u(rng), u(rng), u(rng));
  cluster.push_back(Vec3(0.0));
  for (int i = 0; i < 200000; ++i) cluster.push_back(Vec3(0.5) + 1e-4 * Vec3(u(rng), u(rng), u(rng)));
  cluster.push_back(Vec3(1.0));
  for (const bool fused : {true, false}) {
    SCOPED_TRACE(fused ? "uniform: nodes in the merge" : "cluster: nodes after the merge");
    const std::vector<Vec3>& pts = fused ? uniform : cluster;
    write_f64(dir / "c.f64", pts);
    const Octree t = Octree::build_bulk(pts, OctreeConfig{});
    // The nodes section staged 4 MiB at a time (one stage here) and one page at a time (every
    // page boundary crossed: reserved blocks straddling it, pinned pages, the CRC of each page).
    for (const std::size_t stage : {std::size_t{1024}, std::size_t{1}}) {
      SCOPED_TRACE(stage);
      io::IndexBuildOptions o;
      o.attributes = io::AttributeSet::parse("id");
      o.memory_bytes = 4 << 20;
      o.node_stage_pages = stage;
      const auto st = io::build_index_file({dir / "c.f64"}, dir / "c.rsi", o);
      EXPECT_GT(st.runs, 1u);
      EXPECT_EQ(st.nodes_in_merge, fused);
      const io::MappedIndex m = io::MappedIndex::open(dir / "c.rsi");
      EXPECT_TRUE(m.verified());
      expect_same_tree(m, t);
      // The background read ahead of a render changes no answer (metadata-only checks: with the
      // deep checks open reads the whole file and starts no read ahead). The index is destroyed
      // while the thread may still run (its stop and join).
      io::IndexOpenOptions ra;
      ra.read_ahead = true;
      ra.verify = io::IndexOpenOptions::Verify::metadata_only;
      expect_same_tree(io::MappedIndex::open(dir / "c.rsi", ra), t);
    }
  }
  fs::remove_all(dir);
}

// A build in several runs takes the Morton grid from the LAS header's bounds (no bounds pass) and
// checks it against the points: a header whose max x lies (LAS 1.2 header byte 179) is detected
// and the read pass repeated on the exact grid, so the tree is still build_bulk's (the oracle:
// the in-memory octree of the reader's points, which never trusts the header's box).
TEST(IndexFileBuild, LyingLasHeaderBoundsAreCaughtAndTheTreeIsExact) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "las_lying_header";
  fs::create_directories(dir);
  const fs::path honest = dir / "honest.las", lying = dir / "lying.las";
  fs::copy_file(p, honest, fs::copy_options::overwrite_existing);
  auto bytes = slurp(p);
  double max_x = 0;
  std::memcpy(&max_x, bytes.data() + 179, 8);
  max_x += 100.0;
  std::memcpy(bytes.data() + 179, &max_x, 8);
  std::ofstream(lying, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  const PointCloud src = io::read_point_cloud(p);
  const Octree t = Octree::build_bulk(src.positions, OctreeConfig{});
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id");  // the ids are compared with build_bulk's
  o.memory_bytes = 2 << 20;  // several runs: the grid is needed before the points are read
  for (const fs::path& in : {honest, lying}) {
    SCOPED_TRACE(in.filename().string());
    const auto st = io::build_index_file({in}, dir / "x.rsi", o);
    EXPECT_GT(st.runs, 1u);
    const bool noted = std::any_of(st.notes.begin(), st.notes.end(),
                                   [](const std::string& n) { return n.find("headers' bounds differ") != std::string::npos; });
    if (in == lying) {
      EXPECT_TRUE(noted);  // (autzen's own header box is not the exact box of its points either)
    }
    expect_same_tree(io::MappedIndex::open(dir / "x.rsi"), t);
  }
  fs::remove_all(dir);
}

// LAZ input goes through the same chunked reader (LasReader decoding LAZ chunks on demand): the
// index of autzen_trim.laz equals the index of autzen_trim.las (the same records uncompressed;
// shared data README), node for node, and answers ray and kNN queries identically.
TEST(IndexFileBuild, LazInputGivesTheIndexOfTheSameLas) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(laz, "laz/autzen_trim.laz");
  const fs::path dir = temp_dir() / "laz_site";
  fs::create_directories(dir);
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id,rgb,intensity,classification,gps_time");
  o.memory_bytes = 4 << 20;  // several sorted runs
  const auto st_las = io::build_index_file({las}, dir / "las.rsi", o);
  const auto st_laz = io::build_index_file({laz}, dir / "laz.rsi", o);
  EXPECT_EQ(st_laz.points, st_las.points);
  EXPECT_EQ(st_laz.attributes, st_las.attributes);
  const io::MappedIndex a = io::MappedIndex::open(dir / "las.rsi"), b = io::MappedIndex::open(dir / "laz.rsi");
  ASSERT_GT(a.positions().size(), 10000u);
  ASSERT_EQ(a.node_count(), b.node_count());
  const std::vector<std::uint64_t> ka = mapped_node_keys(a), kb = mapped_node_keys(b);
  for (std::uint32_t n = 0; n < a.node_count(); ++n) {
    ASSERT_EQ(ka[n], kb[n]) << n;
    ASSERT_EQ(a.node_points(n).begin, b.node_points(n).begin) << n;
    ASSERT_EQ(a.node_points(n).end, b.node_points(n).end) << n;
  }
  ASSERT_EQ(a.positions().size(), b.positions().size());
  EXPECT_EQ(a.position_encoding(), PositionEncoding::las_int32);  // LAZ has the LAS grid too
  EXPECT_EQ(b.position_encoding(), PositionEncoding::las_int32);
  for (std::size_t i = 0; i < a.positions().size(); ++i) {
    const Vec3 pa = a.positions()[i], pb = b.positions()[i];
    ASSERT_EQ(0, std::memcmp(&pa, &pb, sizeof(Vec3))) << "slot " << i;
  }
  ASSERT_EQ(a.ids().size(), b.ids().size());
  ASSERT_EQ(a.rgb().size(), b.rgb().size());
  EXPECT_EQ(a.rgb().multiplier(), b.rgb().multiplier());
  for (std::size_t i = 0; i < a.ids().size(); ++i) {
    ASSERT_EQ(a.ids()[i], b.ids()[i]) << "slot " << i;
    ASSERT_EQ(a.rgb()[i], b.rgb()[i]) << "slot " << i;
  }
  EXPECT_TRUE(std::equal(a.intensity().begin(), a.intensity().end(), b.intensity().begin(), b.intensity().end()));
  EXPECT_TRUE(std::equal(a.gps_time().begin(), a.gps_time().end(), b.gps_time().begin(), b.gps_time().end()));
  EXPECT_TRUE(std::equal(a.classification().begin(), a.classification().end(), b.classification().begin(),
                         b.classification().end()));
  // Query results: rays from above aimed at stored points, and kNN around them.
  std::vector<Ray> rays;
  const auto pts = a.positions();
  for (std::size_t i = 0; i < 40; ++i) {
    const Vec3 target = pts[i * 7919 % pts.size()];
    rays.emplace_back(target + Vec3(3.0, 2.0, 50.0), Vec3(-3.0, -2.0, -50.0));
  }
  RayQuery q;
  q.radius = 1.0;
  q.k = 16;
  const auto ha = ray_query_batch(a, rays, q), hb = ray_query_batch(b, rays, q);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    EXPECT_TRUE(same_hits(ha[i], hb[i])) << "ray " << i;
    hits += ha[i].size();
  }
  EXPECT_GT(hits, 40u);  // not vacuous
  for (std::size_t i = 0; i < 20; ++i) {
    const Vec3 c = pts[i * 104729 % pts.size()];
    const auto ka = knn(a, c, 8), kb = knn(b, c, 8);
    ASSERT_EQ(ka.size(), kb.size());
    for (std::size_t j = 0; j < ka.size(); ++j) EXPECT_TRUE(ka[j].index == kb[j].index && ka[j].distance == kb[j].distance);
  }
  fs::remove_all(dir);
}

/// The rgb section an index holds ("rgb" 6 bytes or "rgb8" 3 bytes per point) and its size.
std::pair<std::string, std::uint64_t> rgb_section(const io::MappedIndex& m) {
  for (const io::IndexSectionInfo& x : m.sections())
    if (x.name == "rgb" || x.name == "rgb8") return {x.name, x.bytes};
  return {"", 0};
}

/// Builds `src` into `out` with `attributes` (plus `compact_rgb`) and checks every stored colour
/// bit for bit against read_point_cloud of the source (an independent oracle: the reader's own
/// values, looked up by the slot's id); returns the index.
io::MappedIndex expect_exact_rgb(const fs::path& src, const fs::path& out, bool compact_rgb = true) {
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id,rgb");
  o.compact_rgb = compact_rgb;
  o.memory_bytes = 1 << 20;  // several runs: the merge path encodes the colours too
  const io::IndexBuildStats st = io::build_index_file({src}, out, o);
  io::MappedIndex m = io::MappedIndex::open(out);
  const PointCloud pc = io::read_point_cloud(src);
  EXPECT_EQ(st.rgb_multiplier, m.rgb().multiplier());
  EXPECT_EQ(m.rgb().size(), pc.size());
  EXPECT_EQ(pc.rgb.size(), pc.size());
  for (std::size_t k = 0; k < m.rgb().size() && k < pc.rgb.size(); ++k)
    EXPECT_EQ(m.rgb()[k], pc.rgb[m.ids()[k]]) << src << " slot " << k;
  EXPECT_TRUE(m.to_point_cloud().rgb == pc.rgb);
  return m;
}

// Colour in 3 bytes per point when exact. autzen_trim.las holds 8-bit values (the
// reader delivers them scaled by 257), warsaw_small.las shifted into the high byte (x 256); a LAS
// written with true 16-bit colour (and one with 8-bit values plus a single 256: no multiplier
// fits all) keeps the 6-byte section. The decoded colours equal read_point_cloud's bit for bit.
TEST(IndexFileBuild, RgbIsStoredInThreeBytesWhenExactAndSixOtherwise) {
  RAYSCAN_REQUIRE_FILE(autzen, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(warsaw, "las/warsaw_small.las");
  const fs::path dir = temp_dir() / "rgb8";
  fs::create_directories(dir);
  {
    const io::MappedIndex m = expect_exact_rgb(autzen, dir / "autzen.rsi");
    EXPECT_EQ(m.rgb().multiplier(), 257u);
    EXPECT_EQ(rgb_section(m), std::make_pair(std::string("rgb8"), std::uint64_t{3} * m.positions().size()));
    // Without ids: the same colours by slot (the same tree).
    io::IndexBuildOptions o;
    o.attributes = io::AttributeSet::parse("rgb");
    io::build_index_file({autzen}, dir / "autzen_noids.rsi", o);
    const io::MappedIndex n = io::MappedIndex::open(dir / "autzen_noids.rsi");
    EXPECT_FALSE(n.has_ids());
    ASSERT_EQ(n.rgb().size(), m.rgb().size());
    for (std::size_t k = 0; k < n.rgb().size(); ++k) ASSERT_EQ(n.rgb()[k], m.rgb()[k]) << k;
    // xyz + rgb from LAS: 12 + 3 + nodes.
    EXPECT_LT(static_cast<double>(n.file_bytes()) / static_cast<double>(n.positions().size()), 20.0);
  }
  {
    const io::MappedIndex m = expect_exact_rgb(warsaw, dir / "warsaw.rsi");
    EXPECT_EQ(m.rgb().multiplier(), 256u);
    EXPECT_EQ(rgb_section(m).first, "rgb8");
  }
  {
    const io::MappedIndex m = expect_exact_rgb(autzen, dir / "autzen_wide.rsi", false);  // compact_rgb off
    EXPECT_EQ(m.rgb().multiplier(), 0u);
    EXPECT_EQ(rgb_section(m), std::make_pair(std::string("rgb"), std::uint64_t{6} * m.positions().size()));
  }
  // True 16-bit colour, written with the project's LAS writer.
  auto write_colour = [&](const fs::path& p, auto colour) {
    PointCloud c;
    c.positions = make_points(5000, 21);
    c.rgb.resize(c.positions.size());
    for (std::size_t i = 0; i < c.rgb.size(); ++i) c.rgb[i] = colour(i);
    io::LasWriteOptions lo;
    lo.scale = Vec3(0.001);
    io::write_las(p, c, lo);
  };
  write_colour(dir / "wide.las", [](std::size_t i) {
    return Rgb16{static_cast<std::uint16_t>(300 + 37 * i % 60000), static_cast<std::uint16_t>(65535 - i),
                 static_cast<std::uint16_t>(i * 1031 % 65536)};
  });
  {
    const io::MappedIndex m = expect_exact_rgb(dir / "wide.las", dir / "wide.rsi");
    EXPECT_EQ(m.rgb().multiplier(), 0u);
    EXPECT_EQ(rgb_section(m), std::make_pair(std::string("rgb"), std::uint64_t{6} * m.positions().size()));
  }
  // Values that are each b x 256 or b x 1 but not all on one multiplier: the 6-byte fallback.
  write_colour(dir / "mixed.las", [](std::size_t i) {
    const auto v = static_cast<std::uint16_t>(i == 17 ? 256 : i % 200);
    return Rgb16{v, v, v};
  });
  {
    const PointCloud pc = io::read_point_cloud(dir / "mixed.las");
    ASSERT_EQ(pc.rgb[17].r, 256);  // not read as 8-bit (max 256 > 255)
    const io::MappedIndex m = expect_exact_rgb(dir / "mixed.las", dir / "mixed.rsi");
    EXPECT_EQ(m.rgb().multiplier(), 0u);
    EXPECT_EQ(rgb_section(m).first, "rgb");
  }
  // 16-bit values that are all 0 or 65535 = 255 x 257: stored as 8-bit x 257, exactly.
  write_colour(dir / "full.las", [](std::size_t i) {
    const auto v = static_cast<std::uint16_t>(i % 2 ? 65535 : 0);
    return Rgb16{v, 0, v};
  });
  {
    const io::MappedIndex m = expect_exact_rgb(dir / "full.las", dir / "full.rsi");
    EXPECT_EQ(m.rgb().multiplier(), 257u);
  }
  fs::remove_all(dir);
}

// The build reads LAS tiles with their colour as stored (no colour pass at open) and applies the
// readers' rule itself from each tile's largest value (docs/formats.md: 8-bit colour scaled by
// 257, all zero dropped). Tiles of one kind are read once; tiles that differ (8-bit and 16-bit, or
// one all zero) are read again with each reader's own rule, with a note. Oracle: the colours
// read_point_cloud delivers for each tile, by id, in one run and in several, 3- and 6-byte forms.
TEST(IndexFileBuild, TilesOfDifferentColourKindsGetEachReadersColour) {
  RAYSCAN_REQUIRE_FILE(autzen, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "colour_kinds";
  fs::create_directories(dir);
  const PointCloud src = io::read_point_cloud(autzen);
  ASSERT_TRUE(src.rgb_from_8bit_las);
  const std::size_t half = src.size() / 2;
  auto tile = [&](std::size_t b, std::size_t e, const fs::path& out, int kind) {  // 8: as read, 16: wide, 0: zero
    PointCloud c;
    c.crs_wkt = src.crs_wkt;
    c.positions.assign(src.positions.begin() + static_cast<std::ptrdiff_t>(b), src.positions.begin() + static_cast<std::ptrdiff_t>(e));
    c.rgb.assign(src.rgb.begin() + static_cast<std::ptrdiff_t>(b), src.rgb.begin() + static_cast<std::ptrdiff_t>(e));
    c.rgb_from_8bit_las = kind == 8;  // written back as the 8-bit values
    for (std::size_t i = 0; i < c.rgb.size(); ++i) {
      if (kind == 16) c.rgb[i].g = static_cast<std::uint16_t>(1000 + i % 30000);
      else if (kind == 0) c.rgb[i] = Rgb16{0, 0, 0};
    }
    io::LasWriteOptions w;
    w.scale = Vec3(0.01);
    io::write_las(out, c, w);
  };
  tile(0, half, dir / "a8.las", 8);
  tile(half, src.size(), dir / "b8.las", 8);
  tile(half, src.size(), dir / "b16.las", 16);
  tile(half, src.size(), dir / "b0.las", 0);
  struct Case {
    const char* second;
    bool retried, has_rgb;
  };
  for (const Case& k : {Case{"b8.las", false, true}, Case{"b16.las", true, true}, Case{"b0.las", true, false}})
    for (const bool compact : {true, false})
      for (const std::uint64_t memory : {std::uint64_t{64} << 20, std::uint64_t{1} << 20}) {
        SCOPED_TRACE(std::string(k.second) + (compact ? " rgb8 " : " rgb16 ") + std::to_string(memory));
        const std::vector<fs::path> in{dir / "a8.las", dir / k.second};
        io::IndexBuildOptions o;
        o.attributes = io::AttributeSet::parse("id,rgb");
        o.compact_rgb = compact;
        o.memory_bytes = memory;
        const auto st = io::build_index_file(in, dir / "t.rsi", o);
        bool noted = false;
        for (const std::string& n : st.notes) noted = noted || n.find("colour differs in kind") != std::string::npos;
        EXPECT_EQ(noted, k.retried);
        const io::MappedIndex m = io::MappedIndex::open(dir / "t.rsi");
        std::vector<Rgb16> want;
        for (const fs::path& p : in) {
          const PointCloud pc = io::read_point_cloud(p);
          if (!pc.rgb.empty()) want.insert(want.end(), pc.rgb.begin(), pc.rgb.end());
        }
        EXPECT_EQ(m.attributes().has(io::Attribute::rgb), k.has_rgb);
        if (!k.has_rgb) continue;
        ASSERT_EQ(want.size(), m.positions().size());
        ASSERT_EQ(m.rgb().size(), want.size());
        for (std::size_t s = 0; s < want.size(); ++s) ASSERT_EQ(m.rgb()[s], want[m.ids()[s]]) << "slot " << s;
        if (!k.retried) {
          EXPECT_EQ(m.rgb().multiplier(), compact ? 257u : 0u);
        }
      }
  fs::remove_all(dir);
}

std::string open_error(const fs::path& p);  // below: the IndexError of opening p, "" when it opens

// Corrupted rgb8 multiplier and sections behind a valid header checksum: one-line errors.
TEST(IndexFileBadInput, Rgb8MultiplierAndMissingSectionsAreRefused) {
  RAYSCAN_REQUIRE_FILE(autzen, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "bad_rgb8";
  fs::create_directories(dir);
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("rgb");
  io::build_index_file({autzen}, dir / "a.rsi", o);
  const auto bytes = slurp(dir / "a.rsi");
  auto reheader = [&](auto edit) {
    auto b = bytes;
    edit(b);
    std::memset(b.data() + 120, 0, 4);
    const auto hcrc = io::crc32c(b.data(), 4096);
    std::memcpy(b.data() + 120, &hcrc, 4);
    const fs::path p = dir / "m.rsi";
    std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return open_error(p);
  };
  std::uint32_t mul = 0;
  std::memcpy(&mul, bytes.data() + 920, 4);
  EXPECT_EQ(mul, 257u);
  const std::string e = reheader([](auto& b) {
    const std::uint32_t v = 7;
    std::memcpy(b.data() + 920, &v, 4);
  });
  EXPECT_NE(e.find("m.rsi: byte 920: rgb8 multiplier 7 (expected 1, 256 or 257)"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
  // The header claims ids (attribute bit 6) the file does not hold.
  const std::string e2 = reheader([](auto& b) { b[108] |= 64; });
  EXPECT_NE(e2.find("m.rsi: byte 108: attribute set and sections disagree on ids"), std::string::npos) << e2;
  // A flipped byte in the rgb8 section: its checksum (small file, verified at open).
  {
    auto b = bytes;
    const io::MappedIndex m = io::MappedIndex::open(dir / "a.rsi");
    const auto [name, size] = rgb_section(m);
    std::uint64_t off = 0;
    for (const io::IndexSectionInfo& x : m.sections())
      if (x.name == "rgb8") off = x.offset;
    ASSERT_GT(off, 0u);
    b[off + size / 2] ^= 0x10;
    const fs::path p = dir / "f.rsi";
    std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    const std::string e3 = open_error(p);
    EXPECT_NE(e3.find("f.rsi: section rgb8 (byte " + std::to_string(off) + "): checksum"), std::string::npos) << e3;
    // Truncated inside the rgb8 section.
    b = bytes;
    b.resize(off + size / 2);
    std::ofstream(p, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    const std::string e4 = open_error(p);
    EXPECT_NE(e4.find("f.rsi: byte"), std::string::npos) << e4;
    EXPECT_EQ(e4.find('\n'), std::string::npos);
  }
  fs::remove_all(dir);
}

TEST(IndexFileBuild, RefusesLayeredAndDisagreeingCrsAndLeavesNoFile) {
  RAYSCAN_REQUIRE_FILE(a, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(b, "las/Haystack_Rock.las");
  const fs::path dir = temp_dir() / "refuse";
  fs::create_directories(dir);
  io::IndexBuildOptions o;
  o.config.layout = OctreeLayout::layered;
  EXPECT_THROW(io::build_index_file({a}, dir / "x.rsi", o), std::invalid_argument);
  o.config.layout = OctreeLayout::adaptive;
  try {
    io::build_index_file({a, b}, dir / "x.rsi", o);
    FAIL() << "tiles with different CRS accepted";
  } catch (const io::IndexError& e) {
    EXPECT_NE(std::string(e.what()).find("Haystack_Rock.las"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_empty(dir));  // no output, no temporary, no runs
  fs::remove_all(dir);
}

/// A small valid index to corrupt.
fs::path small_index(const fs::path& dir) {
  fs::create_directories(dir);
  const auto pts = make_points(3000, 11);
  write_f64(dir / "a.f64", pts);
  io::IndexBuildOptions o;
  o.attributes = io::AttributeSet::parse("id");  // the ids section is corrupted below too
  io::build_index_file({dir / "a.f64"}, dir / "a.rsi", o);
  return dir / "a.rsi";
}

/// Writes the index file bytes `b` to `path` with every section's CRC-32C and the header's made
/// valid again (docs/index-format.md, "Header" and the section table), so that the structural
/// checks behind the checksums are what a test reaches.
void write_with_valid_crcs(std::vector<std::uint8_t> b, const fs::path& path) {
  std::uint32_t nsec = 0;
  std::memcpy(&nsec, b.data() + 20, 4);
  for (std::uint32_t i = 0; i < nsec; ++i) {
    const std::size_t e = 128 + 32 * i;
    std::uint64_t off = 0, size = 0;
    std::memcpy(&off, b.data() + e + 8, 8);
    std::memcpy(&size, b.data() + e + 16, 8);
    const std::uint32_t c = io::crc32c(b.data() + off, size);
    std::memcpy(b.data() + e + 24, &c, 4);
  }
  std::memset(b.data() + 120, 0, 4);
  const std::uint32_t h = io::crc32c(b.data(), 4096);
  std::memcpy(b.data() + 120, &h, 4);
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

std::string open_error(const fs::path& p) {
  try {
    io::MappedIndex::open(p);
  } catch (const io::IndexError& e) {
    return e.what();
  }
  return "";
}

TEST(IndexFileBadInput, TruncatedCorruptedVersionChangedSource) {
  const fs::path dir = temp_dir() / "bad";
  const fs::path good = small_index(dir);
  const auto bytes = slurp(good);
  auto write = [&](const std::vector<std::uint8_t>& b) {
    const fs::path p = dir / "m.rsi";
    std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return p;
  };
  EXPECT_EQ(open_error(good), "");
  // Truncated anywhere: inside the header, inside a section.
  for (std::size_t len : {std::size_t{0}, std::size_t{100}, std::size_t{4096}, bytes.size() / 2, bytes.size() - 1}) {
    const std::string e = open_error(write({bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(len)}));
    EXPECT_NE(e.find("m.rsi: "), std::string::npos) << len << ": " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos);
  }
  // A flipped byte in every 4 KiB block (header, table, sections): a checksum or field error.
  for (std::size_t off = 0; off < bytes.size(); off += 4096 + 7) {
    auto b = bytes;
    b[off] ^= 0x5A;
    const std::string e = open_error(write(b));
    EXPECT_NE(e, "") << "flip at " << off << " not detected";
  }
  {
    auto b = bytes;
    b[8] = 1;  // version 1 (zlib CRC-32, no stored spacing): refused, naming both versions
    const std::string e = open_error(write(b));
    EXPECT_NE(e.find("m.rsi: byte 8: index format version 1; this rayscan reads version 4"), std::string::npos) << e;
    b[8] = 2;  // version 2 (float64 positions only): refused too, the rebuild named
    const std::string e2 = open_error(write(b));
    EXPECT_NE(e2.find("m.rsi: byte 8: index format version 2; this rayscan reads version 4 (rebuild the index with "
                      "`rayscan index`)"),
              std::string::npos)
        << e2;
    b[8] = 3;  // version 3 (ids always stored, 6-byte rgb): refused in one line, the rebuild named
    const std::string e3 = open_error(write(b));
    EXPECT_NE(e3.find("m.rsi: byte 8: index format version 3; this rayscan reads version 4 (rebuild the index with "
                      "`rayscan index`)"),
              std::string::npos)
        << e3;
    EXPECT_EQ(e3.find('\n'), std::string::npos);
  }
  // The positions encoding (header byte 864) behind a valid header checksum: an unknown id is
  // refused; a valid id that disagrees with the positions section's element size (a float64 file
  // read as 12-byte positions: the section is not N x 12 bytes) too, naming the section.
  {
    auto reheader = [&](std::uint32_t enc) {
      auto b = bytes;
      std::memcpy(b.data() + 864, &enc, 4);
      std::memset(b.data() + 120, 0, 4);
      const auto hcrc = io::crc32c(b.data(), 4096);
      std::memcpy(b.data() + 120, &hcrc, 4);
      return open_error(write(b));
    };
    std::uint32_t enc = 9;
    std::memcpy(&enc, bytes.data() + 864, 4);
    EXPECT_EQ(enc, 0u);  // make_points: float64
    const std::string e = reheader(7);
    EXPECT_NE(e.find("m.rsi: byte 864: positions encoding 7 (expected 0 float64, 1 float32 or 2 LAS int32 grid)"),
              std::string::npos)
        << e;
    const std::string e1 = reheader(1);
    EXPECT_NE(e1.find("section positions: element size 24, expected 12"), std::string::npos) << e1;
    const std::string e2 = reheader(2);
    EXPECT_NE(e2.find("section positions: element size 24, expected 12"), std::string::npos) << e2;
  }
  {
    auto b = bytes;
    b[bytes.size() - 10] ^= 1;  // in the nodes section
    EXPECT_NE(open_error(write(b)).find("checksum"), std::string::npos);
  }
  // Structurally wrong node keys behind valid checksums (what the fuzz target found: a key 0 has
  // no sentinel bit): a child key that is not parent * 8 + octant is refused, naming the node.
  {
    auto b = bytes;
    std::uint32_t nsec = 0;
    std::memcpy(&nsec, b.data() + 20, 4);
    for (std::uint32_t i = 0; i < nsec; ++i) {
      const std::size_t e = 128 + 32 * i;
      std::uint32_t id = 0;
      std::uint64_t off = 0, size = 0;
      std::memcpy(&id, b.data() + e, 4);
      std::memcpy(&off, b.data() + e + 8, 8);
      std::memcpy(&size, b.data() + e + 16, 8);
      if (id != 9) continue;  // the nodes section
      ASSERT_GE(size, 3u * 32u);
      std::uint32_t root = 0, p1 = 0, p2 = 0;
      std::memcpy(&root, b.data() + off + 28, 4);
      ASSERT_TRUE((root >> 31) != 0 && (root & 0xFFFFFFFu) >= 2u);  // nodes 1 and 2 are the root's children
      std::memcpy(&p1, b.data() + off + 32 + 28, 4);
      std::memcpy(&p2, b.data() + off + 64 + 28, 4);
      p2 = (p2 & ~(7u << 28)) | (p1 & (7u << 28));  // node 2's octant := node 1's (two children, one id)
      std::memcpy(b.data() + off + 64 + 28, &p2, 4);
      const auto crc = io::crc32c(b.data() + off, size);
      std::memcpy(b.data() + e + 24, &crc, 4);
    }
    std::memset(b.data() + 120, 0, 4);
    const auto hcrc = io::crc32c(b.data(), 4096);
    std::memcpy(b.data() + 120, &hcrc, 4);
    const std::string e = open_error(write(b));
    EXPECT_NE(e.find("node 2: octant"), std::string::npos) << e;
    EXPECT_NE(e.find("is not the next child of node 0"), std::string::npos) << e;
  }
  // The source changes after the build.
  {
    std::ofstream(dir / "a.f64", std::ios::app | std::ios::binary).write("\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 24);
    const std::string e = open_error(good);
    EXPECT_NE(e.find("changed since the index was built"), std::string::npos) << e;
  }
  fs::remove_all(dir);
}

// CRC-32C: the RFC 3720 check value, and the hardware path (three interleaved streams over 24 KiB
// blocks, then 8-byte and byte tails) equals the portable table path for every length class and
// alignment, whole or continued piecewise.
TEST(IndexFileCrc32c, CheckValueAndHardwareEqualsPortable) {
  const char* check = "123456789";
  EXPECT_EQ(io::crc32c(check, 9), 0xE3069283u);
  EXPECT_EQ(io::crc32c_portable(check, 9), 0xE3069283u);
  EXPECT_EQ(io::crc32c(check, 0), 0u);
  std::mt19937_64 rng(5);
  std::vector<std::uint8_t> buf(3 * 24576 + 4096);
  for (auto& c : buf) c = static_cast<std::uint8_t>(rng());
  for (std::size_t len : {std::size_t{1}, std::size_t{7}, std::size_t{8}, std::size_t{63}, std::size_t{24575},
                          std::size_t{24576}, std::size_t{24577}, std::size_t{3 * 24576 + 1000}})
    for (std::size_t off : {std::size_t{0}, std::size_t{1}, std::size_t{5}}) {
      const std::uint32_t want = io::crc32c_portable(buf.data() + off, len);
      EXPECT_EQ(io::crc32c(buf.data() + off, len), want) << len << " at " << off;
      const std::size_t cut = len / 3;
      EXPECT_EQ(io::crc32c(buf.data() + off + cut, len - cut, io::crc32c(buf.data() + off, cut)), want) << len;
    }
}

// crc32c_combine: the CRC of a concatenation from the pieces' CRCs (4 KiB pages, whose operator
// is cached, and other lengths, 0 included), against crc32c over the whole bytes.
TEST(IndexFileCrc32c, CombineEqualsTheCrcOfTheConcatenation) {
  std::mt19937_64 rng(11);
  std::vector<std::uint8_t> buf(5 * 4096 + 777);
  for (auto& c : buf) c = static_cast<std::uint8_t>(rng());
  std::uint32_t pages = 0;
  for (std::size_t b = 0; b < buf.size(); b += 4096) {
    const std::size_t len = std::min<std::size_t>(4096, buf.size() - b);
    pages = b == 0 ? io::crc32c(buf.data(), len) : io::crc32c_combine(pages, io::crc32c(buf.data() + b, len), len);
  }
  EXPECT_EQ(pages, io::crc32c(buf.data(), buf.size()));
  for (std::size_t cut : {std::size_t{0}, std::size_t{1}, std::size_t{4095}, std::size_t{4096}, std::size_t{9000}}) {
    const std::uint32_t a = io::crc32c(buf.data(), cut), b = io::crc32c(buf.data() + cut, buf.size() - cut);
    EXPECT_EQ(io::crc32c_combine(a, b, buf.size() - cut), io::crc32c(buf.data(), buf.size())) << cut;
  }
  EXPECT_EQ(io::crc32c_combine(io::crc32c(buf.data(), 100), 0, 0), io::crc32c(buf.data(), 100));
}

// A file opened with Verify::metadata_only (one this process just wrote) skips the node checks;
// then the node accessors sanitise corrupted records, so a query never leaves the mapping or
// loops. Here a small file is opened so after its root was made a cycle, node 1 a leaf with
// points past N and node 2 a node with children past M: the accessors read them as empty leaves,
// queries return (ASan checks the reads), and the deep checks (`info --verify`) name the node.
TEST(IndexFileBadInput, UnverifiedCorruptNodesAreSanitisedAndVerifyNamesThem) {
  const fs::path dir = temp_dir() / "unverified";
  const fs::path good = small_index(dir);
  auto bytes = slurp(good);
  std::uint64_t node_off = 0, node_size = 0, ids_off = 0;
  std::uint32_t nsec = 0;
  std::memcpy(&nsec, bytes.data() + 20, 4);
  for (std::uint32_t i = 0; i < nsec; ++i) {
    std::uint32_t id = 0;
    std::memcpy(&id, bytes.data() + 128 + 32 * i, 4);
    if (id == 9) {
      std::memcpy(&node_off, bytes.data() + 128 + 32 * i + 8, 8);
      std::memcpy(&node_size, bytes.data() + 128 + 32 * i + 16, 8);
    }
    if (id == 4) std::memcpy(&ids_off, bytes.data() + 128 + 32 * i + 8, 8);
  }
  ASSERT_GE(node_size, 3u * 32u);
  const std::uint32_t zero = 0, huge = 0xFFFFFFF0u;
  const std::uint32_t leaf_past_n = io::IndexNodeRecord::pack(5, 1, false);
  const std::uint32_t three_children = io::IndexNodeRecord::pack(3, 2, true);
  std::memcpy(bytes.data() + node_off + 24, &zero, 4);                // root: first child 0 (a cycle)
  std::memcpy(bytes.data() + node_off + 32 + 24, &huge, 4);           // node 1: points past N
  std::memcpy(bytes.data() + node_off + 32 + 28, &leaf_past_n, 4);
  std::memcpy(bytes.data() + node_off + 64 + 24, &huge, 4);           // node 2: children past M
  std::memcpy(bytes.data() + node_off + 64 + 28, &three_children, 4);
  const fs::path bad = dir / "bad.rsi";
  std::ofstream(bad, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  io::IndexOpenOptions quick;
  quick.verify = io::IndexOpenOptions::Verify::metadata_only;
  const io::MappedIndex m = io::MappedIndex::open(bad, quick);
  EXPECT_FALSE(m.verified());
  EXPECT_EQ(m.child_count(0), 0u);
  EXPECT_EQ(m.node_points(0).begin, m.node_points(0).end);
  EXPECT_EQ(m.child_count(1), 0u);
  EXPECT_EQ(m.node_points(1).begin, m.node_points(1).end);
  EXPECT_EQ(m.child_count(2), 0u);
  EXPECT_EQ(m.node_points(2).begin, m.node_points(2).end);
  EXPECT_EQ(m.child_boxes_f(0).count, 0u);  // the SIMD child test reads no box of a sanitised record
  EXPECT_EQ(m.child_boxes_f(2).count, 0u);
  const AABB box = m.bounds();
  RayQuery q;
  q.radius = 1.0;
  q.k = 4;
  const std::vector<Ray> rays{Ray(box.lo - Vec3(1.0), box.hi - box.lo)};
  EXPECT_TRUE(ray_query_batch(m, rays, q).at(0).empty());  // the root is now an empty leaf
  EXPECT_TRUE(knn(m, box.lo, 3).empty());
  // The deep checks refuse it, naming the node and the byte (header CRC still valid: the nodes
  // section CRC is what fails first when verifying everything).
  io::IndexOpenOptions full;
  full.verify = io::IndexOpenOptions::Verify::always;
  try {
    io::MappedIndex::open(bad, full);
    FAIL() << "corrupted nodes accepted by --verify";
  } catch (const io::IndexError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.rsi: section nodes (byte " + std::to_string(node_off) + "): checksum"),
              std::string::npos) << e.what();
  }
  // With the section CRCs forged, the record checks name the node; an id >= N names the slot.
  auto forge = [&](const std::vector<std::uint8_t>& b) { write_with_valid_crcs(b, bad); };
  auto deep_error = [&]() -> std::string {
    try {
      io::MappedIndex::open(bad, full);
    } catch (const io::IndexError& e) {
      return e.what();
    }
    return "";
  };
  forge(bytes);
  EXPECT_NE(deep_error().find("byte " + std::to_string(node_off + 24) + ": node 0: children [0, +"), std::string::npos)
      << deep_error();
  auto b2 = slurp(good);
  std::memcpy(b2.data() + ids_off + 4 * 17, &huge, 4);  // slot 17 holds an id past N
  forge(b2);
  EXPECT_NE(deep_error().find("byte " + std::to_string(ids_off + 68) + ": section ids: slot 17 holds id"), std::string::npos)
      << deep_error();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rayscan::test

namespace rayscan::test {
namespace {

int run_cli(const std::string& args, const fs::path& out) {
  const std::string cmd = std::string(RAYSCAN_EXE) + " " + args + " > '" + out.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}
std::string text(const fs::path& p) {
  std::ifstream f(p);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// The node records are checked at every open but metadata_only, also above the size up to which
// every section's CRC is checked (a limit of 0 bytes stands in for a file past 256 MiB), and the
// header's bounds, the sources' point counts, trailing bytes and repeated ids are refused. The
// cases are those of an adversarial run: a root made an internal node of 0 children (kNN then
// found nothing and the surfel set-up read past an empty vector: SIGSEGV), the root made one leaf
// of all N points (every query a scan of N), random bytes over the nodes section (the surfel
// set-up ran for hours), NaN bounds ("use a cell of at least nan"), source counts whose sum wraps
// past 2^64 to N, and an id twice (passed --verify). Oracle: the records and offsets written here.
TEST(IndexFileBadInput, CorruptRecordsAreRefusedAtOpenAtAnySize) {
  const fs::path dir = temp_dir() / "corrupt_open";
  const fs::path good = small_index(dir);
  const auto bytes = slurp(good);
  std::uint32_t nsec = 0;
  std::memcpy(&nsec, bytes.data() + 20, 4);
  auto section = [&](std::uint32_t want, std::uint64_t& off, std::uint64_t& size) {
    for (std::uint32_t i = 0; i < nsec; ++i) {
      std::uint32_t id = 0;
      std::memcpy(&id, bytes.data() + 128 + 32 * i, 4);
      if (id != want) continue;
      std::memcpy(&off, bytes.data() + 128 + 32 * i + 8, 8);
      std::memcpy(&size, bytes.data() + 128 + 32 * i + 16, 8);
      return 128 + 32 * i;
    }
    return 0u;
  };
  std::uint64_t node_off = 0, node_size = 0, ids_off = 0, ids_size = 0, src_off = 0, src_size = 0;
  section(9, node_off, node_size);
  section(4, ids_off, ids_size);
  const std::size_t src_entry = section(1, src_off, src_size);
  ASSERT_GT(node_size, 64u);
  ASSERT_GT(src_entry, 0u);
  std::uint64_t n = 0;
  std::memcpy(&n, bytes.data() + 24, 8);
  // Writes `b` with every section CRC and the header CRC made valid again.
  const fs::path bad = dir / "bad.rsi";
  auto write_forged = [&](const std::vector<std::uint8_t>& b) { write_with_valid_crcs(b, bad); };
  io::IndexOpenOptions large;  // the automatic open of a large file: node records, no CRCs
  large.deep_check_bytes = 0;
  io::IndexOpenOptions full;
  full.verify = io::IndexOpenOptions::Verify::always;
  auto error_of = [&](const io::IndexOpenOptions& o) -> std::string {
    try {
      io::MappedIndex::open(bad, o);
    } catch (const io::IndexError& e) {
      return e.what();
    }
    return "";
  };
  write_forged(bytes);
  EXPECT_EQ(error_of(large), "");
  EXPECT_EQ(error_of(full), "");

  // The root an internal node of 0 children (the bytes 00 00 00 80 at nodes + 28).
  auto b = bytes;
  const std::uint32_t no_children = 0x80000000u;
  std::memcpy(b.data() + node_off + 28, &no_children, 4);
  write_forged(b);
  EXPECT_NE(error_of(large).find("bad.rsi: byte " + std::to_string(node_off + 24) + ": node 0: children ["),
            std::string::npos) << error_of(large);
  {
    // Opened without the node checks, the surfel set-up reports the inconsistency as an error
    // instead of reading past the empty kNN result.
    io::IndexOpenOptions quick;
    quick.verify = io::IndexOpenOptions::Verify::metadata_only;
    const io::MappedIndex m = io::MappedIndex::open(bad, quick);
    const PointCloud pc = m.to_point_cloud();
    try {
      (void)estimate_surfels_over(m, std::span<const Vec3>(pc.positions), SurfelOptions{});
      ADD_FAILURE() << "surfels on an index whose root holds nothing";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("surfels: the kNN of point"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("found 0 neighbours among " + std::to_string(n)), std::string::npos) << e.what();
    }
  }

  // The root one leaf of all N points.
  b = bytes;
  const std::uint32_t first = 0, all = io::IndexNodeRecord::pack(static_cast<std::uint32_t>(n), 0, false);
  std::memcpy(b.data() + node_off + 24, &first, 4);
  std::memcpy(b.data() + node_off + 28, &all, 4);
  write_forged(b);
  EXPECT_NE(error_of(large).find("bad.rsi: byte " + std::to_string(node_off + 32) + ": node 1: not the child of any earlier node"),
            std::string::npos) << error_of(large);

  // Random bytes over the whole nodes section (five seeds).
  for (unsigned seed = 1; seed <= 5; ++seed) {
    b = bytes;
    std::mt19937 rng(seed);
    for (std::uint64_t i = 0; i < node_size; ++i) b[node_off + i] = static_cast<std::uint8_t>(rng());
    write_forged(b);
    const std::string e = error_of(large);
    EXPECT_NE(e.find("bad.rsi: byte "), std::string::npos) << seed << ": " << e;
    EXPECT_NE(e.find(": node "), std::string::npos) << seed << ": " << e;
  }

  // NaN point bounds (header byte 640, the minimum x).
  b = bytes;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(b.data() + 640, &nan, 8);
  write_forged(b);
  EXPECT_NE(error_of(large).find("bad.rsi: byte 640: point bounds of axis 0 [nan, "), std::string::npos) << error_of(large);

  // Two sources whose point counts sum to N only modulo 2^64.
  b = bytes;
  const std::string lines = "0\t0\t18446744073709551615\t0\tlas\t/nonexistent/a.las\n0\t0\t" + std::to_string(n + 1) +
                            "\t0\tlas\t/nonexistent/b.las\n";
  ASSERT_LE(src_off + lines.size(), src_off + ((src_size + 4095) / 4096) * 4096);  // fits the section's page(s)
  std::memcpy(b.data() + src_off, lines.data(), lines.size());
  const std::uint64_t new_size = lines.size();
  std::memcpy(b.data() + src_entry + 16, &new_size, 8);
  write_forged(b);
  EXPECT_NE(error_of(large).find("bad.rsi: byte " + std::to_string(src_off) + ": section sources: the point counts exceed"),
            std::string::npos) << error_of(large);

  // Slot 5 holding slot 6's id: refused by the full verification, naming slot 6.
  b = bytes;
  std::memcpy(b.data() + ids_off + 4 * 5, b.data() + ids_off + 4 * 6, 4);
  std::uint32_t id6 = 0;
  std::memcpy(&id6, b.data() + ids_off + 4 * 6, 4);
  write_forged(b);
  EXPECT_NE(error_of(full).find("bad.rsi: byte " + std::to_string(ids_off + 24) + ": section ids: slot 6 holds id " +
                                std::to_string(id6) + ", as slot 5 does"),
            std::string::npos) << error_of(full);
  fs::remove_all(dir);
}

// Node boxes: finite but reversed or far too large ones passed every check (only NaN was refused),
// and a query could then derive a negative radius from them. The root's box is checked at every
// open (reversed, or outside the header's point bounds beyond float rounding), every other box
// with the node records (reversed, or outside its parent's). Cases: the fuzz finding whose root
// box is reversed with values up to 6e19 (checksums made valid as fuzz_rsi.cpp does), then boxes
// of a built index rewritten by hand. Oracle: the offsets and values read from the files' bytes.
TEST(IndexFileBadInput, ReversedOrOutsideNodeBoxesAreRefused) {
  const fs::path dir = temp_dir() / "node_boxes";
  fs::create_directories(dir);
  const fs::path bad = dir / "bad.rsi";
  using V = io::IndexOpenOptions::Verify;
  auto error_of = [&](V v) -> std::string {
    io::IndexOpenOptions o;
    o.verify = v;
    o.check_sources = false;
    try {
      io::MappedIndex::open(bad, o);
    } catch (const io::IndexError& e) {
      return e.what();
    }
    return "";
  };
  auto f32 = [](const std::vector<std::uint8_t>& b, std::uint64_t at) { return load_at<float>(b, at); };
  auto f64 = [](const std::vector<std::uint8_t>& b, std::uint64_t at) { return load_at<double>(b, at); };
  auto node_section = [](const std::vector<std::uint8_t>& b) {
    for (std::uint32_t i = 0; i < load_at<std::uint32_t>(b, 20); ++i)
      if (load_at<std::uint32_t>(b, 128 + 32 * i) == 9) return load_at<std::uint64_t>(b, 128 + 32 * i + 8);
    return std::uint64_t{0};
  };
  // "[lo, hi]" of axis k of the record at byte `rec`, in world units (the root cell's corner at
  // header byte 40 + 8k added to the stored floats).
  auto world = [&](const std::vector<std::uint8_t>& b, std::uint64_t rec, int k) {
    const double corner = f64(b, 40 + 8 * k);
    std::string s(1, '[');
    s += shortest_text(corner + f32(b, rec + 4 * k)) + ", " + shortest_text(corner + f32(b, rec + 12 + 4 * k)) + "]";
    return s;
  };

  // The fuzz finding: the root's box reversed on axis 0. Every open mode refuses it at open, and
  // so do `rayscan query` (no output file) and `rayscan info --verify` (one line, exit 2).
  {
    const auto b = slurp(fs::path(RAYSCAN_SOURCE_DIR) / "tests/fuzz/regressions/rsi/rsi-crash-6b17b69c28ea146fa82667e447263d19a461a135");
    const std::uint64_t node_off = node_section(b);
    ASSERT_EQ(node_off, 12288u);
    ASSERT_GT(f32(b, node_off), f32(b, node_off + 12));  // the finding as kept: lo.x > hi.x
    write_with_valid_crcs(b, bad);
    const std::string want = bad.string() + ": byte 12288: node 0 (the root): box of axis 0 " + world(b, node_off, 0) +
                             " (expected minimum <= maximum)";
    for (V v : {V::always, V::automatic, V::metadata_only}) EXPECT_EQ(error_of(v), want) << static_cast<int>(v);
    const fs::path rays = dir / "rays.csv", out = dir / "out.txt";
    std::ofstream(rays) << "ox,oy,oz,dx,dy,dz\n630300,4834540,200,0,0,-1\n";
    EXPECT_EQ(run_cli("query -q --cloud '" + bad.string() + "' --rays '" + rays.string() + "' --k 1 -o '" +
                          (dir / "hits.csv").string() + "'", out), 2);
    EXPECT_NE(text(out).find(want), std::string::npos) << text(out);
    EXPECT_FALSE(fs::exists(dir / "hits.csv"));
    EXPECT_EQ(run_cli("info --verify '" + bad.string() + "'", out), 2);
    EXPECT_NE(text(out).find(want), std::string::npos) << text(out);
  }

  const fs::path good = small_index(dir);
  const auto bytes = slurp(good);
  const std::uint64_t node_off = node_section(bytes);
  ASSERT_GT(node_off, 0u);
  write_with_valid_crcs(bytes, bad);
  for (V v : {V::always, V::automatic, V::metadata_only}) ASSERT_EQ(error_of(v), "");
  // The root's box rounds the header's bounds outwards; one more float step either way is rounding.
  auto b = bytes;
  for (int k = 0; k < 3; ++k) {
    store_at<float>(b, node_off + 4 * k, std::nextafter(f32(b, node_off + 4 * k), -1e30f));
    store_at<float>(b, node_off + 12 + 4 * k, std::nextafter(f32(b, node_off + 12 + 4 * k), 1e30f));
  }
  write_with_valid_crcs(b, bad);
  EXPECT_EQ(error_of(V::always), "");

  // The root's maximum y grown by 1% of the points' extent: outside the header's point bounds.
  const double bounds_lo_y = f64(bytes, 640 + 8), bounds_hi_y = f64(bytes, 664 + 8);
  ASSERT_LT(bounds_lo_y, bounds_hi_y);
  b = bytes;
  store_at<float>(b, node_off + 16, f32(b, node_off + 16) + static_cast<float>(0.01 * (bounds_hi_y - bounds_lo_y)));
  write_with_valid_crcs(b, bad);
  const std::string outside = bad.string() + ": byte " + std::to_string(node_off + 16) + ": node 0 (the root): box of axis 1 " +
                              world(b, node_off, 1) + " (expected inside the header's point bounds [" +
                              shortest_text(bounds_lo_y) + ", " + shortest_text(bounds_hi_y) + "], to float rounding)";
  for (V v : {V::always, V::automatic, V::metadata_only}) EXPECT_EQ(error_of(v), outside) << static_cast<int>(v);

  // An inner node (the root's second child) with its box reversed on axis 2 (lo.z and hi.z
  // swapped): refused with the node records (`info --verify` and the default open), not by the
  // O(1) check of an open without them.
  ASSERT_NE(load_at<std::uint32_t>(bytes, node_off + 28) >> 31, 0u);  // the root has children
  ASSERT_GE(load_at<std::uint32_t>(bytes, node_off + 28) & 0xFFFFFFFu, 2u);
  const std::uint32_t child = load_at<std::uint32_t>(bytes, node_off + 24) + 1;
  const std::uint64_t rec = node_off + 32 * std::uint64_t{child};
  ASSERT_LT(f32(bytes, rec + 8), f32(bytes, rec + 20));
  b = bytes;
  store_at<float>(b, rec + 8, f32(bytes, rec + 20));
  store_at<float>(b, rec + 20, f32(bytes, rec + 8));
  write_with_valid_crcs(b, bad);
  const std::string reversed = bad.string() + ": byte " + std::to_string(rec + 8) + ": node " + std::to_string(child) +
                               ": box of axis 2 " + world(b, rec, 2) + " (expected minimum <= maximum)";
  EXPECT_EQ(error_of(V::always), reversed);
  EXPECT_EQ(error_of(V::automatic), reversed);
  EXPECT_EQ(error_of(V::metadata_only), "");
  EXPECT_EQ(run_cli("info --verify '" + bad.string() + "'", dir / "out.txt"), 2);
  EXPECT_NE(text(dir / "out.txt").find(reversed), std::string::npos) << text(dir / "out.txt");

  // The same node's minimum x moved below its parent's (the root's) minimum x.
  b = bytes;
  store_at<float>(b, rec, f32(bytes, node_off) - 1.0f);
  write_with_valid_crcs(b, bad);
  EXPECT_EQ(error_of(V::always), bad.string() + ": byte " + std::to_string(rec) + ": node " + std::to_string(child) +
                                     ": box of axis 0 " + world(b, rec, 0) + " (expected inside its parent node 0's " +
                                     world(b, node_off, 0) + ")");
  fs::remove_all(dir);
}

// Ids in a file opened without the deep checks: every consumer indexes
// per-point arrays by id, so one id >= N in a large unverified file would be a write out of
// bounds (normals, visibility) or a read past an array (query, spacing). ids() returns a checked
// view: reading the corrupted id reports a clean IndexError naming the slot and byte, and a query
// that never reads it is answered exactly (no pass over all ids first); the CLI exits 2 on
// a file made larger than the 256 MiB verify-at-open limit by a sparse tail (the real unverified
// path, no test hook). Oracle: the byte offset of the corrupted slot computed from the section
// table, and the untouched file passing the same calls.
TEST(IndexFileBadInput, UnverifiedCorruptIdIsRefusedBeforeAnyIdIndexedAccess) {
  const fs::path dir = temp_dir() / "unverified_ids";
  const fs::path good = small_index(dir);
  auto bytes = slurp(good);
  std::uint64_t ids_off = 0;
  std::uint32_t nsec = 0;
  std::memcpy(&nsec, bytes.data() + 20, 4);
  for (std::uint32_t i = 0; i < nsec; ++i) {
    std::uint32_t id = 0;
    std::memcpy(&id, bytes.data() + 128 + 32 * i, 4);
    if (id == 4) std::memcpy(&ids_off, bytes.data() + 128 + 32 * i + 8, 8);
  }
  ASSERT_GT(ids_off, 0u);
  const std::uint32_t huge = 0x7FFFFFF0u;
  std::memcpy(bytes.data() + ids_off + 4 * 1234, &huge, 4);  // slot 1234 holds an id past N
  const fs::path bad = dir / "bad.rsi";
  std::ofstream(bad, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  io::IndexOpenOptions quick;
  quick.verify = io::IndexOpenOptions::Verify::metadata_only;
  const std::string want = "bad.rsi: byte " + std::to_string(ids_off + 4 * 1234) + ": section ids: slot 1234 holds id " +
                           std::to_string(huge);
  {
    const io::MappedIndex ok = io::MappedIndex::open(good, quick);  // the same calls on the good file pass
    EXPECT_FALSE(ok.verified());
    EXPECT_EQ(ok.ids().size(), 3001u);
    EXPECT_EQ(knn(ok, ok.positions()[0], 3).size(), 3u);
  }
  const io::MappedIndex m = io::MappedIndex::open(bad, quick);
  EXPECT_FALSE(m.verified());
  auto error_of = [&](auto&& call) -> std::string {
    try {
      call();
    } catch (const io::IndexError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(error_of([&] { (void)m.ids(); }), "no error");  // the view; its reads are checked
  EXPECT_NE(error_of([&] { (void)m.ids()[1234]; }).find(want), std::string::npos) << error_of([&] { (void)m.ids()[1234]; });
  EXPECT_LT(m.ids()[1233], 3000u);  // the other ids read normally
  // Consumers that read or write per-point arrays by id: each fails cleanly where it reads the
  // corrupted id (ASan: no access past an array); a query elsewhere gets the good file's answer.
  const Vec3 p = m.positions()[1234];
  EXPECT_NE(error_of([&] { (void)knn(m, p, 3); }).find(want), std::string::npos);
  {
    const io::MappedIndex ok = io::MappedIndex::open(good, quick);
    const Vec3 far = m.positions()[0];
    std::vector<PointIndex> a, b;
    // The query near slot 0 never reads slot 1234's id: no error, the good file's answer.
    EXPECT_EQ(error_of([&] {
                for (const auto& n : knn(m, far, 3)) a.push_back(n.index);
              }),
              "no error");
    for (const auto& n : knn(ok, far, 3)) b.push_back(n.index);
    EXPECT_EQ(a, b);
  }
  RayQuery q;
  q.radius = 1.0;
  q.k = 4;
  const std::vector<Ray> rays(64, Ray(p + Vec3(0.0, 0.0, 10.0), Vec3(0.0, 0.0, -1.0)));
  EXPECT_NE(error_of([&] { (void)ray_query_batch(m, rays, q); }).find(want), std::string::npos);  // from TBB tasks
  EXPECT_NE(error_of([&] { (void)median_nn_spacing_by_id(m); }).find(want), std::string::npos);
  EXPECT_NE(error_of([&] { (void)m.to_point_cloud(); }).find("slot 1234 holds id"), std::string::npos);

  // The automatic open of a file above the deep-check size (here a limit of 0 bytes stands in for
  // a file past 256 MiB): the node records are checked, the ids are not, and ids() is the
  // checked view.
  io::IndexOpenOptions large;
  large.deep_check_bytes = 0;
  const io::MappedIndex ml = io::MappedIndex::open(bad, large);
  EXPECT_FALSE(ml.verified());
  EXPECT_NE(error_of([&] { (void)knn(ml, p, 3); }).find(want), std::string::npos);

  // A file padded past 256 MiB (sparse), which would be opened without the deep checks, is
  // refused: the file ends at its last section. The CLI exits 2 with one line.
  const std::uint64_t end = fs::file_size(bad);
  fs::resize_file(bad, (std::uint64_t{256} << 20) + 4096);
  {
    std::ofstream r(dir / "rays.csv");
    r.precision(17);
    r << "ox,oy,oz,dx,dy,dz\n" << p.x << ',' << p.y << ',' << p.z + 10 << ",0,0,-1\n";
  }
  const fs::path log = dir / "log.txt";
  EXPECT_EQ(run_cli("query --cloud '" + bad.string() + "' --rays '" + (dir / "rays.csv").string() + "' --radius 1", log), 2)
      << text(log);
  const std::string e = text(log);
  EXPECT_NE(e.find("bad.rsi: byte " + std::to_string(end) + ": " + std::to_string((std::uint64_t{256} << 20) + 4096 - end) +
                   " bytes after the end of the last section"),
            std::string::npos)
      << e;
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
  fs::remove_all(dir);
}

TEST(IndexFileCli, IndexThenQueryEqualsQueryOnTheCloudAndInfoDescribesIt) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "cli";
  fs::create_directories(dir);
  const fs::path rsi = dir / "autzen.rsi", log = dir / "log.txt";
  ASSERT_EQ(run_cli("index -q '" + las.string() + "' -o '" + rsi.string() + "' --attributes id,rgb --memory 2M", log), 0) << text(log);
  // Without ids (the default): the same rows in index order (the index column is the slot).
  const fs::path rsi_slots = dir / "slots.rsi";
  ASSERT_EQ(run_cli("index -q '" + las.string() + "' -o '" + rsi_slots.string() + "' --attributes rgb --memory 2M", log), 0) << text(log);
  {
    // Rays straight down onto three of the cloud's points (so they hit).
    const PointCloud pc = io::read_point_cloud(las);
    std::ofstream r(dir / "rays.csv");
    r.precision(17);
    r << "ox,oy,oz,dx,dy,dz\n";
    for (std::size_t i : {std::size_t{10}, pc.size() / 2, pc.size() - 7}) {
      const Vec3& p = pc.positions[i];
      r << p.x + 0.3 << ',' << p.y << ',' << p.z + 200 << ",0.001,0,-1\n";
    }
  }
  // -q: standard error (the progress and summary lines) goes into the same files as the CSV.
  const std::string q = " --rays '" + (dir / "rays.csv").string() + "' --radius 3 --k 20 --order sphere_hit -q";
  ASSERT_EQ(run_cli("query --cloud '" + las.string() + "'" + q, dir / "a.csv"), 0) << text(dir / "a.csv");
  ASSERT_EQ(run_cli("query --cloud '" + rsi.string() + "'" + q, dir / "b.csv"), 0) << text(dir / "b.csv");
  EXPECT_EQ(text(dir / "a.csv"), text(dir / "b.csv"));
  ASSERT_EQ(run_cli("query --cloud '" + rsi_slots.string() + "'" + q, dir / "c.csv"), 0) << text(dir / "c.csv");
  {
    // ray,rank,index,x,y,z,t,distance: every column but index equal; index = the slot, whose
    // position is the row's x, y, z.
    const io::MappedIndex ms = io::MappedIndex::open(rsi_slots);
    EXPECT_TRUE(ms.ids().is_identity());
    std::istringstream sb(text(dir / "b.csv")), sc(text(dir / "c.csv"));
    std::string lb, lc;
    std::size_t rows = 0;
    std::getline(sb, lb), std::getline(sc, lc);
    EXPECT_EQ(lb, lc);  // header
    while (std::getline(sb, lb)) {
      ASSERT_TRUE(std::getline(sc, lc)) << rows;
      auto cols = [](const std::string& l) {
        std::vector<std::string> v;
        std::istringstream ls(l);
        for (std::string c; std::getline(ls, c, ',');) v.push_back(c);
        return v;
      };
      auto vb = cols(lb), vc = cols(lc);
      ASSERT_EQ(vb.size(), 8u);
      ASSERT_EQ(vc.size(), 8u);
      for (int k : {0, 1, 3, 4, 5, 6, 7}) EXPECT_EQ(vb[k], vc[k]) << "row " << rows << " column " << k;
      // (Written with the decimals of the LAS grid the index stores: the same grid point.)
      const Vec3 p = ms.positions()[std::stoul(vc[2])], s = ms.positions().scale(), o = ms.positions().offset();
      EXPECT_EQ(std::llround((std::stod(vc[3]) - o.x) / s.x), std::llround((p.x - o.x) / s.x));
      EXPECT_EQ(std::llround((std::stod(vc[4]) - o.y) / s.y), std::llround((p.y - o.y) / s.y));
      ++rows;
    }
    EXPECT_FALSE(std::getline(sc, lc));
    EXPECT_GT(rows, 10u);
  }
  ASSERT_EQ(run_cli("info '" + rsi_slots.string() + "'", log), 0) << text(log);
  EXPECT_NE(text(log).find("ids:               not stored (points in index order)"), std::string::npos) << text(log);
  EXPECT_NE(text(log).find("rgb:               8-bit x 257 (3 bytes/point, exact)"), std::string::npos) << text(log);
  EXPECT_NE(text(log).find(" positions 12 rgb8 3 nodes "), std::string::npos) << text(log);
  const std::string a = text(dir / "a.csv");
  EXPECT_GT(std::count(a.begin(), a.end(), '\n'), 10);  // the rays hit points
  ASSERT_EQ(run_cli("info --verify '" + rsi.string() + "'", log), 0) << text(log);
  EXPECT_NE(text(log).find("points:            110000"), std::string::npos) << text(log);
  EXPECT_NE(text(log).find("all sections verified"), std::string::npos) << text(log);
  // Bad input: exit 2, one line naming the file; a failed build leaves nothing behind.
  {
    std::ofstream(dir / "junk.rsi") << "not an index";
  }
  EXPECT_EQ(run_cli("info '" + (dir / "junk.rsi").string() + "'", log), 2);
  EXPECT_NE(text(log).find("junk.rsi: byte"), std::string::npos) << text(log);
  EXPECT_EQ(run_cli("index -q '" + (dir / "missing.las").string() + "' -o '" + (dir / "x.rsi").string() + "'", log), 2);
  EXPECT_FALSE(fs::exists(dir / "x.rsi"));
  EXPECT_EQ(run_cli("index -q '" + las.string() + "' -o '" + (dir / "x.rsi").string() + "' --memory 10Q", log), 2);
  // A budget below the minimum: the build names IndexBuildOptions::memory_bytes, the CLI its flag.
  EXPECT_EQ(run_cli("index -q '" + las.string() + "' -o '" + (dir / "x.rsi").string() + "' --memory 1000", log), 2);
  EXPECT_NE(text(log).find("rayscan index: --memory 1000 bytes: at least 1M"), std::string::npos) << text(log);
  fs::remove_all(dir);
}

/// Runs `rayscan index` on autzen into `dir/site.rsi` (which holds "old") through `shell_prefix`
/// and checks the full-disk contract: exit 2, one line naming the output and the errno text, the
/// old output untouched, no temporary file or run folder left in `dir`.
void expect_clean_disk_full_failure(const fs::path& dir, const fs::path& las, const std::string& shell_prefix,
                                    const std::string& errno_text) {
  {
    std::ofstream(dir / "site.rsi") << "old";
  }
  const fs::path log = temp_dir() / "disk_full_log.txt";
  const std::string cmd = shell_prefix + "exec " + std::string(RAYSCAN_EXE) + " index -q '" + las.string() +
                          "' -o '" + (dir / "site.rsi").string() + "' --attributes all --memory 1M";
  const int rc = std::system(("bash -c \"" + cmd + "\" > '" + log.string() + "' 2>&1").c_str());
  ASSERT_TRUE(WIFEXITED(rc)) << cmd;
  EXPECT_EQ(WEXITSTATUS(rc), 2) << text(log);
  const std::string e = text(log);
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
  // Named as the output given, never as the hidden temporary output or sort run written.
  EXPECT_EQ(e.rfind("rayscan index: " + (dir / "site.rsi").string() + ": ", 0), 0u) << e;
  EXPECT_EQ(e.find(".tmp."), std::string::npos) << e;
  EXPECT_EQ(e.find(".runs."), std::string::npos) << e;
  EXPECT_NE(e.find(errno_text), std::string::npos) << e;
  EXPECT_EQ(text(dir / "site.rsi"), "old");
  std::vector<std::string> left;
  for (const auto& f : fs::directory_iterator(dir)) left.push_back(f.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"site.rsi"}) << "temporaries left behind";
}

// A build that runs out of disk, in each stage (sorted runs, the output's point sections
// in the merge, its nodes section), fails with one line and leaves the previous output and no
// temporaries. The stages are reached with a file-size limit (RLIMIT_FSIZE with SIGXFSZ ignored,
// so write() fails with EFBIG exactly where a full disk fails with ENOSPC); as root a real full
// disk (a 1 MiB tmpfs in a private mount namespace) is tried as well.
TEST(IndexFileCli, FullDiskInEveryStageLeavesNoPartialOutput) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  const fs::path dir = temp_dir() / "disk_full";
  fs::create_directories(dir);
  for (int kib : {64, 600, 3000}) {  // runs, point sections, nodes (autzen: 110,000 points)
    SCOPED_TRACE("ulimit -f " + std::to_string(kib));
    expect_clean_disk_full_failure(dir, las, "ulimit -f " + std::to_string(kib) + "; trap '' XFSZ; ",
                                   std::strerror(EFBIG));
  }
  fs::remove_all(dir);
  if (::geteuid() == 0 &&
      std::system("unshare -m true > /dev/null 2>&1") == 0) {
    const fs::path mnt = temp_dir() / "disk_full_tmpfs";
    fs::create_directories(mnt);
    // The whole check runs inside the namespace: mount, build, then report what is left.
    const fs::path script = temp_dir() / "disk_full_tmpfs.sh", log = temp_dir() / "disk_full_tmpfs.txt";
    {
      std::ofstream f(script);
      f << "mount -t tmpfs -o size=1m tmpfs '" << mnt.string() << "' || exit 99\n"
        << "cd '" << mnt.string() << "' && printf old > site.rsi\n"
        << "'" << RAYSCAN_EXE << "' index -q '" << las.string() << "' -o site.rsi --memory 1M\n"
        << "rc=$?\necho \"entries=$(ls -A | wc -l) content=$(cat site.rsi)\"\nexit $rc\n";
    }
    const int rc = std::system(("unshare -m bash '" + script.string() + "' > '" + log.string() + "' 2>&1").c_str());
    ASSERT_TRUE(WIFEXITED(rc));
    if (WEXITSTATUS(rc) == 99) {
      std::printf("note: tmpfs mount not permitted here; the file-size-limit cases above stand\n");
    } else {
      EXPECT_EQ(WEXITSTATUS(rc), 2) << text(log);
      EXPECT_NE(text(log).find("rayscan index: site.rsi: "), std::string::npos) << text(log);
      EXPECT_NE(text(log).find(std::strerror(ENOSPC)), std::string::npos) << text(log);
      EXPECT_EQ(text(log).find(".tmp."), std::string::npos) << text(log);
      EXPECT_NE(text(log).find("entries=1 content=old"), std::string::npos) << "leftovers or a changed output: " << text(log);
    }
    fs::remove_all(mnt);
  }
}

}  // namespace
}  // namespace rayscan::test
