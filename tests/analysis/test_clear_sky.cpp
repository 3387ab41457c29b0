// ESRA clear-sky model (rayscan/analysis/clear_sky.hpp): its pieces, its validation, the
// transposition of measured irradiance, and agreement with GRASS GIS r.sun itself, run at test
// time by tests/analysis/rsun_instant.sh (skipped when `grass` is not installed).
#include "run_command.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "rayscan/analysis/clear_sky.hpp"

#ifndef RAYSCAN_SOURCE_DIR
#error "RAYSCAN_SOURCE_DIR (the source tree, for tests/analysis/rsun_instant.sh) must be defined"
#endif

namespace rayscan::analysis::clear_sky_test {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// The message of the std::invalid_argument `f` throws ("" when it throws nothing).
template <class F>
std::string invalid_argument_message(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(ClearSky, ExtraterrestrialIrradianceFollowsRsun) {
  // r.sun 8.2 writes G0 into its maps' history: day 172 -> "1322.508495".
  EXPECT_NEAR(extraterrestrial_irradiance(172), 1322.508495, 1e-6);
  // Perihelion (about January 3) and aphelion: I0 (1 +- 0.03344).
  EXPECT_NEAR(extraterrestrial_irradiance(3), 1367.0 * 1.03344, 0.05);
  EXPECT_NEAR(extraterrestrial_irradiance(185), 1367.0 * (1 - 0.03344), 0.1);
  EXPECT_DOUBLE_EQ(extraterrestrial_irradiance(172, 1361.0) / extraterrestrial_irradiance(172),
                   1361.0 / 1367.0);
}

TEST(ClearSky, AirMassAndRayleigh) {
  // Zenith sun at sea level: m is 1 to the Kasten-Young fit's accuracy (pow term 0.0003).
  EXPECT_NEAR(relative_optical_air_mass(kPi / 2, 0.0), 1.0, 1e-3);
  // Site elevation scales m by p/p0 = exp(-z / 8434.5).
  EXPECT_NEAR(relative_optical_air_mass(0.5, 1500.0) / relative_optical_air_mass(0.5, 0.0),
              std::exp(-1500.0 / 8434.5), 1e-12);
  // At the horizon the refraction-corrected air mass is finite (about 38).
  const double horizon = relative_optical_air_mass(0.0, 0.0);
  EXPECT_GT(horizon, 30.0);
  EXPECT_LT(horizon, 45.0);
  EXPECT_NEAR(refraction_correction(0.0), 0.061359 * 0.1594, 1e-15);
  // The two pieces of delta_R nearly meet at m = 20 (within 0.1 %), and both branches are used.
  const double below = rayleigh_optical_thickness(20.0),
               above = rayleigh_optical_thickness(20.0001);
  EXPECT_NEAR(below / above, 1.0, 1e-3);
  EXPECT_NEAR(rayleigh_optical_thickness(30.0), 1.0 / (10.4 + 0.718 * 30.0), 1e-15);
  EXPECT_NEAR(rayleigh_optical_thickness(1.0), 1.0 / (6.6296 + 1.7513 - 0.1202 + 0.0065 - 0.00013),
              1e-15);
}

TEST(ClearSky, DiffuseCoefficientsClampA1WherePaperSays) {
  // T_LK = 3: A1' T_n = 0.0208 > 0.0022, no clamp.
  const DiffuseAngularCoefficients c3 = diffuse_angular_coefficients(3.0);
  EXPECT_NEAR(c3.a1, 0.26463 - 0.061581 * 3 + 0.0031408 * 9, 1e-15);
  // T_LK = 6: A1' = 0.0082, T_n = 0.181, product 0.0015 < 0.0022 -> A1 = 0.0022 / T_n.
  const DiffuseAngularCoefficients c6 = diffuse_angular_coefficients(6.0);
  EXPECT_NEAR(c6.a1, 0.0022 / diffuse_transmission(6.0), 1e-15);
  EXPECT_NEAR(c6.a2, 2.04020 + 0.018945 * 6 - 0.011161 * 36, 1e-14);
  EXPECT_NEAR(c6.a3, -1.3025 + 0.039231 * 6 + 0.0085079 * 36, 1e-14);
  EXPECT_NEAR(diffuse_angular_function(kPi / 2, 6.0), c6.a1 + c6.a2 + c6.a3, 1e-14);
}

TEST(ClearSky, GeometryHelpers) {
  const SurfaceOrientation south45 = orientation_from_normal(0.0, -1.0, 1.0);
  EXPECT_NEAR(south45.slope, kPi / 4, 1e-15);
  EXPECT_NEAR(south45.aspect, kPi, 1e-15);
  const SurfaceOrientation west_wall = orientation_from_normal(-2.0, 0.0, 0.0);
  EXPECT_NEAR(west_wall.slope, kPi / 2, 1e-15);
  EXPECT_NEAR(west_wall.aspect, 1.5 * kPi, 1e-15);
  EXPECT_NEAR(orientation_from_normal(0.0, 0.0, -1.0).slope, kPi, 1e-15);
  // Sun due south at 30 degrees on a 60-degree south slope: normal incidence.
  EXPECT_NEAR(cos_incidence({30 * kDeg, kPi}, {60 * kDeg, kPi}), 1.0, 1e-15);
  EXPECT_NEAR(cos_incidence({30 * kDeg, 0.0}, {0.0, kPi}), 0.5, 1e-15);
  EXPECT_LT(cos_incidence({10 * kDeg, 0.0}, {kPi / 2, kPi}), 0.0);  // behind a south wall
  EXPECT_DOUBLE_EQ(grass_aspect_deg(kPi), 270.0);
  EXPECT_DOUBLE_EQ(grass_aspect_deg(0.0), 90.0);
  EXPECT_DOUBLE_EQ(grass_aspect_deg(kPi / 2), 360.0);  // not 0: r.sun reads 0 as undefined
  EXPECT_NEAR(grass_aspect_deg(1.5 * kPi), 180.0, 1e-12);
}

TEST(ClearSky, MuneerRatio) {
  const SunDirection sun{40 * kDeg, kPi};
  EXPECT_EQ(muneer_diffuse_ratio(sun, {0.0, kPi}, std::sin(sun.elevation), false, 0.7), 1.0);
  // Shadowed vertical wall: r_i + 0.252271 f_g, f_g = 1 - pi/2.
  EXPECT_NEAR(muneer_diffuse_ratio(sun, {kPi / 2, 0.0}, -0.3, false, 0.7),
              0.5 + 0.252271 * (1.0 - kPi / 2), 1e-15);
  EXPECT_EQ(muneer_diffuse_ratio(sun, {kPi / 2, 0.0}, 0.3, true, 0.7),
            muneer_diffuse_ratio(sun, {kPi / 2, 0.0}, -0.3, false, 0.7));
  // Kb = 0 (no beam): the sunlit form reduces to the isotropic-plus-horizon term r_i + N f_g.
  const double beta = 30 * kDeg;
  const double fg = std::sin(beta) - beta * std::cos(beta) - kPi * std::pow(std::sin(beta / 2), 2);
  EXPECT_NEAR(muneer_diffuse_ratio(sun, {beta, kPi}, 0.9, false, 0.0),
              (1 + std::cos(beta)) / 2 + 0.00263 * fg, 1e-15);
  // Low sun (h0 < 0.1 rad) uses sin(slope) cos(A_LN) / (0.1 - 0.008 h0) instead of the ratio.
  const SunDirection low{0.05, kPi};
  EXPECT_NEAR(muneer_diffuse_ratio(low, {beta, kPi}, 0.5, false, 0.2),
              ((0.00263 - 0.2 * (0.712 + 0.6883 * 0.2)) * fg + (1 + std::cos(beta)) / 2) * 0.8 +
                  0.2 * std::sin(beta) / (0.1 - 0.008 * 0.05),
              1e-14);
}

TEST(ClearSky, SunDownAndShadow) {
  ClearSkyInput in;
  in.sun = {-0.01, kPi};
  in.surface = {30 * kDeg, kPi};
  const SurfaceIrradiance night = clear_sky_irradiance(in);
  EXPECT_EQ(night.global, 0.0);
  EXPECT_EQ(night.horizontal.global, 0.0);
  EXPECT_EQ(clear_sky_horizontal(0.0, 100, 3.0, 0.0).global, 0.0);

  in.sun = {35 * kDeg, kPi};
  const SurfaceIrradiance lit = clear_sky_irradiance(in);
  in.in_shadow = true;
  const SurfaceIrradiance shade = clear_sky_irradiance(in);
  EXPECT_GT(lit.beam, 0.0);
  EXPECT_EQ(shade.beam, 0.0);
  EXPECT_EQ(shade.beam_normal, lit.beam_normal);
  EXPECT_LT(shade.diffuse, lit.diffuse);  // the circumsolar part goes with the beam
  EXPECT_NEAR(shade.reflected, in.albedo * shade.horizontal.diffuse * (1 - std::cos(30 * kDeg)) / 2,
              1e-12);  // r.sun: no beam in the reflected term of a shadowed cell
  in.shadow_drops_reflected_beam = false;
  EXPECT_DOUBLE_EQ(clear_sky_irradiance(in).reflected, lit.reflected);
  EXPECT_NEAR(lit.global, lit.beam + lit.diffuse + lit.reflected, 1e-12);
  // The horizontal values are clear_sky_horizontal's.
  const HorizontalIrradiance h = clear_sky_horizontal(35 * kDeg, in.day_of_year, in.linke, 0.0);
  EXPECT_DOUBLE_EQ(lit.horizontal.beam, h.beam);
  EXPECT_DOUBLE_EQ(lit.horizontal.diffuse, h.diffuse);
  EXPECT_NEAR(lit.beam_normal * std::sin(35 * kDeg), h.beam, 1e-12);
}

TEST(ClearSky, MeasuredTranspositionReproducesClearSky) {
  // Feeding the model's own horizontal values as "measurements" must give the model's surface
  // values (with the reflected term from G_hc, which is what the measured form always uses).
  for (const double elev : {0.05, 0.3, 1.0}) {
    for (const bool shadow : {false, true}) {
      ClearSkyInput cs;
      cs.sun = {elev, 2.5};
      cs.day_of_year = 200;
      cs.linke = 4.0;
      cs.surface = {40 * kDeg, 2.9};
      cs.albedo = 0.3;
      cs.in_shadow = shadow;
      cs.shadow_drops_reflected_beam = false;
      const SurfaceIrradiance model = clear_sky_irradiance(cs);
      MeasuredInput m;
      m.ghi = model.horizontal.global;
      m.dni = model.beam_normal;
      m.dhi = model.horizontal.diffuse;
      m.sun = cs.sun;
      m.day_of_year = cs.day_of_year;
      m.surface = cs.surface;
      m.albedo = cs.albedo;
      m.in_shadow = shadow;
      const SurfaceIrradiance t = measured_irradiance_on_surface(m);
      EXPECT_NEAR(t.beam, model.beam, 1e-9 * model.global) << elev;
      EXPECT_NEAR(t.diffuse, model.diffuse, 1e-9 * model.global) << elev;
      EXPECT_NEAR(t.reflected, model.reflected, 1e-9 * model.global) << elev;
      EXPECT_NEAR(t.global, model.global, 1e-9 * model.global) << elev;
    }
  }
  // Sun below the horizon with diffuse light (an hour's mean at dawn): no beam, shadowed diffuse.
  MeasuredInput dawn;
  dawn.ghi = 20;
  dawn.dni = 5;
  dawn.dhi = 20;
  dawn.sun = {-0.02, 1.6};
  dawn.surface = {kPi / 2, kPi};
  const SurfaceIrradiance d = measured_irradiance_on_surface(dawn);
  EXPECT_EQ(d.beam, 0.0);
  EXPECT_NEAR(d.diffuse, 20 * (0.5 + 0.252271 * (1 - kPi / 2)), 1e-12);
  EXPECT_NEAR(d.reflected, 0.2 * 20 * 0.5, 1e-12);
}

TEST(ClearSky, ValidationMessagesAreOneLineAndNameTheParameter) {
  ClearSkyInput ok;
  ok.sun = {0.5, kPi};
  auto with = [&](auto change) {
    ClearSkyInput in = ok;
    change(in);
    return invalid_argument_message([&] { clear_sky_irradiance(in); });
  };
  EXPECT_EQ(with([](ClearSkyInput&) {}), "");
  EXPECT_EQ(
      with([](ClearSkyInput& in) { in.linke = 0.5; }),
      "clear_sky_irradiance: linke must be in 1..10 (Linke turbidity at air mass 2), got 0.5");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.albedo = 1.5; }),
            "clear_sky_irradiance: albedo must be in 0..1, got 1.5");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.surface.slope = 4.0; }),
            "clear_sky_irradiance: slope must be in 0..pi radians (0..180 degrees), got 4");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.day_of_year = 367; }),
            "extraterrestrial_irradiance: day_of_year must be in 1..366, got 367");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.site_elevation_m = 2e4; }),
            "clear_sky_irradiance: site_elevation_m must be in -1000..10000 m, got 20000");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.sun.elevation = 2.0; }),
            "clear_sky_irradiance: sun elevation must be in -pi/2..pi/2 radians, got 2");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.sun.azimuth = NAN; }),
            "clear_sky_irradiance: sun azimuth must be a finite number, got nan");
  EXPECT_EQ(with([](ClearSkyInput& in) { in.cos_incidence = 1.5; }),
            "clear_sky_irradiance: cos_incidence must be in -1..1, got 1.5");
  EXPECT_EQ(
      with([](ClearSkyInput& in) { in.linke = NAN; }),
      "clear_sky_irradiance: linke must be in 1..10 (Linke turbidity at air mass 2), got nan");
  MeasuredInput m;
  m.dni = -1;
  EXPECT_EQ(invalid_argument_message([&] { measured_irradiance_on_surface(m); }),
            "measured_irradiance_on_surface: dni must be a finite number >= 0 W/m^2, got -1");
  EXPECT_EQ(invalid_argument_message([] { rayleigh_optical_thickness(0.0); }),
            "rayleigh_optical_thickness: air_mass must be a finite number > 0, got 0");
  EXPECT_EQ(invalid_argument_message([] { orientation_from_normal(0, 0, 0); }),
            "orientation_from_normal: the normal must be a finite non-zero vector");
}

// ---- Agreement with GRASS r.sun ---------------------------------------------------------------

struct RsunCase {
  int day = 0;
  double time = 0, linke = 0, z = 0, slope_deg = 0, aspect_deg = 0;
  bool sun_behind = false;  // incidout null: the sun is behind the surface plane
  double incid_deg = 0, beam = 0, diff = 0, refl = 0, glob = 0, azimuth_deg = 0;
};

using rayscan::test::run_output;

std::vector<RsunCase> parse_rsun(const std::string& text) {
  std::vector<RsunCase> cases;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream f(line);
    std::string tag, incid;
    RsunCase c;
    if (!(f >> tag) || tag != "RSUN") continue;
    f >> c.day >> c.time >> c.linke >> c.z >> c.slope_deg >> c.aspect_deg >> incid >> c.beam >>
        c.diff >> c.refl >> c.glob >> c.azimuth_deg;
    if (!f) throw std::runtime_error("unreadable r.sun line: " + line);
    c.sun_behind = incid == "*";
    if (!c.sun_behind) c.incid_deg = std::stod(incid);
    cases.push_back(c);
  }
  return cases;
}

// Relative difference, with 1 W/m^2 as the floor of the scale (a 0 vs 1e-7 is not a 100 % miss).
double rel_diff(double ours, double rsun) {
  return std::abs(ours - rsun) / std::max(std::abs(rsun), 1.0);
}

bool grass_installed() {
  int status = 0;
  run_output("command -v grass >/dev/null 2>&1", status);
  return status == 0;
}

// Runs rsun_instant.sh at latitude 45 N for the given cases (flat plus one tilted orientation),
// feeds r.sun's own sun elevation (its flat cells' incidence angle), azimuth and the tilted cells'
// incidence angle into clear_sky_irradiance, and checks each component against r.sun within
// 0.5 % of max(r.sun value, 1 W/m^2). Returns the largest relative difference per component
// (beam, diffuse, reflected, global) and counts the tilted cases in the given categories.
struct RsunComparison {
  std::array<double, 4> worst{};
  std::size_t cases = 0;
  int low_sun_tilted = 0, sun_behind = 0;
};

RsunComparison compare_with_rsun(const std::string& days, const std::string& times,
                                 const std::string& linkes, const std::string& elevations,
                                 double albedo, double slope_deg, double aspect_deg) {
  RsunComparison result;
  int status = 0;
  char args[512];
  std::snprintf(args, sizeof args, " 45 '%s' '%s' '%s' '%s' %g %g %g 2>&1", days.c_str(),
                times.c_str(), linkes.c_str(), elevations.c_str(), albedo, slope_deg, aspect_deg);
  const std::string script = std::string(RAYSCAN_SOURCE_DIR) + "/tests/analysis/rsun_instant.sh";
  const std::string out = run_output("'" + script + "'" + args, status);
  EXPECT_EQ(status, 0) << out;
  const std::vector<RsunCase> cases = parse_rsun(out);
  EXPECT_FALSE(cases.empty()) << out;
  result.cases = cases.size();

  std::map<std::tuple<int, double>, double> elevation_deg;
  for (const RsunCase& c : cases)
    if (c.slope_deg == 0.0) elevation_deg[{c.day, c.time}] = c.incid_deg;

  constexpr double kTolerance = 0.005;
  for (const RsunCase& c : cases) {
    ClearSkyInput in;
    in.sun = {elevation_deg.at({c.day, c.time}) * kDeg, c.azimuth_deg * kDeg};
    in.day_of_year = c.day;
    in.linke = c.linke;
    in.site_elevation_m = c.z;
    in.albedo = albedo;
    in.surface = {c.slope_deg * kDeg, c.aspect_deg * kDeg};
    in.cos_incidence = c.sun_behind ? 0.0 : std::sin(c.incid_deg * kDeg);
    const SurfaceIrradiance ours = clear_sky_irradiance(in);
    const std::array<double, 4> d = {rel_diff(ours.beam, c.beam), rel_diff(ours.diffuse, c.diff),
                                     rel_diff(ours.reflected, c.refl),
                                     rel_diff(ours.global, c.glob)};
    for (std::size_t k = 0; k < d.size(); ++k) result.worst[k] = std::max(result.worst[k], d[k]);
    EXPECT_LE(*std::max_element(d.begin(), d.end()), kTolerance)
        << "day " << c.day << " time " << c.time << " linke " << c.linke << " z " << c.z
        << " slope " << c.slope_deg << " aspect " << c.aspect_deg << ": ours beam/diff/refl "
        << ours.beam << " " << ours.diffuse << " " << ours.reflected << ", r.sun " << c.beam << " "
        << c.diff << " " << c.refl;
    if (c.slope_deg != 0.0 && in.sun.elevation < kLowSunElevation && !c.sun_behind)
      ++result.low_sun_tilted;
    if (c.sun_behind) ++result.sun_behind;
  }
  std::printf(
      "max relative difference vs r.sun over %zu cases (flat and slope %g aspect %g): "
      "beam %.2e diffuse %.2e reflected %.2e global %.2e\n",
      result.cases, slope_deg, aspect_deg, result.worst[0], result.worst[1], result.worst[2],
      result.worst[3]);
  return result;
}

// Days 15, 172, 355 x solar times 8, 10, 12, 15 h x Linke 2, 3.5, 6 x site elevation 0 and
// 1500 m, albedo 0.2, flat and 30 degrees south-facing. Observed (GRASS 8.2.1): every component
// within 1e-6 of r.sun (its maps are 32-bit floats), far inside the 0.5 % tolerance.
TEST(ClearSkyRsun, FlatAndSouthFacingMatchGrassRsun) {
  if (!grass_installed()) GTEST_SKIP() << "GRASS GIS (`grass`, Debian grass-core) is not installed";
  const RsunComparison r =
      compare_with_rsun("15 172 355", "8 10 12 15", "2 3.5 6", "0 1500", 0.2, 30.0, 180.0);
  EXPECT_EQ(r.cases, 3u * 4u * 3u * 2u * 2u);
  EXPECT_GT(r.low_sun_tilted, 0) << "the cases no longer reach Muneer's low-sun branch";
  RecordProperty("max_rel_beam", std::to_string(r.worst[0]));
  RecordProperty("max_rel_diffuse", std::to_string(r.worst[1]));
  RecordProperty("max_rel_reflected", std::to_string(r.worst[2]));
}

// A steep north-facing slope: in winter the sun is behind its plane (Muneer's shadowed form, and
// r.sun's reflected term without the beam); in summer mornings it is lit from the north-east.
TEST(ClearSkyRsun, SteepNorthFacingMatchesGrassRsun) {
  if (!grass_installed()) GTEST_SKIP() << "GRASS GIS (`grass`, Debian grass-core) is not installed";
  const RsunComparison r = compare_with_rsun("15 172", "7 12", "3.5", "300", 0.3, 60.0, 0.0);
  EXPECT_EQ(r.cases, 2u * 2u * 2u);
  EXPECT_GT(r.sun_behind, 0) << "no case has the sun behind the surface any more";
}

}  // namespace
}  // namespace rayscan::analysis::clear_sky_test
