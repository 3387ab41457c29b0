// Visibility: hand-built scenes with known answers, and the per-point
// result against an independent brute-force ray/sphere oracle on a real scan (autzen crop).
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/io/point_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>

using namespace rayscan;
using namespace rayscan::analysis;

namespace {

// Planar grid of points: origin + a*u + b*v for a, b in [0, na) x [0, nb) steps.
void add_grid(std::vector<Vec3>& pts, Vec3 origin, Vec3 u, Vec3 v, int na, int nb) {
  for (int a = 0; a < na; ++a)
    for (int b = 0; b < nb; ++b) pts.push_back(origin + double(a) * u + double(b) * v);
}

Observer eye(Vec3 p) {
  Observer o;
  o.position = p;
  o.has_z = true;
  return o;
}

AnyIndex octree(const std::vector<Vec3>& pts) { return make_index(pts, IndexOptions{}); }

// ---- The independent oracle: textbook ray/sphere quadratic over every point (no index, no
// projected form), then the rule of is_visible() as stated in its documentation.
struct OracleHit {
  double entry = kInf;
  std::size_t j = 0;
  double margin = kInf;  // distance of the decision's quantities to their thresholds
};

OracleHit oracle_first_hit(const std::vector<Vec3>& pts, const Vec3& o, const Vec3& d, double r,
                           double t_max) {
  OracleHit h;
  double second = kInf;
  for (std::size_t j = 0; j < pts.size(); ++j) {
    const Vec3 oc = o - pts[j];
    const double b = glm::dot(oc, d);
    const double c = glm::dot(oc, oc) - r * r;
    const double disc = b * b - c;
    if (disc < 0) continue;
    const double t0 = -b - std::sqrt(disc);
    h.margin = std::min({h.margin, std::abs(disc) / (r * r), std::abs(t0), std::abs(t0 - t_max)});
    if (t0 < 0 || t0 > t_max) continue;
    if (t0 < h.entry || (t0 == h.entry && j < h.j)) {
      second = h.entry;
      h.entry = t0;
      h.j = j;
    } else {
      second = std::min(second, t0);
    }
  }
  h.margin = std::min(h.margin, std::abs(second - h.entry));
  return h;
}

// Returns visibility; `margin` receives how close the decision was to a threshold.
bool oracle_visible(const std::vector<Vec3>& pts, const Observer& ob, std::size_t i, double r, double tau,
                    double ht, double max_d, double& margin) {
  margin = kInf;
  const Vec3 v = pts[i] - ob.position;
  const double D = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  margin = std::min(std::abs(D - max_d), std::abs(D - r));
  if (D > max_d) return false;
  if (ob.azimuth) {  // bearing clockwise from +y, degrees in [0, 360)
    double az = std::atan2(v.x, v.y) * 180.0 / std::numbers::pi;
    if (az < 0) az += 360.0;
    const bool in = ob.azimuth->lo <= ob.azimuth->hi ? (az >= ob.azimuth->lo && az <= ob.azimuth->hi)
                                                     : (az >= ob.azimuth->lo || az <= ob.azimuth->hi);
    if (!in) return false;
  }
  if (ob.elevation) {
    const double el = std::asin(v.z / D) * 180.0 / std::numbers::pi;
    if (el < ob.elevation->lo || el > ob.elevation->hi) return false;
  }
  if (D <= r) return true;
  const Vec3 a = v + Vec3(0, 0, ht);
  const double Da = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  const Vec3 d = a / Da;
  const OracleHit h = oracle_first_hit(pts, ob.position, d, r, Da - r);
  margin = std::min(margin, h.margin);
  if (h.entry == kInf || h.j == i) return true;
  const double tj = glm::dot(pts[h.j] - ob.position, d);
  margin = std::min(margin, std::abs(tj - (Da - tau)));
  return tj >= Da - tau;
}

std::vector<Vec3> autzen_crop() {
  const PointCloud c = io::read_point_cloud(std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las");
  std::vector<Vec3> pts;
  for (const Vec3& p : c.positions)
    if (p.x >= 636400 && p.x < 636560 && p.y >= 848980 && p.y < 849100) pts.push_back(p);
  return pts;
}

}  // namespace

TEST(Visibility, WallHidesEverythingBehindIt) {
  // A 10 x 10 wall in the plane x = 5 (spacing 0.25, r = 0.2: overlapping spheres, no gaps), points
  // in front of it, in its shadow, and beside the shadow. Eye at the origin.
  std::vector<Vec3> pts;
  add_grid(pts, Vec3(5, -5, -5), Vec3(0, 0.25, 0), Vec3(0, 0, 0.25), 41, 41);
  const std::size_t wall_end = pts.size();
  add_grid(pts, Vec3(10, -8, -8), Vec3(0, 2, 0), Vec3(0, 0, 2), 9, 9);  // shadow at x = 10: |y|,|z| <= 10
  const std::size_t shadow_end = pts.size();
  // In front, outside the wall's cone |y| <= x (so they hide no wall point).
  add_grid(pts, Vec3(2, 2.5, -2), Vec3(0, 0.5, 0), Vec3(0, 0, 1), 5, 5);
  add_grid(pts, Vec3(10, -16, -2), Vec3(0, 1, 0), Vec3(0, 0, 1), 3, 3);    // beside the shadow
  const AnyIndex idx = octree(pts);
  VisibilityOptions vo;
  vo.radius = 0.2;
  vo.tolerance = 0.4;
  const Observer o = eye(Vec3(0, 0, 0));
  const VisibilityResult res = compute_visibility(idx, pts, std::span(&o, 1), vo);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const bool expect = i < wall_end || i >= shadow_end;
    EXPECT_EQ(res.count[i], expect ? 1u : 0u) << "point " << i << " at " << pts[i].x << "," << pts[i].y << ","
                                             << pts[i].z;
    if (expect) EXPECT_DOUBLE_EQ(res.nearest[i], glm::length(pts[i]));
    else EXPECT_EQ(res.nearest[i], -1.0);
  }
  EXPECT_EQ(res.per_observer[0], pts.size() - (shadow_end - wall_end));
  // An eye behind the wall sees the shadow points and none in front.
  const Observer back = eye(Vec3(15, 0, 0));
  const VisibilityResult r2 = compute_visibility(idx, pts, std::span(&back, 1), vo);
  for (std::size_t i = wall_end; i < shadow_end; ++i) EXPECT_EQ(r2.count[i], 1u) << i;
  for (std::size_t i = shadow_end; i < shadow_end + 25; ++i) EXPECT_EQ(r2.count[i], 0u) << i;
}

TEST(Visibility, BeyondMaxDistanceNeverVisible) {
  std::vector<Vec3> pts{{30, 0, 0}, {49.9, 0, 1}, {50.1, 0, 0}, {0, 100, 0}, {0, 0, 500}};
  const AnyIndex idx = octree(pts);
  VisibilityOptions vo;
  vo.radius = 0.1;
  vo.max_distance = 50;
  std::vector<Observer> obs{eye(Vec3(0, 0, 0))};
  VisibilityResult res = compute_visibility(idx, pts, obs, vo);
  EXPECT_EQ(res.count, (std::vector<std::uint32_t>{1, 1, 0, 0, 0}));
  // A per-observer range overrides the run's; a second eye adds its own count and distances.
  obs[0].max_distance = 40;
  obs.push_back(eye(Vec3(0, 60, 0)));
  res = compute_visibility(idx, pts, obs, vo);
  EXPECT_EQ(res.count, (std::vector<std::uint32_t>{1, 0, 0, 1, 0}));
  EXPECT_DOUBLE_EQ(res.nearest[3], 40.0);
  EXPECT_EQ(res.per_observer, (std::vector<std::uint64_t>{1, 1}));
  // Nothing is visible with a zero range except a point at the eye itself.
  vo.max_distance = 0;
  obs = {eye(Vec3(30, 0, 0))};
  res = compute_visibility(idx, pts, obs, vo);
  EXPECT_EQ(res.count, (std::vector<std::uint32_t>{1, 0, 0, 0, 0}));
}

TEST(Visibility, AngleLimits) {
  // Points on a circle of radius 10 at bearings 0 (north, +y), 90 (east, +x), 180, 270 and one
  // straight up; the eye in the centre.
  std::vector<Vec3> pts{{0, 10, 0}, {10, 0, 0}, {0, -10, 0}, {-10, 0, 0}, {0, 0, 10}, {7, 7.2, 7}};
  const AnyIndex idx = octree(pts);
  VisibilityOptions vo;
  vo.radius = 0.1;
  Observer o = eye(Vec3(0, 0, 0));
  auto seen = [&] { return compute_visibility(idx, pts, std::span(&o, 1), vo).count; };
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{1, 1, 1, 1, 1, 1}));
  o.azimuth = AngleRange{315, 45};  // wraps through north; straight up has no bearing: passes
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{1, 0, 0, 0, 1, 1}));
  o.azimuth = AngleRange{80, 190};
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{0, 1, 1, 0, 1, 0}));
  o.azimuth = AngleRange{0, 360};  // full circle
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{1, 1, 1, 1, 1, 1}));
  o.azimuth.reset();
  o.elevation = AngleRange{10, 90};  // (7, 7.2, 7): bearing 44.2, elevation atan(7 / 10.04) = 34.9
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{0, 0, 0, 0, 1, 1}));
  o.elevation = AngleRange{-5, 30};
  EXPECT_EQ(seen(), (std::vector<std::uint32_t>{1, 1, 1, 1, 0, 0}));
}

TEST(Visibility, ToleranceAndTargetHeightAtGrazingIncidence) {
  // Flat ground (spacing 0.5, r = 0.5) seen from 1.7 above it: a ray to a ground point 20 away meets
  // the neighbours' spheres about r / tan(a) = 5.9 before it. With h_t = 0 and tau = 2r it is hidden
  // by its own ground; aiming at the top of its sphere (h_t = r), or tau >= 6, shows it.
  std::vector<Vec3> pts;
  add_grid(pts, Vec3(-25, -25, 0), Vec3(0.5, 0, 0), Vec3(0, 0.5, 0), 101, 101);
  const AnyIndex idx = octree(pts);
  const auto target = std::size_t(std::find(pts.begin(), pts.end(), Vec3(20, 0, 0)) - pts.begin());
  ASSERT_LT(target, pts.size());
  const Observer o = eye(Vec3(0, 0, 1.7));
  std::vector<RayHit> scratch;
  VisibilityOptions vo;
  vo.radius = 0.5;
  vo.tolerance = 1.0;
  EXPECT_FALSE(is_visible(idx, pts, o, PointIndex(target), vo, scratch));
  vo.tolerance = 6.5;
  EXPECT_TRUE(is_visible(idx, pts, o, PointIndex(target), vo, scratch));
  vo.tolerance = 1.0;
  vo.target_height = 0.5;
  EXPECT_TRUE(is_visible(idx, pts, o, PointIndex(target), vo, scratch));
  // ...and every point of the level ground is then visible, while a 1.5-high kerb hides the ground
  // behind it.
  const Observer* op = &o;
  EXPECT_EQ(compute_visibility(idx, pts, std::span(op, 1), vo).per_observer[0], pts.size());
  std::vector<Vec3> with_kerb = pts;
  add_grid(with_kerb, Vec3(10, -25, 0.5), Vec3(0, 0.5, 0), Vec3(0, 0, 0.5), 101, 3);
  const AnyIndex idx2 = octree(with_kerb);
  const VisibilityResult res = compute_visibility(idx2, with_kerb, std::span(op, 1), vo);
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (pts[i].x > 13 && std::abs(pts[i].y) < 5) {
      EXPECT_EQ(res.count[i], 0u) << pts[i].x << "," << pts[i].y;
    }
  EXPECT_EQ(res.count[std::size_t(std::find(pts.begin(), pts.end(), Vec3(5, 0, 0)) - pts.begin())], 1u);
}

TEST(Visibility, EqualsBruteForceOracleOnRealScan) {
  const std::vector<Vec3> pts = autzen_crop();
  ASSERT_GT(pts.size(), 2000u);
  ASSERT_LT(pts.size(), 6000u);
  // Eyes: three at street level (5.5 ft above the lowest point nearby), one high above, one with
  // limits and a short range.
  const double zmin = std::min_element(pts.begin(), pts.end(), [](auto& a, auto& b) { return a.z < b.z; })->z;
  std::vector<Observer> obs{eye(Vec3(636480, 849020, zmin + 5.5)), eye(Vec3(636420, 849090, zmin + 8)),
                            eye(Vec3(636540, 848990, zmin + 20)), eye(Vec3(636480, 849040, zmin + 300))};
  Observer lim = eye(Vec3(636500, 849050, zmin + 6));
  lim.azimuth = AngleRange{300, 120};
  lim.elevation = AngleRange{-30, 10};
  lim.max_distance = 60;
  obs.push_back(lim);
  VisibilityOptions vo;
  vo.radius = 1.3;
  vo.tolerance = 2.6;
  vo.target_height = 1.3;
  vo.max_distance = 150;
  vo.threads = 2;
  const AnyIndex oct = octree(pts);
  const VisibilityResult res = compute_visibility(oct, pts, obs, vo);
  std::size_t mismatches = 0, close_calls = 0, visible = 0;
  for (std::size_t k = 0; k < obs.size(); ++k) {
    const Observer* op = &obs[k];
    const VisibilityResult one = compute_visibility(oct, pts, std::span(op, 1), vo);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      double margin;
      const bool expect = oracle_visible(pts, obs[k], i, vo.radius, vo.tolerance, vo.target_height,
                                         obs[k].max_distance.value_or(vo.max_distance), margin);
      visible += expect;
      if ((one.count[i] == 1) != expect) {
        if (margin < 1e-6) ++close_calls;  // rounding at a threshold: either answer is right
        else ++mismatches;
      }
    }
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_LE(close_calls, 2u);
  std::printf("oracle: %zu points x %zu observers, %zu visible, %zu close calls\n", pts.size(), obs.size(),
              visible, close_calls);
  // The oracle's answers are not degenerate: some points seen, most not.
  EXPECT_GT(visible, pts.size() / 20);
  EXPECT_LT(visible, pts.size() * obs.size() * 9 / 10);
  // Counts add up, and any index type and thread count give the identical result.
  std::uint64_t total = 0;
  for (auto c : res.count) total += c;
  std::uint64_t per = 0;
  for (auto c : res.per_observer) per += c;
  EXPECT_EQ(total, per);
  vo.threads = 1;
  const AnyIndex kd = make_index(pts, IndexOptions{"kdtree"});
  const VisibilityResult res_kd = compute_visibility(kd, pts, obs, vo);
  EXPECT_EQ(res_kd.count, res.count);
  EXPECT_EQ(res_kd.nearest, res.nearest);
}

TEST(SkyView, DirectionSetIsAHemisphereLattice) {
  for (SkyWeighting w : {SkyWeighting::uniform, SkyWeighting::cosine}) {
    const std::uint32_t n = 4096;
    double mean_z = 0, mean_x = 0;
    for (std::uint32_t k = 0; k < n; ++k) {
      const Vec3 d = sky_direction(k, n, 0.3, w);
      EXPECT_NEAR(glm::length(d), 1.0, 1e-12);
      EXPECT_GT(d.z, 0.0);
      mean_z += d.z / n;
      mean_x += d.x / n;
    }
    // E[z] over the hemisphere: 1/2 uniform in solid angle, 2/3 cosine-weighted.
    EXPECT_NEAR(mean_z, w == SkyWeighting::uniform ? 0.5 : 2.0 / 3.0, 1e-3);
    EXPECT_NEAR(mean_x, 0.0, 2e-3);
  }
  EXPECT_EQ(sky_rotation(7, 12345), sky_rotation(7, 12345));
  EXPECT_NE(sky_rotation(7, 12345), sky_rotation(7, 12346));
  EXPECT_NE(sky_rotation(7, 12345), sky_rotation(8, 12345));
}

TEST(SkyView, OpenGroundWallAndRoof) {
  // Level ground 41 x 41 (spacing 1, r = 0.8, rays start 1.6 above each point).
  std::vector<Vec3> ground;
  add_grid(ground, Vec3(-20, -20, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), 41, 41);
  SkyViewOptions so;
  so.rays = 128;
  so.radius = 0.8;
  so.lift = 1.6;
  // Open level ground: every ray is open.
  std::vector<double> sky = compute_sky_view(octree(ground), ground, so);
  for (double v : sky) EXPECT_EQ(v, 1.0);
  // A 40-high, 80-long wall 2 east of the origin closes half the hemisphere (less the sliver over
  // its top and around its ends: < 2 %).
  std::vector<Vec3> walled = ground;
  add_grid(walled, Vec3(2, -40, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), 81, 41);
  sky = compute_sky_view(octree(walled), walled, so);
  const std::size_t origin = 20 * 41 + 20;
  ASSERT_EQ(walled[origin], Vec3(0, 0, 0));
  EXPECT_NEAR(sky[origin], 0.5, 0.03);
  // Under a 30 x 30 roof 3 above the ground (sphere bottoms at 2.2, edge 15.8 away): only rays below
  // about atan(0.6 / 14.2) = 2.4 degrees escape (uniform: a fraction sin 2.4 deg = 0.04).
  std::vector<Vec3> roofed = ground;
  add_grid(roofed, Vec3(-15, -15, 3), Vec3(1, 0, 0), Vec3(0, 1, 0), 31, 31);
  sky = compute_sky_view(octree(roofed), roofed, so);
  EXPECT_LE(sky[origin], 0.1);
  for (double v : sky) {
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 1.0);
    EXPECT_EQ(v * so.rays, std::round(v * so.rays));  // multiples of 1/N
  }
  // Deterministic for any thread count.
  so.threads = 1;
  EXPECT_EQ(compute_sky_view(octree(roofed), roofed, so), sky);
}

TEST(SkyView, EqualsBruteForceOracleOnRealScan) {
  const std::vector<Vec3> pts = autzen_crop();
  const AnyIndex idx = octree(pts);
  SkyViewOptions so;
  so.rays = 24;
  so.radius = 1.3;
  so.lift = 2.6;
  so.seed = 3;
  const std::vector<double> sky = compute_sky_view(idx, pts, so);
  std::size_t checked = 0, mismatches = 0, close_calls = 0;
  for (std::size_t i = 0; i < pts.size(); i += 37, ++checked) {
    const Vec3 o = pts[i] + Vec3(0, 0, so.lift);
    int open = 0;
    bool close = false;
    for (std::uint32_t k = 0; k < so.rays; ++k) {
      const OracleHit h = oracle_first_hit(pts, o, sky_direction(k, so.rays, sky_rotation(so.seed, i), so.weighting),
                                           so.radius, kInf);
      open += h.entry == kInf;
      close = close || h.margin < 1e-9;
    }
    if (sky[i] != double(open) / so.rays) (close ? close_calls : mismatches)++;
  }
  EXPECT_GT(checked, 50u);
  EXPECT_EQ(mismatches, 0u);
  EXPECT_LE(close_calls, 1u);
}

TEST(CameraVisibility, FirstHitsEqualBruteForce) {
  const std::vector<Vec3> pts = autzen_crop();
  const AnyIndex idx = octree(pts);
  LookAtParams lp;
  lp.position = Vec3(636470, 849000, 440);
  lp.look_at = Vec3(636500, 849060, 420);
  lp.vfov_deg = 60;
  const Camera cam = Camera::look_at(lp, 48, 32);
  const double r = 1.3;
  const std::vector<std::uint32_t> px = camera_first_hits(idx, cam, r, kInf, 2);
  ASSERT_EQ(px.size(), 48u * 32u);
  std::size_t hits = 0, mismatches = 0;
  for (std::uint32_t y = 0; y < 32; ++y)
    for (std::uint32_t x = 0; x < 48; ++x) {
      const Ray ray = cam.generate_ray(x, y);
      const OracleHit h = oracle_first_hit(pts, ray.origin(), ray.direction(), r, kInf);
      const std::uint32_t expect = h.entry == kInf ? kNoPoint : std::uint32_t(h.j);
      hits += expect != kNoPoint;
      if (px[std::size_t(y) * 48 + x] != expect && h.margin > 1e-9) ++mismatches;
    }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GT(hits, 48u * 32u / 4);
  const std::vector<std::uint32_t> count = count_pixel_hits(px, pts.size());
  std::uint64_t sum = 0;
  for (auto c : count) sum += c;
  EXPECT_EQ(sum, hits);
  EXPECT_EQ(camera_first_hits(idx, cam, r, kInf, 1), px);
  // A range shorter than the eye's distance to everything sees nothing.
  const std::vector<std::uint32_t> none = camera_first_hits(idx, cam, r, 1.0);
  EXPECT_TRUE(std::all_of(none.begin(), none.end(), [](auto v) { return v == kNoPoint; }));
}

// Each loop checks its cancel flag (rayscan/base/job.hpp) per chunk of points or image row: set,
// the call throws Cancelled; there but clear, the result is that of a call without one.
TEST(Visibility, EveryLoopThrowsCancelledWhenItsFlagIsSet) {
  std::vector<Vec3> pts;
  add_grid(pts, Vec3(-20, -20, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), 41, 41);
  add_grid(pts, Vec3(2, -20, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), 41, 10);  // a wall: some points hidden
  const AnyIndex idx = octree(pts);
  const Observer o = eye(Vec3(-10, 0, 5));
  const std::vector<Vec3> dirs{glm::normalize(Vec3(1, 0, 1)), glm::normalize(Vec3(-1, 1, 2))};
  LookAtParams lp;
  lp.position = Vec3(-30, 0, 20);
  lp.look_at = Vec3(0, 0, 0);
  const Camera cam = Camera::look_at(lp, 16, 12);
  std::atomic<bool> stop{false};
  VisibilityOptions vo;
  vo.radius = 0.8;
  SkyViewOptions so;
  so.radius = 0.8;
  so.rays = 8;
  const auto masks = [&](const VisibilityOptions& opts) {
    std::vector<std::uint64_t> m(pts.size());
    trace_directions(idx, pts, dirs, {}, opts, [&](PointIndex i, std::span<const std::uint64_t> w) { m[i] = w[0]; },
                     false, {});
    return m;
  };
  const VisibilityResult vis = compute_visibility(idx, pts, std::span(&o, 1), vo);
  const std::vector<double> sky = compute_sky_view(idx, pts, so);
  const std::vector<std::uint64_t> open = masks(vo);
  const std::vector<std::uint32_t> px = camera_first_hits(idx, cam, 0.8);
  ASSERT_GT(vis.per_observer[0], 0u);
  ASSERT_LT(vis.per_observer[0], pts.size());

  vo.cancel = so.cancel = &stop;
  EXPECT_EQ(compute_visibility(idx, pts, std::span(&o, 1), vo).count, vis.count);
  EXPECT_EQ(compute_sky_view(idx, pts, so), sky);
  EXPECT_EQ(masks(vo), open);
  EXPECT_EQ(camera_first_hits(idx, cam, 0.8, kInf, 0, false, nullptr, &stop), px);
  stop = true;
  EXPECT_THROW(compute_visibility(idx, pts, std::span(&o, 1), vo), Cancelled);
  EXPECT_THROW(compute_sky_view(idx, pts, so), Cancelled);
  EXPECT_THROW(masks(vo), Cancelled);
  EXPECT_THROW(camera_first_hits(idx, cam, 0.8, kInf, 0, false, nullptr, &stop), Cancelled);
}

TEST(Visibility, BadOptionsThrow) {
  std::vector<Vec3> pts{{0, 0, 0}};
  const AnyIndex idx = octree(pts);
  const Observer o = eye(Vec3(1, 1, 1));
  VisibilityOptions vo;
  vo.radius = 0;
  EXPECT_THROW(compute_visibility(idx, pts, std::span(&o, 1), vo), std::invalid_argument);
  vo.radius = 1;
  vo.tolerance = -1;
  EXPECT_THROW(compute_visibility(idx, pts, std::span(&o, 1), vo), std::invalid_argument);
  vo.tolerance = 0;
  std::vector<Vec3> other{{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(compute_visibility(idx, other, std::span(&o, 1), vo), std::invalid_argument);
  SkyViewOptions so;
  so.rays = 0;
  EXPECT_THROW(compute_sky_view(idx, pts, so), std::invalid_argument);
  EXPECT_THROW(count_pixel_hits(std::vector<std::uint32_t>{5}, 1), std::out_of_range);
}

TEST(Visibility, SurfelHeightFieldHidesWhatPassesUnderACanopyWhileSpheresSeeUnderIt) {
  // Level ground (spacing 0.5) and a level crown 8 above it over x in [20, 25], |y| <= 3, no trunk,
  // seen from 2 above the ground at x = 2. The sight line to a ground point at x >= 30 passes
  // about 1 above the ground, 7 below the crown: the spheres (true 3D) see under the crown; the
  // surfels are a height field like a DSM (the crown's discs are the surface there, solid below
  // them), so the ground behind the crown is hidden, while the ground before it and the crown
  // itself are visible in both modes (is_visible's surfel rule).
  std::vector<Vec3> pts;
  add_grid(pts, Vec3(0, -5, 0), Vec3(0.5, 0, 0), Vec3(0, 0.5, 0), 120, 21);
  const std::size_t ground = pts.size();
  add_grid(pts, Vec3(20, -3, 8), Vec3(0.5, 0, 0), Vec3(0, 0.5, 0), 11, 13);
  const AnyIndex idx = octree(pts);
  const SurfelAttributes sa = estimate_surfels(idx, pts);
  const Observer o = eye(Vec3(2, 0, 2));
  const Observer* op = &o;
  VisibilityOptions surf;
  surf.radius = 0.5;
  surf.tolerance = 0.0;
  surf.surfels = &sa;
  VisibilityOptions sph;
  sph.radius = 0.5;
  sph.target_height = 0.5;  // the sphere mode's default (h_t = r): level ground stays open
  const VisibilityResult rs = compute_visibility(idx, pts, std::span(op, 1), surf);
  const VisibilityResult rp = compute_visibility(idx, pts, std::span(op, 1), sph);
  std::size_t behind = 0, before = 0;
  for (std::size_t i = 0; i < ground; ++i) {
    if (std::abs(pts[i].y) > 1.0) continue;
    if (pts[i].x >= 30.0) {
      ++behind;
      EXPECT_EQ(rs.count[i], 0u) << "surfel, behind the crown: " << pts[i].x << "," << pts[i].y;
      EXPECT_EQ(rp.count[i], 1u) << "sphere, behind the crown: " << pts[i].x << "," << pts[i].y;
    } else if (pts[i].x >= 4.0 && pts[i].x <= 18.0) {
      ++before;
      EXPECT_EQ(rs.count[i], 1u) << "surfel, before the crown: " << pts[i].x << "," << pts[i].y;
      EXPECT_EQ(rp.count[i], 1u) << "sphere, before the crown: " << pts[i].x << "," << pts[i].y;
    }
  }
  EXPECT_GT(behind, 100u);
  EXPECT_GT(before, 100u);
  // The crown's edge facing the observer is visible to both.
  const auto edge = std::size_t(std::find(pts.begin() + std::ptrdiff_t(ground), pts.end(), Vec3(20, 0, 8)) - pts.begin());
  ASSERT_LT(edge, pts.size());
  EXPECT_EQ(rs.count[edge], 1u);
  EXPECT_EQ(rp.count[edge], 1u);
}
