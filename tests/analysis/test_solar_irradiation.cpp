// The sun map and the per-point irradiation sum against the per-instant models they stand for
// (clear_sky_irradiance, measured_irradiance_on_surface, themselves checked against GRASS r.sun
// in test_clear_sky.cpp), and the shadows of the solar job against analytic geometry: a box
// building on a plane, whose shadow is the box projected along the sun direction; the times the
// job states (read back as instants) and its refusal of a CRS from the file's header.
#include "rayscan/analysis/solar_irradiation.hpp"
#include "rayscan/analysis/site_location.hpp"
#include "rayscan/analysis/solar_position.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/site/copc.hpp"

#include "../common/crs_wkt.hpp"
#include "../common/run_command.hpp"
#include "small_copc.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <sys/stat.h>
#include <optional>
#include <sys/wait.h>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using namespace rayscan;
using namespace rayscan::analysis;

namespace {

// Clear-sky steps of one day at 45 N, sun from a simple analytic path (the model's inputs need
// not be SPA's here: the sum is checked against the per-instant model on the same inputs).
std::vector<SolarStep> clear_day(int doy) {
  std::vector<SolarStep> steps;
  const double decl = 23.44 * kDegree * std::sin(2 * std::numbers::pi * (284 + doy) / 365.0), lat = 45 * kDegree;
  for (double hour = 0.25; hour < 24; hour += 0.5) {
    const double h = (hour - 12) * 15 * kDegree;
    const double sin_el = std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(h);
    const double el = std::asin(sin_el);
    double az = std::atan2(std::sin(h), std::cos(h) * std::sin(lat) - std::tan(decl) * std::cos(lat)) + std::numbers::pi;
    SolarStep s;
    s.hours = 0.5;
    s.sun = {el, az};
    s.direction = direction_from_azimuth(az / kDegree, el / kDegree);
    s.ray_direction = s.direction;
    if (el > 0) {
      const HorizontalIrradiance hz = clear_sky_horizontal(el, doy, 3.0, 100.0);
      s.beam_normal = hz.beam / std::sin(el);
      s.diffuse_horizontal = hz.diffuse;
      s.global_horizontal = hz.global;
      s.kb = std::clamp(hz.beam / (extraterrestrial_irradiance(doy) * std::sin(el)), 0.0, 1.0);
    }
    steps.push_back(s);
  }
  return steps;
}

}  // namespace

TEST(SunMap, SectorZeroIsOneSectorPerSunStepAndSectorsHoldNearbyDirections) {
  const SunMap exact = build_sun_map(clear_day(172), 0.0);
  std::size_t up = 0;
  for (const SolarStep& s : exact.steps)
    if (s.beam_normal > 0) {
      EXPECT_EQ(exact.directions[s.sector], s.ray_direction);
      ++up;
    }
  EXPECT_EQ(exact.directions.size(), up);
  EXPECT_GT(up, 20u);
  const double sector = 10.0;
  const SunMap coarse = build_sun_map(clear_day(172), sector);
  EXPECT_LT(coarse.directions.size(), up);
  for (const SolarStep& s : coarse.steps)
    if (s.beam_normal > 0) {  // within a cell of 10 x 10 degrees: at most its diagonal apart
      const double angle = std::acos(std::min(1.0, glm::dot(coarse.directions[s.sector], s.direction))) / kDegree;
      EXPECT_LT(angle, sector * std::sqrt(2.0)) << s.sector;
    }
  EXPECT_THROW(build_sun_map(clear_day(1), -1.0), std::invalid_argument);
}

// Every sector size: the sums per sector (and the step-by-step path of sectors on both sides of
// a surface's plane) give what the model gives step by step, each step lit when its sector is.
TEST(PointIrradiation, EqualsTheSumOfThePerInstantClearSkyModel) {
 for (const double sector : {0.0, 3.0, 10.0, 30.0}) {
  const SunMap map = build_sun_map(clear_day(100), sector);
  const std::size_t nsec = map.directions.size(), words = (nsec + 63) / 64;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 60; ++trial) {
    // Level, tilted, steep and overhanging (facing down) surfaces.
    Vec3 n = trial == 0 ? Vec3(0, 0, 1) : glm::normalize(Vec3(u(rng), u(rng), trial < 50 ? std::abs(u(rng)) + 0.05 : u(rng)));
    std::vector<std::uint64_t> open(words, 0);
    for (std::size_t k = 0; k < nsec; ++k)
      if (trial < 2 || (rng() & 1)) open[k / 64] |= std::uint64_t(1) << (k % 64);
    const double convergence = trial % 3 == 0 ? 0.0 : 1.7;
    const PointIrradiation got = accumulate_irradiation(map, {}, n, convergence, 0.2, open);
    // The oracle: clear_sky_irradiance per step, with the surface's compass orientation and the
    // step's shadow.
    SurfaceOrientation surf = orientation_from_normal(n.x, n.y, n.z);
    surf.aspect -= convergence * kDegree;
    double beam = 0, diffuse = 0, reflected = 0, hours = 0;
    for (const SolarStep& s : map.steps) {
      if (!(s.sun.elevation > 0)) continue;
      ClearSkyInput in;
      in.sun = s.sun;
      in.day_of_year = 100;
      in.linke = 3.0;
      in.site_elevation_m = 100.0;
      in.surface = surf;
      in.albedo = 0.2;
      in.cos_incidence = glm::dot(n, s.direction);
      in.in_shadow = !((open[s.sector / 64] >> (s.sector % 64)) & 1u);
      const SurfaceIrradiance e = clear_sky_irradiance(in);
      beam += e.beam * s.hours;
      diffuse += e.diffuse * s.hours;
      reflected += e.reflected * s.hours;
      hours += e.beam > 0 && s.beam_normal >= kSunshineThreshold ? s.hours : 0.0;  // WMO's sunshine
    }
    EXPECT_NEAR(got.beam, beam, 1e-9 * (1 + beam)) << sector << " " << trial;
    EXPECT_NEAR(got.diffuse, diffuse, 1e-9 * (1 + diffuse)) << sector << " " << trial;
    EXPECT_NEAR(got.reflected, reflected, 1e-9 * (1 + reflected)) << sector << " " << trial;
    EXPECT_NEAR(got.sun_hours, hours, 1e-12) << sector << " " << trial;
    if (trial == 0) {
      EXPECT_GT(beam, 1000.0);  // a clear April day on level ground: kWh/m² of beam
    }
  }
 }
}

// The ground-reflected term follows the traced ground view: a level point whose sky is half
// hidden (a street canyon, the foot of a wall) receives albedo x the horizontal global x the
// hidden half, where the open plane receives nothing; a wall with its sky open keeps r.sun's half.
TEST(PointIrradiation, ReflectedTermFollowsTheTracedGroundView) {
  const SunMap map = build_sun_map(clear_day(172), 3.0);
  const std::size_t nsec = map.directions.size();
  // Sky directions: the zenith and three at 30 degrees elevation, one of them towards the east.
  const std::vector<Vec3> sky{{0, 0, 1}, {0.866, 0, 0.5}, {-0.866, 0, 0.5}, {0, -0.866, 0.5}};
  std::vector<std::uint64_t> open((nsec + sky.size() + 63) / 64, 0);
  for (std::size_t k = 0; k < nsec + sky.size(); ++k) open[k / 64] |= std::uint64_t(1) << (k % 64);
  double global_h = 0.0;  // the oracle's ground source: every step lit
  for (const SolarStep& s : map.steps) global_h += s.global_horizontal * s.hours;
  ASSERT_GT(global_h, 5000.0);
  const PointIrradiation level_open = accumulate_irradiation(map, sky, {0, 0, 1}, 0.0, 0.2, open);
  EXPECT_NEAR(level_open.reflected, 0.0, 1e-9);
  // Hide the zenith and the east direction: the level point sees (0 + 0 + 0.5 + 0.5) / (1 + 1.5).
  const std::size_t hide[] = {nsec + 0, nsec + 1};
  for (std::size_t k : hide) open[k / 64] &= ~(std::uint64_t(1) << (k % 64));
  const PointIrradiation level = accumulate_irradiation(map, sky, {0, 0, 1}, 0.0, 0.2, open);
  EXPECT_DOUBLE_EQ(level.sky_view, 1.0 / 2.5);
  EXPECT_NEAR(level.reflected, 0.2 * global_h * (1.0 - 1.0 / 2.5), 1e-9 * global_h);
  // A south wall with every direction open: the open tilted plane, (1 - cos 90) / 2 = 1/2.
  std::fill(open.begin(), open.end(), ~std::uint64_t(0));
  const PointIrradiation wall = accumulate_irradiation(map, sky, {0, -1, 0}, 0.0, 0.2, open);
  EXPECT_DOUBLE_EQ(wall.sky_view, 1.0);
  double diffuse_h = 0.0;  // the ground source of a surface the sun never reaches
  for (const SolarStep& s : map.steps) diffuse_h += s.diffuse_horizontal * s.hours;
  EXPECT_GE(wall.reflected, 0.2 * 0.5 * diffuse_h * (1 - 1e-12));
  EXPECT_LE(wall.reflected, 0.2 * 0.5 * global_h * (1 + 1e-12));
}

TEST(PointIrradiation, SkyViewIsTheCosineWeightedOpenShare) {
  const std::vector<Vec3> sky{{0, 0, 1}, {1, 0, 0}, {0, 0.6, 0.8}, {0, -0.6, 0.8}};
  SunMap map;  // no sun: only the sky bits
  std::vector<std::uint64_t> open{0b0101};  // directions 0 and 2 open
  const PointIrradiation p = accumulate_irradiation(map, sky, {0, 0, 1}, 0.0, 0.2, open);
  EXPECT_DOUBLE_EQ(p.sky_view, (1.0 + 0.8) / (1.0 + 0.0 + 0.8 + 0.8));
  EXPECT_DOUBLE_EQ(accumulate_irradiation(map, {}, {0, 0, 1}, 0.0, 0.2, open).sky_view, 1.0);
}

// A 10 x 10 x 10 m box on a 60 x 60 m plane; at 10:00 UTC+1 on 2026-03-20 at 48 N, 11 E the
// shadowed ground points must be those whose ray to the sun meets the box. Every point stands for
// a sphere or disc of about the spacing, which widens a shadow by about that much: the box is
// sampled at 5 cm (the spacing of a terrestrial scan), the ground at 25 cm.
TEST(SolarJob, ShadowOfABoxIsTheBoxProjectedAlongTheSun) {
  PointCloud cloud;
  for (double x = -30; x <= 30; x += 0.25)
    for (double y = -30; y <= 30; y += 0.25)
      // Not on the footprint's outline either: there the ground meets the wall's foot, a corner
      // that belongs to both surfaces.
      if (!(std::abs(x) <= 5 && std::abs(y) <= 5)) cloud.positions.emplace_back(x, y, 0.0);
  const std::size_t ground = cloud.positions.size();
  const double step = 0.05;
  for (int ia = 0; ia <= 200; ++ia)
    for (int iz = 1; iz <= 200; ++iz) {  // four walls
      const double a = -5 + ia * step, z = iz * step;
      cloud.positions.emplace_back(a, -5, z);
      cloud.positions.emplace_back(a, 5, z);
      cloud.positions.emplace_back(-5, a, z);
      cloud.positions.emplace_back(5, a, z);
    }
  const std::size_t roof_centre = cloud.positions.size() + 99 * 199 + 99;  // (0, 0, 10)
  for (int i = 1; i < 200; ++i)
    for (int j = 1; j < 200; ++j) cloud.positions.emplace_back(-5 + i * step, -5 + j * step, 10.0);  // roof
  for (const char* primitive : {"surfel", "sphere"}) {
    jobs::SolarJobOptions o;
    o.cloud = &cloud;
    o.latitude = 48.0;
    o.longitude = 11.0;
    o.at = "2026-03-20T10:00:00+01:00";
    o.primitive = primitive;
    o.control.threads = 2;
    o.sky_rays = 0;  // shadows only
    if (std::getenv("SOLAR_LOG")) o.control.log = [](const std::string& s) { std::printf("%s\n", s.c_str()); };
    const jobs::SolarJobResult r = jobs::run_solar(o);
    ASSERT_TRUE(r.sun);
    const Vec3 s = direction_from_azimuth(r.sun->azimuth_deg, r.sun->elevation_deg);
    ASSERT_GT(s.z, 0.3);
    const std::vector<double>* shadow = nullptr;
    for (const ScalarField& f : r.cloud.scalars)
      if (f.name == "in_shadow") shadow = &f.values;
    ASSERT_TRUE(shadow);
    // Analytic: the ray from (x, y, 0) along s meets the box [-5, 5]^2 x [0, 10] (slab test).
    std::size_t both = 0, either = 0;
    for (std::size_t i = 0; i < ground; ++i) {
      const Vec3& p = cloud.positions[i];
      double t0 = 0, t1 = 1e9;
      for (int a = 0; a < 3; ++a) {
        const double lo = a == 2 ? 0.0 : -5.0, hi = a == 2 ? 10.0 : 5.0;
        if (std::abs(s[a]) < 1e-12) {
          if (p[a] < lo || p[a] > hi) t1 = -1;
          continue;
        }
        double ta = (lo - p[a]) / s[a], tb = (hi - p[a]) / s[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      const bool analytic = t0 < t1 - 1e-9;  // a ray that only touches the box (t0 = t1) passes
      const bool got = (*shadow)[i] > 0.5;
      both += analytic && got;
      either += analytic || got;
    }
    ASSERT_GT(either, 1000u);
    const double iou = double(both) / double(either);
    std::printf("box shadow, %s: IoU %.4f (%zu of %zu ground points)\n", primitive, iou, both, either);
    EXPECT_GE(iou, 0.98) << primitive << ": IoU " << iou << " (" << both << " of " << either << ")";
    // The middle of the roof is in the sun; so are the walls the sun faces (south and east), and
    // the walls facing away from it (north and west) are in the shadow of the box itself.
    EXPECT_NEAR(cloud.positions[roof_centre].x, 0.0, 1e-9);
    EXPECT_EQ((*shadow)[roof_centre], 0.0) << primitive;
    std::size_t south_lit = 0, north_dark = 0, south = 0, north = 0;
    for (std::size_t i = ground; i < roof_centre; ++i) {
      const Vec3& p = cloud.positions[i];
      if (p.z < 0.5 || p.z > 9.5 || std::abs(p.x) > 4.5) continue;  // away from the edges
      if (p.y == -5.0) ++south, south_lit += (*shadow)[i] == 0.0;
      if (p.y == 5.0) ++north, north_dark += (*shadow)[i] == 1.0;
    }
    std::printf("box walls, %s: south %.4f lit, north %.4f in shadow\n", primitive, double(south_lit) / double(south),
                double(north_dark) / double(north));
    EXPECT_GT(double(north_dark) / double(north), 0.99) << primitive;
    if (std::string(primitive) == "sphere") {
      EXPECT_GT(double(south_lit) / double(south), 0.99);
    }
  }
}

// The site's place from autzen's CRS (NAD83(HARN) / Oregon GIC Lambert, in feet) against
// GDAL's own command-line transformation, and the meridian convergence against the Lambert conic's
// gamma = n (lambda - lambda0), n = (sin phi1 + sin phi2) / 2 for the standard parallels (Snyder
// 1987, "Map projections: a working manual", eqs. 15-3 and 14-9 on the sphere; the ellipsoid's n
// differs by less than 1e-4 here).
TEST(SiteLocation, AutzenMatchesGdaltransformAndTheLambertConvergence) {
  const PointCloud cloud = io::read_point_cloud(std::string(RAYSCAN_SOURCE_DIR) + "/scenes/data/autzen_trim.las");
  ASSERT_FALSE(cloud.crs_wkt.empty());
  const Vec3 p(636226.5, 849106.5, 420.0);
  const SiteLocation loc = locate_site(cloud.crs_wkt, p);
  // gdaltransform with the file's own WKT.
  const std::string wkt = testing::TempDir() + "/autzen.wkt";
  std::FILE* f = std::fopen(wkt.c_str(), "w");
  ASSERT_TRUE(f);
  std::fputs(cloud.crs_wkt.c_str(), f);
  std::fclose(f);
  const std::string cmd = "echo '636226.5 849106.5' | gdaltransform -s_srs '" + wkt + "' -t_srs EPSG:4326 -output_xy";
  std::FILE* pipe = popen(cmd.c_str(), "r");
  ASSERT_TRUE(pipe);
  double lon = 0, lat = 0;
  const int got = std::fscanf(pipe, "%lf %lf", &lon, &lat);
  pclose(pipe);
  if (got != 2) GTEST_SKIP() << "gdaltransform is not available";
  EXPECT_NEAR(loc.longitude_deg, lon, 1e-9);
  EXPECT_NEAR(loc.latitude_deg, lat, 1e-9);
  OGRSpatialReference srs;
  ASSERT_EQ(srs.importFromWkt(cloud.crs_wkt.c_str()), OGRERR_NONE);
  EXPECT_NEAR(loc.metres_per_unit, 0.3048, 1e-6);  // the file's WKT: the foot
  EXPECT_NEAR(loc.elevation_m, 420.0 * loc.metres_per_unit, 1e-9);
  const double phi1 = srs.GetNormProjParm(SRS_PP_STANDARD_PARALLEL_1) * kDegree;
  const double phi2 = srs.GetNormProjParm(SRS_PP_STANDARD_PARALLEL_2) * kDegree;
  const double lambda0 = srs.GetNormProjParm(SRS_PP_CENTRAL_MERIDIAN);
  const double gamma = (std::sin(phi1) + std::sin(phi2)) / 2.0 * (lon - lambda0);  // true -> grid north
  EXPECT_NEAR(loc.convergence_deg, -gamma, 0.005);  // ours: grid -> true north, clockwise
  EXPECT_GT(loc.convergence_deg, 1.0);  // west of the central meridian: grid north points west of true north
  EXPECT_THROW(locate_site("", p), std::invalid_argument);
  // degrees: no sun directions
  EXPECT_THROW(locate_site(rayscan::test::crs_wkt("EPSG:4326"), p), std::invalid_argument);
}

// A weather file drives the sky: an overcast day (GHI = DHI = 100 W/m², no direct sun) on an open
// level plane gives exactly 24 x 100 Wh/m² of diffuse in a day (Muneer's ratio is 1 on the
// level, the sky view 1, nothing reflected onto it), and no sun hours.
TEST(SolarJob, AnOvercastWeatherDayOnOpenGroundIsTheSumOfItsDiffuse) {
  const std::string epw = testing::TempDir() + "/overcast.epw";
  {
    std::FILE* f = std::fopen(epw.c_str(), "w");
    ASSERT_TRUE(f);
    std::fputs("LOCATION,Test,CA,USA,TMY3,724940,37.62,-122.40,-8.0,2.0\n"
               "DESIGN CONDITIONS,0\nTYPICAL/EXTREME PERIODS,0\nGROUND TEMPERATURES,0\n"
               "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0\nCOMMENTS 1,overcast test year\nCOMMENTS 2,\n"
               "DATA PERIODS,1,1,Data,Sunday, 1/ 1,12/31\n",
               f);
    constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    for (int m = 1; m <= 12; ++m)
      for (int d = 1; d <= kDays[m - 1]; ++d)
        for (int h = 1; h <= 24; ++h)
          std::fprintf(f,
                       "1999,%d,%d,%d,60,?9?9?9?9,10.0,5.0,70,101325,0,0,300,100,0,100,0,0,0,0,180,2.0,10,10,"
                       "10.0,1000,9,999999999,0,0.1,0,0,999,0.0,0.0\n",
                       m, d, h);
    std::fclose(f);
  }
  PointCloud cloud;
  for (double x = -10; x <= 10; x += 0.5)
    for (double y = -10; y <= 10; y += 0.5) cloud.positions.emplace_back(x, y, 0.0);
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 37.62;
  o.longitude = -122.40;
  o.start = "2026-03-10";
  o.end = "2026-03-10";
  o.weather = epw;
  o.control.threads = 2;
  const jobs::SolarJobResult r = jobs::run_solar(o);
  EXPECT_EQ(r.steps, 24u);
  for (const ScalarField& f : r.cloud.scalars) {
    const double want = f.name == "solar_global" || f.name == "solar_diffuse" ? 2.4 : f.name == "sky_view" ? 1.0 : 0.0;
    for (std::size_t i = 0; i < f.values.size(); i += 97) EXPECT_NEAR(f.values[i], want, 1e-9) << f.name << " " << i;
  }
  o.start.clear();
  o.end.clear();
  o.at = "2026-03-10T12:00:00Z";
  EXPECT_THROW(jobs::run_solar(o), std::invalid_argument);  // a weather file needs a period
}

// A typical-year weather file laid on calendar years day for day. Each record is an overcast hour
// (no direct sun) whose diffuse encodes its month, day and hour, so on open level ground the
// period's diffuse is exactly the sum of the mapped records' DHI (the overcast test above): a day
// counted twice, shifted or dropped changes the sum. The oracle is that sum, computed here from
// the dates the period covers.
namespace solar_epw_years {

double dhi_of(int month, int day, int hour) { return month * 100 + day * 3 + hour; }

// A year of hourly records at UTC-8, with 29 February when `leap_day` (the year field 1999, as a
// typical year's February may carry).
std::string write_epw(const std::string& name, bool leap_day) {
  const std::string path = testing::TempDir() + "/" + name;
  std::FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_TRUE(f);
  std::fputs("LOCATION,Test,CA,USA,TMY3,724940,37.62,-122.40,-8.0,2.0\n"
             "DESIGN CONDITIONS,0\nTYPICAL/EXTREME PERIODS,0\nGROUND TEMPERATURES,0\n"
             "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0\nCOMMENTS 1,day-coded test year\nCOMMENTS 2,\n"
             "DATA PERIODS,1,1,Data,Sunday, 1/ 1,12/31\n",
             f);
  constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  for (int m = 1; m <= 12; ++m)
    for (int d = 1; d <= kDays[m - 1] + (m == 2 && leap_day); ++d)
      for (int h = 1; h <= 24; ++h) {
        const double dhi = dhi_of(m, d, h);
        std::fprintf(f,
                     "1999,%d,%d,%d,60,?9?9?9?9,10.0,5.0,70,101325,0,0,300,%.0f,0,%.0f,0,0,0,0,180,2.0,10,10,"
                     "10.0,1000,9,999999999,0,0.1,0,0,999,0.0,0.0\n",
                     m, d, h, dhi, dhi);
      }
  std::fclose(f);
  return path;
}

// The diffuse (kWh/m²) of the days from..to (inclusive) as the file gives them, `feb29` standing
// for 29 February's month/day in the file (28 when the file has none).
double expected_kwh(std::chrono::sys_days from, std::chrono::sys_days to, int feb29) {
  double wh = 0.0;
  for (std::chrono::sys_days d = from; d <= to; d += std::chrono::days{1}) {
    const std::chrono::year_month_day ymd(d);
    int month = int(unsigned(ymd.month())), day = int(unsigned(ymd.day()));
    if (month == 2 && day == 29) day = feb29;
    for (int h = 1; h <= 24; ++h) wh += dhi_of(month, day, h);
  }
  return wh / 1000.0;
}

struct WeatherRun {
  jobs::SolarJobResult result;
  std::vector<std::string> log;
  double diffuse = 0.0;  // the first point's, kWh/m²
};

WeatherRun run_weather(const std::string& epw, const std::string& start, const std::string& end) {
  static PointCloud cloud;
  if (cloud.positions.empty())
    for (double x = -2; x <= 2; x += 1)
      for (double y = -2; y <= 2; y += 1) cloud.positions.emplace_back(x, y, 0.0);
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 37.62;
  o.longitude = -122.40;
  o.utc_offset = -8.0;  // the file's zone: the period's days are the file's days
  o.start = start;
  o.end = end;
  o.weather = epw;
  o.control.threads = 2;
  WeatherRun out;
  o.control.log = [&out](const std::string& line) { out.log.push_back(line); };
  out.result = jobs::run_solar(o);
  for (const ScalarField& f : out.result.cloud.scalars)
    if (f.name == "solar_diffuse") out.diffuse = f.values.at(0);
  return out;
}

bool logged(const WeatherRun& r, const std::string& text) {
  return std::any_of(r.log.begin(), r.log.end(), [&](const std::string& l) { return l.find(text) != l.npos; });
}

}  // namespace solar_epw_years

TEST(SolarJob, AWeatherPeriodIntoTheNextYearTakesEachDayOnce) {
  using namespace solar_epw_years;
  using namespace std::chrono;
  const std::string epw = write_epw("year_coded.epw", false);
  // From a leap year into the next, and the same dates a year later: 12 days, 288 hours each.
  const WeatherRun leap = run_weather(epw, "2024-12-25", "2025-01-05");
  const WeatherRun plain = run_weather(epw, "2025-12-25", "2026-01-05");
  EXPECT_EQ(leap.result.steps, 288u);
  EXPECT_EQ(plain.result.steps, 288u);
  const double want = expected_kwh(sys_days{2024y / 12 / 25}, sys_days{2025y / 1 / 5}, 28);
  EXPECT_NEAR(leap.diffuse, want, 1e-9);
  EXPECT_NEAR(plain.diffuse, want, 1e-9);
  EXPECT_FALSE(logged(leap, "29 February"));
}

TEST(SolarJob, ALeapYearWithoutTheFilesLeapDayRepeats28February) {
  using namespace solar_epw_years;
  using namespace std::chrono;
  const std::string epw = write_epw("no_leap_day.epw", false);
  const WeatherRun r = run_weather(epw, "2024-02-28", "2024-03-01");
  EXPECT_EQ(r.result.steps, 72u);
  EXPECT_NEAR(r.diffuse, expected_kwh(sys_days{2024y / 2 / 28}, sys_days{2024y / 3 / 1}, 28), 1e-9);
  EXPECT_TRUE(logged(r, "the file has no 29 February: 24 records of 28 February repeated for it"));
  // A whole leap year: every hour of it.
  EXPECT_EQ(run_weather(epw, "2024-01-01", "2024-12-31").result.steps, 8784u);
}

TEST(SolarJob, AWeatherFileWithALeapDayServesEveryYear) {
  using namespace solar_epw_years;
  using namespace std::chrono;
  const std::string epw = write_epw("leap_day.epw", true);
  // A leap year takes the file's own 29 February.
  const WeatherRun leap = run_weather(epw, "2024-02-28", "2024-03-01");
  EXPECT_EQ(leap.result.steps, 72u);
  EXPECT_NEAR(leap.diffuse, expected_kwh(sys_days{2024y / 2 / 28}, sys_days{2024y / 3 / 1}, 29), 1e-9);
  EXPECT_FALSE(logged(leap, "29 February"));
  // A year without one leaves it out: 28 February is followed by 1 March.
  const WeatherRun plain = run_weather(epw, "2026-02-27", "2026-03-02");
  EXPECT_EQ(plain.result.steps, 96u);
  EXPECT_NEAR(plain.diffuse, expected_kwh(sys_days{2026y / 2 / 27}, sys_days{2026y / 3 / 2}, 29), 1e-9);
  EXPECT_TRUE(logged(plain, "24 records of the file's 29 February left out (not a leap year)"));
  // A period away from February is not concerned.
  const WeatherRun june = run_weather(epw, "2026-06-01", "2026-06-07");
  EXPECT_EQ(june.result.steps, 168u);
  EXPECT_NEAR(june.diffuse, expected_kwh(sys_days{2026y / 6 / 1}, sys_days{2026y / 6 / 7}, 29), 1e-9);
  EXPECT_FALSE(logged(june, "29 February"));
}

// Times before 1 AD are written as ISO 8601 writes them (a sign and four digits) and read back
// to the same instant.
TEST(SolarTime, NegativeYearsAreWrittenAsIso8601AndReadBack) {
  for (const char* text : {"-0001-03-01T12:00:00Z", "-2000-01-01T00:00:00Z", "0005-07-04T01:02:03Z"}) {
    const UtcInstant t = parse_iso8601_utc(text);
    const std::string written = jobs::format_iso8601(double(t.unix_seconds), 0.0);
    EXPECT_EQ(written, text);
    EXPECT_EQ(parse_iso8601_utc(written).unix_seconds, t.unix_seconds);
    const std::string east = jobs::format_iso8601(double(t.unix_seconds), 5.5);
    EXPECT_EQ(parse_iso8601_utc(east).unix_seconds, t.unix_seconds) << east;
  }
  EXPECT_EQ(jobs::format_iso8601(double(parse_iso8601_utc("-0001-03-01T12:00Z").unix_seconds), -1.0),
            "-0001-03-01T11:00:00-01:00");
  // Through the command: the printed time is the given one and is accepted as input.
  const std::string cmd = std::string(RAYSCAN_BIN) + " solar position --lat 0 --lon 0 --json --time ";
  const auto first = rayscan::test::run_command(cmd + "-0001-03-01T12:00Z", false);
  ASSERT_EQ(first.code, 0) << first.out;
  const std::string printed = nlohmann::json::parse(first.out)["time"];
  EXPECT_EQ(printed, "-0001-03-01T12:00:00Z");
  const auto again = rayscan::test::run_command(cmd + printed, false);
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_EQ(again.out, first.out);
}

// Bad input on the command line: one line on stderr naming the flag or the file, exit code 2, no
// output written.
TEST(SolarCli, BadInputIsOneLineAndExitCodeTwo) {
  const std::string las = std::string(RAYSCAN_SOURCE_DIR) + "/scenes/data/autzen_trim.las";
  const std::string dir = testing::TempDir();
  const std::string bad_epw = dir + "/bad.epw";
  {
    std::FILE* f = std::fopen(bad_epw.c_str(), "w");
    ASSERT_TRUE(f);
    std::fputs("LOCATION,Test,CA,USA,TMY3,724940,north,-122.40,-8.0,2.0\n", f);
    std::fclose(f);
  }
  struct Case {
    std::string args, expect;
  } cases[] = {
      {"--start 2026-13-01 --end 2026-12-31", "--start"},
      {"--start 2026-01-01 --end 2025-12-31", "--end"},
      {"--start 2026-01-01 --end 2026-01-02 --step 50min", "whole number of --steps"},
      {"--start 2026-01-01 --end 2026-01-02 --step 2h", "at most 1h"},
      {"--at 2026-06-21T12:00Z --start 2026-01-01", "--at"},
      {"--start 2026-01-01 --end 2026-01-31 --weather " + bad_epw, "bad.epw: line 1"},
      {"--start 2026-01-01 --end 2026-01-31 --linke 1,2,3", "--linke"},
      {"--at 2026-06-21T12:00Z --raster " + dir + "/x.png --cell 3", "--raster"},
      {"--day 2026-06-21 --raster " + dir + "/f.tif --cell 3 --preview " + dir + "/f.png",
       "--preview does not apply to --day"},
      {"--at 2026-06-21T12:00Z --cache 12Q", "--cache: "},
      {"--at 9999-01-01T00:00Z", "--at: year 9999 is not in -2000..6000, the years SPA is valid for"},
      {"--start 5990-01-01 --end 6010-01-01", "--end: year 6010 is not in -2000..6000"},
      {"--start 2026-06-21 --end 2226-06-21", "time steps of 1h (114 years); use a shorter period"},
      {"--start 2026-06-21 --end 2226-06-21 --step 30min", "use a shorter period or a longer --step (at most 1h)"},
  };
  for (const Case& c : cases) {
    const std::string out = dir + "/solar_cli_out.las";
    std::remove(out.c_str());
    const std::string cmd = std::string(RAYSCAN_BIN) + " solar " + las + " " + c.args + " -q -o " + out + " 2>&1";
    std::FILE* p = popen(cmd.c_str(), "r");
    ASSERT_TRUE(p);
    std::string text;
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) text += buf;
    const int status = pclose(p);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 2) << c.args << ": " << text;
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << c.args << ": " << text;
    EXPECT_NE(text.find(c.expect), std::string::npos) << c.args << ": " << text;
    EXPECT_FALSE(std::filesystem::exists(out)) << c.args;
  }
}

// Options that only a period uses (--monthly, --step) or only a day of shadows (--every) are
// refused with the other kind of run, which would ignore them, in one line naming both options,
// exit 2, before the cloud is read: the cloud named does not exist, and a combination that is
// accepted fails on that file instead.
TEST(SolarCli, PeriodAndDayOptionsAreRefusedWhereTheRunWouldIgnoreThem) {
  const std::string missing = testing::TempDir() + "/no_such_cloud.las";
  const auto run = [&](const std::string& args) {
    return rayscan::test::run_command(std::string(RAYSCAN_BIN) + " solar '" + missing + "' " + args + " --json -q");
  };
  const std::pair<const char*, const char*> refused[] = {
      {"--at 2026-06-21T12:00Z --monthly", "--monthly needs a period (--start, --end), not --at"},
      {"--day 2026-06-21 --monthly", "--monthly needs a period (--start, --end), not --day"},
      {"--at 2026-06-21T12:00Z --step 15min", "--step needs a period (--start, --end), not --at"},
      {"--day 2026-06-21 --step 15min", "--step needs a period (--start, --end), not --day (its instants: --every)"},
      {"--start 2026-06-21 --end 2026-06-22 --every 15min",
       "--every needs a day of shadows (--day), not a period (--start, --end)"},
      {"--at 2026-06-21T12:00Z --every 15min", "--every needs a day of shadows (--day), not --at"},
  };
  for (const auto& [args, line] : refused) {
    const auto r = run(args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_EQ(r.out, std::string("rayscan solar: ") + line + "\n") << args;
  }
  for (const char* args : {"--start 2026-06-21 --end 2026-06-22 --monthly --step 15min",
                           "--day 2026-06-21 --every 15min", "--at 2026-06-21T12:00Z"}) {
    const auto r = run(args);
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.out.find("no_such_cloud.las"), std::string::npos) << args << ": " << r.out;
  }
}

// Integer options are decimal ("08" is eight, which C's base-0 reading refuses as octal) and an
// unknown --index is refused when the options are parsed: the cloud named does not exist, so an
// option accepted leaves the error to that file, and one refused names itself instead.
TEST(SolarCli, IntegersAreDecimalAndTheIndexIsCheckedWhenParsed) {
  const std::string missing = testing::TempDir() + "/no_such_cloud.las";
  const std::string base = std::string(RAYSCAN_BIN) + " solar '" + missing + "' --at 2026-06-21T12:00Z --json -q ";
  auto r = rayscan::test::run_command(base + "--sky-rays 08 --threads 010");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("no_such_cloud.las"), std::string::npos) << r.out;
  r = rayscan::test::run_command(base + "--sky-rays 0x10");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out.rfind("rayscan solar: --sky-rays: expected an integer in [0, 4096], got '0x10'", 0), 0u) << r.out;
  r = rayscan::test::run_command(base + "--index octree-fast");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out.rfind("rayscan solar: --index: expected octree-adaptive, octree-layered, octree-fixed, kdtree or "
                        "brute, got 'octree-fast'",
                        0),
            0u)
      << r.out;
}

// The preview's default path (the raster's name with .png) is checked with the other outputs
// before any work: a folder there is refused before the points are traced, so the run logs one
// line, the error, and writes no GeoTIFF. --no-preview, which writes no preview and so does not
// refuse the folder, traces and writes the map.
TEST(SolarCli, DefaultPreviewPathIsCheckedBeforeTheTrace) {
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_default_preview";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "shadow.png");  // a folder where the default preview goes
  const std::filesystem::path cloud = dir / "ground.ply", tif = dir / "shadow.tif", png = dir / "shadow.png";
  PointCloud ground;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) ground.positions.emplace_back(i, j, 0.0);
  io::write_point_cloud(cloud, ground);
  const std::string base = std::string(RAYSCAN_BIN) + " solar '" + cloud.string() +
                           "' --lat 44 --lon -123 --at 2026-06-21T13:00-07:00 --cell 3 --raster '" + tif.string() +
                           "'";
  const auto r = rayscan::test::run_command(base);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--preview '" + png.string() + "': is a folder, expected a file name"), std::string::npos)
      << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(r.out.find("traced"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(tif));
  const auto ok = rayscan::test::run_command(base + " --no-preview");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_NE(ok.out.find("traced 400 points"), std::string::npos) << ok.out;
  EXPECT_TRUE(std::filesystem::is_regular_file(tif));
  EXPECT_TRUE(std::filesystem::is_directory(png));
  std::filesystem::remove_all(dir);
}

// A day of shadows writes its frames (RASTER_HHMM.tif and .png), not the raster's name, and each
// is checked with the other outputs before any work: a folder where the noon frame or its preview
// goes is refused at once, naming --raster and that frame, before the cloud is opened (a missing
// cloud goes unnamed) or anything is logged or written. Without previews the folder at the
// preview's name is no output: the run writes the frames, noon's at the name the check refused.
// The day's sun_hours count every sunny instant, whatever the beam, and say so (not WMO's
// threshold of a period's). Oracle: the frames the run writes, listed in the folder, and the
// JSON and the PLY header it writes.
TEST(SolarCli, ADaysFramesAreCheckedBeforeAnyWork) {
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_day_frames_checked";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "day_1200.tif");
  const std::filesystem::path cloud = dir / "ground.ply", tif = dir / "day.tif", ply = dir / "day.ply";
  PointCloud ground;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) ground.positions.emplace_back(i, j, 0.0);
  io::write_point_cloud(cloud, ground);
  const std::string args = "' --lat 44 --lon -123 --utc-offset -7 --day 2026-06-21 --every 1h --cell 3 --raster '" +
                           tif.string() + "'";
  const std::string solar = std::string(RAYSCAN_BIN) + " solar '";
  const auto frames_written = [&] {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string().rfind("day_", 0) == 0)
        names.push_back(e.path().filename().string());
    return names;
  };
  const auto refused = [&](const std::string& cmd, const std::filesystem::path& frame) {
    const auto r = rayscan::test::run_command(cmd);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(r.out, "rayscan solar: --raster '" + frame.string() + "': is a folder, expected a file name\n");
    EXPECT_TRUE(frames_written().empty());
  };
  refused(solar + (dir / "missing.las").string() + args, dir / "day_1200.tif");
  refused(solar + cloud.string() + args, dir / "day_1200.tif");
  std::filesystem::remove(dir / "day_1200.tif");
  std::filesystem::create_directories(dir / "day_1200.png");
  refused(solar + cloud.string() + args, dir / "day_1200.png");

  const auto r = rayscan::test::run_command(solar + cloud.string() + args + " --no-preview -q --json -o '" +
                                            ply.string() + "'", false);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "day_1200.tif"));
  EXPECT_TRUE(std::filesystem::is_directory(dir / "day_1200.png"));
  EXPECT_GE(frames_written().size(), 10u);  // 05:00 .. 20:00 local time at 44 N in June
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["fields"]["sun_hours"]["description"], "hours of direct sun, any DNI, h") << r.out;
  std::ifstream in(ply, std::ios::binary);
  std::string line, comment;
  while (std::getline(in, line) && line != "end_header")
    if (line.rfind("comment field scalar_sun_hours: ", 0) == 0) comment = line;
  EXPECT_EQ(comment, "comment field scalar_sun_hours: hours of direct sun, any DNI, h");
  std::filesystem::remove_all(dir);
}

// A day of shadows: a frame for every instant with the sun up (numbered by the clock), and per
// point the hours of sun and of shadow; open ground far from a wall has every sunny hour, the
// ground at the wall's north foot has shadow all day at this latitude.
TEST(SolarJob, ADayOfShadowsWritesAFramePerSunnyInstant) {
  PointCloud cloud;
  for (double x = -20; x <= 20; x += 0.5)
    for (double y = -20; y <= 20; y += 0.5) cloud.positions.emplace_back(x, y, 0.0);
  for (double x = -10; x <= 10; x += 0.1)
    for (double z = 0.1; z <= 8.0; z += 0.1) cloud.positions.emplace_back(x, 0.0, z);  // an east-west wall
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.day = "2026-12-21";
  o.every = "1h";
  o.utc_offset = 1.0;
  o.raster = testing::TempDir() + "/winter.tif";
  o.cell = 1.0;
  o.control.threads = 2;
  const jobs::SolarJobResult r = jobs::run_solar(o);
  // Winter solstice at 48 N: the sun is up from about 08:00 to 16:20 local time.
  EXPECT_GE(r.steps, 8u);
  EXPECT_LE(r.steps, 9u);
  EXPECT_EQ(r.written.size(), 2 * r.steps);  // a GeoTIFF and a PNG per instant
  EXPECT_TRUE(std::filesystem::exists(testing::TempDir() + "/winter_1200.tif"));
  EXPECT_TRUE(std::filesystem::exists(testing::TempDir() + "/winter_1200.png"));
  const std::vector<double>*sun = nullptr, *shadow = nullptr;
  for (const ScalarField& f : r.cloud.scalars) {
    if (f.name == "sun_hours") sun = &f.values;
    if (f.name == "shadow_hours") shadow = &f.values;
  }
  ASSERT_TRUE(sun && shadow);
  const auto at = [&](double x, double y) {
    std::size_t best = 0;
    for (std::size_t i = 0; i < cloud.positions.size(); ++i)
      if (glm::length(cloud.positions[i] - Vec3(x, y, 0)) < glm::length(cloud.positions[best] - Vec3(x, y, 0))) best = i;
    return best;
  };
  const std::size_t open = at(-18, -18), north_foot = at(0, 2);
  EXPECT_DOUBLE_EQ((*sun)[open], double(r.steps));
  EXPECT_DOUBLE_EQ((*shadow)[open], 0.0);
  EXPECT_DOUBLE_EQ((*sun)[north_foot], 0.0);
  EXPECT_DOUBLE_EQ((*shadow)[north_foot], double(r.steps));
}

// --monthly: each month's field adds up to the period's global irradiation, and a month alone
// gives the same field as that month's part of a longer period (its steps never share a sector
// with another month's).
TEST(SolarJob, MonthlyFieldsAddUpAndMatchAMonthAlone) {
  PointCloud cloud;
  for (double x = -10; x <= 10; x += 1.0)
    for (double y = -10; y <= 10; y += 1.0) cloud.positions.emplace_back(x, y, 0.02 * x * x);
  for (double z = 0.25; z <= 6; z += 0.25) cloud.positions.emplace_back(0.0, 3.0, z);  // a pole
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.start = "2026-01-20";
  o.end = "2026-03-10";
  o.monthly = true;
  o.control.threads = 2;
  const jobs::SolarJobResult all = jobs::run_solar(o);
  const auto field = [](const jobs::SolarJobResult& r, const std::string& name) -> const std::vector<double>& {
    for (const ScalarField& f : r.cloud.scalars)
      if (f.name == name) return f.values;
    static const std::vector<double> none;
    ADD_FAILURE() << "no field " << name;
    return none;
  };
  for (const ScalarField& f : all.cloud.scalars) EXPECT_NE(f.name, "solar_global_04");  // April not touched
  const std::vector<double>&jan = field(all, "solar_global_01"), &feb = field(all, "solar_global_02"),
                    &mar = field(all, "solar_global_03"), &total = field(all, "solar_global");
  ASSERT_EQ(jan.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) EXPECT_NEAR(jan[i] + feb[i] + mar[i], total[i], 1e-9 * total[i]);
  o.start = "2026-02-01";
  o.end = "2026-02-28";
  const jobs::SolarJobResult february = jobs::run_solar(o);
  const std::vector<double>& alone = field(february, "solar_global");
  for (std::size_t i = 0; i < cloud.size(); ++i) EXPECT_NEAR(alone[i], feb[i], 1e-9 * feb[i]) << i;
  EXPECT_GT(feb[0], 10.0);  // kWh/m² in a February at 48 N
}

// A COPC file is queried in place (io::CopcIndex; its points read as the output cloud, no tree
// built). Oracle: the same job on the same file read whole (copc_in_place = false: the in-memory
// octree). An instant (shadows and irradiance) and a day of 3-hour steps (sun map, sky map, the
// sums), spheres and surfels, every field bit for bit, with a cache far smaller than the file.
TEST(SolarJob, CopcInPlaceEqualsTheFileReadWhole) {
  const std::filesystem::path& copc = rayscan::analysis::test::small_copc();
  const io::CopcIndex probe(copc);
  struct Case {
    const char* at;
    const char* day;
    const char* primitive;
  } cases[] = {{"2026-06-21T18:30:00Z", "", "sphere"}, {"", "2026-06-21", "sphere"}, {"2026-06-21T18:30:00Z", "", "surfel"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.at) + c.day + " " + c.primitive);
    jobs::SolarJobOptions o;
    o.cloud_file = copc;
    o.latitude = 44.05;  // autzen, Eugene (Oregon)
    o.longitude = -123.07;
    o.at = c.at;
    if (*c.day) {
      o.start = o.end = c.day;
      o.step = "1h";  // (the longest step: --step is at most 1h)
    }
    o.primitive = c.primitive;
    o.sky_rays = std::string(c.primitive) == "surfel" ? 0 : 8;  // (surfels: the shadow alone, for time)
    o.control.threads = 2;
    o.cache_bytes = std::size_t{256} << 10;
    o.copc_in_place = false;
    const jobs::SolarJobResult whole = jobs::run_solar(o);
    o.copc_in_place = true;
    const jobs::SolarJobResult in_place = jobs::run_solar(o);
    EXPECT_EQ(whole.copc_decodes, 0u);
    EXPECT_GT(in_place.copc_decodes, probe.node_count());  // a small cache: evicted nodes decoded again
    EXPECT_EQ(in_place.radius.radius, whole.radius.radius);
    EXPECT_EQ(in_place.sectors, whole.sectors);
    ASSERT_EQ(in_place.cloud.size(), whole.cloud.size());
    EXPECT_EQ(in_place.cloud.positions, whole.cloud.positions);
    ASSERT_EQ(in_place.cloud.scalars.size(), whole.cloud.scalars.size());
    bool varies = false;
    for (std::size_t f = 0; f < whole.cloud.scalars.size(); ++f) {
      const std::vector<double>&a = in_place.cloud.scalars[f].values, &w = whole.cloud.scalars[f].values;
      EXPECT_EQ(in_place.cloud.scalars[f].name, whole.cloud.scalars[f].name);
      ASSERT_EQ(a.size(), w.size());
      EXPECT_EQ(std::memcmp(a.data(), w.data(), a.size() * sizeof(double)), 0) << whole.cloud.scalars[f].name;
      varies = varies || std::any_of(w.begin(), w.end(), [&](double v) { return v != w[0]; });
    }
    EXPECT_TRUE(varies);  // not vacuous: some points in shadow, some in the sun
  }
}

namespace solar_time_test {

// Open ground with an east-west wall: shadows that move with the sun.
PointCloud ground_and_wall() {
  PointCloud cloud;
  for (double x = -10; x <= 10; x += 0.5)
    for (double y = -10; y <= 10; y += 0.5) cloud.positions.emplace_back(x, y, 0.0);
  for (double x = -5; x <= 5; x += 0.1)
    for (double z = 0.1; z <= 4.0; z += 0.1) cloud.positions.emplace_back(x, 0.0, z);
  return cloud;
}

std::string bytes_of(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

const std::vector<double>& field_of(const jobs::SolarJobResult& r, const std::string& name) {
  for (const ScalarField& f : r.cloud.scalars)
    if (f.name == name) return f.values;
  static const std::vector<double> none;
  ADD_FAILURE() << "no field " << name;
  return none;
}

}  // namespace solar_time_test

// With --utc-offset a time written without an offset is that zone's clock (a planner's local
// standard time); one written with 'Z' or +hh:mm stays as written. Oracle: 2026-06-21T12:00 at
// UTC+02:00 is 10:00Z = 1782036000 s (2026-06-21T12:00Z = 1782043200 s, SolarPositionIso8601),
// so "12:00" with the offset, "10:00Z" with it and "10:00Z" without it are one instant: the same
// fields, and with the offset the same map and preview byte for byte; the map states the local
// time with its offset, read back with GDAL.
TEST(SolarJob, ATimeWithoutAnOffsetIsTheClockAtUtcOffset) {
  const PointCloud cloud = solar_time_test::ground_and_wall();
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_utc_offset";
  std::filesystem::create_directories(dir);
  const auto run = [&](const std::string& at, std::optional<double> utc_offset, const std::string& name) {
    jobs::SolarJobOptions o;
    o.cloud = &cloud;
    o.latitude = 48.0;
    o.longitude = 11.0;
    o.at = at;
    o.utc_offset = utc_offset;
    o.sky_rays = 0;
    o.raster = dir / (name + ".tif");
    o.cell = 1.0;
    o.control.threads = 2;
    return jobs::run_solar(o);
  };
  const jobs::SolarJobResult local = run("2026-06-21T12:00", 2.0, "local");
  const jobs::SolarJobResult zulu = run("2026-06-21T10:00Z", 2.0, "zulu");
  const jobs::SolarJobResult utc = run("2026-06-21T10:00Z", std::nullopt, "utc");
  const jobs::SolarJobResult noon = run("2026-06-21T12:00", std::nullopt, "noon");  // no offset: UTC
  EXPECT_EQ(local.start_unix, 1782036000.0);
  EXPECT_EQ(zulu.start_unix, 1782036000.0);
  EXPECT_EQ(utc.start_unix, 1782036000.0);
  EXPECT_EQ(noon.start_unix, 1782043200.0);
  ASSERT_TRUE(local.sun && utc.sun && noon.sun);
  EXPECT_EQ(local.sun->azimuth_deg, utc.sun->azimuth_deg);
  EXPECT_EQ(local.sun->elevation_deg, utc.sun->elevation_deg);
  EXPECT_NE(local.sun->azimuth_deg, noon.sun->azimuth_deg);
  for (const char* f : {"in_shadow", "irradiance_global"}) {
    EXPECT_EQ(solar_time_test::field_of(local, f), solar_time_test::field_of(utc, f)) << f;
    EXPECT_NE(solar_time_test::field_of(local, f), solar_time_test::field_of(noon, f)) << f;
  }
  const std::string tif = solar_time_test::bytes_of(dir / "local.tif");
  ASSERT_GT(tif.size(), 100u);
  EXPECT_EQ(tif, solar_time_test::bytes_of(dir / "zulu.tif"));
  EXPECT_EQ(solar_time_test::bytes_of(dir / "local.png"), solar_time_test::bytes_of(dir / "zulu.png"));

  GDALAllRegister();
  const auto read_back = [&](const std::string& name, const std::string& title, const std::string& iso) {
    GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir / (name + ".tif")).c_str(), GA_ReadOnly));
    ASSERT_NE(ds, nullptr) << name;
    EXPECT_EQ(std::string(ds->GetRasterBand(1)->GetDescription()), title) << name;
    const char* time = ds->GetMetadataItem("RAYSCAN_TIME");
    ASSERT_NE(time, nullptr) << name;
    EXPECT_EQ(std::string(time), iso) << name;
    EXPECT_EQ(parse_iso8601_utc(time).unix_seconds, 1782036000) << name;  // the instant, unambiguous
    GDALClose(ds);
  };
  read_back("local", "shadow at 2026-06-21 12:00 UTC+02:00", "2026-06-21T12:00:00+02:00");
  read_back("utc", "shadow at 2026-06-21 10:00 UTC", "2026-06-21T10:00:00Z");
  // Without --utc-offset, a time naming its own offset is stated in it.
  run("2026-06-21T13:00+03:00", std::nullopt, "own");
  read_back("own", "shadow at 2026-06-21 13:00 UTC+03:00", "2026-06-21T13:00:00+03:00");
  std::filesystem::remove_all(dir);
}

// A day as a period is midnight to midnight in --utc-offset's zone: the dates alone, the same
// clock times written without an offset, and the UTC instants (22:00Z the evening before, at
// UTC+02:00) give the same steps and the same fields bit for bit.
TEST(SolarJob, ADateAlonePeriodIsLocalMidnightToMidnight) {
  const PointCloud cloud = solar_time_test::ground_and_wall();
  const auto run = [&](const std::string& start, const std::string& end, std::optional<double> utc_offset) {
    jobs::SolarJobOptions o;
    o.cloud = &cloud;
    o.latitude = 48.0;
    o.longitude = 11.0;
    o.start = start;
    o.end = end;
    o.utc_offset = utc_offset;
    o.sky_rays = 0;
    o.control.threads = 2;
    return jobs::run_solar(o);
  };
  const double midnight = 1782043200.0 - 14 * 3600.0;  // 2026-06-21T00:00+02:00
  const jobs::SolarJobResult dates = run("2026-06-21", "2026-06-21", 2.0);
  const jobs::SolarJobResult clock = run("2026-06-21T00:00", "2026-06-22T00:00", 2.0);
  const jobs::SolarJobResult zulu = run("2026-06-20T22:00Z", "2026-06-21T22:00Z", std::nullopt);
  for (const jobs::SolarJobResult* r : {&dates, &clock, &zulu}) {
    EXPECT_EQ(r->start_unix, midnight);
    EXPECT_EQ(r->end_unix, midnight + 86400.0);
    EXPECT_EQ(r->steps, 24u);
  }
  for (const char* f : {"solar_global", "sun_hours"}) {
    EXPECT_EQ(solar_time_test::field_of(dates, f), solar_time_test::field_of(clock, f)) << f;
    EXPECT_EQ(solar_time_test::field_of(dates, f), solar_time_test::field_of(zulu, f)) << f;
  }
  const nlohmann::json j = nlohmann::json::parse(jobs::solar_report_json(dates));
  EXPECT_EQ(j["start"], "2026-06-21T00:00:00+02:00");
  EXPECT_EQ(j["end"], "2026-06-22T00:00:00+02:00");
}

// sun_hours is WMO's sunshine duration (WMO-No. 8: DNI >= 120 W/m²): a weather day whose
// records have a faint beam (DNI 12, 60, 119 W/m², an overcast sky) and a bright one (120, 300,
// 650 W/m²) around noon, on an open level plane. Oracle: the records with DNI >= 120 counted from
// the file as written (each record one hour, the sun high at all six).
TEST(SolarJob, SunHoursCountOnlyTheWeatherHoursAtWmosSunshineThreshold) {
  const std::string epw = testing::TempDir() + "/sunshine.epw";
  const std::map<int, double> dni = {{10, 12.0}, {11, 60.0}, {12, 119.0}, {13, 120.0}, {14, 300.0}, {15, 650.0}};
  {
    std::FILE* f = std::fopen(epw.c_str(), "w");
    ASSERT_TRUE(f);
    std::fputs("LOCATION,Test,CA,USA,TMY3,724940,37.62,-122.40,-8.0,2.0\n"
               "DESIGN CONDITIONS,0\nTYPICAL/EXTREME PERIODS,0\nGROUND TEMPERATURES,0\n"
               "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0\nCOMMENTS 1,sunshine test year\nCOMMENTS 2,\n"
               "DATA PERIODS,1,1,Data,Sunday, 1/ 1,12/31\n",
               f);
    constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    for (int m = 1; m <= 12; ++m)
      for (int d = 1; d <= kDays[m - 1]; ++d)
        for (int h = 1; h <= 24; ++h) {
          const auto it = dni.find(h);
          const double b = it == dni.end() ? 0.0 : it->second;
          std::fprintf(f,
                       "1999,%d,%d,%d,60,?9?9?9?9,10.0,5.0,70,101325,0,0,300,%g,%g,100,0,0,0,0,180,2.0,10,10,"
                       "10.0,1000,9,999999999,0,0.1,0,0,999,0.0,0.0\n",
                       m, d, h, 100.0 + b, b);
        }
    std::fclose(f);
  }
  double want = 0.0;
  for (const auto& [hour, b] : dni) want += b >= 120.0 ? 1.0 : 0.0;
  ASSERT_EQ(want, 3.0);
  PointCloud cloud;
  for (double x = -10; x <= 10; x += 0.5)
    for (double y = -10; y <= 10; y += 0.5) cloud.positions.emplace_back(x, y, 0.0);
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 37.62;
  o.longitude = -122.40;
  o.utc_offset = -8.0;
  o.start = "2026-06-21";
  o.end = "2026-06-21";
  o.weather = epw;
  o.sky_rays = 0;
  o.control.threads = 2;
  for (const double sector : {0.0, 1.0}) {  // per step and through the sectors' sums
    o.sector = sector;
    const jobs::SolarJobResult r = jobs::run_solar(o);
    EXPECT_EQ(r.steps, 24u);
    const std::vector<double>& hours = solar_time_test::field_of(r, "sun_hours");
    ASSERT_EQ(hours.size(), cloud.size());
    for (std::size_t i = 0; i < hours.size(); i += 97) EXPECT_DOUBLE_EQ(hours[i], want) << sector << " " << i;
  }
}

// A period map states its period: RAYSCAN_START and RAYSCAN_END (ISO 8601 with the offset of
// --utc-offset), and a title that names the days of whole days, else the times, so that an
// afternoon and its day differ. Oracle: gdalinfo's JSON report of the file.
TEST(SolarJob, APeriodMapStatesItsStartAndEnd) {
  const PointCloud cloud = solar_time_test::ground_and_wall();
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_period_map";
  std::filesystem::create_directories(dir);
  struct Case {
    std::string start, end, value, title, meta_start, meta_end;
  };
  const Case cases[] = {
      {"2026-06-21T13:00", "2026-06-21T16:00", "global",
       "global irradiation 2026-06-21 13:00 UTC+02:00 to 2026-06-21 16:00 UTC+02:00 (kWh/m²)",
       "2026-06-21T13:00:00+02:00", "2026-06-21T16:00:00+02:00"},
      {"2026-06-21", "2026-06-21", "global", "global irradiation 2026-06-21 to 2026-06-21 (kWh/m²)",
       "2026-06-21T00:00:00+02:00", "2026-06-22T00:00:00+02:00"},
      {"2026-06-20T22:00Z", "2026-06-22T22:00Z", "sun_hours",
       "hours of direct sun (DNI >= 120 W/m2) 2026-06-21 to 2026-06-22 (h)",
       "2026-06-21T00:00:00+02:00", "2026-06-23T00:00:00+02:00"},
  };
  for (const Case& c : cases) {
    const std::filesystem::path tif = dir / "p.tif";
    jobs::SolarJobOptions o;
    o.cloud = &cloud;
    o.latitude = 48.0;
    o.longitude = 11.0;
    o.utc_offset = 2.0;
    o.start = c.start;
    o.end = c.end;
    o.sky_rays = 0;
    o.raster = tif;
    o.raster_value = c.value;
    o.write_preview = false;
    o.cell = 1.0;
    o.control.threads = 2;
    jobs::run_solar(o);
    const auto r = rayscan::test::run_command("gdalinfo -json '" + tif.string() + "'", false);
    ASSERT_EQ(r.code, 0) << r.out;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["bands"][0]["description"], c.title) << c.start;
    EXPECT_EQ(j["metadata"][""]["RAYSCAN_START"], c.meta_start) << c.start;
    EXPECT_EQ(j["metadata"][""]["RAYSCAN_END"], c.meta_end) << c.start;
    EXPECT_FALSE(j["metadata"][""].contains("RAYSCAN_TIME")) << c.start;
  }
  std::filesystem::remove_all(dir);
}

// One rule says whether a CRS is a frame for sun directions (is_unprojected_crs): geographic and
// geocentric are not, with or without --lat/--lon; a local (engineering) frame is one, but has no
// place on the Earth for locate_site.
TEST(SiteLocation, GeographicAndGeocentricAreRefusedByOneRule) {
  using rayscan::test::crs_wkt;
  const std::string geographic = crs_wkt("EPSG:4326"), geocentric = crs_wkt("EPSG:4978"),
                    projected = crs_wkt("EPSG:32632");
  const std::string local = R"(LOCAL_CS["site",LOCAL_DATUM["site",0],UNIT["metre",1],AXIS["X",EAST],AXIS["Y",NORTH]])";
  EXPECT_TRUE(is_unprojected_crs(geographic));
  EXPECT_TRUE(is_unprojected_crs(geocentric));
  EXPECT_FALSE(is_unprojected_crs(projected));
  EXPECT_FALSE(is_unprojected_crs(local));
  EXPECT_FALSE(is_unprojected_crs(""));
  const auto why = [](const std::string& wkt) {
    try {
      locate_site(wkt, Vec3(0.0));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(why(geographic).find("geographic or geocentric"), std::string::npos) << why(geographic);
  EXPECT_NE(why(geocentric).find("geographic or geocentric"), std::string::npos) << why(geocentric);
  EXPECT_NE(why(local).find("not projected"), std::string::npos) << why(local);
  // The job gives the same reason with --lat/--lon, and runs on the local frame.
  PointCloud cloud = solar_time_test::ground_and_wall();
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.at = "2026-06-21T10:00Z";
  o.sky_rays = 0;
  o.control.threads = 2;
  cloud.crs_wkt = geocentric;
  try {
    jobs::run_solar(o);
    ADD_FAILURE() << "a geocentric cloud was traced";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), why(geocentric));
  }
  cloud.crs_wkt = local;
  EXPECT_NO_THROW(jobs::run_solar(o));
}

// The refusal of an unprojected CRS has one wording, with what is measured in it: check_site_crs
// gives it for sun directions, the jobs (solar, visibility) for theirs. Oracle: the text itself.
TEST(SiteLocation, UnprojectedCrsRefusalNamesWhatNeedsAProjectedCrs) {
  const std::string geographic = rayscan::test::crs_wkt("EPSG:4326");
  ASSERT_FALSE(geographic.empty());
  const auto why = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(why([&] { refuse_unprojected_crs(geographic, "line-of-sight heights and distances"); }),
            "the cloud's CRS is geographic or geocentric: line-of-sight heights and distances need a projected CRS "
            "(x east, y north, z up); reproject the cloud (e.g. pdal translate with filters.reprojection), or, if "
            "its coordinates are projected and only the CRS is wrong, assign the right one (e.g. pdal translate "
            "with --writers.las.a_srs)");
  EXPECT_EQ(why([&] { check_site_crs(geographic); }),
            why([&] { refuse_unprojected_crs(geographic, "sun directions"); }));
  const std::string local = R"(LOCAL_CS["site",LOCAL_DATUM["site",0],UNIT["metre",1],AXIS["X",EAST],AXIS["Y",NORTH]])";
  for (const std::string& wkt : {std::string(), local})
    EXPECT_EQ(why([&] { refuse_unprojected_crs(wkt, "sun directions"); }), "") << wkt;
}

namespace solar_time_test {

// An ISO 8601 "YYYY-MM-DDThh:mm:ss" with 'Z' or "+hh:mm" / "-hh:mm" as UTC unix seconds, read with
// sscanf and std::chrono's civil calendar rather than the library's own parser.
std::int64_t unix_of_iso(const std::string& text) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
  char zone[8] = {};
  if (std::sscanf(text.c_str(), "%d-%d-%dT%d:%d:%d%7s", &y, &mo, &d, &h, &mi, &s, zone) != 7) {
    ADD_FAILURE() << "not ISO 8601 with an offset: '" << text << "'";
    return 0;
  }
  int offset = 0;
  if (std::string(zone) != "Z") {
    char sign = 0;
    int oh = 0, om = 0;
    if (std::sscanf(zone, "%c%d:%d", &sign, &oh, &om) != 3 || (sign != '+' && sign != '-'))
      ADD_FAILURE() << "no offset in '" << text << "'";
    offset = (sign == '-' ? -60 : 60) * (oh * 60 + om);
  }
  const std::chrono::sys_days day = std::chrono::year{y} / std::chrono::month(unsigned(mo)) / std::chrono::day(unsigned(d));
  return std::int64_t{day.time_since_epoch().count()} * 86400 + h * 3600 + mi * 60 + s - offset;
}

}  // namespace solar_time_test

// ISO 8601 writes an offset in whole minutes, so local mean solar time is longitude / 15 h to the
// minute: -8:12 at 123.07 W (the mean time itself is -8:12:16.8). Every instant `solar position`
// prints, read back, is the instant itself to the second: the date alone's midnight is 08:12:00Z,
// which is also the Julian day SPA was given, and sunrise, transit and sunset are those the same day
// prints at --utc-offset -8 (a whole hour) and, for sunrise and transit, at UTC.
TEST(SolarCli, EveryInstantStatedInLocalMeanSolarTimeIsExact) {
  using solar_time_test::unix_of_iso;
  const auto run = [](const std::string& extra) {
    const auto r = rayscan::test::run_command(
        std::string(RAYSCAN_BIN) + " solar position --lat 44.05 --lon -123.07 --time 2026-06-21 --json" + extra, false);
    EXPECT_EQ(r.code, 0) << extra << ": " << r.out;
    return nlohmann::json::parse(r.out);
  };
  const nlohmann::json mean = run(""), pst = run(" --utc-offset -8"), utc = run(" --utc-offset 0");
  const std::int64_t midnight = unix_of_iso("2026-06-21T00:00:00Z") + 8 * 3600 + 12 * 60;
  EXPECT_EQ(unix_of_iso(mean["time"]), midnight) << mean["time"];
  EXPECT_NEAR(mean["julian_day"].get<double>(), 2440587.5 + double(midnight) / 86400.0, 1e-8);  // JD of unix 0
  for (const char* event : {"sunrise", "transit", "sunset"}) {
    const std::string text = mean[event];
    EXPECT_EQ(text.substr(0, 10), "2026-06-21") << event;  // the local day's events
    EXPECT_EQ(text.substr(19), "-08:12") << event;
    EXPECT_EQ(unix_of_iso(text), unix_of_iso(pst[event])) << text << " vs " << pst[event];
  }
  for (const char* event : {"sunrise", "transit"})
    EXPECT_EQ(unix_of_iso(mean[event]), unix_of_iso(utc[event])) << mean[event] << " vs " << utc[event];
}

// A day of shadows without --utc-offset is numbered and titled in local mean solar time to the
// minute: each frame's title and RAYSCAN_TIME (read back with GDAL) name its clock, and that clock
// at -08:12 is the instant the frame shows: the noon frame's cells equal those of a map at the same
// instant given in UTC (20:12Z).
TEST(SolarJob, ADayOfShadowsInLocalMeanSolarTimeStatesExactInstants) {
  using solar_time_test::unix_of_iso;
  const PointCloud cloud = solar_time_test::ground_and_wall();
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_mean_time";
  std::filesystem::create_directories(dir);
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 44.05;
  o.longitude = -123.07;
  o.sky_rays = 0;
  o.cell = 1.0;
  o.control.threads = 2;
  jobs::SolarJobOptions day = o;
  day.day = "2026-12-21";
  day.every = "1h";
  day.raster = dir / "winter.tif";
  const jobs::SolarJobResult r = jobs::run_solar(day);
  const std::int64_t midnight = unix_of_iso("2026-12-21T00:00:00Z") + 8 * 3600 + 12 * 60;
  EXPECT_EQ(r.start_unix, double(midnight));
  EXPECT_EQ(nlohmann::json::parse(jobs::solar_report_json(r))["start"], "2026-12-21T00:00:00-08:12");

  GDALAllRegister();
  const auto band = [](const std::filesystem::path& tif, std::string* title, std::string* time) {
    std::vector<float> cells;
    GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(tif.c_str(), GA_ReadOnly));
    if (!ds) {
      ADD_FAILURE() << tif;
      return cells;
    }
    GDALRasterBand* b = ds->GetRasterBand(1);
    if (title) *title = b->GetDescription();
    if (time) *time = ds->GetMetadataItem("RAYSCAN_TIME") ? ds->GetMetadataItem("RAYSCAN_TIME") : "";
    cells.resize(std::size_t(ds->GetRasterXSize()) * std::size_t(ds->GetRasterYSize()));
    EXPECT_EQ(b->RasterIO(GF_Read, 0, 0, ds->GetRasterXSize(), ds->GetRasterYSize(), cells.data(),
                          ds->GetRasterXSize(), ds->GetRasterYSize(), GDT_Float32, 0, 0),
              CE_None);
    GDALClose(ds);
    return cells;
  };
  std::size_t frames = 0;
  for (int hour = 0; hour < 24; ++hour) {
    char hh[3];
    std::snprintf(hh, sizeof hh, "%02d", hour % 100);
    const std::filesystem::path tif = dir / ("winter_" + std::string(hh) + "00.tif");
    if (!std::filesystem::exists(tif)) continue;
    ++frames;
    std::string title, time;
    band(tif, &title, &time);
    EXPECT_EQ(title, "shadow at 2026-12-21 " + std::string(hh) + ":00 UTC-08:12");
    EXPECT_EQ(time, "2026-12-21T" + std::string(hh) + ":00:00-08:12");
    EXPECT_EQ(unix_of_iso(time), midnight + hour * 3600) << time;
  }
  EXPECT_EQ(frames, r.steps);
  ASSERT_TRUE(std::filesystem::exists(dir / "winter_1200.tif"));

  jobs::SolarJobOptions at = o;
  at.at = "2026-12-21T20:12:00Z";
  at.raster = dir / "at.tif";
  jobs::run_solar(at);
  std::string time;
  const std::vector<float> shadow_at = band(dir / "at.tif", nullptr, &time);
  EXPECT_EQ(unix_of_iso(time), midnight + 12 * 3600) << time;
  EXPECT_EQ(band(dir / "winter_1200.tif", nullptr, nullptr), shadow_at);
  std::filesystem::remove_all(dir);
}

// A CRS that gives sun directions no frame is refused from the file's header, before any point is
// read: a LAS file naming WGS 84 (geographic) whose point records cannot be read (an x scale of
// 1e308 takes x past the coordinate bound, 1e9, which only reading the records finds, as
// `rayscan info` shows) gets the CRS's refusal, one line and no log line of reading. --lat/--lon do
// not make degrees a frame, so they do not help, and the line does not offer them.
// A weather file that is a FIFO (or a folder) is refused before the points are read: the cloud
// here has an x scale of 1e308, so reading its points fails ("the coordinate bound"); the one
// error line is the weather file's.
TEST(SolarCli, AWeatherFileThatIsNoRegularFileIsRefusedBeforeThePointsAreRead) {
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_weather_fifo";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::filesystem::path las = dir / "c.las", fifo = dir / "w.epw", out = dir / "out.las";
  PointCloud cloud;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) cloud.positions.emplace_back(i, j, 0.0);
  io::write_point_cloud(las, cloud);
  {
    std::fstream f(las, std::ios::in | std::ios::out | std::ios::binary);
    const double scale = 1e308;
    f.seekp(131);  // the header's x scale factor (LAS 1.2-1.4), little-endian float64
    f.write(reinterpret_cast<const char*>(&scale), sizeof scale);
  }
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string base = std::string(RAYSCAN_BIN) + " solar '" + las.string() +
                           "' --lat 44 --lon -123 --start 2026-06-01 --end 2026-06-02 -o '" + out.string() + "'";
  const auto points = rayscan::test::run_command(base);
  EXPECT_EQ(points.code, 2) << points.out;
  EXPECT_NE(points.out.find("the coordinate bound"), std::string::npos) << points.out;
  for (const std::filesystem::path& w : {fifo, dir}) {
    const auto r = rayscan::test::run_command(base + " --weather '" + w.string() + "'");
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find(w.string() + ": is a"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("not a regular file"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("coordinate bound"), std::string::npos) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  }
  EXPECT_FALSE(std::filesystem::exists(out));
  std::filesystem::remove_all(dir);
}

TEST(SolarCli, AGeographicCrsIsRefusedFromTheHeaderBeforeThePointsAreRead) {
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_geographic";
  std::filesystem::create_directories(dir);
  const std::filesystem::path las = dir / "geographic.las", out = dir / "out.las";
  PointCloud cloud;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) cloud.positions.emplace_back(515000.0 + i, 4918000.0 + j, 2300.0);
  cloud.crs_wkt = rayscan::test::crs_wkt("EPSG:4326");
  io::write_point_cloud(las, cloud);
  {
    std::fstream f(las, std::ios::in | std::ios::out | std::ios::binary);
    const double scale = 1e308;
    f.seekp(131);  // the header's x scale factor (LAS 1.2-1.4), little-endian float64
    f.write(reinterpret_cast<const char*>(&scale), sizeof scale);
  }
  const auto info = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " info '" + las.string() + "'");
  EXPECT_EQ(info.code, 2) << info.out;
  EXPECT_NE(info.out.find("the coordinate bound"), std::string::npos) << info.out;
  for (const std::string extra : {"", " --lat 44.4 --lon -110.8"}) {
    const auto r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " solar '" + las.string() +
                                              "' --at 2026-06-21T12:00Z -o '" + out.string() + "'" + extra);
    EXPECT_EQ(r.code, 2) << extra << ": " << r.out;
    EXPECT_EQ(r.out.rfind("rayscan solar: the cloud's CRS is geographic or geocentric: sun directions need a "
                          "projected CRS (x east, y north, z up); reproject the cloud",
                          0),
              0u)
        << extra << ": " << r.out;
    EXPECT_NE(r.out.find("assign the right one"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("--lat"), std::string::npos) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_FALSE(std::filesystem::exists(out));
  }
  std::filesystem::remove_all(dir);
}

// The GeoTIFF's band unit is the unit the JSON report (and so the point outputs' descriptions)
// gives the field the map shows: a period's global irradiation and hours of sun, an instant's
// shadow, and the shadow frames of a day. Oracle: the band's unit as GDAL reads it back
// (GetUnitType) against `--json`'s fields of the same run, and the PLY's own header comment.
TEST(SolarCli, RasterBandUnitIsTheFieldsUnitInTheJsonReport) {
  const std::filesystem::path dir = std::filesystem::path(testing::TempDir()) / "solar_band_unit";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::filesystem::path tif = dir / "map.tif", ply = dir / "out.ply";
  const std::string base = std::string(RAYSCAN_BIN) + " solar -q '" + RAYSCAN_TEST_DATA +
                           "/las/simple.las' --lat 44 --lon -123 --sky-rays 0 --cell 200 --no-preview --json";
  GDALAllRegister();
  const auto band_unit = [](const std::filesystem::path& p) {
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(p.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    return ds ? std::string(ds->GetRasterBand(1)->GetUnitType()) : std::string("(not opened: " + p.string() + ")");
  };
  struct Case {
    std::string args, field;
  };
  const Case cases[] = {{" --start 2026-06-21 --end 2026-06-21", "solar_global"},
                        {" --start 2026-06-21 --end 2026-06-21 --raster-value sun_hours", "sun_hours"},
                        {" --at 2026-06-21T20:00Z", "in_shadow"}};
  std::string shadow_unit;
  for (const Case& c : cases) {
    const auto r = rayscan::test::run_command(base + c.args + " --raster '" + tif.string() + "' -o '" +
                                              ply.string() + "'", false);
    ASSERT_EQ(r.code, 0) << c.args << ": " << r.out;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j["fields"].contains(c.field)) << r.out;
    const std::string unit = j["fields"][c.field]["unit"].get<std::string>();
    EXPECT_FALSE(unit.empty()) << c.field;
    EXPECT_EQ(band_unit(tif), unit) << c.field;
    if (c.field == "in_shadow") shadow_unit = unit;
    if (c.field != "in_shadow") {  // the PLY describes the field with its unit at the end
      std::ifstream in(ply, std::ios::binary);
      std::string line, comment;
      while (std::getline(in, line) && line != "end_header")
        if (line.rfind("comment field scalar_" + c.field + ": ", 0) == 0) comment = line;
      EXPECT_TRUE(comment.ends_with(", " + unit)) << c.field << ": " << comment;
    }
  }
  // A day's shadow frames (map_HHMM.tif) are shadow maps: the in_shadow unit.
  const auto r = rayscan::test::run_command(base + " --day 2026-06-21 --every 6h --raster '" + tif.string() + "'",
                                            false);
  ASSERT_EQ(r.code, 0) << r.out;
  std::size_t frames = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().rfind("map_", 0) == 0 && e.path().extension() == ".tif") {
      ++frames;
      EXPECT_EQ(band_unit(e.path()), shadow_unit) << e.path();
    }
  EXPECT_GE(frames, 2u);
  std::filesystem::remove_all(dir);
}
