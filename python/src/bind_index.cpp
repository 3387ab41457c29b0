// rayscan.Octree / KdTree / BruteForce, rayscan.open's Site (an index file or a COPC file queried in
// place) and their batch queries (ray, kNN, radius, box) on NumPy arrays. Every batch call converts
// its arguments while holding the GIL, then releases it and runs the core's TBB batch API
// (rayscan/octree/batch.hpp); results are flattened into CSR arrays.
#include "arrays.hpp"
#include "bindings.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/list_text.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/batch.hpp"
#include "rayscan/site/site.hpp"

#include <pybind11/stl.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <type_traits>

namespace rayscan::python {

namespace {

/// The index object behind Octree, KdTree and BruteForce.
struct PyIndex {
  AnyIndex index;
  IndexOptions options;
  std::size_t size = 0;

  /// f(the concrete index), as Site::visit.
  template <class F>
  decltype(auto) visit(F&& f) const {
    return std::visit(std::forward<F>(f), index);
  }
  void after_query() const {}
};

/// The message of a closed Site's use, as a closed file's ("I/O operation on closed file").
constexpr const char* kClosedSite = "I/O operation on closed site";

/// The object behind rayscan.Site (rayscan.open): an index file mapped, a COPC file's hierarchy,
/// or another point file read and indexed in memory (Site::open); empty once closed (close()
/// releases the mapping, the decoded nodes or the points, and every later use raises ValueError).
/// Queries from several Python threads may run at once (each releases the GIL): each holds
/// `queries` shared while it runs, and the trim of a COPC file's node cache, which must not run
/// during a query (CopcIndex::trim_cache), takes it exclusively, as close() does. A trim that
/// finds another thread's query running stays pending and is done by the next query part to end
/// alone, so the cache returns to its budget as soon as the queries pause.
struct PySite {
  std::optional<Site> site;
  std::string path;
  std::unique_ptr<std::shared_mutex> queries = std::make_unique<std::shared_mutex>();
  std::unique_ptr<std::atomic<bool>> trim_pending = std::make_unique<std::atomic<bool>>(false);

  /// The open site, for a use with the GIL held; ValueError kClosedSite once closed.
  const Site& open_site() const {
    if (!site) throw py::value_error(kClosedSite);
    return *site;
  }
  template <class F>
  decltype(auto) visit(F&& f) const {
    struct Done {
      const PySite& s;
      ~Done() { s.trim_if_pending(); }
    } done{*this};
    std::shared_lock running(*queries);
    if (!site) throw py::value_error(kClosedSite);  // closed by another thread since the call began
    return site->visit(std::forward<F>(f));
  }
  /// A COPC file keeps the nodes its queries decoded: trimmed to the cache budget after each call.
  void after_query() const {
    if (site && site->copc()) {
      trim_pending->store(true);
      trim_if_pending();
    }
  }
  /// The pending trim, when no other query runs (else left pending). Never throws: a query's own
  /// error, or KeyboardInterrupt, must not be replaced by the trim's.
  void trim_if_pending() const noexcept {
    if (!trim_pending->load()) return;
    std::unique_lock alone(*queries, std::try_to_lock);
    if (!alone || !trim_pending->exchange(false)) return;
    try {
      if (io::CopcIndex* c = site ? site->copc() : nullptr) c->trim_cache();
    } catch (...) {
      trim_pending->store(true);
    }
  }
  /// Releases the site once the queries running in other threads have ended (waiting for them
  /// without the GIL, which they take back between chunks). Closing twice is allowed, as for files.
  void close() {
    py::gil_scoped_release nogil;
    std::unique_lock alone(*queries);
    site.reset();
  }
};

/// Runs `self.after_query()` when the scope ends, also when a batch ends in KeyboardInterrupt.
template <class Self>
struct AfterQuery {
  const Self& self;
  ~AfterQuery() {
    try {
      self.after_query();
    } catch (...) {
    }
  }
};

/// What a query's radius is, for its TypeError.
constexpr const char* kRadiusExpected = "a number >= 0 (world units; inf for no limit)";

RayOrder parse_order(const std::string& s) {
  if (s == "ray") return RayOrder::ray;
  if (s == "time") return RayOrder::time;
  if (s == "sphere_hit") return RayOrder::sphere_hit;
  throw py::value_error("order '" + s + "': expected 'ray', 'time' or 'sphere_hit'");
}

std::uint32_t parse_count(py::handle v, const char* name) {
  return static_cast<std::uint32_t>(int_arg(v, name, 1, 0xFFFFFFFFll, "an integer in [1, 2^32 - 1]"));
}

/// An octree depth argument in [lo, 21] (depth: 0..21; max_depth: 1..21, as OctreeConfig::validate),
/// None for the default.
std::optional<unsigned> parse_depth(py::handle v, const char* name, long long lo) {
  return opt_int_arg<unsigned>(v, name, lo, 21, "None or an integer in [" + std::to_string(lo) + ", 21]");
}

PyIndex build(py::handle xyz, const IndexOptions& opts) {
  const Vec3Rows pts = as_vec3_rows(xyz, "xyz");
  // The trees refuse a non-finite point ("octree: point 5 has a non-finite coordinate"); the brute
  // force scan would keep it and return it as a result, so it is refused here in the same words.
  if (opts.type == "brute")
    for (std::size_t i = 0; i < pts.rows.size(); ++i) {
      const Vec3& p = pts.rows[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw py::value_error("brute: point " + std::to_string(i) + " has a non-finite coordinate");
    }
  PyIndex out{BruteForceIndex(std::span<const Vec3>{}), opts, pts.rows.size()};
  {
    py::gil_scoped_release nogil;
    out.index = make_index(pts.rows, opts);
  }
  return out;
}

/// How long one chunk of a batch runs between two looks for Ctrl-C, in seconds: a batch answers
/// an interruption within about this (or within its slowest query, when one query takes longer),
/// and re-entering the interpreter and the chunk's last, unbalanced moment cost a few percent of it.
constexpr double kChunkSeconds = 0.1;

/// Pieces per thread a chunk is cut into (work stealing balances them): the threads idle at a
/// chunk's end for about one piece at most, 1/kPiecesPerThread of the chunk.
constexpr std::size_t kPiecesPerThread = 8;

/// A batch of n queries, f(first, count) returning one vector of results per query of that range,
/// answered on `threads` threads (0 = all cores; in its own TBB arena otherwise, the jobs' rule
/// capping it at the cores) in chunks sized by time: the first holds one query per thread, each
/// next one as many as the last one's pace fits in kChunkSeconds (at most twice the last; a query
/// can cost microseconds or, returning thousands of points, milliseconds). A chunk is cut into
/// pieces spread over the threads, so that a chunk of a few slow queries still runs on all of them
/// (the batch API's own grain would run it on one). Between chunks the GIL is taken back briefly
/// to look for a pending signal, so Ctrl-C in a notebook stops a long batch (raised as
/// KeyboardInterrupt) instead of waiting for its end. The exception carries a note (PEP 678,
/// Python 3.11+) "interrupted after D of N queries": how much of the batch ran, its answers
/// dropped with the exception. The answers do not depend on the chunks or pieces (each query is
/// answered alone). Call with the GIL released.
template <class F>
auto interruptible_batch(std::size_t n, unsigned threads, F&& f) {
  decltype(f(std::size_t{0}, std::size_t{0})) all(n);
  if (n == 0) {
    (void)f(0, 0);  // no query, but the batch API's checks of the options (a bad radius) still run
    return all;
  }
  std::optional<tbb::task_arena> arena;
  if (threads != 0) arena.emplace(static_cast<int>(resolve_threads(threads)));
  const auto width = static_cast<std::size_t>(
      std::max(1, arena ? arena->max_concurrency() : tbb::this_task_arena::max_concurrency()));
  std::size_t first = 0, count = width;
  while (first < n) {
    count = std::min(count, n - first);
    const std::size_t piece = std::max<std::size_t>(1, count / (width * kPiecesPerThread));
    const auto chunk = [&] {
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(first, first + count, piece),
          [&](const tbb::blocked_range<std::size_t>& r) {
            auto part = f(r.begin(), r.size());
            std::move(part.begin(), part.end(), all.begin() + static_cast<std::ptrdiff_t>(r.begin()));
          },
          tbb::simple_partitioner());
    };
    const auto t0 = std::chrono::steady_clock::now();
    if (arena) arena->execute(chunk);
    else chunk();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    first += count;
    if (first < n) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) {
        py::error_already_set e;
        if (py::hasattr(e.value(), "add_note"))
          e.value().attr("add_note")("interrupted after " + std::to_string(first) + " of " + std::to_string(n) +
                                     " queries");
        throw e;
      }
    }
    const double grow = seconds > 0.0 ? std::min(2.0, kChunkSeconds / seconds) : 2.0;
    count = std::max(width, static_cast<std::size_t>(static_cast<double>(count) * grow));
  }
  return all;
}

/// Row i of a broadcast pair: a one-row array repeats.
inline const Vec3& row(std::span<const Vec3> a, std::size_t i) { return a.size() == 1 ? a[0] : a[i]; }

/// Number of queries of two broadcast (M, 3) / (3,) arguments, as NumPy broadcasts them: equal
/// counts, or one row that repeats (also over zero rows: an empty batch gives no queries).
/// ValueError when they disagree.
std::size_t broadcast_count(const Vec3Rows& a, const char* an, const Vec3Rows& b, const char* bn) {
  const std::size_t na = a.rows.size(), nb = b.rows.size();
  if (na == nb || nb == 1) return na;
  if (na == 1) return nb;
  throw py::value_error(std::string(an) + " has " + std::to_string(na) + " rows but " + bn + " has " +
                        std::to_string(nb) + " (expected equal counts, or one row to broadcast)");
}

/// Prefix sums of the per-query result counts: offsets (M + 1,).
template <class T>
std::vector<std::int64_t> csr_offsets(const std::vector<std::vector<T>>& r) {
  std::vector<std::int64_t> off(r.size() + 1, 0);
  for (std::size_t i = 0; i < r.size(); ++i)
    off[i + 1] = off[i] + static_cast<std::int64_t>(r[i].size());
  return off;
}

/// Fill the flat arrays from per-query vectors in parallel: f(hit, flat position).
template <class T, class F>
void csr_fill(const std::vector<std::vector<T>>& r, const std::vector<std::int64_t>& off, F&& f) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, r.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& b) {
                      for (std::size_t i = b.begin(); i != b.end(); ++i) {
                        auto pos = static_cast<std::size_t>(off[i]);
                        for (const T& h : r[i]) f(h, pos++);
                      }
                    });
}

template <class Index>
py::dict ray_query(const Index& self, py::handle origins, py::handle directions,
                   const py::object& k, py::handle radius, py::handle t_min, py::handle t_max,
                   py::handle order, py::handle any_hit_arg, py::handle allow_all_arg, py::handle threads) {
  const unsigned nthreads = parse_threads(threads);
  const bool any_hit = bool_arg(any_hit_arg, "any_hit");
  const bool allow_all = bool_arg(allow_all_arg, "allow_all");
  RayQuery q;
  q.k = parse_k(k);
  q.radius = float_arg(radius, "radius", kRadiusExpected);
  q.t_min = float_arg(t_min, "t_min", "a number (world units along the ray)");
  q.t_max = float_arg(t_max, "t_max", "a number (world units along the ray)");
  q.order = parse_order(str_arg(order, "order", "'ray', 'time' or 'sphere_hit'"));
  q.any_hit = any_hit;
  q.validate();
  const Vec3Rows o = as_vec3_rows(origins, "origins", true);
  const Vec3Rows d = as_vec3_rows(directions, "directions", true);
  const std::size_t m = broadcast_count(o, "origins", d, "directions");
  std::vector<std::int64_t> off;
  std::vector<std::int64_t> idx;
  std::vector<double> t, dist;
  std::vector<Ray> rays;
  rays.reserve(m);
  for (std::size_t i = 0; i < m; ++i) {
    try {
      rays.emplace_back(row(o.rows, i), row(d.rows, i));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("ray " + std::to_string(i) + ": " + e.what());
    }
  }
  // Checked after the arguments themselves: with neither bound every ray returns every point (N x M
  // hits), which is almost never meant and can exhaust memory.
  if (q.k == kAllPoints && !std::isfinite(q.radius) && !q.any_hit && !allow_all)
    throw py::value_error("ray_query: neither k nor a finite radius: every ray would return every point; give k=, "
                          "radius= or any_hit=True, or allow_all=True to ask for all of them");
  {
    py::gil_scoped_release nogil;
    const AfterQuery<std::remove_cvref_t<decltype(self)>> trim_after{self};
    const auto res = interruptible_batch(rays.size(), nthreads, [&](std::size_t first, std::size_t count) {
      const std::span<const Ray> part(rays.data() + first, count);
      return self.visit([&](const auto& ix) { return ray_query_batch(ix, part, q); });
    });
    off = csr_offsets(res);
    const auto n = static_cast<std::size_t>(off.back());
    idx.resize(n);
    t.resize(n);
    dist.resize(n);
    csr_fill(res, off, [&](const RayHit& h, std::size_t p) {
      idx[p] = h.index;
      t[p] = h.t;
      dist[p] = h.distance;
    });
  }
  py::dict out;
  out["offsets"] = to_numpy(std::move(off));
  out["indices"] = to_numpy(std::move(idx));
  out["t"] = to_numpy(std::move(t));
  out["distance"] = to_numpy(std::move(dist));
  return out;
}

template <class Index>
py::dict knn(const Index& self, py::handle points, const py::object& k, py::handle radius_arg,
             py::handle threads) {
  const unsigned nthreads = parse_threads(threads);
  const std::size_t kk = parse_k(k);
  const double radius = float_arg(radius_arg, "radius", kRadiusExpected);
  const Vec3Rows p = as_vec3_rows(points, "points", true);
  std::vector<std::int64_t> off, idx;
  std::vector<double> dist;
  {
    py::gil_scoped_release nogil;
    // knn_query_batch's refusal in its words, numbering the caller's row: the batch runs in pieces,
    // whose own numbering starts again at 0. After a bad radius, which the batch refuses first.
    for (std::size_t i = 0; radius >= 0.0 && i < p.rows.size(); ++i)
      if (!std::isfinite(p.rows[i].x) || !std::isfinite(p.rows[i].y) || !std::isfinite(p.rows[i].z))
        throw std::invalid_argument("knn query: query point " + std::to_string(i) + " is not finite");
    const AfterQuery<std::remove_cvref_t<decltype(self)>> trim_after{self};
    const auto res = interruptible_batch(p.rows.size(), nthreads, [&](std::size_t first, std::size_t count) {
      const std::span<const Vec3> part(p.rows.data() + first, count);
      return self.visit([&](const auto& ix) { return knn_query_batch(ix, part, kk, radius); });
    });
    off = csr_offsets(res);
    const auto n = static_cast<std::size_t>(off.back());
    idx.resize(n);
    dist.resize(n);
    csr_fill(res, off, [&](const Neighbor& h, std::size_t i) {
      idx[i] = h.index;
      dist[i] = h.distance;
    });
  }
  py::dict out;
  out["offsets"] = to_numpy(std::move(off));
  out["indices"] = to_numpy(std::move(idx));
  out["distance"] = to_numpy(std::move(dist));
  return out;
}

template <class Index>
py::dict box(const Index& self, py::handle lo, py::handle hi, py::handle threads) {
  const unsigned nthreads = parse_threads(threads);
  const Vec3Rows l = as_vec3_rows(lo, "lo", true);
  const Vec3Rows h = as_vec3_rows(hi, "hi", true);
  const std::size_t m = broadcast_count(l, "lo", h, "hi");
  std::vector<std::int64_t> off, idx;
  {
    py::gil_scoped_release nogil;
    std::vector<AABB> boxes(m);
    for (std::size_t i = 0; i < m; ++i) {
      const Vec3 a = row(l.rows, i), b = row(h.rows, i);
      // Infinite bounds are half-open boxes; only NaN (no order) is refused. Tested per coordinate:
      // a sum of -inf and inf would be NaN.
      if (std::isnan(a.x) || std::isnan(a.y) || std::isnan(a.z) || std::isnan(b.x) || std::isnan(b.y) ||
          std::isnan(b.z))
        throw std::invalid_argument("box " + std::to_string(i) + ": lo and hi must not be NaN");
      boxes[i] = AABB{a, b};
    }
    const AfterQuery<std::remove_cvref_t<decltype(self)>> trim_after{self};
    const auto res = interruptible_batch(boxes.size(), nthreads, [&](std::size_t first, std::size_t count) {
      const std::span<const AABB> part(boxes.data() + first, count);
      return self.visit([&](const auto& ix) { return box_query_batch(ix, part); });
    });
    off = csr_offsets(res);
    idx.resize(static_cast<std::size_t>(off.back()));
    csr_fill(res, off, [&](PointIndex v, std::size_t i) { idx[i] = v; });
  }
  py::dict out;
  out["offsets"] = to_numpy(std::move(off));
  out["indices"] = to_numpy(std::move(idx));
  return out;
}

/// The query methods every index class shares (the Python mixin _QueriesMixin calls them).
template <class Class>
void def_queries(Class& c) {
  using Index = typename Class::type;
  c.def("_ray_query", &ray_query<Index>, py::arg("origins"), py::arg("directions"), py::arg("k") = py::none(),
        py::arg("radius") = kInf, py::arg("t_min") = -kInf, py::arg("t_max") = kInf, py::arg("order") = "ray",
        py::arg("any_hit") = false, py::arg("allow_all") = false, py::arg("threads") = 0)
      .def("_knn", &knn<Index>, py::arg("points"), py::arg("k") = py::none(), py::arg("radius") = kInf,
           py::arg("threads") = 0)
      .def("_box", &box<Index>, py::arg("lo"), py::arg("hi"), py::arg("threads") = 0);
}

const char* storage_name(SiteStorage s) {
  switch (s) {
    case SiteStorage::index_file: return "index_file";
    case SiteStorage::copc: return "copc";
    case SiteStorage::memory: break;
  }
  return "memory";
}

}  // namespace

void bind_index(py::module_& m) {
  auto base = py::class_<PyIndex>(m, "_Index", R"doc(
Base of the spatial indexes (Octree, KdTree, BruteForce). Built over an (N, 3) float64 copy of
the points (positions are copied and reordered; the input array is not kept). Queries run on all
cores (TBB) with the GIL released; results use original point indices 0..N-1.)doc");
  base.def("__len__", [](const PyIndex& s) { return s.size; })
      .def_property_readonly("memory_bytes",
                             [](const PyIndex& s) { return index_memory_bytes(s.index); },
                             "Bytes the index holds (positions copy, ids, nodes).")
      .def_property_readonly("type", [](const PyIndex& s) { return s.options.type; },
                             "Index type name as in `rayscan query --index`.")
      ;
  def_queries(base);

  struct PyOctree : PyIndex {};
  py::class_<PyOctree, PyIndex>(m, "_Octree")
      .def(py::init([](py::handle xyz, py::handle layout_arg, py::handle capacity,
                       py::handle depth_arg, py::handle max_depth_arg, py::handle insertion) {
             const OctreeLayout layout =
                 parse_octree_layout(str_arg(layout_arg, "layout", join_alternatives(octree_layout_names("'"))));
             IndexOptions o;
             o.type = octree_index_type(layout);
             if (!capacity.is_none()) o.capacity = parse_count(capacity, "capacity");
             const std::optional<unsigned> depth = parse_depth(depth_arg, "depth", 0);
             const std::optional<unsigned> max_depth = parse_depth(max_depth_arg, "max_depth", 1);
             o.insertion = bool_arg(insertion, "insertion");
             // An argument the layout does not use is refused rather than ignored (a repr showing it
             // would lie), by the rule `rayscan query` and `rayscan index` apply: ValueError naming
             // the keyword (the option's field name) and the layouts that take it.
             GivenIndexOptions given;
             given.capacity = o.capacity.has_value();
             given.max_depth = max_depth.has_value();
             given.depth = depth.has_value();
             given.insertion = o.insertion;
             IndexChoiceWords words;
             words.option = "layout=";
             words.layouts = true;
             words.quote = "'";
             check_applicable(o.type, given, words);
             if (depth) o.depth = *depth;
             if (max_depth) o.max_depth = *max_depth;
             return PyOctree{build(xyz, o)};
           }),
           py::arg("xyz"), py::arg("layout") = "adaptive", py::arg("capacity") = py::none(),
           py::arg("depth") = py::none(), py::arg("max_depth") = py::none(), py::arg("insertion") = false)
      .def_property_readonly("layout", [](const PyOctree& s) { return s.options.type.substr(7); },
                             "\"adaptive\", \"layered\" or \"fixed\".")
      .def_property_readonly("capacity",
                             [](const PyOctree& s) -> std::optional<std::uint32_t> {
                               if (!index_option_applies(s.options.type, IndexOption::capacity)) return std::nullopt;
                               return index_capacity(s.options);
                             },
                             "The capacity built with: most points per leaf (adaptive) or per node (layered); "
                             "the layout's default when None was given. None for layout 'fixed', which has "
                             "no capacity (its leaves lie at `depth` whatever they hold).")
      .def_property_readonly("node_count",
                             [](const PyOctree& s) { return std::get<Octree>(s.index).node_count(); },
                             "Number of nodes, inner nodes and leaves.")
      .def_property_readonly("depth", [](const PyOctree& s) { return std::get<Octree>(s.index).depth(); },
                             "Depth of the deepest node (the root is depth 0).");

  struct PyKdTree : PyIndex {};
  py::class_<PyKdTree, PyIndex>(m, "_KdTree")
      .def(py::init([](py::handle xyz, py::handle capacity) {
             IndexOptions o;
             o.type = "kdtree";
             if (!capacity.is_none()) o.capacity = parse_count(capacity, "capacity");
             return PyKdTree{build(xyz, o)};
           }),
           py::arg("xyz"), py::arg("capacity") = py::none())
      .def_property_readonly("capacity", [](const PyKdTree& s) { return index_capacity(s.options); },
                             "Most points per leaf the tree was built with (32 when None was given).")
      .def_property_readonly("node_count",
                             [](const PyKdTree& s) { return std::get<KdTree>(s.index).node_count(); },
                             "Number of nodes, inner nodes and leaves.");

  struct PyBrute : PyIndex {};
  py::class_<PyBrute, PyIndex>(m, "_BruteForce").def(py::init([](py::handle xyz) {
    IndexOptions o;
    o.type = "brute";
    return PyBrute{build(xyz, o)};
  }), py::arg("xyz"));

  auto site = py::class_<PySite>(m, "_Site", R"doc(
A point file opened for queries without reading it whole where its storage allows: an index
file (.rsi, built by `rayscan index`) is memory-mapped and queried in place, a COPC file's own
octree is queried in place (nodes decoded as queries reach them, kept within `cache`, "2G" by
default); any
other point file is read and indexed in memory (an adaptive octree). Results use the points'
original indices (the order of the sources), except on an index file built without ids (`rayscan
index` without `--attributes id`), whose results are index slots: has_ids says which.)doc");
  site.def(py::init([](py::handle path, py::handle cache) {
             const std::string p = path_arg(path, "path");
             SiteOptions options;
             options.copc_cache_bytes = cache_arg(cache);
             const InputFile probe(p);  // an OSError for its errno (module.cpp) when it cannot be opened
             std::optional<Site> s;
             {
               py::gil_scoped_release nogil;
               s.emplace(Site::open(p, options));
             }
             return PySite{std::move(s), p};
           }),
           py::arg("path"), py::arg("cache") = "2G");
  def_queries(site);
  site.def("__len__", [](const PySite& s) { return s.open_site().size(); })
      .def_property_readonly("storage", [](const PySite& s) { return storage_name(s.open_site().storage()); },
                             "\"index_file\" (.rsi, mapped), \"copc\" (in place) or \"memory\" (read and indexed).")
      .def_property_readonly("path", [](const PySite& s) { return s.path; }, "The file name given to rayscan.open.")
      .def_property_readonly("closed", [](const PySite& s) { return !s.site.has_value(); },
                             "True once close() has run.")
      .def("close", &PySite::close,
           "Release the file's mapping, a COPC file's decoded nodes or the points read, once the queries "
           "running in other threads have ended; every later query or size raises ValueError. Closing a "
           "closed site does nothing.")
      .def_property_readonly("has_ids",
                             [](const PySite& s) {
                               const io::MappedIndex* m = s.open_site().index_file();
                               return m == nullptr || m->has_ids();
                             },
                             "True when query results name points by their original ids (their number in the "
                             "source files, in order, as rayscan.read numbers them): always for a COPC or "
                             "another point file, and for an index file built with `rayscan index --attributes id`. "
                             "False for an index file without the ids section: results are index slots (depth-first "
                             "node order), as `rayscan info` says \"ids: not stored (points in index order)\".");
  // rayscan.open's check of its cache argument alone, for rayscan.dask's checks at the call (its
  // tasks open the file).
  m.def("_check_cache", [](py::handle cache) { cache_arg(cache); }, py::arg("cache"));
}

}  // namespace rayscan::python
