// The renderer traces the camera rays of each 4x4 pixel block (one sample
// index at a time) and their shadow rays as packets (ray_first_hit_packet / ray_any_hit_packet),
// and the bounce rays and theirs through ray_first_hit_each (forced here to its interleaved pairs).
// Oracle: the same render with packets off (every ray traced alone with ray_first_hit, the path
// loop of PathTracer::trace); the images must be identical byte for byte, on the index types that
// take packets (octree, index file) and one that does not (kd-tree: per-ray child tests inside the
// packet), for both hit modes, Russian roulette, partial blocks at tile and image edges, AOVs,
// and surfel mode (first_surfel_hit_packet for the camera rays and, each leaving its own
// surface, their shadow rays).
#include "../common/temp_dir.hpp"
#include "render_test_data.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/surfel_setup.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::render;
namespace fs = std::filesystem;

namespace {

using rayscan::render::test::subset;

// Oblique view of the autzen subset (trees and ground) with a low sun, so that shadow rays are
// both blocked and free; 45 x 34 px so that 4x4 blocks and 7 px tiles end in partial ones.
Scene packet_scene() {
  Scene s = rayscan::render::test::subset_scene(45, 34);
  s.sun.direction = glm::normalize(Vec3(0.6, -0.3, 0.5));
  s.seed = 777;
  return s;
}

template <class I>
void expect_packets_identical(const I& index, const RenderSettings& set, unsigned tile, const std::string& what) {
  SCOPED_TRACE(what);
  // The bounce rays' pairs (ray_first_hit_each) on, whatever this CPU's default.
  const bool saved_pairs = interleaved_pairs();
  set_interleaved_pairs(true);
  Framebuffer fb[2];
  for (int k = 0; k < 2; ++k) {
    RenderOptions o;
    o.threads = 2;
    o.tile_size = tile;
    o.packets = k == 1;
    render_image(index, set, fb[k], o);
  }
  set_interleaved_pairs(saved_pairs);
  ASSERT_EQ(fb[0].beauty.size(), fb[1].beauty.size());
  EXPECT_EQ(std::memcmp(fb[0].beauty.data(), fb[1].beauty.data(), fb[0].beauty.size() * sizeof(Color)), 0);
  EXPECT_EQ(fb[0].depth.size(), fb[1].depth.size());
  EXPECT_EQ(std::memcmp(fb[0].depth.data(), fb[1].depth.data(), fb[0].depth.size() * sizeof(float)), 0);
  EXPECT_EQ(fb[0].index, fb[1].index);
  // Not vacuous: the view holds hits and misses, lit and shadowed pixels.
  std::size_t hit = 0;
  for (auto id : fb[0].index) hit += id != kNoPoint;
  EXPECT_GT(hit, fb[0].index.size() / 8);
  EXPECT_LT(hit, fb[0].index.size());
}

}  // namespace

TEST(RenderPackets, ImageIdenticalWithAndWithoutPackets) {
  const PointCloud& pc = subset();
  std::vector<Color> albedo(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) albedo[i] = Color(0.3f + 0.5f * float(i % 7) / 7.0f, 0.5f, 0.4f);
  Scene s = packet_scene();
  s.output.aovs = {Aov::depth, Aov::index};
  const AnyIndex octree = make_index(pc.positions, IndexOptions{});
  IndexOptions kd;
  kd.type = "kdtree";
  const AnyIndex kdtree = make_index(pc.positions, kd);
  for (const HitMode hit : {HitMode::sphere, HitMode::closest_point}) {
    Scene sh = s;
    sh.hit = hit;
    const std::string mode = hit == HitMode::sphere ? "sphere" : "closest_point";
    expect_packets_identical(octree, make_settings(sh, pc.positions, albedo, 0.8), 16, "octree " + mode);
    expect_packets_identical(octree, make_settings(sh, pc.positions, albedo, 0.8), 7, "octree tile 7 " + mode);
  }
  Scene rr = s;
  rr.max_depth = 5;
  rr.russian_roulette_depth = 2;
  expect_packets_identical(octree, make_settings(rr, pc.positions, albedo, 0.8), 16, "octree roulette");
  expect_packets_identical(kdtree, make_settings(s, pc.positions, albedo, 0.8), 16, "kdtree");

  // The index file (io::MappedIndex), traced in place.
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_render_packets");
  const fs::path rsi = dir / "subset.rsi";
  io::IndexBuildOptions bo;
  bo.attributes = io::AttributeSet::parse("id");  // the settings' per-point arrays are in the source's order
  io::build_index_file({fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz"}, rsi, bo);
  {
    const io::MappedIndex m = io::MappedIndex::open(rsi);
    expect_packets_identical(m, make_settings(s, pc.positions, albedo, 0.8), 16, "index file");
  }

  // Surfel mode: camera rays and their shadow rays in packets of refined-key (disc) queries with
  // per-node radii and float disc boxes, on the octree and the index file.
  Scene su = s;
  su.primitive = Primitive::surfel;
  const SurfelAttributes sa = scene_surfels(su, octree, pc);
  RenderSettings rs = make_settings(su, pc.positions, albedo, 0.8);
  use_surfels(rs, sa);
  expect_packets_identical(octree, rs, 16, "octree surfel");
  expect_packets_identical(octree, rs, 7, "octree tile 7 surfel");
  {
    const io::MappedIndex m = io::MappedIndex::open(rsi);
    expect_packets_identical(m, rs, 16, "index file surfel");
  }
  fs::remove_all(dir);
}
