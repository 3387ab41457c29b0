// dsm_viewshed (R3 line of sight over a raster DSM) against analytic geometry: a straight wall on
// flat ground hides the cells whose sight line passes below its top, by similar triangles.
#include "rayscan/analysis/dsm_viewshed.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace {

using rayscan::Vec3;
using namespace rayscan::analysis;

// A cols x rows DSM of 1-unit cells, west edge 0, north edge `rows`, flat at 0.
Raster flat(std::uint32_t cols, std::uint32_t rows) {
  Raster r;
  r.grid.x0 = 0.0;
  r.grid.y_top = double(rows);
  r.grid.cell = 1.0;
  r.grid.cols = cols;
  r.grid.rows = rows;
  r.values.assign(std::size_t(cols) * rows, 0.0f);
  return r;
}

// Eye 2 above the centre of column 10, a wall of height 1 along column 50: a target on the ground
// at column q > 50 of the eye's row is hidden while the sight line's height at the wall,
// 2 - 2 (50 - 10) / (q - 10), is below 1, i.e. for q < 90; at 90 it grazes the top (seen).
TEST(DsmViewshed, AWallHidesTheGroundBehindItUpToTheAnalyticDistance) {
  Raster dsm = flat(120, 21);
  for (std::uint32_t r = 0; r < 21; ++r) dsm.values[r * 120 + 50] = 1.0f;
  const std::uint32_t row = 10;
  const double y = double(21 - row) - 0.5;  // the centre of row 10
  const std::vector<Vec3> eye{{10.5, y, 2.0}};
  const Raster v = dsm_viewshed(dsm, eye, 0.0, 1);
  for (std::uint32_t q = 0; q < 120; ++q) {
    const bool expected = q <= 50 || q >= 90;
    EXPECT_EQ(v.values[row * 120 + q], expected ? 1.0f : 0.0f) << "column " << q;
  }
  // A target height lifts the targets: with 0.5, the line 2 - 1.5 (40 / (q - 10)) clears 1 from
  // q = 70.
  const Raster lifted = dsm_viewshed(dsm, eye, 0.5, 1);
  for (std::uint32_t q = 51; q < 120; ++q)
    EXPECT_EQ(lifted.values[row * 120 + q], q >= 70 ? 1.0f : 0.0f) << "column " << q;
}

// The same wall along a row (north-south sight lines: the rows are the major axis), an eye off
// the grid to the north, and cells without a value: they do not block, and stay NaN.
TEST(DsmViewshed, RowsAsTheMajorAxisEyesOffTheGridAndGaps) {
  Raster dsm = flat(7, 120);
  for (std::uint32_t q = 0; q < 7; ++q) dsm.values[50 * 7 + q] = 1.0f;  // a wall along row 50
  dsm.values[30 * 7 + 3] = std::numeric_limits<float>::quiet_NaN();
  // 10 cells north of row 0's centre... the eye at row -10 (y = top + 10 - 0.5 + 1), column 3.
  const std::vector<Vec3> eye{{3.5, 120.0 + 9.5, 2.0}};
  const Raster v = dsm_viewshed(dsm, eye, 0.0, 2);
  // Rows counted from the eye at -10: the wall 60 rows away; hidden while 2 - 2 * 60 / (r + 10) < 1.
  for (std::uint32_t r = 0; r < 120; ++r) {
    const float got = v.values[r * 7 + 3];
    if (r == 30) {
      EXPECT_TRUE(std::isnan(got));
      continue;
    }
    const bool expected = r <= 50 || r + 10 >= 120;
    EXPECT_EQ(got, expected ? 1.0f : 0.0f) << "row " << r;
  }
}

// Two eyes: a cell is visible when either sees it (the wall hides each one's far side only).
TEST(DsmViewshed, ACellIsVisibleWhenAnyEyeSeesIt) {
  Raster dsm = flat(120, 1);
  dsm.values[50] = 1.0f;
  const std::vector<Vec3> west{{10.5, 0.5, 2.0}}, both{{10.5, 0.5, 2.0}, {110.5, 0.5, 2.0}};
  const Raster w = dsm_viewshed(dsm, west, 0.0), b = dsm_viewshed(dsm, both, 0.0);
  EXPECT_EQ(w.values[70], 0.0f);
  EXPECT_EQ(b.values[70], 1.0f);  // seen from the east eye
  EXPECT_EQ(b.values[30], 1.0f);
  EXPECT_THROW(dsm_viewshed(dsm, west, -1.0), std::invalid_argument);
  dsm.values.pop_back();
  EXPECT_THROW(dsm_viewshed(dsm, west, 0.0), std::invalid_argument);
}

}  // namespace

namespace {

// Eye 2 above the centre of a flat 41 x 41 DSM: every cell is seen without limits, so the limits
// alone decide. A cell counts when its centre (on the surface, z 0) lies within the range (3-D
// distance from the eye) and its compass bearing from the eye inside the azimuth range; computed
// here from the geometry, the oracle.
TEST(DsmViewshed, ObserversLimitsAsThePerPointLineOfSightAppliesThem) {
  const Raster dsm = flat(41, 41);
  Observer o;
  o.position = Vec3(20.5, 20.5, 2.0);
  o.azimuth = AngleRange{0.0, 90.0};  // north to east, clockwise
  o.max_distance = 10.0;
  Observer far = o;
  far.max_distance.reset();  // the run's maximum distance applies
  far.azimuth.reset();
  const std::vector<Observer> one{o};
  const Raster v = dsm_viewshed(dsm, one, std::numeric_limits<double>::infinity(), 0.0, 1);
  std::size_t seen = 0;
  for (std::uint32_t r = 0; r < 41; ++r)
    for (std::uint32_t q = 0; q < 41; ++q) {
      const double dx = q + 0.5 - 20.5, dy = (41.0 - r - 0.5) - 20.5;
      const double bearing = std::fmod(std::atan2(dx, dy) * 180.0 / M_PI + 360.0, 360.0);
      const bool in_range = std::sqrt(dx * dx + dy * dy + 4.0) <= 10.0;
      const bool in_azimuth = (dx == 0.0 && dy == 0.0) || (bearing >= 0.0 && bearing <= 90.0);
      const bool expected = in_range && in_azimuth;
      seen += expected;
      EXPECT_EQ(v.values[r * 41 + q], expected ? 1.0f : 0.0f) << "cell " << q << "," << r;
    }
  EXPECT_GT(seen, 50u);
  // Without its own limits an observer takes the run's maximum distance, 5 here.
  const std::vector<Observer> other{far};
  const Raster w = dsm_viewshed(dsm, other, 5.0, 0.0, 1);
  for (std::uint32_t r = 0; r < 41; ++r)
    for (std::uint32_t q = 0; q < 41; ++q) {
      const double dx = q + 0.5 - 20.5, dy = (41.0 - r - 0.5) - 20.5;
      EXPECT_EQ(w.values[r * 41 + q], std::sqrt(dx * dx + dy * dy + 4.0) <= 5.0 ? 1.0f : 0.0f) << q << "," << r;
    }
  EXPECT_THROW(dsm_viewshed(dsm, other, -1.0, 0.0, 1), std::invalid_argument);
}

}  // namespace
