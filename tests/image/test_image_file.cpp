// The one image writer and reader (rayscan/image/image_file.hpp): per-channel sample types, the
// uint32 id plane, quantisation and metadata, checked against the file as OpenImageIO reads it
// back in its stored types (the oracle is the file's own samples, not rayscan's reader).
#include "../common/temp_dir.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>

namespace fs = std::filesystem;

namespace {

fs::path temp_dir() { return rayscan::test::process_temp_dir("rayscan_image_file"); }

}  // namespace

TEST(ImageFile, ExrMixedChannelTypesAndExactUint32Ids) {
  rayscan::Image img = rayscan::make_image(4, 1, {"R", "Z"});
  img.pixels = {0.25f, 1.5f, 0.5f, 2.5f, 1.0f, 1e30f, 2.0f, -3.0f};
  img.id_channels = {"id"};
  // 2^24 + 1 is not representable in float: the id plane must keep it exactly.
  img.ids = {0u, (1u << 24) + 1u, rayscan::kNoPoint, 123456789u};
  const fs::path p = temp_dir() / "mixed.exr";
  rayscan::ImageWriteOptions o;
  o.formats = {rayscan::PixelFormat::half, rayscan::PixelFormat::float32};
  o.metadata = {{"rayscan:test", "yes"}};
  rayscan::write_image(img, p, o);

  auto in = OIIO::ImageInput::open(p.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& s = in->spec();
  ASSERT_EQ(s.nchannels, 3);
  EXPECT_EQ(s.channel_name(0), "R");
  EXPECT_EQ(s.channel_name(1), "Z");
  EXPECT_EQ(s.channel_name(2), "id");
  EXPECT_EQ(s.channelformat(0), OIIO::TypeDesc::HALF);
  EXPECT_EQ(s.channelformat(1), OIIO::TypeDesc::FLOAT);
  EXPECT_EQ(s.channelformat(2), OIIO::TypeDesc::UINT);
  EXPECT_EQ(s.get_string_attribute("rayscan:test"), "yes");
  std::uint32_t ids[4];
  ASSERT_TRUE(in->read_image(0, 0, 2, 3, OIIO::TypeDesc::UINT, ids));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(ids[i], img.ids[static_cast<std::size_t>(i)]) << i;
  float z[4];
  ASSERT_TRUE(in->read_image(0, 0, 1, 2, OIIO::TypeDesc::FLOAT, z));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(z[i], img.pixels[static_cast<std::size_t>(i) * 2 + 1]) << i;
  in->close();

  // The reader: float for every channel; misses from the id channel in its stored type.
  const rayscan::Image back = rayscan::read_image(p.string());
  ASSERT_EQ(back.nchannels(), 3);
  EXPECT_EQ(back.at(1, 0, 0), 0.5f);  // exact in half
  EXPECT_TRUE(back.id_channels.empty());
  int w = 0, h = 0;
  const auto miss = rayscan::read_index_misses(p.string(), "index", w, h);
  EXPECT_EQ(w, 4);
  EXPECT_EQ(h, 1);
  EXPECT_EQ(miss, (std::vector<std::uint8_t>{0, 0, 1, 0}));
  fs::remove_all(p.parent_path());
}

TEST(ImageFile, PngQuantisationRoundsAndClamps) {
  rayscan::Image img = rayscan::make_image(5, 1, {"Y"});
  img.pixels = {0.5f, 1.2f, -1.0f, std::numeric_limits<float>::quiet_NaN(), 100.0f / 255.0f};
  const fs::path p = temp_dir() / "q.png";
  rayscan::write_image(img, p.string(), rayscan::PixelFormat::uint8, "a description");
  auto in = OIIO::ImageInput::open(p.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  EXPECT_EQ(in->spec().format, OIIO::TypeDesc::UINT8);
  EXPECT_EQ(in->spec().get_string_attribute("ImageDescription"), "a description");
  std::uint8_t v[5];
  ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::UINT8, v));
  EXPECT_EQ(v[0], 128);  // round(127.5), half away from zero
  EXPECT_EQ(v[1], 255);
  EXPECT_EQ(v[2], 0);
  EXPECT_EQ(v[3], 0);    // NaN
  EXPECT_EQ(v[4], 100);
  in->close();
  fs::remove_all(p.parent_path());
}

TEST(ImageFile, RejectsMismatchedBuffersWithoutWriting) {
  rayscan::Image img = rayscan::make_image(2, 2, {"R", "G", "B"});
  const fs::path p = temp_dir() / "bad.exr";
  rayscan::ImageWriteOptions o;
  o.formats = {rayscan::PixelFormat::half, rayscan::PixelFormat::half};  // 2 formats, 3 channels
  EXPECT_THROW(rayscan::write_image(img, p, o), std::invalid_argument);
  img.id_channels = {"id"};  // no id samples
  EXPECT_THROW(rayscan::write_image(img, p, rayscan::ImageWriteOptions{}), std::invalid_argument);
  EXPECT_FALSE(fs::exists(p));
  fs::remove_all(p.parent_path());
}
