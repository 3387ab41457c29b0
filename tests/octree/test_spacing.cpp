// The automatic radius (spacing.hpp: median nearest-neighbour spacing and choose_radius), the one
// radius heuristic every job calls.
#include "rayscan/octree/spacing.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace rayscan;

TEST(Spacing, AutoRadiusOnAGridIsTheGridStep) {
  // A 2-D grid with step 0.25 and a duplicate of every point: the nearest other distinct point is
  // exactly one step away (duplicates at distance 0 are skipped).
  std::vector<Vec3> pts;
  for (int x = 0; x < 40; ++x)
    for (int y = 0; y < 40; ++y)
      for (int d = 0; d < 2; ++d) pts.emplace_back(0.25 * x, 0.25 * y, 5.0);
  const AnyIndex idx = make_index(pts, IndexOptions{});
  EXPECT_DOUBLE_EQ(median_nn_spacing(idx, pts), 0.25);
  const RadiusChoice a = choose_radius(idx, pts, std::nullopt, 1.5);
  EXPECT_TRUE(a.automatic);
  EXPECT_DOUBLE_EQ(a.spacing, 0.25);
  EXPECT_DOUBLE_EQ(a.radius, 0.375);
  const RadiusChoice g = choose_radius(idx, pts, 0.1);
  EXPECT_FALSE(g.automatic);
  EXPECT_DOUBLE_EQ(g.radius, 0.1);
  EXPECT_THROW((void)choose_radius(idx, pts, -1.0), std::invalid_argument);
  EXPECT_THROW((void)choose_radius(idx, pts, std::nan("")), std::invalid_argument);
  const std::vector<Vec3> same(10, Vec3(1.0));
  const AnyIndex one = make_index(same, IndexOptions{});
  EXPECT_THROW((void)choose_radius(one, same, std::nullopt), std::invalid_argument);
}
