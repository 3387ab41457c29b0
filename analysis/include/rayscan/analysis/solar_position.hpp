// Position of the Sun seen from a point on the Earth, and the day's sunrise, transit and sunset:
// NREL's Solar Position Algorithm (SPA), for sun and shadow analysis of point clouds.
//
// Source: I. Reda, A. Andreas, "Solar position algorithm for solar radiation applications",
// Solar Energy 76(5), 577-589, 2004; NREL/TP-560-34302 (revised 2008). Uncertainty +-0.0003 degrees
// for the years -2000..6000. Section numbers in the comments (3.x, A.x) are the report's.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace rayscan::analysis {

/// An instant in UTC on the POSIX scale (every day has 86400 s, so a leap second has no number of
/// its own). Dates are proleptic Gregorian (ISO 8601) at all times, whereas the report's Julian
/// day formula (3.1) reads dates before 1582-10-15 in the Julian calendar.
struct UtcInstant {
  std::int64_t unix_seconds = 0;  ///< whole seconds since 1970-01-01T00:00:00Z, rounded down
  double fraction = 0.0;          ///< fraction of that second, 0 <= fraction < 1
};

/// An ISO 8601 date-time as written (parse_iso8601): its wall clock and, apart, the UTC offset the
/// text names, so that a caller can read a text without one in a time zone of its choosing.
struct Iso8601Time {
  /// The date and time of day as written, taken as if at UTC: no offset applied.
  UtcInstant clock;
  /// The offset the text names, seconds east of UTC ('Z' = 0); nullopt when it names none.
  std::optional<int> offset_seconds;
  bool date_only = false;  ///< a date alone, no time of day (never with an offset)
};

/// Parses an ISO 8601 date-time:
///   "2026-06-21T12:00:00Z", "2026-06-21T12:00+02:00", "2026-06-21 12:00:00.25", "2026-06-21".
/// Forms: [-]YYYY-MM-DD, optionally followed by 'T' or ' ' and hh:mm[:ss[.fff]] ('.' or ',' before
/// any number of fraction digits), optionally followed by 'Z' or an offset +-hh[:mm] / +-hhmm
/// (|offset| <= 18 h). 24:00 is the next day's 00:00; second 60 (a leap second) reads as the next
/// day's first second, as POSIX time has it. Years are astronomical (0 = 1 BC).
/// Throws std::invalid_argument with one line naming the text and what was expected, e.g.
/// "'2026-13-01': month 13 is not in 1..12".
Iso8601Time parse_iso8601(std::string_view text);

/// parse_iso8601()'s instant in UTC, a text without an offset read as UTC, not local time: a point
/// cloud has no time zone of its own, and a machine's zone must not change a result. A date alone
/// is its 00:00 UTC. Throws as parse_iso8601().
UtcInstant parse_iso8601_utc(std::string_view text);

/// Default ΔT = TT - UT1 in seconds: 32.184 s (TT - TAI) + 37 s (TAI - UTC, unchanged since
/// 2017-01-01), i.e. exact for UTC instants since 2017 when delta_ut1 = 0. For other epochs pass
/// the observed or predicted ΔT (IERS Bulletin A, or Espenak & Meeus's polynomials for the past);
/// an error of 1 s in ΔT moves the Sun by about 0.00001 degrees.
inline constexpr double kDefaultDeltaT = 69.184;

/// The inputs of SPA (section 3 of the report). Angles in degrees, WGS 84 coordinates.
struct SpaInput {
  UtcInstant time;                  ///< the instant, UTC (years -2000..6000)
  double delta_t = kDefaultDeltaT;  ///< ΔT = TT - UT1 in seconds, |ΔT| <= 8000 (section 2)
  double delta_ut1 = 0.0;           ///< ΔUT1 = UT1 - UTC in seconds, -1 < ΔUT1 < 1 (Bulletin A)
  double latitude_deg = 0.0;        ///< geodetic latitude, north positive, -90..90
  double longitude_deg = 0.0;       ///< longitude, east positive, -180..180
  /// Height above the ellipsoid in metres, > -6378140 (the report's Earth radius).
  double elevation_m = 0.0;
  /// Annual mean local pressure in millibars, for refraction, 0 < p <= 5000.
  double pressure_mbar = 1013.25;
  /// Annual mean local temperature in degrees Celsius, for refraction, -273.15 < T <= 6000.
  double temperature_c = 15.0;
  /// Atmospheric refraction at sunrise and sunset, |value| <= 5; with the Sun's radius 0.26667 it
  /// sets the apparent horizon h0' = -(0.26667 + atmos_refract_deg) = -0.8334 by default (A.2).
  double atmos_refract_deg = 0.5667;
  double surface_slope_deg = 0.0;  ///< tilt of the surface from horizontal, 0..180 (section 3.16)
  /// Direction the surface faces (the horizontal projection of its normal), clockwise from north,
  /// -360..360; 180 = facing south. The report's γ is measured from south, westward positive:
  /// γ = surface_azimuth_deg - 180.
  double surface_azimuth_deg = 180.0;
  /// Whether zenith, elevation and incidence include the refraction correction Δe (section 3.14);
  /// false gives the topocentric geometric (airless) position.
  bool refraction = true;
};

/// The Sun at SpaInput's instant: the outputs and main intermediate values of SPA (section 3).
/// Angles in degrees; "geocentric" values are at the Earth's centre, "topocentric" ones at the
/// observer (parallax applied). Right ascensions and hour angles are 0..360.
struct SolarPosition {
  double julian_day = 0.0;                       ///< JD (UT1), section 3.1
  double julian_ephemeris_day = 0.0;             ///< JDE (TT) = JD + ΔT/86400, section 3.1
  double heliocentric_longitude_deg = 0.0;       ///< L of the Earth, 0..360 (section 3.2)
  double heliocentric_latitude_deg = 0.0;        ///< B of the Earth (section 3.2)
  double earth_sun_distance_au = 0.0;            ///< R, astronomical units (section 3.2)
  double geocentric_longitude_deg = 0.0;         ///< Θ = L + 180, 0..360 (section 3.3)
  double geocentric_latitude_deg = 0.0;          ///< β = -B (section 3.3)
  double nutation_longitude_deg = 0.0;           ///< Δψ (section 3.4)
  double nutation_obliquity_deg = 0.0;           ///< Δε (section 3.4)
  double true_obliquity_deg = 0.0;               ///< ε (section 3.5)
  double aberration_deg = 0.0;                   ///< Δτ (section 3.6)
  double apparent_longitude_deg = 0.0;           ///< λ (section 3.7)
  double greenwich_sidereal_time_deg = 0.0;      ///< ν, apparent (section 3.8)
  double right_ascension_deg = 0.0;              ///< α, geocentric (section 3.9)
  double declination_deg = 0.0;                  ///< δ, geocentric (section 3.10)
  double hour_angle_deg = 0.0;                   ///< H, observer's, geocentric Sun (section 3.11)
  double topocentric_right_ascension_deg = 0.0;  ///< α' (section 3.12)
  double topocentric_declination_deg = 0.0;      ///< δ' (section 3.12)
  double topocentric_hour_angle_deg = 0.0;       ///< H' (section 3.13)
  double geometric_elevation_deg = 0.0;  ///< e0, topocentric, without refraction (section 3.14)
  double refraction_deg = 0.0;           ///< Δe; 0 when refraction is off or the Sun is down
  double elevation_deg = 0.0;            ///< e = e0 + Δe = 90 - zenith_deg
  double zenith_deg = 0.0;               ///< θ, topocentric (section 3.14)
  double azimuth_deg = 0.0;              ///< Φ, clockwise from north, 0..360 (section 3.15)
  double incidence_deg = 0.0;  ///< I, between the Sun and the surface's normal (section 3.16)
  double equation_of_time_min = 0.0;  ///< E, apparent minus mean solar time, minutes (A.1)
};

/// Computes the Sun's position for `input` (sections 3.1-3.16 and A.1).
/// Throws std::invalid_argument naming the first field out of range, e.g.
/// "SpaInput.latitude_deg: 95 is not in -90..90".
SolarPosition solar_position(const SpaInput& input);

/// Whether the Sun crosses the apparent horizon h0' on the day (A.2).
enum class SunDayKind {
  rises_and_sets,
  polar_day,    ///< above h0' all day: no sunrise or sunset
  polar_night,  ///< below h0' all day: no sunrise or sunset
};

/// Sun transit, sunrise and sunset of one day (A.2). Times are UTC unix seconds (fractional).
struct SunRiseTransitSet {
  double day_start_unix = 0.0;  ///< the day searched is [day_start_unix, day_start_unix + 86400)
  double transit_unix = 0.0;    ///< the Sun's local hour angle is 0 (it culminates)
  std::optional<double> sunrise_unix;  ///< the Sun's upper limb rises through h0'; none when polar
  std::optional<double> sunset_unix;   ///< the Sun's upper limb sets through h0'; none when polar
  SunDayKind kind = SunDayKind::rises_and_sets;
};

/// Local mean solar time as a time zone, hours east of UTC: longitude / 15, rounded to whole
/// minutes (123.07 W: -8:12, where the mean time itself is -8:12:16.8). ISO 8601 and RFC 3339
/// write an offset in whole minutes, so a time in this zone is written exactly with its offset,
/// and local midnight, the clock and the offset agree; the rounding moves midnight by at most 30 s.
double local_mean_time_offset(double longitude_deg);

/// Sun transit, sunrise and sunset (A.2) of the local day that contains input.time: the calendar
/// day in the time zone UTC + utc_offset_hours (|offset| <= 18), from local midnight to the next.
/// Without an offset the day is local mean solar time (local_mean_time_offset), so that noon
/// falls near the middle of the day wherever the cloud is. With utc_offset_hours = 0 the day is
/// the UTC day, which is the report's own convention (A.2 works from 0 UT). Each event is found
/// once, within that day: a sunset just after local midnight is the previous evening's. As in A.2
/// the Sun is geocentric (no parallax) and refraction is atmos_refract_deg's, not the
/// pressure/temperature formula's. Rise and set repeat A.2's final correction until it settles,
/// where the report applies it once (which is 10 s and more off at grazing angles).
/// Throws std::invalid_argument as solar_position() does, or for an offset out of range.
SunRiseTransitSet sun_rise_transit_set(const SpaInput& input,
                                       std::optional<double> utc_offset_hours = std::nullopt);

}  // namespace rayscan::analysis
