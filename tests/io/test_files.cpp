// Every file of the shared data set (LAZ and COPC included) is read with the point count and the recomputed
// bounding box that ../shared/data/README.md gives for it (values copied from that README, which
// computed them by reading every point with an independent reader; rounded to the decimals shown).
#include "io_test_util.hpp"

#include <cmath>

namespace rayscan::test {
namespace {

struct Expect {
  const char* rel;
  std::size_t count;
  std::uint64_t dropped;
  Vec3 lo, hi;
  int decimals;  // decimals the README prints: tolerance 0.5 * 10^-decimals
};

void PrintTo(const Expect& e, std::ostream* os) { *os << e.rel; }

const Expect kFiles[] = {
    {"las/4_6_crop.las", 23875, 0, {1639600.00, 1454500.02, 7077.92}, {1639799.98, 1454700.00, 7139.70}, 2},
    {"las/Haystack_Rock.las", 21932, 0, {2230738.84, 252070.78, -1.316}, {2231104.52, 252410.10, 80.815}, 2},
    {"las/autzen_trim.las", 110000, 0, {636001.76, 848935.20, 406.26}, {637179.22, 849497.90, 520.51}, 2},
    {"las/hexbin-crop.las", 38367, 0, {393775.823, 3689071.943, 3107.863}, {394069.238, 3689273.095, 3209.321}, 3},
    {"las/mvk-thin.las", 6280, 0, {2045001.76, 1267501.19, 95.79}, {2049993.92, 1272499.79, 228.73}, 2},
    {"las/warsaw_small.las", 3000, 0, {639913.26, 485143.14, 84.70}, {639946.75, 485175.91, 104.55}, 2},
    {"las/conformance/1.0_0.las", 1, 0, {470692.44, 4602888.90, 16.00}, {470692.44, 4602888.90, 16.00}, 2},
    {"las/conformance/1.0_1.las", 1, 0, {470692.44, 4602888.90, 16.00}, {470692.44, 4602888.90, 16.00}, 2},
    {"las/conformance/TO_core_last_clip.las", 8, 0, {630262.30, 4834500.00, 50.90}, {630346.83, 4834500.00, 55.26}, 2},
    {"las/conformance/point10.las", 1065, 0, {493994.87, 4877429.62, 123.93}, {494993.68, 4878817.02, 178.73}, 2},
    {"las/conformance/point-time.las", 1065, 0, {493994.87, 4877429.62, 123.93}, {494993.68, 4878817.02, 178.73}, 2},
    {"las/conformance/point-color.las", 1065, 0, {493994.87, 4877429.62, 123.93}, {494993.68, 4878817.02, 178.73}, 2},
    {"las/conformance/point-color-time.las", 1065, 0, {493994.87, 4877429.62, 123.93}, {494993.68, 4878817.02, 178.73}, 2},
    {"las/conformance/simple1_1.las", 1065, 0, {635619.85, 848899.70, 406.59}, {638982.55, 853535.43, 586.38}, 2},
    {"las/conformance/lots_of_vlr.las", 1, 0, {715001.346, 839349.171, 17.275}, {715001.346, 839349.171, 17.275}, 3},
    {"las/conformance/no-points-1.3.las", 0, 0, {0, 0, 0}, {0, 0, 0}, 0},
    {"las/conformance/vegetation_1_3.las", 10683, 0, {-98451.205, -55975.417, -81460.091}, {-98447.447, -55969.405, -81455.203}, 3},
    {"las/conformance/simple1_3.las", 999, 0, {-235434.519, 5800843.145, 265.094}, {-234935.841, 5800946.249, 273.811}, 3},
    {"las/conformance/test1_4.las", 1000, 0, {1694038.446, 1816492.706, 5592.750}, {1694539.677, 1816497.976, 5599.070}, 3},
    {"las/conformance/1_4_w_evlr.las", 1000, 0, {1694038.446, 1816492.706, 5592.750}, {1694539.677, 1816497.976, 5599.070}, 3},
    {"las/conformance/file_with_both_wkt_and_geotiff_vlrs.las", 25408, 0, {2445180.00, 604300.00, 1352.70}, {2445239.99, 604339.98, 1403.96}, 2},
    {"las/conformance/extrabytes.las", 1065, 0, {635619.85, 848899.70, 406.59}, {638982.55, 853535.43, 586.38}, 2},
    {"las/conformance/autzen_trim_7.las", 110000, 0, {636001.76, 848935.20, 406.26}, {637179.22, 849497.90, 520.51}, 2},
    {"las/derived/lone-star.las", 518862, 0, {515368.602, 4918340.364, 2322.896}, {515401.043, 4918381.124, 2338.575}, 3},
    {"las/derived/append-bug.las", 37805, 0, {698000.00, 6259242.79, 11.72}, {699000.00, 6260000.00, 266.03}, 2},
    {"las/derived/las_with_several_extra_byte_bloc.las", 697721, 0, {484649.36, 6632629.73, 99.65}, {484999.99, 6632999.99, 120.42}, 2},
    {"laz/autzen_trim.laz", 110000, 0, {636001.76, 848935.20, 406.26}, {637179.22, 849497.90, 520.51}, 2},
    {"laz/lone-star.laz", 518862, 0, {515368.602, 4918340.364, 2322.896}, {515401.043, 4918381.124, 2338.575}, 3},
    {"laz/lone-star.copc.laz", 518862, 0, {515368.602, 4918340.364, 2322.896}, {515401.043, 4918381.124, 2338.576}, 3},
    {"laz/append-bug.laz", 37805, 0, {698000.00, 6259242.79, 11.72}, {699000.00, 6260000.00, 266.03}, 2},
    {"laz/las_with_several_extra_byte_bloc.laz", 697721, 0, {484649.36, 6632629.73, 99.65}, {484999.99, 6632999.99, 120.42}, 2},
    {"pcd/table_scene_lms400.pcd", 460400, 0, {-1.1263, -0.6922, -1.9211}, {0.9297, 0.5333, -1.0252}, 4},
    {"pcd/table_scene_mug_stereo_textured.pcd", 209280, 307200 - 209280, {-0.4564, -0.5107, 0.6900}, {0.7152, 0.1792, 2.5927}, 4},
    {"pcd/milk_cartoon_all_small_clorox.pcd", 241407, 307200 - 241407, {-1.0608, -0.2197, -2.0630}, {1.1525, 0.8692, -0.5010}, 4},
    {"pcd/milk.pcd", 12575, 0, {0.1787, -0.2108, -0.8268}, {0.3254, 0.0001, -0.6362}, 4},
    {"pcd/lamppost.pcd", 1771, 0, {-11.1719, -0.3750, -5.4480}, {-9.7656, 0.5938, 0.4670}, 4},
    {"pcd/office1.pcd", 254456, 307200 - 254456, {-2.6455, -2.1964, 1.8330}, {1.5044, 1.5812, 5.3640}, 4},
    {"pcd/autzen-utm.pcd", 1065, 0, {493994.87, 4877429.62, 123.93}, {494993.68, 4878817.02, 178.73}, 2},
    {"pcd/utm17_space.pcd", 10, 0, {289814.15, 4320978.61, 170.58}, {289818.50, 4320980.59, 170.76}, 2},
    {"pcd/cloud_bin_0.pcd", 3903, 0, {1.2317, -0.0049, -2.2900}, {2.9490, 2.0861, -0.8090}, 4},
    {"ply/bunny.ply", 1889, 0, {-0.0944, 0.0334, -0.0617}, {0.0609, 0.1848, 0.0585}, 4},
    {"ply/rs1_normals.ply", 114373, 0, {-171.03, -137.20, -746.39}, {124.37, 129.12, -566.38}, 2},
    {"ply/frag_115.ply", 64365, 0, {0.8398, 0.9180, 0.5664}, {2.5724, 2.8135, 1.6089}, 4},
    {"ply/conformance/points.ply", 4, 0, {0, 0, 0}, {0, 1, 1}, 9},
    {"ply/conformance/cube_binary.ply", 8, 0, {0, 0, 0}, {1, 1, 1}, 9},
    {"ply/conformance/float-color.ply", 3, 0, {0, 0, 0}, {200, 200, 0}, 9},
    {"ply/conformance/simple_binary.ply", 3, 0, {-1, 0, 0}, {1, 1, 0}, 9},
    {"ply/conformance/text_extradim.ply", 1, 0, {-2.6494, -13.0955, 0.0064}, {-2.6494, -13.0955, 0.0064}, 4},
};

class RealFile : public ::testing::TestWithParam<Expect> {};

TEST_P(RealFile, CountAndRecomputedBoundsMatchTheDataReadme) {
  const Expect& e = GetParam();
  RAYSCAN_REQUIRE_FILE(path, e.rel);
  io::FileInfo info;
  const PointCloud pc = io::read_point_cloud(path, {}, &info);
  EXPECT_NO_THROW(pc.validate());
  ASSERT_EQ(pc.size(), e.count) << path;
  EXPECT_EQ(info.dropped_nonfinite, e.dropped);
  EXPECT_EQ(info.header_point_count, e.count + e.dropped);
  if (e.count == 0) {
    EXPECT_TRUE(pc.bounds().empty());
    return;
  }
  const AABB b = pc.bounds();
  const double tol = 0.5 * std::pow(10.0, -e.decimals) + 1e-9;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.lo[k], e.lo[k], tol) << "axis " << k;
    EXPECT_NEAR(b.hi[k], e.hi[k], tol) << "axis " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealFile, ::testing::ValuesIn(kFiles), [](const auto& info) {
  const std::filesystem::path rel(info.param.rel);
  std::string s = rel.stem().string();
  if (rel.extension() == ".laz") s += "_laz";
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return s;
});

TEST(RealFile, TableCoversEveryFileOfTheSharedData) {
  const std::filesystem::path root(RAYSCAN_SHARED_DATA);
  if (!std::filesystem::exists(root)) GTEST_SKIP() << "../shared/data absent";
  std::size_t n = 0;
  for (const auto& de : std::filesystem::recursive_directory_iterator(root)) {
    const std::string ext = de.path().extension().string();
    if (ext != ".las" && ext != ".laz" && ext != ".ply" && ext != ".pcd") continue;
    ++n;
    const std::string rel = std::filesystem::relative(de.path(), root).string();
    bool found = false;
    for (const Expect& e : kFiles) found |= rel == e.rel;
    EXPECT_TRUE(found) << rel << " has no entry in kFiles";
  }
  EXPECT_EQ(n, std::size(kFiles));
}

}  // namespace
}  // namespace rayscan::test
