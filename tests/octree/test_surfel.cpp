// Surfels: the ray-disc test against hand-computed cases and the ray-query
// search against a brute-force loop over every disc.
#include "rayscan/octree/surfel.hpp"

#include "rayscan/octree/any_index.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace rayscan;

TEST(RayDisc, HandComputedCases) {
  const Vec3 c(1.0, 2.0, 3.0), n(0.0, 0.0, 1.0);
  // Straight down onto the centre from 10 above: t = 10.
  EXPECT_EQ(ray_disc_t(Vec3(1, 2, 13), Vec3(0, 0, -1), c, n, 0.5, 0.0, kInf), 10.0);
  // 45 degrees through the plane at (1.3, 2, 3): inside r = 0.5 (distance 0.3), t = 10 sqrt 2.
  const Vec3 d = glm::normalize(Vec3(1, 0, -1));
  EXPECT_NEAR(ray_disc_t(Vec3(-8.7, 2, 13), d, c, n, 0.5, 0.0, kInf), 10.0 * std::sqrt(2.0), 1e-12);
  // Same ray, r = 0.29: misses.
  EXPECT_EQ(ray_disc_t(Vec3(-8.7, 2, 13), d, c, n, 0.29, 0.0, kInf), kInf);
  // Behind the origin or beyond t_max: misses; parallel to the plane: misses.
  EXPECT_EQ(ray_disc_t(Vec3(1, 2, 13), Vec3(0, 0, 1), c, n, 0.5, 0.0, kInf), kInf);
  EXPECT_EQ(ray_disc_t(Vec3(1, 2, 13), Vec3(0, 0, -1), c, n, 0.5, 0.0, 9.0), kInf);
  EXPECT_EQ(ray_disc_t(Vec3(0, 2, 3), Vec3(1, 0, 0), c, n, 0.5, 0.0, kInf), kInf);
  // From below (back face): hit too.
  EXPECT_EQ(ray_disc_t(Vec3(1, 2, 1), Vec3(0, 0, 1), c, n, 0.5, 0.0, kInf), 2.0);
}

namespace {

struct Discs {
  std::vector<Vec3> c;
  std::vector<glm::vec3> n;
  std::vector<float> r;
  double rmax = 0.0;
  SurfelView view() const { return {c, n, r, rmax}; }
};

Discs random_discs(std::size_t count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Discs d;
  for (std::size_t i = 0; i < count; ++i) {
    d.c.push_back(Vec3(u(rng), u(rng), u(rng)));
    d.n.push_back(glm::normalize(glm::vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5)));
    d.r.push_back(float(0.01 + 0.05 * u(rng)));
    d.rmax = std::max(d.rmax, double(d.r.back()));
  }
  return d;
}

}  // namespace

TEST(FirstSurfelHit, MatchesBruteForceOverEveryDisc) {
  const Discs d = random_discs(3000, 5);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const char* type : {"octree-adaptive", "kdtree", "brute"}) {
    const AnyIndex idx = make_index(d.c, IndexOptions{type});
    const std::vector<float> node_r = std::visit([&](const auto& ix) { return surfel_node_radii(ix, d.r); }, idx);
    SurfelView view_node = d.view();
    view_node.node_radii = node_r;
    const float root_r = std::visit([&](const auto& ix) { return node_r.at(ix.root()); }, idx);
    EXPECT_EQ(root_r, float(d.rmax)) << type;  // the root's subtree holds every disc
    int hits = 0;
    for (int k = 0; k < 400; ++k) {
      const Vec3 o(u(rng) * 1.4 - 0.2, u(rng) * 1.4 - 0.2, u(rng) * 1.4 - 0.2);
      const Ray ray(o, Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5));
      // Oracle: every disc.
      double bt = kInf;
      PointIndex bi = 0;
      for (std::size_t i = 0; i < d.c.size(); ++i) {
        const double t = ray_disc_t(ray.origin(), ray.direction(), d.c[i], Vec3(d.n[i]), d.r[i], 0.0, kInf);
        if (t < bt) { bt = t; bi = PointIndex(i); }
      }
      std::vector<RayHit> scratch;
      RayQueryStats st;
      // Both candidate radii: the global maximum, and each node's own largest disc radius.
      for (const SurfelView& v : {d.view(), view_node}) {
        const SurfelHit h = std::visit(
            [&](const auto& ix) { return first_surfel_hit(ix, v, ray, 0.0, kInf, nullptr, false, scratch, st); },
            idx);
        ASSERT_EQ(h.t, bt) << type << " ray " << k << " per-node radii " << !v.node_radii.empty();
        if (bt < kInf) {
          EXPECT_EQ(h.index, bi);
          const SurfelHit any = std::visit(
              [&](const auto& ix) { return first_surfel_hit(ix, v, ray, 0.0, kInf, nullptr, true, scratch, st); },
              idx);
          EXPECT_LT(any.t, kInf);
          EXPECT_EQ(any.t, ray_disc_t(ray.origin(), ray.direction(), d.c[any.index], Vec3(d.n[any.index]),
                                      d.r[any.index], 0.0, kInf));
        }
      }
      hits += bt < kInf;
    }
    EXPECT_GT(hits, 100) << type;  // the sample exercises hits, not only misses
  }
}

TEST(FirstSurfelHit, LeavingAFlatSurfaceIgnoresItsOwnDiscsOnly) {
  // A noisy-free plane z = 0 of overlapping discs (spacing 1, radius 1.2) and a blocker disc 5
  // above. A shadow ray leaving the plane at 10 degrees elevation would clip neighbouring tilted
  // discs; with the leaving surface it finds only the blocker.
  Discs d;
  for (int i = -10; i <= 10; ++i)
    for (int j = -10; j <= 10; ++j) {
      d.c.push_back(Vec3(i, j, 0.0));
      // Tilt alternate discs by 3 degrees (PCA noise).
      const double a = ((i + j) % 2 ? 3.0 : -3.0) * std::numbers::pi / 180.0;
      d.n.push_back(glm::vec3(float(std::sin(a)), 0.0f, float(std::cos(a))));
      d.r.push_back(1.2f);
    }
  d.rmax = 1.2;
  const AnyIndex idx = make_index(d.c, IndexOptions{});
  const auto& oct = std::get<Octree>(idx);
  const PointIndex left = 10 * 21 + 10;  // (0, 0, 0)
  LeavingSurface from{left, Vec3(0.3, 0.2, 0.0), Vec3(0, 0, 1), 1.2};
  const double el = 10.0 * std::numbers::pi / 180.0;
  const Ray shadow(from.position, Vec3(std::cos(el), 0.0, std::sin(el)));
  std::vector<RayHit> scratch;
  RayQueryStats st;
  EXPECT_LT(first_surfel_hit(oct, d.view(), shadow, 0.0, kInf, nullptr, true, scratch, st).t, kInf)
      << "without the leaving surface the tilted neighbours shadow the plane (acne)";
  EXPECT_EQ(first_surfel_hit(oct, d.view(), shadow, 0.0, kInf, &from, true, scratch, st).t, kInf);
  // A wall 3 units away along the ray is still hit.
  Discs w = d;
  for (int k = 0; k < 6; ++k) {
    w.c.push_back(Vec3(3.0, 0.0, 0.25 * k));
    w.n.push_back(glm::vec3(-1.0f, 0.0f, 0.0f));
    w.r.push_back(0.3f);
  }
  const AnyIndex widx = make_index(w.c, IndexOptions{});
  const SurfelHit h = first_surfel_hit(std::get<Octree>(widx), w.view(), shadow, 0.0, kInf, &from, false, scratch, st);
  ASSERT_LT(h.t, kInf);
  EXPECT_GE(h.index, PointIndex(d.c.size()));
  EXPECT_NEAR(h.t, 2.7 / std::cos(el), 1e-9);
}

TEST(CoveringDiscs, HoldEveryCoveringDiscAndGiveTheBlendedNormalOfTheFullRadiusQuery) {
  // Oracle: a brute-force loop over every disc. Every disc that covers x (in-plane distance < r,
  // plane offset <= r / 4) must be found, and the shading normal must equal, bit for bit,
  // blended_normal over every disc centre within blend_reach of x sorted by (distance, index).
  const Discs d = random_discs(3000, 7);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const char* type : {"octree-adaptive", "kdtree", "brute"}) {
    const AnyIndex idx = make_index(d.c, IndexOptions{type});
    const std::vector<float> node_r = std::visit([&](const auto& ix) { return surfel_node_radii(ix, d.r); }, idx);
    SurfelView view_node = d.view();
    view_node.node_radii = node_r;
    // With the per-slot radii too (the renderer's table): they replace the lookups by original
    // index and must change nothing.
    const std::vector<float> slot_r = std::visit([&](const auto& ix) { return surfel_slot_radii(ix, d.r); }, idx);
    SurfelView view_slot = view_node;
    view_slot.slot_radii = slot_r;
    std::size_t covered = 0;
    for (int k = 0; k < 600; ++k) {
      // Points on discs (where shading happens: a hit point in the disc, slightly off its plane)
      // and a few anywhere.
      const PointIndex hit = PointIndex(rng() % d.c.size());
      const Vec3 n(d.n[hit]);
      const Vec3 a = glm::normalize(glm::cross(n, std::abs(n.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0)));
      const Vec3 b = glm::cross(n, a);
      const double rr = d.r[hit] * std::sqrt(u(rng)), ph = 2.0 * std::numbers::pi * u(rng);
      const Vec3 x = k % 10 == 0 ? Vec3(u(rng), u(rng), u(rng))
                                 : d.c[hit] + rr * (std::cos(ph) * a + std::sin(ph) * b) +
                                       (k % 3 == 0 ? (k % 2 ? 0.2499 : -0.2499) : 0.01) * d.r[hit] * n;
      std::vector<Neighbor> ball;
      for (std::size_t i = 0; i < d.c.size(); ++i) {
        const double dist = glm::length(d.c[i] - x);
        if (dist <= blend_reach(d.view())) ball.push_back({PointIndex(i), dist});
      }
      std::sort(ball.begin(), ball.end(), [](const Neighbor& p, const Neighbor& q) {
        return p.distance < q.distance || (p.distance == q.distance && p.index < q.index);
      });
      const Vec3 want = blended_normal(d.view(), ball, hit, x);
      for (const SurfelView& v : {d.view(), view_node, view_slot}) {
        std::vector<Neighbor> got;
        std::visit([&](const auto& ix) { covering_discs(ix, v, x, got); }, idx);
        for (std::size_t i = 0; i < d.c.size(); ++i) {
          const Vec3 w = x - d.c[i];
          const double off = glm::dot(w, Vec3(d.n[i]));
          const double r = d.r[i];
          if (std::abs(off) > 0.25 * r || glm::dot(w, w) - off * off >= r * r) continue;
          covered += 1;
          EXPECT_TRUE(std::any_of(got.begin(), got.end(), [&](const Neighbor& g) { return g.index == i; }))
              << type << " point " << k << " disc " << i;
        }
        const Vec3 n_got = std::visit([&](const auto& ix) { return surfel_shading_normal(ix, v, hit, x, got); }, idx);
        EXPECT_EQ(n_got, want) << type << " point " << k << " per-node radii " << !v.node_radii.empty()
                               << " slot radii " << !v.slot_radii.empty();
      }
    }
    EXPECT_GT(covered, 1000u) << type;  // the sample exercises overlapping discs
  }
}

TEST(CoveringDiscs, FromTheCandidatesOfANearbyCentreEqualTheDescent) {
  // Oracle: covering_discs(x) itself (checked against brute force above). For every x within
  // delta of x0, covering_discs_among(cover_candidates(x0, delta), x) must give the same discs,
  // distances and order, bit for bit, including x at delta (rounded inwards as the renderer does),
  // and blended_normal_among the same normal as blended_normal over them.
  const Discs d = random_discs(3000, 21);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const char* type : {"octree-adaptive", "kdtree"}) {
    const AnyIndex idx = make_index(d.c, IndexOptions{type});
    const std::vector<float> node_r = std::visit([&](const auto& ix) { return surfel_node_radii(ix, d.r); }, idx);
    const std::vector<float> slot_r = std::visit([&](const auto& ix) { return surfel_slot_radii(ix, d.r); }, idx);
    SurfelView v = d.view();
    v.node_radii = node_r;
    v.slot_radii = slot_r;
    std::size_t nonempty = 0;
    for (int k = 0; k < 200; ++k) {
      const PointIndex hit = PointIndex(rng() % d.c.size());
      const Vec3 x0 = d.c[hit] + 0.3 * d.r[hit] * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      const double delta = (k % 4 + 1) * 0.5 * v.max_radius;
      CoverCandidates cands;
      std::visit([&](const auto& ix) { cover_candidates(ix, v, x0, delta, cands); }, idx);
      for (int j = 0; j < 10; ++j) {
        Vec3 dir(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        dir /= glm::length(dir);
        const Vec3 x = x0 + (j == 0 ? 0.999 : u(rng)) * delta * dir;
        std::vector<Neighbor> want, got;
        std::visit([&](const auto& ix) { covering_discs(ix, v, x, want); }, idx);
        std::vector<CoverHit> scratch;
        covering_discs_among(cands, x, got, scratch);
        ASSERT_EQ(got.size(), want.size()) << type << " centre " << k << " point " << j;
        for (std::size_t i = 0; i < got.size(); ++i) {
          EXPECT_EQ(got[i].index, want[i].index) << type << " centre " << k << " point " << j;
          EXPECT_EQ(got[i].distance, want[i].distance) << type << " centre " << k << " point " << j;
        }
        // The renderer's shading normal from the same set: blended_normal over the descent's
        // covering discs, bit for bit (the hit disc: the nearest covering one, else `hit`).
        const PointIndex h = want.empty() ? hit : want.front().index;
        const Vec3 nb = blended_normal_among(cands, h, v.normals[h], x, scratch);
        const Vec3 nw = blended_normal(v, want, h, x);
        for (int a = 0; a < 3; ++a) EXPECT_EQ(nb[a], nw[a]) << type << " centre " << k << " point " << j;
        nonempty += !want.empty();
      }
    }
    EXPECT_GT(nonempty, 500u) << type;  // most sample points are covered
  }
}

TEST(CoveringDiscs, FloatPrefilterNeverDropsADiscTheExactTestsKeep) {
  // Oracle: the exact tests of cover_hits_among applied to every candidate (a brute-force loop),
  // sorted by (d2, id). The candidates are put where the float prefilter is tested hardest: the
  // index position p just inside the exact reach of x (|p - x|^2 <= cover_reach2(r, 0) by at
  // most a few ulps of the coordinates), x up to 0.999 delta from x0, with the disc centre c
  // (which the cover test reads) at half a radius from x in the disc's plane, so the cover test
  // keeps it; far coordinates and
  // radii over six decades; and decoys just outside the reach, which must be dropped. Seven
  // candidates per set: one 4-wide step and a scalar tail.
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto unit = [&] {
    Vec3 a(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    return a / glm::length(a);
  };
  std::size_t kept = 0;
  std::vector<CoverHit> got;
  for (int t = 0; t < 40000; ++t) {
    const float r = static_cast<float>(std::pow(10.0, -3.0 + 3.0 * u(rng)));
    CoverCandidates set;
    set.delta = r * std::pow(10.0, -2.0 + 4.0 * u(rng));
    set.x0 = Vec3(2000 * u(rng) - 1000, 2000 * u(rng) - 1000, 2000 * u(rng) - 1000);
    const Vec3 x = set.x0 + (t % 3 == 0 ? 0.999 : u(rng)) * set.delta * unit();
    const double reach2 = surfel_detail::cover_reach2(r, 0.0);
    for (PointIndex i = 0; i < 7; ++i) {
      const Vec3 w = unit();
      const bool decoy = i == 6;
      Vec3 p = x + std::sqrt(reach2) * (decoy ? 1.0 + 1e-6 : 1.0) * w;
      // Pulled in by doubling steps until the rounded position is inside (far from the origin a
      // coordinate's ulp is up to 1e-10 of a small reach).
      for (int it = 0; !decoy && glm::dot(p - x, p - x) > reach2 && it < 60; ++it)
        p = x + std::sqrt(reach2) * (1.0 - std::ldexp(1e-16, it)) * w;
      const glm::vec3 n(unit());
      Vec3 inplane = glm::cross(Vec3(n), unit());
      inplane /= glm::length(inplane);
      set.cands.push_back({i, p, x + 0.5 * double(r) * inplane, n, r});
    }
    set.finish();
    std::vector<CoverHit> want;
    for (const CoverCandidate& c : set.cands) {
      const double d2 = glm::dot(c.p - x, c.p - x);
      if (d2 > reach2) continue;
      const double pd2 = cover_in_plane_d2(c.c, Vec3(c.n), c.r, x);
      if (pd2 < kInf) want.push_back({d2, c.id, pd2, &c});
    }
    std::sort(want.begin(), want.end(),
              [](const CoverHit& a, const CoverHit& b) { return a.d2 < b.d2 || (a.d2 == b.d2 && a.id < b.id); });
    cover_hits_among(set, x, got);
    ASSERT_EQ(got.size(), want.size()) << "set " << t;
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].id, want[i].id) << "set " << t;
      EXPECT_EQ(got[i].d2, want[i].d2) << "set " << t;
      EXPECT_EQ(got[i].plane_d2, want[i].plane_d2) << "set " << t;
    }
    kept += want.size();
  }
  EXPECT_GT(kept, 40000u * 5);  // nearly every boundary candidate is kept (the decoys are not)
}

TEST(FirstSurfelHit, PerNodeDiscBoxesMatchBruteForce) {
  // The node test on the bounding boxes of each subtree's discs (surfel_node_boxes): the same
  // first hit as a brute-force loop over every disc, and every hit point lies in its disc's box.
  Discs d = random_discs(3000, 13);
  // Flat, thin-boxed discs too (normal along an axis): the case the boxes are for.
  for (std::size_t i = 0; i < d.c.size(); i += 3) d.n[i] = glm::vec3(0.0f, 0.0f, i % 2 ? 1.0f : -1.0f);
  // Small discs in one half of the cube, so that node radius bounds differ from node to node
  // (a bound left over from another node would drop discs of the other half).
  for (std::size_t i = 0; i < d.c.size(); ++i)
    if (d.c[i].x < 0.5) d.r[i] = 0.2f * d.r[i];
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const char* type : {"octree-adaptive", "kdtree", "brute"}) {
    const AnyIndex idx = make_index(d.c, IndexOptions{type});
    const std::vector<float> node_r = std::visit([&](const auto& ix) { return surfel_node_radii(ix, d.r); }, idx);
    SurfelView v = d.view();
    v.node_radii = node_r;
    const std::vector<AABB> boxes = std::visit([&](const auto& ix) { return surfel_node_boxes(ix, v); }, idx);
    v.node_boxes = boxes;
    // On the octree also the float copy of the boxes (the SIMD child test on them).
    std::vector<float> boxes_f;
    if (const auto* oct = std::get_if<Octree>(&idx)) boxes_f = surfel_node_boxes_f(*oct, boxes);
    SurfelView vf = v;
    vf.node_boxes_f = boxes_f;
    // And the render's full view: the disc radii by storage slot too (the SIMD filter's own radius
    // and t floor per point, DiscKey::reject skipped for its survivors).
    std::vector<float> slot_r;
    if (const auto* oct = std::get_if<Octree>(&idx)) slot_r = surfel_slot_radii(*oct, d.r);
    SurfelView vs = vf;
    vs.slot_radii = slot_r;
    // The render's view has the normals by slot too (the disc test reads the centre, normal and
    // radius in storage order); the oracle below reads d.c / d.n / d.r by original index.
    std::vector<glm::vec3> slot_n;
    if (const auto* oct = std::get_if<Octree>(&idx)) slot_n = surfel_slot_normals(*oct, v.centers, v.normals);
    if (!slot_r.empty()) {
      ASSERT_EQ(slot_n.size(), slot_r.size()) << "the octree stores the centres bit for bit";
    }
    SurfelView vn = vs;
    vn.slot_normals = slot_n;
    int hits = 0;
    RayQueryStats st_d, st_f;
    for (int k = 0; k < 6000; ++k) {
      const Vec3 o(u(rng) * 1.4 - 0.2, u(rng) * 1.4 - 0.2, u(rng) * 1.4 - 0.2);
      // Every other ray along an axis (a zero direction component: the scalar child test).
      Vec3 dir(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      if (k % 2 == 1) dir = Vec3(0.0, 0.0, 0.0), dir[k % 3] = k % 4 == 1 ? 1.0 : -1.0;
      const Ray ray(o, dir);
      // Every fourth ray in a window [t0, t1] (the geometry boxes are cut at the disc test's t_min,
      // DiscKey::key_min, far above the query's own t0 - 2 R); the others from the origin on.
      const double t0 = k % 4 == 3 ? 0.4 * u(rng) : 0.0, t1 = k % 4 == 3 ? t0 + 0.6 : kInf;
      double bt = kInf;
      PointIndex bi = 0;
      for (std::size_t i = 0; i < d.c.size(); ++i) {
        const double t = ray_disc_t(ray.origin(), ray.direction(), d.c[i], Vec3(d.n[i]), d.r[i], t0, t1);
        if (t < bt) { bt = t; bi = PointIndex(i); }
      }
      std::vector<RayHit> scratch;
      RayQueryStats st;
      const SurfelHit h = std::visit(
          [&](const auto& ix) { return first_surfel_hit(ix, v, ray, t0, t1, nullptr, false, scratch, st); }, idx);
      ASSERT_EQ(h.t, bt) << type << " ray " << k;
      if (!boxes_f.empty()) {
        const Octree& oct = std::get<Octree>(idx);
        const SurfelHit hd = first_surfel_hit(oct, v, ray, t0, t1, nullptr, false, scratch, st_d);
        const SurfelHit hf = first_surfel_hit(oct, vf, ray, t0, t1, nullptr, false, scratch, st_f);
        ASSERT_EQ(hf.t, bt) << type << " ray " << k << " (float boxes)";
        EXPECT_EQ(hf.index, hd.index) << type << " ray " << k << " (float boxes)";
        RayQueryStats st_s;
        const SurfelHit hs = first_surfel_hit(oct, vs, ray, t0, t1, nullptr, false, scratch, st_s);
        ASSERT_EQ(hs.t, bt) << type << " ray " << k << " (slot radii)";
        EXPECT_EQ(hs.index, hd.index) << type << " ray " << k << " (slot radii)";
        const SurfelHit hn = first_surfel_hit(oct, vn, ray, t0, t1, nullptr, false, scratch, st_s);
        ASSERT_EQ(hn.t, bt) << type << " ray " << k << " (slot normals)";
        EXPECT_EQ(hn.index, hd.index) << type << " ray " << k << " (slot normals)";
      }
      // Every fifth ray leaves a surface (a random disc's): the discs of that surface are skipped
      // (same_surface), on the id path and on the slot path alike.
      if (k % 5 == 2) {
        const PointIndex j = PointIndex(rng() % d.c.size());
        const LeavingSurface from{j, d.c[j], Vec3(d.n[j]), double(d.r[j]), 0.0};
        double ft = kInf;
        for (std::size_t i = 0; i < d.c.size(); ++i) {
          const double t = ray_disc_t(ray.origin(), ray.direction(), d.c[i], Vec3(d.n[i]), d.r[i], t0, t1);
          if (t < ft && !same_surface(from, PointIndex(i), d.c[i], Vec3(d.n[i]), d.r[i])) ft = t;
        }
        const SurfelHit hv = std::visit(
            [&](const auto& ix) { return first_surfel_hit(ix, v, ray, t0, t1, &from, false, scratch, st); }, idx);
        ASSERT_EQ(hv.t, ft) << type << " ray " << k << " (leaving a surface)";
        if (!boxes_f.empty()) {
          RayQueryStats st_n;
          const SurfelHit hn = first_surfel_hit(std::get<Octree>(idx), vn, ray, t0, t1, &from, false, scratch, st_n);
          ASSERT_EQ(hn.t, ft) << type << " ray " << k << " (leaving a surface, slot normals)";
          EXPECT_EQ(hn.index, hv.index) << type << " ray " << k << " (leaving a surface, slot normals)";
        }
      }
      if (bt < kInf) {
        EXPECT_EQ(h.index, bi);
        const AABB db = disc_bounds(d.c[bi], Vec3(d.n[bi]), d.r[bi]);
        const Vec3 p = ray.at(bt);
        for (int a = 0; a < 3; ++a) {
          EXPECT_GE(p[a], db.lo[a] - 1e-12);
          EXPECT_LE(p[a], db.hi[a] + 1e-12);
        }
        const SurfelHit any = std::visit(
            [&](const auto& ix) { return first_surfel_hit(ix, v, ray, t0, t1, nullptr, true, scratch, st); }, idx);
        EXPECT_LT(any.t, kInf);
        EXPECT_GE(any.t, t0);
        EXPECT_LE(any.t, t1);
      }
      hits += bt < kInf;
    }
    EXPECT_GT(hits, 100) << type;
    // The float boxes contain the double ones, so they visit at least as many nodes; rounded
    // outwards by a few ulps only, so hardly more.
    if (!boxes_f.empty()) {
      EXPECT_GE(st_f.nodes_visited, st_d.nodes_visited);
      EXPECT_LE(st_f.nodes_visited, st_d.nodes_visited + st_d.nodes_visited / 20) << st_f.nodes_visited;
    }
  }
}

TEST(SurfelSlotNormals, ByStorageSlotOnlyWhereTheCentresAreTheIndexPositions) {
  // Oracle: the index's own ids (normals[ids[slot]]) and positions; one centre moved by an ulp
  // must turn the table off (the disc test would read a centre that is not the disc's).
  const Discs d = random_discs(500, 3);
  const AnyIndex idx = make_index(d.c, IndexOptions{"octree-adaptive"});
  const Octree& oct = std::get<Octree>(idx);
  const std::vector<glm::vec3> n = surfel_slot_normals(oct, d.c, d.n);
  ASSERT_EQ(n.size(), d.c.size());
  const IdView ids = oct.ids();
  for (std::size_t k = 0; k < n.size(); ++k) {
    EXPECT_EQ(n[k], d.n[ids[k]]) << k;
    EXPECT_EQ(oct.positions()[k], d.c[ids[k]]) << k;
  }
  std::vector<Vec3> moved = d.c;
  moved[123].y = std::nextafter(moved[123].y, 10.0);
  EXPECT_TRUE(surfel_slot_normals(oct, moved, d.n).empty());
}

TEST(DiscBounds, AxisAlignedDiscsAndATiltedOne) {
  // Hand-computed: a disc of radius 2 with normal +z spans +-2 in x and y and nothing in z; with
  // normal (1, 0, 1) / sqrt 2 (not normalised here) it spans +-sqrt 2 in x and z and +-2 in y.
  const AABB a = disc_bounds(Vec3(1, 2, 3), Vec3(0, 0, 5), 2.0);
  EXPECT_NEAR(a.lo.x, -1.0, 1e-8);
  EXPECT_NEAR(a.hi.y, 4.0, 1e-8);
  EXPECT_NEAR(a.hi.z - a.lo.z, 0.0, 1e-8);
  const AABB b = disc_bounds(Vec3(0, 0, 0), Vec3(1, 0, 1), 2.0);
  EXPECT_NEAR(b.hi.x, std::sqrt(2.0), 1e-8);
  EXPECT_NEAR(b.hi.y, 2.0, 1e-8);
  EXPECT_NEAR(b.lo.z, -std::sqrt(2.0), 1e-8);
}
