// The sun map's sectors against one shadow ray per time step on a real scan (autzen_trim: trees,
// houses, open ground): the error the default sector size adds, which docs/solar.md quotes.
#include "rayscan/jobs/solar.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

using namespace rayscan;

namespace {

std::vector<double> global_of(const jobs::SolarJobResult& r) {
  for (const ScalarField& f : r.cloud.scalars)
    if (f.name == "solar_global") return f.values;
  ADD_FAILURE() << "no solar_global field";
  return {};
}

}  // namespace

// March and April, when the declination moves fastest (sectors then hold the fewest days each),
// hourly steps, the default 1-degree sectors against exact casting (--sector 0).
TEST(SolarSectors, DefaultSectorsOnAutzenAreWithinOnePercentOfOneRayPerStep) {
  jobs::SolarJobOptions o;
  o.cloud_file = std::string(RAYSCAN_SOURCE_DIR) + "/scenes/data/autzen_trim.las";
  o.start = "2026-03-01";
  o.end = "2026-04-30";
  o.control.threads = 2;
  const jobs::SolarJobResult sectors = jobs::run_solar(o);
  o.sector = 0.0;
  const jobs::SolarJobResult exact = jobs::run_solar(o);
  EXPECT_LT(sectors.sectors * 2, exact.sectors);  // the map saves rays
  const std::vector<double> a = global_of(sectors), b = global_of(exact);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 100000u);
  double sum_a = 0, sum_b = 0, sum_diff = 0;
  std::size_t within = 0, counted = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sum_a += a[i];
    sum_b += b[i];
    sum_diff += std::abs(a[i] - b[i]);
    if (b[i] > 10.0) {  // kWh/m²: points with some sun
      ++counted;
      within += std::abs(a[i] - b[i]) <= 0.01 * b[i];
    }
  }
  const double mean_error = sum_diff / sum_b, site = sum_a / sum_b - 1.0;
  std::printf("sectors %zu vs %zu steps with sun: site mean %+.4f %%, mean |difference| %.3f %% of the mean, "
              "%.1f %% of the points within 1 %%\n",
              sectors.sectors, exact.sectors, 100 * site, 100 * mean_error, 100.0 * double(within) / double(counted));
  EXPECT_LT(std::abs(site), 0.001);
  EXPECT_LT(mean_error, 0.01);
  EXPECT_GT(double(within) / double(counted), 0.85);
}
