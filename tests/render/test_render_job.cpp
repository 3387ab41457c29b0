// The render job as a library call (rayscan/render/render_job.hpp). Oracles: the lower-level
// calls it composes (compute_albedo, make_index, median_nn_spacing, render_image) run by hand,
// and the files' own bytes read back through OpenImageIO.
#include "rayscan/io/index_file.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/render_job.hpp"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::render;
namespace fs = std::filesystem;

namespace {

const PointCloud& subset() {
  static const PointCloud pc = io::read_point_cloud(fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz");
  return pc;
}

Scene small_scene() {
  const AABB b = subset().bounds();
  LookAtParams la;
  la.position = b.center() + Vec3(-45.0, -60.0, 50.0);
  la.look_at = b.center();
  Scene s;
  s.camera = Camera::look_at(la, 40, 30);
  s.material.mode = ColorMode::elevation;
  s.spp = 2;
  s.seed = 99;
  s.auto_radius_factor = 1.3;
  s.output.aovs = {Aov::index, Aov::depth};
  return s;
}

std::string what_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RenderJob, InMemoryCloudEqualsTheHandComposedRender) {
  RenderJobOptions o;
  o.scene = small_scene();
  o.cloud = &subset();
  o.write = false;
  o.control.threads = 2;
  std::vector<std::string> log;
  o.control.log = [&](const std::string& s) { log.push_back(s); };
  const RenderJobResult r = run_render(o);

  const AnyIndex index = make_index(subset().positions, o.scene.index);
  const double radius = 1.3 * median_nn_spacing(index, subset().positions);
  EXPECT_TRUE(r.radius.automatic);
  EXPECT_DOUBLE_EQ(r.radius.radius, radius);
  const std::vector<Color> albedo = compute_albedo(subset(), o.scene.material, o.scene.up);
  Framebuffer fb;
  render_image(index, make_settings(o.scene, subset().positions, albedo, radius), fb, {});
  ASSERT_EQ(r.image.beauty.size(), fb.beauty.size());
  EXPECT_EQ(std::memcmp(r.image.beauty.data(), fb.beauty.data(), fb.beauty.size() * sizeof(Color)), 0);
  EXPECT_EQ(r.image.index, fb.index);
  EXPECT_TRUE(r.written.empty());
  EXPECT_EQ(r.points, subset().size());
  ASSERT_FALSE(log.empty());
  EXPECT_NE(log.back().find("ray queries"), std::string::npos);
}

TEST(RenderJob, WritesTheImageAndAovsItNames) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_job_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  RenderJobOptions o;
  o.scene = small_scene();
  o.scene.radius = 0.9;
  o.scene.output.image = dir / "a.exr";
  o.cloud = &subset();
  const RenderJobResult r = run_render(o);
  ASSERT_EQ(r.written.size(), 1u);
  EXPECT_EQ(r.written[0], dir / "a.exr");
  EXPECT_FALSE(r.radius.automatic);
  auto in = OIIO::ImageInput::open((dir / "a.exr").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.width, 40);
  EXPECT_GE(spec.channelindex(aov_channels(Aov::index)[0]), 0);
  EXPECT_GE(spec.channelindex(aov_channels(Aov::depth)[0]), 0);
  EXPECT_EQ(spec.get_string_attribute("rayscan:radius"), "0.90000000000000002");
  in->close();
  fs::remove_all(dir);
}

TEST(RenderJob, ErrorsNameTheSceneField) {
  RenderJobOptions o;
  o.scene = small_scene();
  o.cloud = &subset();
  EXPECT_EQ(what_of([&] { (void)run_render(o); }),
            "(scene): /output/image: not set; give it in the scene or with --out");
  o.write = false;
  o.scene.camera.reset();
  EXPECT_NE(what_of([&] { (void)run_render(o); }).find("(scene): /camera: not set"), std::string::npos);
  o.scene = small_scene();
  o.scene.index.type = "rtree";
  EXPECT_EQ(what_of([&] { (void)run_render(o); }).rfind("(scene): /index: ", 0), 0u);
  PointCloud same;
  same.positions.assign(5, Vec3(1.0));
  o.scene = small_scene();
  o.cloud = &same;
  EXPECT_EQ(what_of([&] { (void)run_render(o); }),
            "(scene): /radius: \"auto\" needs at least two distinct points; give a number");
}

TEST(RenderJob, OverridesCheckEachValue) {
  Scene s = small_scene();
  SceneOverrides ov;
  ov.width = 80;  // height follows the 4:3 aspect ratio
  ov.aovs = {"normal", "index"};
  ov.spp = 5;
  apply_overrides(s, ov);
  EXPECT_EQ(s.camera->width(), 80u);
  EXPECT_EQ(s.camera->height(), 60u);
  EXPECT_EQ(s.spp, 5u);
  EXPECT_EQ(s.output.aovs, (std::vector<Aov>{Aov::index, Aov::depth, Aov::normal}));
  SceneOverrides bad_aov, bad_out;
  bad_aov.aovs = {"colour"};
  bad_out.out = "x.bmp";
  EXPECT_EQ(what_of([&] { apply_overrides(s, bad_aov); }),
            "--aov 'colour': expected depth, normal, position, index, albedo or cost");
  EXPECT_EQ(what_of([&] { apply_overrides(s, bad_out); }),
            "--out 'x.bmp': expected a file name ending in .png, .jpg, .jpeg, .tif, .tiff or .exr");
}

// Issue 10: rendering the index file (.rsi) of a cloud gives the image of the cloud itself, bit
// for bit, for spheres and for surfels (normals and radii by kNN over the mapped tree): the ray
// queries are exact, so the tree the hits come from must not show. Oracle: the render of the
// source file through the in-memory index.
TEST(RenderJob, IndexFileRendersLikeTheSourceCloud) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_rsi_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path src = fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz", rsi = dir / "subset.rsi";
  io::IndexBuildOptions bo;
  bo.config.capacity = 16;  // a different tree from the scene's in-memory one
  io::build_index_file({src}, rsi, bo);
  for (Primitive prim : {Primitive::sphere, Primitive::surfel}) {
    SCOPED_TRACE(prim == Primitive::surfel ? "surfel" : "sphere");
    RenderJobResult r[2];
    for (int k = 0; k < 2; ++k) {
      RenderJobOptions o;
      o.scene = small_scene();
      o.scene.primitive = prim;
      o.scene.cloud = k == 0 ? src : rsi;
      o.write = false;
      o.control.threads = 2;
      r[k] = run_render(o);
    }
    ASSERT_EQ(r[0].image.beauty.size(), r[1].image.beauty.size());
    EXPECT_EQ(std::memcmp(r[0].image.beauty.data(), r[1].image.beauty.data(), r[0].image.beauty.size() * sizeof(Color)), 0);
    EXPECT_EQ(r[0].image.index, r[1].image.index);
    EXPECT_EQ(r[0].radius.radius, r[1].radius.radius);
    std::size_t hit = 0;
    for (auto id : r[0].image.index) hit += id != kNoPoint;
    EXPECT_GT(hit, r[0].image.index.size() / 4);  // the comparison is not vacuous
  }
  fs::remove_all(dir);
}
