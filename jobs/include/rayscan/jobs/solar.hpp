// The solar jobs: where the sun is (NREL SPA on the command line), and how much sun each point
// of a scanned site receives -- irradiation over a period and shadows at an instant -- with the
// shadows cast by the points themselves through the ray query. `rayscan solar position`,
// `rayscan solar` and the Python module wrap run_sun_position() and run_solar(). docs/solar.md.
#pragma once

#include "rayscan/site/copc.hpp"
#include "rayscan/analysis/raster.hpp"
#include "rayscan/analysis/site_location.hpp"
#include "rayscan/analysis/solar_position.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/jobs/memory_source.hpp"
#include "rayscan/io/file_info.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/spacing.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan::jobs {

/// Inputs of run_sun_position(): the NREL SPA calculator's (Reda & Andreas 2004, section 3).
struct SunPositionJobOptions {
  double latitude = 0.0;                ///< WGS 84, degrees north (-90..90)
  double longitude = 0.0;               ///< WGS 84, degrees east (-180..180)
  /// ISO 8601 (analysis::parse_iso8601). A time naming its offset ('Z', +02:00) is that instant;
  /// one without is the clock at `utc_offset` when given, else UTC; a date alone is its midnight
  /// at `utc_offset`, else in local mean solar time.
  std::string time;
  double elevation = 0.0;               ///< metres above the ellipsoid
  double pressure = 1013.25;            ///< mbar, for refraction
  double temperature = 15.0;            ///< degrees C, for refraction
  double delta_t = analysis::kDefaultDeltaT;  ///< TT - UT1, seconds
  double slope = 0.0;                   ///< surface tilt for the incidence angle, degrees
  double surface_azimuth = 180.0;       ///< direction the surface faces, degrees clockwise from north
  /// Hours east of UTC, -18..18 in whole minutes (ISO 8601 writes no finer offset): the time zone
  /// of `time` written without an offset, and of the day whose sunrise, transit and sunset are
  /// reported; nullopt = `time` without an offset is UTC, and the day is in the offset written in
  /// `time`, else local mean solar time (analysis::local_mean_time_offset: longitude / 15 h, to the
  /// minute).
  std::optional<double> utc_offset;
};

/// Output of run_sun_position().
struct SunPositionJobResult {
  analysis::UtcInstant time;             ///< the instant, UTC
  /// The time zone `time` is shown in, hours east of UTC: `utc_offset`, else the one written in the
  /// time, else 0 (UTC).
  double time_utc_offset = 0.0;
  analysis::SolarPosition position;      ///< refracted topocentric position and intermediates
  analysis::SunRiseTransitSet day;       ///< the local day's events
  double day_utc_offset = 0.0;           ///< the time zone of `day`, hours east of UTC
};

/// Runs SPA for the options. Throws OptionError naming the field for a bad time, an input out of
/// range or a `utc_offset` that is not whole minutes.
SunPositionJobResult run_sun_position(const SunPositionJobOptions& options);

/// JSON report of a sun position (`rayscan solar position --json`), indented by 2: time (ISO 8601
/// with time_utc_offset), zenith, azimuth, elevation, incidence (degrees), equation of time
/// (minutes), sunrise / transit / sunset (ISO 8601 with the day's offset; null in polar day or
/// night). Every time is the exact instant to the second (format_iso8601).
std::string sun_position_report_json(const SunPositionJobResult& result);

/// ISO 8601 text of a UTC unix time shown at `utc_offset_hours` ("2026-06-21T05:31:12-07:00"),
/// rounded to the nearest whole second. ISO 8601 writes an offset in whole minutes, so an offset
/// that is not a whole number of minutes is shown as UTC ('Z'): the text always names the instant.
std::string format_iso8601(double unix_seconds, double utc_offset_hours);

/// A time for people, as maps' titles and log lines state it: the local clock with its offset,
/// "2026-06-21 12:00 UTC+02:00", seconds only when not zero, "2026-06-21 10:00 UTC" at offset 0
/// (and, as format_iso8601, at an offset that is not whole minutes).
std::string format_time_label(double unix_seconds, double utc_offset_hours);

/// Inputs of run_solar(). An invalid option throws OptionError naming the fields (`start`), which
/// the CLI writes as its flags (`--start`).
struct SolarJobOptions {
  // ---- Input cloud.
  std::filesystem::path cloud_file;     ///< point cloud (LAS, LAZ, COPC, PLY, PCD, text) or index file (.rsi)
  const PointCloud* cloud = nullptr;    ///< in-memory points instead of cloud_file (copied into the result)
  /// The name of `cloud` where a file would be named: messages, log lines, the report's "cloud"
  /// and the rasters' RAYSCAN_SOURCE (the Python module gives the keyword, "cloud").
  std::string source_label{kMemorySource};
  IndexOptions index;                   ///< index type (default octree-adaptive)
  /// COPC input (a LAS/LAZ file with the COPC info VLR): query the file's own octree in place
  /// (io::CopcIndex: nodes decoded as the queries reach them, no tree built, `index` ignored) or,
  /// when false, read it whole and build `index` over it (SiteOptions::copc_in_place). The points
  /// are read whole either way, in file order (the output cloud); the results are the same.
  bool copc_in_place = true;
  /// COPC input in place: bytes of decoded nodes kept resident (`--cache`; trimmed as each chunk
  /// of points or image row ends, plus the nodes of the chunks in flight).
  std::size_t cache_bytes = io::kCopcDefaultCacheBytes;
  std::optional<double> radius;         ///< sphere radius (primitive sphere), world units; nullopt = auto
  double radius_factor = kDefaultAutoRadiusFactor;  ///< auto radius = factor x median NN spacing
                                                    ///< (choose_radius; range: auto_radius_factor_problem)
  /// Geometry of each point for shadows: "sphere" (the paper's model, one radius: light passes
  /// through gaps in crowns, and a crown's top is in the sun) or "surfel" (oriented discs read as
  /// the height field a DSM samples: solid below, so steep leaf discs shade their neighbours and
  /// a crown darkens inside). Normals for the irradiance come from the surfels either way.
  std::string primitive = "sphere";
  SurfelOptions surfel;                 ///< normals and disc radii (file normals when present, else PCA)

  // ---- Place and time.
  std::optional<double> latitude;       ///< degrees north; nullopt = from the cloud's CRS
  std::optional<double> longitude;      ///< degrees east; nullopt = from the cloud's CRS
  std::optional<double> elevation;      ///< site elevation, metres; nullopt = from the cloud's z
  /// The period: ISO 8601 date-times or dates alone. A time naming its offset ('Z', -07:00) is that
  /// instant; one without is the clock at `utc_offset` when given, else UTC. A date alone is its
  /// midnight at `utc_offset`, else in local mean solar time (analysis::local_mean_time_offset:
  /// longitude / 15 h east of UTC, to the minute), and
  /// `end` given as a date alone includes that whole day, so "--start 2026-01-01 --end 2026-12-31"
  /// is the year.
  std::string start, end;
  std::string step = "1h";              ///< time step: N min | N h | N d (e.g. 30min, 1h)
  std::string at;                       ///< one instant instead of a period (read as `start`): shadows and irradiance
  /// A day of shadows instead (a date, YYYY-MM-DD): the shadows every `every` while the sun is up,
  /// a map per instant with `raster` (RASTER_HHMM.tif and .png: numbered frames of an
  /// animation), and per point sun_hours and shadow_hours.
  std::string day;
  std::string every = "30min";          ///< the instants of `day`
  /// Hours east of UTC, -18..18 in whole minutes: the time zone of `start`, `end`, `at` and `day`
  /// written without an offset (a planner's local standard time), of the days (monthly fields, the
  /// maps' dates) and of the times the maps and the report state. nullopt = a date-time without an
  /// offset is UTC, and a date alone and the days are in local mean solar time (longitude / 15 h,
  /// to the minute).
  std::optional<double> utc_offset;
  double delta_t = analysis::kDefaultDeltaT;  ///< TT - UT1, seconds (SPA)
  double pressure = 1013.25;            ///< mbar (SPA refraction)
  double temperature = 15.0;            ///< degrees C (SPA refraction)

  // ---- Irradiance model.
  /// Linke turbidity at air mass 2: one value, or 12 monthly values (January first), r.sun's
  /// linke_value; 3.0 is a rural mid-latitude annual mean (Šúri & Hofierka 2004).
  std::vector<double> linke{3.0};
  double albedo = 0.2;                  ///< ground albedo (r.sun's default)
  /// EnergyPlus EPW: the measured GHI/DNI/DHI of the file's records whose interval's middle lies
  /// in the period replace the clear sky; at most a year. Each calendar year of the period takes
  /// the file's month/day/hour day for day; a leap year without the file's 29 February repeats
  /// 28 February, a non-leap year leaves a file's 29 February out (docs/solar.md).
  std::filesystem::path weather;
  /// Sun-map sector edge, degrees: the time steps whose sun directions share an azimuth x
  /// elevation cell share one shadow ray per point (its mean direction). 0 = one ray per step.
  double sector = 1.0;
  /// Also the global irradiation of each calendar month in the period (days in the time zone of
  /// `utc_offset`): fields solar_global_01 .. solar_global_12, kWh/m², for the months the period
  /// touches; they add up to solar_global.
  bool monthly = false;
  std::uint32_t sky_rays = 64;          ///< sky-map directions per point (the diffuse's sky view); 0 = open sky
  std::optional<double> tolerance;      ///< line-of-sight tolerance (visibility; default 2 x radius, surfels 0)
  std::optional<double> target_height;  ///< shadow rays start this far from the point along its normal (+z without normals); world units (default 1 x radius, surfels 0)

  // ---- Outputs (each written through AtomicFile; "" = not written).
  std::filesystem::path out;            ///< the cloud with the result fields
  std::filesystem::path raster;         ///< top-surface GeoTIFF (.tif); needs `cell`
  std::optional<double> cell;           ///< raster cell edge, world units
  /// global | beam | diffuse | reflected | sun_hours | sky_view (a period); in_shadow | global |
  /// beam | diffuse (an instant); "" = global for a period, in_shadow for an instant; a day's
  /// frames are shadows.
  std::string raster_value;
  std::filesystem::path preview;        ///< PNG preview ("" = the raster's name with .png)
  bool write_preview = true;
  /// The result's cloud is used as it is (the Python module returns its fields): every result
  /// field is computed. false (the CLI): only the fields an output uses are -- every one with
  /// `out`, else the raster's and those solar_report_json states -- and the sky-map rays, which
  /// only the diffuse, reflected, global and sky view need, are not traced when none of those is
  /// used (an instant's shadow map); the fields that need them are then left out of the result.
  bool all_fields = true;

  JobControl control;
};

/// The result fields of a period, in the order run_solar adds them (SolarJobResult::cloud): the
/// names the outputs, the Python module (rayscan.SOLAR_PERIOD_FIELDS) and rayscan.dask use.
inline constexpr std::array<std::string_view, 6> kSolarPeriodFields = {
    "solar_global", "solar_beam", "solar_diffuse", "solar_reflected", "sun_hours", "sky_view"};
/// The result fields of an instant, in the order run_solar adds them (rayscan.SOLAR_INSTANT_FIELDS).
inline constexpr std::array<std::string_view, 4> kSolarInstantFields = {"in_shadow", "irradiance_global",
                                                                        "irradiance_beam", "irradiance_diffuse"};
/// The result fields of a day of shadows.
inline constexpr std::array<std::string_view, 2> kSolarDayFields = {"sun_hours", "shadow_hours"};
/// A period's monthly fields (SolarJobOptions::monthly): this prefix and the month, 01 .. 12.
inline constexpr std::string_view kSolarMonthlyPrefix = "solar_global_";

/// Output of run_solar().
struct SolarJobResult {
  /// The input with the result fields (kSolarPeriodFields, kSolarInstantFields, kSolarDayFields).
  /// A period: solar_global, solar_beam, solar_diffuse, solar_reflected (kWh/m² over the period,
  /// on each point's own surface), sun_hours (h) and sky_view (fraction of the sky seen, weighted
  /// by the surface's cosine). An instant: in_shadow (1: the sun is down or the point's ray to the
  /// sun is blocked -- a cast shadow, whichever way its surface faces), irradiance_global,
  /// irradiance_beam, irradiance_diffuse (W/m²; a surface facing away from the sun gets no beam).
  /// A day of shadows: sun_hours and shadow_hours (h with the sun up and the point's ray to it
  /// blocked).
  PointCloud cloud;
  io::FileInfo info;
  std::string source;  ///< cloud_file, or source_label for points in memory
  RadiusChoice radius;
  std::string primitive;
  analysis::SiteLocation location;      ///< where the sun was computed
  bool location_from_crs = false;
  double start_unix = 0.0, end_unix = 0.0, step_hours = 0.0;
  /// A day of shadows (SolarJobOptions::day): its sun_hours count every instant with the sun up
  /// and the ray open, without a period's sunshine threshold (analysis::kSunshineThreshold).
  bool day_of_shadows = false;
  /// Hours east of UTC the times are stated in (maps' titles and RAYSCAN_TIME, the report's start
  /// and end): `utc_offset`; else, at an instant, the offset written in `at`, over a day of shadows
  /// local mean solar time (to the minute), else 0 (UTC). Always whole minutes.
  double utc_offset = 0.0;
  std::size_t steps = 0;                ///< time steps in the period (1 for an instant)
  std::size_t sun_steps = 0;            ///< steps with the sun above the horizon
  std::size_t sectors = 0;              ///< shadow directions per point (sun-map sectors)
  std::uint32_t sky_rays = 0;           ///< sky-map directions traced per point (0 when no output needs them)
  std::optional<analysis::SolarPosition> sun;  ///< the sun at `at` (an instant)
  std::uint64_t rays = 0;               ///< directions traced (points x directions, before culling)
  double trace_seconds = 0.0;
  std::string weather;                  ///< the EPW's location line, when one was used
  std::optional<analysis::Raster> raster;
  std::string raster_value;
  std::vector<std::filesystem::path> written;
  std::uint64_t copc_decodes = 0;       ///< COPC input in place: node decodes (re-decodes after
                                        ///< eviction included); 0 otherwise
  std::size_t copc_peak_cache_bytes = 0;  ///< COPC input in place: the most bytes of decoded nodes
                                          ///< resident at once (CopcIndex::peak_resident_bytes)
};

/// Checks the options' values alone, as run_solar does first, before it touches a file: the
/// time options and their combinations (one of a period, an instant or a day; monthly and a step
/// other than the default only with a period, an `every` other than the default only with a day;
/// the times' ISO 8601 syntax), utc_offset, latitude with longitude and their ranges, linke,
/// albedo, sky_rays, sector, primitive, radius (given: finite, > 0), radius_factor, tolerance and
/// target_height (finite, >= 0), the weather file's combinations (not its file), and the outputs'
/// extensions and raster options. Left to the run: the files (output folders and replacement, the
/// weather file, the cloud's CRS), what needs the site's place (a date's local midnight, the
/// period against its steps, SPA's range of years) and what needs the points (the automatic
/// radius). Throws OptionError naming the field.
void check_options(const SolarJobOptions& options);

/// Checks every option and the cloud's CRS (from the file's header for LAS, LAZ, COPC and index
/// files, so that a CRS that cannot place the site is refused before any point is read; for other
/// formats once read), reads the cloud, builds the index (none for an index file or a COPC file
/// queried in place: copc_in_place), estimates the surfels, computes the sun
/// positions (SPA) and the sky (ESRA clear sky or the EPW file), traces the sun-map and sky-map
/// directions of every point (analysis::trace_directions) and accumulates the irradiance of every
/// time step on each point's surface, then writes the outputs. With options.control.distributor
/// over several processes (MPI, docs/mpi.md) every process calls it with the same options; point
/// chunks are handed out, and only the root's result holds every point's fields and writes the
/// outputs (byte-identical to one process). Throws OptionError (options),
/// io::FormatError (cloud), std::runtime_error (a malformed EPW file, I/O).
SolarJobResult run_solar(const SolarJobOptions& options);

/// JSON report of a run (`rayscan solar --json`), indented by 2.
std::string solar_report_json(const SolarJobResult& result);

}  // namespace rayscan::jobs
