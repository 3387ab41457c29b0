// The render job as a library call (rayscan/jobs/render.hpp). Oracles: the lower-level
// calls it composes (compute_albedo, make_index, median_nn_spacing, render_image) run by hand.
// The files it writes, read back through OpenImageIO: test_render_files.cpp; the ortho map's
// GeoTIFFs read back through GDAL here.
#include "render_test_data.hpp"
#include "../common/temp_dir.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/jobs/render.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <memory>
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

TEST(RenderJob, OverridesRefuseWhatHasNoMeaning) {
  // Each AOV once, as in a scene file's output.aovs; one the scene already lists is kept once.
  Scene s = small_scene();
  SceneOverrides twice;
  twice.aovs = {"normal", "normal"};
  EXPECT_EQ(what_of([&] { s.apply(twice); }), "aovs 'normal': given twice");
  SceneOverrides again;
  again.aovs = {"depth"};
  s.apply(again);
  EXPECT_EQ(s.output.aovs, (std::vector<Aov>{Aov::index, Aov::depth}));
  // One camera: a camera file and a COLMAP photo together are refused before either is read.
  SceneOverrides both;
  both.camera_file = "no-such-camera.json";
  both.colmap_dir = "no-such-model";
  both.colmap_image = "a.jpg";
  EXPECT_EQ(what_of([&] { s.apply(both); }),
            "colmap_dir: the camera is the COLMAP photo's; do not give camera_file too");
  // Surfels are hit exactly: the scene's closest-point order has no meaning for them.
  Scene cp = small_scene();
  cp.hit = HitMode::closest_point;
  SceneOverrides surfel;
  surfel.primitive = "surfel";
  EXPECT_EQ(what_of([&] { cp.apply(surfel); }),
            "primitive 'surfel': the scene's /hit \"closest_point\" applies to spheres only");
  // JPEG holds 8 bits per channel: a 16-bit scene cannot be written as .jpg, and can as .png.
  Scene deep = small_scene();
  deep.output.bit_depth = 16;
  SceneOverrides jpg, png;
  jpg.out = "x.JPG";
  png.out = "x.png";
  EXPECT_EQ(what_of([&] { deep.apply(jpg); }),
            "out 'x.JPG': a JPEG image has 8 bits per channel; the scene's /output/bit_depth is 16");
  deep.apply(png);
  EXPECT_EQ(deep.output.image, fs::path("x.png"));
}

TEST(RenderJob, ColmapViewNamesItsModelAbsolutely) {
  // The image metadata names the camera's file (rayscan:camera_file): a COLMAP model given by a
  // relative folder is recorded absolute, so the record holds from any working directory.
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_colmap_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "cameras.txt") << "1 PINHOLE 100 80 90 90 50 40\n";
  std::ofstream(dir / "images.txt") << "1 1 0 0 0 0 0 0 1 a.jpg\n\n";
  Scene s = small_scene();
  SceneOverrides ov;
  ov.colmap_dir = fs::relative(dir);
  ov.colmap_image = "a.jpg";
  ASSERT_TRUE(ov.colmap_dir.is_relative());
  s.apply(ov);
  EXPECT_EQ(s.camera_file, fs::weakly_canonical(dir) / "images.txt");
  EXPECT_EQ(s.camera->width(), 100u);
  fs::remove_all(dir);
}

TEST(RenderJob, ExposureOverrideIsTheScenesOutputExposure) {
  Scene s = small_scene();
  SceneOverrides ov;
  ov.exposure = -1.5;
  s.apply(ov);
  EXPECT_EQ(s.output.exposure, -1.5);
  // --print-scene's JSON carries it, and reads back as the same value.
  EXPECT_NE(s.to_json().find("\"exposure\": -1.5"), std::string::npos) << s.to_json();
  for (double bad : {-30.5, 31.0, std::nan("")}) {
    SceneOverrides b;
    b.exposure = bad;
    EXPECT_EQ(what_of([&] { s.apply(b); }), "exposure: expected a number in [-30, 30] (stops)");
  }
  EXPECT_EQ(s.output.exposure, -1.5);
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
        o.camera_for_cloud = [&bounds, k, cam](const AABB& b, double) {
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

// A job whose cancel flag is set stops with rayscan::Cancelled and writes nothing: neither its
// image (nor the ortho map's GeoTIFFs) nor a temporary, the folder stays empty. With the flag
// there but clear, the same job writes the image of a render without one, byte for byte. The
// renderer's own check, per tile: render_image throws too.
TEST(RenderJob, ACancelledJobThrowsAndWritesNothing) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_render_cancel");
  std::atomic<bool> stop{true};
  RenderJobOptions o;
  o.scene = small_scene();
  o.scene.output.image = dir / "cancelled.exr";
  o.cloud = &subset();
  o.control.threads = 2;
  o.control.cancel = &stop;
  EXPECT_THROW((void)run_render(o), Cancelled);
  OrthoMapJobOptions m;
  m.render.scene.material.mode = ColorMode::elevation;
  m.render.scene.spp = 1;
  m.render.scene.output.image = dir / "map.tif";
  m.render.cloud = &subset();
  m.render.control = o.control;
  m.ortho_map = 2.0;
  m.dsm = dir / "dsm.tif";
  EXPECT_THROW((void)run_ortho_map(m), Cancelled);
  EXPECT_EQ(rayscan::test::entry_names(dir), std::set<std::string>{});

  stop = false;
  o.scene.output.image = dir / "clear.exr";
  EXPECT_EQ(run_render(o).written.front(), dir / "clear.exr");
  o.control.cancel = nullptr;
  o.scene.output.image = dir / "none.exr";
  (void)run_render(o);
  const auto bytes = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(bytes(dir / "clear.exr"), bytes(dir / "none.exr"));

  const AnyIndex index = make_index(subset().positions, o.scene.index);
  RenderOptions ro;
  stop = true;
  ro.cancel = &stop;
  Framebuffer fb;
  const std::vector<Color> albedo = compute_albedo(subset(), o.scene.material, o.scene.up);
  EXPECT_THROW(render_image(index, make_settings(o.scene, subset().positions, albedo, 1.0), fb, ro), Cancelled);
  fs::remove_all(dir);
}

// run_ortho_map as a library call, no CLI: the orthophoto and DSM it writes, read back through
// GDAL, lie on the footprint worked out by hand from grid_over's snapping rule (x0 = floor(x_min /
// c) c, y_top = (floor(y_max / c) + 1) c, one cell per started multiple of c) for a plane z = 5
// over x in [0.3, 19.8], y in [-3.7, 6.05] at c = 0.75: 27 x 14 cells from (0, 6.75). The DSM file
// holds the result's elevations (NoData where the ray missed), which are the plane's height
// exactly inside the cloud (the spheres' caps reach up to one radius above it, but no cell rises
// above the points within a radius of its centre, all at z = 5), and the orthophoto's alpha is
// 255 exactly where the DSM has a surface. A non-GeoTIFF name is refused naming the fields,
// before any work.
TEST(RenderJob, OrthoMapJobWritesGeoTiffsOnTheCloudsFootprint) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_ortho_job_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  PointCloud plane;
  for (int j = 0; j <= 65; ++j)  // y = -3.7 .. 6.05
    for (int i = 0; i <= 130; ++i) plane.positions.emplace_back(0.3 + 0.15 * i, -3.7 + 0.15 * j, 5.0);
  OrthoMapJobOptions o;
  o.render.scene.material.mode = ColorMode::elevation;
  o.render.scene.spp = 1;
  o.render.scene.output.image = dir / "o.tif";
  o.render.cloud = &plane;
  o.render.control.threads = 2;
  o.ortho_map = 0.75;
  o.dsm = dir / "d.tif";
  const OrthoMapJobResult r = run_ortho_map(o);
  const std::array<double, 6> gt{0.0, 0.75, 0.0, 6.75, 0.0, -0.75};
  const int cols = 27, rows = 14;
  ASSERT_TRUE(r.map);
  EXPECT_EQ(r.map->grid.geotransform(), gt);
  EXPECT_EQ(r.render.written, (std::vector<fs::path>{dir / "o.tif", dir / "d.tif"}));
  ASSERT_EQ(r.dsm.values.size(), std::size_t(cols * rows));

  GDALAllRegister();
  const auto open = [](const fs::path& f) {
    return std::unique_ptr<GDALDataset, void (*)(GDALDataset*)>(
        static_cast<GDALDataset*>(GDALOpen(f.c_str(), GA_ReadOnly)), [](GDALDataset* d) { GDALClose(d); });
  };
  const auto ortho = open(dir / "o.tif"), dsm = open(dir / "d.tif");
  ASSERT_TRUE(ortho && dsm);
  for (GDALDataset* d : {ortho.get(), dsm.get()}) {
    EXPECT_EQ(d->GetRasterXSize(), cols);
    EXPECT_EQ(d->GetRasterYSize(), rows);
    std::array<double, 6> file_gt{};
    ASSERT_EQ(d->GetGeoTransform(file_gt.data()), CE_None);
    EXPECT_EQ(file_gt, gt);
  }
  ASSERT_EQ(ortho->GetRasterCount(), 4);
  ASSERT_EQ(dsm->GetRasterCount(), 1);
  std::vector<float> z(std::size_t(cols * rows));
  std::vector<std::uint8_t> alpha(z.size());
  ASSERT_EQ(dsm->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, cols, rows, z.data(), cols, rows, GDT_Float32, 0, 0), CE_None);
  ASSERT_EQ(ortho->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, cols, rows, alpha.data(), cols, rows, GDT_Byte, 0, 0),
            CE_None);
  int has_nodata = 0;
  const double nodata = dsm->GetRasterBand(1)->GetNoDataValue(&has_nodata);
  ASSERT_TRUE(has_nodata);
  std::size_t inside = 0;
  for (int row = 0; row < rows; ++row)
    for (int col = 0; col < cols; ++col) {
      const std::size_t k = std::size_t(row) * cols + col;
      const float v = r.dsm.values[k];
      SCOPED_TRACE("cell " + std::to_string(col) + ", " + std::to_string(row));
      if (std::isnan(v)) EXPECT_EQ(z[k], float(nodata));
      else EXPECT_EQ(z[k], v);
      EXPECT_EQ(alpha[k], std::isnan(v) ? 0 : 255);
      const double x = 0.375 + 0.75 * col, y = 6.375 - 0.75 * row;  // the cell's centre
      if (x > 0.5 && x < 19.6 && y > -3.5 && y < 5.85) {
        ++inside;
        EXPECT_EQ(v, 5.0f);
      }
    }
  EXPECT_EQ(inside, std::size_t(25 * 13));  // columns 1..25, rows 1..13
  EXPECT_EQ(r.dsm_reach, r.render.radius.radius);
  // Every cell's ray passes between the points (0.075 off a point column and row), so each hit a
  // cap above z = 5 and was lowered.
  EXPECT_EQ(r.dsm_bounding.lowered, std::size_t(std::count_if(r.dsm.values.begin(), r.dsm.values.end(),
                                                               [](float v) { return !std::isnan(v); })));
  EXPECT_EQ(r.dsm_bounding.raised, 0u);

  OrthoMapJobOptions png = o;
  png.render.scene.output.image = dir / "o.png";
  png.dsm = dir / "d2.tif";
  EXPECT_EQ(what_of([&] { (void)run_ortho_map(png); }),
            "ortho_map: out '" + (dir / "o.png").string() + "': expected a file name ending in .tif or .tiff (GeoTIFF)");
  EXPECT_FALSE(fs::exists(dir / "o.png") || fs::exists(dir / "d2.tif"));
  fs::remove_all(dir);
}

// A tilted disc above a level one: two points at z = 0, A = (0.5, 0.5) with its normal tilted 30
// degrees from vertical towards -x, B = (2.5, 0.5) level, discs of radius 0.6 x 2 = 1.2 (k_radius
// 1). Mapped at c = 1 (3 x 1 cells from x = 0; rays from z_top = 1.02), the ray through cell 1's
// centre (1.5, 0.5) meets A's plane 1 from A at z = tan 30 = 0.577 (in-plane distance 1 / cos 30
// = 1.155 < 1.2: a hit) before B's level disc at z = 0, as the render through the map's camera
// shows: above both points. The DSM holds 0 there, the highest point within the reach 1.2 of that
// centre (A and B, 1 away), and 0 over A and B.
TEST(RenderJob, OrthoMapDsmStaysWithinThePointsUnderATiltedDisc) {
  PointCloud pc;
  pc.positions = {Vec3(0.5, 0.5, 0.0), Vec3(2.5, 0.5, 0.0)};
  pc.normals = {glm::vec3(-0.5f, 0.0f, float(std::sqrt(3.0) / 2.0)), glm::vec3(0.0f, 0.0f, 1.0f)};
  OrthoMapJobOptions o;
  o.render.scene.material.mode = ColorMode::elevation;
  o.render.scene.primitive = Primitive::surfel;
  o.render.scene.surfel.k_radius = 1;
  o.render.scene.spp = 1;
  o.render.cloud = &pc;
  o.render.write = false;
  o.render.control.threads = 1;
  o.ortho_map = 1.0;
  const OrthoMapJobResult r = run_ortho_map(o);
  ASSERT_TRUE(r.map);
  ASSERT_EQ(r.map->grid.cols, 3u);
  ASSERT_EQ(r.map->grid.rows, 1u);
  EXPECT_NEAR(r.dsm_reach, 1.2, 1e-6);  // (radii are floats)

  // The unbounded surface: the same scene rendered through the map's camera.
  RenderJobOptions raw = o.render;
  raw.scene.camera = r.map->camera;
  raw.scene.up = Vec3(0.0, 0.0, 1.0);
  raw.scene.output.aovs = {Aov::depth};
  const analysis::Raster surface = analysis::dsm_from_depth(*r.map, run_render(raw).image.depth);
  EXPECT_NEAR(surface.values[1], 1.0 / std::sqrt(3.0), 1e-4);  // tan 30 degrees

  ASSERT_EQ(r.dsm.values.size(), 3u);
  EXPECT_EQ(r.dsm.values, (std::vector<float>{0.0f, 0.0f, 0.0f}));
  EXPECT_GE(r.dsm_bounding.lowered, 1u);
}

// The DSM of a real scan (tests/data/las/autzen_trim.las, 110,000 points of roofs, trees and
// ground, surfels as a quick look has them, 3 ft cells) against a brute-force oracle over its
// points: every cell with a surface lies between the lowest and the highest point within the
// reach (the largest disc radius) of its centre, and so within the cloud's z range; cells there
// were lowered (the steep discs of roof and tree edges) and raised.
TEST(RenderJob, OrthoMapDsmOfAutzenIsBoundedByItsPoints) {
  const PointCloud pc = io::read_point_cloud(fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las", {});
  OrthoMapJobOptions o;
  o.render.scene.primitive = Primitive::surfel;
  o.render.scene.spp = 1;
  o.render.cloud = &pc;
  o.render.write = false;
  o.render.control.threads = 2;
  o.ortho_map = 3.0;
  const OrthoMapJobResult r = run_ortho_map(o);
  ASSERT_TRUE(r.map);
  const analysis::GridSpec& g = r.map->grid;
  const double reach = r.dsm_reach;
  ASSERT_GT(reach, 1.0);
  // The points by x, so that each cell tests only those within reach of its centre in x.
  std::vector<Vec3> by_x(pc.positions.begin(), pc.positions.end());
  std::sort(by_x.begin(), by_x.end(), [](const Vec3& a, const Vec3& b) { return a.x < b.x; });
  const double z_lo = std::min_element(by_x.begin(), by_x.end(), [](auto& a, auto& b) { return a.z < b.z; })->z;
  const double z_hi = std::max_element(by_x.begin(), by_x.end(), [](auto& a, auto& b) { return a.z < b.z; })->z;
  std::size_t cells = 0, bad = 0;
  for (std::uint32_t row = 0; row < g.rows; ++row)
    for (std::uint32_t col = 0; col < g.cols; ++col) {
      const float v = r.dsm.values[std::size_t(row) * g.cols + col];
      if (std::isnan(v)) continue;
      ++cells;
      const double x = g.x0 + (col + 0.5) * g.cell, y = g.y_top - (row + 0.5) * g.cell;
      double lo = kInf, hi = -kInf;
      auto it = std::lower_bound(by_x.begin(), by_x.end(), x - reach - 1e-6,
                                 [](const Vec3& p, double v) { return p.x < v; });
      for (; it != by_x.end() && it->x <= x + reach + 1e-6; ++it)
        if (std::hypot(it->x - x, it->y - y) <= reach * (1 + 1e-9)) lo = std::min(lo, it->z), hi = std::max(hi, it->z);
      const bool ok = v <= float(hi) && v >= float(lo) && v <= float(z_hi) && v >= float(z_lo);
      if (!ok && ++bad <= 5)
        ADD_FAILURE() << "cell " << col << ", " << row << ": " << v << " outside [" << lo << ", " << hi << "]";
    }
  EXPECT_EQ(bad, 0u);
  EXPECT_GT(cells, 50000u);
  EXPECT_GT(r.dsm_bounding.lowered, 100u);
  EXPECT_GT(r.dsm_bounding.raised, 100u);
}

// An orthophoto cell's colour is the mean over the cell, not the colour under its centre. A flat
// 1 x 1 square of points (spacing s = 1/32, spheres of radius s: each vertical ray shows the point
// nearest it in xy, so a colour edge between two columns of points lies exactly halfway between
// them) coloured A = (200, 60, 30) for x < 1/2 and B = (40, 120, 230) beyond (16-bit v x 257),
// mapped as ONE cell (ortho_map 1). Oracle: the area-weighted mean of the stored 8-bit values,
// A + f (B - A) for the fraction f of the hit area that is B, +-1 (8-bit rounding), with f only
// as uncertain as the strata of the cell's rays leave it (render::stratified_pixel_point):
//  - 16 rays, a 4 x 4 grid of strata whose column boundary is the edge: f = 1/2 exactly;
//  - 9 rays, 3 x 3: the middle column straddles the edge and each of its 3 rays falls either
//    side, so f is in [1/3, 2/3] (a single centre ray would give f = 0 or 1);
//  - 1 ray, through the centre: one point's colour as stored, A or B exactly.
// A half-empty cell (points only over x < 1/2: A, then B from x = 1/4) averages over the hits,
// not over the rays: 16 rays, the first column A, the second B, and the third column's 4 rays hit
// (B) only where the last spheres reach past x = 1/2, so f is in [1/2, 2/3] (misses counted as
// black would halve every channel), and its alpha is the share of the rays that hit, 8 to 12 of
// 16: the colour is not darkened by the misses, the alpha says how much of the cell is covered
// (unassociated). Each file records its rays per cell as RAYSCAN_SPP.
TEST(RenderJob, OrthoMapAlbedoIsTheCellsAreaWeightedMean) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_render_ortho_mean_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const double s = 1.0 / 32;
  const std::array<int, 3> A{200, 60, 30}, B{40, 120, 230};
  const auto square = [&](int columns, double b_from) {
    PointCloud pc;
    for (int j = 0; j < 32; ++j)
      for (int i = 0; i < columns; ++i) {
        const double x = (i + 0.5) * s;
        const std::array<int, 3>& c = x < b_from ? A : B;
        pc.positions.emplace_back(x, (j + 0.5) * s, 2.0);
        pc.rgb.push_back({std::uint16_t(c[0] * 257), std::uint16_t(c[1] * 257), std::uint16_t(c[2] * 257)});
      }
    return pc;
  };
  const PointCloud halves = square(32, 0.5), half_empty = square(16, 0.25);
  GDALAllRegister();
  // The one cell's RGBA bytes as GDAL reads them from the orthophoto of `cloud` at `spp` rays.
  const auto cell = [&](const PointCloud& cloud, std::uint32_t spp, const std::string& name) {
    OrthoMapJobOptions o;
    o.render.scene.spp = spp;
    o.render.scene.radius = s;
    o.render.scene.output.image = dir / (name + ".tif");
    o.render.cloud = &cloud;
    o.render.control.threads = 1;
    o.ortho_map = 1.0;
    (void)run_ortho_map(o);
    std::array<int, 4> rgba{-1, -1, -1, -1};
    const std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(
        static_cast<GDALDataset*>(GDALOpen((dir / (name + ".tif")).c_str(), GA_ReadOnly)),
        [](GDALDataset* d) { GDALClose(d); });
    EXPECT_TRUE(ds && ds->GetRasterXSize() == 1 && ds->GetRasterYSize() == 1 && ds->GetRasterCount() == 4) << name;
    if (!ds) return rgba;
    const char* rays = ds->GetMetadataItem("RAYSCAN_SPP");
    EXPECT_EQ(std::string(rays ? rays : ""), std::to_string(spp)) << name;
    for (int b = 0; b < 4; ++b) {
      std::uint8_t v = 0;
      EXPECT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Read, 0, 0, 1, 1, &v, 1, 1, GDT_Byte, 0, 0), CE_None);
      rgba[b] = v;
    }
    return rgba;
  };
  // Each channel within A + f (B - A) for f in [f_lo, f_hi], +-1.
  const auto expect_mean = [&](const std::array<int, 4>& got, double f_lo, double f_hi, const std::string& what,
                               int alpha_lo = 255, int alpha_hi = 255) {
    EXPECT_GE(got[3], alpha_lo) << what;
    EXPECT_LE(got[3], alpha_hi) << what;
    for (int c = 0; c < 3; ++c) {
      const double a = A[c] + f_lo * (B[c] - A[c]), b = A[c] + f_hi * (B[c] - A[c]);
      EXPECT_GE(got[c], std::min(a, b) - 1.0) << what << ", channel " << c;
      EXPECT_LE(got[c], std::max(a, b) + 1.0) << what << ", channel " << c;
    }
  };
  expect_mean(cell(halves, 16, "halves16"), 0.5, 0.5, "16 rays");
  expect_mean(cell(halves, 9, "halves9"), 1.0 / 3, 2.0 / 3, "9 rays");
  const std::array<int, 4> one = cell(halves, 1, "halves1");
  EXPECT_EQ(one[3], 255);
  EXPECT_TRUE((std::array<int, 3>{one[0], one[1], one[2]} == A || std::array<int, 3>{one[0], one[1], one[2]} == B))
      << one[0] << ", " << one[1] << ", " << one[2];
  expect_mean(cell(half_empty, 16, "half_empty16"), 0.5, 2.0 / 3, "half-empty cell, 16 rays", 128, 191);
  fs::remove_all(dir);
}
