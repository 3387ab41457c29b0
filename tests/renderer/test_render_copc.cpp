// A COPC file is rendered in place (io::CopcIndex: nodes decoded as rays
// reach them, the albedo at shading time from the decoded node attributes). Oracle: the render of
// the same points read whole (io::read_point_cloud, the whole-file LAZ reader) through the
// in-memory octree, bit for bit in beauty and in the index, albedo and depth AOVs; the auto
// radius against a k-d tree over the whole cloud at the same samples.
#include "rayscan/site/copc.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/render.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;
namespace fs = std::filesystem;

namespace {

// The bundled copy (tests/data/laz, attribution in tests/data/README.md), else ../shared/data.
fs::path lone_star() {
  for (const fs::path& dir : {fs::path(RAYSCAN_TEST_DATA), fs::path(RAYSCAN_SHARED_DATA)})
    if (const fs::path p = dir / "laz" / "lone-star.copc.laz"; fs::exists(p)) return p;
  return {};
}

// A small view of the cloud: from `from` (a fraction of the box diagonal away from the centre).
Scene copc_scene(const AABB& b, const Vec3& from) {
  LookAtParams la;
  la.position = b.center() + from;
  la.look_at = b.center();
  Scene s;
  s.camera = Camera::look_at(la, 24, 16);
  s.spp = 1;
  s.max_depth = 2;
  s.seed = 5;
  s.output.aovs = {Aov::index, Aov::albedo, Aov::depth};
  return s;
}

}  // namespace

TEST(RenderCopc, InPlaceRenderEqualsTheWholeFileRender) {
  const fs::path p = lone_star();
  if (p.empty()) GTEST_SKIP() << "lone-star.copc.laz is in neither tests/data/laz nor ../shared/data/laz";
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  const AABB b = pc.bounds();
  for (ColorMode mode : {ColorMode::intensity, ColorMode::elevation}) {
    SCOPED_TRACE("mode " + std::to_string(int(mode)));
    RenderJobOptions copc;
    copc.scene = copc_scene(b, Vec3(-12.0, -16.0, 14.0));
    copc.scene.material.mode = mode;  // intensity and elevation: percentile ranges streamed node by node
    copc.scene.material.albedo_scale = 1.5f;
    copc.scene.cloud = p;
    copc.scene.radius = 0.05;  // the auto radius is the next test's
    copc.write = false;
    copc.control.threads = 2;
    copc.cache_bytes = std::size_t{1} << 20;  // 1 MB, under one node: tiles' ends evict while others trace
    AABB seen;
    double seen_reach = -1.0;
    const Camera cam = *copc.scene.camera;
    copc.camera_for_cloud = [&seen, &seen_reach, cam](const AABB& box, double reach) {
      seen = box;
      seen_reach = reach;
      return cam;
    };
    const RenderJobResult a = run_render(copc);
    EXPECT_EQ(seen.lo, b.lo);  // the exact bounds, from one streamed pass
    EXPECT_EQ(seen.hi, b.hi);
    EXPECT_EQ(seen_reach, a.radius.radius);  // the sphere radius: no farther is a sphere hit
    EXPECT_GT(a.copc_decodes, 0u);
    EXPECT_GT(a.copc_peak_cache_bytes, 0u);
    // The oracle: the same points read whole, the radius the in-place render chose.
    RenderJobOptions whole = copc;
    whole.camera_for_cloud = nullptr;
    whole.cloud = &pc;
    whole.scene.radius = a.radius.radius;
    const RenderJobResult w = run_render(whole);
    ASSERT_EQ(a.image.beauty.size(), w.image.beauty.size());
    EXPECT_EQ(std::memcmp(a.image.beauty.data(), w.image.beauty.data(), a.image.beauty.size() * sizeof(Color)), 0);
    EXPECT_EQ(std::memcmp(a.image.albedo.data(), w.image.albedo.data(), a.image.albedo.size() * sizeof(Color)), 0);
    EXPECT_EQ(std::memcmp(a.image.depth.data(), w.image.depth.data(), a.image.depth.size() * sizeof(float)), 0);
    EXPECT_EQ(a.image.index, w.image.index);
    std::size_t hit = 0;
    for (auto id : a.image.index) hit += id != kNoPoint;
    EXPECT_GT(hit, a.image.index.size() / 4);  // the comparison is not vacuous
  }
}

TEST(RenderCopc, AutoRadiusSamplesNodesAndTracingStartsWithoutReadingTheFile) {
  const fs::path p = lone_star();
  if (p.empty()) GTEST_SKIP() << "lone-star.copc.laz is in neither tests/data/laz nor ../shared/data/laz";
  const PointCloud pc = io::read_point_cloud(p, io::ReadOptions{.scalars = false});
  const AABB b = pc.bounds();
  // The auto radius: the median spacing at CopcIndex::spacing_samples, whose nearest neighbours
  // a k-d tree over the whole cloud must confirm.
  io::CopcIndex idx(p);
  const std::vector<Vec3> samples = idx.spacing_samples(2000);  // what run_render samples
  ASSERT_GT(samples.size(), 1000u);
  EXPECT_LT(idx.decodes(), idx.node_count()) << "the radius samples decoded every node";
  const AnyIndex kd = make_index(pc.positions, IndexOptions{.type = "kdtree"});
  const double spacing = rayscan::median_nn_spacing(kd, std::span<const Vec3>(samples), samples.size());
  // A close view of one corner, a constant material (no statistics pass): tracing decodes only
  // the nodes the rays reach.
  RenderJobOptions o;
  o.scene = copc_scene(b, Vec3(1.0, 1.0, 1.0));
  LookAtParams la;
  la.position = b.lo + Vec3(-2.0, -2.0, 6.0);
  la.look_at = b.lo + (b.hi - b.lo) * 0.1;
  la.vfov_deg = 30.0;
  o.scene.camera = Camera::look_at(la, 24, 16);
  o.scene.material.mode = ColorMode::constant;
  o.scene.radius = 0.05;
  o.scene.cloud = p;
  o.write = false;
  o.control.threads = 2;
  const RenderJobResult r = run_render(o);
  EXPECT_GT(r.copc_decodes, 0u);
  EXPECT_LT(r.copc_decodes, idx.node_count()) << "a corner view decoded every node";
  RenderJobOptions whole = o;
  whole.cloud = &pc;
  const RenderJobResult w = run_render(whole);
  EXPECT_EQ(r.image.index, w.image.index);
  EXPECT_EQ(std::memcmp(r.image.beauty.data(), w.image.beauty.data(), r.image.beauty.size() * sizeof(Color)), 0);
  // "radius": "auto" (a 4x3 image: the radius is what is checked).
  RenderJobOptions a = o;
  a.scene.radius.reset();
  a.scene.auto_radius_factor = 1.2;
  a.scene.camera = Camera::look_at(la, 4, 3);
  const RenderJobResult ra = run_render(a);
  EXPECT_TRUE(ra.radius.automatic);
  EXPECT_EQ(ra.radius.spacing, spacing);
  EXPECT_EQ(ra.radius.radius, 1.2 * spacing);
}
