// `rayscan compare`'s inputs end to end: samples compared as stored (unassociated alpha not
// multiplied in), inputs that do not decode whole refused with one line, and the heat maps' help
// listing the extensions the job accepts. Input files are written through GDAL, whose bytes are
// the oracle, independent of OpenImageIO.
#include "rayscan/image/image_file.hpp"
#include "image_test_util.hpp"

#include "../common/run_command.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <gdal_priv.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <regex>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;

// Named, not anonymous: this file shares unity batches with test_compare_cli.cpp, whose helpers
// in its anonymous namespace have the same short names; the tests are in here too, so that no
// using-directive reaches the other files of a batch.
namespace compare_input_test {

using rayscan::Image;
using rayscan::PixelFormat;
using rayscan::read_image;
using rayscan::analysis::test::noise_image;
using Result = rayscan::test::CommandResult;

Result run(const std::string& cmd, bool merge = false) { return rayscan::test::run_command(cmd, merge); }

using rayscan::test::quoted;

Result compare(const fs::path& a, const fs::path& b, const std::string& opts = "", bool merge = false) {
  return run(std::string(RAYSCAN_BIN) + " compare " + quoted(a) + " " + quoted(b) + " " + opts, merge);
}

nlohmann::json compare_json(const fs::path& a, const fs::path& b, const std::string& opts = "") {
  const Result r = compare(a, b, "--json " + opts);
  EXPECT_TRUE(r.code == 0 || r.code == 1) << r.out;
  return nlohmann::json::parse(r.out);
}

/// Writes a 4-band 8-bit RGBA image through GDAL (PNG, or an uncompressed GeoTIFF whose alpha is
/// marked unassociated, ExtraSamples = 2): `rgb(x, y, c)` and `alpha(x, y)` are the stored bytes,
/// the oracle of the tests below, independent of OpenImageIO.
template <class Rgb, class Alpha>
void write_rgba_gdal(const fs::path& p, int w, int h, Rgb rgb, Alpha alpha) {
  GDALAllRegister();
  std::vector<std::uint8_t> band(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  ASSERT_NE(mem, nullptr);
  std::unique_ptr<GDALDataset> ds(mem->Create("", w, h, 4, GDT_Byte, nullptr));
  for (int c = 0; c < 4; ++c) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        band[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] =
            c < 3 ? rgb(x, y, c) : alpha(x, y);
    ASSERT_EQ(ds->GetRasterBand(c + 1)->RasterIO(GF_Write, 0, 0, w, h, band.data(), w, h, GDT_Byte, 0, 0), CE_None);
  }
  ds->GetRasterBand(4)->SetColorInterpretation(GCI_AlphaBand);
  const bool tiff = p.extension() == ".tif";
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName(tiff ? "GTiff" : "PNG");
  ASSERT_NE(drv, nullptr);
  char** opts = nullptr;
  if (tiff) {
    opts = CSLSetNameValue(opts, "ALPHA", "NON-PREMULTIPLIED");
    opts = CSLSetNameValue(opts, "PHOTOMETRIC", "RGB");
  }
  std::unique_ptr<GDALDataset> out(drv->CreateCopy(p.c_str(), ds.get(), FALSE, opts, nullptr, nullptr));
  CSLDestroy(opts);
  ASSERT_NE(out, nullptr) << CPLGetLastErrorMsg();
}

std::string file_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void put_bytes(const fs::path& p, const std::string& b) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
}

/// The value of the ExtraSamples tag (338) of a little-endian TIFF's first directory, read from
/// the file's bytes (TIFF 6.0 section 2: header, IFD entries of 12 bytes; a SHORT value in place):
/// 1 associated, 2 unassociated alpha; -1 when absent or not a little-endian TIFF.
int tiff_extra_samples(const fs::path& p) {
  const std::string b = file_bytes(p);
  const auto u16 = [&](std::size_t at) {
    return at + 2 <= b.size() ? unsigned(std::uint8_t(b[at])) | unsigned(std::uint8_t(b[at + 1])) << 8 : 0u;
  };
  const auto u32 = [&](std::size_t at) { return std::size_t(u16(at)) | std::size_t(u16(at + 2)) << 16; };
  if (b.size() < 8 || b.compare(0, 4, std::string("II*\0", 4)) != 0) return -1;
  const std::size_t ifd = u32(4);
  for (unsigned i = 0, n = u16(ifd); i < n; ++i)
    if (const std::size_t e = ifd + 2 + 12 * std::size_t(i); u16(e) == 338) return int(u16(e + 8));
  return -1;
}

class CompareInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rayscan_compare_input_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path write(const std::string& name, const Image& img, PixelFormat f) {
    const fs::path p = dir_ / name;
    rayscan::write_image(img, p.string(), f);
    return p;
  }
  fs::path dir_;
};

// Colour stored with unassociated alpha is compared as stored, not multiplied by the alpha: two
// files with the same R,G,B bytes and alpha 255 vs 128 (or 0..255 across the image) are equal
// in R,G,B, and differ only in A with --alpha, by the stored bytes' difference. Oracle: the bytes
// GDAL was given (and, for the TIFF, read back from the file by GDAL).
TEST_F(CompareInput, UnassociatedAlphaColourIsComparedAsStored) {
  const int W = 16, H = 12;
  const auto rgb = [](int x, int y, int c) { return static_cast<std::uint8_t>((x * 16 + y * 21 + c * 85) % 256); };
  const auto opaque = [](int, int) { return std::uint8_t{255}; };
  const auto half = [](int, int) { return std::uint8_t{128}; };
  const auto ramp = [](int x, int y) { return static_cast<std::uint8_t>((x + y * 16) * 255 / (16 * 12 - 1)); };
  for (const char* ext : {".png", ".tif"}) {
    SCOPED_TRACE(ext);
    const fs::path a = dir_ / (std::string("a255") + ext), b = dir_ / (std::string("a128") + ext),
                   c = dir_ / (std::string("ramp") + ext);
    write_rgba_gdal(a, W, H, rgb, opaque);
    write_rgba_gdal(b, W, H, rgb, half);
    write_rgba_gdal(c, W, H, rgb, ramp);
    if (std::string(ext) == ".tif") {
      EXPECT_EQ(tiff_extra_samples(b), 2);  // unassociated alpha
    }
    for (const auto& [path, alpha] : {std::pair{b, 128}, std::pair{c, -1}}) {
      const Image img = read_image(path.string());
      ASSERT_EQ(img.nchannels(), 4);
      EXPECT_EQ(img.alpha_channel, 3);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          // To float rounding (OpenImageIO scales by 1/255); premultiplied would be off by up to 1/2.
          for (int ch = 0; ch < 3; ++ch) ASSERT_NEAR(img.at(x, y, ch), rgb(x, y, ch) / 255.0, 1e-6) << x << "," << y;
          ASSERT_NEAR(img.at(x, y, 3), (alpha >= 0 ? alpha : ramp(x, y)) / 255.0, 1e-6) << x << "," << y;
        }
    }
    for (const fs::path& other : {b, c}) {
      const nlohmann::json j = compare_json(a, other, "--no-flip");
      EXPECT_EQ(j["mae"].get<double>(), 0.0) << j.dump();
      EXPECT_EQ(j["verdict"], "pass") << j.dump();
    }
    EXPECT_EQ(compare(a, b, "--no-flip").code, 0);
    const nlohmann::json j = compare_json(a, b, "--no-flip --alpha");
    EXPECT_NEAR(j["max_error"]["value"].get<double>(), 127.0 / 255.0, 1e-6) << j.dump();
    EXPECT_EQ(j["max_error"]["channel"], "A") << j.dump();
    EXPECT_NEAR(j["mae"].get<double>(), 127.0 / 255.0 / 4.0, 1e-6) << j.dump();
  }
}

// An input that does not decode whole is an error of one line naming the file, exit 2: a JPEG cut
// short (libjpeg decodes it with a warning only), a PNG cut short or with a corrupted byte in its
// pixel data, an empty file. The truncated JPEG's own bytes show what it lacks: the end-of-image
// marker FF D9 (ISO/IEC 10918-1 B.2.1) that the whole file ends with.
TEST_F(CompareInput, InputThatDoesNotDecodeWholeIsOneLineError) {
  const Image noise = noise_image(120, 80, {"R", "G", "B"}, 7, 0, 1);
  const fs::path jpg = write("a.jpg", noise, PixelFormat::uint8), png = write("a.png", noise, PixelFormat::uint8);
  const std::string jb = file_bytes(jpg), pb = file_bytes(png);
  ASSERT_GT(jb.size(), 3000u);
  ASSERT_EQ(jb.substr(jb.size() - 2), "\xFF\xD9");
  const fs::path tj = dir_ / "tr.jpg", tp = dir_ / "tr.png", cp = dir_ / "crc.png", ep = dir_ / "empty.png";
  put_bytes(tj, jb.substr(0, jb.size() * 2 / 3));
  ASSERT_NE(file_bytes(tj).substr(file_bytes(tj).size() - 2), "\xFF\xD9");
  put_bytes(tp, pb.substr(0, pb.size() * 2 / 3));
  std::string corrupt = pb;
  const std::size_t idat = corrupt.find("IDAT");
  ASSERT_NE(idat, std::string::npos);
  corrupt[idat + 4 + 200] = static_cast<char>(corrupt[idat + 4 + 200] ^ 0x5A);  // inside the pixel data
  put_bytes(cp, corrupt);
  put_bytes(ep, "");
  const std::string tail = "): the file is truncated or corrupt\n";
  for (const auto& [bad, good] : {std::pair{tj, jpg}, std::pair{tp, png}, std::pair{cp, png}}) {
    SCOPED_TRACE(bad.filename().string());
    for (const auto& [ref, img] : {std::pair{good, bad}, std::pair{bad, bad}}) {
      const Result r = compare(ref, img, "--no-flip", true);
      EXPECT_EQ(r.code, 2) << r.out;
      const std::string head = "rayscan compare: " + bad.string() + ": cannot decode the pixels (";
      EXPECT_EQ(r.out.rfind(head, 0), 0u) << r.out;
      ASSERT_GE(r.out.size(), tail.size());
      EXPECT_EQ(r.out.substr(r.out.size() - tail.size()), tail) << r.out;
      EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
      EXPECT_EQ(r.out.find("\\n"), std::string::npos) << r.out;  // no escaped line breaks either
      EXPECT_EQ(r.out.find(bad.string(), head.size()), std::string::npos) << r.out;  // named once
    }
  }
  EXPECT_NE(compare(jpg, tj, "--no-flip", true).out.find("(JPEG error: Premature end of JPEG file)"),
            std::string::npos);
  const Result e = compare(png, ep, "--no-flip", true);
  EXPECT_EQ(e.code, 2);
  EXPECT_EQ(e.out, "rayscan compare: " + ep.string() + ": file is empty (0 bytes), expected a .png image\n");
  EXPECT_THROW(read_image(tj.string()), std::runtime_error);
  EXPECT_EQ(read_image(jpg.string()).width, 120);  // the whole JPEG reads
}

// The heat maps' help lists exactly the extensions the job accepts (its refusal names them).
TEST_F(CompareInput, HeatMapHelpListsTheAcceptedExtensions) {
  const fs::path pa = write("a.png", noise_image(4, 4, {"R", "G", "B"}, 1, 0, 1), PixelFormat::uint8);
  const Result refused = compare(pa, pa, "--diff " + quoted(dir_ / "d.bmp"), true);
  EXPECT_EQ(refused.code, 2);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(refused.out, m, std::regex(R"(ending in (.*) or (\.\w+)\n)"))) << refused.out;
  const std::string listed = std::regex_replace(m[1].str(), std::regex(", "), " ") + " " + m[2].str();
  const Result help = run(std::string(RAYSCAN_BIN) + " compare --help");
  EXPECT_NE(help.out.find("heat map of the per-pixel error here (" + listed + ")"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("map over [0, 1] (" + listed + ")"), std::string::npos) << help.out;
}

}  // namespace compare_input_test
