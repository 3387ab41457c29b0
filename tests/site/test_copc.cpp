// COPC: the info VLR and hierarchy of the shared COPC file, and CopcIndex (the layered octree read
// straight from the file) against the brute-force oracle on the same decoded points.
#include "../io/io_test_util.hpp"
#include "../common/las_patch.hpp"

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/copc_writer.hpp"
#include "rayscan/jobs/query.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <functional>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <thread>

namespace rayscan::test {
namespace {

// autzen_trim written as COPC with leaves of 2,000 points: several levels, many octants without
// a child (once per test process; empty when the file is absent).
fs::path deep_copc() {
  static const fs::path out = []() -> fs::path {
    const fs::path src = data_file("las/autzen_trim.las");
    if (src.empty()) return {};
    const fs::path f = temp_dir() / "deep.copc.laz";
    io::CopcWriteOptions o;
    o.leaf_points = 2000;
    io::write_copc(src, f, o);
    return f;
  }();
  return out;
}

// A hierarchy node's points node holds no point inside one of its children's cubes.
void expect_pushed_down(const fs::path& p) {
  io::CopcIndex idx(p);
  const io::CopcInfo& info = idx.info();
  const Vec3 margin = Vec3(2 * std::abs(info.scale.x), 2 * std::abs(info.scale.y), 2 * std::abs(info.scale.z));
  std::size_t checked = 0, at_root = 0, at_deepest = 0;
  std::vector<std::pair<io::CopcIndex::Node, int>> hier{{idx.root(), 0}};  // (handle, level)
  while (!hier.empty()) {
    const auto [h, level] = hier.back();
    hier.pop_back();
    // the handle's children: its points node (part 1) and its hierarchy children (part 0),
    // perhaps under a group (part kGroup)
    std::vector<io::CopcIndex::Node> kids, pts;
    std::vector<io::CopcIndex::Node> todo{h};
    while (!todo.empty()) {
      const io::CopcIndex::Node n = todo.back();
      todo.pop_back();
      for (unsigned c = 0; c < idx.child_count(n); ++c) {
        const io::CopcIndex::Node k = idx.child(n, c);
        const std::uint32_t part = static_cast<std::uint32_t>(k >> 32);
        if (part == 0) kids.push_back(k);
        else if (part == 1) pts.push_back(k);
        else todo.push_back(k);
      }
    }
    std::vector<AABB> inner;
    for (io::CopcIndex::Node k : kids) {
      AABB b = idx.node_bounds(k);
      b.lo = b.lo + margin;
      b.hi = b.hi - margin;
      inner.push_back(b);
      hier.emplace_back(k, level + 1);
    }
    std::size_t here = 0;
    for (std::vector<io::CopcIndex::Node> cells = pts; !cells.empty();) {
      const io::CopcIndex::Node c = cells.back();
      cells.pop_back();
      const SlotRange s = idx.node_points(c);
      for (std::uint32_t k = s.begin; k < s.end; ++k, ++here) {
        for (const AABB& b : inner) ASSERT_FALSE(b.contains(idx.positions()[k])) << "point id " << idx.ids()[k];
        ++checked;
      }
      for (unsigned j = 0; j < idx.child_count(c); ++j) cells.push_back(idx.child(c, j));
    }
    if (level == 0) at_root = here;
    if (level + 1 == info.depth) at_deepest += here;
  }
  EXPECT_EQ(checked, info.point_count);
  // the root's subsample went down to its children; the deepest nodes (leaves) hold their own
  // chunks and points from above
  EXPECT_LT(at_root, info.points_per_level.front());
  EXPECT_GT(at_deepest, info.points_per_level.back());
}

// Walk the whole index (decoding every node): the local trees of the decoded nodes, read through
// the SpatialIndex interface, must hold every point of the file exactly once, each inside the
// box of every node on its path, with at most 8 children per node; position_of(id) (file order)
// must equal the whole-file read despite the Morton order of the slots.
void expect_partition(const fs::path& p) {
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  io::CopcIndex idx(p);
  std::vector<std::uint8_t> seen(pc.size(), 0);
  std::size_t cells = 0, max_children = 0;
  struct Item {
    io::CopcIndex::Node n;
    std::vector<AABB> path;
  };
  std::vector<Item> stack{{idx.root(), {}}};
  while (!stack.empty()) {
    Item it = std::move(stack.back());
    stack.pop_back();
    it.path.push_back(idx.node_bounds(it.n));
    const SlotRange s = idx.node_points(it.n);
    for (std::uint32_t k = s.begin; k < s.end; ++k) {
      const PointIndex id = idx.ids()[k];
      ASSERT_LT(id, pc.size());
      ++seen[id];
      ASSERT_EQ(idx.positions()[k], pc.positions[id]);
      for (const AABB& b : it.path) ASSERT_TRUE(b.contains(pc.positions[id]));
    }
    ++cells;
    const unsigned nc = idx.child_count(it.n);
    max_children = std::max<std::size_t>(max_children, nc);
    for (unsigned c = 0; c < nc; ++c) stack.push_back({idx.child(it.n, c), it.path});
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), std::uint8_t{1}), static_cast<std::ptrdiff_t>(pc.size()));
  EXPECT_LE(max_children, 8u);
  EXPECT_GT(cells, 10 * idx.node_count()) << "the nodes were not sub-indexed";
  std::mt19937 rng(3);
  for (int i = 0; i < 2000; ++i) {
    const PointIndex id = static_cast<PointIndex>(rng() % pc.size());
    ASSERT_EQ(idx.position_of(id), pc.positions[id]);
  }
}

TEST(Copc, InfoAndHierarchyAreConsistentWithTheHeader) {
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const io::CopcInfo c = io::read_copc_info(p);
  EXPECT_EQ(c.point_count, 518862u);  // shared data README
  EXPECT_EQ(c.pdrf, 6);
  std::uint64_t pts = 0, nodes = 0;
  for (std::size_t l = 0; l < c.points_per_level.size(); ++l) pts += c.points_per_level[l], nodes += c.nodes_per_level[l];
  EXPECT_EQ(pts, c.point_count);
  EXPECT_EQ(nodes, c.nodes.size());
  EXPECT_EQ(c.nodes_per_level.at(0), 1u);
  EXPECT_GT(c.depth, 1);
  // The README's recomputed bounds (3 decimals) lie inside the root cube.
  const AABB root = c.node_cube(io::CopcNode{});
  const double tol = 5e-4;
  EXPECT_LE(root.lo.x, 515368.602 + tol);
  EXPECT_GE(root.hi.x, 515401.043 - tol);
  EXPECT_LE(root.lo.y, 4918340.364 + tol);
  EXPECT_GE(root.hi.y, 4918381.124 - tol);
  EXPECT_LE(root.lo.z, 2322.896 + tol);
  EXPECT_GE(root.hi.z, 2338.576 - tol);
}

TEST(Copc, IndexRayQueriesEqualBruteForceAndDecodeLazily) {
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  io::CopcIndex idx(p, std::size_t{4} << 20);  // a 4 MB cache: forces evictions below
  EXPECT_EQ(idx.decodes(), 0u);  // opening decodes nothing
  const PointCloud pc = io::read_point_cloud(p);
  ASSERT_EQ(pc.size(), 518862u);
  const BruteForceIndex bf(pc);
  const AABB b = pc.bounds();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<RayHit> got, want;
  for (int q = 0; q < 40; ++q) {
    const Vec3 o = b.lo + Vec3(u(rng), u(rng), u(rng)) * (b.hi - b.lo);
    Vec3 d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    RayQuery rq;
    rq.radius = 0.05 + 0.2 * u(rng);
    if (q % 2 == 0) rq.k = 5;
    else rq.t_min = 0;
    ray_query(idx, Ray(o, d), rq, got);
    ray_query(bf, Ray(o, d), rq, want);
    ASSERT_EQ(got.size(), want.size()) << "query " << q;
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].index, want[i].index) << "query " << q;
      EXPECT_EQ(got[i].t, want[i].t);
      // slots are in Morton order inside a node: the hit's slot still names the hit's point
      EXPECT_EQ(idx.ids()[got[i].slot], got[i].index);
      EXPECT_EQ(idx.positions()[got[i].slot], pc.positions[got[i].index]);
    }
    if (q == 0) {
      EXPECT_LT(idx.resident_nodes(), idx.node_count()) << "a single narrow ray touched every node";
    }
    if (q % 10 == 9) idx.trim_cache();  // evicted nodes are decoded again on the next touch
  }
  EXPECT_GT(idx.decodes(), 0u);
}

// Pages of `bytes` at `p` that the kernel holds resident (mincore): what the cache really keeps
// of the positions array, independent of its own accounting.
std::size_t resident_pages(const void* p, std::size_t bytes) {
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  const auto b = reinterpret_cast<std::uintptr_t>(p) / page * page;
  const std::size_t n = (reinterpret_cast<std::uintptr_t>(p) + bytes - b + page - 1) / page;
  std::vector<unsigned char> v(n);
  if (::mincore(reinterpret_cast<void*>(b), n * page, v.data()) != 0) return ~std::size_t{0};
  std::size_t k = 0;
  for (unsigned char c : v) k += c & 1;
  return k;
}

// Random rays through the cloud's box and the brute force's answers (the oracle).
struct ScopeRays {
  std::vector<Ray> rays;
  std::vector<RayQuery> queries;
  std::vector<std::vector<RayHit>> want;
};
ScopeRays scope_rays(const PointCloud& pc, int n) {
  const BruteForceIndex bf(pc);
  const AABB b = pc.bounds();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  ScopeRays r;
  for (int q = 0; q < n; ++q) {
    const Vec3 o = b.lo + Vec3(u(rng), u(rng), u(rng)) * (b.hi - b.lo);
    r.rays.emplace_back(o, Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5));
    RayQuery rq;
    rq.radius = 0.05 + 0.2 * u(rng);
    rq.k = q % 3 == 0 ? 1 : 4;
    r.queries.push_back(rq);
    ray_query(bf, r.rays.back(), rq, r.want.emplace_back());
  }
  return r;
}

TEST(Copc, QueryScopesKeepTheCacheWithinItsBudget) {
  // One query per scope on one thread: every scope's end leaves the decoded nodes within the
  // budget by the cache's accounting, the kernel's resident pages of the positions array within
  // that accounting (whole pages are counted; released nodes really give their pages back), and the answers equal the
  // brute force's although nodes are evicted and decoded again between the queries.
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  const ScopeRays r = scope_rays(pc, 60);
  const std::size_t budget = std::size_t{3} << 20;  // ~2 of lone-star's 15 nodes (~35,000 points each)
  io::CopcIndex idx(p, budget);
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  std::vector<RayHit> got;
  std::size_t over = 0;
  for (std::size_t q = 0; q < r.rays.size(); ++q) {
    {
      const io::CopcIndex::QueryScope scope(idx);
      ray_query(idx, r.rays[q], r.queries[q], got);
      ASSERT_EQ(got.size(), r.want[q].size()) << "query " << q;
      for (std::size_t i = 0; i < got.size(); ++i) {
        EXPECT_EQ(got[i].index, r.want[q][i].index) << "query " << q;
        EXPECT_EQ(got[i].t, r.want[q][i].t) << "query " << q;
      }
      over += idx.resident_bytes() > budget;
    }
    EXPECT_LE(idx.resident_bytes(), budget) << "after query " << q;
    const std::span<const Vec3> pos = idx.positions();
    EXPECT_LE(resident_pages(pos.data(), pos.size_bytes()) * page, idx.resident_bytes())
        << "after query " << q;
  }
  EXPECT_GT(over, 0u) << "no query went over the budget: the trim was not exercised";
  EXPECT_GT(idx.decodes(), idx.node_count()) << "no node was decoded twice: nothing was evicted";
}

TEST(Copc, ConcurrentScopesEvictWithoutChangingAnswers) {
  // Many threads' scopes over a cache of a few nodes: each scope's end evicts what the others
  // may still be reading unless the retirement protocol holds it; a released node read
  // by a ray in flight would read zeroed pages and change its hits. Oracle: the brute force.
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  const ScopeRays r = scope_rays(pc, 300);
  io::CopcIndex idx(p, std::size_t{4} << 20);  // ~3 of the 15 nodes
  std::vector<std::vector<RayHit>> got(r.rays.size());
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> threads;  // more threads than cores: scopes interleave at any point
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (std::size_t q; (q = next.fetch_add(1)) < r.rays.size();) {
        const io::CopcIndex::QueryScope scope(idx);
        ray_query(idx, r.rays[q], r.queries[q], got[q]);
      }
    });
  for (std::thread& t : threads) t.join();
  for (std::size_t q = 0; q < r.rays.size(); ++q) {
    ASSERT_EQ(got[q].size(), r.want[q].size()) << "query " << q;
    for (std::size_t i = 0; i < got[q].size(); ++i) {
      EXPECT_EQ(got[q][i].index, r.want[q][i].index) << "query " << q;
      EXPECT_EQ(got[q][i].t, r.want[q][i].t) << "query " << q;
    }
  }
  // Every scope's end found the cache over budget (whether a node is released or revived by a
  // scope in flight depends on the interleaving; the single-thread test asserts re-decodes).
  EXPECT_GT(idx.peak_resident_bytes(), idx.cache_bytes());
  idx.trim_cache();  // no scope open: every retired node can go
  EXPECT_LE(idx.resident_bytes(), idx.cache_bytes());
}

TEST(Copc, LocalTreesPartitionEachNodeAndPositionOfFollowsThePermutation) {
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  expect_partition(p);
  // a deeper, sparse hierarchy from rayscan's writer
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  expect_partition(deep_copc());
}

TEST(Copc, EachPointLivesInTheDeepestNodeWhoseCubeHoldsIt) {
  // A ray should cross one local tree, not one per level: a hierarchy node's points node holds
  // no point that lies inside one of its existing children's cubes (each level's subsample is
  // pushed down), so the leaves hold their ancestors' points in their cubes. Oracle: the voxel
  // cubes from the hierarchy keys (COPC 1.0), shrunk by two scale steps (the bounds are the
  // cubes grown by one; a point on a face may go either way).
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  expect_pushed_down(p);
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  expect_pushed_down(deep_copc());
}

TEST(Copc, QueryJobRunsOnTheHierarchyAndEqualsTheWholeFilePath) {
  // run_query on a COPC file goes through CopcIndex (decoding only the nodes the rays reach); the
  // same rays on the whole decoded cloud with the brute-force index are the oracle.
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  EXPECT_TRUE(io::is_copc_file(p));
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  const AABB b = pc.bounds();
  // A ray grazing one corner of the bounding box: it must reach only a few nodes.
  const Vec3 corner = b.lo + (b.hi - b.lo) * 0.02;
  jobs::QueryJobOptions copc;
  copc.cloud_file = p;
  copc.query.radius = 0.5;
  copc.cache_bytes = std::size_t{8} << 20;
  copc.rays = {Ray(corner - Vec3(0, 0, 100), Vec3(0, 0, 1))};
  const jobs::QueryJobResult one = jobs::run_query(copc);
  EXPECT_EQ(one.copc_nodes, io::CopcIndex(p).node_count());
  EXPECT_GT(one.copc_decodes, 0u);
  EXPECT_LT(one.copc_decodes, one.copc_nodes) << "a corner ray decoded every node";
  // Many rays: hits and hit positions equal the whole-file path.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  copc.rays.clear();
  for (int q = 0; q < 30; ++q)
    copc.rays.emplace_back(b.lo + Vec3(u(rng), u(rng), u(rng)) * (b.hi - b.lo),
                           Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5));
  copc.query.k = 4;
  copc.query.radius = 0.3;
  jobs::QueryJobOptions whole = copc;
  whole.cloud = &pc;
  whole.index.type = "brute";
  const jobs::QueryJobResult a = jobs::run_query(copc), w = jobs::run_query(whole);
  ASSERT_EQ(a.hits.size(), w.hits.size());
  std::size_t flat = 0, total = 0;
  for (std::size_t r = 0; r < a.hits.size(); ++r) {
    ASSERT_EQ(a.hits[r].size(), w.hits[r].size()) << "ray " << r;
    for (std::size_t k = 0; k < a.hits[r].size(); ++k, ++flat) {
      EXPECT_EQ(a.hits[r][k].index, w.hits[r][k].index) << "ray " << r;
      EXPECT_EQ(a.hits[r][k].t, w.hits[r][k].t);
      EXPECT_EQ(a.hit_positions[flat], pc.positions[a.hits[r][k].index]);
    }
    total += a.hits[r].size();
  }
  EXPECT_GT(total, 0u);
  // the CSV of a COPC query prints the positions (as for an index file)
  std::ostringstream csv;
  jobs::write_hits_csv(csv, a);
  EXPECT_NE(csv.str().find("ray,rank,index"), std::string::npos);
}

// COPC queried in place holds the LAS reader's coordinate bound (1e9 world units): the node
// holding a point beyond it is refused when it is decoded, with the reader's line for that point,
// at the byte where the node's chunk starts; the other nodes still decode. The file: two clusters
// of 250 points, about (0, 0, 0) and (1e6, 1e6, 1e6), written as COPC on scale 1 in nodes of up
// to 16 points, then its X scale (header byte 131, outside the compressed chunks) set to 1000, so
// that only the point stored at X = 1000001 lies beyond the bound (1000001000). Oracle: the LAS
// reader's refusal of the same file (its point number and text) and the file's own hierarchy
// (chunk offsets and point counts, file order by offset).
TEST(Copc, APointBeyondTheCoordinateBoundIsRefusedInPlaceAsTheReaderRefusesIt) {
  PointCloud pc;
  for (std::uint64_t i = 0; i < 500; ++i) {
    const double base = i < 250 ? 0.0 : 999000.0;
    pc.positions.emplace_back(base + double(i * 7919 % 1000), base + double(i * 104729 % 1000),
                              base + double(i * 1299709 % 1000));
  }
  pc.positions[321].x = 1000001;
  const fs::path las = temp_dir() / "bound_src.las", copc = temp_dir() / "bound.copc.laz";
  write_unit_grid_las(las, pc);
  io::CopcWriteOptions o;
  o.leaf_points = 16;
  io::write_copc(las, copc, o);
  ASSERT_EQ(patch_las_x_scale(copc, 1000), 1.0);

  const std::string reader = reader_error(copc);
  const std::size_t at = reader.find(": point ");
  ASSERT_NE(at, std::string::npos) << reader;
  const std::string point = reader.substr(at + 2);
  const std::uint64_t id = std::stoull(point.substr(6));
  EXPECT_EQ(point, "point " + std::to_string(id) + ": X coordinate is 1000001000 (stored integer 1000001 x scale 1000 + "
                   "offset 0; expected within +-1e+09, the coordinate bound in world units)");

  io::CopcIndex idx(copc);
  std::vector<io::CopcNode> nodes = idx.info().nodes;
  ASSERT_GT(nodes.size(), 2u);
  std::sort(nodes.begin(), nodes.end(), [](const io::CopcNode& a, const io::CopcNode& c) { return a.offset < c.offset; });
  std::uint64_t first = 0, chunk = 0, root_first = 0;
  bool bad_in_root = false;
  for (const io::CopcNode& n : nodes) {
    const std::uint64_t end = first + static_cast<std::uint64_t>(n.point_count);
    if (id >= first && id < end) chunk = n.offset, bad_in_root = n.level == 0;
    if (n.level == 0) root_first = first;
    first = end;
  }
  ASSERT_GT(chunk, 0u);
  const std::string expected = copc.string() + ": byte " + std::to_string(chunk) + ": " + point;
  const auto error_of = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const io::FormatError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  // The root decodes first (every node's ancestor): a point of its own reads as the reader's
  // arithmetic gives it, when the point beyond lies deeper.
  EXPECT_FALSE(bad_in_root) << "the test wants the point beyond the bound below the root";
  if (!bad_in_root) {
    const Vec3 p = idx.position_of(static_cast<PointIndex>(root_first));
    EXPECT_LE(std::abs(p.x), 1e9);
    EXPECT_EQ(std::fmod(p.x, 1000.0), 0.0) << p.x;  // stored integer x 1000
  }
  EXPECT_EQ(error_of([&] { (void)idx.position_of(static_cast<PointIndex>(id)); }), expected);
  // A query job whose ray crosses the point's cube meets the same refusal.
  jobs::QueryJobOptions q;
  q.cloud_file = copc;
  q.query.radius = 1;
  q.rays = {Ray(Vec3(-1, pc.positions[321].y, pc.positions[321].z), Vec3(1, 0, 0))};
  EXPECT_EQ(error_of([&] { (void)jobs::run_query(q); }), expected);
}

TEST(Copc, ARootCubeFieldOutOfRangeIsNamedAtItsOwnByte) {
  const fs::path p = deep_copc();
  if (p.empty()) GTEST_SKIP() << "las/autzen_trim.las not found";
  const std::vector<std::uint8_t> good = slurp(p);
  // COPC 1.0: the info VLR is the first VLR after the 375-byte LAS 1.4 header, so its payload
  // starts at byte 375 + 54 = 429 with center_x, center_y, center_z and halfsize (doubles).
  const auto error_with = [&](std::size_t at, double v) {
    std::vector<std::uint8_t> b = good;
    std::memcpy(&b[at], &v, sizeof v);
    try {
      (void)io::read_copc_info(b, "t.copc.laz");
    } catch (const io::FormatError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_with(429, inf), "t.copc.laz: byte 429: COPC root cube has center_x inf (expected a finite number)");
  EXPECT_EQ(error_with(437, nan), "t.copc.laz: byte 437: COPC root cube has center_y nan (expected a finite number)");
  EXPECT_EQ(error_with(445, -inf), "t.copc.laz: byte 445: COPC root cube has center_z -inf (expected a finite number)");
  EXPECT_EQ(error_with(453, -1.5),
            "t.copc.laz: byte 453: COPC root cube has halfsize -1.5 (expected a finite number > 0)");
  EXPECT_EQ(error_with(453, 0.0), "t.copc.laz: byte 453: COPC root cube has halfsize 0 (expected a finite number > 0)");
}

}  // namespace
}  // namespace rayscan::test
