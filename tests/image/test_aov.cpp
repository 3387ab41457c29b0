// AOV names and their file channels (rayscan/image/aov.hpp): one definition shared by the
// renderer, the image files and the CLI.
#include "rayscan/image/aov.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

namespace rayscan {
namespace {

TEST(Aov, NamesRoundTripAndChannelsAreDistinct) {
  std::set<std::string> channels;
  for (Aov a : all_aovs()) {
    EXPECT_EQ(parse_aov(to_string(a)), a);
    for (const std::string& c : aov_channels(a)) EXPECT_TRUE(channels.insert(c).second) << c;
  }
  EXPECT_EQ(all_aovs().size(), 6u);
  EXPECT_FALSE(parse_aov("Depth"));
  EXPECT_EQ(aov_names_expected(), "expected depth, normal, position, index, albedo or cost");
  EXPECT_EQ(aov_channels(Aov::index), std::vector<std::string>{"id"});
  EXPECT_EQ(kNoPoint, 0xFFFFFFFFu);  // the bits of int32 -1, as the renderer's uint32 "id" AOV stores a miss
}

}  // namespace
}  // namespace rayscan
