// ESRA clear-sky model as GRASS r.sun uses it (rsunlib.c's com_sol_const(), brad(), drad();
// main.c's joules2()); equations cited from Šúri & Hofierka 2004 (Transactions in GIS 8(2)),
// section 2, which restates ESRA (Rigollier et al. 2000, Solar Energy 68(1)) and Muneer (1990).
#include "rayscan/analysis/clear_sky.hpp"

#include "rayscan/analysis/angles.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace rayscan::analysis {
// Named (and anonymous inside) so that a unity build can merge this file with others.
namespace csky {
namespace {

constexpr double kPi = std::numbers::pi;

std::string format_value(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// One-line message: "<where>: <name> must be <expected>, got <value>".
[[noreturn]] void fail(const char* where, const char* name, const char* expected, double got) {
  throw std::invalid_argument(std::string(where) + ": " + name + " must be " + expected + ", got " +
                              format_value(got));
}

void require_range(const char* where, const char* name, double v, double lo, double hi,
                   const char* expected) {
  if (!(v >= lo && v <= hi)) fail(where, name, expected, v);
}

void require_finite(const char* where, const char* name, double v) {
  if (!std::isfinite(v)) fail(where, name, "a finite number", v);
}

void check_day(const char* where, int day_of_year) {
  if (day_of_year < 1 || day_of_year > 366)
    fail(where, "day_of_year", "in 1..366", static_cast<double>(day_of_year));
}

void check_linke(const char* where, double linke) {
  require_range(where, "linke", linke, 1.0, 10.0, "in 1..10 (Linke turbidity at air mass 2)");
}

void check_sun(const char* where, const SunDirection& sun) {
  require_range(where, "sun elevation", sun.elevation, -kPi / 2, kPi / 2, "in -pi/2..pi/2 radians");
  require_finite(where, "sun azimuth", sun.azimuth);
}

void check_surface(const char* where, const SurfaceOrientation& s) {
  require_range(where, "slope", s.slope, 0.0, kPi, "in 0..pi radians (0..180 degrees)");
  require_finite(where, "aspect", s.aspect);
}

// The caller's cos(incidence), or the one computed from the geometry; a value a rounding step
// outside -1..1 is clamped.
double incidence_or_computed(const char* where, const std::optional<double>& given,
                             const SunDirection& sun, const SurfaceOrientation& surface) {
  if (!given) return cos_incidence(sun, surface);
  require_range(where, "cos_incidence", *given, -1.0 - 1e-9, 1.0 + 1e-9, "in -1..1");
  return std::clamp(*given, -1.0, 1.0);
}

// Beam on the horizontal, B_hc = B_0c sin h0, and the beam normal B_0c (eqs. (3), (10)) for
// h0 > 0. r.sun's brad() multiplies by the sine of the TRUE elevation; the refracted one enters
// only the air mass.
struct Beam {
  double normal = 0.0, horizontal = 0.0;
};

Beam clear_sky_beam(double h0, double g0, double linke, double site_elevation_m) {
  const double m = relative_optical_air_mass(h0, site_elevation_m);
  const double normal = g0 * std::exp(-0.8662 * linke * m * rayleigh_optical_thickness(m));
  return {normal, normal * std::sin(h0)};
}

}  // namespace
}  // namespace csky

double extraterrestrial_irradiance(int day_of_year, double solar_constant) {
  constexpr const char* where = "extraterrestrial_irradiance";
  csky::check_day(where, day_of_year);
  if (!(solar_constant > 0.0) || !std::isfinite(solar_constant))
    csky::fail(where, "solar_constant", "a finite number > 0 W/m^2", solar_constant);
  // Extraterrestrial irradiance (r.sun com_sol_const()): day angle j' = 2 pi j / 365.25 and the
  // perihelion offset 0.048869 rad.
  const double day_angle = 2.0 * csky::kPi * day_of_year / 365.25;
  return solar_constant * (1.0 + 0.03344 * std::cos(day_angle - 0.048869));
}

double refraction_correction(double sun_elevation) {
  csky::require_range("refraction_correction", "sun_elevation", sun_elevation, 0.0, csky::kPi / 2,
                      "in 0..pi/2 radians");
  const double h = sun_elevation;
  // Refraction correction of the elevation (ESRA; r.sun brad()), h0 in radians.
  return 0.061359 * (0.1594 + h * (1.123 + 0.065656 * h)) / (1.0 + h * (28.9344 + 277.3971 * h));
}

double relative_optical_air_mass(double sun_elevation, double site_elevation_m) {
  constexpr const char* where = "relative_optical_air_mass";
  csky::require_range(where, "sun_elevation", sun_elevation, 0.0, csky::kPi / 2,
                      "in 0..pi/2 radians");
  csky::require_range(where, "site_elevation_m", site_elevation_m, -1000.0, 10000.0,
                      "in -1000..10000 m");
  // Station-height pressure correction p/p0 and the refraction-corrected elevation (ESRA; r.sun brad()).
  const double pressure_ratio = std::exp(-site_elevation_m / 8434.5);
  const double h_ref = sun_elevation + refraction_correction(sun_elevation);
  // Relative optical air mass: Kasten & Young (1989) with the elevation in degrees inside the power term.
  return pressure_ratio /
         (std::sin(h_ref) + 0.50572 * std::pow(h_ref * (1.0 / kDegree) + 6.07995, -1.6364));
}

double rayleigh_optical_thickness(double air_mass) {
  if (!(air_mass > 0.0) || !std::isfinite(air_mass))
    csky::fail("rayleigh_optical_thickness", "air_mass", "a finite number > 0", air_mass);
  const double m = air_mass;
  if (m <= 20.0)  // Rayleigh optical thickness, air mass <= 20 (ESRA)
    return 1.0 / (6.6296 + m * (1.7513 + m * (-0.1202 + m * (0.0065 - m * 0.00013))));
  return 1.0 / (10.4 + 0.718 * m);  // Rayleigh optical thickness, air mass > 20
}

double diffuse_transmission(double linke) {
  csky::check_linke("diffuse_transmission", linke);
  // Diffuse transmission function Trd (ESRA; r.sun drad()).
  return -0.015843 + linke * (0.030543 + 0.0003797 * linke);
}

DiffuseAngularCoefficients diffuse_angular_coefficients(double linke) {
  csky::check_linke("diffuse_angular_coefficients", linke);
  const double tn = diffuse_transmission(linke);
  DiffuseAngularCoefficients c;
  // Diffuse angular coefficient A1' and its lower bound A1 T_n >= 0.0022 (r.sun's drad() tests A1' * T_n).
  const double a1_prime = 0.26463 + linke * (-0.061581 + 0.0031408 * linke);
  c.a1 = a1_prime * tn < 0.0022 ? 0.0022 / tn : a1_prime;
  c.a2 = 2.04020 + linke * (0.018945 - 0.011161 * linke);   // diffuse angular function coefficient (ESRA)
  c.a3 = -1.3025 + linke * (0.039231 + 0.0085079 * linke);  // diffuse angular function coefficient (ESRA)
  return c;
}

double diffuse_angular_function(double sun_elevation, double linke) {
  csky::require_range("diffuse_angular_function", "sun_elevation", sun_elevation, 0.0,
                      csky::kPi / 2, "in 0..pi/2 radians");
  const DiffuseAngularCoefficients c = diffuse_angular_coefficients(linke);
  const double s = std::sin(sun_elevation);
  return c.a1 + s * (c.a2 + s * c.a3);  // diffuse angular function Fd (ESRA)
}

double cos_incidence(const SunDirection& sun, const SurfaceOrientation& surface) {
  constexpr const char* where = "cos_incidence";
  csky::check_sun(where, sun);
  csky::check_surface(where, surface);
  return std::sin(sun.elevation) * std::cos(surface.slope) +
         std::cos(sun.elevation) * std::sin(surface.slope) * std::cos(sun.azimuth - surface.aspect);
}

SurfaceOrientation orientation_from_normal(double east, double north, double up) {
  const double len = std::sqrt(east * east + north * north + up * up);
  if (!std::isfinite(len) || !(len > 0.0))
    throw std::invalid_argument(
        "orientation_from_normal: the normal must be a finite non-zero vector");
  const double horizontal = std::hypot(east, north);
  SurfaceOrientation s;
  s.slope = std::atan2(horizontal, up);  // 0..pi
  s.aspect = horizontal > 0.0 ? std::atan2(east, north) : csky::kPi;
  if (s.aspect < 0.0) s.aspect += 2.0 * csky::kPi;
  return s;
}

double grass_aspect_deg(double compass_aspect) {
  csky::require_finite("grass_aspect_deg", "compass_aspect", compass_aspect);
  // r.sun's main.c turns its input (counterclockwise from east) into compass degrees with
  // 90 - a (a < 90) or 450 - a; this is the inverse, kept in (0, 360].
  double a = std::fmod(90.0 - compass_aspect * (1.0 / kDegree), 360.0);
  if (a <= 0.0) a += 360.0;
  return a;
}

double muneer_diffuse_ratio(const SunDirection& sun, const SurfaceOrientation& surface,
                            double cos_inc, bool shadowed, double kb) {
  constexpr const char* where = "muneer_diffuse_ratio";
  csky::check_sun(where, sun);
  csky::check_surface(where, surface);
  csky::require_range(where, "cos_incidence", cos_inc, -1.0, 1.0, "in -1..1");
  csky::require_range(where, "kb", kb, 0.0, 1.0, "in 0..1");
  const MuneerSurfaceTerms t = muneer_surface_terms(surface);
  if (t.flat) return 1.0;                                                   // r.sun's "plane" branch: D_ic = D_hc
  if (shadowed || cos_inc <= 0.0) return t.r_sky + kMuneerShadowN * t.fg;  // eqs. (19), (22)
  if (!(sun.elevation > 0.0))
    csky::fail(where, "sun elevation", "> 0 for a sunlit surface", sun.elevation);
  const double f = (muneer_n(kb) * t.fg + t.r_sky) * (1.0 - kb);
  if (sun.elevation >= kLowSunElevation)
    return f + kb * cos_inc / std::sin(sun.elevation);  // Muneer's sky-diffuse function, sunlit surface (r.sun drad())
  // Muneer's sky-diffuse function for the low sun (r.sun drad()), with cos(A_LN) =
  // cos(A_sun - aspect) expanded (no wrapping of A_LN into -pi..pi as r.sun does is needed).
  const double cos_a_ln = std::cos(sun.azimuth) * t.cos_aspect + std::sin(sun.azimuth) * t.sin_aspect;
  return f + kb * t.sin_slope * cos_a_ln / (0.1 - 0.008 * sun.elevation);
}

MuneerSurfaceTerms muneer_surface_terms(const SurfaceOrientation& surface) {
  csky::check_surface("muneer_surface_terms", surface);
  MuneerSurfaceTerms t;
  const double beta = surface.slope;
  if (beta == 0.0) return t;
  t.flat = false;
  t.r_sky = (1.0 + std::cos(beta)) / 2.0;  // sky view of a tilted plane (r.sun drad())
  const double half_sin = std::sin(beta / 2.0);
  // Muneer's N function term (r.sun drad()).
  t.fg = std::sin(beta) - beta * std::cos(beta) - csky::kPi * half_sin * half_sin;
  t.sin_slope = std::sin(beta);
  t.cos_aspect = std::cos(surface.aspect);
  t.sin_aspect = std::sin(surface.aspect);
  return t;
}

double muneer_n(double kb) { return 0.00263 - kb * (0.712 + 0.6883 * kb); }

HorizontalIrradiance clear_sky_horizontal(double sun_elevation, int day_of_year, double linke,
                                          double site_elevation_m, double solar_constant) {
  constexpr const char* where = "clear_sky_horizontal";
  csky::require_range(where, "sun_elevation", sun_elevation, -csky::kPi / 2, csky::kPi / 2,
                      "in -pi/2..pi/2 radians");
  csky::check_linke(where, linke);
  csky::require_range(where, "site_elevation_m", site_elevation_m, -1000.0, 10000.0,
                      "in -1000..10000 m");
  const double g0 = extraterrestrial_irradiance(day_of_year, solar_constant);
  HorizontalIrradiance h;
  if (!(sun_elevation > 0.0)) return h;
  h.beam = csky::clear_sky_beam(sun_elevation, g0, linke, site_elevation_m).horizontal;
  h.diffuse = g0 * diffuse_transmission(linke) * diffuse_angular_function(sun_elevation, linke);
  h.global = h.beam + h.diffuse;
  return h;
}

SurfaceIrradiance clear_sky_irradiance(const ClearSkyInput& in) {
  constexpr const char* where = "clear_sky_irradiance";
  csky::check_sun(where, in.sun);
  csky::check_surface(where, in.surface);
  csky::check_linke(where, in.linke);
  csky::require_range(where, "albedo", in.albedo, 0.0, 1.0, "in 0..1");
  csky::require_range(where, "site_elevation_m", in.site_elevation_m, -1000.0, 10000.0,
                      "in -1000..10000 m");
  const double g0 = extraterrestrial_irradiance(in.day_of_year, in.solar_constant);
  const double cos_inc = csky::incidence_or_computed(where, in.cos_incidence, in.sun, in.surface);

  SurfaceIrradiance out;
  const double h0 = in.sun.elevation;
  if (!(h0 > 0.0)) return out;  // r.sun's joules2(): nothing while the sun is down

  const csky::Beam beam = csky::clear_sky_beam(h0, g0, in.linke, in.site_elevation_m);
  const double diffuse_h =
      g0 * diffuse_transmission(in.linke) * diffuse_angular_function(h0, in.linke);
  out.beam_normal = beam.normal;
  out.horizontal = {beam.horizontal, diffuse_h, beam.horizontal + diffuse_h};

  const bool shadowed = in.in_shadow || cos_inc <= 0.0;
  out.beam = shadowed ? 0.0 : beam.normal * cos_inc;  // beam on the inclined surface
  // Kb = B_hc / (G0 sin h0) = B_0c / G0, the beam's share (r.sun drad()), computed as r.sun does
  // from the beam.
  const double kb = std::clamp(beam.normal / g0, 0.0, 1.0);
  out.diffuse = diffuse_h * muneer_diffuse_ratio(in.sun, in.surface, cos_inc, shadowed, kb);
  const double ground =
      (shadowed && in.shadow_drops_reflected_beam) ? diffuse_h : out.horizontal.global;
  // Ground-reflected irradiance (r.sun drad()).
  out.reflected = in.albedo * ground * (1.0 - std::cos(in.surface.slope)) / 2.0;
  out.global = out.beam + out.diffuse + out.reflected;
  return out;
}

SurfaceIrradiance measured_irradiance_on_surface(const MeasuredInput& in) {
  constexpr const char* where = "measured_irradiance_on_surface";
  for (const auto& [name, v] :
       {std::pair{"ghi", in.ghi}, std::pair{"dni", in.dni}, std::pair{"dhi", in.dhi}})
    if (!(v >= 0.0) || !std::isfinite(v)) csky::fail(where, name, "a finite number >= 0 W/m^2", v);
  csky::check_sun(where, in.sun);
  csky::check_surface(where, in.surface);
  csky::require_range(where, "albedo", in.albedo, 0.0, 1.0, "in 0..1");
  const double g0 = extraterrestrial_irradiance(in.day_of_year, in.solar_constant);
  const double cos_inc = csky::incidence_or_computed(where, in.cos_incidence, in.sun, in.surface);

  SurfaceIrradiance out;
  const bool sun_up = in.sun.elevation > 0.0;
  out.beam_normal = in.dni;
  out.horizontal = {sun_up ? in.dni * std::sin(in.sun.elevation) : 0.0, in.dhi, in.ghi};
  const bool shadowed = in.in_shadow || cos_inc <= 0.0 || !sun_up;
  out.beam = shadowed ? 0.0 : in.dni * cos_inc;
  const double kb = std::clamp(in.dni / g0, 0.0, 1.0);
  out.diffuse = in.dhi * muneer_diffuse_ratio(in.sun, in.surface, cos_inc, shadowed, kb);
  out.reflected = in.albedo * in.ghi * (1.0 - std::cos(in.surface.slope)) / 2.0;
  out.global = out.beam + out.diffuse + out.reflected;
  return out;
}

}  // namespace rayscan::analysis
