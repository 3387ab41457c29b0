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
                "rayscan:spp: 4\nrayscan:camera: {\"width\":2,\"height\":2}\nrayscan:exposure: 0\nrayscan:transfer: sRGB");
    }
  }
}

TEST(ImageOutput, ImagesRecordTheExposureAndTransferTheirPixelsWentThrough) {
  // The beauty 0.5 at -1 EV is 0.25 in the file: the header says so (rayscan:exposure) and how the
  // values were encoded (rayscan:transfer), in every format; TIFF and JPEG as description lines.
  Framebuffer fb;
  fb.width = 2;
  fb.height = 2;
  fb.beauty.assign(4, Color(0.5f));
  for (const double ev : {0.0, -1.0, 0.25}) {
    const std::string evs = ev == 0.0 ? "0" : ev == -1.0 ? "-1" : "0.25";
    for (const char* name : {"x.png", "x.exr", "x.tif", "x.jpg"}) {
      SCOPED_TRACE(std::string(name) + " at " + evs + " EV");
      OutputDesc out;
      out.image = files_temp_dir() / name;
      out.exposure = ev;
      out.exr_half = false;
      write_image(fb, out, {{"rayscan:spp", "1"}});
      auto in = OIIO::ImageInput::open(out.image.string());
      ASSERT_TRUE(in);
      const OIIO::ImageSpec& spec = in->spec();
      const std::string ext = out.image.extension().string();
      const std::string transfer = ext == ".exr" ? "linear" : "sRGB";
      if (ext == ".png" || ext == ".exr") {
        EXPECT_EQ(spec.get_string_attribute("rayscan:exposure"), evs);
        EXPECT_EQ(spec.get_string_attribute("rayscan:transfer"), transfer);
      } else {
        EXPECT_EQ(spec.get_string_attribute("ImageDescription"),
                  "rayscan:spp: 1\nrayscan:exposure: " + evs + "\nrayscan:transfer: " + transfer);
      }
      if (ext == ".exr") {  // the linear value the header describes: 0.5 x 2^ev
        std::vector<float> px(std::size_t(fb.width) * std::size_t(fb.height) * 3);  // the whole 2x2 RGB image
        ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, px.data()));
        for (const float v : px) EXPECT_EQ(v, 0.5f * std::exp2(float(ev)));
      }
    }
  }
  // The AOV file beside an 8-bit image holds unscaled linear channels: it carries the render's
  // record, not the beauty's exposure, transfer or sRGB colour space.
  fb.depth.assign(4, 2.0f);
  OutputDesc out;
  out.image = files_temp_dir() / "withaov.png";
  out.exposure = -1.0;
  const auto files = write_image(fb, out, {{"rayscan:spp", "1"}});
  ASSERT_EQ(files.size(), 2u);
  auto in = OIIO::ImageInput::open(files[1].string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:spp"), "1");
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:exposure", "(none)"), "(none)");
  EXPECT_EQ(in->spec().get_string_attribute("rayscan:transfer", "(none)"), "(none)");
  EXPECT_NE(in->spec().get_string_attribute("oiio:ColorSpace"), "sRGB");
}

namespace {

/// The 4 x 4 float matrix attribute `name` of `spec` (case-insensitive, as OpenImageIO looks
/// names up), in the file's layout; empty when absent or not of type matrix44 (OpenEXR m44f).
std::vector<double> matrix_attribute(const OIIO::ImageSpec& spec, const char* name) {
  const OIIO::ParamValue* p = spec.find_attribute(name);
  if (!p || p->type() != OIIO::TypeMatrix44) return {};
  const float* f = static_cast<const float*>(p->data());
  return std::vector<double>(f, f + 16);
}

/// p * M with Imath's row-vector convention (OpenEXR's m44f), then the homogeneous divide.
Vec3 transform(const std::vector<double>& m, const Vec3& p) {
  double r[4];
  for (int c = 0; c < 4; ++c) r[c] = p.x * m[c] + p.y * m[4 + c] + p.z * m[8 + c] + m[12 + c];
  return Vec3(r[0], r[1], r[2]) / r[3];
}

/// The header of the EXR that write_image writes for a render through `cam`, and its bytes.
OIIO::ImageSpec exr_header(const Camera& cam, const std::string& name, std::string* bytes = nullptr) {
  Framebuffer fb;
  fb.width = cam.width();
  fb.height = cam.height();
  fb.beauty.assign(std::size_t(fb.width) * fb.height, Color(0.25f));
  OutputDesc out;
  out.image = files_temp_dir() / name;
  write_image(fb, out, {}, &cam);
  if (bytes) {
    std::ifstream f(out.image, std::ios::binary);
    *bytes = std::string(std::istreambuf_iterator<char>(f), {});
  }
  auto in = OIIO::ImageInput::open(out.image.string());
  return in ? in->spec() : OIIO::ImageSpec();
}

void expect_near(const Vec3& got, const Vec3& want, double tol, const std::string& what) {
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], tol) << what << " component " << k;
}

}  // namespace

// OpenEXR's worldToCamera (x right, y up, z forward, left-handed) and worldToNDC ((0, 0) and
// (1, 1) the image's upper-left and lower-right corners; ImfStandardAttributes.h), read back by
// OpenImageIO, place world points where the camera itself does: the analytic projection of a
// look-at, K/[R|t] and orthographic camera, and the rays of a thin lens. Float matrices of
// coordinates below 20: agreement to a few float ulps.
TEST(ImageOutput, ExrCarriesTheStandardCameraMatricesOfTheCamera) {
  {
    // Looking along +y from (1, 2, 3), z up, vfov 90 degrees, 40 x 20: f = 10 px, principal point
    // (19.5, 9.5). The point (3, 7, 4) is 2 right, 1 up and 5 ahead: pixel (19.5 + 10 * 2 / 5,
    // 9.5 - 10 * 1 / 5) = (23.5, 7.5), NDC ((23.5 + 0.5) / 40, (7.5 + 0.5) / 20) = (0.6, 0.4).
    LookAtParams p;
    p.position = Vec3(1, 2, 3);
    p.look_at = Vec3(1, 12, 3);
    p.vfov_deg = 90.0;
    std::string bytes;
    const OIIO::ImageSpec spec = exr_header(Camera::look_at(p, 40, 20), "lookat.exr", &bytes);
    const std::vector<double> cam = matrix_attribute(spec, "worldtocamera"), ndc = matrix_attribute(spec, "worldtoNDC");
    ASSERT_EQ(cam.size(), 16u);
    ASSERT_EQ(ndc.size(), 16u);
    expect_near(transform(cam, Vec3(3, 7, 4)), Vec3(2, 1, 5), 1e-5, "camera");
    expect_near(transform(cam, p.position), Vec3(0.0), 1e-5, "centre");
    expect_near(transform(ndc, Vec3(3, 7, 4)), Vec3(0.6, 0.4, 1.0 / 5.0), 1e-6, "NDC");
    // The file's own bytes: OpenEXR attributes named as the standard ones, of type m44f.
    EXPECT_NE(bytes.find(std::string("worldToCamera\0m44f\0", 19)), std::string::npos);
    EXPECT_NE(bytes.find(std::string("worldToNDC\0m44f\0", 16)), std::string::npos);
  }
  {
    // A tilted thin lens: the point at any depth along the ray through the lens centre of pixel
    // (u, v) projects to (u, v), and so does the in-focus point of a ray through another part of
    // the lens; camera z is the depth along the view, camera x and y the offsets right and up.
    LookAtParams p;
    p.position = Vec3(-2, 1, 4);
    p.look_at = Vec3(3, 6, -1);
    p.up = Vec3(0.1, 0, 1);
    p.vfov_deg = 35.0;
    p.aperture = 0.4;
    p.focus_distance = 6.0;
    const Camera c = Camera::look_at(p, 33, 21);
    const OIIO::ImageSpec spec = exr_header(c, "lens.exr");
    const std::vector<double> cam = matrix_attribute(spec, "worldtocamera"), ndc = matrix_attribute(spec, "worldtoNDC");
    ASSERT_EQ(cam.size(), 16u);
    ASSERT_EQ(ndc.size(), 16u);
    const Vec3 w = glm::normalize(p.look_at - p.position), right = glm::normalize(glm::cross(w, p.up));
    const Vec3 up = glm::cross(right, w);
    for (const auto& [u, v] : {std::pair{0.0, 0.0}, {32.0, 20.0}, {7.25, 13.5}, {-0.5, 20.5}})
      for (const double t : {0.5, 3.0, 11.0}) {
        const std::string at = "pixel (" + std::to_string(u) + ", " + std::to_string(v) + ") at " + std::to_string(t);
        const Ray r = c.generate_ray(u, v, 0.0, 0.0);
        const Vec3 x = r.at(t), d = x - p.position;
        expect_near(transform(ndc, x), Vec3((u + 0.5) / 33.0, (v + 0.5) / 21.0, 1.0 / glm::dot(d, w)), 2e-6, at);
        expect_near(transform(cam, x), Vec3(glm::dot(d, right), glm::dot(d, up), glm::dot(d, w)), 2e-5, at);
      }
    const Ray r = c.generate_ray(7.25, 13.5, 0.8, 0.3);
    const Vec3 focus = r.at((p.focus_distance - glm::dot(r.origin() - p.position, w)) / glm::dot(r.direction(), w));
    const Vec3 n = transform(ndc, focus);
    EXPECT_NEAR(n.x, 7.75 / 33.0, 2e-6);
    EXPECT_NEAR(n.y, 14.0 / 21.0, 2e-6);
  }
  {
    // K/[R|t] with skew and an off-centre principal point: pixel ~ K (R X + t) (OpenCV's y down),
    // OpenEXR's camera point (x, -y, z) of x = R X + t. With lens distortion no matrix projects:
    // the pose is written, worldToNDC is not.
    PinholeParams p;
    p.K = {{{50.0, 2.0, 20.3}, {0.0, 45.0, 11.1}, {0.0, 0.0, 1.0}}};
    const double a = 0.4, b = 1.9;  // R = Rz(a) Rx(b)
    const glm::dmat3 rz(std::cos(a), std::sin(a), 0, -std::sin(a), std::cos(a), 0, 0, 0, 1);
    const glm::dmat3 rx(1, 0, 0, 0, std::cos(b), std::sin(b), 0, -std::sin(b), std::cos(b));
    const glm::dmat3 R = rz * rx;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) p.R[i][j] = R[j][i];
    p.t = Vec3(0.3, -1.0, 2.0);
    LensDistortion k;
    k.k1 = -0.1;
    for (const bool distorted : {false, true}) {
      const Camera c = distorted ? Camera::pinhole_distorted(p, k, 41, 23) : Camera::pinhole(p, 41, 23);
      const OIIO::ImageSpec spec = exr_header(c, distorted ? "distorted.exr" : "pinhole.exr");
      const std::vector<double> cam = matrix_attribute(spec, "worldtocamera"), ndc = matrix_attribute(spec, "worldtoNDC");
      ASSERT_EQ(cam.size(), 16u);
      EXPECT_EQ(ndc.size(), distorted ? 0u : 16u);
      // World points of given OpenCV camera coordinates x: X = R^T (x - t).
      for (const Vec3& x : {Vec3(0.2, -0.1, 3.0), Vec3(-1.0, 0.5, 4.0), Vec3(0.3, 0.3, 1.5)}) {
        const Vec3 X = glm::transpose(R) * (x - p.t);
        expect_near(transform(cam, X), Vec3(x.x, -x.y, x.z), 1e-5, "camera");
        if (distorted) continue;
        const double u = (50.0 * x.x + 2.0 * x.y) / x.z + 20.3, v = 45.0 * x.y / x.z + 11.1;
        expect_near(transform(ndc, X), Vec3((u + 0.5) / 41.0, (v + 0.5) / 23.0, 1.0 / x.z), 2e-6, "NDC");
      }
    }
  }
  {
    // Orthographic, looking down -z from (0, 0, 10), y up in the image, 4 units tall at 8 x 4 px
    // (1 unit per pixel): (1.5, -0.5, 2) is 1.5 right, 0.5 down, 8 ahead: pixel (3.5 + 1.5,
    // 1.5 + 0.5) = (5, 2), NDC (5.5 / 8, 2.5 / 4); z is the depth.
    OrthographicParams p;
    p.position = Vec3(0, 0, 10);
    p.look_at = Vec3(0, 0, 0);
    p.up = Vec3(0, 1, 0);
    p.view_height = 4.0;
    const OIIO::ImageSpec spec = exr_header(Camera::orthographic(p, 8, 4), "ortho.exr");
    const std::vector<double> cam = matrix_attribute(spec, "worldtocamera"), ndc = matrix_attribute(spec, "worldtoNDC");
    ASSERT_EQ(cam.size(), 16u);
    ASSERT_EQ(ndc.size(), 16u);
    expect_near(transform(cam, Vec3(1.5, -0.5, 2)), Vec3(1.5, -0.5, 8), 1e-5, "camera");
    expect_near(transform(ndc, Vec3(1.5, -0.5, 2)), Vec3(5.5 / 8.0, 2.5 / 4.0, 8.0), 1e-6, "NDC");
  }
  {
    // A panorama has no projective matrix and no single view direction: neither attribute.
    EquirectangularParams p;
    const OIIO::ImageSpec spec = exr_header(Camera::equirectangular(p, 16, 8), "pano.exr");
    EXPECT_TRUE(matrix_attribute(spec, "worldtocamera").empty());
    EXPECT_EQ(spec.find_attribute("worldtoNDC"), nullptr);
  }
}

TEST(ImageOutput, AovFileCarriesTheCameraMatricesAndEightBitImagesDoNot) {
  LookAtParams p;
  p.position = Vec3(1, 2, 3);
  p.look_at = Vec3(1, 12, 3);
  const Camera c = Camera::look_at(p, 6, 4);
  Framebuffer fb;
  fb.width = 6;
  fb.height = 4;
  fb.beauty.assign(24, Color(0.5f));
  fb.depth.assign(24, 1.0f);
  OutputDesc out;
  out.image = files_temp_dir() / "cam.png";
  const auto files = write_image(fb, out, {}, &c);
  ASSERT_EQ(files.size(), 2u);
  const std::vector<MatrixAttribute> want = exr_camera_matrices(c);
  ASSERT_EQ(want.size(), 2u);
  auto aov = OIIO::ImageInput::open(files[1].string());
  ASSERT_TRUE(aov);
  for (const MatrixAttribute& m : want)
    EXPECT_EQ(matrix_attribute(aov->spec(), m.name.c_str()), std::vector<double>(m.m.begin(), m.m.end())) << m.name;
  auto png = OIIO::ImageInput::open(files[0].string());
  ASSERT_TRUE(png);
  EXPECT_EQ(png->spec().find_attribute("worldtocamera"), nullptr);
  // A camera of another size than the framebuffer is not the one it was traced through.
  const Camera larger = c.resized(std::uint32_t(12), std::uint32_t(8));
  EXPECT_THROW(write_image(fb, out, {}, &larger), std::invalid_argument);
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

TEST(RenderCli, ExposureAndCameraMatricesReachTheFile) {
  // `--exposure -1` is recorded in the image, and the EXR's worldToCamera / worldToNDC are those
  // of the camera the image records (rayscan:camera).
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_render_exposure_cli");
  const fs::path cloud = fs::path(RAYSCAN_TEST_DATA) / "las" / "simple.las";
  const rayscan::test::CommandResult r = rayscan::test::run_command(
      std::string(RAYSCAN_BIN) + " render " + cloud.string() + " --width 30 --spp 1 -q --exposure -1 --out " +
      (dir / "e.exr").string());
  ASSERT_EQ(r.code, 0) << r.out;
  auto in = OIIO::ImageInput::open((dir / "e.exr").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.get_string_attribute("rayscan:exposure"), "-1");
  EXPECT_EQ(spec.get_string_attribute("rayscan:transfer"), "linear");
  const Camera cam = io::parse_camera(nlohmann::json::parse(spec.get_string_attribute("rayscan:camera", "null")),
                                      "rayscan:camera", "");
  const std::vector<MatrixAttribute> want = exr_camera_matrices(cam);
  ASSERT_EQ(want.size(), 2u);
  for (const MatrixAttribute& m : want)
    EXPECT_EQ(matrix_attribute(spec, m.name.c_str()), std::vector<double>(m.m.begin(), m.m.end())) << m.name;
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
