#include "rayscan/render/image_output.hpp"

#include "rayscan/image/aov.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/version.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rayscan::render {

namespace {

/// One float channel of a framebuffer: samples src[i * stride], stored as `format`.
struct Source {
  std::string name;
  PixelFormat format;
  const float* src;
  std::size_t stride;
};

/// The image of fb's size holding the listed float channels (interleaved once) and, when
/// `with_index`, fb.index as the uint32 id channel; `formats` receives the channels' sample types.
Image to_image(const Framebuffer& fb, const std::vector<Source>& chans, bool with_index,
               std::vector<PixelFormat>& formats) {
  Image img;
  img.width = static_cast<int>(fb.width);
  img.height = static_cast<int>(fb.height);
  const std::size_t n = img.npixels(), nc = chans.size();
  img.pixels.resize(n * nc);
  formats.clear();
  for (std::size_t c = 0; c < nc; ++c) {
    img.channels.push_back(chans[c].name);
    formats.push_back(chans[c].format);
    for (std::size_t i = 0; i < n; ++i) img.pixels[i * nc + c] = chans[c].src[i * chans[c].stride];
  }
  if (with_index && !fb.index.empty()) {  // uint32: point indices above 2^24 are not exact in float
    img.id_channels = {aov_channels(Aov::index)[0]};
    img.ids = fb.index;
  }
  return img;
}

/// RGB channels of the colours `px`, stored as `format`.
std::vector<Source> rgb_channels(const std::vector<Color>& px, PixelFormat format) {
  std::vector<Source> ch;
  for (int k = 0; k < 3; ++k) ch.push_back({std::string(1, "RGB"[k]), format, &px[0][k], 3});
  return ch;
}

/// The float AOV channels of fb (the index AOV is the id plane, see to_image).
void add_aov_channels(const Framebuffer& fb, PixelFormat color_format, std::vector<Source>& ch) {
  // Channel names: rayscan/image/aov.hpp (aov_channels), the one list the compare job also reads.
  const PixelFormat f32 = PixelFormat::float32;
  if (!fb.depth.empty()) ch.push_back({aov_channels(Aov::depth)[0], f32, fb.depth.data(), 1});
  if (!fb.normal.empty())
    for (int k = 0; k < 3; ++k) ch.push_back({aov_channels(Aov::normal)[k], f32, &fb.normal[0][k], 3});
  if (!fb.position.empty())
    for (int k = 0; k < 3; ++k) ch.push_back({aov_channels(Aov::position)[k], f32, &fb.position[0][k], 3});
  if (!fb.albedo.empty())
    for (int k = 0; k < 3; ++k) ch.push_back({aov_channels(Aov::albedo)[k], color_format, &fb.albedo[0][k], 3});
  if (!fb.cost.empty()) ch.push_back({aov_channels(Aov::cost)[0], f32, fb.cost.data(), 1});
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
  ImageWriteOptions opt;
  opt.metadata = metadata;
  opt.metadata.emplace_back("Software", software_name());
  if (!fb.position.empty()) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g", fb.position_origin.x, fb.position_origin.y,
                  fb.position_origin.z);
    opt.metadata.emplace_back("rayscan:position_origin", buf);
  }
  const float scale = static_cast<float>(std::exp2(out.exposure));
  const std::size_t n = fb.beauty.size();
  std::vector<Color> px(n);
  for (std::size_t i = 0; i < n; ++i) px[i] = fb.beauty[i] * scale;
  const std::string ext = lower_extension(out.image);
  const bool has_aovs = !fb.depth.empty() || !fb.normal.empty() || !fb.position.empty() ||
                        !fb.albedo.empty() || !fb.cost.empty() || !fb.index.empty();
  std::vector<std::filesystem::path> written;
  OutputTransaction tx;  // the image and its AOV file: all or nothing
  if (ext == ".exr") {
    const PixelFormat cf = out.exr_half ? PixelFormat::half : PixelFormat::float32;
    std::vector<Source> ch = rgb_channels(px, cf);
    add_aov_channels(fb, cf, ch);
    rayscan::write_image(to_image(fb, ch, true, opt.formats), out.image, opt);
    written.push_back(out.image);
    tx.commit();
    return written;
  }
  const bool jpeg = ext == ".jpg" || ext == ".jpeg";
  const PixelFormat f = (out.bit_depth == 16 && !jpeg) ? PixelFormat::uint16 : PixelFormat::uint8;
  for (Color& c : px) c = {linear_to_srgb(c.r), linear_to_srgb(c.g), linear_to_srgb(c.b)};
  opt.metadata.emplace_back("oiio:ColorSpace", "sRGB");
  ImageWriteOptions aov_opt;  // the AOV file carries the same metadata
  aov_opt.metadata = opt.metadata;
  if (jpeg) opt.jpeg_quality = 95;
  if (jpeg || ext == ".tif" || ext == ".tiff") {
    // TIFF and JPEG headers keep no free-form keys (OpenImageIO drops "rayscan:*"): the rayscan
    // keys go to the one free-text field both have, ImageDescription (TIFF tag 270, JPEG COM),
    // one "key: value" line each.
    std::string text;
    for (const auto& [k, v] : opt.metadata)
      if (k.rfind("rayscan:", 0) == 0) text += (text.empty() ? "" : "\n") + k + ": " + v;
    if (!text.empty()) opt.metadata.emplace_back("ImageDescription", text);
  }
  std::filesystem::path aov = out.image;
  aov.replace_extension(".aovs.exr");
  require_replaceable_output(out.image);
  if (has_aovs) require_replaceable_output(aov);  // both checked before either is written
  rayscan::write_image(to_image(fb, rgb_channels(px, f), false, opt.formats), out.image, opt);
  written.push_back(out.image);
  if (has_aovs) {
    std::vector<Source> ach;
    add_aov_channels(fb, PixelFormat::half, ach);
    rayscan::write_image(to_image(fb, ach, true, aov_opt.formats), aov, aov_opt);
    written.push_back(aov);
  }
  tx.commit();
  return written;
}

}  // namespace rayscan::render
