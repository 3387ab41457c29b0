// bench_table1: the workload of Table 1 of Teuscher et al., "Ray Queries On Raw Point Clouds"
// (section 5.1): N uniform points in the unit cube; construction by insertion and by bulk loading,
// Q box range queries (box spanned by two random points) and Q kNN queries (k = 8). rayscan's
// octree (layered, fixed, adaptive) and kd-tree run side by side in the same process with the
// peers Boost.Geometry rtree (R*-tree; bulk = packing constructor, insertion = R* inserts) and
// nanoflann (KDTreeSingleIndexAdaptor). Repetitions are interleaved (every contender once per
// round, the starting contender rotating) and the median is reported. Before timing, every answer
// of every contender is cross-checked against the others; a disagreement aborts (exit 3).
#include "bench_cli.hpp"
#include "bench_common.hpp"

#include "rayscan/octree/kdtree.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/simd.hpp"

#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <nanoflann.hpp>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using rayscan::AABB;
using rayscan::PointIndex;
using rayscan::Vec3;
namespace rb = rayscan::bench;

namespace {

// ---- peers --------------------------------------------------------------------------------------

using BPoint = bg::model::point<double, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BPoint, PointIndex>;
using BTree = bgi::rtree<BValue, bgi::rstar<16, 4>>;

struct NanoCloud {
  const std::vector<Vec3>* pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts->size(); }
  [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return (*pts)[i][static_cast<int>(dim)];
  }
  template <class BBOX>
  bool kdtree_get_bbox(BBOX&) const {
    return false;
  }
};
using NanoTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, NanoCloud>,
                                                     NanoCloud, 3, PointIndex>;

// nanoflann 1.4 has no box range query; this is the obvious one over its public tree (leaf index
// ranges in vAcc, split planes divlow/divhigh), reported as "nanoflann (+ box traversal)".
void nano_box(const NanoTree& t, const std::vector<Vec3>& pts, const AABB& box,
              std::vector<PointIndex>& out) {
  out.clear();
  if (!t.root_node) return;
  thread_local std::vector<const NanoTree::Node*> stack;
  stack.clear();
  stack.push_back(t.root_node);
  while (!stack.empty()) {
    const NanoTree::Node* n = stack.back();
    stack.pop_back();
    if (!n->child1) {
      for (auto i = n->node_type.lr.left; i < n->node_type.lr.right; ++i) {
        const PointIndex id = t.vAcc[i];
        if (box.contains(pts[id])) out.push_back(id);
      }
      continue;
    }
    const int f = n->node_type.sub.divfeat;
    if (box.lo[f] <= n->node_type.sub.divlow) stack.push_back(n->child1);
    if (box.hi[f] >= n->node_type.sub.divhigh) stack.push_back(n->child2);
  }
}

// ---- workload -----------------------------------------------------------------------------------

struct Workload {
  std::vector<Vec3> pts;
  std::vector<AABB> boxes;
  std::vector<Vec3> knn_q;
  std::size_t k = 8;
};

/// One contender: optional insertion build, bulk build, and the two query loops over the bulk
/// index. Each query loop returns a checksum (total result count + sum of ids) compared across
/// contenders after every timed run.
struct Contender {
  std::string name;
  bool peer = false;
  std::function<void()> build_insert;  // empty when the index has no insertion build
  std::function<void()> build_bulk;    // builds the index the queries then use
  std::function<std::uint64_t()> run_box;
  std::function<std::uint64_t()> run_knn;
  // Answers for the cross-check (computed once, outside timing).
  std::function<std::vector<PointIndex>(const AABB&)> box_ids;
  std::function<std::vector<PointIndex>(const Vec3&)> knn_ids;
  std::function<void()> release;
  std::vector<double> t_insert, t_bulk, t_box, t_knn;
};

/// The contenders with each one `pick` accepts replaced by `count` variants: variant i (of
/// setting(i) = {name suffix, set-up}) runs the set-up before each of its steps (an A/B of a
/// process-wide switch, interleaved in every round).
template <class Pick, class Setting>
std::vector<Contender> variants(const std::vector<Contender>& cs, Pick pick, std::size_t count, Setting setting) {
  std::vector<Contender> out;
  for (const Contender& c : cs) {
    if (!pick(c)) {
      out.push_back(c);
      continue;
    }
    for (std::size_t i = 0; i < count; ++i) {
      const auto [suffix, set] = setting(i);
      Contender d = c;
      d.name += suffix;
      d.build_bulk = [set, f = c.build_bulk] { set(); f(); };
      if (c.build_insert) d.build_insert = [set, f = c.build_insert] { set(); f(); };
      d.run_box = [set, f = c.run_box] { set(); return f(); };
      d.run_knn = [set, f = c.run_knn] { set(); return f(); };
      d.box_ids = [set, f = c.box_ids](const AABB& b) { set(); return f(b); };
      d.knn_ids = [set, f = c.knn_ids](const Vec3& q) { set(); return f(q); };
      out.push_back(std::move(d));
    }
  }
  return out;
}

std::uint64_t fold(std::uint64_t acc, PointIndex id) { return acc * 1000003u + id + 1; }

// A set-valued checksum (independent of result order): count and sum of ids.
struct Sum {
  std::uint64_t n = 0, s = 0;
  void add(PointIndex id) {
    ++n;
    s += id;
  }
  [[nodiscard]] std::uint64_t value() const { return fold(n, static_cast<PointIndex>(s)) ^ (s << 20); }
};

template <class Index>
Contender rayscan_contender(const std::string& name, const Workload& w,
                            std::function<Index()> bulk, std::function<Index()> insert) {
  auto idx = std::make_shared<std::optional<Index>>();
  Contender c;
  c.name = name;
  if (insert) c.build_insert = [idx, insert] { idx->reset(); idx->emplace(insert()); };
  c.build_bulk = [idx, bulk] { idx->reset(); idx->emplace(bulk()); };
  c.run_box = [idx, &w] {
    std::vector<PointIndex> out;
    Sum sum;
    for (const AABB& b : w.boxes) {
      rayscan::box_query(**idx, b, out);
      for (PointIndex id : out) sum.add(id);
    }
    return sum.value();
  };
  c.run_knn = [idx, &w] {
    std::vector<rayscan::Neighbor> out;
    Sum sum;
    for (const Vec3& q : w.knn_q) {
      rayscan::knn_query(**idx, q, w.k, rayscan::kInf, out);
      for (const auto& nb : out) sum.add(nb.index);
    }
    return sum.value();
  };
  c.box_ids = [idx](const AABB& b) {
    std::vector<PointIndex> out;
    rayscan::box_query(**idx, b, out);
    return out;
  };
  c.knn_ids = [idx, &w](const Vec3& q) {
    std::vector<rayscan::Neighbor> nb;
    rayscan::knn_query(**idx, q, w.k, rayscan::kInf, nb);
    std::vector<PointIndex> out;
    for (const auto& n : nb) out.push_back(n.index);
    return out;
  };
  c.release = [idx] { idx->reset(); };
  return c;
}

Contender boost_contender(const Workload& w) {
  auto tree = std::make_shared<std::optional<BTree>>();
  Contender c;
  c.name = "Boost rtree R*";
  c.peer = true;
  auto values = [&w] {
    std::vector<BValue> v;
    v.reserve(w.pts.size());
    for (std::size_t i = 0; i < w.pts.size(); ++i)
      v.emplace_back(BPoint(w.pts[i].x, w.pts[i].y, w.pts[i].z), static_cast<PointIndex>(i));
    return v;
  };
  c.build_insert = [tree, &w] {
    tree->reset();
    tree->emplace();
    for (std::size_t i = 0; i < w.pts.size(); ++i)
      (*tree)->insert(BValue(BPoint(w.pts[i].x, w.pts[i].y, w.pts[i].z), static_cast<PointIndex>(i)));
  };
  c.build_bulk = [tree, values] {
    tree->reset();
    const std::vector<BValue> v = values();
    tree->emplace(v.begin(), v.end());  // packing (STR bulk loading) constructor
  };
  c.run_box = [tree, &w] {
    std::vector<BValue> out;
    Sum sum;
    for (const AABB& b : w.boxes) {
      out.clear();
      (*tree)->query(bgi::intersects(BBox(BPoint(b.lo.x, b.lo.y, b.lo.z), BPoint(b.hi.x, b.hi.y, b.hi.z))),
                     std::back_inserter(out));
      for (const BValue& v : out) sum.add(v.second);
    }
    return sum.value();
  };
  c.run_knn = [tree, &w] {
    std::vector<BValue> out;
    Sum sum;
    for (const Vec3& q : w.knn_q) {
      out.clear();
      (*tree)->query(bgi::nearest(BPoint(q.x, q.y, q.z), static_cast<unsigned>(w.k)),
                     std::back_inserter(out));
      for (const BValue& v : out) sum.add(v.second);
    }
    return sum.value();
  };
  c.box_ids = [tree](const AABB& b) {
    std::vector<BValue> out;
    (*tree)->query(bgi::intersects(BBox(BPoint(b.lo.x, b.lo.y, b.lo.z), BPoint(b.hi.x, b.hi.y, b.hi.z))),
                   std::back_inserter(out));
    std::vector<PointIndex> ids;
    for (const BValue& v : out) ids.push_back(v.second);
    return ids;
  };
  c.knn_ids = [tree, &w](const Vec3& q) {
    std::vector<BValue> out;
    (*tree)->query(bgi::nearest(BPoint(q.x, q.y, q.z), static_cast<unsigned>(w.k)),
                   std::back_inserter(out));
    std::vector<PointIndex> ids;
    for (const BValue& v : out) ids.push_back(v.second);
    return ids;
  };
  c.release = [tree] { tree->reset(); };
  return c;
}

Contender nanoflann_contender(const Workload& w, std::size_t leaf) {
  struct State {
    NanoCloud cloud;
    std::unique_ptr<NanoTree> tree;
  };
  auto st = std::make_shared<State>();
  st->cloud.pts = &w.pts;
  Contender c;
  c.name = "nanoflann kd-tree";
  c.peer = true;
  c.build_bulk = [st, leaf] {
    st->tree.reset();
    st->tree = std::make_unique<NanoTree>(3, st->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
  };
  c.run_box = [st, &w] {
    std::vector<PointIndex> out;
    Sum sum;
    for (const AABB& b : w.boxes) {
      nano_box(*st->tree, w.pts, b, out);
      for (PointIndex id : out) sum.add(id);
    }
    return sum.value();
  };
  c.run_knn = [st, &w] {
    std::vector<PointIndex> idx(w.k);
    std::vector<double> d2(w.k);
    Sum sum;
    for (const Vec3& q : w.knn_q) {
      const double qq[3] = {q.x, q.y, q.z};
      const std::size_t n = st->tree->knnSearch(qq, w.k, idx.data(), d2.data());
      for (std::size_t i = 0; i < n; ++i) sum.add(idx[i]);
    }
    return sum.value();
  };
  c.box_ids = [st, &w](const AABB& b) {
    std::vector<PointIndex> out;
    nano_box(*st->tree, w.pts, b, out);
    return out;
  };
  c.knn_ids = [st, &w](const Vec3& q) {
    std::vector<PointIndex> idx(w.k);
    std::vector<double> d2(w.k);
    const double qq[3] = {q.x, q.y, q.z};
    idx.resize(st->tree->knnSearch(qq, w.k, idx.data(), d2.data()));
    return idx;
  };
  c.release = [st] { st->tree.reset(); };
  return c;
}

// ---- cross-check --------------------------------------------------------------------------------

double dist2(const Vec3& a, const Vec3& b) {
  const Vec3 v = a - b;
  return glm::dot(v, v);
}

void cross_check(std::vector<Contender>& cs, const Workload& w) {
  for (auto& c : cs) c.build_bulk();
  for (std::size_t qi = 0; qi < w.boxes.size(); ++qi) {
    std::vector<PointIndex> ref = cs[0].box_ids(w.boxes[qi]);
    std::sort(ref.begin(), ref.end());
    for (std::size_t ci = 1; ci < cs.size(); ++ci) {
      std::vector<PointIndex> got = cs[ci].box_ids(w.boxes[qi]);
      std::sort(got.begin(), got.end());
      if (got != ref)
        rb::fail("box query " + std::to_string(qi) + ": " + cs[ci].name + " returns " +
                 std::to_string(got.size()) + " points, " + cs[0].name + " " +
                 std::to_string(ref.size()));
    }
  }
  for (std::size_t qi = 0; qi < w.knn_q.size(); ++qi) {
    const Vec3 q = w.knn_q[qi];
    std::vector<PointIndex> ref = cs[0].knn_ids(q);
    std::sort(ref.begin(), ref.end());
    double kth = 0;
    for (PointIndex id : ref) kth = std::max(kth, dist2(q, w.pts[id]));
    for (std::size_t ci = 1; ci < cs.size(); ++ci) {
      std::vector<PointIndex> got = cs[ci].knn_ids(q);
      std::sort(got.begin(), got.end());
      if (got == ref) continue;
      // Only a tie at the k-th distance may make the sets differ.
      bool tie_only = got.size() == ref.size();
      for (PointIndex id : got)
        if (!std::binary_search(ref.begin(), ref.end(), id) && dist2(q, w.pts[id]) != kth)
          tie_only = false;
      if (!tie_only)
        rb::fail("kNN query " + std::to_string(qi) + ": " + cs[ci].name + " and " + cs[0].name +
                 " return different neighbour sets");
    }
  }
  for (auto& c : cs) c.release();
}

// ---- report -------------------------------------------------------------------------------------

std::string fmt(double v) {
  if (std::isnan(v)) return "n/a";
  char buf[32];
  std::snprintf(buf, sizeof buf, v >= 100 ? "%.0f" : (v >= 10 ? "%.1f" : "%.2f"), v);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rayscan benchmark: paper Table 1 workload (construction, box range, kNN) vs "
               "Boost.Geometry rtree and nanoflann"};
  std::size_t n = 100000, queries = 1000, k = 8, reps = 7, nano_leaf = 10;
  std::uint64_t seed = 20240601;
  std::uint32_t capacity = 0, kd_leaf = 16;
  int fixed_depth = -1;
  bool no_insert = false;
  std::string only;
  std::vector<std::string> simd_paths;
  double box_edge = 0.0;
  bool entry_ab = false;
  app.add_option("--points", n, "number of uniform points in the unit cube")->capture_default_str();
  app.add_option("--queries", queries, "box queries and kNN queries (each)")->capture_default_str();
  app.add_option("-k", k, "k of the kNN queries")->capture_default_str();
  app.add_option("--reps", reps, "interleaved repetitions; the median is reported")->capture_default_str();
  app.add_option("--seed", seed, "seed of points and queries")->capture_default_str();
  app.add_option("--capacity", capacity,
                 "octree node capacity (layered, adaptive), points; 0 = each layout's library default "
                 "(rayscan::default_capacity: layered 32, adaptive 64), what a user's index has")
      ->capture_default_str();
  app.add_option("--fixed-depth", fixed_depth,
                 "octree-fixed leaf depth; -1 = ceil(log8(points / capacity))")->capture_default_str();
  app.add_option("--kd-leaf", kd_leaf, "rayscan kd-tree leaf size, points")->capture_default_str();
  app.add_option("--nano-leaf", nano_leaf, "nanoflann leaf_max_size, points")->capture_default_str();
  app.add_flag("--no-insert", no_insert, "skip the insertion builds");
  app.add_option("--only", only,
                 "run only the contenders whose name contains this text (e.g. \"octree layered\"; for "
                 "valgrind --tool=callgrind --toggle-collect on one index's queries)");
  app.add_option("--box-edge", box_edge,
                 "box queries as cubes of this edge around uniform centres (a neighbourhood, as normals "
                 "and observers query) instead of the paper's boxes spanned by two random points; 0 = "
                 "the paper's")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--simd-paths", simd_paths,
                 "comma-separated SIMD paths (scalar,sse2,avx2,avx512): each rayscan contender runs once per "
                 "path, named \"... [path]\", interleaved with the others in every round (an A/B of the "
                 "kernels in one process, where a shared machine's noise would swamp separate runs)")
      ->delimiter(',');
  app.add_flag("--entry-ab", entry_ab,
               "each rayscan octree contender also without the kNN's entry-point search "
               "(rayscan::set_entry_point_search(false)), named \"... /no-entry\", interleaved with the others "
               "in every round (an A/B in one process)");
  rayscan::bench::parse_or_exit(app, argc, argv);
  std::vector<rayscan::SimdPath> paths;
  for (const std::string& name : simd_paths) {
    const std::optional<rayscan::SimdPath> p = rayscan::parse_simd_path(name);
    if (!p || !rayscan::simd_path_supported(*p)) {
      std::cerr << "bench_table1: --simd-paths: \"" << name << "\" is not a path this CPU runs (scalar|sse2|avx2|avx512)\n";
      return 2;
    }
    paths.push_back(*p);
  }
  if (reps == 0 || n == 0) {
    std::cerr << "bench_table1: --reps and --points must be >= 1\n";
    return 2;
  }

  // Every contender runs on this one thread (the peers are single-threaded; rayscan's bulk build
  // would otherwise use TBB's parallel sort), and is timed by this thread's CPU clock.
  tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  Workload w;
  w.k = k;
  w.pts = rb::uniform_cube(n, seed);
  rb::Rng rng(seed + 1);
  for (std::size_t i = 0; i < queries; ++i) {
    AABB b;
    const Vec3 c = rng.point_in_unit_cube();
    b.expand(box_edge > 0.0 ? c - 0.5 * box_edge : c);
    b.expand(box_edge > 0.0 ? c + 0.5 * box_edge : rng.point_in_unit_cube());
    w.boxes.push_back(b);
  }
  for (std::size_t i = 0; i < queries; ++i) w.knn_q.push_back(rng.point_in_unit_cube());

  const auto capacity_of = [capacity](rayscan::OctreeLayout layout) {
    return capacity != 0 ? capacity : rayscan::default_capacity(layout);
  };
  const std::uint32_t leaf_capacity = capacity_of(rayscan::OctreeLayout::adaptive);
  const unsigned depth = fixed_depth >= 0
                             ? static_cast<unsigned>(fixed_depth)
                             : static_cast<unsigned>(std::max(
                                   0.0, std::ceil(std::log(static_cast<double>(n) / leaf_capacity) / std::log(8.0))));

  std::vector<Contender> cs;
  for (auto layout : {rayscan::OctreeLayout::layered, rayscan::OctreeLayout::fixed,
                      rayscan::OctreeLayout::adaptive}) {
    rayscan::OctreeConfig cfg;
    cfg.layout = layout;
    cfg.capacity = capacity_of(layout);
    cfg.depth = depth;
    const std::vector<Vec3>* p = &w.pts;
    std::function<rayscan::Octree()> ins;
    if (!no_insert) ins = [p, cfg] { return rayscan::Octree::build_by_insertion(*p, cfg); };
    cs.push_back(rayscan_contender<rayscan::Octree>(
        std::string("rayscan octree ") + rayscan::to_string(layout), w,
        [p, cfg] { return rayscan::Octree::build_bulk(*p, cfg); }, ins));
  }
  {
    const std::vector<Vec3>* p = &w.pts;
    cs.push_back(rayscan_contender<rayscan::KdTree>(
        "rayscan kd-tree", w, [p, kd_leaf] { return rayscan::KdTree(*p, kd_leaf); }, {}));
  }
  cs.push_back(boost_contender(w));
  if (no_insert) cs.back().build_insert = {};
  cs.push_back(nanoflann_contender(w, nano_leaf));
  if (!paths.empty()) {  // each rayscan contender once per path, the path set before each of its steps
    cs = variants(cs, [](const Contender& c) { return !c.peer; }, paths.size(), [&](std::size_t i) {
      const rayscan::SimdPath p = paths[i];
      return std::pair{std::string(" [") + rayscan::to_string(p) + "]", std::function<void()>([p] { rayscan::set_simd_path(p); })};
    });
  }
  if (entry_ab) {  // each octree contender with and without the search, set before each of its steps
    cs = variants(cs, [](const Contender& c) { return !c.peer && c.name.find("octree") != std::string::npos; }, 2,
                  [](std::size_t i) {
                    const bool on = i == 0;
                    return std::pair{std::string(on ? "" : " /no-entry"),
                                     std::function<void()>([on] { rayscan::set_entry_point_search(on); })};
                  });
  }
  if (!only.empty()) {
    std::erase_if(cs, [&](const Contender& c) { return c.name.find(only) == std::string::npos; });
    if (cs.empty()) {
      std::cerr << "bench_table1: no contender name contains \"" << only << "\"\n";
      return 2;
    }
  }

  std::printf("load average: %s\n", rb::loadavg().c_str());
  std::printf("bench_table1: %zu uniform points in the unit cube (seed %llu), %zu box queries (%s), "
              "%zu kNN queries (k = %zu), median of %zu interleaved rounds, 1 thread, thread CPU time\n",
              n, static_cast<unsigned long long>(seed), queries,
              box_edge > 0.0 ? ("cubes of edge " + std::to_string(box_edge)).c_str() : "spanned by two random points",
              queries, k, reps);
  std::printf("CPU: %s; octree capacity layered %u / adaptive %u, fixed depth %u, kd-tree leaf %u, "
              "nanoflann leaf %zu, Boost rtree rstar<16,4>\n",
              rb::cpu_model().c_str(), capacity_of(rayscan::OctreeLayout::layered), leaf_capacity, depth, kd_leaf,
              nano_leaf);
  std::fflush(stdout);

  cross_check(cs, w);
  std::printf("cross-check: all %zu contenders agree on %zu box and %zu kNN answers\n", cs.size(),
              w.boxes.size(), w.knn_q.size());
  std::fflush(stdout);

  std::uint64_t box_ref = 0, knn_ref = 0;
  for (std::size_t r = 0; r < reps; ++r) {
    for (std::size_t j = 0; j < cs.size(); ++j) {
      Contender& c = cs[(j + r) % cs.size()];
      if (c.build_insert) {
        rb::ThreadCpuStopwatch sw;
        c.build_insert();
        c.t_insert.push_back(sw.ms());
      }
      {
        rb::ThreadCpuStopwatch sw;
        c.build_bulk();
        c.t_bulk.push_back(sw.ms());
      }
      {
        rb::ThreadCpuStopwatch sw;
        const std::uint64_t s = c.run_box();
        c.t_box.push_back(sw.ms());
        if (box_ref == 0) box_ref = s;
        if (s != box_ref) rb::fail("box checksum of " + c.name + " differs in round " + std::to_string(r));
      }
      {
        rb::ThreadCpuStopwatch sw;
        const std::uint64_t s = c.run_knn();
        c.t_knn.push_back(sw.ms());
        if (knn_ref == 0) knn_ref = s;
        if (s != knn_ref) rb::fail("kNN checksum of " + c.name + " differs in round " + std::to_string(r));
      }
      c.release();
    }
  }

  struct Row {
    double ins, bulk, box, knn;
  };
  std::vector<Row> rows;
  for (const auto& c : cs)
    rows.push_back({rb::median(c.t_insert), rb::median(c.t_bulk), rb::median(c.t_box), rb::median(c.t_knn)});
  auto best_peer = [&](double Row::*f) {
    double b = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < cs.size(); ++i)
      if (cs[i].peer && !std::isnan(rows[i].*f)) b = std::isnan(b) ? rows[i].*f : std::min(b, rows[i].*f);
    return b;
  };
  const Row peer{best_peer(&Row::ins), best_peer(&Row::bulk), best_peer(&Row::box), best_peer(&Row::knn)};
  std::printf("\n| index | build (insertion) ms | build (bulk) ms | %zu box queries ms | %zu kNN queries ms |\n",
              queries, queries);
  std::printf("|---|---:|---:|---:|---:|\n");
  auto ratio = [](double a, double b) { return std::isnan(a) || std::isnan(b) ? std::string("") : " (" + fmt(a / b) + "x)"; };
  for (std::size_t i = 0; i < cs.size(); ++i) {
    const Row& x = rows[i];
    if (cs[i].peer)
      std::printf("| %s | %s | %s | %s | %s |\n", cs[i].name.c_str(), fmt(x.ins).c_str(),
                  fmt(x.bulk).c_str(), fmt(x.box).c_str(), fmt(x.knn).c_str());
    else
      std::printf("| %s | %s%s | %s%s | %s%s | %s%s |\n", cs[i].name.c_str(), fmt(x.ins).c_str(),
                  ratio(x.ins, peer.ins).c_str(), fmt(x.bulk).c_str(), ratio(x.bulk, peer.bulk).c_str(),
                  fmt(x.box).c_str(), ratio(x.box, peer.box).c_str(), fmt(x.knn).c_str(),
                  ratio(x.knn, peer.knn).c_str());
  }
  // box_query returns storage order, like the peers' tree order: no sort is timed.

  std::printf("(x) = rayscan time / fastest peer's time in the same column (goal: <= 1). "
              "Peers' bulk: Boost packing constructor, nanoflann buildIndex; insertion: Boost R* "
              "insert (nanoflann has none). nanoflann's box query is our traversal of its tree.\n");
  std::printf("load average at the end: %s\n", rb::loadavg().c_str());
  return 0;
}
