// The auto radius factor's one range, (0, 100], and its one message, wherever a factor is given: a
// render scene's auto_radius_factor, `rayscan visibility --radius-factor`, the solar job's
// radius_factor. Oracles: the range's own ends (100 accepted, the next double above it refused) and
// the exact lines the program prints, with exit status 2.
#include "rayscan/base/option_error.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/octree/spacing.hpp"

#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>

using namespace rayscan;
using rayscan::test::run_command;

namespace {

const std::string kExpected = "expected a number in (0, 100]";
const std::string kCloud = std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las";

/// The last line of `text` (without its newline).
std::string last_line_of(std::string text) {
  while (!text.empty() && text.back() == '\n') text.pop_back();
  const std::size_t nl = text.rfind('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

/// `rayscan render` of a scene over autzen_trim with "auto_radius_factor": `factor` (JSON text).
test::CommandResult render_with_factor(const std::filesystem::path& dir, const std::string& factor) {
  const std::filesystem::path scene = dir / "factor.json";
  std::ofstream(scene) << R"({"cloud": ")" << kCloud << R"(", "auto_radius_factor": )" << factor << "}";
  return run_command(std::string(RAYSCAN_BIN) + " render " + test::quoted(scene) +
                     " --width 8 --height 8 --spp 1 --threads 2 --out " + test::quoted(dir / "factor.png"));
}

/// `rayscan visibility` of autzen_trim from one observer with `--radius-factor FACTOR`.
test::CommandResult visibility_with_factor(const std::filesystem::path& dir, const std::string& factor) {
  return run_command(std::string(RAYSCAN_BIN) + " visibility " + test::quoted(kCloud) +
                     " --observer 636226.5,849106.5 --height 6 --threads 2 --radius-factor " +
                     factor + " -o " + test::quoted(dir / "factor.las"));
}

}  // namespace

TEST(AutoRadiusFactor, TheCheckAcceptsExactlyZeroToOneHundred) {
  EXPECT_EQ(kDefaultAutoRadiusFactor, 1.0);
  for (double ok : {std::numeric_limits<double>::denorm_min(), 1e-9, 1.0, 99.5, 100.0})
    EXPECT_EQ(auto_radius_factor_problem(ok), "") << ok;
  for (double bad : {0.0, -0.0, -1.0, std::nextafter(100.0, 200.0), 200.0, std::nan(""),
                     std::numeric_limits<double>::infinity()})
    EXPECT_EQ(auto_radius_factor_problem(bad), kExpected) << bad;
}

// choose_radius applies the same check (auto only: a given radius makes the factor moot there).
TEST(AutoRadiusFactor, ChooseRadiusRefusesOutOfRange) {
  const auto spacing = [] { return 2.0; };
  EXPECT_EQ(choose_radius(std::nullopt, 100.0, spacing).radius, 200.0);
  try {
    (void)choose_radius(std::nullopt, 100.5, spacing);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "radius factor: " + kExpected);
  }
  EXPECT_EQ(choose_radius(0.5, 100.5, spacing).radius, 0.5);
}

// render, visibility and the solar job refuse an out-of-range factor with one message after the
// name each front end gives it, render and visibility with exit status 2 before any output.
TEST(AutoRadiusFactor, RenderVisibilityAndSolarRefuseWithOneMessage) {
  const std::filesystem::path dir = test::fresh_temp_dir("rayscan_radius_factor");
  for (const char* bad : {"200", "0", "-1", "100.000001"}) {
    const test::CommandResult render = render_with_factor(dir, bad);
    EXPECT_EQ(render.code, 2) << render.out;
    EXPECT_EQ(last_line_of(render.out), "rayscan render: " + (dir / "factor.json").string() +
                                            ": /auto_radius_factor: " + kExpected)
        << bad;
    const test::CommandResult vis = visibility_with_factor(dir, bad);
    EXPECT_EQ(vis.code, 2) << vis.out;
    EXPECT_EQ(last_line_of(vis.out), "rayscan visibility: --radius-factor: " + kExpected) << bad;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "factor.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "factor.las"));

  // The solar job (no command-line option: the library's and Python's callers), also with a
  // given radius, which the factor does not affect.
  const PointCloud cloud = [] {
    PointCloud pc;
    for (int i = 0; i < 10; ++i)
      for (int j = 0; j < 10; ++j) pc.positions.emplace_back(0.5 * i, 0.5 * j, 0.0);
    return pc;
  }();
  jobs::SolarJobOptions o;
  o.cloud = &cloud;
  o.latitude = 48.0;
  o.longitude = 11.0;
  o.at = "2026-06-21T12:00:00+02:00";
  o.control.threads = 2;
  for (std::optional<double> radius : {std::optional<double>(), std::optional<double>(0.3)}) {
    o.radius = radius;
    o.radius_factor = 200.0;
    try {
      (void)jobs::run_solar(o);
      ADD_FAILURE() << "no OptionError";
    } catch (const OptionError& e) {
      EXPECT_EQ(std::string(e.what()), "radius_factor: " + kExpected);
      ASSERT_FALSE(e.parts().empty());
      EXPECT_EQ(std::get<OptionName>(e.parts().front()).field, "radius_factor");
    }
    o.radius_factor = 100.0;  // the range's end is accepted
    EXPECT_EQ(jobs::run_solar(o).cloud.size(), cloud.size());
  }
  std::filesystem::remove_all(dir);
}

// The range's upper end runs: visibility's log states the factor, and the render writes its image.
TEST(AutoRadiusFactor, OneHundredIsAccepted) {
  const std::filesystem::path dir = test::fresh_temp_dir("rayscan_radius_factor_100");
  const test::CommandResult vis = visibility_with_factor(dir, "100");
  EXPECT_EQ(vis.code, 0) << vis.out;
  EXPECT_NE(vis.out.find(" x 100 = "), std::string::npos) << vis.out;
  const test::CommandResult render = render_with_factor(dir, "100");
  EXPECT_EQ(render.code, 0) << render.out;
  EXPECT_TRUE(std::filesystem::exists(dir / "factor.png"));
  std::filesystem::remove_all(dir);
}
