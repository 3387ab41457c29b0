// `rayscan render` end to end for its argument checks: user errors exit with code 2, print one
// line naming the option or file, and write no output file; and the DSM's band unit as GDAL reads
// it back.
#include "../common/temp_dir.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/scene.hpp"

#include "../common/run_command.hpp"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <sched.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <utility>

namespace fs = std::filesystem;

namespace {

using RunResult = rayscan::test::CommandResult;

/// Runs `rayscan ARGS`, capturing standard output and error.
RunResult run(const std::string& args) {
  return rayscan::test::run_command(std::string(RAYSCAN_BIN) + " " + args);
}

fs::path cli_temp_dir() { return rayscan::test::process_temp_dir("rayscan_render_cli"); }

// A valid scene over a 3-point cloud.
fs::path small_scene_file() {
  const fs::path d = cli_temp_dir();
  std::ofstream(d / "c.xyz") << "0 0 0\n1 0 0\n0 1 0\n";
  std::ofstream(d / "s.json") << R"({"cloud": "c.xyz", "radius": 0.5, "spp": 1, "material": {"color": [0.5, 0.5, 0.5]},
    "camera": {"width": 8, "height": 6, "position": [0, -10, 2], "look_at": [0, 0, 0]}})";
  return d / "s.json";
}

}  // namespace

TEST(RenderCli, OutRejectsExtensionsTheSceneFileRejects) {
  const fs::path scene = small_scene_file();
  const fs::path out = cli_temp_dir() / "x.bmp";
  const RunResult r = run("render -q " + scene.string() + " --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan render: --out '" + out.string() + "': " + rayscan::render::image_file_name_expected() + "\n");
  EXPECT_FALSE(fs::exists(out));
}

TEST(RenderCli, AnImageModuleThatDoesNotLoadStopsTheRenderBeforeItStarts) {
  // The image writer (OpenImageIO, in librayscan_oiio.so) is loaded before the render, so a
  // missing module costs no render: one line naming the path tried, exit 2, no output file.
  const fs::path scene = small_scene_file();
  const fs::path out = cli_temp_dir() / "m.png";
  const std::string bad = (cli_temp_dir() / "no-such-module.so").string();
  const RunResult r = rayscan::test::run_command("RAYSCAN_OIIO_MODULE=" + bad + " " + std::string(RAYSCAN_BIN) +
                                                 " render " + scene.string() + " --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan render: image files need rayscan's OpenImageIO module librayscan_oiio.so: not found "
                   "(looked for " + bad + ")\n");
  EXPECT_FALSE(fs::exists(out));
  // Positive control: the built module named explicitly renders and writes the image.
  const RunResult ok = rayscan::test::run_command("RAYSCAN_OIIO_MODULE=" + std::string(RAYSCAN_OIIO_MODULE_FILE) +
                                                  " " + std::string(RAYSCAN_BIN) + " render -q " + scene.string() +
                                                  " --out " + out.string());
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(out));
}

TEST(RenderCli, OutAcceptsEveryImageExtension) {
  // Positive control for the test above: every extension --help lists (in either case) writes a
  // file of that format, told by its own first bytes (PNG, JPEG, TIFF and OpenEXR signatures).
  const fs::path scene = small_scene_file();
  const std::pair<const char*, std::string> kinds[] = {
      {"x.png", "\x89PNG"}, {"x.PNG", "\x89PNG"}, {"x.jpg", "\xFF\xD8\xFF"}, {"x.jpeg", "\xFF\xD8\xFF"},
      {"x.tif", "II*"}, {"x.tiff", "II*"}, {"x.exr", "\x76\x2F\x31\x01"}};
  for (const auto& [name, magic] : kinds) {
    const fs::path out = cli_temp_dir() / name;
    const RunResult r = run("render -q " + scene.string() + " --spp 1 --out " + out.string());
    EXPECT_EQ(r.code, 0) << name << ": " << r.out;
    std::ifstream f(out, std::ios::binary);
    std::string head(magic.size(), '\0');
    f.read(head.data(), static_cast<std::streamsize>(head.size()));
    EXPECT_EQ(head, magic) << name;
  }
}

TEST(RenderCli, OrthoMapOutputsAreCheckedBeforeTheRender) {
  // The orthophoto and DSM are written by the ortho-map job, not as the render's image: their
  // directories are checked before the render (one line, exit 2, nothing written), as every job
  // checks its outputs.
  const std::string cloud = std::string(RAYSCAN_TEST_DATA) + "/las/autzen_trim.las";
  const fs::path ortho = cli_temp_dir() / "o.tif";
  const RunResult r = run("render " + cloud + " --ortho-map 3 --out " + ortho.string() + " --dsm /nonexistent-dir/d.tif");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan render: /nonexistent-dir/d.tif: output directory '/nonexistent-dir' does not exist\n");
  EXPECT_FALSE(fs::exists(ortho));
}

TEST(RenderCli, TheDsmBandIsInTheCrsHeightUnit) {
  // EPSG:2992+5703 (EPSG registry): x and y in international feet, NAVD88 heights in metres; the
  // DSM holds heights, so its band is in metres, what `rayscan info` calls the vertical unit.
  // EPSG:2992 alone names one unit, the foot, for heights too. GDAL reads the unit back. The log's
  // elevation ramp (the cloud has no colours) gives its heights in the same unit as the band.
  rayscan::PointCloud cloud;
  for (int x = 0; x <= 20; ++x)
    for (int y = 0; y <= 20; ++y) cloud.positions.push_back(rayscan::Vec3(637000.0 + x, 849000.0 + y, 120.0));
  for (const auto& [crs, unit] : {std::pair{"EPSG:2992+5703", "metre"}, std::pair{"EPSG:2992", "foot"}}) {
    SCOPED_TRACE(crs);
    cloud.crs_wkt = rayscan::io::crs_wkt_from_user_input(crs);
    ASSERT_FALSE(cloud.crs_wkt.empty());
    const fs::path ply = cli_temp_dir() / "crs.ply", ortho = cli_temp_dir() / "crs_ortho.tif",
                   dsm = cli_temp_dir() / "crs_dsm.tif";
    rayscan::io::write_ply(ply, cloud);
    const RunResult r = run("render " + ply.string() + " --ortho-map 4 --spp 1 --out " + ortho.string() +
                            " --dsm " + dsm.string());
    ASSERT_EQ(r.code, 0) << r.out;
    const std::size_t ramp = r.out.find("rayscan render: colour: elevation along up (0, 0, 1), viridis, ");
    ASSERT_NE(ramp, std::string::npos) << r.out;
    const std::string line = r.out.substr(ramp, r.out.find('\n', ramp) - ramp);
    EXPECT_NE(line.find(" (bright) " + std::string(unit) + ", the 2nd and 98th percentiles"), std::string::npos) << line;
    GDALAllRegister();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(dsm.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(ds);
    EXPECT_STREQ(ds->GetRasterBand(1)->GetUnitType(), unit);
  }
}

TEST(RenderCli, ThreadsAboveTheCoresRunOnTheCoresWithoutTbbsWarning) {
  // TBB runs no more threads than the process may use (its CPU affinity): a larger --threads is
  // capped, so TBB prints no "number of workers is currently limited" warning, even with -q, and
  // the log gives the count really used.
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof set, &set), 0);
  const int cpus = CPU_COUNT(&set);
  const fs::path scene = small_scene_file();
  const fs::path out = cli_temp_dir() / "t.png";
  const RunResult quiet = run("render -q " + scene.string() + " --threads 1024 --out " + out.string());
  EXPECT_EQ(quiet.code, 0) << quiet.out;
  EXPECT_EQ(quiet.out, "wrote " + out.string() + "\n");
  const RunResult r = run("render " + scene.string() + " --threads 1024 --out " + out.string());
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("TBB"), std::string::npos) << r.out;
  const std::size_t at = r.out.find(" threads, ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const int used = std::stoi(r.out.substr(r.out.rfind(' ', at - 1) + 1));
  EXPECT_GE(used, 1);
  EXPECT_LE(used, cpus);
}

TEST(RenderCli, CombinationsWithoutMeaningAreRefusedNamingTheFlags) {
  const fs::path scene = small_scene_file();
  const fs::path out = cli_temp_dir() / "c.png";
  // Two cameras: the COLMAP photo's would win silently.
  RunResult r = run("render " + scene.string() + " --colmap some-model --image a.jpg --camera cam.json --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan render: --colmap: the camera is the COLMAP photo's; do not give --camera too\n");
  // An AOV named twice, as a scene file's output.aovs refuses it.
  r = run("render " + scene.string() + " --aov depth --aov depth --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "rayscan render: --aov 'depth': given twice\n");
  EXPECT_FALSE(fs::exists(out));
  // --exposure is the scene's output.exposure, as --print-scene shows; outside [-30, 30] refused.
  r = rayscan::test::run_command(std::string(RAYSCAN_BIN) + " render " + scene.string() + " --exposure -2.5 --print-scene",
                                 false);
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\"exposure\": -2.5"), std::string::npos) << r.out;
  r = run("render " + scene.string() + " --exposure 31 --out " + out.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--exposure"), std::string::npos) << r.out;
}

// A scene file's "radius" is refused by the rule of `rayscan visibility --radius` and in its words
// (the one check of a given sphere radius): after the scene's JSON pointer, the line the flag gives
// after its name, less the value it names (", got -3"), for a negative, a zero and a non-number
// radius. Exit code 2, no image.
TEST(RenderCli, SceneRadiusIsRefusedInTheWordsOfTheRadiusFlag) {
  const fs::path d = cli_temp_dir();
  std::ofstream(d / "c.xyz") << "0 0 0\n1 0 0\n0 1 0\n";
  const fs::path out = d / "radius.png";
  const std::pair<std::string, std::string> values[] = {{"-3", "-3"}, {"0", "0"}, {"\"big\"", "big"}};
  for (const auto& v : values) {
    const RunResult flag =
        run("visibility " + (d / "c.xyz").string() + " --sky-view 4 -o " + (d / "v.las").string() + " --radius " + v.second);
    EXPECT_EQ(flag.code, 2) << flag.out;
    const std::string head = "rayscan visibility: --radius: ";
    const std::size_t got = flag.out.rfind(", got ");
    ASSERT_EQ(flag.out.rfind(head, 0), 0u) << flag.out;
    ASSERT_NE(got, std::string::npos) << flag.out;
    const std::string rule = flag.out.substr(head.size(), got - head.size());

    const fs::path scene = d / "radius.json";
    std::ofstream(scene) << R"({"cloud": "c.xyz", "radius": )" << v.first
                         << R"(, "camera": {"width": 8, "height": 6, "position": [0, -10, 2], "look_at": [0, 0, 0]}})";
    const RunResult r = run("render -q " + scene.string() + " --out " + out.string());
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(r.out, "rayscan render: " + scene.string() + ": /radius: " + rule + "\n") << v.first;
    EXPECT_FALSE(fs::exists(out));
  }
}
