// Top-down orthophoto and DSM: a tilted plane z = 5 + 0.1 x rendered through the
// ortho map camera gives back its analytic elevation per cell centre; the GeoTIFF carries the grid.
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/surfel_setup.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/render.hpp"

#include "../common/run_command.hpp"
#include "../common/sanitizers.hpp"
#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>

#include <gdal_priv.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::render;

TEST(OrthoMap, DsmOfATiltedPlaneIsItsAnalyticElevation) {
  std::vector<Vec3> pts;
  for (int j = 0; j <= 60; ++j)
    for (int i = 0; i <= 60; ++i) pts.push_back(Vec3(100.0 + 0.25 * i, 200.0 + 0.25 * j, 5.0 + 0.1 * 0.25 * i));
  AABB b;
  for (const Vec3& p : pts) b.expand(p);
  Scene s;
  s.spp = 1;
  s.max_depth = 1;
  s.output.aovs = {Aov::depth};
  const std::vector<Color> albedo(pts.size(), Color(0.5f));
  const AnyIndex index = make_index(pts, IndexOptions{});
  PointCloud pc;
  pc.positions = pts;
  s.surfel_orient_camera = false;
  const SurfelAttributes sa = scene_surfels(s, index, pc);
  const analysis::OrthoMap map = analysis::ortho_map(b, 1.0, sa.max_radius);
  ASSERT_EQ(map.grid.x0, 100.0);
  s.camera = map.camera;
  RenderSettings rs = make_settings(s, pts, albedo, 0.25);
  use_surfels(rs, sa);
  Framebuffer fb;
  render_image(index, rs, fb);
  const analysis::Raster dsm = analysis::dsm_from_depth(map, fb.depth);
  int checked = 0;
  for (std::uint32_t r = 0; r < map.grid.rows; ++r)
    for (std::uint32_t c = 0; c < map.grid.cols; ++c) {
      const double x = map.grid.x0 + (c + 0.5), y = map.grid.y_top - (r + 0.5);
      const float z = dsm.values[r * map.grid.cols + c];
      if (x > 115.0 || y > 215.0 || y < 200.0) {
        if (x > 116.0 || y > 216.0) {
          EXPECT_TRUE(std::isnan(z)) << c << "," << r;
        }
        continue;
      }
      EXPECT_NEAR(z, 5.0 + 0.1 * (x - 100.0), 1e-4) << c << "," << r;
      ++checked;
    }
  EXPECT_GT(checked, 150);
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::vector<float> hit(fb.depth.size());  // one ray per cell: covered where it hit
  for (std::size_t i = 0; i < hit.size(); ++i) hit[i] = std::isfinite(fb.depth[i]) ? 1.0f : 0.0f;
  analysis::write_ortho_geotiff(dir / "o.tif", map, fb.beauty, hit, 0.0, "");
  analysis::write_geotiff(dir / "d.tif", dsm, {});
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir / "o.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ds->GetGeoTransform(gt);
  // RGB plus alpha: the alpha band is 0 exactly on the cells where the DSM has no surface (NaN).
  ASSERT_EQ(ds->GetRasterCount(), 4);
  EXPECT_EQ(ds->GetRasterBand(4)->GetColorInterpretation(), GCI_AlphaBand);
  std::vector<std::uint8_t> alpha(dsm.values.size());
  ASSERT_EQ(ds->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, int(map.grid.cols), int(map.grid.rows), alpha.data(),
                                           int(map.grid.cols), int(map.grid.rows), GDT_Byte, 0, 0),
            CE_None);
  std::size_t holes = 0;
  for (std::size_t i = 0; i < alpha.size(); ++i) {
    EXPECT_EQ(alpha[i], std::isnan(dsm.values[i]) ? 0 : 255) << i;
    holes += alpha[i] == 0;
  }
  EXPECT_GT(holes, 0u);  // the plane does not cover the whole map: some cells must be transparent
  EXPECT_EQ(gt[0], map.grid.x0);
  EXPECT_EQ(gt[3], map.grid.y_top);
  EXPECT_EQ(gt[1], 1.0);
  EXPECT_EQ(gt[5], -1.0);
  GDALClose(ds);
  std::filesystem::remove_all(dir);
}

// The CLI end to end: `rayscan render SCENE --primitive surfel --ortho-map RES
// --out o.tif --dsm d.tif` over the same tilted plane written as a PLY; the DSM read back through
// GDAL gives the analytic elevation per cell centre, and misuse of the options exits 2.
TEST(OrthoMap, CliWritesOrthophotoAndDsm) {
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_cli_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  PointCloud pc;
  for (int j = 0; j <= 60; ++j)
    for (int i = 0; i <= 60; ++i) pc.positions.push_back(Vec3(100.0 + 0.25 * i, 200.0 + 0.25 * j, 5.0 + 0.025 * i));
  io::write_ply(dir / "plane.ply", pc);
  std::ofstream(dir / "scene.json") << R"({"cloud": "plane.ply", "spp": 1, "max_depth": 1, "material": {"color": "elevation"},
    "camera": {"width": 8, "height": 8, "position": [107, 180, 20], "look_at": [107, 207, 5]}})";
  const std::string base = std::string(RAYSCAN_BIN) + " render " + (dir / "scene.json").string() + " -q";
  const auto r = rayscan::test::run_command(base + " --primitive surfel --ortho-map 1 --out " +
                                            (dir / "o.tif").string() + " --dsm " + (dir / "d.tif").string());
  ASSERT_EQ(r.code, 0) << r.out;
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir / "d.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ds->GetGeoTransform(gt);
  EXPECT_EQ(gt[0], 100.0);
  EXPECT_EQ(gt[1], 1.0);
  const int cols = ds->GetRasterXSize(), rows = ds->GetRasterYSize();
  std::vector<float> z(std::size_t(cols) * rows);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, cols, rows, z.data(), cols, rows, GDT_Float32, 0, 0),
            CE_None);
  GDALClose(ds);
  int checked = 0;
  for (int row = 0; row < rows; ++row)
    for (int c = 0; c < cols; ++c) {
      const double x = gt[0] + (c + 0.5) * gt[1], y = gt[3] + (row + 0.5) * gt[5];
      if (x > 115.0 || y > 215.0 || y < 200.0) continue;
      EXPECT_NEAR(z[std::size_t(row) * cols + c], 5.0 + 0.1 * (x - 100.0), 1e-4) << c << "," << row;
      ++checked;
    }
  EXPECT_GT(checked, 150);
  EXPECT_TRUE(std::filesystem::exists(dir / "o.tif"));
  EXPECT_EQ(rayscan::test::run_command(base + " --dsm " + (dir / "x.tif").string()).code, 2);
  EXPECT_EQ(rayscan::test::run_command(base + " --ortho-map 1 --out " + (dir / "x.png").string()).code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.tif"));
  std::filesystem::remove_all(dir);
}

namespace {

// Band `b` (1-based) of a GDAL raster as bytes, row-major; empty when it cannot be read.
std::vector<std::uint8_t> byte_band(GDALDataset* ds, int b) {
  const int cols = ds->GetRasterXSize(), rows = ds->GetRasterYSize();
  std::vector<std::uint8_t> v(std::size_t(cols) * rows);
  if (ds->GetRasterBand(b)->RasterIO(GF_Read, 0, 0, cols, rows, v.data(), cols, rows, GDT_Byte, 0, 0) != CE_None)
    v.clear();
  return v;
}

std::string metadata_item(GDALDataset* ds, const char* key) {
  const char* v = ds->GetMetadataItem(key);
  return v ? v : "";
}

}  // namespace

// The orthophoto is a map of the points' own colours: a LAS of two flat 10 x 10 squares side by
// side, one coloured (200, 60, 30) stored as 16-bit v * 257, the other (40, 120, 230) stored as
// v * 256 (the two scalings writers use), rendered by `rayscan render CLOUD --ortho-map 1`: every
// cell whose centre lies more than a cell from the squares' edges holds its square's 8-bit colour
// (+-1, the 16-bit scaling) with alpha 255, whatever the sky. The shaded render of the same cloud
// (--ortho-colour shaded) is not those colours; each file says which it holds
// (RAYSCAN_ORTHO_COLOUR), the DSM carries the render's metadata as GDAL items (RAYSCAN_SPP), and
// the colour option is refused without --ortho-map or with an unknown value.
TEST(OrthoMap, OrthophotoCellsHoldThePointsOwnColours) {
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_rgb_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const int colours[2][3] = {{200, 60, 30}, {40, 120, 230}};
  const int scale[2] = {257, 256};
  PointCloud pc;
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 80; ++i) {
      const int sq = i < 40 ? 0 : 1;  // x < 10: square 0
      pc.positions.push_back(Vec3(0.125 + 0.25 * i, 0.125 + 0.25 * j, 3.0));
      pc.rgb.push_back({std::uint16_t(colours[sq][0] * scale[sq]), std::uint16_t(colours[sq][1] * scale[sq]),
                        std::uint16_t(colours[sq][2] * scale[sq])});
    }
  io::write_las(dir / "squares.las", pc);
  const std::string base = std::string(RAYSCAN_BIN) + " render -q " + (dir / "squares.las").string() + " --ortho-map 1";
  const auto albedo = rayscan::test::run_command(base + " --out " + (dir / "a.tif").string() + " --dsm " +
                                                 (dir / "d.tif").string());
  ASSERT_EQ(albedo.code, 0) << albedo.out;
  const auto shaded = rayscan::test::run_command(base + " --ortho-colour shaded --out " + (dir / "s.tif").string());
  ASSERT_EQ(shaded.code, 0) << shaded.out;

  GDALAllRegister();
  const auto open = [](const std::filesystem::path& f) {
    return std::unique_ptr<GDALDataset, void (*)(GDALDataset*)>(
        static_cast<GDALDataset*>(GDALOpen(f.c_str(), GA_ReadOnly)), [](GDALDataset* d) { GDALClose(d); });
  };
  const auto a = open(dir / "a.tif"), s = open(dir / "s.tif"), d = open(dir / "d.tif");
  ASSERT_TRUE(a && s && d);
  EXPECT_EQ(metadata_item(a.get(), "RAYSCAN_ORTHO_COLOUR"), "albedo");
  EXPECT_EQ(metadata_item(s.get(), "RAYSCAN_ORTHO_COLOUR"), "shaded");
  EXPECT_EQ(metadata_item(d.get(), "RAYSCAN_SPP"), "16");  // albedo: the mean of 16 rays per cell by default
  EXPECT_EQ(metadata_item(s.get(), "RAYSCAN_PRIMITIVE"), "surfel");
  double gt[6];
  ASSERT_EQ(a->GetGeoTransform(gt), CE_None);
  ASSERT_EQ(gt[0], 0.0);
  ASSERT_EQ(gt[3], 10.0);
  const int cols = a->GetRasterXSize(), rows = a->GetRasterYSize();
  ASSERT_EQ(cols, 20);
  ASSERT_EQ(rows, 10);
  std::vector<std::uint8_t> ab[4], sb[3];
  for (int b = 0; b < 4; ++b) {
    ab[b] = byte_band(a.get(), b + 1);
    ASSERT_EQ(ab[b].size(), std::size_t(cols * rows));
    if (b < 3) sb[b] = byte_band(s.get(), b + 1);
  }
  int checked[2] = {0, 0}, shaded_differs = 0;
  for (int row = 0; row < rows; ++row)
    for (int col = 0; col < cols; ++col) {
      const double x = col + 0.5, y = 10.0 - (row + 0.5);
      if (y < 1.0 || y > 9.0 || x < 1.0 || x > 19.0 || std::abs(x - 10.0) < 1.0) continue;
      const int sq = x < 10.0 ? 0 : 1;
      const std::size_t k = std::size_t(row) * cols + col;
      SCOPED_TRACE("cell " + std::to_string(col) + ", " + std::to_string(row));
      EXPECT_EQ(ab[3][k], 255);
      int off = 0;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(int(ab[c][k]), colours[sq][c], 1);
        off = std::max(off, std::abs(int(sb[c][k]) - colours[sq][c]));
      }
      shaded_differs += off > 10;
      ++checked[sq];
    }
  EXPECT_EQ(checked[0], 8 * 8);
  EXPECT_EQ(checked[1], 8 * 8);
  EXPECT_EQ(shaded_differs, checked[0] + checked[1]);  // sky light and shading change every cell

  const auto refused = [&](const std::string& args) { return rayscan::test::run_command(base + args).code; };
  EXPECT_EQ(refused(" --ortho-colour flat --out " + (dir / "x.tif").string()), 2);
  EXPECT_EQ(rayscan::test::run_command(std::string(RAYSCAN_BIN) + " render -q " + (dir / "squares.las").string() +
                                       " --ortho-colour shaded --out " + (dir / "x.png").string())
                .code,
            2);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.tif") || std::filesystem::exists(dir / "x.png"));
  std::filesystem::remove_all(dir);
}

// The map's elevation colours run along +z, the axis its camera looks down, even for a cloud
// without a CRS whose quick look estimates another up axis: a plane z = 3 + 0.5 x (no colours, no
// CRS; its estimated up is its own normal, along which every point has the same height) maps to
// the elevation ramp rising west to east. Oracle: the plane's heights, which are equal along each
// north-south column of cells and grow with x: every interior column holds one colour (+-2), and
// viridis's green, which rises monotonically over the ramp, rises from each column to the next and
// spans most of its range (a map coloured along the normal would be one colour).
TEST(OrthoMap, ElevationColoursRunAlongZWhateverTheQuickLookUpAxis) {
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_up_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  PointCloud pc;
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 80; ++i) {
      const double x = 0.125 + 0.25 * i;
      pc.positions.push_back(Vec3(x, 0.125 + 0.25 * j, 3.0 + 0.5 * x));
    }
  io::write_las(dir / "slope.las", pc);
  const auto r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " render " + (dir / "slope.las").string() +
                                            " --ortho-map 1 --out " + (dir / "a.tif").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("colour: elevation along up (0, 0, 1)"), std::string::npos) << r.out;
  GDALAllRegister();
  const std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> a(
      static_cast<GDALDataset*>(GDALOpen((dir / "a.tif").c_str(), GA_ReadOnly)), [](GDALDataset* d) { GDALClose(d); });
  ASSERT_TRUE(a);
  const int cols = a->GetRasterXSize(), rows = a->GetRasterYSize();
  ASSERT_EQ(cols, 20);
  ASSERT_EQ(rows, 10);
  std::vector<std::uint8_t> band[4];
  for (int b = 0; b < 4; ++b) band[b] = byte_band(a.get(), b + 1);
  int previous_green = -1, first_green = -1;
  for (int col = 1; col < cols - 1; ++col) {
    for (int row = 1; row < rows - 1; ++row) {
      const std::size_t k = std::size_t(row) * cols + col, top = std::size_t(1) * cols + col;
      EXPECT_EQ(band[3][k], 255) << col << "," << row;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(int(band[c][k]), int(band[c][top]), 2) << col << "," << row;
    }
    const int green = band[1][std::size_t(rows / 2) * cols + col];
    if (first_green < 0) first_green = green;
    EXPECT_GT(green, previous_green) << "column " << col;
    previous_green = green;
  }
  EXPECT_GT(previous_green - first_green, 150);
  std::filesystem::remove_all(dir);
}

// The map's rays start above everything the primitives can show: z_top = the cloud's top + the
// reach + a cell (and z_bottom as far below its bottom), whatever the extent; a reach that is not
// a finite number >= 0 is refused.
TEST(OrthoMap, RaysStartAReachAndACellAboveTheCloud) {
  AABB b;
  b.expand(Vec3(0.0, 0.0, -1.0));
  b.expand(Vec3(200.0, 100.0, 3.0));
  const analysis::OrthoMap map = analysis::ortho_map(b, 2.0, 7.5);
  EXPECT_EQ(map.z_top, 3.0 + 7.5 + 2.0);
  EXPECT_EQ(map.z_bottom, -1.0 - 7.5 - 2.0);
  EXPECT_EQ(analysis::ortho_map(b, 2.0, 0.0).z_top, 5.0);
  for (const double bad : {-0.5, std::nan(""), HUGE_VAL})
    EXPECT_THROW((void)analysis::ortho_map(b, 2.0, bad), std::invalid_argument) << bad;
}

namespace {

// The one-row map of `cloud` at 1 world unit per cell (spp 1: the cell-centre ray's colour),
// written to `tif`; the GeoTIFF's RGBA bytes of cell `col` as GDAL reads them back.
std::array<int, 4> ortho_cell(const jobs::OrthoMapJobResult& r, const std::filesystem::path& tif, int col) {
  std::array<int, 4> rgba{-1, -1, -1, -1};
  EXPECT_EQ(r.render.written.front(), tif);
  GDALAllRegister();
  const std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(
      static_cast<GDALDataset*>(GDALOpen(tif.c_str(), GA_ReadOnly)), [](GDALDataset* d) { GDALClose(d); });
  if (!ds || ds->GetRasterCount() != 4 || col >= ds->GetRasterXSize()) {
    ADD_FAILURE() << tif << ": not a 4-band GeoTIFF with a column " << col;
    return rgba;
  }
  for (int b = 0; b < 4; ++b) {
    std::uint8_t v = 0;
    EXPECT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Read, col, 0, 1, 1, &v, 1, 1, GDT_Byte, 0, 0), CE_None);
    rgba[b] = v;
  }
  return rgba;
}

}  // namespace

// A disc standing steeper than the map's old clearance: point A = (0.5, 0.5, 0), red, its normal
// tilted 60 degrees from vertical towards -x, and B = (2.5, 0.5, 0), blue, level; discs of radius
// 1.2 x 2 = 2.4 (k_radius 1), mapped at 1 (3 x 1 cells). The ray through cell 1's centre (1.5, 0.5)
// meets A's plane z = tan 60 (x - 0.5) at z = sqrt 3 = 1.732, 2 from A in the plane (< 2.4: a
// hit), above B's level disc at z = 0: the map shows A there, red, at that height (the depth AOV's
// surface; the DSM itself is held within the points' heights). Rays from the cloud's top + 1% of
// its extent + a cell (1.02) would start below A's disc and show B. Likewise a sphere of radius
// 1.5 over a point, its top 1.5 above the cloud: the ray through the point meets the top.
TEST(OrthoMap, ASteepDiscAboveTheCloudIsSeenFromAbove) {
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_steep_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::uint16_t red[3] = {200 * 257, 60 * 257, 30 * 257}, blue[3] = {40 * 257, 120 * 257, 230 * 257};
  PointCloud pc;
  pc.positions = {Vec3(0.5, 0.5, 0.0), Vec3(2.5, 0.5, 0.0)};
  pc.normals = {glm::vec3(-float(std::sqrt(3.0) / 2.0), 0.0f, 0.5f), glm::vec3(0.0f, 0.0f, 1.0f)};
  pc.rgb = {{red[0], red[1], red[2]}, {blue[0], blue[1], blue[2]}};
  jobs::OrthoMapJobOptions o;
  o.render.scene.material.mode = ColorMode::rgb;
  o.render.scene.primitive = Primitive::surfel;
  o.render.scene.surfel.k_radius = 1;
  o.render.scene.surfel.radius_factor = 1.2;
  o.render.scene.spp = 1;
  o.render.scene.output.image = dir / "disc.tif";
  o.render.cloud = &pc;
  o.render.control.threads = 1;
  o.ortho_map = 1.0;
  const jobs::OrthoMapJobResult r = jobs::run_ortho_map(o);
  ASSERT_TRUE(r.map);
  ASSERT_EQ(r.map->grid.cols, 3u);
  ASSERT_EQ(r.map->grid.rows, 1u);
  EXPECT_NEAR(r.dsm_reach, 2.4, 1e-6);  // (radii are floats)
  EXPECT_NEAR(r.map->z_top, 2.4 + 1.0, 1e-6);
  const analysis::Raster surface = analysis::dsm_from_depth(*r.map, r.render.image.depth);
  EXPECT_NEAR(surface.values[1], std::sqrt(3.0), 1e-4);
  EXPECT_EQ(ortho_cell(r, dir / "disc.tif", 1), (std::array<int, 4>{200, 60, 30, 255}));
  EXPECT_EQ(ortho_cell(r, dir / "disc.tif", 2), (std::array<int, 4>{40, 120, 230, 255}));  // B alone

  jobs::OrthoMapJobOptions sphere = o;
  sphere.render.scene.primitive = Primitive::sphere;
  sphere.render.scene.radius = 1.5;
  sphere.render.scene.output.image = dir / "sphere.tif";
  const jobs::OrthoMapJobResult q = jobs::run_ortho_map(sphere);
  ASSERT_TRUE(q.map);
  EXPECT_EQ(q.dsm_reach, 1.5);
  EXPECT_NEAR(analysis::dsm_from_depth(*q.map, q.render.image.depth).values[0], 1.5, 1e-4);
  EXPECT_EQ(ortho_cell(q, dir / "sphere.tif", 0), (std::array<int, 4>{200, 60, 30, 255}));
  std::filesystem::remove_all(dir);
}

// The alpha band is the share of the cell the colour's rays found covered. One 1 x 1 cell whose
// left half holds points (spacing s = 1/32 from s/2, x < 1/2; spheres of radius s, which cover
// the half-plane and reach past x = 1/2 by 0.37 s to 0.5 s): the covered fraction f of the cell
// lies in [1/2 + 0.366 s, 1/2 + s/2]. Its 64 rays (8 x 8 strata) find it to within one column of
// strata (an edge across the cell straddles one column), so alpha / 255 is within 1/8 of f
// (+ the 8-bit rounding); one ray through the centre alone would make it 255. The colour
// is the points' own, not darkened by the misses: unassociated alpha, as the writer marks it.
TEST(OrthoMap, AlphaIsTheShareOfTheCellsRaysThatHit) {
  const auto dir = std::filesystem::temp_directory_path() / ("rayscan_ortho_alpha_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const double s = 1.0 / 32;
  PointCloud pc;
  for (int j = 0; j < 32; ++j)
    for (int i = 0; i < 16; ++i) {
      pc.positions.emplace_back((i + 0.5) * s, (j + 0.5) * s, 2.0);
      pc.rgb.push_back({200 * 257, 60 * 257, 30 * 257});
    }
  jobs::OrthoMapJobOptions o;
  o.render.scene.material.mode = ColorMode::rgb;
  o.render.scene.radius = s;
  o.render.scene.spp = 64;
  o.render.scene.output.image = dir / "half.tif";
  o.render.cloud = &pc;
  o.render.control.threads = 1;
  o.ortho_map = 1.0;
  const jobs::OrthoMapJobResult r = jobs::run_ortho_map(o);
  ASSERT_TRUE(r.map);
  ASSERT_EQ(r.map->grid.cols, 1u);
  ASSERT_EQ(r.map->grid.rows, 1u);
  const std::array<int, 4> got = ortho_cell(r, dir / "half.tif", 0);
  EXPECT_EQ((std::array<int, 3>{got[0], got[1], got[2]}), (std::array<int, 3>{200, 60, 30}));
  const double f_lo = 0.5 + 0.366 * s, f_hi = 0.5 + 0.5 * s, strata = 1.0 / 8, byte = 0.5 / 255;
  EXPECT_GE(got[3] / 255.0, f_lo - strata - byte);
  EXPECT_LE(got[3] / 255.0, f_hi + strata + byte);
  std::filesystem::remove_all(dir);
}

namespace {

// The lines of `text` that are log lines ("rayscan render: ..."), not progress bars.
std::vector<std::string> log_lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("progress:", 0) != 0) out.push_back(line);
  return out;
}

std::string file_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

// The map's grid depends only on the cloud's bounds and the cell (analysis::ortho_grid), not on
// the points' reach, so a cell too fine for it is refused right after the cloud is read, before
// the albedo statistics, the index, the radius and the surfel estimate. Oracle: the log of a
// fitting cell reports those phases; a refused run's log is the read line and the error line
// only. The cloud read as LAS (surfels), mapped as an index file, and traced in place as COPC
// (spheres); too many cells (grid_over's limit), a side over 65536 cells (a long thin cloud), and
// buffers over a 2 GB address-space limit (ulimit -v, the memory check's own limit).
TEST(OrthoMap, ATooFineCellIsRefusedRightAfterTheRead) {
  namespace fs = std::filesystem;
  using rayscan::test::quoted;
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_ortho_early");
  const std::string bin = quoted(RAYSCAN_BIN);
  const fs::path las = fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las";
  const auto refused_after = [&](const std::string& command, const std::string& read_line,
                                 const std::string& error) {
    SCOPED_TRACE(command);
    const auto r = rayscan::test::run_command(command);
    EXPECT_EQ(r.code, 2) << r.out;
    const std::vector<std::string> lines = log_lines(r.out);
    ASSERT_EQ(lines.size(), 2u) << r.out;
    EXPECT_EQ(lines[0].rfind("rayscan render: " + read_line, 0), 0u) << r.out;
    EXPECT_EQ(lines[1].rfind("rayscan render: " + error, 0), 0u) << r.out;
  };

  // LAS, surfels (the quick look's primitive).
  const auto fits = rayscan::test::run_command(bin + " render " + quoted(las) + " --ortho-map 5 -o " +
                                               quoted(dir / "fits.tif"));
  ASSERT_EQ(fits.code, 0) << fits.out;
  EXPECT_NE(fits.out.find("rayscan render: built "), std::string::npos) << fits.out;
  EXPECT_NE(fits.out.find("rayscan render: surfels: "), std::string::npos) << fits.out;
  fs::remove(dir / "fits.tif");
  refused_after(bin + " render " + quoted(las) + " --ortho-map 0.01 -o " + quoted(dir / "x.tif"),
                "read 110000 points from ", "--ortho-map: raster: cell size 0.01 gives ");
  if (rayscan::test::kSanitized) {
    std::cout << "the address-space case is skipped: a sanitizer reserves its shadow memory beyond any ulimit -v\n";
  } else {
    // 11776 x 5628 cells of beauty 12, depth 4, albedo 12 and coverage 4 bytes: 2.0 GiB.
    refused_after("ulimit -v 2000000 && " + bin + " render " + quoted(las) + " --ortho-map 0.1 -o " +
                      quoted(dir / "x.tif"),
                  "read 110000 points from ", "an image of 11776 x 5628 pixels with AOVs needs about 2.0 GiB");
  }

  // An index file: its stored bounds, before the surfels' copy of the points is estimated.
  ASSERT_EQ(rayscan::test::run_command(bin + " index -q " + quoted(las) + " -o " + quoted(dir / "a.rsi")).code, 0);
  refused_after(bin + " render " + quoted(dir / "a.rsi") + " --ortho-map 0.01 -o " + quoted(dir / "x.tif"),
                "mapped index file ", "--ortho-map: raster: cell size 0.01 gives ");

  // COPC traced in place (spheres, a scene with a camera: not read whole for a quick look): the
  // bounds' pass comes before the albedo statistics and the radius estimate.
  const fs::path copc = fs::path(RAYSCAN_TEST_DATA) / "laz" / "lone-star.copc.laz";
  std::ofstream(dir / "copc.json") << R"({"cloud": ")" << copc.string()
                                   << R"(", "primitive": "sphere", "spp": 1, "material": {"color": "elevation"},
    "camera": {"width": 8, "height": 8, "position": [515380, 4918300, 2400], "look_at": [515380, 4918360, 2330]}})";
  const std::string scene = bin + " render " + quoted(dir / "copc.json");
  const auto copc_fits = rayscan::test::run_command(scene + " --ortho-map 1 -o " + quoted(dir / "fits.tif"));
  ASSERT_EQ(copc_fits.code, 0) << copc_fits.out;
  EXPECT_NE(copc_fits.out.find("rayscan render: albedo at shading time"), std::string::npos) << copc_fits.out;
  EXPECT_NE(copc_fits.out.find("rayscan render: radius auto: "), std::string::npos) << copc_fits.out;
  fs::remove(dir / "fits.tif");
  refused_after(scene + " --ortho-map 0.001 -o " + quoted(dir / "x.tif"), "COPC file ",
                "--ortho-map: raster: cell size 0.001 gives ");

  // A long thin cloud: few cells, but 70001 in a row, over the side limit.
  std::ofstream(dir / "thin.xyz") << "0 0 0\n70000 1 1\n35000 0.5 0.5\n";
  refused_after(bin + " render " + quoted(dir / "thin.xyz") + " --ortho-map 1 -o " + quoted(dir / "x.tif"),
                "read 3 points from ", "--ortho-map: ortho map: 70001 x 2 pixels; at most 65536 per side");

  EXPECT_EQ(rayscan::test::entry_names(dir), (std::set<std::string>{"a.rsi", "copc.json", "thin.xyz"}));
  fs::remove_all(dir);
}

// The orthophoto and the DSM are one output: a file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored,
// so the write fails with EFBIG) between the two files' sizes makes the DSM's write fail after
// the orthophoto's temporary was written; neither old file is replaced and no temporary is left.
// Oracle: the sizes of the same render without a limit (the Float32 DSM of a rough surface is
// larger than the orthophoto of one constant colour, which is written first), the old files' own
// bytes and the folder's listing.
TEST(OrthoMap, OrthophotoAndDsmAreWrittenAllOrNothing) {
  namespace fs = std::filesystem;
  using rayscan::test::quoted;
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_ortho_all_or_nothing");
  PointCloud pc;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> rough(0.0, 1.0);
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 64; ++i) pc.positions.push_back(Vec3(0.125 + 0.25 * i, 0.125 + 0.25 * j, 5.0 + rough(rng)));
  io::write_ply(dir / "rough.ply", pc);
  std::ofstream(dir / "scene.json") << R"({"cloud": "rough.ply", "spp": 1, "max_depth": 1, "radius": 0.25,
    "material": {"color": [0.5, 0.5, 0.5]},
    "camera": {"width": 8, "height": 8, "position": [8, -10, 20], "look_at": [8, 8, 5]}})";
  const auto render = [&](const std::string& limit, const fs::path& folder) {
    // standard error only: the written files' names go to standard output
    return rayscan::test::run_command("(trap '' XFSZ; " + limit + quoted(RAYSCAN_BIN) + " render -q " +
                                          quoted(dir / "scene.json") + " --ortho-map 0.25 -o " +
                                          quoted(folder / "o.tif") + " --dsm " + quoted(folder / "d.tif") +
                                          " 2>&1 >/dev/null)",
                                      false);
  };
  fs::create_directories(dir / "free");
  ASSERT_EQ(render("", dir / "free").code, 0);
  const std::uintmax_t ortho = fs::file_size(dir / "free" / "o.tif"), dsm = fs::file_size(dir / "free" / "d.tif");
  ASSERT_LT(2 * ortho, dsm);
  const std::uintmax_t limit = (ortho + dsm) / 2;

  const fs::path out = dir / "capped";
  fs::create_directories(out);
  std::ofstream(out / "o.tif") << "old orthophoto";
  std::ofstream(out / "d.tif") << "old dsm";
  const auto r = render("prlimit --fsize=" + std::to_string(limit) + " ", out);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("rayscan render: " + (out / "d.tif").string() + ": ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("File too large"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(rayscan::test::entry_names(out), (std::set<std::string>{"d.tif", "o.tif"}));
  EXPECT_TRUE(file_text(out / "o.tif") == "old orthophoto") << fs::file_size(out / "o.tif") << " bytes";
  EXPECT_TRUE(file_text(out / "d.tif") == "old dsm") << fs::file_size(out / "d.tif") << " bytes";
  fs::remove_all(dir);
}
