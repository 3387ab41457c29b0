// Shared generators, the independent brute-force oracle and the first-hit answer comparison for the
// core tests.
#pragma once

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "../common/entry_search_guard.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace rayscan::test {

/// Point distributions the property tests sweep.
enum class Dist { uniform, clustered, identical, grid, utm_mm };

inline const char* name(Dist d) {
  switch (d) {
    case Dist::uniform: return "uniform";
    case Dist::clustered: return "clustered";
    case Dist::identical: return "identical";
    case Dist::grid: return "grid";
    case Dist::utm_mm: return "utm_mm";
  }
  return "?";
}

/// Three draws of f, in this order, as a vector: the order of evaluation of a constructor's
/// arguments is unspecified (GCC draws z first, Clang x), so Vec3(f(), f(), f()) would give each
/// compiler different test data.
template <class F>
inline Vec3 draw3(F&& f) {
  const double x = f();
  const double y = f();
  const double z = f();
  return Vec3(x, y, z);
}

/// n points of distribution d, deterministic in (n, d, seed).
/// grid: integer lattice coordinates in [0, 8]^3 / 8, i.e. exactly on octree cell boundaries, with
/// repeats; utm_mm: x ~ 6e5, y ~ 5.3e6 with millimetre spacing (a 0.1 m cube on a 1 mm lattice).
inline std::vector<Vec3> make_points(std::size_t n, Dist d, unsigned seed = 1) {
  std::mt19937_64 rng(seed * 7919 + n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.02);
  std::vector<Vec3> pts(n);
  std::vector<Vec3> centres(5);
  for (auto& c : centres) c = draw3([&] { return u(rng); });
  for (std::size_t i = 0; i < n; ++i) {
    switch (d) {
      case Dist::uniform: pts[i] = draw3([&] { return u(rng); }); break;
      case Dist::clustered: pts[i] = centres[i % centres.size()] + draw3([&] { return g(rng); }); break;
      case Dist::identical: pts[i] = Vec3(0.25, 0.5, 0.75); break;
      case Dist::grid: {
        std::uniform_int_distribution<int> k(0, 8);
        pts[i] = draw3([&] { return double(k(rng)); }) / 8.0;
        break;
      }
      case Dist::utm_mm: {
        std::uniform_int_distribution<int> k(0, 100);
        pts[i] = Vec3(600000.0, 5300000.0, 100.0) + draw3([&] { return k(rng) * 0.001; });
        break;
      }
    }
  }
  return pts;
}

/// A random ray aimed through the points' bounding box (origin outside or inside).
inline Ray random_ray(std::mt19937_64& rng, const AABB& box, bool inside) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Vec3 c = box.center();
  const double s = std::max(box.max_extent(), 1e-3);
  auto in_box = [&] { return box.lo + draw3([&] { return u(rng); }) * (box.hi - box.lo); };
  const Vec3 target = in_box();
  Vec3 origin = inside ? in_box() : c + draw3([&] { return u(rng) - 0.5; }) * (4.0 * s);
  Vec3 dir = target - origin;
  if (glm::length(dir) < 1e-12 * s) dir = draw3([&] { return u(rng) - 0.5; });
  return Ray(origin, dir);
}

/// Independent oracle for ray_query: a plain loop over all points in original order evaluating the
/// predicates of RayQuery's documentation, then a sort by (key, index) and a cut at k.
inline std::vector<RayHit> oracle_ray_query(std::span<const Vec3> pts, const Ray& ray,
                                            const RayQuery& q) {
  std::vector<RayHit> all;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const RayPointTerms pt = ray_point_terms(ray.origin(), ray.direction(), pts[i]);
    if (pt.d2 > q.radius * q.radius) continue;
    const double t =
        q.order == RayOrder::sphere_hit ? sphere_entry(pt.t, pt.d2, q.radius) : pt.t;
    if (t < q.t_min || t > q.t_max) continue;
    bool ok = true;
    for (const Plane& pl : q.planes) ok = ok && dist_plane(pl.point, pl.normal, pts[i]) <= 0.0;
    if (!ok) continue;
    const double dist = std::sqrt(pt.d2);
    const double key = q.order == RayOrder::ray ? dist : t;
    // slot: the oracle has no storage order; it is the original index (never compared).
    all.push_back({static_cast<PointIndex>(i), static_cast<std::uint32_t>(i), t, dist, key});
  }
  std::sort(all.begin(), all.end(), [](const RayHit& a, const RayHit& b) {
    return a.key < b.key || (a.key == b.key && a.index < b.index);
  });
  if (q.k < all.size()) all.resize(q.k);
  return all;
}

/// Every index configuration the traversal must work on.
inline std::vector<IndexOptions> all_index_options() {
  std::vector<IndexOptions> v;
  for (const char* t : {"octree-adaptive", "octree-layered", "octree-fixed"})
    for (bool ins : {false, true}) {
      IndexOptions o;
      o.type = t;
      o.capacity = 8;
      o.depth = 4;
      o.insertion = ins;
      v.push_back(o);
    }
  IndexOptions kd;
  kd.type = "kdtree";
  kd.capacity = 6;
  v.push_back(kd);
  IndexOptions bf;
  bf.type = "brute";
  v.push_back(bf);
  return v;
}

inline std::string label(const IndexOptions& o) {
  return o.type + (o.insertion ? "/insert" : "");
}

/// A first-hit answer against another that must equal it (a batch function's against the
/// single-ray call's, or one SIMD path's against another's): both absent, or both present with
/// every field bit for bit. ctx: the failure message's context.
inline void expect_same_answer(const std::optional<RayHit>& got, const std::optional<RayHit>& one,
                               const std::string& ctx) {
  ASSERT_EQ(got.has_value(), one.has_value()) << ctx;
  if (!got) return;
  EXPECT_EQ(got->index, one->index) << ctx;
  EXPECT_EQ(got->slot, one->slot) << ctx;
  EXPECT_EQ(got->t, one->t) << ctx;
  EXPECT_EQ(got->distance, one->distance) << ctx;
  EXPECT_EQ(got->key, one->key) << ctx;
}

/// Sets interleaved_pairs() for a scope and restores the value before it: tests of the pairs
/// (ray_first_hit_each) force them on, as the CPU's default may be single rays.
struct PairsGuard {
  bool saved = interleaved_pairs();
  explicit PairsGuard(bool on) { set_interleaved_pairs(on); }
  ~PairsGuard() { set_interleaved_pairs(saved); }
  PairsGuard(const PairsGuard&) = delete;
  PairsGuard& operator=(const PairsGuard&) = delete;
};

/// The CPU's vendor and family as the kernel decodes CPUID for /proc/cpuinfo (vendor_id, and
/// "cpu family": the base plus the extended family), an oracle independent of
/// simd::amd_cpu_family; nullopt where the file has neither (not x86, or no /proc).
struct CpuIdentity {
  std::string vendor;
  int family = -1;
};
inline std::optional<CpuIdentity> cpu_identity_from_proc() {
  std::ifstream in("/proc/cpuinfo");
  CpuIdentity id;
  std::string line;
  while (in && std::getline(in, line) && (id.vendor.empty() || id.family < 0)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos || colon == 0 || colon + 2 > line.size()) continue;
    const std::string key = line.substr(0, line.find_last_not_of(" \t", colon - 1) + 1);
    if (key == "vendor_id") id.vendor = line.substr(colon + 2);
    if (key == "cpu family") id.family = std::stoi(line.substr(colon + 2));
  }
  if (id.vendor.empty() || id.family < 0) return std::nullopt;
  return id;
}

}  // namespace rayscan::test
