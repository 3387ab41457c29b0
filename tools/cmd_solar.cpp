// `rayscan solar`: sun and shadow on a scanned site -- per-point irradiation over a period
// (kWh/m², hours of sun) or shadows at an instant, with the points' own shadows; and
// `rayscan solar position`, the NREL SPA calculator. The jobs are jobs::run_solar and
// jobs::run_sun_position (rayscan/jobs/solar.hpp); this file parses options and prints.
#include "commands.hpp"
#include "processes.hpp"

#include "rayscan/base/byte_size.hpp"

#include "rayscan/jobs/solar.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>

namespace rayscan::cli {

namespace {

struct SolarCli {
  jobs::SolarJobOptions job;
  jobs::SunPositionJobOptions position;
  std::string cloud, out, raster, preview, weather, radius = "auto", cache = "2G";
  bool no_preview = false, json = false, quiet = false;
  CLI::App* position_cmd = nullptr;
};

int run_position(SolarCli& o) {
  const jobs::SunPositionJobResult r = jobs::run_sun_position(o.position);
  if (o.json) {
    std::cout << jobs::sun_position_report_json(r) << "\n";
    return 0;
  }
  const analysis::SolarPosition& p = r.position;
  auto event = [&](const std::optional<double>& t) {
    return t ? jobs::format_iso8601(*t, r.day_utc_offset) : std::string("none");
  };
  char buf[256];
  std::snprintf(buf, sizeof buf, "time      %s\nzenith    %.5f deg\nazimuth   %.5f deg (clockwise from north)\n"
                "elevation %.5f deg\nincidence %.5f deg\n",
                jobs::format_iso8601(double(r.time.unix_seconds) + r.time.fraction, r.time_utc_offset).c_str(), p.zenith_deg,
                p.azimuth_deg, p.elevation_deg, p.incidence_deg);
  std::cout << buf;
  std::cout << "sunrise   " << event(r.day.sunrise_unix) << "\n";
  std::cout << "transit   " << event(r.day.transit_unix) << "\n";
  std::cout << "sunset    " << event(r.day.sunset_unix) << "\n";
  if (r.day.kind != analysis::SunDayKind::rises_and_sets)
    std::cout << (r.day.kind == analysis::SunDayKind::polar_day ? "polar day" : "polar night") << "\n";
  return 0;
}

int run_solar(SolarCli& o) {
  if (o.position_cmd->parsed()) {
    require_single_process("rayscan solar position");
    return run_position(o);
  }
  if (o.cloud.empty()) throw UsageError("expected a CLOUD, or the subcommand position (see --help)");
  // The whole trace, then nothing written or printed: refused before the work.
  if (o.out.empty() && o.raster.empty() && !o.json)
    throw UsageError("nothing to write: give -o OUT (the cloud with the result fields), --raster MAP.tif, or --json");
  jobs::SolarJobOptions& job = o.job;
  job.radius = parse_radius(o.radius);
  job.cloud_file = o.cloud;
  job.out = o.out;
  job.raster = o.raster;
  job.preview = o.preview;
  job.weather = o.weather;
  job.write_preview = !o.no_preview;
  job.all_fields = false;  // only the outputs' fields: a shadow map traces no sky rays
  try {
    job.cache_bytes = static_cast<std::size_t>(rayscan::parse_byte_size(o.cache));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--cache: ") + e.what());
  }
  // MPI (docs/mpi.md): point chunks over the ranks; only rank 0 logs, prints and writes.
  job.control.distributor = distributor();
  const bool talk = !o.quiet && is_root();
  job.control.progress = talk;
  if (talk) job.control.log = [](const std::string& s) { std::cerr << "rayscan solar: " << s << "\n"; };
  const jobs::SolarJobResult r = jobs::run_solar(job);
  if (!is_root()) return 0;
  if (talk && !traffic_summary().empty()) std::cerr << "rayscan solar: " << traffic_summary() << "\n";
  if (o.json) {
    std::cout << jobs::solar_report_json(r) << "\n";
    return 0;
  }
  for (const auto& f : r.written) std::cout << "wrote " << f.string() << "\n";
  return 0;
}

}  // namespace

Runner add_solar_command(CLI::App& app) {
  auto o = std::make_shared<SolarCli>();
  // The site, clock and atmosphere ranges `solar` and `solar position` share: the limits SPA
  // checks (analysis/src/solar_position.cpp, require_range), a site's elevation -1000..9000 m.
  const CLI::Validator utc_offset = finite_number(-18, 18), latitude = finite_number(-90, 90),
                       longitude = finite_number(-180, 180), elevation = finite_number(-1000, 9000),
                       pressure = finite_number(0, 5000, true), temperature = finite_number(-273, 6000),
                       delta_t = finite_number(-8000, 8000);
  CLI::App* c = app.add_subcommand(
      "solar",
      "Sun and shadow on a scanned site: per-point irradiation over a period (kWh/m², clear sky as "
      "GRASS r.sun or an EPW weather file) and hours of sun, or shadows at one instant, with the "
      "shadows the points cast on each other; written as fields of LAS/PLY and a GeoTIFF of the top "
      "surface with a PNG preview (docs/solar.md). `rayscan solar position` is the NREL SPA "
      "calculator.");
  c->add_option("cloud", o->cloud, "Point cloud (LAS, LAZ, COPC, PLY, PCD, text) or index file (.rsi)");
  c->add_option("--start", o->job.start,
                "Start of the period (ISO 8601; without an offset: local time at --utc-offset, else UTC; a date "
                "alone is midnight at --utc-offset, else local mean solar midnight)");
  c->add_option("--end", o->job.end, "End of the period (ISO 8601, as --start; a date alone includes that day)");
  c->add_option("--step", o->job.step, "Time step of the integration, at most 1h (e.g. 15min, 30min, 1h); a period only")
      ->capture_default_str();
  c->add_option("--at", o->job.at,
                "One instant instead of a period: shadows (ISO 8601, e.g. 2026-06-21T12:00 with --utc-offset 2, or "
                "2026-06-21T12:00+02:00; without an offset: local time at --utc-offset, else UTC)");
  c->add_option("--day", o->job.day,
                "A day of shadows instead (YYYY-MM-DD): with --raster, a map every --every while the sun is up "
                "(RASTER_HHMM.tif/.png, numbered frames); per point sun_hours and shadow_hours");
  c->add_option("--every", o->job.every, "The instants of --day (e.g. 15min, 30min, 1h); a day only")->capture_default_str();
  c->add_option("--utc-offset", o->job.utc_offset,
                "Local standard time, hours east of UTC in whole minutes (e.g. 2, -7, 5.5): the zone of --start, "
                "--end, --at and --day written without an offset, and of the times and dates the maps and logs "
                "state (default: a time without an offset is UTC, a date alone local mean solar time, longitude / "
                "15 to the minute)")
      ->check(utc_offset);
  c->add_option("--lat,--latitude", o->job.latitude, "Site latitude, degrees north (default: from the cloud's CRS)")
      ->check(latitude);
  c->add_option("--lon,--longitude", o->job.longitude, "Site longitude, degrees east (default: from the CRS)")
      ->check(longitude);
  c->add_option("--elevation", o->job.elevation, "Site elevation, metres (default: from the cloud)")
      ->check(elevation);
  c->add_option("--linke", o->job.linke,
                "Linke turbidity: one value or 12 monthly values (January first), 1..10")
      ->delimiter(',')
      ->capture_default_str();
  c->add_option("--albedo", o->job.albedo, "Ground albedo, 0..1")->capture_default_str()->check(finite_number(0, 1));
  c->add_option("--weather", o->weather, "EnergyPlus weather file (.epw): measured hourly GHI, DNI, DHI");
  c->add_option("--sector", o->job.sector,
                "Sun-map sector edge in degrees: time steps whose sun directions share a sector share "
                "one shadow ray per point (0 = one ray per step)")
      ->capture_default_str()
      ->check(finite_number(0, 30));
  c->add_flag("--monthly", o->job.monthly,
              "Also each month's global irradiation: fields solar_global_01 .. solar_global_12 (kWh/m²); a "
              "period only");
  c->add_option("--sky-rays", o->job.sky_rays, "Sky-map directions per point for the diffuse's sky view (0 = open sky)")
      ->capture_default_str()
      ->transform(integer_in(0, 4096));
  c->add_option("--primitive", o->job.primitive,
                "Geometry that casts shadows: sphere (the paper's model: light passes through gaps, crown "
                "tops are lit) or surfel (the height field a DSM samples: solid below)")
      ->capture_default_str()
      ->check(one_of(kPrimitiveNames));
  c->add_option("--radius", o->radius, "Sphere radius (world units) or auto")->capture_default_str();
  c->add_option("--tolerance", o->job.tolerance,
                "A blocker at most this far before the point along the sun ray is its own surface, world units "
                "(default 2 x radius; surfels 0)")
      ->check(non_negative());
  c->add_option("--target-height", o->job.target_height,
                "Shadow rays start this far from each point along its normal, straight up without normals, world "
                "units (default 1 x radius; surfels 0)")
      ->check(non_negative());
  c->add_option("--pressure", o->job.pressure, "Annual mean pressure, mbar (refraction)")
      ->capture_default_str()
      ->check(pressure);
  c->add_option("--temperature", o->job.temperature, "Annual mean temperature, degrees C (refraction)")
      ->capture_default_str()
      ->check(temperature);
  c->add_option("--delta-t", o->job.delta_t, "TT - UT1 in seconds (SPA), -8000..8000")->capture_default_str()->check(delta_t);
  c->add_option("-o,--out", o->out, "Write the cloud with the result fields here (.las, .laz, .ply, .pcd, .xyz, .csv, .txt)");
  c->add_option("--raster", o->raster, "Write a GeoTIFF of the top surface here (.tif)");
  c->add_option("--cell", o->job.cell, "Raster cell size (world units; required with --raster)")->check(positive());
  c->add_option("--raster-value", o->job.raster_value,
                "A period: global | beam | diffuse | reflected | sun_hours | sky_view (default global); an "
                "instant: in_shadow | global | beam | diffuse (default in_shadow)");
  c->add_option("--preview", o->preview, "PNG preview of the raster (default: the raster's name with .png)");
  c->add_flag("--no-preview", o->no_preview, "Do not write the PNG preview");
  c->add_option("--cache", o->cache,
                "COPC input: bound on decoded node data kept in memory (LRU, trimmed as each chunk of points "
                "ends; plus the nodes of the chunks in flight; e.g. 2G, 512M). A COPC file is queried on its own "
                "octree, decoding only the nodes the rays reach (its points are still read, as the output cloud)")
      ->capture_default_str();
  add_index_option(*c, o->job.index.type);
  add_threads_option(*c, o->job.control.threads, "the results are identical for any count");
  c->add_flag("--json", o->json, "Print a JSON report on stdout");
  c->add_flag("--quiet,-q", o->quiet, "No log lines or progress bar on stderr");

  CLI::App* p = c->add_subcommand("position", "Where the sun is: NREL's Solar Position Algorithm (Reda & Andreas 2004)");
  o->position_cmd = p;
  p->add_option("--lat,--latitude", o->position.latitude, "Latitude, degrees north")->required()->check(latitude);
  p->add_option("--lon,--longitude", o->position.longitude, "Longitude, degrees east")->required()->check(longitude);
  p->add_option("--time", o->position.time,
                "Instant, ISO 8601 (e.g. 2026-06-21T12:00:00+02:00; without an offset: local time at --utc-offset, "
                "else UTC; a date alone = its midnight at --utc-offset, else in local mean solar time)")
      ->required();
  p->add_option("--elevation", o->position.elevation, "Elevation, metres, -1000..9000")
      ->capture_default_str()
      ->check(elevation);
  p->add_option("--pressure", o->position.pressure, "Annual mean pressure, mbar, > 0")
      ->capture_default_str()
      ->check(pressure);
  p->add_option("--temperature", o->position.temperature, "Annual mean temperature, degrees C, -273..6000")
      ->capture_default_str()
      ->check(temperature);
  p->add_option("--delta-t", o->position.delta_t, "TT - UT1, seconds, -8000..8000")
      ->capture_default_str()
      ->check(delta_t);
  p->add_option("--slope", o->position.slope, "Surface tilt for the incidence angle, degrees, 0..180")
      ->capture_default_str()
      ->check(finite_number(0, 180));
  p->add_option("--surface-azimuth", o->position.surface_azimuth,
                "Direction the surface faces, degrees clockwise from north, -360..360")
      ->capture_default_str()
      ->check(finite_number(-360, 360));
  p->add_option("--utc-offset", o->position.utc_offset,
                "Local standard time, hours east of UTC, -18..18, whole minutes: the zone of --time written without "
                "an offset, of the printed time and of the reported day (default: --time without an offset is UTC; "
                "the day is in the time's offset, else local mean solar time to the minute)")
      ->check(utc_offset);
  p->add_flag("--json", o->json, "Print JSON");
  c->require_subcommand(0, 1);
  return [o] { return run_solar(*o); };
}

}  // namespace rayscan::cli
