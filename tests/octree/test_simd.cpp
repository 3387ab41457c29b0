// SIMD kernels of the traversal against independent scalar oracles: the child slab test
// never rejects a box the exact double slab test accepts, the point filter never drops a point the
// exact predicate keeps, and ray queries answer bit-identically on every path the CPU supports.
// CTest also runs the ray/point property suites once per forced path (RAYSCAN_SIMD).
#include "test_util.hpp"

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/detail/point_query_impl.hpp"
#include "rayscan/octree/detail/ray_query_impl.hpp"
#include "rayscan/octree/distance.hpp"
#include "rayscan/octree/octree.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/octree/simd.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <random>

using namespace rayscan;
using namespace rayscan::test;

namespace rayscan::simd {
// The child MINDIST kernel of a path (simd.cpp; knn_query takes it from active_kernels()).
ChildDist2Fn child_dist2_kernel(SimdPath p);
}  // namespace rayscan::simd

namespace {

std::vector<SimdPath> supported_paths() {
  std::vector<SimdPath> v;
  for (SimdPath p : {SimdPath::scalar, SimdPath::sse2, SimdPath::avx2, SimdPath::avx512})
    if (simd_path_supported(p)) v.push_back(p);
  return v;
}

/// Restores the process-wide path after a test that switches it.
struct PathGuard {
  SimdPath saved = simd_path();
  ~PathGuard() { set_simd_path(saved); }
};

TEST(Simd, ForcedPathIsActiveAndNamed) {
  const char* env = std::getenv("RAYSCAN_SIMD");
  if (!env) {
    EXPECT_EQ(simd_path(), best_simd_path());
  } else {
    const auto p = parse_simd_path(env);
    ASSERT_TRUE(p.has_value()) << env;
    if (!simd_path_supported(*p)) GTEST_SKIP() << "CPU lacks " << env;
    EXPECT_EQ(simd_path(), *p);
  }
  EXPECT_NE(simd_description().find(to_string(simd_path())), std::string::npos);
  EXPECT_FALSE(parse_simd_path("avx3").has_value());
}

TEST(Simd, ChildSlabNeverRejectsWhatTheDoubleSlabAccepts) {
  PathGuard guard;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t accepted = 0, rejected = 0;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    if (!k.child_slab) continue;
    for (int trial = 0; trial < 4000; ++trial) {
      // 1..8 float boxes (stride 9 floats, as an arbitrary record of >= 8 floats: the kernels
      // read 8 floats per box), relative to the origin 0. The 8 - n rows after them (read as
      // they are with rows8) hold a box around everything, which no lane past n may report.
      const unsigned n = 1 + static_cast<unsigned>(trial % 8);
      std::vector<float> rec(8 * 9);
      for (unsigned i = n; i < 8; ++i)
        for (int a = 0; a < 3; ++a) rec[i * 9 + a] = -1e30f, rec[i * 9 + 3 + a] = 1e30f;
      std::vector<AABB> boxes(n);
      for (unsigned i = 0; i < n; ++i) {
        const Vec3 c(u(rng), u(rng), u(rng));
        const double h = 0.3 * u(rng) * u(rng);
        for (int a = 0; a < 3; ++a) {
          rec[i * 9 + a] = static_cast<float>(c[a] - h);
          rec[i * 9 + 3 + a] = static_cast<float>(c[a] + h);
          boxes[i].lo[a] = rec[i * 9 + a];
          boxes[i].hi[a] = rec[i * 9 + 3 + a];
        }
      }
      // Rays from outside and inside, some nearly axis-parallel (huge 1/d), pads from 0.
      const Vec3 o(3 * u(rng) - 1, 3 * u(rng) - 1, 3 * u(rng) - 1);
      Vec3 dir = Vec3(u(rng), u(rng), u(rng)) - o;  // aimed into the unit cube
      if (trial % 5 == 0) dir[trial % 3] *= 1e-9;
      const Ray ray(o, dir);
      const Vec3 d = ray.direction(), inv = 1.0 / d;
      const double pad = (trial % 4 == 0) ? 0.0 : 0.05 * u(rng);
      const double t_lo = (trial % 3 == 0) ? -kInf : 0.0, t_hi = (trial % 7 == 0) ? 0.8 : kInf;
      simd::SlabRayF r{};
      const double margin = 0x1p-20 * (4.0 + pad);
      for (int a = 0; a < 3; ++a) {
        r.o_plus[a] = static_cast<float>(o[a] + pad + margin);
        r.o_minus[a] = static_cast<float>(o[a] - pad - margin);
        r.inv_d[a] = static_cast<float>(inv[a]);
      }
      if (!std::isfinite(r.inv_d[0]) || !std::isfinite(r.inv_d[1]) || !std::isfinite(r.inv_d[2])) continue;
      r.t_lo = static_cast<float>(t_lo);
      r.t_hi = static_cast<float>(t_hi);
      // The traversal's k-bound on the entry (enter_max) and the floor t_min (lb_floor), in some
      // trials: a box entered no later than the bound is never rejected.
      const double enter_max = (trial % 6 == 1) ? 2.5 * u(rng) : kInf;
      const double t_min = (trial % 6 == 2) ? 2.0 * u(rng) - 0.5 : -kInf;
      r.enter_max = detail::round_float_up(enter_max);
      r.lb_floor = detail::round_float_down(t_min);
      float entry[8], entry8[8];
      const unsigned mask = k.child_slab({rec.data(), 9, n}, r, entry);
      ASSERT_EQ(mask >> n, 0u) << "lanes beyond count must be clear";
      // The same boxes with the rows past n read as they are (ChildBoxesF::rows8): the same
      // answer, lane for lane.
      const unsigned mask8 = k.child_slab({rec.data(), 9, n, true}, r, entry8);
      ASSERT_EQ(mask8, mask) << to_string(path) << " trial " << trial;
      // And transposed (ChildBoxesF::soa, the octree's child blocks): the same again.
      {
        float soa[48], entry_t[8];
        for (unsigned i = 0; i < 8; ++i)
          for (unsigned f = 0; f < 6; ++f) soa[f * 8 + i] = rec[i * 9 + f];
        ASSERT_EQ(k.child_slab({rec.data(), 9, n, false, soa}, r, entry_t), mask) << to_string(path);
        for (unsigned i = 0; i < n; ++i)
          if ((mask >> i) & 1u) {
            ASSERT_EQ(entry_t[i], entry[i]) << to_string(path) << " trial " << trial;
          }
      }
      for (unsigned i = 0; i < n; ++i) {
        if ((mask >> i) & 1u) {
          ASSERT_EQ(entry8[i], entry[i]) << to_string(path) << " trial " << trial;
        }
      }
      // The keys kernel: the same mask, and each passing child's key is child_key(entry, i).
      if (k.child_slab_keys) {
        std::uint32_t keys[8], near = 0;
        ASSERT_EQ(k.child_slab_keys({rec.data(), 9, n, trial % 2 == 0}, r, keys, near), mask) << to_string(path);
        ASSERT_EQ(near, *std::min_element(keys, keys + 8)) << to_string(path);
        for (unsigned i = 0; i < 8; ++i)
          ASSERT_EQ(keys[i], (mask >> i & 1u) ? simd::child_key(entry[i], i) : ~0u) << to_string(path) << " lane " << i;
      }
      for (unsigned i = 0; i < n; ++i) {
        const Interval iv = slab_interval(o, inv, boxes[i], pad, t_lo, t_hi);
        if (iv.empty() || iv.lo > enter_max) {
          rejected += !(mask >> i & 1u);
          continue;
        }
        ++accepted;
        ASSERT_TRUE(mask >> i & 1u) << to_string(path) << " trial " << trial << " box " << i;
        ASSERT_LE(entry[i], std::max(iv.lo, t_min)) << to_string(path) << " entry must be a lower bound";
        ASSERT_GE(entry[i], r.lb_floor) << to_string(path) << " entry raised to the floor";
      }
    }
  }
  EXPECT_GT(accepted, 1000u);
  EXPECT_GT(rejected, 1000u);  // the test also prunes, or it would be vacuous
}

// detail::root_test (the path's ray_box kernel, simd::RayBoxFn) against the traversal's own test of
// the root (RayTraversal::test_node, constructed for the same query): it never finds a miss where
// that test lets the ray in, for the orders sphere_hit, time and ray, with and without planes, for
// rays aimed at the root box's faces, edges and corners grown by the radius plus -1, 0, 1 or 2
// tolerances, axis-parallel rays (1 / d infinite), flat clouds and UTM magnitudes; it finds a miss
// for every ray that misses the root box grown by twice node_test_tolerance_bound (a kernel that
// keeps everything fails); and ray_first_hit, ray_first_hit_each (pairs) and ray_first_hit_packet
// answer those rays as the scalar path does, which has no kernel. Counted per path.
TEST(Simd, RootKernelNeverRejectsWhatTheRootTestAccepts) {
  PathGuard guard;
  const PairsGuard pairs(true);  // (ray_first_hit_each's pairs, whatever this CPU's default)
  std::vector<std::optional<RayHit>> scalar_answers;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    std::mt19937_64 rng(35);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::size_t kept = 0, missed = 0, within_tolerance = 0, answer = 0, packet_lanes = 0;
    for (int cloud = 0; cloud < 200; ++cloud) {
      const double size = cloud % 5 == 0 ? 1e-3 : cloud % 5 == 1 ? 300.0 : 1.0;
      const Vec3 offset = cloud % 3 == 0 ? Vec3(4.5e5, 5.3e6, 120.0) : cloud % 3 == 1 ? Vec3(-2.0, 0.5, 1e3) : Vec3(0.0);
      std::vector<Vec3> pts(2 + cloud % 40);
      for (Vec3& p : pts)
        for (int a = 0; a < 3; ++a) p[a] = offset[a] + size * ((cloud % 7 == 0 && a == cloud % 3) ? 0.25 : u(rng));
      const Octree oc = Octree::build_bulk(pts);
      const AABB b = oc.node_bounds(oc.root());
      std::vector<Ray> rays;
      RayQuery q;
      q.k = 1;
      q.radius = cloud % 4 == 0 ? 0.0 : 0.05 * size * u(rng);
      q.order = cloud % 3 == 0 ? RayOrder::sphere_hit : cloud % 3 == 1 ? RayOrder::time : RayOrder::ray;
      q.t_min = cloud % 6 == 0 ? -kInf : cloud % 6 == 1 ? 3.0 * size * u(rng) : 0.0;
      q.t_max = cloud % 9 == 0 ? q.t_min + 4.0 * size * u(rng) : kInf;
      std::vector<Plane> planes;
      if (cloud % 10 == 7) planes.push_back({b.center(), glm::normalize(Vec3(u(rng) - 0.5, u(rng) - 0.5, 1.0))});
      q.planes = planes;
      q.validate();
      for (int trial = 0; trial < 64; ++trial) {
        Vec3 o;
        for (int a = 0; a < 3; ++a) o[a] = 0.5 * (b.lo[a] + b.hi[a]) + 4.0 * size * (u(rng) - 0.5);
        // The direction: at a point of the box grown by r + s * tol on each axis, s in {-1, 0, 1,
        // 2} (a face, edge or corner just inside, on or just outside the grown box), at a random
        // point around the box, or axis-parallel.
        const double tol = node_test_tolerance(o, b);
        Vec3 target;
        for (int a = 0; a < 3; ++a) {
          const int side = static_cast<int>(rng() % 3);  // lo, hi, inside
          const double grown = q.radius + static_cast<double>(static_cast<int>(rng() % 4) - 1) * tol;
          target[a] = side == 0 ? b.lo[a] - grown : side == 1 ? b.hi[a] + grown : b.lo[a] + u(rng) * (b.hi[a] - b.lo[a]);
        }
        if (trial % 8 == 3)
          for (int a = 0; a < 3; ++a) target[a] = 0.5 * (b.lo[a] + b.hi[a]) + 2.0 * size * (u(rng) - 0.5);
        Vec3 dir = target - o;
        if (trial % 8 == 5) dir[trial % 3] = 0.0;
        if (trial % 16 == 6) dir[(trial + 1) % 3] = 0.0, dir[trial % 3] = 0.0;
        if (!(glm::length(dir) > 0.0)) dir = Vec3(0.0, 0.0, 1.0);
        const Ray ray(o, dir);
        rays.push_back(ray);
        if (!k.ray_box) continue;
        const detail::RootTest found = detail::root_test<simd::Kernels, OrderKey>(k, oc, ray, q);
        ASSERT_NE(found, detail::RootTest::exact) << to_string(path);
        detail::Candidate best;
        const OrderKey key;
        detail::RayTraversal<true, Octree, OrderKey, simd::Kernels> traversal(oc, ray, q, best, nullptr, key);
        double lb;
        if (traversal.test_node(traversal.root_box, lb)) {
          ++kept;
          const Vec3 inv = 1.0 / ray.direction();
          within_tolerance += slab_interval(o, inv, b, q.radius, q.t_min, q.t_max + q.radius).empty();
          ASSERT_EQ(found, detail::RootTest::enter) << to_string(path) << " cloud " << cloud << " trial " << trial;
        }
        const Vec3 d = ray.direction();
        if (d.x != 0.0 && d.y != 0.0 && d.z != 0.0) {  // (no NaN axis: 0 * inf)
          double mag = 0;
          for (int a = 0; a < 3; ++a) mag = std::max({mag, std::abs(o[a]), std::abs(b.lo[a]), std::abs(b.hi[a])});
          const double bound = node_test_tolerance_bound(mag);
          ASSERT_LE(2.0 * tol, bound) << "cloud " << cloud;
          const double g2 = q.radius + 2.0 * bound;
          if (slab_interval_grown(o + g2, o - g2, 1.0 / d, b, q.t_min - 2.0 * bound, (q.t_max + q.radius) + 2.0 * bound)
                  .empty()) {
            ++missed;
            ASSERT_EQ(found, detail::RootTest::miss) << to_string(path) << " cloud " << cloud << " trial " << trial;
          }
        }
      }
      // The packet root test (SIMD over up to 16 rays): lane by lane the single-ray kernel's answer.
      if (k.ray_box && k.packet_ray_box && q.radius < kInf) {
        for (std::size_t first = 0; first < rays.size(); first += 16) {
          const unsigned n = static_cast<unsigned>(std::min<std::size_t>(16 - cloud % 3, rays.size() - first));
          const std::uint32_t got = k.packet_ray_box(&b.lo.x, &b.hi.x, &rays[first].origin().x,
                                                     &rays[first].direction().x, sizeof(Ray) / sizeof(double), n,
                                                     q.radius, q.t_min, q.t_max + q.radius);
          ASSERT_EQ(got >> n, 0u) << to_string(path) << ": a bit past the packet";
          for (unsigned i = 0; i < n; ++i) {
            const Ray& r = rays[first + i];
            const bool one = k.ray_box(&b.lo.x, &b.hi.x, &r.origin().x, &r.direction().x, q.radius, q.t_min,
                                       q.t_max + q.radius);
            ASSERT_EQ(((got >> i) & 1u) != 0, one) << to_string(path) << " cloud " << cloud << " ray " << first + i;
            ++packet_lanes;
          }
        }
      }
      // End to end: single rays, pairs and packets answer as the scalar path (no root kernel).
      std::vector<std::optional<RayHit>> each(rays.size()), packet(rays.size());
      ray_first_hit_each(oc, std::span<const Ray>(rays), q, std::span<std::optional<RayHit>>(each));
      ray_first_hit_packet(oc, std::span<const Ray>(rays), q, std::span<std::optional<RayHit>>(packet));
      for (std::size_t r = 0; r < rays.size(); ++r, ++answer) {
        const std::optional<RayHit> single = ray_first_hit(oc, rays[r], q);
        const std::string ctx = std::string(to_string(path)) + " cloud " + std::to_string(cloud) + " ray " + std::to_string(r);
        expect_same_answer(each[r], single, ctx + " (pairs)");
        expect_same_answer(packet[r], single, ctx + " (packets)");
        if (path == SimdPath::scalar)
          scalar_answers.push_back(single);
        else if (answer < scalar_answers.size())
          expect_same_answer(single, scalar_answers[answer], ctx + " (against the scalar path)");
        if (::testing::Test::HasFailure()) return;
      }
    }
    if (!k.ray_box) continue;
    EXPECT_GT(kept, 4000u) << to_string(path);
    EXPECT_GT(missed, 1500u) << to_string(path);
    EXPECT_GT(within_tolerance, 50u) << to_string(path);  // rays the tolerance alone lets in were reached
    if (k.packet_ray_box) {
      EXPECT_GT(packet_lanes, 4000u) << to_string(path);
    }
  }
}

// round_float_down / round_float_up (simd.hpp, stepping in IEEE bits) against their
// definition: the largest float <= x / the least float >= x, found with std::nextafter; doubles
// of every class (zeros, subnormal and normal floats, float midpoints, past the float range,
// infinities).
TEST(Simd, RoundFloatIsTheNearestFloatOnEachSide) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> ex(-160.0, 140.0);
  std::vector<double> xs = {0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300, kInf, -kInf,
                            double(std::numeric_limits<float>::max()), -double(std::numeric_limits<float>::max()),
                            double(std::numeric_limits<float>::denorm_min()) * 0.5,
                            -double(std::numeric_limits<float>::denorm_min()) * 0.5, 1.0, -1.0};
  for (int i = 0; i < 20000; ++i) {
    const double x = (i % 2 ? -1.0 : 1.0) * std::exp2(ex(rng));
    xs.push_back(x);
    const float f = static_cast<float>(x);  // and the midpoint between f and its neighbour
    xs.push_back(0.5 * (double(f) + double(std::nextafter(f, std::numeric_limits<float>::infinity()))));
  }
  const float inf = std::numeric_limits<float>::infinity();
  for (double x : xs) {
    const float d = detail::round_float_down(x), u = detail::round_float_up(x);
    ASSERT_LE(double(d), x) << x;
    ASSERT_GE(double(u), x) << x;
    if (d != inf) {
      ASSERT_GT(double(std::nextafter(d, inf)), x) << x;
    }
    if (u != -inf) {
      ASSERT_LT(double(std::nextafter(u, -inf)), x) << x;
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(detail::round_float_down(nan)));
  EXPECT_TRUE(std::isnan(detail::round_float_up(nan)));
}

// Child order keys (simd.hpp): a key's bound never exceeds the entry it encodes (and is within 8
// ulps of it), its number is the child's, and keys order as their entries do: checked on floats
// of every class (signed zeros, subnormals, infinities, neighbours in ulps).
TEST(Simd, ChildKeysAreOrderedLowerBounds) {
  std::mt19937_64 rng(11);
  std::vector<float> v = {0.0f, -0.0f, std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::denorm_min(), -std::numeric_limits<float>::denorm_min(),
                          std::numeric_limits<float>::min(), 1.0f, -1.0f};
  std::uniform_real_distribution<double> ex(-40.0, 40.0);
  for (int i = 0; i < 4000; ++i) {
    const float f = static_cast<float>((i % 2 ? -1.0 : 1.0) * std::exp2(ex(rng)));
    v.push_back(f);
    v.push_back(std::nextafter(f, std::numeric_limits<float>::infinity()));  // neighbours: same key bits
  }
  for (float e : v)
    for (unsigned i = 0; i < 8; ++i) {
      const std::uint32_t key = simd::child_key(e, i);
      ASSERT_NE(key, ~0u) << e;
      ASSERT_EQ(simd::child_key_index(key), i);
      const double b = simd::child_key_bound(key);
      ASSERT_LE(b, static_cast<double>(e)) << "bound of " << e;
      if (std::isfinite(e) && std::abs(e) > std::numeric_limits<float>::min()) {
        ASSERT_GE(b, static_cast<double>(e) - 8.0 * std::abs(static_cast<double>(e)) * 0x1p-23) << e;
      }
    }
  std::sort(v.begin(), v.end());
  for (std::size_t j = 1; j < v.size(); ++j) {
    // Non-decreasing with the entry; a smaller entry's key with the largest number still sorts no
    // later than a larger entry's key with the smallest, unless both round to the same bits.
    if (!(v[j - 1] < v[j])) continue;  // (-0 and +0 are equal entries: either order)
    const std::uint32_t a = simd::child_key(v[j - 1], 7), b = simd::child_key(v[j], 0);
    ASSERT_TRUE(a <= b || (a & ~7u) == (b & ~7u)) << v[j - 1] << " " << v[j];
  }
}

// sort_keys8 against std::sort: all 256 0-1 inputs (the 0-1 principle: a comparator network that
// sorts them sorts every input) and random keys with ties and empty lanes (~0u).
TEST(Simd, SortKeys8SortsEveryInput) {
  PathGuard guard;
  std::mt19937_64 rng(5);
  bool ran = false;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    if (!k.sort_keys8) continue;
    ran = true;
    for (unsigned bits = 0; bits < 256; ++bits) {
      std::uint32_t keys[8], want[8];
      for (unsigned i = 0; i < 8; ++i) keys[i] = want[i] = (bits >> i) & 1u;
      k.sort_keys8(keys);
      std::sort(want, want + 8);
      ASSERT_TRUE(std::equal(keys, keys + 8, want)) << to_string(path) << " bits " << bits;
    }
    for (int t = 0; t < 20000; ++t) {
      std::uint32_t keys[8], want[8];
      for (unsigned i = 0; i < 8; ++i) {
        const std::uint64_t r = rng();
        keys[i] = want[i] = (r % 5 == 0) ? ~0u : (t % 2 ? static_cast<std::uint32_t>(r >> 8) : static_cast<std::uint32_t>(r >> 60));
      }
      k.sort_keys8(keys);
      std::sort(want, want + 8);
      ASSERT_TRUE(std::equal(keys, keys + 8, want)) << to_string(path) << " trial " << t;
    }
  }
  if (!ran) GTEST_SKIP() << "no path with sort_keys8 on this CPU";
}

// sort_push_keys8 against a scalar oracle: the keys of child_slab_keys' form (n passing children
// with keys child_key(entry, i) from floats of every class, the other lanes ~0u) sorted by
// std::sort, the n - 1 farther ones as entries farthest first with child_key_bound and
// first_child + the child's number; on every path that has the kernel.
TEST(Simd, SortPushKeys8WritesTheFartherChildrenFarthestFirst) {
  PathGuard guard;
  std::mt19937_64 rng(17);
  const std::vector<float> special = {0.0f, -0.0f, std::numeric_limits<float>::infinity(),
                                      -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::denorm_min(),
                                      -std::numeric_limits<float>::denorm_min(), 1.0f, -1.0f, 1e30f, -1e30f};
  std::uniform_real_distribution<double> ex(-30.0, 30.0);
  bool ran = false;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    if (!k.sort_push_keys8) continue;
    ran = true;
    for (int t = 0; t < 20000; ++t) {
      std::uint32_t keys[8];
      std::vector<std::uint32_t> passing;
      const unsigned mask = static_cast<unsigned>(rng() & 0xFFu) | (1u << (t % 8));  // at least one child
      for (unsigned i = 0; i < 8; ++i) {
        if (!((mask >> i) & 1u)) {
          keys[i] = ~0u;
          continue;
        }
        const std::uint64_t r = rng();
        float e = (r % 7 == 0) ? special[(r >> 8) % special.size()]
                               : static_cast<float>((r % 2 ? -1.0 : 1.0) * std::exp2(ex(rng)));
        if (t % 3 == 0) e = static_cast<float>(r % 4);  // ties of entries
        keys[i] = simd::child_key(e, i);
        passing.push_back(keys[i]);
      }
      std::sort(passing.begin(), passing.end());
      const std::uint32_t first = static_cast<std::uint32_t>(rng() >> 40);
      detail::NodeEntry<std::uint32_t> out[8];  // the traversal's own entries, as it passes them
      std::memset(out, 0xFF, sizeof out);
      k.sort_push_keys8(keys, static_cast<unsigned>(passing.size()), first, out);
      for (std::size_t j = 0; j + 1 < passing.size(); ++j) {
        const std::uint32_t key = passing[passing.size() - 1 - j];
        const double want = simd::child_key_bound(key);
        ASSERT_EQ(std::bit_cast<std::uint64_t>(out[j].lb), std::bit_cast<std::uint64_t>(want))
            << to_string(path) << " trial " << t << " entry " << j;
        ASSERT_EQ(out[j].node, first + simd::child_key_index(key)) << to_string(path) << " trial " << t;
        // Bytes 12..15 zero: knn_query's KnnEntry reads its points flag there.
        std::uint32_t pad;
        std::memcpy(&pad, reinterpret_cast<const unsigned char*>(&out[j]) + 12, 4);
        ASSERT_EQ(pad, 0u) << to_string(path) << " trial " << t;
      }
    }
  }
  if (!ran) GTEST_SKIP() << "no path with sort_push_keys8 on this CPU";
}

TEST(Simd, ChildDist2IsALowerBoundOfTheExactMindist) {
  PathGuard guard;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t positive = 0;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::ChildDist2Fn child_dist2 = simd::child_dist2_kernel(path);
    if (!child_dist2) continue;
    for (int trial = 0; trial < 3000; ++trial) {
      const unsigned n = 1 + static_cast<unsigned>(trial % 8);
      std::vector<float> rec(n * 12);
      std::vector<AABB> boxes(n);
      for (unsigned i = 0; i < n; ++i) {
        const Vec3 c(u(rng), u(rng), u(rng));
        const double h = 0.2 * u(rng);
        for (int a = 0; a < 3; ++a) {
          rec[i * 12 + a] = static_cast<float>(c[a] - h);
          rec[i * 12 + 3 + a] = static_cast<float>(c[a] + h);
          boxes[i].lo[a] = rec[i * 12 + a];
          boxes[i].hi[a] = rec[i * 12 + 3 + a];
        }
      }
      const Vec3 q(3 * u(rng) - 1, 3 * u(rng) - 1, 3 * u(rng) - 1);
      const float qf[3] = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z)};
      float lb2[8];
      child_dist2({rec.data(), 12, n}, qf, static_cast<float>(0x1p-20 * 3.0), lb2);
      for (unsigned i = 0; i < n; ++i) {
        const double exact = distance2_point_box(q, boxes[i]);
        positive += lb2[i] > 0.5 * exact && exact > 0;
        ASSERT_LE(lb2[i], exact) << to_string(path) << " trial " << trial << " box " << i;
      }
    }
  }
  EXPECT_GT(positive, 1000u);  // the bound is also tight enough to prune
}

// child_dist2_keys against child_dist2 on the same path (the bounds it encodes) and the scalar
// child_key: the mask is the children i < n within the bound, the keys of the others ~0u, near the
// least key; bounds on both sides of the children's own, 0 and infinity.
TEST(Simd, ChildDist2KeysEncodeTheChildrenWithinTheBound) {
  PathGuard guard;
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  bool ran = false;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    if (!k.child_dist2_keys) continue;
    ASSERT_NE(k.child_dist2, nullptr);
    ran = true;
    for (int trial = 0; trial < 5000; ++trial) {
      const unsigned n = 1 + static_cast<unsigned>(trial % 8);
      std::vector<float> rec(8 * 12, 0.5f);  // rows past n readable (as an octree's records)
      for (unsigned i = 0; i < n; ++i)
        for (int a = 0; a < 3; ++a) {
          const double c = u(rng), h = 0.2 * u(rng);
          rec[i * 12 + a] = static_cast<float>(c - h);
          rec[i * 12 + 3 + a] = static_cast<float>(c + h);
        }
      const float q[3] = {static_cast<float>(3 * u(rng) - 1), static_cast<float>(3 * u(rng) - 1),
                          static_cast<float>(3 * u(rng) - 1)};
      const float margin = static_cast<float>(0x1p-20 * 3.0);
      const simd::ChildBoxesF boxes{rec.data(), 12, n};
      float lb2[8];
      k.child_dist2(boxes, q, margin, lb2);
      const float pick = lb2[trial % n];
      const float bound = trial % 7 == 0   ? std::numeric_limits<float>::infinity()
                          : trial % 7 == 1 ? 0.0f
                          : trial % 7 == 2 ? pick
                          : trial % 7 == 3 ? std::nextafter(pick, 0.0f)
                                           : static_cast<float>(u(rng) * 2.0);
      unsigned want_mask = 0;
      std::uint32_t want_keys[8], want_near = ~0u;
      for (unsigned i = 0; i < 8; ++i) {
        const bool in = i < n && lb2[i] <= bound;
        want_mask |= static_cast<unsigned>(in) << i;
        want_keys[i] = in ? simd::child_key(lb2[i], i) : ~0u;
        want_near = std::min(want_near, want_keys[i]);
      }
      std::uint32_t keys[8], near = 0;
      const unsigned mask = k.child_dist2_keys(boxes, q, margin, bound, keys, near);
      ASSERT_EQ(mask, want_mask) << to_string(path) << " trial " << trial;
      ASSERT_TRUE(std::equal(keys, keys + 8, want_keys)) << to_string(path) << " trial " << trial;
      if (mask) {
        ASSERT_EQ(near, want_near) << to_string(path) << " trial " << trial;
      }
    }
  }
  if (!ran) GTEST_SKIP() << "no path with child_dist2_keys on this CPU";
}

TEST(Simd, KnnIsBitIdenticalOnEveryPath) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(20000, Dist::utm_mm, 4);
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
  for (const OctreeLayout layout : {OctreeLayout::layered, OctreeLayout::fixed, OctreeLayout::adaptive}) {
    OctreeConfig cfg;
    cfg.layout = layout;
    const Octree tree = Octree::build_bulk(pts, cfg);
    for (int i = 0; i < 30; ++i) {
      const Vec3 q = pts[pick(rng)] + Vec3(0.0004, -0.0003, 0.0002);
      // Oracle: every point, sorted by (squared distance, index).
      std::vector<std::pair<double, PointIndex>> all(pts.size());
      for (std::size_t j = 0; j < pts.size(); ++j) {
        const Vec3 v = pts[j] - q;
        all[j] = {glm::dot(v, v), static_cast<PointIndex>(j)};
      }
      // k = 1 to 8: the vector k best (detail::Best8) on the SIMD instances (the k-th in every
      // lane), the sorted candidate array on the others; k = 20: the sorted array; k = 40: the
      // heap (detail::kKnnSortedMax = 32).
      std::partial_sort(all.begin(), all.begin() + 40, all.end());
      for (const std::size_t k : {1, 2, 3, 4, 5, 6, 7, 8, 20, 40}) {
        std::vector<Neighbor> want;
        for (std::size_t j = 0; j < k; ++j) want.push_back({all[j].second, std::sqrt(all[j].first)});
        for (SimdPath path : supported_paths()) {
          set_simd_path(path);
          // Every SIMD path bounds the children with child_dist2 (the scalar path has none).
          ASSERT_EQ(simd::active_kernels().child_dist2 == nullptr, path == SimdPath::scalar) << to_string(path);
          const auto got = knn(tree, q, k);
          ASSERT_EQ(got.size(), want.size()) << to_string(path);
          for (std::size_t j = 0; j < got.size(); ++j) {
            ASSERT_EQ(got[j].index, want[j].index) << to_string(path) << " k " << k << " rank " << j;
            ASSERT_EQ(got[j].distance, want[j].distance) << to_string(path) << " k " << k << " rank " << j;
          }
        }
      }
    }
  }
}

// Runs f(k, path) with each supported SIMD path set whose kernels k have a point filter.
template <class F>
void for_each_point_filter(F&& f) {
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    const simd::Kernels& k = simd::active_kernels();
    if (k.point_filter) f(k, path);
  }
}

// Runs kernel set k's point filter over pts[off, end) with f and returns, per point, whether it
// was kept (a local index past the count, or kept twice, is reported as a failure and ignored).
std::vector<char> filter_kept(const simd::Kernels& k, const std::vector<Vec3>& pts, unsigned off,
                              const simd::PointFilterD& f) {
  const unsigned count = static_cast<unsigned>(pts.size()) - off;
  std::vector<std::uint32_t> sel(count);
  const unsigned n = k.point_filter(&pts[off].x, count, f, sel.data());
  std::vector<char> in(count, 0);
  for (unsigned j = 0; j < n; ++j) {
    if (sel[j] >= count) ADD_FAILURE() << "local index " << sel[j] << " past the count " << count;
    else if (in[sel[j]]) ADD_FAILURE() << "local index " << sel[j] << " kept twice";
    else in[sel[j]] = 1;
  }
  return in;
}

TEST(Simd, PointFilterNeverDropsAPointThatPasses) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(1003, Dist::utm_mm, 5);  // large magnitudes, mm lattice
  std::mt19937_64 rng(11);
  const AABB box = bounds_of(pts);
  std::size_t kept = 0, dropped = 0;
  for_each_point_filter([&](const simd::Kernels& k, [[maybe_unused]] SimdPath path) {
    for (int trial = 0; trial < 200; ++trial) {
      const Ray ray = random_ray(rng, box, trial % 2 == 0);
      const Vec3 o = ray.origin(), d = ray.direction();
      const double r2 = std::pow(0.004 * (1 + trial % 5), 2), t_lo = (trial % 3) ? -kInf : 0.0, t_hi = kInf;
      // Bounds as the traversal passes them (widened by 1e-12 of the scale).
      const double vmax = glm::length(o - box.center()) + glm::length(box.hi - box.lo);
      const simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, r2 + 1e-12 * vmax * vmax,
                                 t_lo - 1e-12 * vmax, t_hi};
      const unsigned off = static_cast<unsigned>(trial % 7);  // unaligned starts and odd counts
      const unsigned count = static_cast<unsigned>(pts.size()) - off;
      const std::vector<char> in = filter_kept(k, pts, off, f);
      for (unsigned j = 0; j < count; ++j) {
        const RayPointTerms pt = ray_point_terms(o, d, pts[off + j]);
        const bool pass = pt.d2 <= r2 && pt.t >= t_lo;
        if (pass) {
          ++kept;
          ASSERT_TRUE(in[j]) << to_string(path) << " dropped point " << j << " of trial " << trial;
        } else {
          dropped += !in[j];
        }
      }
    }
  });
  EXPECT_GT(kept, 100u);
  EXPECT_GT(dropped, 1000u);
}

// The packet filter (SIMD over up to 16 rays) keeps, for each ray of its mask, exactly the points
// the same path's single-ray filter keeps with that ray's constants (the same expressions), so
// never one fewer than the exact predicate; no ray outside the mask, no point twice, in order.
TEST(Simd, PacketPointFilterKeepsWhatEachRaysOwnFilterKeeps) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(301, Dist::utm_mm, 7);  // large magnitudes, mm lattice
  std::mt19937_64 rng(23);
  const AABB box = bounds_of(pts);
  std::size_t paths = 0, kept = 0;
  for_each_point_filter([&](const simd::Kernels& k, SimdPath path) {
    if (!k.packet_point_filter) return;
    ++paths;
    for (int trial = 0; trial < 60; ++trial) {
      alignas(64) simd::PointFilterPacketD pk;
      simd::PointFilterD single[16];
      const double vmax = glm::length(box.hi - box.lo) * 4.0;
      for (unsigned i = 0; i < 16; ++i) {
        // Every third origin inside the box, the others outside it.
        const Ray ray = random_ray(rng, box, (trial + i) % 3 == 0);
        const Vec3 o = ray.origin(), d = ray.direction();
        const double r2 = std::pow(0.004 * (1 + (trial + i) % 5), 2);
        const double t_lo = ((trial + i) % 3) ? -kInf : 0.0, t_hi = (i % 4 == 3) ? 0.5 * vmax : kInf;
        single[i] = simd::PointFilterD{{o.x, o.y, o.z}, {d.x, d.y, d.z}, r2 + 1e-12 * vmax * vmax,
                                       t_lo - 1e-12 * vmax, t_hi};
        for (int a = 0; a < 3; ++a) {
          pk.o[a][i] = single[i].o[a];
          pk.d[a][i] = single[i].d[a];
        }
        pk.d2_max[i] = single[i].d2_max;
        pk.t_lo[i] = single[i].t_lo;
        pk.t_hi[i] = single[i].t_hi;
      }
      // Ray masks: all, one half, the other, sparse, a single ray.
      const std::uint32_t masks[] = {0xFFFFu, 0x00FFu, 0xFF00u, 0x8421u, 1u << (trial % 16),
                                     static_cast<std::uint32_t>(rng()) & 0xFFFFu};
      const std::uint32_t rays = masks[trial % 6] ? masks[trial % 6] : 1u;
      const unsigned off = static_cast<unsigned>(trial % 5);
      const unsigned count = static_cast<unsigned>(pts.size()) - off - static_cast<unsigned>(trial % 11) * 20;
      std::vector<std::uint32_t> idx(count), got(count);
      const unsigned n = k.packet_point_filter(&pts[off].x, count, pk, rays, idx.data(), got.data());
      ASSERT_LE(n, count);
      std::vector<std::uint32_t> per_point(count, 0);
      for (unsigned j = 0; j < n; ++j) {
        ASSERT_LT(idx[j], count) << to_string(path);
        if (j > 0) {
          ASSERT_LT(idx[j - 1], idx[j]) << to_string(path) << ": points out of order or twice";
        }
        ASSERT_NE(got[j], 0u) << to_string(path) << ": a point kept for no ray";
        ASSERT_EQ(got[j] & ~rays, 0u) << to_string(path) << ": a ray outside the mask";
        per_point[idx[j]] = got[j];
      }
      const std::vector<Vec3> sub(pts.begin() + off, pts.begin() + off + count);
      for (unsigned i = 0; i < 16; ++i) {
        if (!((rays >> i) & 1u)) continue;
        const std::vector<char> in = filter_kept(k, sub, 0, single[i]);
        for (unsigned j = 0; j < count; ++j) {
          const bool packet = (per_point[j] >> i) & 1u;
          ASSERT_EQ(packet, in[j] != 0) << to_string(path) << ": ray " << i << ", point " << j << ", trial " << trial;
          kept += packet;
          const RayPointTerms pt = ray_point_terms(Vec3(single[i].o[0], single[i].o[1], single[i].o[2]),
                                                   Vec3(single[i].d[0], single[i].d[1], single[i].d[2]), sub[j]);
          if (pt.d2 <= single[i].d2_max - 1e-12 * vmax * vmax && pt.t >= single[i].t_lo + 1e-12 * vmax &&
              pt.t <= single[i].t_hi) {
            ASSERT_TRUE(packet) << to_string(path) << ": ray " << i << " dropped point " << j;
          }
        }
      }
    }
  });
  if (paths == 0) GTEST_SKIP() << "no SIMD path with the packet point filter on this CPU";
  EXPECT_GT(kept, 200u);
}

// The filter with a radius per point (PointFilterD::radii, surfel rendering's disc radii): never
// drops a point within its own radius (oracle: d^2 <= r_i^2 in scalar double, as DiscKey::reject)
// nor, with t_lo_own, one whose t_p lies within its own radius before the floor; and drops most
// points that pass the common bounds but not their own.
TEST(Simd, PointFilterWithPerPointRadiiNeverDropsAPointWithinItsRadius) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(1003, Dist::utm_mm, 7);
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<float> ur(0.0005f, 0.02f);
  std::vector<float> radii(pts.size());
  for (float& r : radii) r = ur(rng);
  const AABB box = bounds_of(pts);
  std::size_t kept = 0, dropped_by_radius = 0, dropped_by_t = 0;
  for_each_point_filter([&](const simd::Kernels& k, [[maybe_unused]] SimdPath path) {
    for (int trial = 0; trial < 200; ++trial) {
      const Ray ray = random_ray(rng, box, trial % 2 == 0);
      const Vec3 o = ray.origin(), d = ray.direction();
      const double r_max = 0.02, vmax = glm::length(o - box.center()) + glm::length(box.hi - box.lo);
      const double slack = 1e-12 * vmax * vmax;
      const unsigned off = static_cast<unsigned>(trial % 11);  // unaligned starts and odd counts
      simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, r_max * r_max + slack, -kInf, kInf,
                           radii.data() + off, slack};
      // Every other trial a key floor as the traversal sets it (RefinedKey::key_min): t_lo the
      // query radius before it, t_lo_own the floor itself (the projection of a random point).
      const bool floor = trial % 4 >= 2;
      const double t_floor = ray_point_terms(o, d, pts[rng() % pts.size()]).t;
      const double slack_t = 1e-12 * vmax;
      if (floor) {
        f.t_lo = t_floor - r_max - slack_t;
        f.t_lo_own = t_floor - slack_t;
      }
      const unsigned count = static_cast<unsigned>(pts.size()) - off;
      const std::vector<char> in = filter_kept(k, pts, off, f);
      for (unsigned j = 0; j < count; ++j) {
        const RayPointTerms pt = ray_point_terms(o, d, pts[off + j]);
        const double r = radii[off + j];
        if (pt.d2 <= r * r && (!floor || pt.t >= t_floor - r)) {
          ++kept;
          ASSERT_TRUE(in[j]) << to_string(path) << " dropped point " << j << " of trial " << trial;
        } else if (pt.d2 <= r * r && pt.t >= t_floor - r_max) {
          dropped_by_t += !in[j];
        } else if (pt.d2 <= r_max * r_max && (!floor || pt.t >= t_floor - r_max)) {
          dropped_by_radius += !in[j];
        }
      }
    }
  });
  EXPECT_GT(kept, 100u);
  EXPECT_GT(dropped_by_radius, 100u);  // the per-point radius filters, not only the common bound
  EXPECT_GT(dropped_by_t, 100u);       // and so does each point's own t floor (t_lo_own)
}

// With per-point radii, every point the filter keeps passed its widened tests, the last count %
// width points (the scalar tail, or the AVX2 kernel's overlapping last step) included: points far
// inside or far outside one bound each (the
// common distance bound, each point's own radius, both ends of the t window, each point's own t
// floor) and passing points with a NaN radius (which keeps the common bounds), every count from 1
// to 11 on every path; the kept set must be exactly the passing one.
TEST(Simd, PointFilterWithRadiiKeepsOnlyPassingPointsTailIncluded) {
  PathGuard guard;
  std::mt19937_64 rng(21);
  const Vec3 o(636300.5, 848450.25, 1050.0), d = glm::normalize(Vec3(0.3, 0.8, -0.5));
  const Vec3 side = glm::normalize(glm::cross(d, Vec3(0, 0, 1)));
  for_each_point_filter([&](const simd::Kernels& k, [[maybe_unused]] SimdPath path) {
    for (int trial = 0; trial < 60; ++trial) {
      const unsigned count = 1 + static_cast<unsigned>(trial % 11);
      std::vector<Vec3> pts;
      std::vector<float> radii;
      std::vector<char> pass;
      for (unsigned j = 0; j < count; ++j) {
        // kind 0: passes (radius 1); 1: outside the common bound only (1.5 from the ray, radius
        // 2); 2: outside its own radius only (0.5 from the ray, radius 0.1); 3: before the t
        // window only (t = 2 < 5, radius 9: its own floor is 10 - 9 = 1); 4: more than its own
        // radius before the floor only (t = 8, radius 1); 5: past the window (t = 150 > 100);
        // 6: passes with a NaN radius.
        const int kind = static_cast<int>(rng() % 7);
        const double t = kind == 3 ? 2.0 : kind == 4 ? 8.0 : kind == 5 ? 150.0 : 20.0;
        const double off = kind == 1 ? 1.5 : kind == 2 ? 0.5 : 0.05;
        pts.push_back(o + t * d + off * side);
        radii.push_back(kind == 1   ? 2.0f
                        : kind == 2 ? 0.1f
                        : kind == 3 ? 9.0f
                        : kind == 6 ? std::numeric_limits<float>::quiet_NaN()
                                    : 1.0f);
        pass.push_back(kind == 0 || kind == 6);
      }
      const simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, 1.0, 5.0, 100.0, radii.data(), 1e-9, 10.0};
      const std::vector<char> in = filter_kept(k, pts, 0, f);
      for (unsigned j = 0; j < count; ++j)
        EXPECT_EQ(in[j], pass[j]) << to_string(path) << " point " << j << " of " << count;
    }
  });
}

// The ray-disc test in scalar double (pbrt-v4 6.4.2, as render::ray_disc_t, which the core tests do
// not link): the t where o + t d crosses the disc (centre c, unit normal n, radius r) in
// [t_lo, t_hi], or nullopt.
std::optional<double> disc_hit(const Vec3& o, const Vec3& d, const Vec3& c, const Vec3& n, double r, double t_lo,
                               double t_hi) {
  const double denom = glm::dot(d, n);
  if (std::abs(denom) < 1e-12) return std::nullopt;
  const Vec3 v = c - o;
  const double t = glm::dot(v, n) / denom;
  if (!(t >= t_lo && t <= t_hi)) return std::nullopt;
  const Vec3 w = t * d - v;
  if (!(glm::dot(w, w) <= r * r)) return std::nullopt;
  return t;
}

// The filter with disc normals (PointFilterD::normals, surfel rendering's ray-disc test): points
// within about their radius of rays at UTM magnitudes, normals random, a fifth of them within
// 0.06 degrees of parallel to the ray, a fifth at a disc's rim to within 1e-13 (where the
// kernels' rounding differs from the scalar test's); t windows [0, 40] or open, every
// count from 1 to 19 at unaligned starts. It never drops a disc the scalar test hits, and the
// AVX2 and AVX-512 kernels drop most of those within their radius of the ray that it misses.
TEST(Simd, PointFilterWithDiscNormalsNeverDropsAHitDisc) {
  PathGuard guard;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto unit = [&] {
    for (;;) {
      const Vec3 v(2 * u(rng) - 1, 2 * u(rng) - 1, 2 * u(rng) - 1);
      if (glm::dot(v, v) > 0.01 && glm::dot(v, v) <= 1.0) return glm::normalize(v);
    }
  };
  std::size_t hits = 0, misses_near = 0, dropped = 0;
  for_each_point_filter([&](const simd::Kernels& k, SimdPath path) {
    std::size_t path_misses = 0, path_dropped = 0;
    for (int trial = 0; trial < 400; ++trial) {
      const Vec3 o = Vec3(636300.5, 848450.25, 1050.0) + 50.0 * unit();
      const Vec3 d = unit();
      const bool window = trial % 2 == 0;
      const double t_lo = window ? 0.0 : -kInf, t_hi = window ? 40.0 : kInf;
      const unsigned count = 1 + static_cast<unsigned>(trial % 19), off = static_cast<unsigned>(trial % 3);
      std::vector<Vec3> pts(off + count);
      std::vector<float> radii(off + count), normals(3 * (off + count));
      double r_max = 0;
      for (unsigned j = 0; j < off + count; ++j) {
        const float r = static_cast<float>(0.05 + 2.0 * u(rng));
        Vec3 n = unit();
        if (u(rng) < 0.2) n = glm::normalize(glm::cross(d, n) + 1e-3 * (u(rng) - 0.5) * d);  // near parallel
        const glm::vec3 nf(n);
        const Vec3 side = glm::normalize(glm::cross(d, unit()));
        pts[j] = o + (-10.0 + 60.0 * u(rng)) * d + (1.2 * u(rng) * r) * side;
        if (u(rng) < 0.2) {  // at the disc's rim: the centre r (1 +- 1e-13) from the plane crossing
          const Vec3 nd(nf);
          const Vec3 in_plane = glm::normalize(glm::cross(nd, glm::cross(d, nd)));
          pts[j] = o + (5.0 + 30.0 * u(rng)) * d - (double(r) * (1 + 1e-13 * (u(rng) - 0.5))) * in_plane;
        }
        radii[j] = r;
        normals[3 * j] = nf.x, normals[3 * j + 1] = nf.y, normals[3 * j + 2] = nf.z;
        r_max = std::max(r_max, double(r));
      }
      // Bounds as RayTraversal sets them (update_simd, with the key floor t_lo).
      const double vmax = 200.0, slack_t = 1e-12 * vmax, slack_d2 = 1e-12 * vmax * vmax;
      simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, r_max * r_max + slack_d2, -kInf, kInf,
                           radii.data() + off, slack_d2};
      if (window) {
        f.t_lo = t_lo - r_max - slack_t;
        f.t_lo_own = t_lo - slack_t;
        f.t_hi = t_hi + r_max + slack_t;
      }
      f.normals = normals.data() + 3 * off;
      f.disc_t_lo = t_lo;
      f.disc_t_hi = t_hi;
      f.disc_slack = 0x1p-36 * vmax + 1e-9 * vmax;
      const std::vector<char> in = filter_kept(k, pts, off, f);
      for (unsigned j = 0; j < count; ++j) {
        const unsigned p = off + j;
        const Vec3 n(normals[3 * p], normals[3 * p + 1], normals[3 * p + 2]);
        const double r = radii[p];
        if (disc_hit(o, d, pts[p], n, r, t_lo, t_hi)) {
          ++hits;
          ASSERT_TRUE(in[j]) << to_string(path) << " dropped hit disc " << j << " of " << count << ", trial " << trial;
        } else if (ray_point_terms(o, d, pts[p]).d2 <= r * r) {
          ++path_misses;
          path_dropped += !in[j];
        }
      }
    }
    if (path == SimdPath::avx2 || path == SimdPath::avx512) {
      misses_near += path_misses;
      dropped += path_dropped;
      EXPECT_GT(path_dropped, path_misses / 2) << to_string(path);
    }
  });
  EXPECT_GT(hits, 1000u);
  if (simd_path_supported(SimdPath::avx2)) {
    EXPECT_GT(dropped, 500u) << "of " << misses_near;
  }
  std::printf("disc filter: %zu hits kept; %zu of %zu misses near the ray dropped\n", hits, dropped, misses_near);
}

// The disc filter's margins at their limits: discs hit exactly at their rim (r the least float with
// r^2 >= the scalar test's |t d - v|^2) with the window closed on the hit itself (disc_t_lo =
// disc_t_hi = t: the key floor and the k-bound at a tie), |d.n| from 2^-30 up, |p - o| up to
// 1e5 at UTM magnitudes, and the least disc_slack the doc allows (2^-36 max |p - o|). None may be
// dropped. A lane with a NaN normal is kept whatever the window, one with a NaN radius by an open
// window (no radius test, as the filter without radii); a window that holds no t (disc_t_lo =
// +inf, or disc_t_hi = -inf) drops every other lane.
TEST(Simd, PointFilterWithDiscNormalsKeepsRimHitsAtTheWindowEnds) {
  PathGuard guard;
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto unit = [&] {
    for (;;) {
      const Vec3 v(2 * u(rng) - 1, 2 * u(rng) - 1, 2 * u(rng) - 1);
      if (glm::dot(v, v) > 0.01 && glm::dot(v, v) <= 1.0) return glm::normalize(v);
    }
  };
  constexpr unsigned kCount = 8;
  std::size_t tested = 0;
  for_each_point_filter([&](const simd::Kernels& k, SimdPath path) {
    if (path != SimdPath::avx2 && path != SimdPath::avx512) return;  // the kernels that use normals
    for (int trial = 0; trial < 30000; ++trial) {
      const Vec3 o(636300.123 + 1000 * u(rng), 8484500.77 + 1000 * u(rng), 105.3 + 10 * u(rng));
      const Vec3 d = unit();
      const double scale = trial % 3 == 0 ? 10.0 : trial % 3 == 1 ? 1e3 : 1e5;
      std::vector<Vec3> pts(kCount);
      std::vector<float> radii(kCount), normals(3 * kCount);
      std::vector<double> ts(kCount);
      double vmax = 0;
      for (unsigned j = 0; j < kCount; ++j) {
        // |d.n| = 2^-10 (1 + 5%), 2^-10 .. 2^-4, any, or 2^-30 .. 2^-11 (below the guard: kept).
        const Vec3 across = glm::normalize(glm::cross(d, unit()));
        const double c = j % 4 == 0   ? std::ldexp(1.0 + 0.05 * u(rng), -10)
                         : j % 4 == 1 ? std::ldexp(1.0, -10 + static_cast<int>(6 * u(rng)))
                                      : std::ldexp(1.0, -30 + static_cast<int>(20 * u(rng)));
        const Vec3 n = j % 4 == 2 ? unit() : glm::normalize(std::sqrt(1 - c * c) * across + c * d);
        const glm::vec3 nf(n);
        const Vec3 nd(nf);
        const Vec3 in_plane = glm::normalize(glm::cross(nd, glm::cross(d, nd)));
        const Vec3 side = glm::normalize(glm::cross(nd, in_plane));
        const double rim = 0.01 + 3 * u(rng), angle = 6.283 * u(rng);
        pts[j] = o + ((2 * u(rng) - 1) * scale) * d - rim * (std::cos(angle) * in_plane + std::sin(angle) * side);
        // The scalar test's own terms (disc_hit's), and the least float radius that it hits with.
        const Vec3 v = pts[j] - o;
        const double t = glm::dot(v, nd) / glm::dot(d, nd);
        const Vec3 w = t * d - v;
        float r = static_cast<float>(std::sqrt(glm::dot(w, w)));
        while (double(r) * double(r) < glm::dot(w, w)) r = std::nextafter(r, std::numeric_limits<float>::infinity());
        radii[j] = r;
        normals[3 * j] = nf.x, normals[3 * j + 1] = nf.y, normals[3 * j + 2] = nf.z;
        ts[j] = t;
        vmax = std::max(vmax, glm::length(v));
      }
      for (unsigned j = 0; j < kCount; ++j) {
        const Vec3 n(normals[3 * j], normals[3 * j + 1], normals[3 * j + 2]);
        if (!disc_hit(o, d, pts[j], n, radii[j], ts[j], ts[j])) continue;  // (a rounding of t itself)
        simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, kInf, -kInf, kInf, radii.data(), 1e-12 * vmax * vmax};
        f.normals = normals.data();
        f.disc_t_lo = f.disc_t_hi = ts[j];
        f.disc_slack = std::ldexp(vmax, -36);
        ++tested;
        ASSERT_TRUE(filter_kept(k, pts, 0, f)[j])
            << to_string(path) << " dropped a rim hit at t = " << ts[j] << ", trial " << trial << ", disc " << j;
      }
    }
    // NaN data keeps its lane; an empty window drops every other one.
    const Vec3 o(636300.5, 848450.25, 1050.0), d = glm::normalize(Vec3(0.3, 0.8, -0.5));
    std::vector<Vec3> pts;
    for (unsigned j = 0; j < kCount; ++j) pts.push_back(o + (5.0 + j) * d);
    std::vector<float> radii(kCount, 1.0f), normals(3 * kCount, 0.0f);
    for (unsigned j = 0; j < kCount; ++j) normals[3 * j + 2] = 1.0f;
    normals[3 * 2] = std::numeric_limits<float>::quiet_NaN();
    radii[5] = std::numeric_limits<float>::quiet_NaN();
    for (int window = 0; window < 3; ++window) {
      simd::PointFilterD f{{o.x, o.y, o.z}, {d.x, d.y, d.z}, 4.0, -kInf, kInf, radii.data(), 1e-9};
      f.normals = normals.data();
      f.disc_t_lo = window == 1 ? kInf : -kInf;
      f.disc_t_hi = window == 2 ? -kInf : kInf;
      const std::vector<char> in = filter_kept(k, pts, 0, f);
      for (unsigned j = 0; j < kCount; ++j)
        EXPECT_EQ(in[j], window == 0 || j == 2) << to_string(path) << " window " << window << " point " << j;
    }
  });
  if (simd_path_supported(SimdPath::avx2)) {
    EXPECT_GT(tested, 100000u);
  }
}

// knn_query's use of the point filter (d = 0: the distance-only loops): never drops a point within
// the bound (oracle: |p - q|^2 in scalar double, as knn_query's exact test), drops most others.
TEST(Simd, DistanceFilterNeverDropsAPointWithinTheBound) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(1003, Dist::utm_mm, 6);
  std::mt19937_64 rng(12);
  const AABB box = bounds_of(pts);
  std::size_t kept = 0, dropped = 0;
  for_each_point_filter([&](const simd::Kernels& k, [[maybe_unused]] SimdPath path) {
    for (int trial = 0; trial < 100; ++trial) {
      // Query points: data points (exact ties at distance 0) and random points in the box.
      const Vec3 q = trial % 2 ? pts[(static_cast<std::size_t>(trial) * 37) % pts.size()]
                               : box.lo + (box.hi - box.lo) * Vec3(std::uniform_real_distribution<double>(0, 1)(rng),
                                                                   std::uniform_real_distribution<double>(0, 1)(rng),
                                                                   std::uniform_real_distribution<double>(0, 1)(rng));
      const double r2 = std::pow(0.02 * box.max_extent() * (1 + trial % 4), 2);
      const double vmax = glm::length(q - box.center()) + glm::length(box.hi - box.lo);
      const simd::PointFilterD f{{q.x, q.y, q.z}, {0.0, 0.0, 0.0}, r2 * (1.0 + 1e-12) + 1e-12 * vmax * vmax,
                                 -kInf, kInf};
      const unsigned off = static_cast<unsigned>(trial % 9);  // unaligned starts and odd counts
      const unsigned count = static_cast<unsigned>(pts.size()) - off;
      const std::vector<char> in = filter_kept(k, pts, off, f);
      for (unsigned j = 0; j < count; ++j) {
        const Vec3 v = pts[off + j] - q;
        if (glm::dot(v, v) <= r2) {
          ++kept;
          ASSERT_TRUE(in[j]) << to_string(path) << " dropped point " << j << " of trial " << trial;
        } else {
          dropped += !in[j];
        }
      }
    }
  });
  EXPECT_GT(kept, 50u);
  EXPECT_GT(dropped, 10000u);
}

// Query boxes over pts for the box kernels: random boxes, boxes whose faces lie exactly on data
// points' coordinates (ties: the closed box keeps them), thin slabs, a degenerate box (one point)
// and boxes with a NaN face (keep nothing, as AABB::contains).
std::vector<AABB> box_kernel_queries(const std::vector<Vec3>& pts, std::mt19937_64& rng) {
  const AABB all = bounds_of(pts);
  std::uniform_real_distribution<double> u(-0.1, 1.1);
  std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
  const auto at = [&](double x, double y, double z) { return all.lo + (all.hi - all.lo) * Vec3(x, y, z); };
  std::vector<AABB> boxes;
  for (int i = 0; i < 40; ++i) {
    AABB b;
    b.expand(at(u(rng), u(rng), u(rng)));
    b.expand(i % 2 ? pts[pick(rng)] : at(u(rng), u(rng), u(rng)));
    boxes.push_back(b);
  }
  for (int i = 0; i < 10; ++i) {  // every face on a data point's coordinate
    AABB b;
    b.expand(pts[pick(rng)]);
    b.expand(pts[pick(rng)]);
    boxes.push_back(b);
  }
  AABB slab = all;
  slab.lo.y = slab.hi.y = pts[pick(rng)].y;
  boxes.push_back(slab);
  boxes.push_back(AABB{pts[0], pts[0]});
  AABB nan_box = all;
  nan_box.lo.z = std::nan("");
  boxes.push_back(nan_box);
  nan_box = all;
  nan_box.hi.x = std::nan("");
  boxes.push_back(nan_box);
  return boxes;
}

// BoxPointsFn is exact: each ISA's kernel (whichever path's table holds it) keeps the local
// indices of the points AABB::contains keeps, ascending, for any start and count (the 8- and
// 4-wide steps, the overlapping last step and the masked or scalar short runs); the paths from
// AVX2 on have one.
TEST(Simd, BoxPointsKeepExactlyThePointsInTheBox) {
  PathGuard guard;
  std::vector<Vec3> pts = make_points(1003, Dist::utm_mm, 7);
  std::mt19937_64 rng(21);
  const std::vector<AABB> boxes = box_kernel_queries(pts, rng);
  pts[3].y = std::nan("");  // a point with a NaN coordinate is in no box
  pts[20].z = std::nan("");
  std::size_t kept = 0, dropped = 0;
  for (SimdPath path : supported_paths()) {
    set_simd_path(path);
    ASSERT_EQ(simd::active_kernels().box_points == nullptr, path < SimdPath::avx2) << to_string(path);
  }
  std::vector<std::pair<SimdPath, simd::BoxPointsFn>> kernels;
#if RAYSCAN_SIMD_X86
  if (simd_path_supported(SimdPath::avx2)) kernels.emplace_back(SimdPath::avx2, simd::Avx2Kernels::box_points);
  if (simd_path_supported(SimdPath::avx512)) kernels.emplace_back(SimdPath::avx512, simd::Avx512Kernels::box_points);
#endif
  for (const auto& [path, box_points] : kernels) {
    for (std::size_t bi = 0; bi < boxes.size(); ++bi) {
      const AABB& b = boxes[bi];
      for (const unsigned off : {0u, 1u, 5u, 17u})
        for (const unsigned count : {0u, 1u, 2u, 3u, 4u, 5u, 7u, 8u, 9u, 12u, 15u, 16u, 23u, 64u, 986u}) {
          std::vector<std::uint32_t> want;
          for (unsigned j = 0; j < count; ++j)
            if (b.contains(pts[off + j])) want.push_back(j);
          // The run in a buffer of exactly its size (a read past it is a heap overflow under
          // ASan) and one guard entry past the output's room.
          const std::vector<Vec3> run(pts.begin() + off, pts.begin() + off + count);
          // With ids (an exact-size buffer as well): each kept index's id instead of the index.
          std::vector<std::uint32_t> run_ids(count), want_ids;
          for (unsigned j = 0; j < count; ++j) run_ids[j] = 2654435761u * (off + j + 1);
          for (const std::uint32_t j : want) want_ids.push_back(run_ids[j]);
          for (const bool with_ids : {false, true}) {
            std::vector<std::uint32_t> got(count + 1, 0xdeadbeefu);
            const unsigned n = box_points(reinterpret_cast<const double*>(run.data()), count, &b.lo.x, &b.hi.x,
                                          with_ids ? run_ids.data() : nullptr, got.data());
            ASSERT_EQ(got[count], 0xdeadbeefu) << to_string(path) << " wrote past its room, count " << count;
            ASSERT_LE(n, count) << to_string(path);
            got.resize(n);
            ASSERT_EQ(got, with_ids ? want_ids : want)
                << to_string(path) << " box " << bi << " off " << off << " count " << count << " ids " << with_ids;
          }
          kept += want.size();
          dropped += count - want.size();
        }
    }
  }
  if (simd_path_supported(SimdPath::avx2)) {  // neither side of the comparison is vacuous
    EXPECT_GT(kept, 10000u);
    EXPECT_GT(dropped, 10000u);
  }
}

// The CPU family behind the per-family kernel choices (simd::amd_cpu_family) is the kernel's
// decoding of CPUID (/proc/cpuinfo); the AVX-512 path's table holds the AVX2 box kernel on Zen 4
// and Zen 5 (AuthenticAMD families 25 and 26 with AVX-512) and its own elsewhere, and its own ray
// and point kernels everywhere.
TEST(Simd, Avx512PathTakesTheAvx2BoxKernelOnZen4AndZen5Only) {
  const auto cpu = cpu_identity_from_proc();
  if (!cpu) GTEST_SKIP() << "no x86 vendor_id / cpu family in /proc/cpuinfo";
  const bool amd = cpu->vendor == "AuthenticAMD";
  EXPECT_EQ(simd::amd_cpu_family(), amd ? static_cast<unsigned>(cpu->family) : 0u) << cpu->vendor;
#if RAYSCAN_SIMD_X86
  if (!simd_path_supported(SimdPath::avx512)) GTEST_SKIP() << "no AVX-512";
  PathGuard guard;
  set_simd_path(SimdPath::avx512);
  const simd::Kernels& k = simd::active_kernels();
  const bool zen4_or_5 = amd && (cpu->family == 25 || cpu->family == 26);
  EXPECT_EQ(k.box_points, zen4_or_5 ? simd::Avx2Kernels::box_points : simd::Avx512Kernels::box_points)
      << cpu->vendor << " family " << cpu->family;
  EXPECT_EQ(k.point_filter, simd::Avx512Kernels::point_filter);
  EXPECT_EQ(k.child_slab_keys, simd::Avx512Kernels::child_slab_keys);
#endif
}

// box_query's output (its order included) is the same on every path, on each octree layout.
TEST(Simd, BoxQueryIsIdenticalOnEveryPath) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(20000, Dist::clustered, 9);
  std::mt19937_64 rng(23);
  const std::vector<AABB> boxes = box_kernel_queries(pts, rng);
  std::size_t total = 0;
  for (const OctreeLayout layout : {OctreeLayout::layered, OctreeLayout::fixed, OctreeLayout::adaptive}) {
    OctreeConfig cfg;
    cfg.layout = layout;
    const Octree tree = Octree::build_bulk(pts, cfg);
    for (std::size_t bi = 0; bi < boxes.size(); ++bi) {
      std::vector<PointIndex> want;
      for (std::size_t j = 0; j < pts.size(); ++j)
        if (boxes[bi].contains(pts[j])) want.push_back(static_cast<PointIndex>(j));
      std::optional<std::vector<PointIndex>> first;
      for (SimdPath path : supported_paths()) {
        set_simd_path(path);
        std::vector<PointIndex> got;
        box_query(tree, boxes[bi], got);
        if (!first) {
          first = got;
          std::sort(got.begin(), got.end());
          ASSERT_EQ(got, want) << to_string(path) << " box " << bi;  // the brute-force answer
          total += want.size();
        } else {
          ASSERT_EQ(got, *first) << to_string(path) << " box " << bi;  // in the same order
        }
      }
    }
  }
  EXPECT_GT(total, 10000u);
}

TEST(Simd, RayQueriesAreBitIdenticalOnEveryPath) {
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(20000, Dist::clustered, 9);
  const AABB box = bounds_of(pts);
  const Octree tree = Octree::build_bulk(pts);
  std::mt19937_64 rng(3);
  std::vector<Ray> rays;
  for (int i = 0; i < 60; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
  std::vector<RayQuery> qs(4);
  qs[0].k = 1, qs[0].radius = 0.01, qs[0].t_min = 0, qs[0].order = RayOrder::sphere_hit;
  qs[1].k = 8;
  qs[2].radius = 0.02, qs[2].order = RayOrder::time;
  qs[3].k = 3, qs[3].radius = 0.05, qs[3].order = RayOrder::time;
  std::size_t nonempty = 0;
  for (const RayQuery& q : qs) {
    for (const Ray& ray : rays) {
      const auto want = oracle_ray_query(pts, ray, q);
      nonempty += !want.empty();
      for (SimdPath path : supported_paths()) {
        set_simd_path(path);
        const auto got = ray_query(tree, ray, q);
        ASSERT_EQ(got.size(), want.size()) << to_string(path);
        for (std::size_t i = 0; i < got.size(); ++i) {
          ASSERT_EQ(got[i].index, want[i].index) << to_string(path);
          ASSERT_EQ(got[i].t, want[i].t) << to_string(path);
          ASSERT_EQ(got[i].distance, want[i].distance) << to_string(path);
        }
      }
    }
  }
  EXPECT_GT(nonempty, 60u);
}

}  // namespace

namespace {

// The per-ISA instances of the traversal (detail/ray_dispatch.hpp: ray_traverse_avx2 / _avx512 and the packet
// ones, compiled with target attributes and their kernels inlined) against the instance that calls
// the same path's kernels through simd::Kernels, and against the brute-force oracle: bit-identical
// first hits (key, id, t, d^2), so no rounding of the compiled instance (FMA contraction, vector
// code) reaches an answer.
TEST(Simd, TraversalCompiledPerIsaEqualsTheKernelTableInstance) {
  static_assert(detail::kIsaInstances<Octree, OrderKey>, "octree first hits run the per-ISA instances");
  PathGuard guard;
  const std::vector<Vec3> pts = make_points(30000, Dist::clustered, 21);
  const AABB box = bounds_of(pts);
  const Octree tree = Octree::build_bulk(pts);
  std::mt19937_64 rng(5);
  std::vector<Ray> rays;
  for (int i = 0; i < 400; ++i) rays.push_back(random_ray(rng, box, i % 4 == 0));
  RayQuery q;
  q.k = 1, q.radius = 0.008, q.t_min = 0, q.order = RayOrder::sphere_hit;
  std::size_t compared = 0, hits = 0;
  for (SimdPath path : {SimdPath::avx2, SimdPath::avx512}) {
    if (!simd_path_supported(path)) continue;
    set_simd_path(path);
    std::vector<detail::Candidate> packet(rays.size());
    std::vector<bool> packet_found(rays.size());
    detail::for_each_ray_packet(tree, std::span<const Ray>(rays), q, nullptr,
                                [&](std::size_t b, unsigned n, const detail::Candidate* best, std::uint32_t found) {
                                  for (unsigned i = 0; i < n; ++i) {
                                    packet[b + i] = best[i];
                                    packet_found[b + i] = (found >> i) & 1u;
                                  }
                                });
    for (std::size_t r = 0; r < rays.size(); ++r) {
      detail::Candidate isa{}, table{};
      const bool fi = path == SimdPath::avx2
                          ? detail::ray_traverse_avx2<true>(tree, rays[r], q, isa, nullptr, OrderKey{})
                          : detail::ray_traverse_avx512<true>(tree, rays[r], q, isa, nullptr, OrderKey{});
      const bool ft = detail::ray_traverse_with<true, simd::Kernels>(tree, rays[r], q, table, nullptr, OrderKey{});
      const auto want = oracle_ray_query(pts, rays[r], q);
      ASSERT_EQ(fi, ft) << to_string(path) << " ray " << r;
      ASSERT_EQ(fi, !want.empty()) << to_string(path) << " ray " << r;
      ASSERT_EQ(packet_found[r], fi) << to_string(path) << " ray " << r;
      ++compared;
      if (!fi) continue;
      ++hits;
      for (const detail::Candidate* c : {&table, &packet[r]}) {
        ASSERT_EQ(isa.key, c->key) << to_string(path) << " ray " << r;
        ASSERT_EQ(isa.id, c->id) << to_string(path) << " ray " << r;
        ASSERT_EQ(isa.t, c->t) << to_string(path) << " ray " << r;
        ASSERT_EQ(isa.d2, c->d2) << to_string(path) << " ray " << r;
      }
      ASSERT_EQ(isa.id, want[0].index) << to_string(path) << " ray " << r;
      ASSERT_EQ(isa.t, want[0].t) << to_string(path) << " ray " << r;
    }
  }
  if (compared == 0) GTEST_SKIP() << "CPU has neither AVX2 nor AVX-512";
  EXPECT_GT(hits, 50u);  // 76 of the 800 comparisons hit (the seeds are fixed)
}

}  // namespace
