// Top-down orthophoto and DSM: a tilted plane z = 5 + 0.1 x rendered through the
// ortho map camera gives back its analytic elevation per cell centre; the GeoTIFF carries the grid.
#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/surfel_setup.hpp"
#include "rayscan/io/point_io.hpp"

#include "../common/run_command.hpp"

#include <gtest/gtest.h>

#include <gdal_priv.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <unistd.h>

using namespace rayscan;
using namespace rayscan::render;

TEST(OrthoMap, DsmOfATiltedPlaneIsItsAnalyticElevation) {
  std::vector<Vec3> pts;
  for (int j = 0; j <= 60; ++j)
    for (int i = 0; i <= 60; ++i) pts.push_back(Vec3(100.0 + 0.25 * i, 200.0 + 0.25 * j, 5.0 + 0.1 * 0.25 * i));
  AABB b;
  for (const Vec3& p : pts) b.expand(p);
  const analysis::OrthoMap map = analysis::ortho_map(b, 1.0);
  ASSERT_EQ(map.grid.x0, 100.0);
  Scene s;
  s.camera = map.camera;
  s.spp = 1;
  s.max_depth = 1;
  s.output.aovs = {Aov::depth};
  const std::vector<Color> albedo(pts.size(), Color(0.5f));
  const AnyIndex index = make_index(pts, IndexOptions{});
  RenderSettings rs = make_settings(s, pts, albedo, 0.25);
  PointCloud pc;
  pc.positions = pts;
  s.surfel_orient_camera = false;
  const SurfelAttributes sa = scene_surfels(s, index, pc);
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
  analysis::write_ortho_geotiff(dir / "o.tif", map, fb.beauty, fb.depth, 0.0, "");
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
