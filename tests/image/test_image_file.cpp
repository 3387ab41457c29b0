// The one image writer and reader (rayscan/image/image_file.hpp): per-channel sample types, the
// uint32 id plane, quantisation and metadata, checked against the file as OpenImageIO reads it
// back in its stored types (the oracle is the file's own samples, not rayscan's reader).
#include "../common/file_size_limit.hpp"
#include "../common/temp_dir.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <sys/mount.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <vector>

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

namespace {

/// The names in `dir`, sorted.
std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir)) v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

/// A 16x8 RGB test pattern whose 8-bit samples are exact (k / 255).
rayscan::Image pattern() {
  rayscan::Image img = rayscan::make_image(16, 8, {"R", "G", "B"});
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float((i * 37) % 256) / 255.0f;
  return img;
}

/// Sets an environment variable for the scope and restores the old value.
struct ScopedEnv {
  std::string name;
  std::optional<std::string> old;
  ScopedEnv(std::string n, const std::string& value) : name(std::move(n)) {
    if (const char* v = std::getenv(name.c_str())) old = v;
    ::setenv(name.c_str(), value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old) ::setenv(name.c_str(), old->c_str(), 1);
    else ::unsetenv(name.c_str());
  }
};

}  // namespace

// A TIFF is encoded into the temporary beside its output and renamed, like every other format:
// with the system's temporary folder unusable (TMPDIR naming no folder) it is still written, its
// pixels read back through OpenImageIO, and the folder holds the final file and nothing else.
TEST(ImageFile, TiffIsWrittenBesideItsOutputNotInTheSystemTemp) {
  const fs::path dir = temp_dir() / "tiff_beside";
  fs::create_directories(dir);
  const rayscan::Image img = pattern();
  {
    const ScopedEnv tmp("TMPDIR", (dir / "no_such_folder").string());
    rayscan::write_image(img, (dir / "p.tif").string(), rayscan::PixelFormat::uint8);
    rayscan::write_image(img, (dir / "p.tiff").string(), rayscan::PixelFormat::uint8);  // replaced in place too
    rayscan::write_image(img, (dir / "p.tiff").string(), rayscan::PixelFormat::uint8);
  }
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"p.tif", "p.tiff"}));
  for (const char* name : {"p.tif", "p.tiff"}) {
    auto in = OIIO::ImageInput::open((dir / name).string());
    ASSERT_TRUE(in) << OIIO::geterror();
    EXPECT_EQ(std::string(in->format_name()), "tiff");
    ASSERT_EQ(in->spec().width, 16);
    ASSERT_EQ(in->spec().nchannels, 3);
    std::vector<std::uint8_t> v(img.pixels.size());
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, v.data()));
    for (std::size_t i = 0; i < v.size(); ++i) ASSERT_EQ(v[i], (i * 37) % 256) << name << " sample " << i;
  }
  fs::remove_all(dir);
}

// A file size limit at every byte count short of the whole TIFF (the strips, or the directory
// libtiff writes at close, cut short): each write throws naming the output, the old file stays
// byte-identical and no temporary is left; at the full size the write succeeds.
TEST(ImageFile, TiffCutShortAtAnySizeFailsAndKeepsTheOldFile) {
  const fs::path dir = temp_dir() / "tiff_short";
  fs::create_directories(dir);
  const fs::path out = dir / "t.tif", probe = dir / "probe.tif";
  rayscan::ImageWriteOptions o;
  o.formats = {rayscan::PixelFormat::uint8};
  const rayscan::Image img = pattern();
  rayscan::write_image(img, probe, o);
  const auto full = static_cast<rlim_t>(fs::file_size(probe));
  fs::remove(probe);
  { std::ofstream(out) << "OLD"; }
  // The helper's own refusal when the hard limit is below the whole file: nothing to test then.
  if (rayscan::test::error_within_file_size(full, [] {}) == "hard file size limit too low")
    GTEST_SKIP() << "hard file size limit too low";
  int failures = 0;
  for (rlim_t limit = 1; limit <= full; ++limit) {
    const std::string error = rayscan::test::error_within_file_size(limit, [&] { rayscan::write_image(img, out, o); });
    if (limit < full) {
      ++failures;
      EXPECT_NE(error.find(out.string()), std::string::npos) << "limit " << limit << ": '" << error << "'";
      std::ifstream f(out);
      EXPECT_EQ(std::string(std::istreambuf_iterator<char>(f), {}), "OLD") << "limit " << limit;
    } else {
      EXPECT_EQ(error, "");
    }
    EXPECT_EQ(names_in(dir), std::vector<std::string>{"t.tif"}) << "limit " << limit;
  }
  EXPECT_EQ(failures, int(full) - 1);
  fs::remove_all(dir);
}

// An output in a directory that takes no files (a read-only tmpfs mounted by the test as root, a
// 0555 folder otherwise) fails with an error naming the output path and leaves nothing behind.
TEST(ImageFile, ReadOnlyDirectoryFailsNamingThePathAndLeavesNothing) {
  const fs::path dir = temp_dir() / "ro";
  fs::create_directories(dir);
  bool mounted = false;
  if (::geteuid() == 0) {
    mounted = ::mount("tmpfs", dir.c_str(), "tmpfs", MS_RDONLY, "size=64k") == 0;
    if (!mounted) GTEST_SKIP() << "cannot mount a read-only tmpfs as root; skipped";
  } else {
    fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
  }
  for (const char* name : {"r.tif", "r.png", "r.exr"}) {
    const fs::path out = dir / name;
    try {
      rayscan::write_image(pattern(), out.string(), rayscan::PixelFormat::uint8);
      ADD_FAILURE() << name << ": written into a read-only directory";
    } catch (const rayscan::OutputFileError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(out.string() + ": cannot create output file", 0), 0u) << e.what();
    }
  }
  EXPECT_TRUE(fs::is_empty(dir));
  if (mounted) ::umount2(dir.c_str(), MNT_DETACH);
  else fs::permissions(dir, fs::perms::owner_all);
  fs::remove_all(dir);
}
