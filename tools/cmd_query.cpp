// `rayscan query`: the paper's ray query (Algorithm 1) from the command line; the job is
// jobs::run_query (rayscan/jobs/query.hpp).
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/jobs/query.hpp"
#include "atomic_file.hpp"

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <utility>
#include <vector>

namespace rayscan::cli {

namespace {

struct QueryOptions {
  std::string cloud, rays, out, order = "ray", cache = "2G";
  IndexOptions index;
  std::uint32_t capacity = 0;  // --capacity (0: not given; the index type's default)
  long long k = -1;
  double radius = kInf, t_min = -kInf, t_max = kInf;
  bool depth_given = false;
  bool all = false;  // --all: no --k and no finite --radius is meant (every point on every ray)
  bool quiet = false;
  unsigned threads = 0;
};

/// The names --order takes and the ray order each names, in the order --help lists them.
constexpr std::array<std::pair<std::string_view, RayOrder>, 3> kOrders = {
    {{"ray", RayOrder::ray}, {"time", RayOrder::time}, {"sphere_hit", RayOrder::sphere_hit}}};

/// The ray order named `s`, one of kOrders (one_of refused any other when the options were parsed).
RayOrder parse_order(const std::string& s) {
  for (const auto& [name, order] : kOrders)
    if (name == s) return order;
  throw std::logic_error("--order '" + s + "' passed its check");
}

int run_query(const QueryOptions& o) {
  // An option the chosen index does not use is refused rather than ignored, by the library's rule
  // (check_applicable; its OptionError is printed with the flags' names).
  GivenIndexOptions given;
  given.capacity = o.capacity > 0;
  given.depth = o.depth_given;
  given.insertion = o.index.insertion;
  IndexChoiceWords words;
  words.option = "--index ";
  check_applicable(o.index.type, given, words);
  RayQuery q;
  q.order = parse_order(o.order);
  if (o.k >= 0) q.k = static_cast<std::size_t>(o.k);
  q.radius = o.radius;
  q.t_min = o.t_min;
  q.t_max = o.t_max;
  q.validate();  // (an OptionError: printed with the flags' names)
  jobs::QueryJobOptions job;
  job.cloud_file = o.cloud;
  job.rays_file = o.rays;
  job.query = q;
  job.index = o.index;
  if (o.capacity > 0) job.index.capacity = o.capacity;
  try {
    job.cache_bytes = static_cast<std::size_t>(rayscan::parse_byte_size(o.cache));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--cache: ") + e.what());
  }
  job.control.distributor = distributor();
  job.control.threads = o.threads;  // MPI: blocks of rays over the ranks (docs/mpi.md)
  if (!o.out.empty() && o.out != "-") {  // checked before the queries, not after them
    const std::filesystem::path out[] = {o.out}, in[] = {o.cloud, o.rays};
    rayscan::require_outputs(out, in);
    // The hits are CSV: a name promising another format (hits.las) would get CSV text.
    if (!rayscan::has_extension(o.out, {".csv"}))
      throw UsageError("--out '" + o.out + "': " + rayscan::extensions_expected({".csv"}) +
                       " (the hits are CSV; '-' or no --out writes them to standard output)");
  }
  job.allow_unbounded = o.all;
  // Everything said goes to stderr: with no --out the hits on stdout stay the CSV alone.
  const bool talk = !o.quiet && is_root();
  job.control.progress = talk;
  if (talk) job.control.log = [](const std::string& s) { std::cerr << "rayscan query: " << s << "\n"; };
  const bool to_stdout = o.out.empty() || o.out == "-";
  // Only rank 0 writes: the rows as the rays are answered (a query may return more than memory
  // holds), into the output's temporary, so that a failure on the way leaves no file.
  std::optional<AtomicOutput> out;
  if (is_root()) {
    out.emplace(o.out);
    job.csv = [&](std::string_view text) {
      std::ostream& s = out->stream();
      errno = 0;
      s.write(text.data(), static_cast<std::streamsize>(text.size()));
      // A full disk ends the run at once, not after the last ray.
      if (!s) throw std::runtime_error(write_failed(to_stdout ? std::string("standard output") : o.out));
    };
  }
  const auto t0 = std::chrono::steady_clock::now();
  const jobs::QueryJobResult r = jobs::run_query(job);
  if (!is_root()) return 0;
  out->commit();
  if (to_stdout) check_standard_output();  // a failed write is reported instead of the summary
  if (talk) {
    // The summary: counts from what was written, the thread count actually used (--threads above
    // the cores runs on all of them), the time in all and the query rate.
    std::string line = rayscan::count_text(r.rays.size(), "ray") + ", " + rayscan::count_text(r.rows, "result") +
                       " written to " + (to_stdout ? std::string("standard output") : "'" + o.out + "'") + "; " +
                       rayscan::count_text(r.threads, "thread");
    if (process_count() > 1) line += " on each of " + std::to_string(process_count()) + " processes";
    char buf[160];
    std::snprintf(buf, sizeof buf, ", %.2f s in all (%.2f s querying, %.0f rays/s)", rayscan::seconds_since(t0),
                  r.query_seconds, r.query_seconds > 0 ? static_cast<double>(r.rays.size()) / r.query_seconds : 0.0);
    std::cerr << "rayscan query: " << line << buf << "\n";
    if (!traffic_summary().empty()) std::cerr << "rayscan query: " << traffic_summary() << "\n";
  }
  return 0;
}

}  // namespace

Runner add_query_command(CLI::App& app) {
  auto o = std::make_shared<QueryOptions>();
  CLI::App* c = app.add_subcommand(
      "query", "Ray query (paper Algorithm 1): points near rays, ordered by distance to the ray, "
               "time along it, or first sphere hit. Writes CSV ray,rank,index,x,y,z,t,distance; t is "
               "the projection parameter (orders ray/time) or the sphere entry (sphere_hit).");
  // The cloud positionally, as every other command takes it; --cloud also names it.
  c->add_option("cloud,--cloud", o->cloud,
                "Point cloud file (any supported format) or index file (.rsi; --index options then come from the file)")
      ->required();
  c->add_option("--rays", o->rays,
                "Rays: CSV with header ox,oy,oz,dx,dy,dz, or .f64 (6 little-endian float64 per ray)")
      ->required();
  c->add_option("--k", o->k, "Keep the k best results per ray, an integer >= 1 (default: no limit; give --k or --radius, or --all)")
      ->transform(integer_in(1));
  c->add_flag("--all", o->all, "Without --k or a finite --radius: return every point on every ray (otherwise refused)");
  c->add_option("--radius", o->radius,
                "Max orthogonal distance to the ray line, world units (default: infinite)");
  c->add_option("--t-min", o->t_min, "Lower end of the time interval, world units (default: -inf)");
  c->add_option("--t-max", o->t_max, "Upper end of the time interval, world units (default: +inf)");
  c->add_option("--order", o->order,
                "Ordering: ray (distance to line, eq. 1), time (t along the ray, eq. 2) or "
                "sphere_hit (entry into the sphere of --radius)")
      ->check(one_of([] {
        std::vector<std::string_view> names;
        for (const auto& e : kOrders) names.push_back(e.first);
        return names;
      }()))
      ->capture_default_str();
  add_index_option(*c, o->index.type);
  c->add_option("--capacity", o->capacity,
                "Octree node capacity / kd-tree leaf size, points (default: the index's own, " +
                    std::to_string(default_capacity(OctreeLayout::adaptive)) + " for octree-adaptive, " +
                    std::to_string(default_capacity(OctreeLayout::layered)) + " for octree-layered, " +
                    std::to_string(kDefaultKdTreeLeaf) + " for kdtree; octree-fixed and brute: an error)")
      ->transform(integer_in(1, 0xFFFFFFFF));
  CLI::Option* depth_opt = c->add_option("--depth", o->index.depth, "Leaf depth of octree-fixed (0..21; other indexes: an error)")
      ->capture_default_str()
      ->transform(integer_in(0, 21));
  c->add_flag("--insertion", o->index.insertion,
              "Build the octree by point insertion instead of Morton bulk loading (octrees only)");
  c->add_option("-o,--out", o->out, "Output CSV, a name ending in .csv (default: standard output)");
  c->add_option("--cache", o->cache,
                "COPC input: bound on decoded node data kept in memory (LRU; e.g. 2G, 512M). A COPC file is "
                "queried on its own hierarchy, decoding only the nodes the rays reach")
      ->capture_default_str();
  add_threads_option(*c, o->threads, "the hits are identical for any count");
  c->add_flag("--quiet,-q", o->quiet, "No log lines, progress bar or summary line on stderr");
  return [o, depth_opt] {
    o->depth_given = depth_opt->count() > 0;
    return run_query(*o);
  };
}

}  // namespace rayscan::cli
