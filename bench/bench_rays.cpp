// bench_rays: ray-query throughput of rayscan (paper Algorithm 1) on uniform points in the unit cube,
// with the first-hit query side by side with Embree 3 (RTC_GEOMETRY_TYPE_SPHERE_POINT, same radius,
// same rays, rtcIntersect1 per ray), a per-ray cross-check of the first hit against Embree's, index
// build time against Embree's rtcCommitScene, and resident memory per point of every index, each
// built in a fresh child process (this program re-executed with --mem-child).
//
// Queries, all with t_min = 0 like Embree's tnear = 0:
//   knn8      k = 8, order ray            (kNN to the ray)
//   radius    radius r, no k, order ray   (every point of the cylinder, sorted by distance)
//   closest   k = 1, order time, radius r (ray-marching emulation)
//   sphere    k = 1, order sphere_hit, radius r (exact first hit of the spheres of radius r)
// Rays: (a) a 600 x 400 pinhole camera looking at the cube from outside, (b) random rays through
// the cube (origin on a sphere of radius 2 around the cube centre, aimed at a uniform point in the
// cube). Every timed configuration runs once per round, rounds interleave all contenders (the first
// one rotating), and the median of the rounds is reported.
// Coherent rays: the camera's first sphere hit also in 2x2 and 4x4 pixel packets
// (ray_first_hit_packet) against the same rays one by one and Embree's rtcIntersect1 and its ray
// packets (rtcIntersect4 on 2x2 tiles, rtcIntersect8 on 4x2 halves of 4x4 tiles, rtcIntersect16
// on 4x4 tiles where this Embree build supports them), same rays, interleaved in the same rounds;
// and the row-major camera rays through ray_first_hit_each (two rays at a time, their traversals
// interleaved node by node) and ray_query_each, the batch API's path (the same pairs, with result
// vectors).
#include "bench_cli.hpp"
#include "bench_common.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <embree3/rtcore.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cinttypes>
#include <cstdio>
#include <iostream>
#include <malloc.h>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <tuple>
#include <string>
#include <string_view>
#include <thread>
#include <unistd.h>
#include <variant>
#include <vector>

using rayscan::PointIndex;
using rayscan::Ray;
using rayscan::RayHit;
using rayscan::RayQuery;
using rayscan::Vec3;
namespace rb = rayscan::bench;

namespace {

constexpr PointIndex kNoHit = 0xFFFFFFFFu;

// ---- rays ---------------------------------------------------------------------------------------

/// Pinhole camera rays through pixel centres, row-major from the top-left pixel.
std::vector<Ray> camera_rays(int width, int height) {
  const Vec3 target(0.5, 0.5, 0.5);
  const Vec3 eye(1.9, 1.3, -1.6);
  const double vfov = 30.0 * 3.14159265358979323846 / 180.0;
  const Vec3 fwd = glm::normalize(target - eye);
  const Vec3 right = glm::normalize(glm::cross(fwd, Vec3(0, 1, 0)));
  const Vec3 up = glm::cross(right, fwd);
  const double h = std::tan(vfov / 2), w = h * width / height;
  std::vector<Ray> rays;
  rays.reserve(static_cast<std::size_t>(width) * height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double u = (2.0 * (x + 0.5) / width - 1.0) * w;
      const double v = (1.0 - 2.0 * (y + 0.5) / height) * h;
      rays.emplace_back(eye, fwd + u * right + v * up);
    }
  return rays;
}

/// The camera's rays regrouped into t x t pixel tiles: order[j] is the row-major pixel index of
/// the j-th ray in tile order (tiles row-major, pixels row-major inside a tile). Empty when the
/// image is not a whole number of tiles.
std::vector<std::size_t> tile_order(int width, int height, int t) {
  std::vector<std::size_t> order;
  if (width % t != 0 || height % t != 0) return order;
  order.reserve(static_cast<std::size_t>(width) * height);
  for (int ty = 0; ty < height; ty += t)
    for (int tx = 0; tx < width; tx += t)
      for (int y = ty; y < ty + t; ++y)
        for (int x = tx; x < tx + t; ++x) order.push_back(static_cast<std::size_t>(y) * width + x);
  return order;
}

/// Random rays through the cube: origin on the sphere of radius 2 around the centre (outside the
/// cube), aimed at a uniform point inside it.
std::vector<Ray> random_rays(std::size_t n, std::uint64_t seed) {
  rb::Rng rng(seed);
  const Vec3 c(0.5);
  std::vector<Ray> rays;
  rays.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 o = c + 2.0 * rng.unit_vector();
    const Vec3 t = rng.point_in_unit_cube();
    rays.emplace_back(o, t - o);
  }
  return rays;
}

// ---- Embree -------------------------------------------------------------------------------------

void embree_error(void*, RTCError code, const char* str) {
  std::fprintf(stderr, "Embree error %d: %s\n", static_cast<int>(code), str ? str : "");
  std::exit(4);
}

/// Embree device + scene of one RTC_GEOMETRY_TYPE_SPHERE_POINT geometry (float4 x, y, z, r in a
/// buffer Embree owns), default build quality (medium) and scene flags.
struct EmbreeScene {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  double commit_ms = 0;  // rtcCommitScene only
  double fill_ms = 0;    // creating the geometry and filling its vertex buffer

  EmbreeScene(const std::vector<Vec3>& pts, double radius) {
    device = rtcNewDevice(nullptr);
    if (!device) {
      std::fprintf(stderr, "Embree: rtcNewDevice failed\n");
      std::exit(4);
    }
    rtcSetDeviceErrorFunction(device, embree_error, nullptr);
    rb::Stopwatch sw;
    scene = rtcNewScene(device);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                          4 * sizeof(float), pts.size()));
    for (std::size_t i = 0; i < pts.size(); ++i) {
      v[4 * i + 0] = static_cast<float>(pts[i].x);
      v[4 * i + 1] = static_cast<float>(pts[i].y);
      v[4 * i + 2] = static_cast<float>(pts[i].z);
      v[4 * i + 3] = static_cast<float>(radius);
    }
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    fill_ms = sw.ms();
    rb::Stopwatch sc;
    rtcCommitScene(scene);
    commit_ms = sc.ms();
  }
  ~EmbreeScene() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  /// First hit of one ray with tnear = 0: primitive id (kNoHit on a miss) and t.
  std::pair<PointIndex, float> intersect(const Ray& r) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(r.origin().x);
    rh.ray.org_y = static_cast<float>(r.origin().y);
    rh.ray.org_z = static_cast<float>(r.origin().z);
    rh.ray.dir_x = static_cast<float>(r.direction().x);
    rh.ray.dir_y = static_cast<float>(r.direction().y);
    rh.ray.dir_z = static_cast<float>(r.direction().z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {kNoHit, 0.0f};
    return {rh.hit.primID, rh.ray.tfar};
  }

  /// True when this Embree build traces native packets of w = 4, 8 or 16 rays.
  bool packets_supported(int w) const {
    const RTCDeviceProperty p = w == 4   ? RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED
                                : w == 8 ? RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED
                                         : RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED;
    return rtcGetDeviceProperty(device, p) != 0;
  }

  /// First hits of the W rays r[0, W) as one Embree packet (rtcIntersect4/8/16, RH = RTCRayHit4/8/16).
  template <int W, class RH>
  void intersect_packet(const Ray* r, PointIndex* id, float* t) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    alignas(64) RH rh{};
    alignas(64) int valid[W];
    for (int i = 0; i < W; ++i) {
      valid[i] = -1;
      rh.ray.org_x[i] = static_cast<float>(r[i].origin().x);
      rh.ray.org_y[i] = static_cast<float>(r[i].origin().y);
      rh.ray.org_z[i] = static_cast<float>(r[i].origin().z);
      rh.ray.dir_x[i] = static_cast<float>(r[i].direction().x);
      rh.ray.dir_y[i] = static_cast<float>(r[i].direction().y);
      rh.ray.dir_z[i] = static_cast<float>(r[i].direction().z);
      rh.ray.tnear[i] = 0.0f;
      rh.ray.tfar[i] = std::numeric_limits<float>::infinity();
      rh.ray.mask[i] = 0xFFFFFFFFu;
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    }
    if constexpr (W == 4) rtcIntersect4(valid, scene, &ctx, &rh);
    else if constexpr (W == 8) rtcIntersect8(valid, scene, &ctx, &rh);
    else rtcIntersect16(valid, scene, &ctx, &rh);
    for (int i = 0; i < W; ++i) {
      const bool hit = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
      id[i] = hit ? rh.hit.primID[i] : kNoHit;
      t[i] = hit ? rh.ray.tfar[i] : 0.0f;
    }
  }
};

// ---- rayscan queries ----------------------------------------------------------------------------

enum class Q { knn8, radius, closest, sphere };
constexpr std::array<Q, 4> kQueries{Q::knn8, Q::radius, Q::closest, Q::sphere};
const char* qname(Q q) {
  switch (q) {
    case Q::knn8: return "kNN k=8";
    case Q::radius: return "radius";
    case Q::closest: return "closest";
    case Q::sphere: return "sphere_hit";
  }
  return "?";
}

RayQuery make_query(Q q, double r) {
  RayQuery rq;
  rq.t_min = 0.0;
  switch (q) {
    case Q::knn8: rq.k = 8; break;
    case Q::radius: rq.radius = r; break;
    case Q::closest:
      rq.k = 1;
      rq.radius = r;
      rq.order = rayscan::RayOrder::time;
      break;
    case Q::sphere:
      rq.k = 1;
      rq.radius = r;
      rq.order = rayscan::RayOrder::sphere_hit;
      break;
  }
  rq.validate();  // once per batch: run_rayscan's first-hit loop (ray_first_hit) does not
  return rq;
}

/// Runs query q over rays[0, n) in parallel (current TBB parallelism); per ray it records the
/// result count and the first result's id and t. Returns the total result count.
struct RayResults {
  std::vector<std::uint32_t> count;
  std::vector<PointIndex> first;
  std::vector<double> first_t;
  explicit RayResults(std::size_t n) : count(n), first(n), first_t(n) {}
};

/// body(idx, br) over blocks of `grain` of [0, n) in parallel (TBB), idx the index's concrete type;
/// returns the sum of the hit counts the blocks return.
template <class Body>
std::uint64_t sum_over_blocks(const rayscan::AnyIndex& index, std::size_t n, std::size_t grain, Body&& body) {
  return std::visit(
      [&](const auto& idx) {
        std::atomic<std::uint64_t> total{0};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                          [&](const tbb::blocked_range<std::size_t>& br) { total += body(idx, br); });
        return total.load();
      },
      index);
}

std::uint64_t run_rayscan(const rayscan::AnyIndex& index, std::span<const Ray> rays, const RayQuery& rq,
                          RayResults& res) {
  return sum_over_blocks(index, rays.size(), 64, [&](const auto& idx, const tbb::blocked_range<std::size_t>& br) {
    thread_local std::vector<RayHit> out;
    std::uint64_t local = 0;
    if (rq.k == 1) {
      // First hit (closest, sphere_hit): no result vector, validated once per batch (make_query),
      // like rtcIntersect1.
      for (std::size_t i = br.begin(); i != br.end(); ++i) {
        const std::optional<RayHit> h = rayscan::ray_first_hit(idx, rays[i], rq);
        res.count[i] = h.has_value();
        res.first[i] = h ? h->index : kNoHit;
        res.first_t[i] = h ? h->t : 0.0;
        local += h.has_value();
      }
      return local;
    }
    for (std::size_t i = br.begin(); i != br.end(); ++i) {
      rayscan::ray_query(idx, rays[i], rq, out);
      res.count[i] = static_cast<std::uint32_t>(out.size());
      res.first[i] = out.empty() ? kNoHit : out.front().index;
      res.first_t[i] = out.empty() ? 0.0 : out.front().t;
      local += out.size();
    }
    return local;
  });
}

std::uint64_t run_embree(const EmbreeScene& es, std::span<const Ray> rays, RayResults& res) {
  std::atomic<std::uint64_t> total{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 64),
                    [&](const tbb::blocked_range<std::size_t>& br) {
                      std::uint64_t local = 0;
                      for (std::size_t i = br.begin(); i != br.end(); ++i) {
                        const auto [id, t] = es.intersect(rays[i]);
                        res.first[i] = id;
                        res.first_t[i] = t;
                        res.count[i] = id != kNoHit;
                        local += id != kNoHit;
                      }
                      total += local;
                    });
  return total.load();
}

/// First sphere hits of tile-ordered rays in packets of p consecutive rays (ray_first_hit_packet),
/// results in the same (tile) order. Returns the hit count.
std::uint64_t run_rayscan_packets(const rayscan::AnyIndex& index, std::span<const Ray> rays, std::size_t p,
                                  const RayQuery& rq, RayResults& res) {
  return sum_over_blocks(index, rays.size() / p, std::max<std::size_t>(1, 64 / p),
                         [&](const auto& idx, const tbb::blocked_range<std::size_t>& br) {
                           std::uint64_t local = 0;
                           std::optional<RayHit> out[rayscan::kMaxRayPacket];
                           for (std::size_t k = br.begin(); k != br.end(); ++k) {
                             rayscan::ray_first_hit_packet(idx, rays.subspan(k * p, p), rq,
                                                           std::span<std::optional<RayHit>>(out, p));
                             for (std::size_t j = 0; j < p; ++j) {
                               const std::size_t i = k * p + j;
                               res.count[i] = out[j].has_value();
                               res.first[i] = out[j] ? out[j]->index : kNoHit;
                               res.first_t[i] = out[j] ? out[j]->t : 0.0;
                               local += out[j].has_value();
                             }
                           }
                           return local;
                         });
}

/// First sphere hits of the row-major camera rays by ray_first_hit_each: two consecutive rays at
/// a time, their traversals interleaved node by node (the caller turns rayscan::interleaved_pairs
/// on). Returns the hit count.
std::uint64_t run_rayscan_pairs(const rayscan::AnyIndex& index, std::span<const Ray> rays, const RayQuery& rq,
                                RayResults& res) {
  return sum_over_blocks(index, rays.size(), 64, [&](const auto& idx, const tbb::blocked_range<std::size_t>& br) {
    thread_local std::vector<std::optional<RayHit>> out;
    const std::size_t n = br.size();
    if (out.size() < n) out.resize(n);
    rayscan::ray_first_hit_each(idx, rays.subspan(br.begin(), n), rq, std::span<std::optional<RayHit>>(out.data(), n));
    std::uint64_t local = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const std::size_t i = br.begin() + j;
      res.count[i] = out[j].has_value();
      res.first[i] = out[j] ? out[j]->index : kNoHit;
      res.first_t[i] = out[j] ? out[j]->t : 0.0;
      local += out[j].has_value();
    }
    return local;
  });
}

/// First sphere hits of the row-major camera rays by ray_query_each (the batch API's path:
/// ray_query_batch / ray_query_each_parallel, the Python module, `rayscan query`): with k = 1,
/// ray_first_hit_each's interleaved pairs, and result vectors. Returns the hit count.
std::uint64_t run_rayscan_each(const rayscan::AnyIndex& index, std::span<const Ray> rays, const RayQuery& rq,
                               RayResults& res) {
  // Runs of whole 16-ray blocks counted from rays[0], as ray_query_each_parallel (batch.hpp) cuts
  // them, into per-thread result vectors (no allocation once warm).
  constexpr std::size_t kB = rayscan::kMaxRayPacket;
  return sum_over_blocks(index, (rays.size() + kB - 1) / kB, 4, [&](const auto& idx, const tbb::blocked_range<std::size_t>& bb) {
    const std::size_t b = bb.begin() * kB, e = std::min(rays.size(), bb.end() * kB);
    thread_local std::vector<std::vector<RayHit>> out;
    if (out.size() < e - b) out.resize(e - b);
    rayscan::ray_query_each(idx, rays.subspan(b, e - b), rq, std::span<std::vector<RayHit>>(out.data(), e - b));
    std::uint64_t local = 0;
    for (std::size_t j = 0; j < e - b; ++j) {
      const std::size_t i = b + j;
      res.count[i] = static_cast<std::uint32_t>(out[j].size());
      res.first[i] = out[j].empty() ? kNoHit : out[j].front().index;
      res.first_t[i] = out[j].empty() ? 0.0 : out[j].front().t;
      local += out[j].size();
    }
    return local;
  });
}

/// Embree's first hits of tile-ordered rays as native packets of w = 4, 8 or 16 rays.
std::uint64_t run_embree_packets(const EmbreeScene& es, std::span<const Ray> rays, int w, RayResults& res) {
  std::atomic<std::uint64_t> total{0};
  const std::size_t p = static_cast<std::size_t>(w);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size() / p, std::max<std::size_t>(1, 64 / p)),
                    [&](const tbb::blocked_range<std::size_t>& br) {
                      std::uint64_t local = 0;
                      PointIndex id[16];
                      float t[16];
                      for (std::size_t k = br.begin(); k != br.end(); ++k) {
                        const Ray* r = rays.data() + k * p;
                        if (w == 4) es.intersect_packet<4, RTCRayHit4>(r, id, t);
                        else if (w == 8) es.intersect_packet<8, RTCRayHit8>(r, id, t);
                        else es.intersect_packet<16, RTCRayHit16>(r, id, t);
                        for (std::size_t j = 0; j < p; ++j) {
                          const std::size_t i = k * p + j;
                          res.first[i] = id[j];
                          res.first_t[i] = t[j];
                          res.count[i] = id[j] != kNoHit;
                          local += id[j] != kNoHit;
                        }
                      }
                      total += local;
                    });
  return total.load();
}

/// The suffix of a --indexes entry whose first hits run without the entry-point search
/// (rayscan::set_entry_point_search(false) around each of its timed runs): its A/B in one process.
constexpr std::string_view kNoEntrySuffix = "/no-entry";

/// Whether a --indexes entry runs its first hits with the entry-point search (no kNoEntrySuffix).
bool entry_search_of(const std::string& type) { return !type.ends_with(kNoEntrySuffix); }

/// Index options of a --indexes entry: a make_index type, optionally with ":capacity" (octree
/// node capacity / kd-tree leaf size, e.g. "octree-adaptive:8", for leaf-capacity sweeps) and
/// kNoEntrySuffix.
rayscan::IndexOptions index_options(std::string type) {
  if (!entry_search_of(type)) type.resize(type.size() - kNoEntrySuffix.size());
  rayscan::IndexOptions o;
  const std::size_t colon = type.find(':');
  o.type = type.substr(0, colon);
  if (colon != std::string::npos) o.capacity = static_cast<std::uint32_t>(std::stoul(type.substr(colon + 1)));
  return o;
}

// ---- memory probe (child process) ---------------------------------------------------------------

/// In a fresh process: RSS before the input exists, generate the input, reset the peak, build,
/// record the peak, free the input, record the resident size. Prints one "MEM ..." line.
int memory_child(const std::string& type, std::size_t n, std::uint64_t seed, double radius) {
  const std::uint64_t rss_empty = rb::rss_bytes();
  auto pts = rb::uniform_cube(n, seed);
  const std::uint64_t rss_input = rb::rss_bytes();
  if (!rb::reset_peak_rss()) {
    std::printf("MEM-ERROR cannot reset VmHWM\n");
    return 1;
  }
  std::size_t api = 0;
  std::unique_ptr<EmbreeScene> es;
  std::optional<rayscan::AnyIndex> idx;
  if (type == "embree") {
    es = std::make_unique<EmbreeScene>(pts, radius);
  } else {
    idx.emplace(rayscan::make_index(pts, index_options(type)));
    api = rayscan::index_memory_bytes(*idx);
  }
  const std::uint64_t peak = rb::peak_rss_bytes();
  std::vector<Vec3>().swap(pts);
  // Give freed build temporaries back to the OS: glibc keeps freed heap blocks below its dynamic
  // mmap threshold (up to 32 MiB), which would otherwise be counted as index memory.
  malloc_trim(0);
  const std::uint64_t steady = rb::rss_bytes();
  std::printf("MEM %s %zu steady=%" PRIu64 " peak_extra=%" PRIu64 " api=%zu\n", type.c_str(), n,
              steady - rss_empty, peak - rss_input, api);
  return 0;
}

struct MemFigure {
  double steady = 0, peak_extra = 0, api = 0;  // bytes per point
  bool ok = false;
};

MemFigure probe_memory(const std::string& self, const std::string& type, std::size_t n,
                       std::uint64_t seed, double radius) {
  const std::string cmd = "'" + self + "' --mem-child " + type + " --points " + std::to_string(n) +
                          " --seed " + std::to_string(seed) + " --radius " + std::to_string(radius);
  MemFigure m;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return m;
  char line[512];
  while (std::fgets(line, sizeof line, p)) {
    char t[64];
    std::size_t nn = 0;
    unsigned long long s = 0, pk = 0, api = 0;
    if (std::sscanf(line, "MEM %63s %zu steady=%llu peak_extra=%llu api=%llu", t, &nn, &s, &pk, &api) == 5) {
      m.steady = static_cast<double>(s) / n;
      m.peak_extra = static_cast<double>(pk) / n;
      m.api = static_cast<double>(api) / n;
      m.ok = true;
    }
  }
  pclose(p);
  return m;
}

// ---- cross-check against Embree ------------------------------------------------------------------

/// Compares rayscan's exact (double) first sphere hit with Embree's (float) per ray and explains
/// each mismatch with the double-precision geometry of the two candidate points.
struct HitCheck {
  std::size_t rays = 0, both_hit_same = 0, both_miss = 0;
  std::size_t diff_near_tie = 0;    // different point, entry t within tie_eps (float resolution)
  std::size_t grazing = 0;          // hit vs miss where the point's distance to the ray ~ r
  std::size_t unexplained = 0;
  double max_dt_same = 0;           // max |t_rayscan - t_embree| when both hit the same point
  double max_gap_diff = 0;          // max entry-t gap for the "near tie" mismatches
};

HitCheck check_hits(const std::vector<Vec3>& pts, std::span<const Ray> rays, const RayResults& rs,
                    const RayResults& em, double radius) {
  HitCheck h;
  // Prints the double-precision geometry of an unexplained mismatch (at most a few per set).
  auto explain = [&](std::size_t i) {
    if (h.unexplained > 3) return;
    std::printf("  unexplained mismatch, ray %zu:", i);
    for (const auto& [who, id, t] : {std::tuple{"rayscan", rs.first[i], rs.first_t[i]},
                                     std::tuple{"Embree", em.first[i], em.first_t[i]}}) {
      if (id == kNoHit) {
        std::printf(" %s miss;", who);
        continue;
      }
      const auto pt = rayscan::ray_point_terms(rays[i].origin(), rays[i].direction(), pts[id]);
      std::printf(" %s point %u t %.9f (double: t_p %.9f, d/r %.9f, entry %.9f);", who, id, t, pt.t,
                  std::sqrt(pt.d2) / radius,
                  pt.d2 <= radius * radius ? rayscan::sphere_entry(pt.t, pt.d2, radius) : NAN);
    }
    std::printf("\n");
  };
  h.rays = rays.size();
  // Float32 tolerances: Embree rounds point, origin and direction to float (spacing 1.2e-7 for
  // coordinates in [1, 2), 2.4e-7 in [2, 4); the camera sits at |x| ~ 2 and t reaches ~3.5), so
  // the distance of a point to the ray is uncertain by a few 1e-7 world units, about 1e-4 of
  // r = 0.0046, and entry parameters of two spheres closer than ~1e-5 may swap order.
  const double tie_eps = 1e-5;    // entry-t gap a float sphere test can misorder
  const double graze_eps = 1e-4;  // relative |d - r| / r where float hit/miss can flip
  auto terms = [&](std::size_t i, PointIndex id) {
    return rayscan::ray_point_terms(rays[i].origin(), rays[i].direction(), pts[id]);
  };
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const PointIndex a = rs.first[i], b = em.first[i];
    if (a == kNoHit && b == kNoHit) {
      ++h.both_miss;
    } else if (a == b) {
      ++h.both_hit_same;
      h.max_dt_same = std::max(h.max_dt_same, std::abs(rs.first_t[i] - em.first_t[i]));
    } else if (a != kNoHit && b != kNoHit) {
      const auto tb = terms(i, b);
      const double db = std::sqrt(tb.d2);
      if (db > radius) {  // Embree hit a sphere that double geometry says the ray misses
        if ((db - radius) / radius < graze_eps) {
          ++h.grazing;
        } else {
          ++h.unexplained;
          explain(i);
        }
        continue;
      }
      const double gap = rayscan::sphere_entry(tb.t, tb.d2, radius) - rs.first_t[i];
      const double da = std::sqrt(terms(i, a).d2);
      if (std::abs(gap) < tie_eps) {
        ++h.diff_near_tie;
        h.max_gap_diff = std::max(h.max_gap_diff, std::abs(gap));
      } else if ((radius - da) / radius < graze_eps || (radius - db) / radius < graze_eps) {
        ++h.grazing;  // one of the two barely touches its sphere: float misses it
      } else {
        ++h.unexplained;
        explain(i);
      }
    } else {
      const PointIndex id = a != kNoHit ? a : b;
      const double d = std::sqrt(terms(i, id).d2);
      if (std::abs(d - radius) / radius < graze_eps) {
        ++h.grazing;
      } else {
        ++h.unexplained;
        explain(i);
      }
    }
  }
  return h;
}

// ---- report helpers -----------------------------------------------------------------------------

std::string mrays(double rays_per_s) {
  char b[32];
  if (rays_per_s >= 1e6) std::snprintf(b, sizeof b, "%.2f M", rays_per_s / 1e6);
  else std::snprintf(b, sizeof b, "%.0f k", rays_per_s / 1e3);
  return b;
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) v.push_back(item);
  return v;
}

struct RaySet {
  std::string name;
  std::vector<Ray> rays;
  std::vector<Ray> slow;  // even-stride subset for the kNN / radius queries
  // Camera only: the rays in 2x2 and 4x4 pixel tiles and their row-major indices (tile_order).
  std::vector<Ray> tiles2, tiles4;
  std::vector<std::size_t> order2, order4;
};

/// rays[order[j]] for every j.
std::vector<Ray> permuted(const std::vector<Ray>& rays, const std::vector<std::size_t>& order) {
  std::vector<Ray> out;
  out.reserve(order.size());
  for (const std::size_t i : order) out.push_back(rays[i]);
  return out;
}

/// m rays at an even stride over `rays` (all of them when m is 0 or >= rays.size()).
std::vector<Ray> stride_subset(const std::vector<Ray>& rays, std::size_t m) {
  if (m == 0 || m >= rays.size()) return rays;
  std::vector<Ray> out;
  out.reserve(m);
  for (std::size_t i = 0; i < m; ++i) out.push_back(rays[i * rays.size() / m]);
  return out;
}

Q parse_q(const std::string& s) {
  if (s == "knn8") return Q::knn8;
  if (s == "radius") return Q::radius;
  if (s == "closest") return Q::closest;
  return Q::sphere;
}

/// Work counters per ray (RayQueryStats) of one query, serially over `rays`.
std::pair<double, double> work_per_ray(const rayscan::AnyIndex& index, std::span<const Ray> rays,
                                       const RayQuery& rq) {
  rayscan::RayQueryStats st;
  std::vector<RayHit> out;
  std::visit([&](const auto& idx) { for (const Ray& r : rays) rayscan::ray_query(idx, r, rq, out, &st); }, index);
  const double n = static_cast<double>(std::max<std::size_t>(1, rays.size()));
  return {static_cast<double>(st.nodes_visited) / n, static_cast<double>(st.points_tested) / n};
}

/// --profile: one query only, one thread, each ray set once (kNN/radius on the slow subset), with
/// RayQueryStats, so a profiler (valgrind --tool=callgrind) sees nothing else of interest.
void profile(const std::string& which, const std::vector<Vec3>& pts, const std::vector<std::string>& indexes,
             const std::vector<RaySet>& sets, double radius, int reps) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
  if (which == "embree") {
    const EmbreeScene es(pts, radius);
    for (const RaySet& set : sets) {
      RayResults res(set.rays.size());
      rb::Stopwatch sw;
      std::uint64_t hits = 0;
      for (int r = 0; r < reps; ++r) hits = run_embree(es, set.rays, res);
      std::printf("profile embree %s: %zu rays, %" PRIu64 " hits, %.1f ms\n", set.name.c_str(), set.rays.size(),
                  hits, sw.ms());
    }
    return;
  }
  if (which == "sphere2x2" || which == "sphere4x4") {  // coherent rays: the camera in pixel packets
    const std::size_t p = which == "sphere2x2" ? 4 : 16;
    const RaySet& set = sets[0];
    const std::vector<Ray>& tiles = p == 4 ? set.tiles2 : set.tiles4;
    for (const auto& type : indexes) {
      const auto idx = rayscan::make_index(pts, index_options(type));
      const RayQuery rq = make_query(Q::sphere, radius);
      RayResults res(tiles.size());
      rb::Stopwatch sw;
      std::uint64_t total = 0;
      for (int r = 0; r < reps; ++r) total = run_rayscan_packets(idx, tiles, p, rq, res);
      const double ms = sw.ms();
      rayscan::RayQueryStats st;
      std::vector<std::optional<RayHit>> out(p);
      std::visit([&](const auto& ix) {
        for (std::size_t k = 0; k + p <= tiles.size(); k += p)
          rayscan::ray_first_hit_packet(ix, std::span<const Ray>(tiles).subspan(k, p), rq,
                                        std::span<std::optional<RayHit>>(out), &st);
      }, idx);
      const double nr = static_cast<double>(std::max<std::size_t>(1, tiles.size()));
      std::printf("profile %s sphere_hit %s in %s packets: %zu rays, %" PRIu64 " results, %.1f ms; per ray %.1f "
                  "nodes visited, %.1f points tested\n",
                  type.c_str(), set.name.c_str(), which.c_str() + 6, tiles.size(), total, ms,
                  static_cast<double>(st.nodes_visited) / nr, static_cast<double>(st.points_tested) / nr);
    }
    return;
  }
  const Q q = parse_q(which);
  for (const auto& type : indexes) {
    const auto idx = rayscan::make_index(pts, index_options(type));
    for (const RaySet& set : sets) {
      const auto& rays = (q == Q::knn8 || q == Q::radius) ? set.slow : set.rays;
      RayResults res(rays.size());
      rb::Stopwatch sw;
      std::uint64_t total = 0;
      for (int r = 0; r < reps; ++r) total = run_rayscan(idx, rays, make_query(q, radius), res);
      const double ms = sw.ms();
      const auto [nodes, points] = work_per_ray(idx, rays, make_query(q, radius));
      std::printf("profile %s %s %s: %zu rays, %" PRIu64 " results, %.1f ms; per ray %.1f nodes visited, "
                  "%.1f points tested\n",
                  type.c_str(), qname(q), set.name.c_str(), rays.size(), total, ms, nodes, points);
    }
  }
}

}  // namespace

/// --coherence: where single camera rays lose to Embree and when packets
/// pay, on the first index of --indexes, one thread (thread CPU time), `reps` interleaved rounds,
/// medians. (1) The camera rays split by rayscan's answer into hits and misses, each set timed
/// with ray_first_hit and rtcIntersect1. (2) Every k-th camera ray in row order (k = 1..16), so
/// that 16 consecutive rays share the eye in a cone k times as wide, and the random rays: time of
/// ray_first_hit_packet on consecutive blocks of 16 over one ray_first_hit per ray (the figures
/// behind packet_coherent's 2-degree cone).
void coherence(const std::vector<Vec3>& pts, const std::string& index_name, const std::vector<RaySet>& sets,
               double radius, std::size_t reps) {
  const rayscan::AnyIndex built = rayscan::make_index(pts, index_options(index_name));
  const EmbreeScene es(pts, radius);
  const RayQuery q = make_query(Q::sphere, radius);
  const auto single = [&](std::span<const Ray> rays) {
    return std::visit([&](const auto& idx) {
      std::size_t h = 0;
      for (const Ray& r : rays) h += rayscan::ray_first_hit(idx, r, q).has_value();
      return h;
    }, built);
  };
  const auto packets = [&](std::span<const Ray> rays) {
    return std::visit([&](const auto& idx) {
      std::size_t h = 0;
      std::optional<RayHit> out[rayscan::kMaxRayPacket];
      for (std::size_t b = 0; b < rays.size(); b += rayscan::kMaxRayPacket) {
        const std::size_t n = std::min(rayscan::kMaxRayPacket, rays.size() - b);
        rayscan::ray_first_hit_packet(idx, rays.subspan(b, n), q, std::span<std::optional<RayHit>>(out, n));
        for (std::size_t j = 0; j < n; ++j) h += out[j].has_value();
      }
      return h;
    }, built);
  };
  const auto embree = [&](std::span<const Ray> rays) {
    std::size_t h = 0;
    for (const Ray& r : rays) h += es.intersect(r).first != kNoHit;
    return h;
  };
  // Median thread-CPU ms of f over the rays, `reps` rounds alternating with g.
  const auto ab = [&](auto&& f, auto&& g, std::span<const Ray> rays) {
    std::vector<double> a, b;
    for (std::size_t r = 0; r < reps; ++r) {
      rb::ThreadCpuStopwatch c1;
      (void)f(rays);
      a.push_back(c1.ms());
      rb::ThreadCpuStopwatch c2;
      (void)g(rays);
      b.push_back(c2.ms());
    }
    return std::pair{rb::median(a), rb::median(b)};
  };
  const std::vector<Ray>& cam = sets[0].rays;
  std::vector<Ray> hit, miss;
  std::visit([&](const auto& idx) {
    for (const Ray& r : cam) (rayscan::ray_first_hit(idx, r, q) ? hit : miss).push_back(r);
  }, built);
  std::printf("coherence, %s, 1 thread, median of %zu rounds (ns per ray):\n", index_name.c_str(), reps);
  std::printf("| camera rays | rays | rayscan ray_first_hit | Embree rtcIntersect1 | ratio |\n|---|---:|---:|---:|---:|\n");
  for (const std::vector<Ray>* set : {&cam, static_cast<const std::vector<Ray>*>(&hit), static_cast<const std::vector<Ray>*>(&miss)}) {
    const auto [r, e] = ab(single, embree, *set);
    const double n = static_cast<double>(set->size());
    std::printf("| %s | %zu | %.1f | %.1f | %.2fx |\n", set == &cam ? "all" : set == &hit ? "hits" : "misses",
                set->size(), 1e6 * r / n, 1e6 * e / n, e / r);
  }
  std::printf("| 16 consecutive rays | cone (degrees, first to last) | single | packets of 16 | packets / single time |\n"
              "|---|---:|---:|---:|---:|\n");
  for (const std::size_t k : {1u, 2u, 4u, 8u, 16u}) {
    std::vector<Ray> sub;
    for (std::size_t i = 0; i < cam.size(); i += k) sub.push_back(cam[i]);
    const double deg = std::acos(std::min(1.0, glm::dot(sub[0].direction(), sub[15].direction()))) * 180.0 /
                       3.14159265358979323846;
    const auto [a, b] = ab(single, packets, sub);
    const double n = static_cast<double>(sub.size());
    std::printf("| every %zu-th camera ray | %.2f | %.1f | %.1f | %.2f |\n", k, deg, 1e6 * a / n, 1e6 * b / n, b / a);
  }
  const std::vector<Ray>& rnd = sets[1].rays;
  const auto [a, b] = ab(single, packets, rnd);
  const double n = static_cast<double>(rnd.size());
  std::printf("| random rays | | %.1f | %.1f | %.2f |\n", 1e6 * a / n, 1e6 * b / n, b / a);
  std::fflush(stdout);
}

int main(int argc, char** argv) {
  CLI::App app{"rayscan benchmark: ray-query throughput, first hit vs Embree 3, build time, memory"};
  std::vector<std::size_t> sizes{1000000, 10000000};
  std::vector<int> threads{1, 2};
  std::string index_list = "octree-adaptive,kdtree";
  std::string mem_child;
  int width = 600, height = 400;
  std::size_t random_n = 50000, slow_rays = 5000, reps = 5, build_reps = 3;
  std::size_t points_child = 0;
  double radius = 0.0046;
  std::uint64_t seed = 20240601;
  bool no_memory = false, no_build = false, only_build = false;
  std::string profile_query;
  int profile_reps = 1;
  bool coherence_only = false;
  app.add_option("--points-list", sizes, "comma-separated cloud sizes")
      ->delimiter(',')->check(CLI::Range(std::size_t{1}, std::size_t{1} << 31))->capture_default_str();
  app.add_option("--indexes", index_list,
                 "comma-separated rayscan indexes: octree-adaptive, octree-layered, octree-fixed, kdtree; "
                 "NAME:C sets the node capacity / leaf size C (default: make_index's, index_capacity); "
                 "NAME/no-entry: the same index with its first hits' entry-point search off "
                 "(rayscan::set_entry_point_search), for an A/B of it in one process")
      ->capture_default_str();
  app.add_option("--threads", threads, "comma-separated thread counts (tbb::global_control)")
      ->delimiter(',')->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--width", width, "camera image width, pixels")->check(CLI::Range(1, 1 << 15))->capture_default_str();
  app.add_option("--height", height, "camera image height, pixels")->check(CLI::Range(1, 1 << 15))->capture_default_str();
  app.add_option("--random-rays", random_n, "number of random rays through the cube")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 30))->capture_default_str();
  app.add_option("--slow-rays", slow_rays,
                 "rays (an even stride over each set) timed for the kNN and radius queries; 0 = all")
      ->capture_default_str();
  app.add_option("--radius", radius, "r of radius, closest and sphere_hit (and Embree's spheres), world units")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--reps", reps, "interleaved rounds per throughput figure (median reported)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1000}))->capture_default_str();
  app.add_option("--build-reps", build_reps, "interleaved rounds of the build-time comparison")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1000}))->capture_default_str();
  app.add_option("--seed", seed, "seed of points and random rays")->capture_default_str();
  app.add_flag("--no-memory", no_memory, "skip the per-index memory probes");
  app.add_flag("--no-build", no_build, "skip the build-time comparison");
  app.add_flag("--only-build", only_build, "only the build-time comparison (and memory, unless --no-memory)");
  app.add_flag("--coherence", coherence_only,
               "only the coherence study on the first of --indexes: camera hits and misses vs Embree, and "
               "packets of 16 consecutive rays in cones of growing width (1 thread)");
  app.add_option("--profile", profile_query,
                 "run only this query (knn8|radius|closest|sphere|embree; sphere2x2|sphere4x4: the camera's "
                 "sphere hits in pixel packets) once per ray set on one thread, with work counters; for "
                 "callgrind/perf")
      ->check(CLI::IsMember({"knn8", "radius", "closest", "sphere", "embree", "sphere2x2", "sphere4x4"}));
  app.add_option("--profile-reps", profile_reps, "with --profile: passes over each ray set (the times printed "
                 "are of all passes)")->check(CLI::Range(1, 100000))->capture_default_str();
  app.add_option("--mem-child", mem_child, "internal: run one memory probe in this process")->group("");
  app.add_option("--points", points_child, "internal: size of the --mem-child cloud")->group("");
  rayscan::bench::parse_or_exit(app, argc, argv);
  if (!mem_child.empty()) return memory_child(mem_child, points_child, seed, radius);

  const std::vector<std::string> indexes = split_list(index_list);
  const int hw = static_cast<int>(std::thread::hardware_concurrency());
  char self[4096];
  const ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
  self[len > 0 ? len : 0] = 0;

  std::printf("bench_rays: CPU %s, %d hardware threads; r = %g; rounds interleaved, median of %zu\n",
              rb::cpu_model().c_str(), hw, radius, reps);
  std::printf("Embree %d.%d.%d, RTC_GEOMETRY_TYPE_SPHERE_POINT (float4), rtcIntersect1 per ray, "
              "default build quality; rayscan: double precision, per-thread result vectors\n",
              RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH);
  std::printf("ray_first_hit_each's default on this CPU (rayscan::interleaved_pairs): %s\n",
              rayscan::interleaved_pairs_default() ? "interleaved pairs" : "single rays");
  std::printf("rayscan indexes from make_index with its defaults unless NAME:C: capacity %u (octree-adaptive, "
              "-fixed), %u (octree-layered), kd-tree leaf %u; bulk build; queries use t_min = 0\n",
              rayscan::default_capacity(rayscan::OctreeLayout::adaptive),
              rayscan::default_capacity(rayscan::OctreeLayout::layered), rayscan::kDefaultKdTreeLeaf);
  std::printf("load average: %s\n", rb::loadavg().c_str());
  std::fflush(stdout);

  std::vector<RaySet> sets;
  sets.push_back({"camera " + std::to_string(width) + "x" + std::to_string(height), camera_rays(width, height), {}, {}, {}, {}, {}});
  sets.push_back({"random " + std::to_string(random_n), random_rays(random_n, seed + 7), {}, {}, {}, {}, {}});
  for (auto& s : sets) s.slow = stride_subset(s.rays, slow_rays);
  sets[0].order2 = tile_order(width, height, 2);
  sets[0].order4 = tile_order(width, height, 4);
  sets[0].tiles2 = permuted(sets[0].rays, sets[0].order2);
  sets[0].tiles4 = permuted(sets[0].rays, sets[0].order4);
  if (sets[0].order4.empty()) std::printf("(image not a whole number of 4x4 tiles: no packet figures)\n");

  for (const std::size_t n : sizes) {
    std::printf("\n=== %zu uniform points in the unit cube ===\n", n);
    std::fflush(stdout);
    const std::vector<Vec3> pts = rb::uniform_cube(n, seed);

    if (!profile_query.empty()) {
      profile(profile_query, pts, indexes, sets, radius, profile_reps);
      continue;
    }
    if (coherence_only) {
      coherence(pts, indexes.front(), sets, radius, reps);
      continue;
    }

    // -- build time, all hardware threads (2 here) --------------------------------------------
    if (!no_build) {
      // t: wall ms; faults / sys: the process's minor page faults and system CPU ms of the same
      // span (for Embree: geometry fill + commit, which cannot be split).
      std::vector<std::vector<double>> t(indexes.size() + 1), faults(indexes.size() + 1), sys(indexes.size() + 1);
      std::vector<double> fill;
      for (std::size_t r = 0; r < build_reps; ++r)
        for (std::size_t j = 0; j <= indexes.size(); ++j) {
          const std::size_t c = (j + r) % (indexes.size() + 1);
          rb::ProcessFaults pf;
          if (c == indexes.size()) {
            EmbreeScene es(pts, radius);
            t[c].push_back(es.commit_ms);
            fill.push_back(es.fill_ms);
          } else {
            rb::Stopwatch sw;
            auto idx = rayscan::make_index(pts, index_options(indexes[c]));
            t[c].push_back(sw.ms());
            rb::keep(idx);
          }
          faults[c].push_back(pf.minor_faults());
          sys[c].push_back(pf.sys_ms());
        }
      const double em = rb::median(t.back());
      std::printf("\nbuild, %d threads, median of %zu interleaved rounds:\n", hw, build_reps);
      std::printf("| index | build ms | speed-up vs Embree rtcCommitScene (goal >= 5x) | every round, ms | "
                  "page faults (median) | system CPU ms (median) |\n|---|---:|---:|---|---:|---:|\n");
      auto rounds = [](const std::vector<double>& v) {
        std::string out;
        for (const double x : v) out += (out.empty() ? "" : " ") + std::to_string(static_cast<long>(x + 0.5));
        return out;
      };
      for (std::size_t c = 0; c < indexes.size(); ++c)
        std::printf("| rayscan %s (bulk) | %.0f | %.2fx | %s | %.0f | %.0f |\n", indexes[c].c_str(), rb::median(t[c]),
                    em / rb::median(t[c]), rounds(t[c]).c_str(), rb::median(faults[c]), rb::median(sys[c]));
      std::printf("| Embree rtcCommitScene | %.0f | 1 | %s | %.0f | %.0f |\n", em, rounds(t.back()).c_str(),
                  rb::median(faults.back()), rb::median(sys.back()));
      std::printf("(Embree: faults and system CPU include the geometry fill. Its geometry creation + float4 "
                  "buffer fill, not in the build ms above: %.0f ms)\n", rb::median(fill));
      std::fflush(stdout);
    }

    // -- memory, each index in a fresh child process ------------------------------------------
    if (!no_memory) {
      std::printf("\nmemory per point, each index built in a fresh process (%s --mem-child):\n", self);
      std::printf("| index | index + coordinates B/pt (RSS after build, input freed, malloc_trim) | "
                  "build peak B/pt above input | index's own count B/pt |\n|---|---:|---:|---:|\n");
      std::vector<std::string> all = indexes;
      all.push_back("embree");
      for (const auto& type : all) {
        const MemFigure m = probe_memory(self, type, n, seed, radius);
        if (!m.ok) {
          std::printf("| %s | probe failed | | |\n", type.c_str());
          continue;
        }
        std::printf("| %s | %.1f | %.1f | %s |\n", type == "embree" ? "Embree 3 (float4 + BVH)" : type.c_str(),
                    m.steady, m.peak_extra, type == "embree" ? "n/a" : std::to_string(m.api).substr(0, 5).c_str());
        std::fflush(stdout);
      }
    }

    if (only_build) continue;

    // -- throughput ----------------------------------------------------------------------------
    std::vector<rayscan::AnyIndex> built;
    for (const auto& type : indexes) built.push_back(rayscan::make_index(pts, index_options(type)));
    const EmbreeScene es(pts, radius);

    for (const RaySet& set : sets) {
      // Cross-check first (all threads): every index must agree exactly on every query; the first
      // sphere hit is compared with Embree's.
      std::vector<std::array<std::uint64_t, 4>> totals(built.size());
      RayResults first_hits(set.rays.size());
      for (std::size_t b = 0; b < built.size(); ++b)
        for (Q q : kQueries) {
          const auto& rays = (q == Q::knn8 || q == Q::radius) ? set.slow : set.rays;
          RayResults res(rays.size());
          totals[b][static_cast<int>(q)] = run_rayscan(built[b], rays, make_query(q, radius), res);
          if (q == Q::sphere) {
            if (b == 0) first_hits = res;
            else if (res.first != first_hits.first)
              rb::fail(set.name + ": sphere_hit first hits of " + indexes[b] + " differ from " + indexes[0]);
          }
          if (totals[b][static_cast<int>(q)] != totals[0][static_cast<int>(q)])
            rb::fail(set.name + ": " + qname(q) + " result count of " + indexes[b] + " differs from " +
                     indexes[0]);
        }
      RayResults em_hits(set.rays.size());
      const std::uint64_t em_total = run_embree(es, set.rays, em_hits);
      const HitCheck hc = check_hits(pts, set.rays, first_hits, em_hits, radius);
      const std::size_t mismatches = hc.rays - hc.both_hit_same - hc.both_miss;
      std::printf("\n-- %zu points, %s rays --\n", n, set.name.c_str());
      std::printf("first-hit cross-check vs Embree on %zu rays: rayscan hits %" PRIu64 ", Embree hits %" PRIu64
                  "; same point %zu, both miss %zu, mismatches %zu (%.4f%%): %zu different point with "
                  "entry t within 1e-5 (max gap %.2e), %zu grazing (|d - r| < 1e-4 r), %zu unexplained; "
                  "max |t_rayscan - t_embree| on agreeing hits %.2e\n",
                  hc.rays, totals[0][3], em_total, hc.both_hit_same, hc.both_miss, mismatches,
                  100.0 * static_cast<double>(mismatches) / static_cast<double>(hc.rays), hc.diff_near_tie,
                  hc.max_gap_diff, hc.grazing, hc.unexplained, hc.max_dt_same);
      if (hc.unexplained * 1000 > hc.rays)
        rb::fail(set.name + ": more than 0.1% of first hits differ from Embree without a float explanation");
      // Packets (camera only): every index's packet answer must equal its single-ray answer, ray by
      // ray; Embree's packets are compared with its rtcIntersect1 hits.
      const bool packets = !set.order4.empty();
      std::vector<int> em_widths;
      if (packets) {
        for (std::size_t b = 0; b < built.size(); ++b)
          for (const auto& [tiles, order] : {std::pair{&set.tiles2, &set.order2}, std::pair{&set.tiles4, &set.order4}}) {
            RayResults single(set.rays.size()), pk(set.rays.size());
            run_rayscan(built[b], set.rays, make_query(Q::sphere, radius), single);
            run_rayscan_packets(built[b], *tiles, tiles == &set.tiles2 ? 4 : 16, make_query(Q::sphere, radius), pk);
            for (std::size_t j = 0; j < order->size(); ++j)
              if (pk.first[j] != single.first[(*order)[j]] || pk.first_t[j] != single.first_t[(*order)[j]])
                rb::fail(set.name + ": packet first hit of " + indexes[b] + " differs from its single-ray hit");
          }
        for (const int w : {4, 8, 16}) {
          if (!es.packets_supported(w)) continue;
          em_widths.push_back(w);
          RayResults pk(set.rays.size());
          const auto& [tiles, order] = w == 4 ? std::pair{&set.tiles2, &set.order2} : std::pair{&set.tiles4, &set.order4};
          const std::uint64_t tot = run_embree_packets(es, *tiles, w, pk);
          std::size_t same = 0;
          for (std::size_t j = 0; j < order->size(); ++j) same += pk.first[j] == em_hits.first[(*order)[j]];
          std::printf("Embree rtcIntersect%d packets: %" PRIu64 " hits, same point as rtcIntersect1 on %zu of %zu rays\n",
                      w, tot, same, order->size());
        }
        std::printf("packet first hits (2x2, 4x4) of every index equal their single-ray first hits on all %zu rays\n",
                    set.rays.size());
      }

      // Work per ray (RayQueryStats) on 1000 rays at an even stride: where the time goes.
      const std::vector<Ray> sample = stride_subset(set.rays, 1000);
      std::printf("work per ray (RayQueryStats, %zu rays at an even stride; nodes whose points were "
                  "evaluated / points tested):\n| index |", sample.size());
      for (Q q : kQueries) std::printf(" %s |", qname(q));
      std::printf("\n|---|---:|---:|---:|---:|\n");
      for (std::size_t b = 0; b < built.size(); ++b) {
        std::printf("| %s |", indexes[b].c_str());
        for (Q q : kQueries) {
          const auto [nodes, points] = work_per_ray(built[b], sample, make_query(q, radius));
          std::printf(" %.1f / %.0f |", nodes, points);
        }
        std::printf("\n");
      }
      std::fflush(stdout);

      for (const int nt : threads) {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(nt));
        // Contenders: (index, query) pairs plus Embree; one round runs each once.
        struct Run {
          std::size_t b;  // index into built, or built.size() for Embree
          Q q;
          std::vector<double> ms;
          int packet = 0;  // rays per packet: 0 single rays; rayscan 4 (2x2) / 16 (4x4), 1 ray_query_each,
                           // 2 ray_first_hit_each (row-major, two rays interleaved); Embree 4 / 8 / 16
        };
        std::vector<Run> runs;
        for (std::size_t b = 0; b < built.size(); ++b)
          for (Q q : kQueries) runs.push_back({b, q, {}});
        runs.push_back({built.size(), Q::sphere, {}});
        const std::size_t first_packet_run = runs.size();
        if (packets) {
          for (std::size_t b = 0; b < built.size(); ++b)
            for (const int p : {2, 1, 4, 16}) runs.push_back({b, Q::sphere, {}, p});
          for (const int w : em_widths) runs.push_back({built.size(), Q::sphere, {}, w});
        }
        for (std::size_t r = 0; r < reps; ++r)
          for (std::size_t j = 0; j < runs.size(); ++j) {
            Run& run = runs[(j + r) % runs.size()];
            const auto& rays = (run.q == Q::knn8 || run.q == Q::radius) ? set.slow
                               : run.packet <= 2                       ? set.rays
                               : run.packet == 4                       ? set.tiles2
                                                                       : set.tiles4;
            RayResults res(rays.size());
            const bool em = run.b == built.size();
            if (!em) rayscan::set_entry_point_search(entry_search_of(indexes[run.b]));
            // The pairs row measures the interleaved pairs whatever this CPU's default (single
            // rays on Intel: rayscan::interleaved_pairs); ray_query_each keeps the default.
            rayscan::set_interleaved_pairs(run.packet == 2 || rayscan::interleaved_pairs_default());
            rb::Stopwatch sw;
            rb::ThreadCpuStopwatch cpu;
            const std::uint64_t tot =
                run.packet == 0 ? (em ? run_embree(es, rays, res)
                                      : run_rayscan(built[run.b], rays, make_query(run.q, radius), res))
                : em              ? run_embree_packets(es, rays, run.packet, res)
                : run.packet == 1 ? run_rayscan_each(built[run.b], rays, make_query(run.q, radius), res)
                : run.packet == 2 ? run_rayscan_pairs(built[run.b], rays, make_query(run.q, radius), res)
                                  : run_rayscan_packets(built[run.b], rays, static_cast<std::size_t>(run.packet),
                                                        make_query(run.q, radius), res);
            // One thread: TBB runs everything on this thread, so its CPU time is the cost free of
            // waiting for a core on the shared machine; more threads: wall time.
            run.ms.push_back(nt == 1 ? cpu.ms() : sw.ms());
            const std::uint64_t want = run.b == built.size() ? em_total : totals[run.b][static_cast<int>(run.q)];
            if (tot != want && !(em && run.packet))  // (Embree's packets may differ from rtcIntersect1 in float)
              rb::fail(set.name + ": result count changed between runs");
          }
        const double em_rps =
            static_cast<double>(set.rays.size()) / (rb::median(runs[first_packet_run - 1].ms) / 1e3);
        // The fastest round of each as well: Embree's single-ray passes at 1e7 vary 2-4x within one
        // process (with almost no page faults or context switches; ours by ~1.3x), so a median of a
        // few rounds can flatter rayscan there (bench/notes/: Embree's erratic passes). NaN
        // without rounds, as rb::median.
        const auto fastest = [](const Run& run) {
          return run.ms.empty() ? std::numeric_limits<double>::quiet_NaN()
                                : *std::min_element(run.ms.begin(), run.ms.end());
        };
        const double em_fastest_ms = fastest(runs[first_packet_run - 1]);
        std::printf("\n%d thread%s, rays/s (%s; kNN and radius timed on %zu of the rays):\n", nt,
                    nt > 1 ? "s" : "", nt == 1 ? "per CPU-second of the one thread" : "wall clock",
                    set.slow.size());
        std::printf("| index | kNN k=8 | radius r | closest | sphere_hit | sphere_hit / Embree (goal >= 1.0) | "
                    "fastest rounds: sphere_hit / Embree |\n");
        std::printf("|---|---:|---:|---:|---:|---:|---:|\n");
        for (std::size_t b = 0; b < built.size(); ++b) {
          std::printf("| rayscan %s", indexes[b].c_str());
          double sphere_rps = 0;
          for (Q q : kQueries) {
            const Run& run = runs[b * kQueries.size() + static_cast<std::size_t>(q)];
            const auto& rays = (q == Q::knn8 || q == Q::radius) ? set.slow : set.rays;
            const double rps = static_cast<double>(rays.size()) / (rb::median(run.ms) / 1e3);
            if (q == Q::sphere) sphere_rps = rps;
            std::printf(" | %s", mrays(rps).c_str());
          }
          const double sphere_fastest_ms = fastest(runs[b * kQueries.size() + static_cast<std::size_t>(Q::sphere)]);
          std::printf(" | %.2fx | %.2fx |\n", sphere_rps / em_rps, em_fastest_ms / sphere_fastest_ms);
        }
        std::printf("| Embree 3 first hit (rtcIntersect1) | | | | %s | 1 | 1 |\n", mrays(em_rps).c_str());
        if (packets) {
          // Coherent rays: the camera's first sphere hit in pixel packets, same rounds as above.
          double em_best = em_rps;
          std::string em_best_name = "rtcIntersect1";
          for (std::size_t k = first_packet_run; k < runs.size(); ++k)
            if (runs[k].b == built.size()) {
              const double rps = static_cast<double>(set.rays.size()) / (rb::median(runs[k].ms) / 1e3);
              if (rps > em_best) em_best = rps, em_best_name = "rtcIntersect" + std::to_string(runs[k].packet);
            }
          std::printf("\ncoherent rays, %d thread%s: first sphere hit of the camera rays in pixel packets and batches "
                      "(rays/s, same rounds as above):\n", nt, nt > 1 ? "s" : "");
          std::printf("| contender | rays/s | vs its single rays | vs Embree rtcIntersect1 | vs Embree's best (%s) | "
                      "fastest rounds: vs Embree rtcIntersect1 |\n"
                      "|---|---:|---:|---:|---:|---:|\n", em_best_name.c_str());
          for (std::size_t k = 0; k < runs.size(); ++k) {
            const Run& run = runs[k];
            if (run.q != Q::sphere) continue;
            const bool em = run.b == built.size();
            const double rps = static_cast<double>(set.rays.size()) / (rb::median(run.ms) / 1e3);
            const Run& single = em ? runs[built.size() * kQueries.size()]
                                   : runs[run.b * kQueries.size() + static_cast<std::size_t>(Q::sphere)];
            const double single_rps = static_cast<double>(set.rays.size()) / (rb::median(single.ms) / 1e3);
            std::string who = em ? std::string("Embree ") + (run.packet ? "rtcIntersect" + std::to_string(run.packet) +
                                                                              (run.packet == 4 ? " (2x2)" : run.packet == 8 ? " (4x2)" : " (4x4)")
                                                                        : "rtcIntersect1")
                                 : "rayscan " + indexes[run.b] +
                                       (run.packet == 0   ? " single rays"
                                        : run.packet == 1 ? (rayscan::interleaved_pairs_default()
                                                                 ? " ray_query_each, row-major (two rays interleaved)"
                                                                 : " ray_query_each, row-major (rays one by one)")
                                        : run.packet == 2 ? " ray_first_hit_each, row-major (two rays interleaved)"
                                        : run.packet == 4 ? " packets 2x2"
                                                          : " packets 4x4");
            std::printf("| %s | %s | %.2fx | %.2fx | %.2fx | %.2fx |\n", who.c_str(), mrays(rps).c_str(), rps / single_rps,
                        rps / em_rps, rps / em_best, em_fastest_ms / fastest(run));
          }
        }
        std::fflush(stdout);
      }
    }
  }
  std::printf("\nload average at the end: %s\n", rb::loadavg().c_str());
  return 0;
}
