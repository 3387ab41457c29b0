// Measured fidelity: analytic surfaces (plane, sphere, box, terrain height
// field) sampled with a scanner-like 1 x 3 pattern (spacing s along one axis, 3 s across) and
// noise of 0.05 s, rendered in both primitive modes; depth and normal AOVs are compared with the
// analytic ray cast of the true surface, and a sun-lit plane with the analytic Lambert shading.
// The table printed here is the one in docs/fidelity.md (summarised in docs/rendering.md).
#include "rayscan/octree/normals.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/render/surfel_setup.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <numbers>
#include <random>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;

namespace {

constexpr double kS = 1.0;        // along-track spacing s
constexpr double kNoise = 0.05;   // noise sigma along the normal, in s

/// The true surface: ray cast (t, unit normal) or nullopt, and whether a hit counts (inside the
/// sampled domain by a margin, so edge pixels are not judged).
struct TruthHit {
  double t;
  Vec3 n;
  bool judged;
};
using Truth = std::function<std::optional<TruthHit>(const Ray&)>;

struct AnalyticScene {
  const char* name;
  std::vector<Vec3> points;
  Truth truth;
  Camera camera;
};

Camera cam(const Vec3& eye, const Vec3& at) {
  LookAtParams la;
  la.position = eye;
  la.look_at = at;
  la.vfov_deg = 45.0;
  return Camera::look_at(la, 160, 120);
}

/// Height field z = f(x, y) over [-L, L]^2 sampled on x every s, y every 3 s, noise along z.
AnalyticScene height_field(const char* name, std::function<double(double, double)> f,
                           std::function<Vec3(double, double)> grad_normal, double L, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, kNoise * kS);
  AnalyticScene sc{name, {}, {}, cam(Vec3(0, -1.25 * L, 0.55 * L), Vec3(0, 0, 0))};
  for (double y = -L; y <= L + 1e-9; y += 3 * kS)
    for (double x = -L; x <= L + 1e-9; x += kS) sc.points.push_back(Vec3(x, y, f(x, y) + g(rng)));
  sc.truth = [f, grad_normal, L](const Ray& r) -> std::optional<TruthHit> {
    // March in steps of 0.05 s until below the surface, then bisect (the fields are smooth).
    auto below = [&](double t) { const Vec3 p = r.at(t); return p.z < f(p.x, p.y); };
    double t0 = 0.0;
    for (double t = 0.05; t < 6 * L; t += 0.05) {
      if (below(t)) {
        double lo = t0, hi = t;
        for (int i = 0; i < 60; ++i) (below(0.5 * (lo + hi)) ? hi : lo) = 0.5 * (lo + hi);
        const Vec3 p = r.at(hi);
        if (std::abs(p.x) > L || std::abs(p.y) > L) return std::nullopt;
        const bool judged = std::abs(p.x) < L - 4 * kS && std::abs(p.y) < L - 4 * kS;
        return TruthHit{hi, grad_normal(p.x, p.y), judged};
      }
      t0 = t;
    }
    return std::nullopt;
  };
  return sc;
}

AnalyticScene plane() {
  return height_field("plane", [](double, double) { return 0.0; },
                      [](double, double) { return Vec3(0, 0, 1); }, 60.0, 1);
}

AnalyticScene terrain() {
  auto f = [](double x, double y) { return 4.0 * std::sin(x / 10.0) * std::cos(y / 13.0); };
  auto n = [](double x, double y) {
    const double fx = 0.4 * std::cos(x / 10.0) * std::cos(y / 13.0);
    const double fy = -4.0 / 13.0 * std::sin(x / 10.0) * std::sin(y / 13.0);
    return glm::normalize(Vec3(-fx, -fy, 1.0));
  };
  return height_field("terrain", f, n, 60.0, 2);
}

/// Sphere of radius 20 s on latitude rings 3 s apart, points s apart along each ring.
AnalyticScene sphere() {
  const double rho = 20.0 * kS;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, kNoise * kS);
  AnalyticScene sc{"sphere", {}, {}, cam(Vec3(0, -60, 25), Vec3(0, 0, 0))};
  const double dlat = 3.0 * kS / rho;
  for (double lat = -std::numbers::pi / 2 + dlat / 2; lat < std::numbers::pi / 2; lat += dlat) {
    const int n = std::max(1, int(std::round(2 * std::numbers::pi * rho * std::cos(lat) / kS)));
    for (int i = 0; i < n; ++i) {
      const double lon = 2 * std::numbers::pi * i / n;
      const Vec3 u(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat));
      sc.points.push_back((rho + g(rng)) * u);
    }
  }
  sc.truth = [rho](const Ray& r) -> std::optional<TruthHit> {
    const double b = glm::dot(r.origin(), r.direction());
    const double c = glm::dot(r.origin(), r.origin()) - rho * rho;
    const double disc = b * b - c;
    if (disc < 0) return std::nullopt;
    const double t = -b - std::sqrt(disc);
    // Grazing rims are not judged (the sampled rings are polygons of chord 3 s).
    const Vec3 n = r.at(t) / rho;
    return TruthHit{t, n, -glm::dot(n, r.direction()) > 0.15};
  };
  return sc;
}

/// Box [-15, 15]^3 s, each face sampled on a 1 x 3 grid including its edges.
AnalyticScene box() {
  const double h = 15.0 * kS;
  std::mt19937_64 rng(4);
  std::normal_distribution<double> g(0.0, kNoise * kS);
  AnalyticScene sc{"box", {}, {}, cam(Vec3(-40, -55, 40), Vec3(0, 0, 0))};
  for (int axis = 0; axis < 3; ++axis)
    for (double side : {-h, h}) {
      const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
      for (double v = -h; v <= h + 1e-9; v += 3 * kS)
        for (double u = -h; u <= h + 1e-9; u += kS) {
          Vec3 p;
          p[axis] = side + g(rng);
          p[a1] = u;
          p[a2] = v;
          sc.points.push_back(p);
        }
    }
  sc.truth = [h](const Ray& r) -> std::optional<TruthHit> {
    double t0 = -kInf, t1 = kInf;
    int ax = 0;
    for (int a = 0; a < 3; ++a) {
      double lo = (-h - r.origin()[a]) / r.direction()[a], hi = (h - r.origin()[a]) / r.direction()[a];
      if (lo > hi) std::swap(lo, hi);
      if (lo > t0) { t0 = lo; ax = a; }
      t1 = std::min(t1, hi);
    }
    if (t0 > t1 || t0 < 0) return std::nullopt;
    Vec3 n(0.0);
    n[ax] = r.direction()[ax] > 0 ? -1.0 : 1.0;
    // Pixels within 1.5 s of an edge are not judged (the face's discs may stop short or overhang).
    const Vec3 p = r.at(t0);
    bool judged = true;
    for (int a = 0; a < 3; ++a)
      if (a != ax && std::abs(p[a]) > h - 1.5 * kS) judged = false;
    return TruthHit{t0, n, judged};
  };
  return sc;
}

struct Metrics {
  std::size_t judged = 0, holes = 0;
  double depth_median = 0, depth_p95 = 0, normal_median = 0, normal_p95 = 0;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, std::size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

/// Render the AOVs of `sc` in `mode` and compare them with the analytic truth.
Metrics measure(const AnalyticScene& sc, Primitive mode) {
  Scene s;
  s.camera = sc.camera;
  s.spp = 1;
  s.max_depth = 1;
  s.output.aovs = {Aov::depth, Aov::normal};
  const std::vector<Color> albedo(sc.points.size(), Color(0.5f));
  const AnyIndex index = make_index(sc.points, IndexOptions{});
  RenderSettings rs = make_settings(s, sc.points, albedo, median_nn_spacing(index, sc.points));
  SurfelAttributes sa;
  if (mode == Primitive::surfel) {
    s.primitive = Primitive::surfel;
    PointCloud pc;
    pc.positions = sc.points;
    sa = scene_surfels(s, index, pc);
    use_surfels(rs, sa);
  }
  Framebuffer fb;
  render_image(index, rs, fb);
  Metrics m;
  std::vector<double> dz, na;
  for (std::uint32_t y = 0; y < fb.height; ++y)
    for (std::uint32_t x = 0; x < fb.width; ++x) {
      const auto truth = sc.truth(sc.camera.generate_ray(x, y));
      if (!truth || !truth->judged) continue;
      ++m.judged;
      const std::size_t p = std::size_t(y) * fb.width + x;
      if (std::isinf(fb.depth[p])) {
        ++m.holes;
        continue;
      }
      dz.push_back(std::abs(double(fb.depth[p]) - truth->t) / kS);
      const double c = std::abs(glm::dot(Vec3(fb.normal[p]), truth->n));
      na.push_back(std::acos(std::min(1.0, c)) * 180.0 / std::numbers::pi);
    }
  m.depth_median = quantile(dz, 0.5);
  m.depth_p95 = quantile(dz, 0.95);
  m.normal_median = quantile(na, 0.5);
  m.normal_p95 = quantile(na, 0.95);
  return m;
}

/// Fraction of judged plane pixels darker than the analytic Lambert shading by more than 2%
/// (acne), under a sun at 60 degrees elevation with a black sky and direct light only.
double acne_fraction(Primitive mode) {
  AnalyticScene sc = plane();
  // Less noise here: the shading of a 0.05 s-noisy PCA normal varies by ~1% on its own.
  for (Vec3& p : sc.points) p.z *= 0.2;
  Scene s;
  s.camera = sc.camera;
  s.spp = 2;
  s.max_depth = 1;
  s.background.gradient = false;
  s.background.color = Color(0.0f);
  s.sun.enabled = true;
  const double el = 60.0 * std::numbers::pi / 180.0;
  s.sun.direction = Vec3(0.3 * std::cos(el), std::sqrt(0.91) * std::cos(el), std::sin(el));
  s.sun.color = Color(1.0f);
  const std::vector<Color> albedo(sc.points.size(), Color(0.5f));
  const AnyIndex index = make_index(sc.points, IndexOptions{});
  RenderSettings rs = make_settings(s, sc.points, albedo, median_nn_spacing(index, sc.points));
  SurfelAttributes sa;
  if (mode == Primitive::surfel) {
    PointCloud pc;
    pc.positions = sc.points;
    sa = scene_surfels(s, index, pc);
    use_surfels(rs, sa);
  }
  Framebuffer fb;
  render_image(index, rs, fb);
  const double expect = 0.5 / std::numbers::pi * s.sun.irradiance * std::sin(el);
  std::size_t judged = 0, dark = 0;
  for (std::uint32_t y = 0; y < fb.height; ++y)
    for (std::uint32_t x = 0; x < fb.width; ++x) {
      const auto truth = sc.truth(sc.camera.generate_ray(x, y));
      if (!truth || !truth->judged) continue;
      ++judged;
      if (fb.beauty[std::size_t(y) * fb.width + x].g < 0.98 * expect) ++dark;
    }
  return double(dark) / double(judged);
}

}  // namespace

TEST(Fidelity, AnalyticScenesInBothModes) {
  std::printf("| scene | mode | judged px | holes | depth err median / p95 (s) | normal err median / p95 (deg) |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const auto& sc : {plane(), sphere(), box(), terrain()}) {
    for (Primitive mode : {Primitive::sphere, Primitive::surfel}) {
      const Metrics m = measure(sc, mode);
      const double holes = double(m.holes) / double(m.judged);
      std::printf("| %s | %s | %zu | %.3f%% | %.3f / %.3f | %.2f / %.2f |\n", sc.name,
                  mode == Primitive::surfel ? "surfel" : "sphere", m.judged, 100.0 * holes,
                  m.depth_median, m.depth_p95, m.normal_median, m.normal_p95);
      ASSERT_GT(m.judged, 3000u) << sc.name;
      if (mode == Primitive::surfel) {
        EXPECT_LT(holes, 0.001) << sc.name;            // goal: holes < 0.1%
        EXPECT_LT(m.normal_median, 3.0) << sc.name;    // median normal error < 3 degrees
        EXPECT_LT(m.depth_median, 0.25) << sc.name;    // within a quarter spacing
      } else {
        // The sphere rows are the baseline the docs quote (0.6-5.8% holes, median normal errors
        // of 46-50 degrees: a sphere's normal is the direction from its centre, not the
        // surface's): a result outside these bands means those figures need measuring again.
        EXPECT_GT(holes, 0.003) << sc.name;
        EXPECT_LT(holes, 0.10) << sc.name;
        EXPECT_GT(m.normal_median, 35.0) << sc.name;
        EXPECT_LT(m.normal_median, 60.0) << sc.name;
      }
    }
  }
}

TEST(Fidelity, SunLitPlaneHasNoAcneWithSurfels) {
  const double sphere_acne = acne_fraction(Primitive::sphere);
  const double surfel_acne = acne_fraction(Primitive::surfel);
  std::printf("acne (pixels > 2%% darker than Lambert): sphere %.2f%%, surfel %.2f%%\n",
              100.0 * sphere_acne, 100.0 * surfel_acne);
  EXPECT_EQ(surfel_acne, 0.0);
  EXPECT_GT(sphere_acne, 0.05);  // the paper's spheres: shaded with the sphere normal
}

/// Acne on a real depth-quantised scan: the lit wall of the bundled Kinect scan
/// office1 (scenes/data/office1.pcd, 640x480 organised). At 5 m a Kinect's depth comes in
/// disparity steps of ~7 cm (7 x the point spacing): the wall is a staircase of flat terraces, and
/// without the measured thickness shadow rays leaving one terrace hit the discs of the next
/// (15-22% of the lit samples).
/// Oracle, independent of the renderer: the wall plane z = a x + b y + c fitted by least squares
/// to the crop's points; pixels whose hit lies within 10 cm of it are wall pixels, and the sun is
/// truly blocked at one only if some point of the crop lies off the wall (> 10 cm in front of the
/// plane) within 3 cm of its sun ray (brute force over every point). An acne pixel is an
/// unblocked wall pixel darker than half the unoccluded Lambert shading of the fitted plane (half:
/// a terrace's flat normal shades it up to ~20% differently from the plane, a shadow blacks it).
TEST(Fidelity, KinectScanWallHasNoAcneWithSurfels) {
  const std::string file = RAYSCAN_SCENES_DIR "/data/office1.pcd";
  const PointCloud full = io::read_point_cloud(file);
  // The crop: the sensor pixels (u, v) in [80, 220) x [40, 260) of the main wall (pinhole
  // f = 525, centre (319.5, 239.5), the data's own sensor model).
  PointCloud crop;
  for (const Vec3& p : full.positions) {
    if (!(p.z > 0.0)) continue;
    const double u = 525.0 * p.x / p.z + 319.5, v = 525.0 * p.y / p.z + 239.5;
    if (u >= 80 && u < 220 && v >= 40 && v < 260) crop.positions.push_back(p);
  }
  ASSERT_GT(crop.size(), 20000u);
  // Least-squares plane z = a x + b y + c (normal equations, Cramer's rule).
  double sxx = 0, sxy = 0, sx = 0, syy = 0, sy = 0, n = 0, sxz = 0, syz = 0, sz = 0;
  for (const Vec3& p : crop.positions) {
    sxx += p.x * p.x; sxy += p.x * p.y; sx += p.x; syy += p.y * p.y; sy += p.y; n += 1;
    sxz += p.x * p.z; syz += p.y * p.z; sz += p.z;
  }
  const auto det3 = [](double a, double b, double c, double d, double e, double f, double g, double h, double i) {
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  };
  const double D = det3(sxx, sxy, sx, sxy, syy, sy, sx, sy, n);
  const double a = det3(sxz, sxy, sx, syz, syy, sy, sz, sy, n) / D;
  const double b = det3(sxx, sxz, sx, sxy, syz, sy, sx, sz, n) / D;
  const double c = det3(sxx, sxy, sxz, sxy, syy, syz, sx, sy, sz) / D;
  const Vec3 plane_n = glm::normalize(Vec3(a, b, -1.0));  // towards the camera (at the origin, z < wall)
  const auto plane_dist = [&](const Vec3& p) { return (a * p.x + b * p.y + c - p.z) / std::sqrt(a * a + b * b + 1.0); };

  Scene scene;
  scene.camera = load_camera(RAYSCAN_SCENES_DIR "/cameras/kinect_sensor.json");
  SceneOverrides ov;
  ov.width = 160;
  ov.primitive = "surfel";
  scene.apply(ov);
  scene.material.mode = ColorMode::constant;
  scene.material.constant = Color(0.5f);
  scene.background.gradient = false;
  scene.background.color = Color(0.0f);
  scene.sun.enabled = true;
  scene.sun.direction = glm::normalize(Vec3(0.2, -0.3, -1.0));
  scene.sun.angular_diameter_deg = 0.0;
  scene.sun.irradiance = 1.0f;
  scene.sun.color = Color(1.0f);
  scene.max_depth = 1;
  scene.spp = 1;
  scene.output.aovs = {Aov::position};
  const AnyIndex index = make_index(crop.positions, IndexOptions{});
  const SurfelAttributes attrs = scene_surfels(scene, index, crop);
  const std::vector<Color> albedo(crop.size(), Color(0.5f));
  const Vec3 L = scene.sun.direction;
  const double expect = 0.5 * std::max(0.0, glm::dot(plane_n, L)) / std::numbers::pi;
  ASSERT_GT(expect, 0.1);
  // Acne fraction of a render with the given surfels (judged pixels: lit wall, sun not blocked).
  const auto acne_of = [&](const SurfelAttributes& a, std::size_t& judged) {
    RenderSettings st = make_settings(scene, crop.positions, albedo, 1.0);
    use_surfels(st, a);
    Framebuffer fb;
    render_image(index, st, fb);
    std::size_t acne = 0;
    judged = 0;
    for (std::size_t p = 0; p < fb.beauty.size(); ++p) {
      if (glm::length(fb.position[p]) == 0.0f) continue;
      const Vec3 x = fb.position_origin + Vec3(fb.position[p]);
      if (std::abs(plane_dist(x)) > 0.10) continue;
      bool blocked = false;
      for (const Vec3& q : crop.positions) {
        const Vec3 v = q - x;
        const double t = glm::dot(v, L);
        if (t <= 0.0 || plane_dist(q) < 0.10) continue;  // only points well in front of the wall
        if (glm::dot(v, v) - t * t < 0.03 * 0.03) { blocked = true; break; }
      }
      if (blocked) continue;
      ++judged;
      if (fb.beauty[p].r < 0.5 * expect) ++acne;
    }
    return judged ? double(acne) / double(judged) : 1.0;
  };
  std::size_t judged = 0, judged0 = 0;
  const double frac = acne_of(attrs, judged);
  SurfelAttributes thin = attrs;  // the control: the rule without the measured thickness
  std::fill(thin.thickness.begin(), thin.thickness.end(), 0.0f);
  const double frac0 = acne_of(thin, judged0);
  ASSERT_GT(judged, 1000u);
  std::printf("office1 wall: %zu lit wall pixels, acne (darker than half the plane's Lambert shading): "
              "%.2f%% (without the measured thickness: %.2f%%)\n", judged, 100.0 * frac, 100.0 * frac0);
  EXPECT_LT(frac, 0.05);
  EXPECT_GT(frac0, 0.10);  // the case this test guards: terrace discs shadowing their neighbours
}
