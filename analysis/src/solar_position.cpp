// NREL's Solar Position Algorithm, written from Reda & Andreas, NREL/TP-560-34302 (revised 2008).
// Section numbers (3.x, A.x) are the report's; the periodic terms are in spa_tables.hpp.
#include "rayscan/analysis/solar_position.hpp"

#include "rayscan/analysis/angles.hpp"

#include "spa_tables.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace rayscan::analysis {
namespace solar_detail {
namespace {

constexpr double kSecondsPerDay = 86400.0;
// Days from the Unix epoch (JD 2440587.5) to J2000.0 (JD 2451545.0).
constexpr double kUnixEpochToJ2000Days = 10957.5;
constexpr double kJ2000 = 2451545.0;
// The Sun's angular radius, with atmos_refract_deg it places the apparent horizon h0' (A.2).
constexpr double kSunRadiusDeg = 0.26667;

double radians(double deg) { return deg * kDegree; }
double degrees(double rad) { return rad / kDegree; }
double sind(double deg) { return std::sin(radians(deg)); }
double cosd(double deg) { return std::cos(radians(deg)); }

/// The angle reduced to 0 <= a < 360 (the report's "limit to 0..360").
double limit_360(double deg) {
  double r = std::fmod(deg, 360.0);
  if (r < 0.0) r += 360.0;
  return r >= 360.0 ? 0.0 : r;
}

/// The angle reduced to -180 <= a < 180.
double limit_180(double deg) { return limit_360(deg + 180.0) - 180.0; }

/// The value reduced into [lo, lo + 1) by whole units (A.2 limits day fractions this way).
double limit_unit(double x, double lo) { return x - std::floor(x - lo); }

std::string number(double v) {
  std::ostringstream s;
  s.precision(12);
  s << v;
  return s.str();
}

/// Throws unless lo <= value <= hi, with lo or hi itself excluded where the flags say so. `field`
/// names the value for the message ("SpaInput.latitude_deg").
void require_range(const std::string& field, double value, double lo, double hi,
                   bool lo_open = false, bool hi_open = false) {
  const bool ok = std::isfinite(value) && (lo_open ? value > lo : value >= lo) &&
                  (hi_open ? value < hi : value <= hi);
  if (ok) return;
  std::string message =
      field + ": " + number(value) + " is not in " + number(lo) + ".." + number(hi);
  if (lo_open && hi_open)
    message += " (" + number(lo) + " and " + number(hi) + " excluded)";
  else if (lo_open || hi_open)
    message += " (" + number(lo_open ? lo : hi) + " excluded)";
  throw std::invalid_argument(message);
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  const std::int64_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

/// The UTC calendar year of a Unix day number.
int civil_year(std::int64_t unix_day) {
  using namespace std::chrono;
  const year_month_day ymd{sys_days{days{unix_day}}};
  return static_cast<int>(ymd.year());
}

void validate(const SpaInput& in) {
  require_range("SpaInput.time.fraction", in.time.fraction, 0.0, 1.0, false, true);
  constexpr std::int64_t kFirst = -125281123200;  // -2000-01-01T00:00:00Z
  constexpr std::int64_t kEnd = 127206115200;     // 6001-01-01T00:00:00Z
  const std::int64_t s = in.time.unix_seconds;
  if (s < kFirst || s >= kEnd) {
    const std::int64_t day = floor_div(s, 86400);
    // Beyond a billion days the calendar conversion would overflow; the seconds say enough.
    const std::string when = std::abs(day) < 1000000000
                                 ? "year " + std::to_string(civil_year(day))
                                 : "unix time " + std::to_string(s) + " s";
    throw std::invalid_argument("SpaInput.time: " + when +
                                " is not in -2000..6000, the years SPA is valid for");
  }
  require_range("SpaInput.delta_t", in.delta_t, -8000.0, 8000.0);
  require_range("SpaInput.delta_ut1", in.delta_ut1, -1.0, 1.0, true, true);
  require_range("SpaInput.latitude_deg", in.latitude_deg, -90.0, 90.0);
  require_range("SpaInput.longitude_deg", in.longitude_deg, -180.0, 180.0);
  require_range("SpaInput.elevation_m", in.elevation_m, -6378140.0,
                std::numeric_limits<double>::infinity(), true);
  require_range("SpaInput.pressure_mbar", in.pressure_mbar, 0.0, 5000.0, true);
  require_range("SpaInput.temperature_c", in.temperature_c, -273.15, 6000.0, true);
  require_range("SpaInput.atmos_refract_deg", in.atmos_refract_deg, -5.0, 5.0);
  require_range("SpaInput.surface_slope_deg", in.surface_slope_deg, 0.0, 180.0);
  require_range("SpaInput.surface_azimuth_deg", in.surface_azimuth_deg, -360.0, 360.0);
}

/// Sum over the rows of one series of Table A4.2: sum of A cos(B + C JME) (eqs. 9-10).
double periodic_sum(std::span<const spa_tables::PeriodicTerm> terms, double jme) {
  double sum = 0.0;
  for (const auto& t : terms) sum += t.a * std::cos(t.b + t.c * jme);
  return sum;
}

/// (X0 + X1 JME + X2 JME^2 + ...) / 1e8 for the series X0, X1, ... of L, B or R (section 3.2).
template <std::size_t N>
double series_polynomial(const std::array<std::span<const spa_tables::PeriodicTerm>, N>& series,
                         double jme) {
  double sum = 0.0;
  for (std::size_t i = N; i-- > 0;) sum = sum * jme + periodic_sum(series[i], jme);
  return sum / 1e8;
}

/// The geocentric apparent Sun and sidereal time at one instant (sections 3.1-3.10, A.1).
struct Geocentric {
  double jd = 0.0;
  double jde = 0.0;
  double l_deg = 0.0;
  double b_deg = 0.0;
  double r_au = 0.0;
  double theta_deg = 0.0;
  double beta_deg = 0.0;
  double dpsi_deg = 0.0;
  double deps_deg = 0.0;
  double eps_deg = 0.0;
  double dtau_deg = 0.0;
  double lambda_deg = 0.0;
  double nu_deg = 0.0;
  double alpha_deg = 0.0;
  double delta_deg = 0.0;
  double eot_min = 0.0;
};

/// Nutation in longitude and obliquity, degrees (section 3.4, Table A4.3).
std::pair<double, double> nutation(double jce) {
  const double jce2 = jce * jce;
  const double jce3 = jce2 * jce;
  // X0..X4: mean elongation of the Moon from the Sun, mean anomalies of the Sun and the Moon, the
  // Moon's argument of latitude, longitude of the Moon's ascending node.
  const std::array<double, 5> x{
      297.85036 + 445267.111480 * jce - 0.0019142 * jce2 + jce3 / 189474.0,
      357.52772 + 35999.050340 * jce - 0.0001603 * jce2 - jce3 / 300000.0,
      134.96298 + 477198.867398 * jce + 0.0086972 * jce2 + jce3 / 56250.0,
      93.27191 + 483202.017538 * jce - 0.0036825 * jce2 + jce3 / 327270.0,
      125.04452 - 1934.136261 * jce + 0.0020708 * jce2 + jce3 / 450000.0,
  };
  double dpsi = 0.0;
  double deps = 0.0;
  for (const auto& t : spa_tables::kNutation) {
    double arg = 0.0;
    for (std::size_t j = 0; j < 5; ++j) arg += x[j] * t.y[j];
    dpsi += (t.a + t.b * jce) * sind(arg);
    deps += (t.c + t.d * jce) * cosd(arg);
  }
  // Units of 0.0001 arc second to degrees.
  return {dpsi / 36000000.0, deps / 36000000.0};
}

/// Mean obliquity of the ecliptic ε0 in arc seconds, U = JME / 10 (section 3.5).
double mean_obliquity_arcsec(double jme) {
  constexpr std::array<double, 11> c{84381.448, -4680.93, -1.55, 1999.25, -51.38, -249.67,
                                     -39.05,    7.12,     27.87, 5.79,    2.45};
  const double u = jme / 10.0;
  double sum = 0.0;
  for (std::size_t i = c.size(); i-- > 0;) sum = sum * u + c[i];
  return sum;
}

/// days_ut: UT1 days since J2000.0 (JD 2451545.0); delta_t: ΔT in seconds.
Geocentric geocentric_sun(double days_ut, double delta_t) {
  Geocentric g;
  // 3.1: Julian day, ephemeris day, centuries and millennium. The day count since J2000.0 is
  // carried instead of JD so that no precision goes into the 2.45e6 offset.
  const double days_tt = days_ut + delta_t / kSecondsPerDay;
  g.jd = kJ2000 + days_ut;
  g.jde = kJ2000 + days_tt;
  const double jc = days_ut / 36525.0;
  const double jce = days_tt / 36525.0;
  const double jme = jce / 10.0;

  // 3.2: the Earth's heliocentric longitude, latitude and radius vector.
  g.l_deg = limit_360(degrees(series_polynomial(spa_tables::kL, jme)));
  g.b_deg = degrees(series_polynomial(spa_tables::kB, jme));
  g.r_au = series_polynomial(spa_tables::kR, jme);

  // 3.3: geocentric longitude and latitude.
  g.theta_deg = limit_360(g.l_deg + 180.0);
  g.beta_deg = -g.b_deg;

  // 3.4-3.5: nutation and the true obliquity of the ecliptic.
  std::tie(g.dpsi_deg, g.deps_deg) = nutation(jce);
  g.eps_deg = mean_obliquity_arcsec(jme) / 3600.0 + g.deps_deg;

  // 3.6-3.7: aberration correction and apparent Sun longitude.
  g.dtau_deg = -20.4898 / (3600.0 * g.r_au);
  g.lambda_deg = g.theta_deg + g.dpsi_deg + g.dtau_deg;

  // 3.8: apparent sidereal time at Greenwich.
  const double nu0 = limit_360(280.46061837 + 360.98564736629 * days_ut + 0.000387933 * jc * jc -
                               jc * jc * jc / 38710000.0);
  g.nu_deg = nu0 + g.dpsi_deg * cosd(g.eps_deg);

  // 3.9-3.10: geocentric right ascension and declination.
  const double lam = radians(g.lambda_deg);
  const double eps = radians(g.eps_deg);
  const double beta = radians(g.beta_deg);
  g.alpha_deg = limit_360(degrees(
      std::atan2(std::sin(lam) * std::cos(eps) - std::tan(beta) * std::sin(eps), std::cos(lam))));
  g.delta_deg = degrees(
      std::asin(std::sin(beta) * std::cos(eps) + std::cos(beta) * std::sin(eps) * std::sin(lam)));

  // A.1: equation of time from the Sun's mean longitude M; minutes, wrapped to -12 h..12 h (the
  // report's +-20 minute limit does the same for real values).
  const double m = limit_360(280.4664567 + 360007.6982779 * jme + 0.03032028 * jme * jme +
                             std::pow(jme, 3) / 49931.0 - std::pow(jme, 4) / 15300.0 -
                             std::pow(jme, 5) / 2000000.0);
  g.eot_min = 4.0 * limit_180(m - 0.0057183 - g.alpha_deg + g.dpsi_deg * cosd(g.eps_deg));
  return g;
}

/// UT1 days since J2000.0 of the input's instant.
double days_ut_since_j2000(const SpaInput& in) {
  // Whole days and the remaining seconds apart, so that the sum keeps sub-millisecond precision.
  const std::int64_t day = floor_div(in.time.unix_seconds, 86400);
  const double seconds =
      static_cast<double>(in.time.unix_seconds - day * 86400) + in.time.fraction + in.delta_ut1;
  return (static_cast<double>(day) - kUnixEpochToJ2000Days) + seconds / kSecondsPerDay;
}

/// The observer's terms x = ρ cos φ' and y = ρ sin φ' of the parallax (section 3.12).
std::pair<double, double> parallax_terms(double latitude_deg, double elevation_m) {
  const double phi = radians(latitude_deg);
  const double u = std::atan(0.99664719 * std::tan(phi));
  const double h = elevation_m / 6378140.0;
  return {std::cos(u) + h * std::cos(phi), 0.99664719 * std::sin(u) + h * std::sin(phi)};
}

}  // namespace

/// solar_position(): sections 3.11-3.16 on the geocentric Sun of geocentric_sun().
SolarPosition compute_position(const SpaInput& in) {
  validate(in);
  const Geocentric g = geocentric_sun(days_ut_since_j2000(in), in.delta_t);
  SolarPosition p;
  p.julian_day = g.jd;
  p.julian_ephemeris_day = g.jde;
  p.heliocentric_longitude_deg = g.l_deg;
  p.heliocentric_latitude_deg = g.b_deg;
  p.earth_sun_distance_au = g.r_au;
  p.geocentric_longitude_deg = g.theta_deg;
  p.geocentric_latitude_deg = g.beta_deg;
  p.nutation_longitude_deg = g.dpsi_deg;
  p.nutation_obliquity_deg = g.deps_deg;
  p.true_obliquity_deg = g.eps_deg;
  p.aberration_deg = g.dtau_deg;
  p.apparent_longitude_deg = g.lambda_deg;
  p.greenwich_sidereal_time_deg = g.nu_deg;
  p.right_ascension_deg = g.alpha_deg;
  p.declination_deg = g.delta_deg;
  p.equation_of_time_min = g.eot_min;

  // 3.11: observer local hour angle.
  const double hour_angle = limit_360(g.nu_deg + in.longitude_deg - g.alpha_deg);
  p.hour_angle_deg = hour_angle;

  // 3.12-3.13: parallax in right ascension, topocentric right ascension, declination, hour angle.
  const double xi = radians(8.794 / (3600.0 * g.r_au));  // equatorial horizontal parallax
  const auto [x, y] = parallax_terms(in.latitude_deg, in.elevation_m);
  const double h = radians(hour_angle);
  const double delta = radians(g.delta_deg);
  const double denom = std::cos(delta) - x * std::sin(xi) * std::cos(h);
  const double dalpha = std::atan2(-x * std::sin(xi) * std::sin(h), denom);
  const double delta_topo =
      std::atan2((std::sin(delta) - y * std::sin(xi)) * std::cos(dalpha), denom);
  p.topocentric_right_ascension_deg = limit_360(g.alpha_deg + degrees(dalpha));
  p.topocentric_declination_deg = degrees(delta_topo);
  p.topocentric_hour_angle_deg = limit_360(hour_angle - degrees(dalpha));

  // 3.14: topocentric elevation and zenith. The refraction formula of 3.14.2 holds for a Sun above
  // the apparent horizon h0' and grows without bound below it, so a set Sun gets none.
  const double phi = radians(in.latitude_deg);
  const double h_topo = radians(p.topocentric_hour_angle_deg);
  const double e0 = degrees(std::asin(std::sin(phi) * std::sin(delta_topo) +
                                      std::cos(phi) * std::cos(delta_topo) * std::cos(h_topo)));
  double de = 0.0;
  if (in.refraction && e0 >= -(kSunRadiusDeg + in.atmos_refract_deg))
    de = (in.pressure_mbar / 1010.0) * (283.0 / (273.0 + in.temperature_c)) * 1.02 /
         (60.0 * std::tan(radians(e0 + 10.3 / (e0 + 5.11))));
  p.geometric_elevation_deg = e0;
  p.refraction_deg = de;
  p.elevation_deg = e0 + de;
  p.zenith_deg = 90.0 - p.elevation_deg;

  // 3.15: astronomers' azimuth Γ (westward from south), then Φ = Γ + 180 (eastward from north).
  const double gamma = degrees(std::atan2(
      std::sin(h_topo), std::cos(h_topo) * std::sin(phi) - std::tan(delta_topo) * std::cos(phi)));
  p.azimuth_deg = limit_360(gamma + 180.0);

  // 3.16: incidence on the surface. Γ - γ equals Φ - surface azimuth, both measured from north.
  const double zen = radians(p.zenith_deg);
  const double slope = radians(in.surface_slope_deg);
  p.incidence_deg = degrees(std::acos(
      std::clamp(std::cos(zen) * std::cos(slope) +
                     std::sin(slope) * std::sin(zen) * cosd(p.azimuth_deg - in.surface_azimuth_deg),
                 -1.0, 1.0)));
  return p;
}

namespace {

/// Interpolates a daily-tabulated angle at day fraction n from its values at days -1, 0, +1
/// (A.2, the interpolation of α and δ). The differences are taken modulo 360 so that a right
/// ascension passing 360 -> 0 between the tabulated days stays continuous.
double interpolate_daily(const std::array<double, 3>& v, double n) {
  const double a = limit_180(v[1] - v[0]);
  const double b = limit_180(v[2] - v[1]);
  const double c = b - a;
  return v[1] + n * (a + b + c * n) / 2.0;
}

}  // namespace

/// sun_rise_transit_set(): A.2 on the local day.
SunRiseTransitSet compute_rise_transit_set(const SpaInput& in,
                                           std::optional<double> utc_offset_hours) {
  validate(in);
  if (utc_offset_hours) require_range("utc_offset_hours", *utc_offset_hours, -18.0, 18.0);
  const double offset_s = utc_offset_hours.value_or(local_mean_time_offset(in.longitude_deg)) * 3600.0;

  // The local day: local midnight before the instant, in UTC and then UT1 unix seconds.
  const double local_s = static_cast<double>(in.time.unix_seconds) + in.time.fraction + offset_s;
  SunRiseTransitSet out;
  out.day_start_unix = std::floor(local_s / kSecondsPerDay) * kSecondsPerDay - offset_s;
  const double start_ut_days = (out.day_start_unix + in.delta_ut1) / kSecondsPerDay;
  // A.2 tabulates the Sun at 0 UT of a base day and limits the events' day fractions m to [0, 1);
  // here the base day is the one whose 0 UT is nearest the local day's start, and m is limited to
  // the local day, [w, w + 1) with |w| <= 0.5.
  const double base_day = std::floor(start_ut_days + 0.5);
  const double w = start_ut_days - base_day;
  const double base_j2000 = base_day - kUnixEpochToJ2000Days;

  // A.2: sidereal time at 0 UT, and the Sun at 0 TT (ΔT = 0) of days -1, 0, +1.
  const double nu = geocentric_sun(base_j2000, 0.0).nu_deg;
  std::array<double, 3> alpha{};
  std::array<double, 3> delta{};
  for (int k = 0; k < 3; ++k) {
    const Geocentric g = geocentric_sun(base_j2000 + (k - 1), 0.0);
    alpha[k] = g.alpha_deg;
    delta[k] = g.delta_deg;
  }
  const double sigma = in.longitude_deg;
  const double phi = radians(in.latitude_deg);
  const double h0 = -(kSunRadiusDeg + in.atmos_refract_deg);

  // A.2: approximate transit time m0, and the local hour angle H0 of rise and set.
  std::array<double, 3> m{};
  m[0] = limit_unit((alpha[1] - sigma - nu) / 360.0, w);
  const double arg = (sind(h0) - std::sin(phi) * sind(delta[1])) / (std::cos(phi) * cosd(delta[1]));
  if (arg < -1.0)
    out.kind = SunDayKind::polar_day;
  else if (arg > 1.0)
    out.kind = SunDayKind::polar_night;
  const double big_h0 = out.kind == SunDayKind::rises_and_sets ? degrees(std::acos(arg)) : 0.0;
  m[1] = limit_unit(m[0] - big_h0 / 360.0, w);
  m[2] = limit_unit(m[0] + big_h0 / 360.0, w);

  // A.2: sidereal time, interpolated Sun, local hour angle and elevation at day fraction m.
  struct SunAt {
    double hour_angle;  // -180..180
    double declination;
    double elevation;
  };
  const auto sun_at = [&](double mi) {
    const double nu_i = nu + 360.985647 * mi;
    const double n = mi + in.delta_t / kSecondsPerDay;
    SunAt s;
    s.declination = interpolate_daily(delta, n);
    s.hour_angle = limit_180(nu_i + sigma - interpolate_daily(alpha, n));
    s.elevation = degrees(std::asin(std::sin(phi) * sind(s.declination) +
                                    std::cos(phi) * cosd(s.declination) * cosd(s.hour_angle)));
    return s;
  };

  // A.2: transit, sunrise and sunset corrected from the interpolated positions. A.2 corrects rise
  // and set once, a Newton step on the elevation; one step leaves 10 s and more where the Sun meets
  // the horizon at a grazing angle (12 s at 69.6 N in May), so the step is repeated on the same
  // interpolated Sun until it moves the time by less than 1 ms. Should that not settle (the Sun
  // only touching the horizon), the report's single step stands.
  const auto to_unix = [&](double day_fraction) {
    return (base_day + day_fraction) * kSecondsPerDay - in.delta_ut1;
  };
  out.transit_unix = to_unix(m[0] - sun_at(m[0]).hour_angle / 360.0);
  if (out.kind == SunDayKind::rises_and_sets) {
    const auto step = [&](double mi) {
      const SunAt s = sun_at(mi);
      return (s.elevation - h0) /
             (360.0 * cosd(s.declination) * std::cos(phi) * sind(s.hour_angle));
    };
    const auto corrected = [&](double m_approx) {
      const double single = m_approx + step(m_approx);
      double mi = single;
      for (int i = 0; i < 20; ++i) {
        const double d = step(mi);
        if (!std::isfinite(d) || std::abs(mi + d - single) > 0.05) return single;
        mi += d;
        if (std::abs(d) < 1e-3 / kSecondsPerDay) return mi;
      }
      return single;
    };
    out.sunrise_unix = to_unix(corrected(m[1]));
    out.sunset_unix = to_unix(corrected(m[2]));
  }
  return out;
}

namespace {

constexpr const char* kIsoForm = "[-]YYYY-MM-DD[Thh:mm[:ss[.fff]]][Z|+hh:mm|-hh:mm]";

/// Reads an ISO 8601 date-time left to right; every failure names the whole text.
class IsoReader {
 public:
  explicit IsoReader(std::string_view text) : text_(text) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw std::invalid_argument("'" + std::string(text_) + "': " + what);
  }

  /// Fails at the current character: what was expected there, and the accepted form.
  [[noreturn]] void fail_here(const char* expected) const {
    const std::string found = done() ? std::string("the end") : "'" + std::string(1, peek()) + "'";
    fail("expected " + std::string(expected) + " at character " + std::to_string(pos_ + 1) +
         ", found " + found + " (form " + kIsoForm + ")");
  }

  bool done() const { return pos_ >= text_.size(); }
  char peek() const { return text_[pos_]; }
  bool eat(char c) {
    if (done() || peek() != c) return false;
    ++pos_;
    return true;
  }
  void expect(char c, const char* expected) {
    if (!eat(c)) fail_here(expected);
  }
  bool at_digit() const { return !done() && peek() >= '0' && peek() <= '9'; }

  /// Exactly n decimal digits.
  int digits(int n, const char* expected) {
    int v = 0;
    for (int i = 0; i < n; ++i) {
      if (!at_digit()) fail_here(expected);
      v = v * 10 + (text_[pos_++] - '0');
    }
    return v;
  }

  /// One or more digits after a decimal separator, as a fraction 0 <= f <= 1.
  double fraction() {
    const std::size_t begin = pos_;
    while (at_digit()) ++pos_;
    if (pos_ == begin) fail_here("a digit after the decimal separator");
    const std::string s = "0." + std::string(text_.substr(begin, pos_ - begin));
    double f = 0.0;
    std::from_chars(s.data(), s.data() + s.size(), f);
    return f;
  }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
};

void require_field(const IsoReader& r, const char* name, int value, int lo, int hi,
                   const std::string& note = {}) {
  if (value < lo || value > hi)
    r.fail(std::string(name) + " " + std::to_string(value) + " is not in " + std::to_string(lo) +
           ".." + std::to_string(hi) + note);
}

/// Reads the optional UTC offset (Z, +-hh, +-hhmm, +-hh:mm); returns it in seconds east of UTC,
/// nullopt at the end of the text (none written).
std::optional<int> read_offset_seconds(IsoReader& r) {
  if (r.done()) return std::nullopt;
  if (r.eat('Z') || r.eat('z')) return 0;
  const bool negative = r.eat('-');
  if (!negative && !r.eat('+')) r.fail_here("'Z', '+' or '-' (the UTC offset)");
  const int hh = r.digits(2, "the offset's hours (2 digits)");
  int mm = 0;
  if (r.eat(':') || r.at_digit()) mm = r.digits(2, "the offset's minutes (2 digits)");
  require_field(r, "offset minute", mm, 0, 59);
  const int total = hh * 60 + mm;
  if (total > 18 * 60)
    r.fail("UTC offset " + std::string(negative ? "-" : "+") + std::to_string(hh) + ":" +
           (mm < 10 ? "0" : "") + std::to_string(mm) + " is not in -18:00..+18:00");
  return (negative ? -total : total) * 60;
}

}  // namespace

/// parse_iso8601().
Iso8601Time parse_iso8601(std::string_view text) {
  using namespace std::chrono;
  IsoReader r(text);
  const bool negative_year = r.eat('-');
  if (!negative_year) r.eat('+');
  const int year_abs = r.digits(4, "the year (4 digits)");
  const int year_value = negative_year ? -year_abs : year_abs;
  r.expect('-', "'-' after the year");
  const int month_value = r.digits(2, "the month (2 digits)");
  r.expect('-', "'-' after the month");
  const int day_value = r.digits(2, "the day (2 digits)");
  require_field(r, "month", month_value, 1, 12);
  const year_month_day_last last{year{year_value} / month{static_cast<unsigned>(month_value)} /
                                 std::chrono::last};
  const int last_day = static_cast<int>(static_cast<unsigned>(last.day()));
  require_field(r, "day", day_value, 1, last_day,
                " (" + std::to_string(year_value) + "-" + (month_value < 10 ? "0" : "") +
                    std::to_string(month_value) + ")");

  int hour = 0, minute = 0, second = 0;
  double frac = 0.0;
  Iso8601Time out;
  out.date_only = r.done();
  if (!out.date_only) {
    if (!r.eat('T') && !r.eat('t') && !r.eat(' ')) r.fail_here("'T' or ' ' before the time");
    hour = r.digits(2, "the hour (2 digits)");
    r.expect(':', "':' after the hour");
    minute = r.digits(2, "the minute (2 digits)");
    if (r.eat(':')) {
      second = r.digits(2, "the second (2 digits)");
      if (r.eat('.') || r.eat(',')) frac = r.fraction();
    }
    require_field(r, "hour", hour, 0, 24);
    require_field(r, "minute", minute, 0, 59);
    require_field(r, "second", second, 0, 60);
    if (hour == 24 && (minute != 0 || second != 0 || frac != 0.0))
      r.fail("hour 24 is only allowed as 24:00:00 (the end of the day)");
  }
  out.offset_seconds = read_offset_seconds(r);
  if (!r.done()) r.fail_here("the end of the text");

  const sys_days date{year{year_value} / month{static_cast<unsigned>(month_value)} /
                      day{static_cast<unsigned>(day_value)}};
  UtcInstant& t = out.clock;
  t.unix_seconds = static_cast<std::int64_t>(date.time_since_epoch().count()) * 86400 +
                   hour * 3600 + minute * 60 + second;
  t.fraction = frac;
  if (t.fraction >= 1.0) {  // ".9999999999999999999" rounds up to a whole second
    t.fraction = 0.0;
    ++t.unix_seconds;
  }
  return out;
}

}  // namespace solar_detail

SolarPosition solar_position(const SpaInput& input) { return solar_detail::compute_position(input); }

double local_mean_time_offset(double longitude_deg) { return std::round(longitude_deg * 4.0) / 60.0; }

SunRiseTransitSet sun_rise_transit_set(const SpaInput& input,
                                       std::optional<double> utc_offset_hours) {
  return solar_detail::compute_rise_transit_set(input, utc_offset_hours);
}

Iso8601Time parse_iso8601(std::string_view text) { return solar_detail::parse_iso8601(text); }

UtcInstant parse_iso8601_utc(std::string_view text) {
  Iso8601Time t = solar_detail::parse_iso8601(text);
  t.clock.unix_seconds -= t.offset_seconds.value_or(0);
  return t.clock;
}

}  // namespace rayscan::analysis
