#include "rayscan/render/image_output.hpp"

#include "rayscan/aov.hpp"
#include "rayscan/atomic_file.hpp"
#include "rayscan/file_names.hpp"

#include <OpenImageIO/half.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace rayscan::render {

namespace {

using OIIO::TypeDesc;

/// One output channel: a strided float or uint32 source.
struct Channel {
  std::string name;
  TypeDesc type;
  const float* f = nullptr;
  const std::uint32_t* u = nullptr;
  std::size_t stride = 1;  // in elements
};

/// Write channels to `path` atomically (temporary sibling + rename).
void write_file(const std::filesystem::path& path, std::uint32_t w, std::uint32_t h,
                const std::vector<Channel>& chans, const ImageMetadata& meta, int quality = 0) {
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out) throw std::runtime_error(path.string() + ": cannot create image writer (" + OIIO::geterror() + ")");
  OIIO::ImageSpec spec(int(w), int(h), int(chans.size()), chans[0].type);
  spec.channelnames.clear();
  bool mixed = false;
  std::size_t pixel_bytes = 0;
  for (const Channel& c : chans) {
    spec.channelnames.push_back(c.name);
    spec.channelformats.push_back(c.type);
    mixed |= c.type != chans[0].type;
    pixel_bytes += c.type.size();
  }
  if (!mixed) spec.channelformats.clear();
  spec.alpha_channel = -1;
  for (const auto& [k, v] : meta) spec.attribute(k, v);
  // No wall-clock time in the file (issue 8, requirement 5): OpenImageIO stamps "DateTime" with
  // the current time unless it is set, so it is set to a fixed value; `cmp` then confirms that
  // two renders of one scene and seed are identical.
  spec.attribute("DateTime", "");
  if (quality > 0) spec.attribute("Compression", "jpeg:" + std::to_string(quality));
  if (lower_extension(path) == ".exr") spec.attribute("compression", "zip");

  // Pack pixels in the channels' native formats.
  const std::size_t n = std::size_t(w) * h;
  std::vector<unsigned char> buf(n * pixel_bytes);
  unsigned char* dst = buf.data();
  for (std::size_t i = 0; i < n; ++i)
    for (const Channel& c : chans) {
      if (c.type == TypeDesc::UINT) {
        std::memcpy(dst, &c.u[i * c.stride], 4);
        dst += 4;
        continue;
      }
      const float v = c.f[i * c.stride];
      if (c.type == TypeDesc::FLOAT) { std::memcpy(dst, &v, 4); dst += 4; }
      else if (c.type == TypeDesc::HALF) { const half hv(v); std::memcpy(dst, &hv, 2); dst += 2; }
      else if (c.type == TypeDesc::UINT8) {
        const auto q = static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
        *dst++ = q;
      } else {  // UINT16
        const auto q = static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 65535.0f));
        std::memcpy(dst, &q, 2);
        dst += 2;
      }
    }

  AtomicFile file(path);
  if (!out->open(file.temp().string(), spec))
    throw std::runtime_error(path.string() + ": cannot create output file (" + out->geterror() + ")");
  const bool ok = out->write_image(mixed ? TypeDesc::UNKNOWN : chans[0].type, buf.data()) && out->close();
  if (!ok) throw std::runtime_error(path.string() + ": write failed (" + out->geterror() + ")");
  out.reset();
  file.commit();
}

void add_aov_channels(const Framebuffer& fb, TypeDesc color_type, std::vector<Channel>& ch) {
  // Channel names: rayscan/aov.hpp (aov_channels), the one list the compare job also reads.
  if (!fb.depth.empty()) ch.push_back({aov_channels(Aov::depth)[0], TypeDesc::FLOAT, fb.depth.data(), nullptr, 1});
  if (!fb.normal.empty())
    for (int k = 0; k < 3; ++k)
      ch.push_back({aov_channels(Aov::normal)[k], TypeDesc::FLOAT, &fb.normal[0][k], nullptr, 3});
  if (!fb.position.empty())
    for (int k = 0; k < 3; ++k)
      ch.push_back({aov_channels(Aov::position)[k], TypeDesc::FLOAT, &fb.position[0][k], nullptr, 3});
  if (!fb.albedo.empty())
    for (int k = 0; k < 3; ++k)
      ch.push_back({aov_channels(Aov::albedo)[k], color_type, &fb.albedo[0][k], nullptr, 3});
  if (!fb.cost.empty()) ch.push_back({aov_channels(Aov::cost)[0], TypeDesc::FLOAT, fb.cost.data(), nullptr, 1});
  if (!fb.index.empty()) ch.push_back({aov_channels(Aov::index)[0], TypeDesc::UINT, nullptr, fb.index.data(), 1});
}

}  // namespace

std::vector<std::filesystem::path> write_image(const Framebuffer& fb, const OutputDesc& out,
                                               const ImageMetadata& metadata) {
  if (out.image.empty()) throw std::runtime_error("no output image file given");
  if (fb.width == 0 || fb.height == 0 || fb.beauty.size() != std::size_t(fb.width) * fb.height)
    throw std::invalid_argument("write_image: empty or inconsistent framebuffer");
  const std::filesystem::path dir = out.image.parent_path();
  if (!dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw std::runtime_error(out.image.string() + ": cannot create folder " + dir.string() + " (" + ec.message() + ")");
  }
  ImageMetadata meta = metadata;
  meta.emplace_back("Software", "rayscan 0.1.0");
  if (!fb.position.empty()) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g", fb.position_origin.x, fb.position_origin.y,
                  fb.position_origin.z);
    meta.emplace_back("rayscan:position_origin", buf);
  }
  const float scale = static_cast<float>(std::exp2(out.exposure));
  const std::size_t n = fb.beauty.size();
  std::vector<Color> px(n);
  for (std::size_t i = 0; i < n; ++i) px[i] = fb.beauty[i] * scale;
  const std::string ext = lower_extension(out.image);
  const bool has_aovs = !fb.depth.empty() || !fb.normal.empty() || !fb.position.empty() ||
                        !fb.albedo.empty() || !fb.cost.empty() || !fb.index.empty();
  std::vector<std::filesystem::path> written;
  OutputTransaction tx;  // the image and its AOV file: all or nothing (issue 8)
  if (ext == ".exr") {
    const TypeDesc ct = out.exr_half ? TypeDesc::HALF : TypeDesc::FLOAT;
    std::vector<Channel> ch;
    for (int k = 0; k < 3; ++k) ch.push_back({std::string(1, "RGB"[k]), ct, &px[0][k], nullptr, 3});
    add_aov_channels(fb, ct, ch);
    write_file(out.image, fb.width, fb.height, ch, meta);
    written.push_back(out.image);
    tx.commit();
    return written;
  }
  const bool jpeg = ext == ".jpg" || ext == ".jpeg";
  const TypeDesc t = (out.bit_depth == 16 && !jpeg) ? TypeDesc::UINT16 : TypeDesc::UINT8;
  for (Color& c : px) c = {linear_to_srgb(c.r), linear_to_srgb(c.g), linear_to_srgb(c.b)};
  std::vector<Channel> ch;
  for (int k = 0; k < 3; ++k) ch.push_back({std::string(1, "RGB"[k]), t, &px[0][k], nullptr, 3});
  meta.emplace_back("oiio:ColorSpace", "sRGB");
  std::filesystem::path aov = out.image;
  aov.replace_extension(".aovs.exr");
  require_replaceable_output(out.image);
  if (has_aovs) require_replaceable_output(aov);  // both checked before either is written
  write_file(out.image, fb.width, fb.height, ch, meta, jpeg ? 95 : 0);
  written.push_back(out.image);
  if (has_aovs) {
    std::vector<Channel> ach;
    add_aov_channels(fb, TypeDesc::HALF, ach);
    write_file(aov, fb.width, fb.height, ach, meta);
    written.push_back(aov);
  }
  tx.commit();
  return written;
}

}  // namespace rayscan::render
