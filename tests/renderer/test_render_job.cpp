// The render job as a library call (rayscan/jobs/render.hpp). Oracles: the lower-level
// calls it composes (compute_albedo, make_index, median_nn_spacing, render_image) run by hand.
// The files it writes, read back through OpenImageIO: test_render_files.cpp.
#include "render_test_data.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/jobs/render.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;
namespace fs = std::filesystem;

namespace {

using rayscan::render::test::subset;

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

TEST(RenderJob, ErrorsNameTheSceneField) {
  RenderJobOptions o;
  o.scene = small_scene();
  o.cloud = &subset();
  EXPECT_EQ(what_of([&] { (void)run_render(o); }),
            "(scene): /output/image: not set; give it in the scene or set the out option");
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
  s.apply(ov);
  EXPECT_EQ(s.camera->width(), 80u);
  EXPECT_EQ(s.camera->height(), 60u);
  EXPECT_EQ(s.spp, 5u);
  EXPECT_EQ(s.output.aovs, (std::vector<Aov>{Aov::index, Aov::depth, Aov::normal}));
  SceneOverrides bad_aov, bad_out;
  bad_aov.aovs = {"colour"};
  bad_out.out = "x.bmp";
  EXPECT_EQ(what_of([&] { s.apply(bad_aov); }),
            "aovs 'colour': expected depth, normal, position, index, albedo or cost");
  EXPECT_EQ(what_of([&] { s.apply(bad_out); }),
            "out 'x.bmp': expected a file name ending in .png, .jpg, .jpeg, .tif, .tiff or .exr");
}

// Rendering the index file (.rsi) of a cloud gives the image of the cloud itself, bit
// for bit, for spheres and for surfels (normals and radii by kNN over the mapped tree): the ray
// queries are exact, so the tree the hits come from must not show. Oracle: the render of the
// source file through the in-memory index.
TEST(RenderJob, IndexFileRendersLikeTheSourceCloud) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_rsi_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path src = fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz", rsi = dir / "subset.rsi";
  io::IndexBuildOptions bo;
  bo.config.capacity = 16;  // a different tree from the scene's in-memory one
  bo.attributes = io::AttributeSet::parse("id");  // the index AOV in the source's order
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

// An index file is traced in place, its albedo computed at shading time from
// the stored colour, intensity and classification (AlbedoRule over the slot-ordered attributes)
// instead of a per-point array. Oracle: the render of the source LAS through the in-memory index,
// for every material mode (8-bit and 16-bit colour, the intensity and elevation percentile
// ranges), compared bit for bit in beauty, the albedo AOV and the index AOV; and a camera from
// the cloud's exact bounds (the --ortho-map hook) gets the same bounds from both.
TEST(RenderJob, IndexFileAlbedoAtShadingTimeEqualsThePerPointArray) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_rsi_albedo_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const int bits : {8, 16}) {
    SCOPED_TRACE("colour bits " + std::to_string(bits));
    PointCloud pc = subset();
    const std::size_t n = pc.size();
    pc.rgb.resize(n);
    pc.intensity.resize(n);
    pc.classification.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t h = std::uint32_t(i) * 2654435761u;  // a deterministic spread of values
      const std::uint16_t m = bits == 8 ? 255 : 65535;
      pc.rgb[i] = {std::uint16_t((h >> 3) % (m + 1u)), std::uint16_t((h >> 11) % (m + 1u)), std::uint16_t((h >> 19) % (m + 1u))};
      pc.intensity[i] = std::uint16_t(h >> 16);
      pc.classification[i] = std::uint8_t((h >> 8) % 10);
    }
    const fs::path las = dir / ("src" + std::to_string(bits) + ".las"), rsi = dir / ("src" + std::to_string(bits) + ".rsi");
    io::write_las(las, pc);
    io::IndexBuildOptions bo;
    bo.config.capacity = 16;
    bo.attributes = io::AttributeSet::parse("id,rgb,intensity,classification");
    io::build_index_file({las}, rsi, bo);
    for (ColorMode mode : {ColorMode::rgb, ColorMode::intensity, ColorMode::classification, ColorMode::elevation,
                           ColorMode::constant}) {
      SCOPED_TRACE("mode " + std::to_string(int(mode)));
      RenderJobResult r[2];
      AABB bounds[2];
      for (int k = 0; k < 2; ++k) {
        RenderJobOptions o;
        o.scene = small_scene();
        o.scene.material.mode = mode;
        o.scene.material.albedo_scale = 1.7f;  // some albedos clamp
        o.scene.output.aovs = {Aov::index, Aov::albedo};
        o.scene.cloud = k == 0 ? las : rsi;
        o.write = false;
        o.control.threads = 2;
        const Camera cam = *o.scene.camera;
        o.camera_for_cloud = [&bounds, k, cam](const AABB& b) {
          bounds[k] = b;
          return cam;
        };
        r[k] = run_render(o);
      }
      EXPECT_EQ(bounds[0].lo, bounds[1].lo);
      EXPECT_EQ(bounds[0].hi, bounds[1].hi);
      ASSERT_EQ(r[0].image.beauty.size(), r[1].image.beauty.size());
      EXPECT_EQ(std::memcmp(r[0].image.beauty.data(), r[1].image.beauty.data(), r[0].image.beauty.size() * sizeof(Color)), 0);
      EXPECT_EQ(std::memcmp(r[0].image.albedo.data(), r[1].image.albedo.data(), r[0].image.albedo.size() * sizeof(Color)), 0);
      EXPECT_EQ(r[0].image.index, r[1].image.index);
      // The albedo AOV of a hit pixel is compute_albedo of the point it shows (the array oracle).
      const PointCloud back = io::read_point_cloud(las);
      MaterialDesc mat = small_scene().material;
      mat.mode = mode;
      mat.albedo_scale = 1.7f;
      const std::vector<Color> albedo = compute_albedo(back, mat, Vec3(0, 0, 1));
      std::size_t hit = 0;
      for (std::size_t p = 0; p < r[1].image.index.size(); ++p) {
        if (r[1].image.index[p] == kNoPoint) continue;
        ++hit;
        EXPECT_EQ(r[1].image.albedo[p], albedo[r[1].image.index[p]]);
      }
      EXPECT_GT(hit, r[1].image.index.size() / 4);
    }
  }
  fs::remove_all(dir);
}
