// `rayscan query`: the paper's ray query (Algorithm 1) from the command line.
#include "commands.hpp"

#include "rayscan/any_index.hpp"
#include "rayscan/batch.hpp"
#include "rayscan/io/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "atomic_file.hpp"

#include <charconv>
#include <functional>
#include <unordered_map>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

namespace rayscan::cli {

namespace {

struct QueryOptions {
  std::string cloud, rays, out, order = "ray";
  IndexOptions index;
  long long k = -1;
  double radius = kInf, t_min = -kInf, t_max = kInf;
  bool depth_given = false;
};

bool parse_num(const std::string& s, double& v) {
  const char* b = s.data();
  const char* e = b + s.size();
  while (b < e && (*b == ' ' || *b == '\t')) ++b;
  while (e > b && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) --e;
  if (b < e && *b == '+') ++b;
  auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e && b != e;
}

/// RAYS: a CSV with header ox,oy,oz,dx,dy,dz, or a headerless little-endian float64 file (.f64).
std::vector<Ray> read_rays(const std::string& path) {
  std::vector<Ray> rays;
  auto make = [&](const double* v, const std::string& where) {
    try {
      rays.emplace_back(Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5]));
    } catch (const std::invalid_argument& e) {
      throw UsageError(path + ": " + where + ": " + e.what());
    }
  };
  if (path.size() > 4 && path.substr(path.size() - 4) == ".f64") {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw UsageError(path + ": cannot open rays file");
    const auto size = static_cast<std::uint64_t>(in.tellg());
    if (size % 48)
      throw UsageError(path + ": byte " + std::to_string(size - size % 48) + ": size " +
                       std::to_string(size) + " is not a multiple of 48 (6 float64 per ray)");
    in.seekg(0);
    std::vector<double> v(size / 8);
    in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(size));
    for (std::size_t i = 0; i < v.size() / 6; ++i) make(&v[6 * i], "ray " + std::to_string(i));
    return rays;
  }
  std::ifstream in(path);
  if (!in) throw UsageError(path + ": cannot open rays file");
  std::string line;
  if (!std::getline(in, line)) throw UsageError(path + ": line 1: expected header ox,oy,oz,dx,dy,dz");
  std::string hdr;
  for (char c : line)
    if (c != ' ' && c != '\r' && c != '\t') hdr.push_back(c);
  if (hdr != "ox,oy,oz,dx,dy,dz")
    throw UsageError(path + ": line 1: expected header ox,oy,oz,dx,dy,dz, got '" + line + "'");
  std::size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::stringstream ss(line);
    std::string cell;
    double v[6];
    int n = 0;
    while (std::getline(ss, cell, ',')) {
      if (n == 6 || !parse_num(cell, v[n]))
        throw UsageError(path + ": line " + std::to_string(lineno) +
                         ": expected 6 comma-separated numbers ox,oy,oz,dx,dy,dz, got '" + line + "'");
      ++n;
    }
    if (n != 6)
      throw UsageError(path + ": line " + std::to_string(lineno) + ": expected 6 values, got " +
                       std::to_string(n));
    make(v, "line " + std::to_string(lineno));
  }
  return rays;
}

RayOrder parse_order(const std::string& s) {
  if (s == "ray") return RayOrder::ray;
  if (s == "time") return RayOrder::time;
  if (s == "sphere_hit") return RayOrder::sphere_hit;
  throw UsageError("--order '" + s + "': expected ray, time or sphere_hit");
}

int run_query(const QueryOptions& o) {
  if (o.depth_given && o.index.type != "octree-fixed")
    throw UsageError("--depth applies to --index octree-fixed only (got --index " + o.index.type + ")");
  if (o.index.insertion && o.index.type.rfind("octree-", 0) != 0)
    throw UsageError("--insertion applies to the octree indexes only (got --index " + o.index.type + ")");
  RayQuery q;
  q.order = parse_order(o.order);
  if (o.k >= 0) q.k = static_cast<std::size_t>(o.k);
  q.radius = o.radius;
  q.t_min = o.t_min;
  q.t_max = o.t_max;
  try {
    q.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  // Rays first: a malformed rays file is reported before a large cloud is read.
  const std::vector<Ray> rays = read_rays(o.rays);
  std::vector<std::vector<RayHit>> results;
  PointCloud cloud;
  std::function<Vec3(PointIndex)> position;
  std::unordered_map<PointIndex, Vec3> hit_pos;
  if (io::is_index_file(o.cloud)) {
    // An index file: queries run on the memory map; positions of the hits are looked up by one
    // sequential scan of the ids (no inverse permutation in memory).
    const io::MappedIndex idx = io::MappedIndex::open(o.cloud);
    results = ray_query_batch(idx, rays, q);
    for (const auto& r : results)
      for (const RayHit& h : r) hit_pos.emplace(h.index, Vec3(0.0));
    const auto ids = idx.ids();
    const auto pos = idx.positions();
    for (std::size_t s = 0; s < ids.size() && !hit_pos.empty(); ++s)
      if (auto it = hit_pos.find(ids[s]); it != hit_pos.end()) it->second = pos[s];
    position = [&hit_pos](PointIndex i) { return hit_pos.at(i); };
  } else {
    cloud = io::read_point_cloud(o.cloud, io::ReadOptions{.scalars = false});
    const AnyIndex index = make_index(cloud.positions, o.index);
    results = std::visit([&](const auto& idx) { return ray_query_batch(idx, rays, q); }, index);
    position = [&cloud](PointIndex i) { return cloud.positions[i]; };
  }

  AtomicOutput out(o.out);
  std::ostream& os = out.stream();
  os.precision(17);
  os << "ray,rank,index,x,y,z,t,distance\n";
  for (std::size_t r = 0; r < results.size(); ++r)
    for (std::size_t k = 0; k < results[r].size(); ++k) {
      const RayHit& h = results[r][k];
      const Vec3 p = position(h.index);
      os << r << ',' << k << ',' << h.index << ',' << p.x << ',' << p.y << ',' << p.z << ','
         << h.t << ',' << h.distance << '\n';
    }
  out.commit();
  return 0;
}

}  // namespace

Runner add_query_command(CLI::App& app) {
  auto o = std::make_shared<QueryOptions>();
  CLI::App* c = app.add_subcommand(
      "query", "Ray query (paper Algorithm 1): points near rays, ordered by distance to the ray, "
               "time along it, or first sphere hit. Writes CSV ray,rank,index,x,y,z,t,distance; t is "
               "the projection parameter (orders ray/time) or the sphere entry (sphere_hit).");
  c->add_option("--cloud", o->cloud, "Point cloud file (any supported format) or index file (.rsi; --index options then come from the file)")->required();
  c->add_option("--rays", o->rays,
                "Rays: CSV with header ox,oy,oz,dx,dy,dz, or .f64 (6 little-endian float64 per ray)")
      ->required();
  c->add_option("--k", o->k, "Keep the k best results per ray (default: all)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--radius", o->radius,
                "Max orthogonal distance to the ray line, world units (default: infinite)");
  c->add_option("--t-min", o->t_min, "Lower end of the time interval, world units (default: -inf)");
  c->add_option("--t-max", o->t_max, "Upper end of the time interval, world units (default: +inf)");
  c->add_option("--order", o->order,
                "Ordering: ray (distance to line, eq. 1), time (t along the ray, eq. 2) or "
                "sphere_hit (entry into the sphere of --radius)")
      ->capture_default_str();
  c->add_option("--index", o->index.type,
                "Index: octree-adaptive, octree-layered, octree-fixed, kdtree or brute")
      ->capture_default_str();
  c->add_option("--capacity", o->index.capacity,
                "Octree node capacity / kd-tree leaf size, points")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI::Option* depth_opt = c->add_option("--depth", o->index.depth, "Leaf depth of octree-fixed (0..21; other indexes: an error)")
      ->capture_default_str()
      ->check(CLI::Range(0, 21));
  c->add_flag("--insertion", o->index.insertion,
              "Build the octree by point insertion instead of Morton bulk loading (octrees only)");
  c->add_option("--out", o->out, "Output CSV (default: standard output)");
  return [o, depth_opt] {
    o->depth_given = depth_opt->count() > 0;
    return run_query(*o);
  };
}

}  // namespace rayscan::cli
