// Measured fidelity (issue 16, section 2): analytic surfaces (plane, sphere, box, terrain height
// field) sampled with a scanner-like 1 x 3 pattern (spacing s along one axis, 3 s across) and
// noise of 0.05 s, rendered in both primitive modes; depth and normal AOVs are compared with the
// analytic ray cast of the true surface, and a sun-lit plane with the analytic Lambert shading.
// The table printed here is the one in README.md ("Surfels").
#include "rayscan/normals.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/surfel_setup.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <numbers>
#include <random>

using namespace rayscan;
using namespace rayscan::render;

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
        EXPECT_LT(holes, 0.001) << sc.name;            // issue 16 goal: holes < 0.1%
        EXPECT_LT(m.normal_median, 3.0) << sc.name;    // median normal error < 3 degrees
        EXPECT_LT(m.depth_median, 0.25) << sc.name;    // within a quarter spacing
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
