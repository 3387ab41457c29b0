// Clear-sky irradiance: the ESRA model (C. Rigollier, O. Bauer, L. Wald, "On the clear sky model
// of the ESRA -- European Solar Radiation Atlas -- with respect to the Heliosat method", Solar
// Energy 68(1), 2000) in the form GRASS r.sun uses it (M. Šúri, J. Hofierka, "A new GIS-based
// solar radiation model and its application to photovoltaic assessments", Transactions in GIS
// 8(2), 2004, section 2), with the diffuse irradiance on inclined surfaces of T. Muneer (1990) as
// given there. Also the transposition of measured (weather-file) horizontal irradiance onto a
// tilted surface with the same diffuse and ground-reflected models.
//
// Each formula below is cited by the quantity ESRA and Šúri & Hofierka 2004 name and by the GRASS
// r.sun function that evaluates it (raster/r.sun/rsunlib.c: com_sol_const() the extraterrestrial
// irradiance, brad() the air mass and the beam, drad() the diffuse and Muneer's ratio); the
// formulas are checked against GRASS r.sun 8.2 (to 1e-6) by tests/analysis/test_clear_sky.cpp.
//
// Conventions used throughout:
//  * angles are in radians;
//  * sun elevation h0 is the true (geometric, unrefracted) elevation above the horizon -- r.sun's
//    solarAltitude. Refraction enters only through the air mass, as in ESRA and r.sun;
//  * azimuths (sun azimuth, surface aspect) are compass azimuths: clockwise from north, looking
//    down (N = 0, E = pi/2, S = pi, W = 3 pi/2). r.sun converts its aspect maps to this same
//    convention internally (see grass_aspect_deg below for its input convention);
//  * slope is the tilt of the surface from horizontal, 0..pi (pi/2 = vertical wall, > pi/2 =
//    overhanging, facing down); aspect is the compass azimuth of the direction the surface faces
//    (the horizontal projection of its outward normal, i.e. downslope);
//  * irradiances are in W/m^2.
#pragma once

#include <numbers>
#include <optional>

namespace rayscan::analysis {

/// Solar constant I0 = 1367 W/m^2 (Šúri & Hofierka 2004, the extraterrestrial irradiance; r.sun's
/// default solar_constant).
inline constexpr double kSolarConstant = 1367.0;

/// Sun elevation below which r.sun and Šúri & Hofierka use the low-sun form of the sunlit
/// inclined diffuse (Muneer's model; r.sun's drad()): 0.1 rad (5.7 degrees).
inline constexpr double kLowSunElevation = 0.1;

/// Direction of the sun as seen from the site.
struct SunDirection {
  double elevation = 0.0;  ///< true elevation h0 above the horizon, radians, -pi/2..pi/2
  double azimuth = 0.0;    ///< compass azimuth, radians (clockwise from north); any finite value
};

/// Orientation of a plane surface element.
struct SurfaceOrientation {
  double slope = 0.0;                ///< tilt from horizontal, radians, 0..pi
  double aspect = std::numbers::pi;  ///< compass azimuth the surface faces, radians; any finite
};

/// Horizontal-plane components (W/m^2).
struct HorizontalIrradiance {
  double beam = 0.0;     ///< beam (direct) on the horizontal plane, B_hc = B_0c sin h0
  double diffuse = 0.0;  ///< diffuse on the horizontal plane, D_hc
  double global = 0.0;   ///< beam + diffuse, G_hc
};

/// Components on a surface (W/m^2), plus the horizontal values they were derived from.
struct SurfaceIrradiance {
  double beam_normal = 0.0;  ///< beam on a plane normal to the sun, B_0c (not shadow-masked)
  double beam = 0.0;         ///< beam on the surface, B_ic = B_0c cos(incidence); 0 in shadow
  double diffuse = 0.0;      ///< sky diffuse on the surface, D_ic
  double reflected = 0.0;    ///< ground-reflected on the surface, R_i
  double global = 0.0;       ///< beam + diffuse + reflected
  HorizontalIrradiance horizontal;  ///< the horizontal-plane values used
};

/// Extraterrestrial irradiance normal to the sun, G0 = I0 * epsilon with the eccentricity
/// correction epsilon = 1 + 0.03344 cos(2 pi j / 365.25 - 0.048869) (Šúri & Hofierka 2004, the
/// extraterrestrial irradiance; GRASS r.sun's com_sol_const()). day_of_year j: 1..366.
/// solar_constant > 0. Throws std::invalid_argument for an argument out of range.
double extraterrestrial_irradiance(int day_of_year, double solar_constant = kSolarConstant);

/// Atmospheric refraction correction of the sun elevation, radians (ESRA and Šúri & Hofierka 2004,
/// the corrected solar altitude, after Kasten & Young 1989; r.sun's brad()): 0.061359 (0.1594 +
/// 1.123 h0 + 0.065656 h0^2) / (1 + 28.9344 h0 + 277.3971 h0^2), h0 in radians. sun_elevation:
/// 0..pi/2, else std::invalid_argument.
double refraction_correction(double sun_elevation);

/// Relative optical air mass, corrected for the site elevation (ESRA and Šúri & Hofierka 2004, the
/// relative optical air mass; Kasten & Young 1989; r.sun's brad()): m = (p/p0) / (sin h0ref +
/// 0.50572 (h0ref_deg + 6.07995)^-1.6364) with h0ref = h0 + refraction_correction(h0) and p/p0 =
/// exp(-z / 8434.5). sun_elevation: 0..pi/2 radians; site_elevation_m: -1000..10000 m. Throws
/// std::invalid_argument for an argument out of range.
double relative_optical_air_mass(double sun_elevation, double site_elevation_m);

/// Rayleigh optical thickness at air mass m (ESRA and Šúri & Hofierka 2004, after Kasten 1996;
/// r.sun's brad()):
/// 1 / (6.6296 + 1.7513 m - 0.1202 m^2 + 0.0065 m^3 - 0.00013 m^4) for m <= 20,
/// 1 / (10.4 + 0.718 m) for m > 20. air_mass: > 0 and finite, else std::invalid_argument.
double rayleigh_optical_thickness(double air_mass);

/// Diffuse transmission function at zenith, T_n(T_LK) = -0.015843 + 0.030543 T_LK +
/// 0.0003797 T_LK^2 (Šúri & Hofierka 2004's T_n, ESRA's T_rd; r.sun's drad()). linke: 1..10, else
/// std::invalid_argument (see clear_sky_horizontal for the range).
double diffuse_transmission(double linke);

/// Coefficients of the diffuse angular function F_d (ESRA and Šúri & Hofierka 2004; r.sun's
/// drad()):
/// A1' = 0.26463 - 0.061581 T_LK + 0.0031408 T_LK^2, A1 = 0.0022 / T_n when A1' T_n < 0.0022
/// (r.sun's drad() tests the same product), else A1 = A1'. Within 1..10 this bound acts for
/// turbid atmospheres, T_LK above about 5.8, where A1' falls towards and below 0 (it would also
/// act below T_LK 0.85, outside the accepted range);
/// A2 = 2.04020 + 0.018945 T_LK - 0.011161 T_LK^2; A3 = -1.3025 + 0.039231 T_LK +
/// 0.0085079 T_LK^2. linke: 1..10, else std::invalid_argument.
struct DiffuseAngularCoefficients {
  double a1 = 0.0, a2 = 0.0, a3 = 0.0;
};
DiffuseAngularCoefficients diffuse_angular_coefficients(double linke);

/// Diffuse angular function F_d(h0) = A1 + A2 sin h0 + A3 sin^2 h0 (ESRA and Šúri & Hofierka
/// 2004), with the true (unrefracted) elevation as r.sun's drad() uses it.
/// sun_elevation: 0..pi/2 radians; linke: 1..10. Throws std::invalid_argument.
double diffuse_angular_function(double sun_elevation, double linke);

/// Cosine of the angle between the sun direction and the surface normal, i.e. r.sun's
/// sin(delta_exp) (the sine of the sun's elevation above the surface plane):
/// sin h0 cos(slope) + cos h0 sin(slope) cos(sun azimuth - aspect). Negative when the sun is
/// behind the plane. Throws std::invalid_argument for a non-finite angle or slope outside 0..pi.
double cos_incidence(const SunDirection& sun, const SurfaceOrientation& surface);

/// Slope and aspect of a surface from its outward normal given in a local east-north-up frame
/// (any length > 0). A horizontal surface (normal straight up or down) gets aspect pi (south).
/// Throws std::invalid_argument for a zero or non-finite normal.
SurfaceOrientation orientation_from_normal(double east, double north, double up);

/// GRASS r.sun's aspect input convention (degrees counterclockwise from east: E = 0, N = 90,
/// W = 180, S = 270) from a compass aspect in radians. r.sun reads an aspect of exactly 0 as
/// "undefined" (its surface is then treated as horizontal), so east is returned as 360.
double grass_aspect_deg(double compass_aspect);

/// Muneer's (1990) ratio D_ic / D_hc of the sky diffuse on an inclined surface to the diffuse on
/// the horizontal, as r.sun's drad() evaluates it (Šúri & Hofierka 2004, the diffuse irradiance
/// on inclined surfaces):
///   shadowed (or sun behind the plane, cos_incidence <= 0): F = r_i + 0.252271 f_g;
///   sunlit, h0 >= 0.1 rad: F (1 - Kb) + Kb cos_incidence / sin h0;
///   sunlit, h0 <  0.1 rad: F (1 - Kb) + Kb sin(slope) cos(A_LN) / (0.1 - 0.008 h0),
/// with F = r_i + N f_g, N = 0.00263 - 0.712 Kb - 0.6883 Kb^2, r_i = (1 + cos slope) / 2,
/// f_g = sin(slope) - slope cos(slope) - pi sin^2(slope / 2) and A_LN = sun azimuth - aspect.
/// kb is the beam fraction B_hc / (G0 sin h0) in 0..1. Returns exactly 1 for slope 0.
/// Throws std::invalid_argument for arguments out of range (slope 0..pi, kb 0..1,
/// cos_incidence -1..1, finite angles; h0 > 0 when sunlit).
double muneer_diffuse_ratio(const SunDirection& sun, const SurfaceOrientation& surface,
                            double cos_incidence, bool shadowed, double kb);

/// Muneer's ratio split into the terms of the surface and of the sky, so that a sum over many
/// instants is a few products (the sun map of solar_irradiation.hpp):
///   shadowed: r_i + kMuneerShadowN f_g;
///   sunlit:   (r_i + N f_g)(1 - Kb) + Kb q, with q = cos_incidence / sin h0 (h0 >= 0.1 rad) or
///             sin(slope) (cos(sun azimuth) cos(aspect) + sin(sun azimuth) sin(aspect)) /
///             (0.1 - 0.008 h0) (the low sun),
/// and exactly 1 for a horizontal surface (`flat`). muneer_diffuse_ratio() evaluates the same.
struct MuneerSurfaceTerms {
  bool flat = true;          ///< slope 0: the ratio is 1
  double r_sky = 1.0;        ///< r_i = (1 + cos slope) / 2
  double fg = 0.0;           ///< f_g = sin slope - slope cos slope - pi sin^2(slope / 2)
  double sin_slope = 0.0;
  double cos_aspect = 0.0, sin_aspect = 0.0;  ///< of the compass aspect
};
/// N of a shadowed surface in Muneer's model (Šúri & Hofierka 2004; r.sun's drad()).
inline constexpr double kMuneerShadowN = 0.252271;
/// The surface's terms. Throws std::invalid_argument for a slope outside 0..pi or a non-finite
/// aspect.
MuneerSurfaceTerms muneer_surface_terms(const SurfaceOrientation& surface);
/// N of a sunlit surface, 0.00263 - 0.712 Kb - 0.6883 Kb^2 (Muneer's model as r.sun's drad());
/// kb in 0..1.
double muneer_n(double kb);

/// Clear-sky horizontal irradiance (ESRA and Šúri & Hofierka 2004, the beam and diffuse
/// components on a horizontal surface; r.sun's brad() and drad()):
/// B_0c = G0 exp(-0.8662 T_LK m delta_R(m)), B_hc = B_0c sin h0, D_hc = G0 T_n F_d, all 0 when
/// the sun is at or below the horizon (h0 <= 0, as r.sun).
/// sun_elevation: radians, -pi/2..pi/2. day_of_year: 1..366. linke: Linke turbidity factor at air
/// mass 2, 1..10 (1 is a clean dry atmosphere, the definition's lower bound; above ~7 is
/// extreme haze; T_n turns negative below 0.52). site_elevation_m: -1000..10000 m.
/// Throws std::invalid_argument (one line naming the parameter and its range).
HorizontalIrradiance clear_sky_horizontal(double sun_elevation, int day_of_year, double linke,
                                          double site_elevation_m,
                                          double solar_constant = kSolarConstant);

/// Inputs of clear_sky_irradiance().
struct ClearSkyInput {
  SunDirection sun;               ///< true elevation and compass azimuth, radians
  int day_of_year = 1;            ///< 1..366, for G0
  double linke = 3.0;             ///< Linke turbidity at air mass 2, 1..10
  double site_elevation_m = 0.0;  ///< -1000..10000 m above sea level
  SurfaceOrientation surface;     ///< slope 0..pi, compass aspect
  double albedo = 0.2;            ///< ground albedo rho_g, 0..1
  /// cos(incidence) on the surface (-1..1); when empty, cos_incidence(sun, surface).
  std::optional<double> cos_incidence;
  bool in_shadow = false;  ///< the beam is blocked (terrain, buildings, the point cloud)
  /// r.sun quirk (joules2() sets bh = 0 before drad()): when the surface is shadowed or faces
  /// away from the sun, the ground-reflected term uses D_hc instead of B_hc + D_hc. true matches
  /// r.sun; false uses G_hc always (the unobstructed foreground assumption).
  bool shadow_drops_reflected_beam = true;
  double solar_constant = kSolarConstant;  ///< I0, W/m^2, > 0
};

/// Clear-sky irradiance on a surface as r.sun's instantaneous mode computes it: beam B_ic = B_0c
/// cos(incidence) (0 when in_shadow or cos_incidence <= 0; Šúri & Hofierka 2004, the beam
/// irradiance on an inclined surface); diffuse D_hc * muneer_diffuse_ratio(...) with Kb = B_hc /
/// (G0 sin h0); ground-reflected R_i = rho_g G_hc (1 - cos slope) / 2 (Šúri & Hofierka 2004, the
/// ground-reflected irradiance; r.sun's drad(); see shadow_drops_reflected_beam). All components
/// are 0 when h0 <= 0. Throws std::invalid_argument (one line naming the parameter and its range).
SurfaceIrradiance clear_sky_irradiance(const ClearSkyInput& in);

/// Inputs of measured_irradiance_on_surface(): measured (e.g. EPW hourly mean) horizontal
/// components and the geometry at the representative instant.
struct MeasuredInput {
  double ghi = 0.0;  ///< global horizontal, W/m^2, >= 0
  double dni = 0.0;  ///< direct normal, W/m^2, >= 0
  double dhi = 0.0;  ///< diffuse horizontal, W/m^2, >= 0
  SunDirection sun;
  int day_of_year = 1;  ///< 1..366, for G0 in Kb
  SurfaceOrientation surface;
  double albedo = 0.2;                  ///< 0..1
  std::optional<double> cos_incidence;  ///< as in ClearSkyInput
  bool in_shadow = false;
  double solar_constant = kSolarConstant;
};

/// Transposes measured horizontal irradiance onto a surface: beam = DNI cos(incidence) (0 in
/// shadow, behind the plane, or with the sun at or below the horizon); diffuse = DHI *
/// muneer_diffuse_ratio(...) with Kb = DNI / G0 clamped to 0..1 (= B_h / (G0 sin h0), the
/// measured beam fraction), in its shadowed form when the sun is at or below the horizon;
/// reflected = albedo GHI (1 - cos slope) / 2. `horizontal` holds DNI sin h0, DHI and GHI as
/// given; beam_normal = DNI. Throws std::invalid_argument for negative or non-finite
/// irradiances or any geometry argument out of range.
SurfaceIrradiance measured_irradiance_on_surface(const MeasuredInput& in);

}  // namespace rayscan::analysis
