// Ray query (paper Algorithm 1) against the independent brute-force oracle, for every modality of
// section 3.1, every index and organisation, several sizes and distributions.
#include "test_util.hpp"

#include "rayscan/octree/batch.hpp"
#include "rayscan/octree/brute_force.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

using namespace rayscan;
using namespace rayscan::test;

namespace {

std::string describe(const RayQuery& q) {
  std::ostringstream s;
  s << "k=" << (q.k == kAllPoints ? -1.0 : static_cast<double>(q.k)) << " r=" << q.radius
    << " t=[" << q.t_min << "," << q.t_max << "] order=" << static_cast<int>(q.order)
    << " planes=" << q.planes.size();
  return s.str();
}

void expect_same(const std::vector<RayHit>& got, const std::vector<RayHit>& want,
                 const std::string& ctx) {
  ASSERT_EQ(got.size(), want.size()) << ctx;
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].index, want[i].index) << ctx << " rank " << i;
    ASSERT_EQ(got[i].t, want[i].t) << ctx << " rank " << i;
    ASSERT_EQ(got[i].distance, want[i].distance) << ctx << " rank " << i;
  }
}

// The query modalities of paper section 3.1 (and combinations), scaled to the cloud's extent s.
std::vector<RayQuery> modalities(double s, std::size_t n) {
  std::vector<RayQuery> qs;
  RayQuery q;
  q.k = 8;  // kNN to the ray
  qs.push_back(q);
  q = {};
  q.k = 5;  // kNN along the ray (closest by t)
  q.order = RayOrder::time;
  qs.push_back(q);
  q = {};
  q.radius = 0.05 * s;  // radius: the infinite cylinder
  qs.push_back(q);
  q = {};
  q.t_min = 0.2 * s;  // time range: the slab between two planes
  q.t_max = 0.6 * s;
  q.order = RayOrder::time;
  qs.push_back(q);
  q = {};
  q.k = 1;  // "closest": ray-marching emulation, k = 1 by time within r
  q.radius = 0.03 * s;
  q.order = RayOrder::time;
  qs.push_back(q);
  q = {};
  q.k = 1;  // first sphere hit
  q.radius = 0.02 * s;
  q.t_min = 0.0;
  q.order = RayOrder::sphere_hit;
  qs.push_back(q);
  q = {};
  q.k = 3;  // combination: k + r + time, ordered by ray distance
  q.radius = 0.1 * s;
  q.t_min = -0.5 * s;
  q.t_max = 1.5 * s;
  qs.push_back(q);
  q = {};
  q.k = 4;  // sphere_hit, several hits, bounded time
  q.radius = 0.05 * s;
  q.t_min = 0.1 * s;
  q.t_max = 3.0 * s;
  q.order = RayOrder::sphere_hit;
  qs.push_back(q);
  q = {};
  q.k = n + 7;  // k > N
  qs.push_back(q);
  q = {};
  q.radius = 0.0;  // r = 0: only points exactly on the line
  qs.push_back(q);
  q = {};
  q.k = 3;  // eq. 3 node bound instead of the exact distance: same answers
  q.radius = 0.2 * s;
  q.node_distance = NodeDistance::eq3;
  qs.push_back(q);
  return qs;
}

struct Case {
  std::size_t n;
  Dist dist;
};

class RayQueryProperty : public ::testing::TestWithParam<Case> {};

TEST_P(RayQueryProperty, MatchesBruteForceOracleOnEveryIndex) {
  const Case c = GetParam();
  const std::vector<Vec3> pts = make_points(c.n, c.dist, 3);
  AABB box;
  for (const Vec3& p : pts) box.expand(p);
  if (box.empty()) box = AABB{Vec3(0.0), Vec3(1.0)};
  const double s = std::max(box.max_extent(), 1e-3);
  std::mt19937_64 rng(42 + c.n);
  std::vector<Ray> rays;
  const int nrays = c.n >= 100000 ? 6 : 24;
  for (int i = 0; i < nrays; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
  // Rays parallel to each axis, through a data point (so r = 0 and ties are exercised).
  for (int a = 0; a < 3; ++a) {
    Vec3 d(0.0);
    d[a] = (a == 1) ? -1.0 : 1.0;
    const Vec3 through = pts.empty() ? box.center() : pts[pts.size() / 2];
    rays.emplace_back(through - 2.0 * s * d, d);
  }
  const auto qs = modalities(s, c.n);
  // The oracle's answers, once for all indexes (want[qi][r]: modality qi, ray r).
  std::vector<std::vector<std::vector<RayHit>>> want(qs.size());
  std::vector<std::size_t> nonempty(qs.size(), 0);  // guards against a vacuous comparison
  for (std::size_t qi = 0; qi < qs.size(); ++qi)
    for (const Ray& ray : rays) {
      want[qi].push_back(oracle_ray_query(pts, ray, qs[qi]));
      nonempty[qi] += !want[qi].back().empty();
    }
  for (const IndexOptions& opt : all_index_options()) {
    if (c.n >= 100000 && opt.insertion && opt.type != "octree-adaptive") continue;  // time budget
    const AnyIndex index = make_index(pts, opt);
    for (std::size_t qi = 0; qi < qs.size(); ++qi) {
      const RayQuery& q = qs[qi];
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const auto got = std::visit(
            [&](const auto& idx) {
              std::vector<RayHit> hits = ray_query(idx, rays[r], q);
              // RayHit::slot names the hit's storage slot: the index stores that point there.
              for (const RayHit& h : hits) {
                EXPECT_EQ(idx.ids()[h.slot], h.index);
                EXPECT_EQ(idx.positions()[h.slot], pts[h.index]);
              }
              return hits;
            },
            index);
        expect_same(got, want[qi][r],
                    std::string(name(c.dist)) + " n=" + std::to_string(c.n) + " " + label(opt) +
                        " ray " + std::to_string(r) + " " + describe(q));
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
  }
  if (c.n >= 1000) {
    for (std::size_t qi = 0; qi < qs.size(); ++qi)
      EXPECT_GT(nonempty[qi], 0u) << "modality " << describe(qs[qi]) << " never returned a point";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Sizes, RayQueryProperty,
    ::testing::Values(Case{0, Dist::uniform}, Case{1, Dist::uniform}, Case{2, Dist::uniform},
                      Case{1000, Dist::uniform}, Case{1000, Dist::clustered},
                      Case{500, Dist::identical}, Case{1000, Dist::grid}, Case{1000, Dist::utm_mm},
                      Case{100000, Dist::uniform}, Case{100000, Dist::clustered}),
    [](const ::testing::TestParamInfo<Case>& i) {
      return std::string(name(i.param.dist)) + "_" + std::to_string(i.param.n);
    });

TEST(RayQuery, StatsCountWorkAndPruningVisitsFewNodes) {
  const auto pts = make_points(100000, Dist::uniform, 12);
  const Octree tree = Octree::build_bulk(pts);
  RayQuery q;
  q.k = 1;
  q.radius = 0.005;
  q.order = RayOrder::sphere_hit;
  RayQueryStats st;
  const auto hits = ray_query(tree, Ray(Vec3(-1, 0.5, 0.5), Vec3(1, 0.01, 0.02)), q, &st);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_GT(st.nodes_visited, 0u);
  // The first hit lies near the entry face: pruning must skip almost all of the tree.
  EXPECT_LT(st.nodes_visited, tree.node_count() / 20);
}

TEST(RayQuery, AnyHitFindsACandidateExactlyWhenOneExists) {
  const auto pts = make_points(20000, Dist::clustered, 13);
  AABB box;
  for (const Vec3& p : pts) box.expand(p);
  for (const IndexOptions& opt : all_index_options()) {
    std::mt19937_64 rng(17);  // the same rays for every index
    const AnyIndex index = make_index(pts, opt);
    std::size_t found = 0;
    for (int i = 0; i < 200; ++i) {
      const Ray ray = random_ray(rng, box, i % 4 == 0);
      for (RayOrder order : {RayOrder::sphere_hit, RayOrder::time, RayOrder::ray}) {
        RayQuery all;
        all.radius = 0.01;
        all.t_min = 0.0;
        all.order = order;
        const auto want = oracle_ray_query(pts, ray, all);  // every candidate
        RayQuery any = all;
        any.any_hit = true;
        const auto got = std::visit([&](const auto& idx) { return ray_query(idx, ray, any); }, index);
        ASSERT_EQ(got.empty(), want.empty()) << label(opt) << " ray " << i;
        if (got.empty()) continue;
        ++found;
        ASSERT_EQ(got.size(), 1u);
        const bool member = std::any_of(want.begin(), want.end(), [&](const RayHit& h) {
          return h.index == got[0].index && h.t == got[0].t && h.distance == got[0].distance;
        });
        EXPECT_TRUE(member) << label(opt) << " ray " << i;
      }
    }
    EXPECT_GT(found, 20u) << label(opt);  // guards against a vacuous comparison
  }
}

TEST(RayQuery, FrustumPlanesCombineWithRayPredicates) {
  const auto pts = make_points(3000, Dist::uniform, 9);
  // A box-shaped frustum [0.2, 0.7]^3 as six planes, plus an oblique plane.
  const std::vector<Plane> planes = {
      {Vec3(0.2), Vec3(-1, 0, 0)}, {Vec3(0.7), Vec3(1, 0, 0)}, {Vec3(0.2), Vec3(0, -1, 0)},
      {Vec3(0.7), Vec3(0, 1, 0)},  {Vec3(0.2), Vec3(0, 0, -1)}, {Vec3(0.7), Vec3(0, 0, 1)},
      {Vec3(0.5), Vec3(1, 1, 1)}};
  const Ray ray(Vec3(-1, 0.45, 0.4), Vec3(1, 0.05, 0.1));
  for (const IndexOptions& opt : all_index_options()) {
    const AnyIndex index = make_index(pts, opt);
    RayQuery q;
    q.planes = planes;
    q.radius = 0.2;
    q.k = 20;
    const auto want = oracle_ray_query(pts, ray, q);
    ASSERT_FALSE(want.empty());
    const auto got = std::visit([&](const auto& idx) { return ray_query(idx, ray, q); }, index);
    expect_same(got, want, label(opt));
    // Standalone frustum query == oracle filter.
    std::vector<PointIndex> fwant;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      bool in = true;
      for (const Plane& pl : planes) in = in && dist_plane(pl.point, pl.normal, pts[i]) <= 0.0;
      if (in) fwant.push_back(static_cast<PointIndex>(i));
    }
    const auto fgot = std::visit([&](const auto& idx) { return frustum_query(idx, planes); }, index);
    EXPECT_EQ(fgot, fwant) << label(opt);
  }
}

TEST(RayQuery, TimeRangeEqualsTwoPlaneFrustum) {
  // Section 3.1: the time interval is the slab between two planes with normals -d and +d.
  const auto pts = make_points(2000, Dist::clustered, 5);
  const Ray ray(Vec3(-0.5, 0.3, 0.2), Vec3(1, 0.2, 0.3));
  const Octree tree = Octree::build_bulk(pts);
  RayQuery slab;
  slab.t_min = 0.4;
  slab.t_max = 0.9;
  slab.order = RayOrder::time;
  std::vector<PointIndex> a;
  for (const RayHit& h : ray_query(tree, ray, slab)) a.push_back(h.index);
  std::sort(a.begin(), a.end());
  const std::vector<Plane> planes = {{ray.at(0.4), -ray.direction()}, {ray.at(0.9), ray.direction()}};
  const auto b = frustum_query(tree, planes);
  // Points within rounding of a plane may fall either way; there are none at this seed.
  EXPECT_EQ(a, b);
  EXPECT_FALSE(a.empty());
}

TEST(RayQuery, InvalidParametersThrow) {
  const Octree tree = Octree::build_bulk(make_points(10, Dist::uniform));
  const Ray ray(Vec3(0.0), Vec3(1, 0, 0));
  RayQuery q;
  q.t_min = 2;
  q.t_max = 1;
  EXPECT_THROW((void)ray_query(tree, ray, q), std::invalid_argument);
  q = {};
  q.radius = -1;
  EXPECT_THROW((void)ray_query(tree, ray, q), std::invalid_argument);
  q = {};
  q.order = RayOrder::sphere_hit;  // needs a radius
  EXPECT_THROW((void)ray_query(tree, ray, q), std::invalid_argument);
  q = {};
  q.t_max = std::nan("");
  EXPECT_THROW((void)ray_query(tree, ray, q), std::invalid_argument);
  EXPECT_THROW(Ray(Vec3(0.0), Vec3(0.0)), std::invalid_argument);
  EXPECT_THROW(Ray(Vec3(0.0), Vec3(std::nan(""), 0, 0)), std::invalid_argument);
}

TEST(RayQuery, SphereHitIsAnalyticEntryPoint) {
  // One point at (5, 0.3, 0) with r = 0.5 seen along +x from the origin: the entry parameter is
  // 5 - sqrt(0.25 - 0.09) = 4.6 exactly (analytic ray/sphere intersection).
  const std::vector<Vec3> pts = {Vec3(5, 0.3, 0), Vec3(9, 0, 0)};
  const Octree tree = Octree::build_bulk(pts);
  RayQuery q;
  q.k = 1;
  q.radius = 0.5;
  q.order = RayOrder::sphere_hit;
  const auto hits = ray_query(tree, Ray(Vec3(0.0), Vec3(1, 0, 0)), q);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].index, 0u);
  EXPECT_NEAR(hits[0].t, 4.6, 1e-12);
  EXPECT_NEAR(hits[0].distance, 0.3, 1e-12);
}

TEST(RayQuery, BatchEqualsSingleRayCalls) {
  const auto pts = make_points(20000, Dist::clustered, 11);
  const Octree tree = Octree::build_bulk(pts);
  AABB box;
  for (const Vec3& p : pts) box.expand(p);
  std::mt19937_64 rng(7);
  std::vector<Ray> rays;
  for (int i = 0; i < 500; ++i) rays.push_back(random_ray(rng, box, i % 2 == 0));
  RayQuery q;
  q.k = 4;
  q.radius = 0.02;
  q.order = RayOrder::sphere_hit;
  const auto batch = ray_query_batch(tree, std::span<const Ray>(rays), q);
  ASSERT_EQ(batch.size(), rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i)
    expect_same(batch[i], ray_query(tree, rays[i], q), "ray " + std::to_string(i));
}

TEST(RayQuery, PacketCoherentAcceptsOneOriginInANarrowCone) {
  // Analytic directions: rotations of +x by a known angle about z.
  const auto dir = [](double deg) {
    const double a = deg * 3.14159265358979323846 / 180.0;
    return Vec3(std::cos(a), std::sin(a), 0.0);
  };
  const Vec3 eye(-2.0, 0.5, 0.25);
  std::vector<Ray> rays;
  for (int i = 0; i < 16; ++i) rays.emplace_back(eye, dir(0.1 * i));  // 0 .. 1.5 degrees
  EXPECT_TRUE(packet_coherent(rays));
  rays[9] = Ray(eye, dir(2.5));  // 2.5 degrees from the first ray
  EXPECT_FALSE(packet_coherent(rays));
  rays[9] = Ray(eye, dir(1.9));
  EXPECT_TRUE(packet_coherent(rays));
  rays[3] = Ray(eye + Vec3(1e-9, 0, 0), dir(0.3));  // another origin, however close
  EXPECT_FALSE(packet_coherent(rays));
  EXPECT_FALSE(packet_coherent(std::span<const Ray>(rays.data(), 1)));
}

namespace {
// A pinhole camera outside the box of `pts` looking at pts[target]: rows x cols rays in row order,
// `step` radians apart (one origin, a narrow cone: the rays packet_coherent accepts). `box` and
// `scale` (the box's largest extent, >= 1e-3) receive the cloud's box.
std::vector<Ray> camera_at(std::span<const Vec3> pts, std::size_t target, int cols, int rows, double step, AABB& box,
                           double& scale) {
  box = AABB{};
  for (const Vec3& p : pts) box.expand(p);
  scale = std::max(box.max_extent(), 1e-3);
  const Vec3 eye = box.center() + Vec3(1.3, 0.9, -1.1) * scale;
  const Vec3 fwd = glm::normalize(pts[target] - eye);
  const Vec3 right = glm::normalize(glm::cross(fwd, Vec3(0, 1, 0)));
  const Vec3 up = glm::cross(right, fwd);
  std::vector<Ray> rays;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      rays.emplace_back(eye, fwd + (step * (x - 0.5 * (cols - 1))) * right + (step * (y - 0.5 * (rows - 1))) * up);
  return rays;
}
}  // namespace

TEST(RayQuery, BatchFirstHitsEqualSingleRayCallsAndOracle) {
  // ray_query_batch with k = 1 traces the rays in interleaved pairs (ray_query_each,
  // ray_first_hit_each): every answer equals ray_query on that ray alone and the brute-force
  // oracle, for camera rays (one origin, a narrow cone), one wide ray among them, and random rays,
  // on every index and for orders sphere_hit, time and ray (and every forced SIMD path:
  // simd_*_properties).
  const PairsGuard pairs(true);
  const auto pts = make_points(3000, Dist::clustered, 29);
  AABB box;
  double s = 0;
  // 6 rows of 24 pixels, 0.0015 rad apart, at a point of a cluster so that most rays hit.
  std::vector<Ray> rays = camera_at(pts, 17, 24, 6, 0.0015, box, s);
  const Vec3 eye = rays[0].origin();
  const Vec3 fwd = glm::normalize(pts[17] - eye);
  const Vec3 right = glm::normalize(glm::cross(fwd, Vec3(0, 1, 0)));
  rays[40] = Ray(eye, fwd + 0.2 * right);  // paired with a camera ray
  std::mt19937_64 rng(31);
  for (int i = 0; i < 40; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
  std::size_t hits = 0;
  for (const IndexOptions& opt : all_index_options()) {
    const AnyIndex index = make_index(pts, opt);
    for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time, RayOrder::ray}) {
      RayQuery q;
      q.k = 1;
      q.radius = 0.03 * s;
      q.t_min = 0.0;
      q.order = order;
      const auto batch = std::visit([&](const auto& idx) { return ray_query_batch(idx, std::span<const Ray>(rays), q); }, index);
      ASSERT_EQ(batch.size(), rays.size());
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const auto one = std::visit([&](const auto& idx) { return ray_query(idx, rays[r], q); }, index);
        const std::string ctx = label(opt) + " ray " + std::to_string(r) + " " + describe(q);
        expect_same(batch[r], one, ctx);
        if (!batch[r].empty()) {
          EXPECT_EQ(batch[r][0].slot, one[0].slot) << ctx;
          EXPECT_EQ(batch[r][0].key, one[0].key) << ctx;
        }
        expect_same(batch[r], oracle_ray_query(pts, rays[r], q), ctx);
        hits += batch[r].size();
        if (::testing::Test::HasFailure()) return;
      }
    }
  }
  EXPECT_GT(hits, 200u);
}

TEST(RayQuery, RayQueryEachEqualsSingleCallsForEveryQueryKind) {
  // ray_query_each on coherent camera rays (ray_first_hit_each for k = 1) equals ray_query per
  // ray for k = 1 with a plane, any_hit (one candidate, whichever the order), k = 3 and no k, on
  // an octree and an empty index; and rejects a length mismatch and an invalid query.
  const auto pts = make_points(2000, Dist::clustered, 37);
  AABB box;
  double s = 0;
  const std::vector<Ray> rays = camera_at(pts, 5, 12, 4, 0.0015, box, s);
  const Octree tree = Octree::build_bulk(pts);
  const Octree empty = Octree::build_bulk(std::span<const Vec3>());
  const Plane plane{box.center(), Vec3(0.3, -1.0, 0.2)};
  std::size_t hits = 0;
  for (int kind = 0; kind < 4; ++kind) {
    RayQuery q;
    q.radius = 0.03 * s;
    q.t_min = 0.0;
    q.order = RayOrder::sphere_hit;
    if (kind == 0) q.k = 1, q.planes = std::span<const Plane>(&plane, 1);
    if (kind == 1) q.k = 1, q.any_hit = true;
    if (kind == 2) q.k = 3;
    for (const Octree* t : {&tree, &empty}) {
      std::vector<std::vector<RayHit>> out(rays.size());
      ray_query_each(*t, std::span<const Ray>(rays), q, std::span<std::vector<RayHit>>(out));
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const std::string ctx = "kind " + std::to_string(kind) + " ray " + std::to_string(r) + " " + describe(q);
        if (q.any_hit) {  // any candidate: the same existence as the oracle's
          EXPECT_EQ(out[r].size(), ray_query(*t, rays[r], q).size()) << ctx;
        } else {
          expect_same(out[r], ray_query(*t, rays[r], q), ctx);
        }
        hits += out[r].size();
      }
    }
  }
  EXPECT_GT(hits, 50u);
  std::vector<std::vector<RayHit>> short_out(rays.size() - 1);
  RayQuery q1;
  q1.k = 1;
  q1.radius = 0.03 * s;
  q1.order = RayOrder::sphere_hit;
  EXPECT_THROW(ray_query_each(tree, std::span<const Ray>(rays), q1, std::span<std::vector<RayHit>>(short_out)),
               std::invalid_argument);
  std::vector<std::vector<RayHit>> out(rays.size());
  q1.t_min = 2.0;
  q1.t_max = 1.0;  // invalid: t_min > t_max
  EXPECT_THROW(ray_query_each(tree, std::span<const Ray>(rays), q1, std::span<std::vector<RayHit>>(out)),
               std::invalid_argument);
}

TEST(RayQuery, FirstHitEqualsTheOracleFirstResult) {
  // ray_first_hit (no result vector) against the brute-force oracle's first result, whatever
  // q.k says (it answers k = 1), on every index and for orders sphere_hit, time and ray.
  const auto pts = make_points(5000, Dist::clustered, 13);
  AABB box;
  for (const Vec3& p : pts) box.expand(p);
  const double s = box.max_extent();
  std::mt19937_64 rng(9);
  std::vector<Ray> rays;
  for (int i = 0; i < 60; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
  std::size_t hits = 0, misses = 0;
  for (const IndexOptions& opt : all_index_options()) {
    const AnyIndex index = make_index(pts, opt);
    for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time, RayOrder::ray}) {
      RayQuery q;
      q.k = 7;  // ignored by ray_first_hit
      q.radius = 0.02 * s;
      q.t_min = 0.0;
      q.order = order;
      RayQuery q1 = q;
      q1.k = 1;
      for (std::size_t r = 0; r < rays.size(); ++r) {
        const auto want = oracle_ray_query(pts, rays[r], q1);
        const auto got = std::visit([&](const auto& idx) { return ray_first_hit(idx, rays[r], q); }, index);
        const std::string ctx = label(opt) + " ray " + std::to_string(r) + " " + describe(q);
        ASSERT_EQ(got.has_value(), !want.empty()) << ctx;
        if (!got) {
          ++misses;
          continue;
        }
        ++hits;
        expect_same({*got}, want, ctx);
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
  }
  EXPECT_GT(hits, 100u);
  EXPECT_GT(misses, 10u);
}

TEST(RayQuery, UtmMagnitudeKeepsMillimetres) {
  // Points 1 mm apart at x ~ 6e5, y ~ 5.3e6: a ray along x through the middle row must return
  // exactly that row's points for r = 0.4 mm, ordered by t with 1 mm steps.
  std::vector<Vec3> pts;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) pts.emplace_back(600000.0 + i * 0.001, 5300000.0 + j * 0.001, 100.0);
  const Octree tree = Octree::build_bulk(pts);
  RayQuery q;
  q.radius = 0.0004;
  q.order = RayOrder::time;
  const Ray ray(Vec3(599999.0, 5300000.004, 100.0), Vec3(1, 0, 0));
  const auto hits = ray_query(tree, ray, q);
  ASSERT_EQ(hits.size(), 10u);  // only row j = 4; rows 3 and 5 are 1 mm away
  for (std::size_t i = 0; i < hits.size(); ++i) {
    EXPECT_EQ(hits[i].index, static_cast<PointIndex>(i * 10 + 4));
    EXPECT_NEAR(hits[i].t, 1.0 + 0.001 * static_cast<double>(i), 1e-6);
    EXPECT_LT(hits[i].distance, 1e-6);
  }
}

TEST(RayQuery, PacketFirstHitEqualsSingleRayAndOracle) {
  // ray_first_hit_packet against ray_first_hit on each ray (every field, bit for bit) and the
  // brute-force oracle: coherent packets (a pinhole camera's 4x4 pixel tiles, some rays parallel
  // to an axis so their float reciprocal is infinite), incoherent ones (random rays), packet sizes
  // 1..20 (more than kMaxRayPacket splits), on every index and for orders sphere_hit, time and
  // ray, with and without a plane, on every forced SIMD path (simd_*_properties).
  for (const Dist dist : {Dist::clustered, Dist::grid}) {
    const auto pts = make_points(3000, dist, 17);
    AABB box;
    for (const Vec3& p : pts) box.expand(p);
    const double s = std::max(box.max_extent(), 1e-3);
    std::vector<Ray> rays;
    // Camera: 8 x 4 pixels looking at the box centre from outside; tile-ordered (4x4 tiles).
    const Vec3 eye = box.center() + Vec3(1.3, 0.9, -1.1) * s;
    const Vec3 fwd = glm::normalize(box.center() - eye);
    const Vec3 right = glm::normalize(glm::cross(fwd, Vec3(0, 1, 0)));
    const Vec3 up = glm::cross(right, fwd);
    for (int tx = 0; tx < 2; ++tx)
      for (int y = 0; y < 4; ++y)
        for (int x = 4 * tx; x < 4 * tx + 4; ++x)
          rays.emplace_back(eye, fwd + (0.03 * (x - 3.5)) * right + (0.03 * (y - 1.5)) * up);
    // Axis-parallel rays through the box (zero direction components), as one coherent packet.
    for (int i = 0; i < 4; ++i)
      rays.emplace_back(box.lo - Vec3(0.5 * s, 0, 0) + Vec3(0, (0.3 + 0.1 * i) * s, 0.5 * s), Vec3(1, 0, 0));
    std::mt19937_64 rng(23);
    for (int i = 0; i < 20; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
    const Plane plane{box.center(), Vec3(0.3, -1.0, 0.2)};
    std::size_t hits = 0;
    for (const IndexOptions& opt : all_index_options()) {
      const AnyIndex index = make_index(pts, opt);
      for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time, RayOrder::ray})
        for (const bool with_plane : {false, true}) {
          RayQuery q;
          q.radius = 0.03 * s;
          q.t_min = 0.0;
          q.order = order;
          if (with_plane) q.planes = std::span<const Plane>(&plane, 1);
          q.validate();
          RayQuery q1 = q;
          q1.k = 1;
          std::vector<std::optional<RayHit>> got(rays.size());
          // Packets of 4, 16, then the rest split as 1, 3, 7, 20-ish spans.
          const std::size_t cuts[] = {0, 4, 20, 32, 33, 36, 43, rays.size()};
          for (std::size_t c = 0; c + 1 < std::size(cuts); ++c) {
            const std::span<const Ray> span(rays.data() + cuts[c], cuts[c + 1] - cuts[c]);
            std::visit([&](const auto& idx) {
              ray_first_hit_packet(idx, span, q, std::span<std::optional<RayHit>>(got.data() + cuts[c], span.size()));
            }, index);
          }
          for (std::size_t r = 0; r < rays.size(); ++r) {
            const auto one = std::visit([&](const auto& idx) { return ray_first_hit(idx, rays[r], q); }, index);
            const auto want = oracle_ray_query(pts, rays[r], q1);
            const std::string ctx = std::string(name(dist)) + " " + label(opt) + " ray " + std::to_string(r) + " " +
                                    describe(q);
            expect_same_answer(got[r], one, ctx);
            if (::testing::Test::HasFailure()) return;
            ASSERT_EQ(got[r].has_value(), !want.empty()) << ctx;
            if (!got[r]) continue;
            ++hits;
            expect_same({*got[r]}, want, ctx);
            if (::testing::Test::HasFailure()) return;
          }
        }
    }
    EXPECT_GT(hits, 50u) << name(dist);  // (clustered: ~100 hits, grid: more)
  }
  // A length mismatch is an error, not a silent partial answer.
  const auto pts = make_points(100, Dist::uniform, 3);
  const Octree tree = Octree::build_bulk(pts);
  const std::vector<Ray> two{Ray(Vec3(-1, 0.5, 0.5), Vec3(1, 0, 0)), Ray(Vec3(-1, 0.4, 0.5), Vec3(1, 0, 0))};
  std::vector<std::optional<RayHit>> one(1);
  RayQuery q;
  q.radius = 0.1;
  q.order = RayOrder::sphere_hit;
  EXPECT_THROW(ray_first_hit_packet(tree, std::span<const Ray>(two), q, std::span<std::optional<RayHit>>(one)),
               std::invalid_argument);
}

TEST(RayQuery, FirstHitEachInterleavedPairsEqualSingleRaysAndOracle) {
  // ray_first_hit_each (two rays at a time, their traversals interleaved node by node) against
  // ray_first_hit on each ray (every field, bit for bit, and the same work counters: each ray
  // follows its own traversal) and the brute-force oracle: camera rays, axis-parallel rays (an
  // infinite float reciprocal), rays that miss the root box paired with rays that enter it, random
  // rays through and from inside the box, spans of odd and even lengths (a lone last ray), on
  // every index, for orders sphere_hit, time and ray, with and without a plane and any_hit, on
  // every forced SIMD path (simd_*_properties); and with the pairs off (interleaved_pairs(): the
  // rays one by one), which must give the same.
  for (const bool pairs_on : {true, false})
  for (const Dist dist : {Dist::clustered, Dist::grid}) {
    const PairsGuard pairs(pairs_on);
    const auto pts = make_points(3000, dist, 41);
    AABB box;
    double s = 0;
    std::vector<Ray> rays = camera_at(pts, 17, 9, 4, 0.03, box, s);  // 9 x 4 pixels, row order
    for (int i = 0; i < 3; ++i)
      rays.emplace_back(box.lo - Vec3(0.5 * s, 0, 0) + Vec3(0, (0.3 + 0.1 * i) * s, 0.5 * s), Vec3(1, 0, 0));
    // Two rays that miss the root box (from the eye, away from it), paired with rays that enter it
    // (38-39, 40-41).
    rays.emplace_back(rays[0].origin(), -rays[0].direction());
    rays.emplace_back(rays[0].origin(), -rays[35].direction());
    std::mt19937_64 rng(43);
    for (int i = 0; i < 22; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
    ASSERT_EQ(rays.size(), 63u);  // (odd: the last ray of the whole span alone)
    const Plane plane{box.center(), Vec3(0.3, -1.0, 0.2)};
    std::size_t hits = 0;
    for (const IndexOptions& opt : all_index_options()) {
      const AnyIndex index = make_index(pts, opt);
      for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time, RayOrder::ray})
        for (const int variant : {0, 1, 2}) {  // plain, with a plane, any_hit
          RayQuery q;
          q.radius = 0.03 * s;
          q.t_min = 0.0;
          q.order = order;
          if (variant == 1) q.planes = std::span<const Plane>(&plane, 1);
          q.any_hit = variant == 2;
          q.validate();
          RayQuery q1 = q;
          q1.k = 1;
          q1.any_hit = false;
          std::vector<std::optional<RayHit>> got(rays.size());
          RayQueryStats st_each, st_one;
          const std::size_t cuts[] = {0, 1, 3, 6, 10, rays.size()};  // spans of 1, 2, 3, 4 and 53 rays
          for (std::size_t c = 0; c + 1 < std::size(cuts); ++c) {
            const std::span<const Ray> span(rays.data() + cuts[c], cuts[c + 1] - cuts[c]);
            std::visit([&](const auto& idx) {
              ray_first_hit_each(idx, span, q, std::span<std::optional<RayHit>>(got.data() + cuts[c], span.size()),
                                 &st_each);
            }, index);
          }
          for (std::size_t r = 0; r < rays.size(); ++r) {
            const auto one = std::visit([&](const auto& idx) { return ray_first_hit(idx, rays[r], q, &st_one); }, index);
            const auto want = oracle_ray_query(pts, rays[r], q1);
            const std::string ctx = std::string(name(dist)) + " " + label(opt) + " ray " + std::to_string(r) + " " +
                                    describe(q) + (q.any_hit ? " any_hit" : "");
            expect_same_answer(got[r], one, ctx);
            if (::testing::Test::HasFailure()) return;
            ASSERT_EQ(got[r].has_value(), !want.empty()) << ctx;
            if (!got[r]) continue;
            ++hits;
            if (!q.any_hit) expect_same({*got[r]}, want, ctx);  // (any_hit: any qualifying point)
            if (::testing::Test::HasFailure()) return;
          }
          EXPECT_FALSE(got[39] || got[40]) << "the two rays away from the box miss it";
          EXPECT_EQ(st_each.nodes_visited, st_one.nodes_visited) << label(opt) << " " << describe(q);
          EXPECT_EQ(st_each.points_tested, st_one.points_tested) << label(opt) << " " << describe(q);
        }
    }
    EXPECT_GT(hits, 100u) << name(dist);
  }
  // A length mismatch is an error; an empty index answers nothing.
  const auto pts = make_points(100, Dist::uniform, 3);
  const Octree tree = Octree::build_bulk(pts);
  const Octree empty = Octree::build_bulk(std::span<const Vec3>());
  const std::vector<Ray> two{Ray(Vec3(-1, 0.5, 0.5), Vec3(1, 0, 0)), Ray(Vec3(-1, 0.4, 0.5), Vec3(1, 0, 0))};
  RayQuery q;
  q.radius = 0.3;  // (a cylinder of ~28% of the unit cube around each ray: ~28 of the 100 points)
  q.order = RayOrder::sphere_hit;
  std::vector<std::optional<RayHit>> one(1);
  EXPECT_THROW(ray_first_hit_each(tree, std::span<const Ray>(two), q, std::span<std::optional<RayHit>>(one)),
               std::invalid_argument);
  std::vector<std::optional<RayHit>> out(2, RayHit{});
  ray_first_hit_each(empty, std::span<const Ray>(two), q, std::span<std::optional<RayHit>>(out));
  EXPECT_FALSE(out[0].has_value());
  EXPECT_FALSE(out[1].has_value());
  ray_first_hit_each(tree, std::span<const Ray>(two), q, std::span<std::optional<RayHit>>(out));
  EXPECT_TRUE(out[0].has_value() && out[1].has_value());
}

TEST(RayQuery, PacketAnyHitEqualsOracleExistence) {
  // ray_any_hit_packet (shadow rays) against the brute-force oracle: out[i] is true exactly when
  // some point qualifies along ray i. Coherent packets (parallel rays from a grid of origins, as
  // shadow rays towards a sun), incoherent ones (random rays) and packets of 1..20 rays, with
  // and without any_hit, on every index and forced SIMD path (simd_*_properties).
  for (const Dist dist : {Dist::clustered, Dist::grid}) {
    const auto pts = make_points(3000, dist, 29);
    AABB box;
    for (const Vec3& p : pts) box.expand(p);
    const double s = std::max(box.max_extent(), 1e-3);
    std::vector<Ray> rays;
    const Vec3 sun = glm::normalize(Vec3(0.4, -0.3, 0.85));
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 6; ++x)
        rays.emplace_back(box.lo + Vec3((0.1 + 0.15 * x) * s, (0.1 + 0.15 * y) * s, 0.3 * s), sun);
    std::mt19937_64 rng(31);
    for (int i = 0; i < 20; ++i) rays.push_back(random_ray(rng, box, i % 3 == 0));
    std::size_t blocked_count = 0, total = 0;
    for (const IndexOptions& opt : all_index_options()) {
      const AnyIndex index = make_index(pts, opt);
      for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time})
        for (const bool any : {true, false}) {
          RayQuery q;
          q.radius = 0.02 * s;
          q.t_min = 0.0;
          q.order = order;
          q.any_hit = any;
          q.validate();
          RayQuery q1 = q;
          q1.k = 1;
          q1.any_hit = false;
          std::vector<char> got(rays.size(), 2);
          const std::size_t cuts[] = {0, 16, 17, 20, 36, 43, rays.size()};
          for (std::size_t c = 0; c + 1 < std::size(cuts); ++c) {
            const std::span<const Ray> span(rays.data() + cuts[c], cuts[c + 1] - cuts[c]);
            bool out[kMaxRayPacket + 8];
            std::visit([&](const auto& idx) { ray_any_hit_packet(idx, span, q, std::span<bool>(out, span.size())); },
                       index);
            for (std::size_t i = 0; i < span.size(); ++i) got[cuts[c] + i] = out[i] ? 1 : 0;
          }
          for (std::size_t r = 0; r < rays.size(); ++r) {
            const bool want = !oracle_ray_query(pts, rays[r], q1).empty();
            ASSERT_EQ(got[r], want ? 1 : 0) << name(dist) << " " << label(opt) << " ray " << r << " " << describe(q);
            blocked_count += want;
            ++total;
          }
        }
    }
    EXPECT_GT(blocked_count, total / 50) << name(dist);  // both answers occur (clustered: ~5%)
    EXPECT_LT(blocked_count, total - total / 10) << name(dist);
  }
  const auto pts = make_points(100, Dist::uniform, 3);
  const Octree tree = Octree::build_bulk(pts);
  const std::vector<Ray> two{Ray(Vec3(-1, 0.5, 0.5), Vec3(1, 0, 0)), Ray(Vec3(-1, 0.4, 0.5), Vec3(1, 0, 0))};
  bool one[1];
  RayQuery q;
  q.radius = 0.1;
  q.any_hit = true;
  EXPECT_THROW(ray_any_hit_packet(tree, std::span<const Ray>(two), q, std::span<bool>(one, 1)), std::invalid_argument);
}

}  // namespace

TEST(RayQuery, EntryPointSearchEqualsTheRootTraversalAndTheOracle) {
  // The first hits' entry-point search (EntryGrid; forced: EntryPointSearch::always) against the same queries with it off
  // (every field, bit for bit) and the brute-force oracle, single rays and interleaved pairs, on
  // the rays that stress its test of finality: hits just inside and just past a grid cell's face
  // (lattice points on the faces, axis-parallel rays along them and origins on them), radii from
  // a fraction of the deepest cell to twice it (S grown past several cells), t_min inside the
  // cloud, origins inside, and UTM magnitudes; orders sphere_hit and time, with any_hit (which
  // returns some qualifying point: only its existence is compared). The search must be at work:
  // fewer nodes visited with it than without, over each cloud's queries (but the lattice's, whose
  // points all lie on grid faces: there it goes back up on almost every ray).
  const PairsGuard pairs(true);  // (ray_first_hit_each below: its pairs)
  const EntrySearchGuard entry_guard;
  for (const Dist dist : {Dist::uniform, Dist::grid, Dist::clustered, Dist::utm_mm}) {
    const auto pts = make_points(20000, dist, 53);
    OctreeConfig cfg;
    cfg.capacity = 8;
    const Octree tree = Octree::build_bulk(pts, cfg);
    const Octree::EntryGrid g = tree.entry_grid();
    ASSERT_NE(g.cells, nullptr) << name(dist);
    const double cell = g.side / static_cast<double>(1u << g.depth);
    AABB box;
    for (const Vec3& p : pts) box.expand(p);
    std::mt19937_64 rng(61);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Ray> rays;
    for (int i = 0; i < 150; ++i) rays.push_back(random_ray(rng, box, i % 4 == 0));
    // Axis-parallel rays along grid faces (and a cell's width off them), from outside and inside.
    for (int i = 0; i < 60; ++i) {
      const int a = i % 3, b = (a + 1) % 3, c = (a + 2) % 3;
      Vec3 o = box.lo + draw3([&] { return u(rng); }) * (box.hi - box.lo);
      o[b] = g.quant.lo[b] + cell * std::floor((o[b] - g.quant.lo[b]) / cell) + (i % 2 ? 0.0 : 0.5 * cell);
      o[c] = g.quant.lo[c] + cell * std::floor((o[c] - g.quant.lo[c]) / cell);
      Vec3 dir(0.0);
      dir[a] = i % 4 < 2 ? 1.0 : -1.0;
      if (i % 5 != 0) o[a] = dir[a] > 0 ? box.lo[a] - 0.3 * box.max_extent() : box.hi[a] + 0.3 * box.max_extent();
      rays.emplace_back(o, dir);
    }
    std::size_t hits = 0;
    std::uint64_t nodes_on = 0, nodes_off = 0;
    for (const double rel : {0.05, 0.4, 2.0})
      for (const RayOrder order : {RayOrder::sphere_hit, RayOrder::time})
        for (const bool mid_t : {false, true})
          for (const bool any : {false, true}) {
            RayQuery q;
            q.radius = rel * cell;
            q.order = order;
            q.k = 1;
            q.any_hit = any;
            q.t_min = mid_t ? 0.5 : 0.0;  // (rays' directions are not unit: half way along some)
            q.validate();
            RayQueryStats on_st, off_st;
            std::vector<std::optional<RayHit>> on(rays.size()), off(rays.size()), on_each(rays.size());
            set_entry_point_search(false);
            for (std::size_t r = 0; r < rays.size(); ++r) off[r] = ray_first_hit(tree, rays[r], q, &off_st);
            set_entry_point_search(EntryPointSearch::always);  // (also on the clouds whose grid is not for first hits)
            for (std::size_t r = 0; r < rays.size(); ++r) on[r] = ray_first_hit(tree, rays[r], q, &on_st);
            ray_first_hit_each(tree, std::span<const Ray>(rays), q, std::span<std::optional<RayHit>>(on_each));
            for (std::size_t r = 0; r < rays.size(); ++r) {
              const std::string ctx = std::string(name(dist)) + " ray " + std::to_string(r) + " r/cell " +
                                      std::to_string(rel) + " " + describe(q);
              expect_same_answer(on_each[r], on[r], ctx);
              const auto want = oracle_ray_query(pts, rays[r], q);
              ASSERT_EQ(on[r].has_value(), !want.empty()) << ctx;
              if (any) {
                ASSERT_EQ(off[r].has_value(), on[r].has_value()) << ctx;
                continue;
              }
              expect_same_answer(on[r], off[r], ctx);
              if (on[r]) {
                ++hits;
                expect_same({*on[r]}, want, ctx);
              }
              if (::testing::Test::HasFailure()) return;
            }
            nodes_on += on_st.nodes_visited;
            nodes_off += off_st.nodes_visited;
          }
    EXPECT_GT(hits, 300u) << name(dist);
    if (dist != Dist::grid) {
      EXPECT_LT(nodes_on, nodes_off) << name(dist);
    }
  }
}

TEST(RayQuery, EntryPointSearchWhereTheRootEdgeRoundsUp) {
  // A cloud a millimetre wide at x = 5e6: the root cell's edge (hi - lo, two rounded corners) is
  // 4.7e-10 longer than the edge the points' Morton codes were computed with, so a point just
  // above a cell face by its code can lie below it by the cell edge: the grid must take its
  // cells from the points' own quantizer (Octree::quantizer). The point at height v (id 3) is
  // the first hit, in the upper z half by its Morton code; a ray between it and a point below
  // (id 2) must return it with the search on as with it off.
  const PairsGuard pairs(true);  // (ray_first_hit_each below: its pairs)
  const EntrySearchGuard entry_guard;
  const double x = 5e6;
  double e = 0, gap = 0;
  for (int i = 0; i < 200000; ++i) {
    const double ei = 0.001 + i * 1e-12;
    AABB b;
    b.expand(Vec3(x, 0, 0));
    b.expand(Vec3(x, ei, 0));
    const AABB c = OctreeRules::root_cell(b);
    if (const double g = (c.hi.x - c.lo.x) - OctreeRules::root_side(b); g > gap) gap = g, e = ei;
  }
  ASSERT_GT(gap, 0.0);
  AABB b;
  b.expand(Vec3(x, 0, 0));
  b.expand(Vec3(x, e, 0));
  const double side = OctreeRules::root_side(b), cube = OctreeRules::root_cell(b).max_extent();
  double v = side / 2;  // the least height in the upper half by the Morton code
  while (v * (static_cast<double>(1u << kMortonBits) / side) < static_cast<double>(1u << (kMortonBits - 1)))
    v = std::nextafter(v, 1.0);
  ASSERT_LT(v * (2.0 / cube), 1.0);  // (below the face by the root cell's own edge)
  const double r = 0.1 * e, y0 = 0.2 * e;
  const std::vector<Vec3> pts{{x, 0, 0}, {x, e, 0}, {x + 0.3 * e, y0, v - 0.9 * r}, {x + 0.1 * e, y0, v},
                              {x + 0.9 * e, 0.9 * e, 0.1 * e}};
  const Ray ray(Vec3(x - e, y0, v - 0.5 * r), Vec3(1, 0, 0));
  OctreeConfig fixed2, fixed6, adaptive1;
  fixed2.layout = fixed6.layout = OctreeLayout::fixed;
  fixed2.depth = 2;
  fixed6.depth = 6;
  adaptive1.capacity = 1;
  for (const OctreeConfig& cfg : {fixed2, fixed6, adaptive1}) {
    const Octree tree = Octree::build_bulk(pts, cfg);
    ASSERT_NE(tree.entry_grid().cells, nullptr);
    for (const RayOrder order : {RayOrder::time, RayOrder::sphere_hit}) {
      RayQuery q;
      q.radius = r;
      q.order = order;
      q.k = 1;
      const std::string ctx = "depth " + std::to_string(tree.depth()) + " " + describe(q);
      const auto want = oracle_ray_query(pts, ray, q);
      ASSERT_EQ(want.size(), 1u);
      ASSERT_EQ(want[0].index, 3u);
      set_entry_point_search(false);
      const auto off = ray_first_hit(tree, ray, q);
      set_entry_point_search(EntryPointSearch::always);
      const auto on = ray_first_hit(tree, ray, q);
      std::vector<std::optional<RayHit>> each(2);
      const std::vector<Ray> two{ray, ray};
      ray_first_hit_each(tree, std::span<const Ray>(two), q, std::span<std::optional<RayHit>>(each));
      expect_same_answer(on, off, ctx);
      expect_same_answer(each[1], off, ctx);
      ASSERT_TRUE(on.has_value()) << ctx;
      EXPECT_EQ(on->index, 3u) << ctx;
      const auto node = tree.locate(pts[3]);  // (the same quantizer: the deepest node holding it)
      ASSERT_TRUE(node.has_value());
      const SlotRange sub = tree.subtree_points(*node);
      EXPECT_TRUE(on->slot >= sub.begin && on->slot < sub.end) << ctx;
    }
  }
}
