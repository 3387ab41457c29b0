// Site: Site::open chooses the storage from the file, and every storage of the same points answers
// a ray query as the brute-force oracle over the points read whole does.
#include "../io/io_test_util.hpp"

#include "rayscan/octree/brute_force.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/site/site.hpp"

#include <algorithm>
#include <random>
#include <type_traits>

namespace rayscan::test {
namespace {

// Downward, slightly slanted rays over the cloud's bounds (fixed seed).
std::vector<Ray> rays_over(const AABB& b, std::size_t n) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Ray> rays;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 o{b.lo.x + u(rng) * (b.hi.x - b.lo.x), b.lo.y + u(rng) * (b.hi.y - b.lo.y), b.hi.z + 10.0};
    rays.push_back(Ray(o, glm::normalize(Vec3{0.05 * (u(rng) - 0.5), 0.05 * (u(rng) - 0.5), -1.0})));
  }
  return rays;
}

// The (t, position) of each hit, in the query's order: storage-independent (indices are original
// ids in memory and in an index file with ids, slots in COPC).
struct Hit {
  double t;
  Vec3 p;
  bool operator==(const Hit&) const = default;
};

std::vector<std::vector<Hit>> answers(const rayscan::Site& site, std::span<const Vec3> original, const std::vector<Ray>& rays,
                                      const RayQuery& q) {
  std::vector<std::vector<Hit>> out;
  for (const Ray& ray : rays) {
    out.push_back(site.visit([&](const auto& idx) {
      std::vector<Hit> h;
      for (const RayHit& x : ray_query(idx, ray, q)) {
        if constexpr (is_copc_index<decltype(idx)>)
          h.push_back({x.t, idx.position_of(x.index)});
        else
          h.push_back({x.t, original[x.index]});
      }
      return h;
    }));
  }
  return out;
}

TEST(Site, OpenChoosesTheStorageAndEveryStorageAnswersAsBruteForce) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  const PointCloud cloud = io::read_point_cloud(las);
  const BruteForceIndex brute(cloud.positions);
  const std::vector<Ray> rays = rays_over(bounds_of(cloud.positions), 200);
  RayQuery q;
  q.k = 4;
  q.radius = 3.0;  // international feet: about a point spacing
  const auto expected = answers(rayscan::Site(AnyIndex(brute)), cloud.positions, rays, q);
  std::size_t hits = 0;
  for (const auto& h : expected) hits += h.size();
  ASSERT_GT(hits, rays.size());  // the rays meet the cloud

  // A point file: read and indexed in memory (the default octree).
  SiteOpenTimes times;
  const rayscan::Site mem = rayscan::Site::open(las, {}, &times);
  EXPECT_EQ(mem.storage(), SiteStorage::memory);
  ASSERT_NE(mem.cloud(), nullptr);
  EXPECT_EQ(mem.size(), cloud.size());
  EXPECT_GE(times.read_seconds, 0.0);
  mem.visit([](const auto& idx) { EXPECT_TRUE((std::is_same_v<std::remove_cvref_t<decltype(idx)>, Octree>)); });
  EXPECT_EQ(answers(mem, mem.cloud()->positions, rays, q), expected);

  // The same points as an index file: mapped, queried in place.
  const fs::path dir = temp_dir() / "site";
  fs::create_directories(dir);
  io::IndexBuildOptions bo;
  bo.attributes = io::AttributeSet::parse("id");
  io::build_index_file({las}, dir / "autzen.rsi", bo);
  const rayscan::Site rsi = rayscan::Site::open(dir / "autzen.rsi");
  EXPECT_EQ(rsi.storage(), SiteStorage::index_file);
  EXPECT_EQ(rsi.cloud(), nullptr);
  ASSERT_NE(rsi.index_file(), nullptr);
  EXPECT_EQ(rsi.size(), cloud.size());
  EXPECT_EQ(answers(rsi, cloud.positions, rays, q), expected);

  // The surfel estimate over a site: the same attributes in memory and in the index file.
  SurfelOptions so;
  so.measure_thickness = false;
  const SurfelAttributes sm = estimate_surfels(mem, cloud.positions, so);
  const SurfelAttributes sr = estimate_surfels(rsi, cloud.positions, so);
  ASSERT_EQ(sm.normals.size(), cloud.size());
  EXPECT_TRUE(sm.normals == sr.normals);
  EXPECT_TRUE(sm.radii == sr.radii);
  EXPECT_GT(median_nn_spacing(mem, cloud.positions), 0.0);

  // A copy shares the storage and outlives the original handle.
  std::optional<rayscan::Site> first = rayscan::Site::open(dir / "autzen.rsi");
  const rayscan::Site copy = *first;
  first.reset();
  EXPECT_EQ(answers(copy, cloud.positions, rays, q), expected);
}

TEST(Site, CopcOpensInPlaceOrInMemoryWithTheSameAnswers) {
  RAYSCAN_REQUIRE_FILE(copc, "laz/lone-star.copc.laz");
  const rayscan::Site in_place = rayscan::Site::open(copc);
  EXPECT_EQ(in_place.storage(), SiteStorage::copc);
  ASSERT_NE(in_place.copc(), nullptr);
  SiteOptions whole;
  whole.copc_in_place = false;
  const rayscan::Site mem = rayscan::Site::open(copc, whole);
  EXPECT_EQ(mem.storage(), SiteStorage::memory);
  ASSERT_NE(mem.cloud(), nullptr);
  EXPECT_EQ(in_place.size(), mem.size());
  EXPECT_EQ(in_place.size(), 518862u);  // tests/data/README.md

  const BruteForceIndex brute(mem.cloud()->positions);
  const std::vector<Ray> rays = rays_over(bounds_of(mem.cloud()->positions), 100);
  RayQuery q;
  q.k = 1;
  q.radius = 0.05;  // metres
  const auto expected = answers(rayscan::Site(AnyIndex(brute)), mem.cloud()->positions, rays, q);
  EXPECT_EQ(answers(mem, mem.cloud()->positions, rays, q), expected);
  EXPECT_EQ(answers(in_place, {}, rays, q), expected);
  // The auto radius: without the points, from a sample of the hierarchy's nodes; given them (file
  // order), the in-memory value exactly. Surfels are estimated in place too
  // (tests/analysis/test_jobs.cpp, VisibilityJob.CopcInPlaceSurfels*), but not the thickness,
  // whose patches are runs of storage slots.
  EXPECT_GT(median_nn_spacing(in_place, {}), 0.0);
  EXPECT_EQ(median_nn_spacing(in_place, mem.cloud()->positions), median_nn_spacing(mem, mem.cloud()->positions));
  EXPECT_THROW((void)estimate_surfels(in_place, mem.cloud()->positions, SurfelOptions{}), std::invalid_argument);
}

TEST(Site, ReferringToAnIndexDoesNotOwnIt) {
  const std::vector<Vec3> pts{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const AnyIndex index = make_index(pts, {});
  const rayscan::Site site(index);
  EXPECT_EQ(site.storage(), SiteStorage::memory);
  EXPECT_EQ(site.memory_index(), &index);
  EXPECT_EQ(site.cloud(), nullptr);
  EXPECT_EQ(site.size(), 3u);
}

}  // namespace
}  // namespace rayscan::test
