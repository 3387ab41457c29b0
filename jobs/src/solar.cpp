// The solar jobs (rayscan/jobs/solar.hpp): what `rayscan solar position`, `rayscan solar` and
// rayscan.solar() run.
#include "rayscan/jobs/solar.hpp"

#include "cloud_site.hpp"

#include "rayscan/analysis/clear_sky.hpp"
#include "rayscan/analysis/epw.hpp"
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/raster_preview.hpp"
#include "rayscan/analysis/solar_irradiation.hpp"
#include "rayscan/analysis/visibility.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/io/crs.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string_view>

namespace rayscan::jobs {

using namespace rayscan::analysis;

namespace {

double unix_of(const UtcInstant& t) { return double(t.unix_seconds) + t.fraction; }

UtcInstant instant_of(double unix_seconds) {
  const double whole = std::floor(unix_seconds);
  return {static_cast<std::int64_t>(whole), unix_seconds - whole};
}

/// The time zones of a time option written without an offset. With --utc-offset (`utc_offset`,
/// hours east of UTC) every such text is that zone's clock, as a planner's local standard time
/// (PVGIS, pvlib). Without it a date-time is UTC (a cloud has no time zone, and the machine's must
/// not change a result) and a date alone is midnight in local mean solar time
/// (local_mean_time_offset: longitude / 15 h to the minute).
struct LocalZone {
  std::optional<double> utc_offset;
  double longitude_deg = 0.0;
};

/// A time option read by option_time().
struct OptionTime {
  double unix_seconds = 0.0;               ///< the instant, UTC
  std::optional<double> written_offset;    ///< the offset the text names, hours east of UTC
  bool date_only = false;                  ///< a date alone
};

/// `field`'s ISO 8601 text as a UTC instant: a text naming its offset ('Z', +hh:mm) is exactly
/// that instant; one without is read in `zone` (LocalZone). A date alone is its midnight there
/// and, for the end of a period (`end_of_day`), the next midnight: the day is included whole.
/// Throws OptionError naming the field for text that is not ISO 8601.
OptionTime option_time(const char* field, const std::string& text, const LocalZone& zone, bool end_of_day) {
  Iso8601Time t;
  try {
    t = parse_iso8601(text);
  } catch (const std::invalid_argument& e) {
    throw OptionError({option(field), std::string(" ") + e.what()});
  }
  OptionTime out;
  out.date_only = t.date_only;
  double offset_hours = 0.0;
  if (t.offset_seconds) {
    out.written_offset = *t.offset_seconds / 3600.0;
    offset_hours = *out.written_offset;
  } else {
    offset_hours = zone.utc_offset.value_or(t.date_only ? local_mean_time_offset(zone.longitude_deg) : 0.0);
  }
  out.unix_seconds = unix_of(t.clock) - offset_hours * 3600.0 + (t.date_only && end_of_day ? 86400.0 : 0.0);
  return out;
}

/// SPA's input errors ("SpaInput.pressure_mbar: ...") with the job's field names; SpaInput.time
/// becomes `time_field`, the time option the instant came from.
OptionError spa_error(const std::invalid_argument& e, const char* time_field) {
  static const std::pair<const char*, const char*> names[] = {
      {"SpaInput.latitude_deg", "latitude"},   {"SpaInput.longitude_deg", "longitude"},
      {"SpaInput.elevation_m", "elevation"},   {"SpaInput.pressure_mbar", "pressure"},
      {"SpaInput.temperature_c", "temperature"}, {"SpaInput.delta_t", "delta_t"},
      {"SpaInput.surface_slope_deg", "slope"}, {"SpaInput.surface_azimuth_deg", "surface_azimuth"}};
  const std::string what = e.what();
  for (const auto& [spa, field] : names)
    if (what.rfind(spa, 0) == 0) return OptionError({option(field), what.substr(std::strlen(spa))});
  constexpr std::string_view kTime = "SpaInput.time:";
  if (what.rfind(kTime, 0) == 0) return OptionError({option(time_field), what.substr(kTime.size() - 1)});
  return OptionError({what});
}

/// Refuses a `utc_offset` outside -18..18 h or not a whole number of minutes: ISO 8601 writes an
/// offset in whole minutes, and every time the jobs state is written with it.
void check_utc_offset(const std::optional<double>& hours) {
  if (!hours) return;
  const double minutes = *hours * 60.0;
  if (!(std::abs(*hours) <= 18.0) || std::abs(minutes - std::round(minutes)) > 1e-9)
    throw OptionError({option("utc_offset"), ": expected hours east of UTC in -18..18, in whole minutes (e.g. -7, "
                                             "5.5, 5.75)"});
}

/// "30min", "1h", "2 h", "1d" -> seconds; `name`: the option it came from, for the error.
double parse_step(const std::string& text, const char* name = "step") {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  unit.erase(0, unit.find_first_not_of(' '));
  double scale = 0.0;
  if (unit == "min" || unit == "m") scale = 60.0;
  else if (unit == "h") scale = 3600.0;
  else if (unit == "d") scale = 86400.0;
  if (used == 0 || scale == 0.0 || !(v > 0.0) || !std::isfinite(v) || v * scale < 60.0)
    throw OptionError({option(name), " '" + text + "': expected a duration of at least 1 min, e.g. 30min, 1h or 1d"});
  return v * scale;
}

/// The instants of a day of shadows (--day, --every `every` seconds), in seconds after the day's
/// midnight: 0, every, 2 x every, ... before the next midnight. A day is a date alone (never with
/// an offset), so it starts at midnight of its own clock: these are also the frames' clock times.
std::vector<double> day_instants(double every) {
  std::vector<double> out;
  for (double k = 0.0; k * every < 86400.0 - 1e-6; k += 1.0) out.push_back(k * every);
  return out;
}

/// The map of a day of shadows `since_midnight` seconds into the day (day_instants): the raster's
/// name with the clock's hours and minutes, `maps/site.tif` -> `maps/site_0830.tif`. The one rule
/// for the check before the work and the write after it.
std::filesystem::path day_frame_path(const std::filesystem::path& raster, double since_midnight) {
  const std::string clock = format_iso8601(since_midnight, 0.0);  // 1970-01-01Thh:mm:ssZ
  const std::size_t t = clock.find('T') + 1;
  return std::filesystem::path(raster).replace_extension().string() + "_" + clock.substr(t, 2) +
         clock.substr(t + 3, 2) + ".tif";
}

/// The longest integration step: the sun is sampled once per step, at its middle, and the step's
/// irradiation is that sample times the step's length. Over an hour the sun moves 15 degrees and
/// the midpoint rule stays within a few percent of the day's total; a day-long step samples solar
/// noon only (three times the day's irradiation, 24 sun hours).
constexpr double kMaxIntegrationStep = 3600.0;

/// --step as an integration step (parse_step, at most kMaxIntegrationStep).
double parse_integration_step(const std::string& text) {
  const double step = parse_step(text);
  if (step > kMaxIntegrationStep)
    throw OptionError({option("step"), " '" + text + "': the sun is sampled once per step, at its middle, so a "
                       "step longer than 1h misweights the day; expected at most 1h (e.g. 15min, 30min, 1h)"});
  return step;
}

/// The UTC calendar day of a unix time.
std::chrono::sys_days day_of(double unix_seconds) {
  return std::chrono::floor<std::chrono::days>(
      std::chrono::sys_seconds(std::chrono::seconds(static_cast<std::int64_t>(std::floor(unix_seconds)))));
}

int day_of_year(double unix_seconds) {
  const std::chrono::sys_days days = day_of(unix_seconds);
  const std::chrono::year_month_day ymd(days);
  return (days - std::chrono::sys_days(ymd.year() / std::chrono::January / 1)).count() + 1;
}

/// The month of a unix time, 1..12.
int month_of(double unix_seconds) {
  return static_cast<int>(static_cast<unsigned>(std::chrono::year_month_day(day_of(unix_seconds)).month()));
}

}  // namespace

std::string format_iso8601(double unix_seconds, double utc_offset_hours) {
  // An offset ISO 8601 cannot write (not whole minutes) would make the text name another instant.
  const double minutes = utc_offset_hours * 60.0;
  const long off_min = std::abs(minutes - std::round(minutes)) <= 1e-9 ? std::lround(minutes) : 0;
  const auto local = static_cast<std::int64_t>(std::llround(unix_seconds)) + std::int64_t{off_min} * 60;
  const auto tp = std::chrono::sys_seconds(std::chrono::seconds(local));
  const auto day = std::chrono::floor<std::chrono::days>(tp);
  const std::chrono::year_month_day ymd(day);
  const std::chrono::hh_mm_ss hms(tp - day);
  char buf[64];
  // ISO 8601 writes a year before 1 AD as a sign and four digits (-0001); %04d would give -001.
  const int year = int(ymd.year());
  const char* sign = year < 0 ? "-" : "";
  if (off_min == 0)
    std::snprintf(buf, sizeof buf, "%s%04d-%02u-%02uT%02d:%02d:%02dZ", sign, std::abs(year), unsigned(ymd.month()),
                  unsigned(ymd.day()), int(hms.hours().count()), int(hms.minutes().count()),
                  int(hms.seconds().count()));
  else
    std::snprintf(buf, sizeof buf, "%s%04d-%02u-%02uT%02d:%02d:%02d%c%02ld:%02ld", sign, std::abs(year),
                  unsigned(ymd.month()), unsigned(ymd.day()), int(hms.hours().count()), int(hms.minutes().count()),
                  int(hms.seconds().count()), off_min < 0 ? '-' : '+', std::labs(off_min) / 60,
                  std::labs(off_min) % 60);
  return buf;
}

std::string format_time_label(double unix_seconds, double utc_offset_hours) {
  const std::string iso = format_iso8601(unix_seconds, utc_offset_hours);
  const std::size_t t = iso.find('T');  // YYYY-MM-DDThh:mm:ss, then Z or +hh:mm
  std::string label = iso.substr(0, t) + " " + iso.substr(t + 1, 5);
  if (iso.compare(t + 7, 2, "00") != 0) label += iso.substr(t + 6, 3);
  return label + " UTC" + (iso.back() == 'Z' ? std::string() : iso.substr(t + 9));
}

SunPositionJobResult run_sun_position(const SunPositionJobOptions& o) {
  SunPositionJobResult r;
  check_utc_offset(o.utc_offset);
  // Read as `rayscan solar` reads its times (option_time): a date alone is that day's midnight in
  // the day's time zone, not UTC midnight, which west of Greenwich is the evening before.
  const OptionTime time = option_time("time", o.time, {o.utc_offset, o.longitude}, false);
  r.time = instant_of(time.unix_seconds);
  r.time_utc_offset = o.utc_offset.value_or(time.written_offset.value_or(0.0));
  SpaInput in;
  in.time = r.time;
  in.latitude_deg = o.latitude;
  in.longitude_deg = o.longitude;
  in.elevation_m = o.elevation;
  in.pressure_mbar = o.pressure;
  in.temperature_c = o.temperature;
  in.delta_t = o.delta_t;
  in.surface_slope_deg = o.slope;
  in.surface_azimuth_deg = o.surface_azimuth;
  // The day's time zone: the one asked for, else the offset written in the time, else local mean
  // solar time.
  const std::optional<double> offset = o.utc_offset ? o.utc_offset : time.written_offset;
  try {
    r.position = solar_position(in);
    r.day = sun_rise_transit_set(in, offset);
  } catch (const std::invalid_argument& e) {
    throw spa_error(e, "time");
  }
  r.day_utc_offset = offset.value_or(local_mean_time_offset(o.longitude));
  return r;
}

std::string sun_position_report_json(const SunPositionJobResult& r) {
  nlohmann::json j;
  const SolarPosition& p = r.position;
  j["time"] = format_iso8601(unix_of(r.time), r.time_utc_offset);
  j["zenith"] = p.zenith_deg;
  j["azimuth"] = p.azimuth_deg;
  j["elevation"] = p.elevation_deg;
  j["incidence"] = p.incidence_deg;
  j["declination"] = p.declination_deg;
  j["equation_of_time_minutes"] = p.equation_of_time_min;
  j["julian_day"] = p.julian_day;
  auto event = [&](const std::optional<double>& t) {
    return t ? nlohmann::json(format_iso8601(*t, r.day_utc_offset)) : nlohmann::json(nullptr);
  };
  j["sunrise"] = event(r.day.sunrise_unix);
  j["transit"] = event(r.day.transit_unix);
  j["sunset"] = event(r.day.sunset_unix);
  j["day"] = r.day.kind == SunDayKind::polar_day     ? "polar day"
             : r.day.kind == SunDayKind::polar_night ? "polar night"
                                                     : "rises and sets";
  j["units"] = {{"angles", "degrees"}, {"azimuth", "clockwise from north"}};
  return j.dump(2);
}

namespace {

/// The result fields solar_report_json states.
constexpr std::string_view kReportFields[] = {"solar_global", "in_shadow", "sun_hours"};

/// What the outputs of a day of shadows say of its sun_hours: every instant with the sun up and
/// the point's ray to it open counts, however faint the beam (a period's counts only sunshine,
/// kSunshineThreshold, as the table says).
constexpr detail::FieldDescription kDayDescriptions[] = {{"sun_hours", "hours of direct sun, any DNI, h"}};

/// The descriptions the outputs of a run give its fields instead of the table's (detail::ResultFields).
std::span<const detail::FieldDescription> field_descriptions(bool day_of_shadows) {
  if (day_of_shadows) return kDayDescriptions;
  return {};
}

/// check_options's checks of `o` (the values alone, jobs::check_options), in order; returns the
/// raster value, resolved (the default for an instant or a period; in_shadow for a day's frames).
std::string checked_raster_value(const SolarJobOptions& o) {
  const bool instant = !o.at.empty();
  const bool frames_mode = !o.day.empty();
  std::string value;
  if (frames_mode && (instant || !o.start.empty() || !o.end.empty()))
    throw OptionError({option("day"), " is a day of shadows: give it alone, without ", option("at"), ", ",
                       option("start"), " or ", option("end")});
  if (frames_mode) {
    if (!option_time("day", o.day, {}, false).date_only)
      throw OptionError({option("day"), " '" + o.day + "': expected a date, YYYY-MM-DD"});
    parse_step(o.every, "every");
    if (!o.weather.empty()) throw OptionError({option("weather"), " needs a period (", option("start"), ", ", option("end"), ")"});
  }
  check_utc_offset(o.utc_offset);
  if (frames_mode) {
    value = "in_shadow";
  } else if (instant && (!o.start.empty() || !o.end.empty()))
    throw OptionError({option("at"), " is one instant: give it, or a period (", option("start"), " and ",
                       option("end"), "), not both"});
  else if (!instant && (o.start.empty() || o.end.empty()))
    // The day's clause is its own three parts: a front end without `day` leaves them out.
    throw OptionError({"give a period (", option("start"), " and ", option("end"), ") or an instant (",
                       option("at"), ")", ", or a day of shadows (", option("day"), ")"});
  // Options that only a period or only a day uses, refused where the run would ignore them (a
  // value other than the default: a front end that cannot tell a default given from none).
  const SolarJobOptions defaults;
  if (instant || frames_mode) {
    const OptionName when = option(instant ? "at" : "day");
    if (o.monthly)
      throw OptionError({option("monthly"), " needs a period (", option("start"), ", ", option("end"), "), not ", when});
    if (o.step != defaults.step) {
      if (instant)
        throw OptionError({option("step"), " needs a period (", option("start"), ", ", option("end"), "), not ", when});
      throw OptionError({option("step"), " needs a period (", option("start"), ", ", option("end"), "), not ", when,
                         " (its instants: ", option("every"), ")"});
    }
  }
  if (!frames_mode && o.every != defaults.every) {
    if (instant) throw OptionError({option("every"), " needs a day of shadows (", option("day"), "), not ", option("at")});
    throw OptionError({option("every"), " needs a day of shadows (", option("day"), "), not a period (", option("start"),
                       ", ", option("end"), ")"});
  }
  if (o.latitude.has_value() != o.longitude.has_value())
    throw OptionError({option("latitude"), " and ", option("longitude"), " go together"});
  if (o.latitude && !(std::abs(*o.latitude) <= 90.0))
    throw OptionError({option("latitude"), ": expected degrees in -90..90"});
  if (o.longitude && !(std::abs(*o.longitude) <= 180.0))
    throw OptionError({option("longitude"), ": expected degrees in -180..180"});
  if (o.linke.size() != 1 && o.linke.size() != 12)
    throw OptionError({option("linke"), ": expected one value or 12 monthly values"});
  for (double v : o.linke)
    if (!(v >= 1.0 && v <= 10.0)) throw OptionError({option("linke"), ": expected values in 1..10"});
  if (!(o.albedo >= 0.0 && o.albedo <= 1.0)) throw OptionError({option("albedo"), ": expected a number in 0..1"});
  if (o.sky_rays > 4096) throw OptionError({option("sky_rays"), ": expected 0..4096 directions"});
  if (instant && !o.weather.empty())
    throw OptionError({option("weather"), " needs a period (", option("start"), ", ", option("end"), ")"});
  if (!instant && !frames_mode && o.weather.empty()) parse_integration_step(o.step);
  if (!o.weather.empty() && o.step != defaults.step)
    throw OptionError({option("step"), " is the weather file's interval with ", option("weather")});
  // The times' syntax now; their meaning needs the site's longitude (a date alone).
  for (const auto& [field, text] : {std::pair{"at", &o.at}, {"start", &o.start}, {"end", &o.end}})
    if (!text->empty()) option_time(field, *text, {}, false);
  if (!(o.sector >= 0.0 && o.sector <= 30.0))
    throw OptionError({option("sector"), ": expected degrees in 0..30 (0 = one shadow ray per time step)"});
  if (o.primitive != "sphere" && o.primitive != "surfel")
    throw OptionError({option("primitive"), " '" + o.primitive + "': expected sphere or surfel"});
  detail::check_sight_lengths({o.radius, o.radius_factor, o.tolerance, o.target_height, {}});
  if (!o.out.empty())
    if (const std::string why = io::point_cloud_output_problem(o.out); !why.empty())
      throw OptionError({option("out"), " '" + o.out.string() + "': " + why});
  detail::check_raster_options(o.raster, o.cell, o.raster_value, o.preview);
  if (frames_mode && !o.raster_value.empty())
    throw OptionError({option("raster_value"), " does not apply to ", option("day"), " (its frames are shadows)"});
  if (frames_mode && !o.preview.empty())
    throw OptionError({option("preview"), " does not apply to ", option("day"),
                       " (each frame's preview is the frame's name with .png)"});
  if (!frames_mode) value = o.raster_value.empty() ? (instant ? "in_shadow" : "global") : o.raster_value;
  static const char* period_values[] = {"global", "beam", "diffuse", "reflected", "sun_hours", "sky_view"};
  static const char* instant_values[] = {"in_shadow", "global", "beam", "diffuse"};
  const bool known = frames_mode ||
                     instant ? std::find_if(std::begin(instant_values), std::end(instant_values),
                                            [&](const char* v) { return value == v; }) != std::end(instant_values)
                             : std::find_if(std::begin(period_values), std::end(period_values),
                                            [&](const char* v) { return value == v; }) != std::end(period_values);
  if (!known)
    throw OptionError({option("raster_value"), " '" + value + "': expected " +
                                                   (instant ? "in_shadow, global, beam or diffuse (an instant)"
                                                            : "global, beam, diffuse, reflected, sun_hours or "
                                                              "sky_view (a period)")});
  return value;
}

/// One run_solar call: the steps in order, sharing the options, the result and the site.
struct SolarRun {
  const SolarJobOptions& o;
  const JobControl& ctl;
  char buf[512];
  SolarJobResult r;
  detail::CloudSite cs;
  PointCloud& cloud = cs.cloud;
  bool instant = false;
  std::string value;
  SurfelAttributes surfels;
  std::vector<Vec3> normals;  // unit, each point's surface facing out (the irradiance's surface)
  VisibilityOptions vo;
  SunMap map;
  std::vector<Vec3> sky;
  bool sky_traced = true;  // sky_needed(): false leaves the fields that need the sky out of the cloud
  std::optional<EpwFile> weather;
  bool frames_mode = false;  // --day: shadows through a day
  struct Frame {
    std::filesystem::path path;
    double unix_seconds;  // the instant, UTC
    std::vector<double> shadow;
  };
  std::vector<Frame> frames;
  std::filesystem::path preview;  // the raster's PNG preview to write (detail::preview_path), "" for none

  explicit SolarRun(const SolarJobOptions& options) : o(options), ctl(options.control) {}
  SolarRun(const SolarRun&) = delete;

  /// Every option checked before any work: the values (checked_raster_value, what
  /// jobs::check_options checks), then the files; resolves `value` and `preview`.
  void check_options() {
    instant = !o.at.empty();
    frames_mode = !o.day.empty();
    value = checked_raster_value(o);
    detail::check_output_folder("out", o.out);
    detail::check_output_folder("raster", o.raster);
    if (o.write_preview && !o.raster.empty()) {
      // Resolved here, the default beside the raster too, so that the path the write uses is
      // the one checked before the trace.
      if (!frames_mode) preview = detail::preview_path(o.raster, o.preview);
      detail::check_output_folder("preview", preview);
      load_image_io();
    }
    std::vector<std::filesystem::path> outs = {o.out, preview};
    if (frames_mode && !o.raster.empty()) {
      // A day writes its frames, not the raster's name: each frame and its preview is checked as
      // the other outputs are. Which instants have the sun up is known only once the site is
      // located, so every instant of the day's clock is.
      for (const double since_midnight : day_instants(parse_step(o.every, "every"))) {
        const std::filesystem::path frame = day_frame_path(o.raster, since_midnight);
        outs.push_back(frame);
        if (o.write_preview) outs.push_back(detail::preview_path(frame, {}));
      }
      for (std::size_t k = 2; k < outs.size(); ++k) detail::check_output_folder("raster", outs[k]);
    } else {
      outs.push_back(o.raster);
    }
    const std::filesystem::path ins[] = {o.cloud_file, o.weather};
    require_outputs(outs, ins);
    // The weather file is read once the site is known (weather_steps), after the points: its
    // kind is checked now, so a FIFO or a folder is refused before any work ("-": standard input).
    if (!o.weather.empty() && o.weather != "-") require_regular_file(o.weather);
    r.raster_value = value;
  }

  /// Refuses a CRS that cannot place the site or give sun directions a frame (check_site_crs). With
  /// --latitude/--longitude only a geographic or geocentric one is refused (degrees are no frame
  /// for a direction wherever the site is: refuse_unprojected_crs, as visibility refuses it); any
  /// other then turns compass azimuths into the grid where PROJ can, and keeps grid north where it
  /// cannot (a local frame). The refusal of such a CRS names no location options, which cannot
  /// help it.
  void check_crs(const std::string& wkt) const {
    if (o.latitude) {
      detail::refuse_unprojected_crs(wkt, "sun directions");
      return;
    }
    try {
      check_site_crs(wkt);
    } catch (const std::invalid_argument& e) {
      if (is_unprojected_crs(wkt)) throw OptionError({e.what()});
      throw OptionError({e.what(), " (", option("latitude"), ", ", option("longitude"), ")"});
    }
  }

  /// The CRS checked before the points are read, indexed and their normals estimated: from the
  /// file's header (header_crs) or the cloud in memory. A format whose CRS comes only with its
  /// points is checked in open_site(), before its normals. A GeoTIFF (--raster) carries the
  /// cloud's CRS, so one GDAL cannot read is refused first, naming the input, rather than by the
  /// writer after the trace.
  void check_header_crs() const {
    if (!o.raster.empty()) detail::require_readable_header_crs(o.cloud_file, o.cloud, o.source_label);
    if (o.cloud) check_crs(o.cloud->crs_wkt);
    else if (const std::optional<std::string> wkt = detail::header_crs(o.cloud_file)) check_crs(*wkt);
  }

  void open_site() {
    detail::open_cloud_site(cs, o.cloud_file, o.cloud, o.source_label, o.index, o.radius, o.radius_factor, ctl,
                            {o.copc_in_place, o.cache_bytes});
    if (!o.raster.empty()) io::require_readable_crs(cs.source, cloud.crs_wkt);
    check_crs(cloud.crs_wkt);
    r.info = cs.info;
    r.source = cs.source;
    r.radius = cs.radius;
    r.primitive = o.primitive;
    // Normals for every primitive: the surface each point's irradiance falls on.
    surfels = detail::estimate_analysis_surfels(cs, o.surfel, ctl);
    normals.assign(surfels.normals.begin(), surfels.normals.end());
    if (cloud.normals.empty()) {  // PCA normals point up; a wall's must point out of the building
      const auto t0 = std::chrono::steady_clock::now();
      const std::size_t turned = orient_steep_normals(*cs.site, cloud.positions, normals, cs.radius.radius, ctl.threads);
      std::snprintf(buf, sizeof buf, "steep normals turned to their open side: %zu in %.2f s", turned, seconds_since(t0));
      ctl.info(buf);
    }
    const bool surfel = o.primitive == "surfel";
    vo.radius = r.radius.radius;
    vo.tolerance = o.tolerance.value_or(surfel ? 0.0 : 2.0 * vo.radius);
    vo.target_height = o.target_height.value_or(surfel ? 0.0 : vo.radius);
    if (surfel) vo.surfels = &surfels;
    vo.threads = ctl.threads;
    vo.progress = ctl.progress;
    vo.distributor = ctl.distributor;
    vo.cancel = ctl.cancel;
  }

  void locate() {
    const AABB box = cloud.bounds();
    const Vec3 centre = 0.5 * (box.lo + box.hi);
    if (o.latitude) {
      r.location.latitude_deg = *o.latitude;
      r.location.longitude_deg = *o.longitude;
      // With a CRS, still turn compass azimuths into grid bearings, and take the site's height
      // from the centre's z in metres (as without --latitude); without one, z's unit is unknown.
      r.location.elevation_m = 0.0;
      if (!cloud.crs_wkt.empty()) try {
          const SiteLocation at = locate_site(cloud.crs_wkt, centre);
          r.location.convergence_deg = at.convergence_deg;
          r.location.elevation_m = at.elevation_m;
        } catch (const std::invalid_argument&) {
          // A CRS PROJ cannot place (a local one) keeps grid north; a geographic or geocentric one
          // was refused by check_crs.
        }
      if (o.elevation) r.location.elevation_m = *o.elevation;
    } else {
      try {
        r.location = locate_site(cloud.crs_wkt, centre);
      } catch (const std::invalid_argument& e) {
        throw OptionError({e.what(), " (", option("latitude"), ", ", option("longitude"), ")"});
      }
      r.location_from_crs = true;
      if (o.elevation) r.location.elevation_m = *o.elevation;
    }
    r.location.elevation_m = std::clamp(r.location.elevation_m, -1000.0, 9000.0);
    std::snprintf(buf, sizeof buf, "site at %.5f %c, %.5f %c, %.0f m (%s); grid north %.3f deg from true north",
                  std::abs(r.location.latitude_deg), r.location.latitude_deg < 0 ? 'S' : 'N',
                  std::abs(r.location.longitude_deg), r.location.longitude_deg < 0 ? 'W' : 'E', r.location.elevation_m,
                  r.location_from_crs ? "from the CRS" : "given", r.location.convergence_deg);
    ctl.info(buf);
  }

  SpaInput spa_at(double unix_seconds) const {
    SpaInput in;
    in.time = instant_of(unix_seconds);
    in.latitude_deg = r.location.latitude_deg;
    in.longitude_deg = r.location.longitude_deg;
    in.elevation_m = r.location.elevation_m;
    in.pressure_mbar = o.pressure;
    in.temperature_c = o.temperature;
    in.delta_t = o.delta_t;
    return in;
  }

  /// The step at `t` (its middle) of `hours`, clear sky or from `record`.
  SolarStep make_step(double t, double hours, const EpwRecord* record) const {
    SolarStep s;
    s.hours = hours;
    SolarPosition p;
    try {
      p = solar_position(spa_at(t));
    } catch (const std::invalid_argument& e) {
      throw spa_error(e, instant ? "at" : "start");
    }
    s.direction = direction_from_azimuth(p.azimuth_deg, p.geometric_elevation_deg, r.location.convergence_deg);
    s.ray_direction = direction_from_azimuth(p.azimuth_deg, p.elevation_deg, r.location.convergence_deg);
    s.sun = {p.geometric_elevation_deg * kDegree, p.azimuth_deg * kDegree};
    const int doy = day_of_year(t);
    if (record) {
      s.reflected_from_global = true;
      const double g0 = extraterrestrial_irradiance(doy);
      auto ok = [](double v) { return std::isfinite(v) ? std::max(0.0, v) : 0.0; };
      s.global_horizontal = ok(record->ghi);
      s.beam_normal = s.sun.elevation > 0.0 ? ok(record->dni) : 0.0;
      s.diffuse_horizontal = ok(record->dhi);
      s.kb = std::clamp(s.beam_normal / g0, 0.0, 1.0);
    } else if (s.sun.elevation > 0.0) {
      const double linke = o.linke.size() == 12 ? o.linke[month_of(t) - 1] : o.linke[0];
      const HorizontalIrradiance h = clear_sky_horizontal(s.sun.elevation, doy, linke, r.location.elevation_m);
      s.beam_normal = h.beam / std::sin(s.sun.elevation);
      s.diffuse_horizontal = h.diffuse;
      s.global_horizontal = h.global;
      s.kb = std::clamp(h.beam / (extraterrestrial_irradiance(doy) * std::sin(s.sun.elevation)), 0.0, 1.0);
    }
    return s;
  }

  /// The result field `--raster-value` maps.
  std::string raster_field() const {
    static const std::pair<const char*, const char*> fields[] = {
        {"global", "solar_global"}, {"beam", "solar_beam"}, {"diffuse", "solar_diffuse"},
        {"reflected", "solar_reflected"}, {"sun_hours", "sun_hours"}, {"sky_view", "sky_view"}};
    if (instant) return value == "in_shadow" ? "in_shadow" : "irradiance_" + value;
    for (const auto& [v, f] : fields)
      if (value == v) return f;
    return value;
  }

  /// True when an output uses result field `name` (SolarJobOptions::all_fields): the cloud
  /// output writes every field, the raster its own, the report kReportFields.
  bool field_used(const std::string& name) const {
    return detail::result_field_used(name, o.all_fields, !o.out.empty(), o.raster.empty() ? std::string() : raster_field(),
                                     kReportFields);
  }

  /// True for a result field whose value does not depend on the sky-map rays: the shadow, the
  /// beam and the hours of sun come from the sun-map rays alone; the diffuse is weighed by the
  /// sky view, the reflected by its complement, and the global adds both.
  static bool sky_free(const std::string& name) {
    return name == "in_shadow" || name == "irradiance_beam" || name == "solar_beam" || name == "sun_hours";
  }

  /// The result fields of the run (the monthly ones are all sky-dependent, as solar_global).
  std::vector<std::string> result_fields() const {
    if (instant) return {kSolarInstantFields.begin(), kSolarInstantFields.end()};
    return {kSolarPeriodFields.begin(), kSolarPeriodFields.end()};
  }

  /// True when some output uses a field that needs the sky-map rays.
  bool sky_needed() const {
    for (const std::string& f : result_fields())
      if (!sky_free(f) && field_used(f)) return true;
    return false;
  }

  void sun_and_sky() {
    std::vector<SolarStep> steps;
    sky_traced = sky_needed();
    r.sky_rays = sky_traced ? o.sky_rays : 0;
    if (!sky_traced && o.sky_rays > 0)
      ctl.info("sky-map rays not traced: no output uses the diffuse, reflected, global or sky view (" +
               raster_field() + " map)");
    if (instant) {
      const OptionTime at = option_time("at", o.at, zone(), false);
      r.start_unix = r.end_unix = at.unix_seconds;
      r.utc_offset = o.utc_offset.value_or(at.written_offset.value_or(0.0));
      steps.push_back(make_step(r.start_unix, 1.0, nullptr));
      r.step_hours = 0.0;
      try {
        r.sun = solar_position(spa_at(r.start_unix));
      } catch (const std::invalid_argument& e) {
        throw spa_error(e, "at");
      }
    } else {
      r.start_unix = option_time("start", o.start, zone(), false).unix_seconds;
      r.end_unix = option_time("end", o.end, zone(), true).unix_seconds;
      r.utc_offset = o.utc_offset.value_or(0.0);
      if (!(r.end_unix > r.start_unix)) throw OptionError({option("end"), " must be after ", option("start")});
      // SPA's years checked at both ends (the steps lie between), so that the error names the one out.
      for (const auto& [field, t] : {std::pair{"start", r.start_unix}, std::pair{"end", r.end_unix - 1.0}}) {
        try {
          solar_position(spa_at(t));
        } catch (const std::invalid_argument& e) {
          throw spa_error(e, field);
        }
      }
      if (!o.weather.empty())
        weather_steps(steps);
      else
        clear_sky_steps(steps);
    }
    r.steps = steps.size();
    for (const SolarStep& s : steps) r.sun_steps += s.beam_normal > 0.0 && s.ray_direction.z > 0.0;
    map = build_sun_map(std::move(steps), instant ? 0.0 : o.sector);
    r.sectors = map.directions.size();
    for (std::uint32_t k = 0; k < r.sky_rays; ++k) sky.push_back(sky_direction(k, r.sky_rays, 0.0, SkyWeighting::uniform));
    if (instant) {
      std::snprintf(buf, sizeof buf, "sun at %s: azimuth %.3f deg, elevation %.3f deg",
                    format_time_label(r.start_unix, r.utc_offset).c_str(), r.sun->azimuth_deg, r.sun->elevation_deg);
    } else {
      std::snprintf(buf, sizeof buf,
                    "%zu time steps of %.4g h from %s to %s, %zu with sun; %zu sun-map sectors of %.3g deg, "
                    "%u sky-map directions",
                    r.steps, r.step_hours, format_time_label(r.start_unix, r.utc_offset).c_str(),
                    format_time_label(r.end_unix, r.utc_offset).c_str(), r.sun_steps, r.sectors, o.sector, r.sky_rays);
    }
    ctl.info(buf);
  }

  /// Clear-sky steps of --step over the period, each at its middle.
  void clear_sky_steps(std::vector<SolarStep>& steps) {
    const double step = parse_integration_step(o.step);
    const double span = r.end_unix - r.start_unix, n = std::round(span / step);
    if (std::abs(n * step - span) > 1.0)
      throw OptionError({"the period is not a whole number of ", option("step"), "s (", std::to_string(span / step),
                         ")"});
    if (n < 1.0) throw OptionError({"the period is shorter than one ", option("step")});
    if (n > 1e6) {
      // Whether a longer step is still allowed decides the advice.
      if (step < kMaxIntegrationStep)
        throw OptionError({"the period has more than 1,000,000 time steps; use a shorter period or a longer ",
                           option("step"), " (at most 1h)"});
      throw OptionError({"the period has more than 1,000,000 time steps of 1h (114 years); use a shorter period"});
    }
    r.step_hours = step / 3600.0;
    steps.reserve(std::size_t(n));
    for (std::size_t k = 0; k < std::size_t(n); ++k) {
      const double t = r.start_unix + (double(k) + 0.5) * step;
      steps.push_back(make_step(t, r.step_hours, nullptr));
      steps.back().group = month_group(t);
    }
  }

  /// The weather file's records whose interval's middle falls in the period. The file is a
  /// typical year (its months from different years), so each calendar year of the period takes
  /// the file's month/day/hour day for day (epw_utc_mid). A leap year without 29 February in the
  /// file repeats 28 February's records for it (a neighbour's weather rather than a day without
  /// sun); a file's 29 February is left out of a year that has none. Both are logged.
  void weather_steps(std::vector<SolarStep>& steps) {
    if (r.end_unix - r.start_unix > 366.0 * 86400.0)
      throw OptionError({"a period with ", option("weather"), " is at most one year (the file's)"});
    weather = read_epw(o.weather);
    const EpwLocation& at = weather->location;
    r.weather = at.city + ", " + at.country;
    r.step_hours = 1.0 / weather->records_per_hour;
    const auto leap_day = [](const EpwRecord& rec) { return rec.month == 2 && rec.day == 29; };
    const bool file_leap_day = std::any_of(weather->records.begin(), weather->records.end(), leap_day);
    auto in_period = [&](std::chrono::sys_seconds mid) {
      const double t = double(mid.time_since_epoch().count());
      return t >= r.start_unix && t < r.end_unix;
    };
    std::vector<std::pair<std::chrono::sys_seconds, const EpwRecord*>> taken;
    std::size_t missing = 0, repeated = 0, left_out = 0;
    // The file's local standard dates lie within a day of the UTC ones: one year either side of
    // the period's UTC years covers every record that can fall in it.
    const int first = int(std::chrono::year_month_day(day_of(r.start_unix)).year()) - 1;
    const int last = int(std::chrono::year_month_day(day_of(r.end_unix)).year()) + 1;
    for (int y = first; y <= last; ++y) {
      const bool leap_year = std::chrono::year{y}.is_leap();
      for (const EpwRecord& rec : weather->records) {
        if (leap_day(rec) && !leap_year) {
          EpwRecord day_before = rec;  // where the day would be: 24 h after 28 February
          day_before.day = 28;
          left_out += in_period(*epw_utc_mid(day_before, y) + std::chrono::days{1});
          continue;
        }
        const std::chrono::sys_seconds mid = *epw_utc_mid(rec, y);
        if (in_period(mid)) taken.emplace_back(mid, &rec);
        if (leap_year && !file_leap_day && rec.month == 2 && rec.day == 28 && in_period(mid + std::chrono::days{1})) {
          taken.emplace_back(mid + std::chrono::days{1}, &rec);
          ++repeated;
        }
      }
    }
    std::sort(taken.begin(), taken.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    steps.reserve(taken.size());
    for (const auto& [mid, rec] : taken) {
      const double t = double(mid.time_since_epoch().count());
      missing += !(std::isfinite(rec->ghi) && std::isfinite(rec->dni) && std::isfinite(rec->dhi));
      steps.push_back(make_step(t, r.step_hours, rec));
      steps.back().group = month_group(t);
    }
    if (steps.empty()) throw OptionError({option("weather"), " '" + o.weather.string() + "': no record in the period"});
    // Great-circle distance between the file's station and the site (haversine).
    const double p1 = at.latitude_deg * kDegree, p2 = r.location.latitude_deg * kDegree;
    const double dl = (r.location.longitude_deg - at.longitude_deg) * kDegree;
    const double h = std::pow(std::sin((p2 - p1) / 2), 2) + std::cos(p1) * std::cos(p2) * std::pow(std::sin(dl / 2), 2);
    const double km = 2.0 * 6371.0 * std::asin(std::min(1.0, std::sqrt(h)));
    std::snprintf(buf, sizeof buf, "weather: %zu records of %s (%.3f, %.3f), %.0f km from the site%s", steps.size(),
                  r.weather.c_str(), at.latitude_deg, at.longitude_deg, km,
                  km > 100.0 ? ": far; is it the right file?" : "");
    ctl.info(buf);
    if (missing) {
      std::snprintf(buf, sizeof buf, "weather: %zu records with missing radiation count as 0", missing);
      ctl.info(buf);
    }
    if (repeated) {
      std::snprintf(buf, sizeof buf, "weather: the file has no 29 February: %zu records of 28 February repeated for it",
                    repeated);
      ctl.info(buf);
    }
    if (left_out) {
      std::snprintf(buf, sizeof buf, "weather: %zu records of the file's 29 February left out (not a leap year)",
                    left_out);
      ctl.info(buf);
    }
  }

  void trace_and_sum() {
    const std::size_t n = cloud.size(), nsec = map.directions.size();
    std::vector<Vec3> dirs = map.directions;
    dirs.insert(dirs.end(), sky.begin(), sky.end());
    std::vector<double> beam(n), diffuse(n), reflected(n), hours(n), view(n), shadow(instant ? n : 0);
    const std::size_t groups = o.monthly && !instant ? 12 : 0;
    std::vector<double> by_month(groups * n, 0.0);  // Wh/m², month-major
    const bool sun_up = instant && nsec == 1;
    // Under MPI the ranks' per-point results travel to the root.
    std::vector<GatheredField> gathered{GatheredField::of(beam), GatheredField::of(diffuse), GatheredField::of(reflected),
                                        GatheredField::of(hours), GatheredField::of(view)};
    if (instant) gathered.push_back(GatheredField::of(shadow));
    for (std::size_t g = 0; g < groups; ++g) gathered.push_back(GatheredField::of(std::span(by_month).subspan(g * n, n)));
    const auto t0 = std::chrono::steady_clock::now();
    // Over a period, directions behind a surface are not traced: no beam comes from there, and
    // the sky view weighs them 0. At an instant every point's sun ray is traced: a shadow map
    // shows cast shadows, whichever way the surface faces.
    trace_directions(
        *cs.site, cloud.positions, dirs, normals, vo,
        [&](PointIndex i, std::span<const std::uint64_t> open) {
                       if (instant) shadow[i] = sun_up && (open[0] & 1u) ? 0.0 : 1.0;
                       double months[12] = {};
                       const PointIrradiation p =
                           accumulate_irradiation(map, sky, normals[i], r.location.convergence_deg, o.albedo, open,
                                                  std::span<double>(months, groups));
                       for (std::size_t g = 0; g < groups; ++g) by_month[g * n + i] = months[g];
                       beam[i] = p.beam;
                       diffuse[i] = p.diffuse;
                       reflected[i] = p.reflected;
                       hours[i] = p.sun_hours;
                       view[i] = p.sky_view;
                     },
        !instant, gathered);
    r.trace_seconds = seconds_since(t0);
    if (!root()) return;
    r.rays = std::uint64_t(n) * dirs.size();
    // Without the sky-map rays a field that needs them would hold the open sky's value: left out.
    auto set_field = [&](const std::string& name, std::vector<double> v) {
      if (sky_traced || sky_free(name)) detail::set_scalar(cloud, name, std::move(v));
    };
    if (instant) {
      if (!sun_up) ctl.info("the sun is below the horizon: every point is in shadow");
      std::vector<double> global(n);
      for (std::size_t i = 0; i < n; ++i) global[i] = beam[i] + diffuse[i] + reflected[i];
      set_field("in_shadow", std::move(shadow));
      set_field("irradiance_global", std::move(global));
      set_field("irradiance_beam", std::move(beam));
      set_field("irradiance_diffuse", std::move(diffuse));
    } else {
      double total = 0.0;
      std::vector<double> global(n);
      for (std::size_t i = 0; i < n; ++i) {
        global[i] = (beam[i] + diffuse[i] + reflected[i]) / 1000.0;  // Wh/m² -> kWh/m²
        beam[i] /= 1000.0;
        diffuse[i] /= 1000.0;
        reflected[i] /= 1000.0;
        total += global[i];
      }
      std::snprintf(buf, sizeof buf, "mean global irradiation %.4g kWh/m² over the period", total / double(n));
      ctl.info(buf);
      set_field("solar_global", std::move(global));
      set_field("solar_beam", std::move(beam));
      set_field("solar_diffuse", std::move(diffuse));
      set_field("solar_reflected", std::move(reflected));
      set_field("sun_hours", std::move(hours));
      set_field("sky_view", std::move(view));
      std::vector<bool> touched(groups, false);
      if (groups > 0)
        for (const SolarStep& s : map.steps) touched[s.group] = true;
      for (std::size_t g = 0; g < groups; ++g) {
        if (!touched[g]) continue;
        std::vector<double> v(by_month.begin() + std::ptrdiff_t(g * n), by_month.begin() + std::ptrdiff_t((g + 1) * n));
        for (double& x : v) x /= 1000.0;
        char name[48];
        std::snprintf(name, sizeof name, "%.*s%02zu", int(kSolarMonthlyPrefix.size()), kSolarMonthlyPrefix.data(), g + 1);
        set_field(name, std::move(v));
      }
    }
    std::snprintf(buf, sizeof buf, " in %.2f s", r.trace_seconds);
    ctl.info("traced " + count_text(n, "point") + " x " + count_text(dirs.size(), "direction") + " (" +
             std::to_string(nsec) + " sun, " + std::to_string(sky.size()) + " sky)" + buf);
  }

  /// The grid of the maps (--cell over the cloud's extent).
  GridSpec map_grid() const {
    try {
      return grid_over(cloud.bounds(), *o.cell);
    } catch (const std::invalid_argument& e) {
      throw OptionError({option("cell"), std::string(": ") + e.what()});
    }
  }

  /// A top-surface map of per-point `values` as a GeoTIFF at `path` and its PNG preview at
  /// `preview` (detail::preview_path; "" for none): a shadow map (`shadow`) with a categorical
  /// legend, else the heat ramp from 0 to the largest value (`hi` when given). The title is the
  /// band's description; the band's unit is the one the point outputs give the result field
  /// `field` (detail::ResultFields), so the map and the cloud cannot disagree. A map of an instant
  /// (`at`, UTC unix seconds) also carries it as RAYSCAN_TIME, one of a period its start and its
  /// (exclusive) end as RAYSCAN_START and RAYSCAN_END, ISO 8601 with the offset r.utc_offset. Throws
  /// std::logic_error for a `field` that is no result field.
  Raster write_map(const std::filesystem::path& path, const std::filesystem::path& preview,
                   std::span<const double> values, const std::string& title, const std::string& field, bool shadow,
                   std::optional<double> hi, std::optional<double> at) {
    const std::optional<std::string> unit = detail::ResultFields(cloud.crs_wkt).unit(field);
    if (!unit) throw std::logic_error("solar: the map of '" + field + "' has no result field unit");
    const std::string& units = *unit;
    Raster map = rasterize(cloud.positions, values, map_grid(), CellReduce::top, title);
    GeoTiffOptions go;
    go.crs_wkt = cloud.crs_wkt;
    go.metadata = {{"RAYSCAN_VALUE", value}, {"RAYSCAN_SOURCE", r.source}, {"RAYSCAN_UNITS", units}};
    if (at) {
      go.metadata.push_back({"RAYSCAN_TIME", format_iso8601(*at, r.utc_offset)});
    } else {
      go.metadata.push_back({"RAYSCAN_START", format_iso8601(r.start_unix, r.utc_offset)});
      go.metadata.push_back({"RAYSCAN_END", format_iso8601(r.end_unix, r.utc_offset)});
    }
    go.unit = units;
    write_geotiff(path, map, go);
    r.written.push_back(path);
    if (!preview.empty()) {
      PreviewStyle style;
      style.crs_wkt = go.crs_wkt;
      double top = 0.0;
      for (float v : map.values)
        if (std::isfinite(v)) top = std::max(top, double(v));
      if (shadow) style.categories = {{0.0f, "sun", {1.0f, 0.8f, 0.1f}}, {1.0f, "shadow", {0.15f, 0.15f, 0.3f}}};
      const std::string legend = write_raster_preview(preview, map, 0.0, hi.value_or(top), title, style);
      if (!frames_mode) ctl.info("preview legend: " + legend);
      r.written.push_back(preview);
    }
    return map;
  }

  /// The raster of --raster-value.
  void write_raster() {
    const std::string field = raster_field();
    const ScalarField* sf = nullptr;
    for (const ScalarField& f : cloud.scalars)
      if (f.name == field) sf = &f;
    const double offset = day_offset();
    std::string title;
    std::optional<double> hi;
    if (instant) {
      const std::string when = format_time_label(r.start_unix, r.utc_offset);
      title = value == "in_shadow" ? "shadow at " + when : value + " irradiance at " + when + " (W/m²)";
    } else if (value == "sky_view") {
      title = "sky view factor";
      hi = 1.0;
    } else {
      // A period of whole days in the days' time zone is named by its days, the end day inclusive;
      // any other by its start and end times, so that an afternoon and its whole day differ.
      const auto midnight = [&](double t) { return std::llround(t + offset * 3600.0) % 86400 == 0; };
      const std::string period =
          midnight(r.start_unix) && midnight(r.end_unix)
              ? format_iso8601(r.start_unix, offset).substr(0, 10) + " to " +
                    format_iso8601(r.end_unix - 1.0, offset).substr(0, 10)
              : format_time_label(r.start_unix, r.utc_offset) + " to " + format_time_label(r.end_unix, r.utc_offset);
      title = value == "sun_hours" ? "hours of direct sun (" + sunshine_criterion() + ") " + period + " (h)"
                                   : value + " irradiation " + period + " (kWh/m²)";
    }
    r.raster = write_map(o.raster, preview, sf->values, title, field, instant && value == "in_shadow", hi,
                         instant ? std::optional<double>(r.start_unix) : std::nullopt);
  }

  /// The step group of UTC time `t`: its month (0..11) in the days' time zone with --monthly, else 0.
  std::uint32_t month_group(double t) const {
    return o.monthly ? static_cast<std::uint32_t>(month_of(t + day_offset() * 3600.0) - 1) : 0u;
  }

  /// Hours east of UTC of the days: --utc-offset, else local mean solar time.
  double day_offset() const { return o.utc_offset.value_or(local_mean_time_offset(r.location.longitude_deg)); }

  /// The time zones of the time options written without an offset, at the site.
  LocalZone zone() const { return {o.utc_offset, r.location.longitude_deg}; }

  /// A day of shadows (--day, --every): the shadow of every instant with the sun up, a map per
  /// instant (numbered frames), and per point the hours of sun and of shadow.
  void day_frames() {
    const double every = parse_step(o.every, "every");
    r.start_unix = option_time("day", o.day, zone(), false).unix_seconds;
    r.utc_offset = day_offset();
    r.end_unix = r.start_unix + 86400.0;
    r.day_of_shadows = true;
    r.step_hours = every / 3600.0;
    const std::size_t n = cloud.size();
    std::vector<double> sun(n, 0.0), shadow(n, 0.0), frame(n);
    for (const double since_midnight : day_instants(every)) {
      const double t = r.start_unix + since_midnight;
      const SolarStep step = make_step(t, r.step_hours, nullptr);
      if (!(step.ray_direction.z > 0.0)) continue;  // night: no frame
      ++r.steps;
      ++r.sun_steps;
      const std::vector<Vec3> dir{step.ray_direction};
      trace_directions(
          *cs.site, cloud.positions, dir, normals, vo,
          [&](PointIndex i, std::span<const std::uint64_t> open) { frame[i] = (open[0] & 1u) ? 0.0 : 1.0; },
          false, std::array{GatheredField::of(frame)});
      for (std::size_t i = 0; i < n; ++i) {
        const bool lit = frame[i] == 0.0 && glm::dot(normals[i], step.direction) > 0.0;
        sun[i] += lit ? r.step_hours : 0.0;
        shadow[i] += frame[i] * r.step_hours;
      }
      if (!o.raster.empty()) frames.push_back({day_frame_path(o.raster, since_midnight), t, frame});
    }
    r.rays = std::uint64_t(n) * r.steps;
    std::snprintf(buf, sizeof buf, "%zu instants with the sun up, every %.4g h on %s", r.steps, r.step_hours,
                  format_iso8601(r.start_unix, day_offset()).substr(0, 10).c_str());
    ctl.info(buf);
    detail::set_scalar(cloud, "sun_hours", std::move(sun));
    detail::set_scalar(cloud, "shadow_hours", std::move(shadow));
  }

  /// True on the process that holds every point's results and writes the outputs: the only one,
  /// or rank 0 under MPI.
  bool root() const { return !ctl.distributor || ctl.distributor->is_root(); }

  void write_outputs() {
    if (!root()) return;
    OutputTransaction tx;
    if (!o.out.empty()) {
      detail::write_result_cloud(o.out, cloud, r.info, field_descriptions(frames_mode));
      r.written.push_back(o.out);
    }
    if (frames_mode) {
      for (const Frame& f : frames) {
        const std::filesystem::path png = o.write_preview ? detail::preview_path(f.path, {}) : std::filesystem::path();
        write_map(f.path, png, f.shadow, "shadow at " + format_time_label(f.unix_seconds, r.utc_offset), "in_shadow",
                  true, std::nullopt, f.unix_seconds);
      }
      if (!frames.empty()) {
        std::snprintf(buf, sizeof buf, "%zu shadow frames %s ... %s (and .png)", frames.size(),
                      frames.front().path.string().c_str(), frames.back().path.filename().string().c_str());
        ctl.info(buf);
      }
    } else if (!o.raster.empty()) {
      write_raster();
    }
    tx.commit();
  }
};

}  // namespace

void check_options(const SolarJobOptions& o) { checked_raster_value(o); }

SolarJobResult run_solar(const SolarJobOptions& o) {
  SolarRun run(o);
  run.check_options();
  run.check_header_crs();
  run.open_site();
  // Between the stages too: the normals' estimate and orientation (open_site) have no check of
  // their own.
  o.control.check_cancel();
  run.locate();
  if (run.frames_mode) {
    run.day_frames();
  } else {
    run.sun_and_sky();
    run.trace_and_sum();
  }
  o.control.check_cancel();
  detail::copc_cache_stats(run.cs, o.control, run.r.copc_decodes, run.r.copc_peak_cache_bytes);
  run.write_outputs();
  run.r.cloud = std::move(run.cloud);
  return std::move(run.r);
}

std::string solar_report_json(const SolarJobResult& r) {
  nlohmann::json j;
  j["cloud"] = r.source;
  j["points"] = r.cloud.size();
  j["primitive"] = r.primitive;
  j["radius"] = r.radius.radius;
  j["site"] = {{"latitude", r.location.latitude_deg},
               {"longitude", r.location.longitude_deg},
               {"elevation_m", r.location.elevation_m},
               {"grid_convergence_deg", r.location.convergence_deg},
               {"from_crs", r.location_from_crs}};
  j["start"] = format_iso8601(r.start_unix, r.utc_offset);
  if (r.sun) {
    j["sun"] = {{"azimuth", r.sun->azimuth_deg}, {"elevation", r.sun->elevation_deg}, {"zenith", r.sun->zenith_deg}};
  } else {
    j["end"] = format_iso8601(r.end_unix, r.utc_offset);
    j["step_hours"] = r.step_hours;
  }
  j["steps"] = r.steps;
  j["sun_steps"] = r.sun_steps;
  j["sectors"] = r.sectors;
  j["sky_rays"] = r.sky_rays;
  if (!r.weather.empty()) j["weather"] = r.weather;
  j["rays"] = r.rays;
  j["seconds"] = {{"trace", r.trace_seconds}};
  const detail::ResultFields described(r.cloud.crs_wkt, field_descriptions(r.day_of_shadows));
  for (const ScalarField& f : r.cloud.scalars) {
    if (std::find(std::begin(kReportFields), std::end(kReportFields), f.name) == std::end(kReportFields)) continue;
    double sum = 0.0, lo = kInf, hi = -kInf;
    for (double v : f.values) {
      sum += v;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    j["fields"][f.name] = {{"mean", sum / double(f.values.size())}, {"min", lo}, {"max", hi}};
    // The unit and meaning the output file's LAS descriptor or PLY/PCD comment gives the field.
    if (const auto unit = described.unit(f.name)) j["fields"][f.name]["unit"] = *unit;
    if (const auto d = described.info(f.name)) j["fields"][f.name]["description"] = d->description;
  }
  nlohmann::json written = nlohmann::json::array();
  for (const auto& f : r.written) written.push_back(f.string());
  j["written"] = written;
  return j.dump(2);
}

}  // namespace rayscan::jobs
