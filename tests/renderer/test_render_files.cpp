// Render output read back through OpenImageIO (the files' own samples and metadata, not rayscan's
// reader): the EXR's beauty and AOV channels and metadata, the 16-bit sRGB PNG, and
// the files the render job writes. A test binary of its own, so that only these tests load
// OpenImageIO's ~260 libraries at process start (0.4 s each; every other render test process is
// spared it).
#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"
#include "render_test_data.hpp"
#include "rayscan/render/image_output.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/jobs/render.hpp"

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;
namespace fs = std::filesystem;

namespace {

using rayscan::render::test::subset;
using rayscan::render::test::subset_scene;

fs::path files_temp_dir() { return rayscan::test::process_temp_dir("rayscan_render_files_test"); }

}  // namespace

TEST(ImageOutput, ExrHoldsBeautyAndAovChannelsAndMetadata) {
  const PointCloud& pc = subset();
  MaterialDesc mat;
  mat.mode = ColorMode::elevation;
  const std::vector<Color> albedo = compute_albedo(pc, mat, Vec3(0, 0, 1));
  const AnyIndex index = make_index(pc.positions, IndexOptions{});
  Scene s = subset_scene(32, 24);
  s.spp = 1;
  s.output.aovs = {Aov::depth, Aov::normal, Aov::position, Aov::index, Aov::albedo, Aov::cost};
  Framebuffer fb;
  render_image(index, make_settings(s, pc.positions, albedo, 0.8), fb);
  OutputDesc out;
  out.image = files_temp_dir() / "img.exr";
  out.exr_half = false;
  const auto files = write_image(fb, out, {{"rayscan:spp", "1"}});
  ASSERT_EQ(files.size(), 1u);
  auto in = OIIO::ImageInput::open(out.image.string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.width, 32);
  EXPECT_EQ(spec.get_string_attribute("rayscan:spp"), "1");
  int zc = -1, idc = -1;
  for (int c = 0; c < spec.nchannels; ++c) {
    if (spec.channelnames[c] == "Z") zc = c;
    if (spec.channelnames[c] == "id") idc = c;
  }
  ASSERT_GE(zc, 0);
  ASSERT_GE(idc, 0);
  EXPECT_EQ(spec.nchannels, 3 + 1 + 3 + 3 + 3 + 1 + 1);
  EXPECT_EQ(spec.channelformat(idc), OIIO::TypeDesc::UINT);
  std::vector<float> z(32 * 24);
  std::vector<std::uint32_t> ids(32 * 24);
  ASSERT_TRUE(in->read_image(0, 0, zc, zc + 1, OIIO::TypeDesc::FLOAT, z.data()));
  ASSERT_TRUE(in->read_image(0, 0, idc, idc + 1, OIIO::TypeDesc::UINT, ids.data()));
  for (std::size_t i = 0; i < z.size(); ++i) {
    EXPECT_EQ(z[i], fb.depth[i]);
    EXPECT_EQ(ids[i], fb.index[i]);
  }
  // Nothing temporary is left next to the image.
  for (const auto& e : fs::directory_iterator(files_temp_dir()))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(ImageOutput, PngIsSrgbEncodedAt16Bit) {
  Framebuffer fb;
  fb.width = 2;
  fb.height = 1;
  fb.beauty = {Color(0.5f), Color(0.0031308f, 1.0f, 2.0f)};
  OutputDesc out;
  out.image = files_temp_dir() / "img16.png";
  out.bit_depth = 16;
  write_image(fb, out, {});
  auto in = OIIO::ImageInput::open(out.image.string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().format, OIIO::TypeDesc::UINT16);
  std::vector<std::uint16_t> px(6);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT16, px.data()));
  // sRGB(0.5) = 1.055 * 0.5^(1/2.4) - 0.055 = 0.735357...
  EXPECT_EQ(px[0], std::lround(0.7353569830524495 * 65535));
  EXPECT_EQ(px[3], std::lround(0.0031308 * 12.92 * 65535));
  EXPECT_EQ(px[4], 65535);
  EXPECT_EQ(px[5], 65535);  // clamped
}

TEST(ImageOutput, ExposureScalesThenEightBitClipsAndExrKeepsLinear) {
  // 0.3 x 2^2 = 1.2 clips to 1 in PNG (no tone mapping); 0.3 x 2^-1 = 0.15 is sRGB-encoded:
  // 1.055 * 0.15^(1/2.4) - 0.055 = 0.423268...; EXR keeps 1.2 (float).
  Framebuffer fb;
  fb.width = 1;
  fb.height = 1;
  fb.beauty = {Color(0.3f)};
  OutputDesc out;
  out.exposure = 2.0;
  out.image = files_temp_dir() / "bright.png";
  write_image(fb, out, {});
  std::uint8_t px[3];
  auto in = OIIO::ImageInput::open(out.image.string());
  ASSERT_TRUE(in);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
  EXPECT_EQ(px[0], 255);
  in->close();
  out.exposure = -1.0;
  out.image = files_temp_dir() / "dim.png";
  write_image(fb, out, {});
  in = OIIO::ImageInput::open(out.image.string());
  ASSERT_TRUE(in);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
  EXPECT_EQ(px[0], std::lround(0.42326790 * 255));
  in->close();
  out.exposure = 2.0;
  out.exr_half = false;
  out.image = files_temp_dir() / "bright.exr";
  write_image(fb, out, {});
  float f[3];
  in = OIIO::ImageInput::open(out.image.string());
  ASSERT_TRUE(in);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, f));
  EXPECT_FLOAT_EQ(f[0], 1.2f);
}

TEST(ImageOutput, TiffAndJpegCarryTheRayscanKeysAsTheirDescription) {
  // TIFF and JPEG keep no free-form keys: the rayscan:* entries are one "key: value" line each of
  // the ImageDescription (TIFF tag 270, JPEG COM), read back by OpenImageIO; PNG keeps the keys.
  Framebuffer fb;
  fb.width = 2;
  fb.height = 2;
  fb.beauty.assign(4, Color(0.5f));
  const ImageMetadata meta = {{"rayscan:spp", "4"}, {"rayscan:camera", R"({"width":2,"height":2})"}};
  for (const char* name : {"d.tif", "d.jpg", "d.png"}) {
    SCOPED_TRACE(name);
    OutputDesc out;
    out.image = files_temp_dir() / name;
    write_image(fb, out, meta);
    auto in = OIIO::ImageInput::open(out.image.string());
    ASSERT_TRUE(in);
    const OIIO::ImageSpec& spec = in->spec();
    if (std::string(name) == "d.png") {
      EXPECT_EQ(spec.get_string_attribute("rayscan:spp"), "4");
      EXPECT_EQ(spec.get_string_attribute("rayscan:camera"), R"({"width":2,"height":2})");
      EXPECT_EQ(spec.get_string_attribute("ImageDescription"), "");
    } else {
      EXPECT_EQ(spec.get_string_attribute("ImageDescription"),
                "rayscan:spp: 4\nrayscan:camera: {\"width\":2,\"height\":2}");
    }
  }
}

// Every image format the writer offers decodes with OpenImageIO to the written pixels: the 8-bit
// formats to the sRGB encoding of each value, EXR to the half-float values (JPEG within its loss).
// Decoding, not the signature bytes: OpenImageIO's TIFF writer through an in-memory proxy writes a
// file with a valid signature whose first directory points at the EXIF one, which no reader opens.
TEST(ImageOutput, EveryFormatDecodesToTheWrittenPixels) {
  Framebuffer fb;
  fb.width = 4;
  fb.height = 3;
  for (int i = 0; i < 12; ++i) fb.beauty.push_back(Color(0.05f * float(i), 0.5f, 1.0f - 0.08f * float(i)));
  for (const char* name : {"e.png", "e.tif", "e.tiff", "e.TIF", "e.jpg", "e.jpeg", "e.exr"}) {
    OutputDesc out;
    out.image = files_temp_dir() / name;
    write_image(fb, out, {});
    auto in = OIIO::ImageInput::open(out.image.string());
    ASSERT_TRUE(in) << name << ": " << OIIO::geterror();
    ASSERT_EQ(in->spec().width, 4) << name;
    ASSERT_EQ(in->spec().height, 3) << name;
    ASSERT_GE(in->spec().nchannels, 3) << name;
    const int nc = in->spec().nchannels;
    std::vector<float> px(std::size_t(12 * nc));
    ASSERT_TRUE(in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, px.data())) << name;
    const bool exr = fs::path(name).extension() == ".exr";
    const bool jpeg = fs::path(name).extension().string().find("jp") != std::string::npos;
    const auto srgb = [](float v) {
      return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
    };
    for (int c = 0; c < 3; ++c) {
      double got_mean = 0.0, want_mean = 0.0;
      for (int i = 0; i < 12; ++i) {
        const float v = fb.beauty[std::size_t(i)][c];
        const float want = exr ? v : srgb(v);
        got_mean += px[std::size_t(i * nc + c)] / 12.0;
        want_mean += want / 12.0;
        // JPEG's chroma subsampling blurs a 4 x 3 gradient pixel by pixel: its means are checked.
        if (!jpeg) {
          EXPECT_NEAR(px[std::size_t(i * nc + c)], want, exr ? 1e-3f : 0.5f / 255.0f) << name << " " << i << "," << c;
        }
      }
      EXPECT_NEAR(got_mean, want_mean, jpeg ? 0.03 : exr ? 1e-3 : 0.5 / 255.0 + 1e-6) << name << " channel " << c;
    }
  }
}

TEST(RenderJob, WritesTheImageAndAovsItNames) {
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_render_job");
  RenderJobOptions o;
  o.scene = subset_scene(40, 30);
  o.scene.material.mode = ColorMode::elevation;  // (the subset has no RGB)
  o.scene.output.aovs = {Aov::index, Aov::depth};
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
  // Points given only in memory; no scene file; the camera as camera-file JSON, which reads back
  // as the camera the image was traced through (the same rays, parse_camera's inverse).
  EXPECT_EQ(spec.get_string_attribute("rayscan:cloud"), "(memory)");
  EXPECT_EQ(spec.get_string_attribute("rayscan:scene", "(none)"), "(none)");
  const std::string cam = spec.get_string_attribute("rayscan:camera");
  const Camera back = io::parse_camera(nlohmann::json::parse(cam), "rayscan:camera", "");
  EXPECT_EQ(io::camera_to_json(back).dump(), io::camera_to_json(*o.scene.camera).dump());
  in->close();
  // The file the in-memory points were read from (as `rayscan render` reads a quick look's) is
  // named, absolute.
  RenderJobOptions named = o;
  named.scene.cloud = fs::path(RAYSCAN_RENDER_TEST_DATA) / "autzen_subset.xyz";
  named.cloud_read_from_scene = true;
  named.scene.output.image = dir / "b.exr";
  (void)run_render(named);
  in = OIIO::ImageInput::open((dir / "b.exr").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:cloud"),
            fs::absolute(named.scene.cloud).lexically_normal().string());
  in->close();
  fs::remove_all(dir);
}


TEST(RenderCli, OutputsRecordTheCloudFileAndTheCameraUsed) {
  // A quick look reads its cloud once for the overview camera and the render; its image names that
  // file (absolute, not "(memory)"), no scene file, and the camera as camera-file JSON, which
  // --print-scene's "camera" (the same command line) is. Each --frames image records its own camera.
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_render_meta_cli");
  const fs::path cloud = fs::path(RAYSCAN_TEST_DATA) / "las" / "simple.las";
  const std::string cmd = std::string(RAYSCAN_BIN) + " render " + cloud.string() + " --width 30 --spp 1 -q";
  const auto run = [](const std::string& c) {
    std::string out;
    FILE* p = ::popen((c + " 2>/dev/null").c_str(), "r");
    char buf[4096];
    for (std::size_t n; p && (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    const int st = p ? ::pclose(p) : -1;
    EXPECT_EQ(st, 0) << c;
    return out;
  };
  const nlohmann::json printed = nlohmann::json::parse(run(cmd + " --print-scene"));
  (void)run(cmd + " --out " + (dir / "q.png").string());
  auto in = OIIO::ImageInput::open((dir / "q.png").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:cloud"), fs::absolute(cloud).lexically_normal().string());
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:scene", "(none)"), "(none)");
  EXPECT_EQ(nlohmann::json::parse(in->spec().get_string_attribute("rayscan:camera", "null")), printed["camera"]);
  in->close();
  nlohmann::json second = printed["camera"];
  second["vfov_deg"] = 20.0;
  std::ofstream(dir / "frames.json") << nlohmann::json::array({printed["camera"], second}).dump();
  (void)run(cmd + " --frames " + (dir / "frames.json").string() + " --out " + (dir / "f.png").string());
  for (int f = 0; f < 2; ++f) {
    in = OIIO::ImageInput::open((dir / ("f_000" + std::to_string(f) + ".png")).string());
    ASSERT_TRUE(in);
    EXPECT_EQ(nlohmann::json::parse(in->spec().get_string_attribute("rayscan:camera", "null")),
              f == 0 ? printed["camera"] : second);
    in->close();
  }
  fs::remove_all(dir);
}

TEST(RenderCli, FramesAreWrittenAllOrNothing) {
  // Two small frames and a large one: a file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored, so the
  // write fails with EFBIG) between their sizes makes the third frame's write fail after the first
  // two were written. The frames are one output: the old files stay, no new frame and no
  // temporary is left.
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_render_frames_all_or_nothing");
  const fs::path cloud = fs::path(RAYSCAN_TEST_DATA) / "las" / "simple.las";
  std::ofstream(dir / "frames.json") << R"([
      {"width": 8, "height": 6, "position": [637300, 847000, 1500], "look_at": [637300, 851200, 500]},
      {"width": 8, "height": 6, "position": [637400, 847000, 1500], "look_at": [637300, 851200, 500]},
      {"width": 200, "height": 150, "position": [637300, 847000, 1500], "look_at": [637300, 851200, 500]}])";
  const auto render = [&](const std::string& limit, const fs::path& out) {
    // stderr only: the written files' names go to stdout
    return rayscan::test::run_command("(trap '' XFSZ; " + limit + std::string(RAYSCAN_BIN) + " render -q " +
                                          cloud.string() + " --spp 1 --frames " + (dir / "frames.json").string() +
                                          " --out " + out.string() + " 2>&1 >/dev/null)",
                                      false);
  };
  fs::create_directories(dir / "free");
  ASSERT_EQ(render("", dir / "free" / "f.png").code, 0);
  const std::uintmax_t limit = 8192;
  ASSERT_LT(fs::file_size(dir / "free" / "f_0001.png"), limit);
  ASSERT_GT(fs::file_size(dir / "free" / "f_0002.png"), limit);

  const fs::path out = dir / "capped";
  fs::create_directories(out);
  std::ofstream(out / "f_0000.png") << "old frame 0";
  std::ofstream(out / "f_0001.png") << "old frame 1";
  const rayscan::test::CommandResult r = render("prlimit --fsize=" + std::to_string(limit) + " ", out / "f.png");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.out.rfind("rayscan render: " + (out / "f_0002.png").string() + ": cannot write", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("File too large"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  std::vector<std::string> left;
  for (const fs::directory_entry& e : fs::directory_iterator(out)) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"f_0000.png", "f_0001.png"}));
  const auto text = [](const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(text(out / "f_0000.png"), "old frame 0");
  EXPECT_EQ(text(out / "f_0001.png"), "old frame 1");

  // A name that cannot be written (a directory at the third frame's name) is refused before any
  // frame is rendered.
  fs::remove(out / "f_0001.png");
  fs::create_directories(out / "f_0002.png");
  const rayscan::test::CommandResult d = render("", out / "f.png");
  EXPECT_EQ(d.code, 2);
  EXPECT_EQ(d.out, "rayscan render: " + (out / "f_0002.png").string() +
                       ": is a directory; refusing to replace it (outputs go to a new path or over a regular file)\n");
  EXPECT_EQ(text(out / "f_0000.png"), "old frame 0");
  EXPECT_FALSE(fs::exists(out / "f_0001.png"));
  fs::remove_all(dir);
}
