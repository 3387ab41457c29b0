// The in-memory image type (rayscan/image/image.hpp): channel lookup, construction, selection.
#include "rayscan/image/image.hpp"

#include "rayscan/image/aov.hpp"

#include <optional>
#include <stdexcept>
#include <utility>

namespace rayscan {

int Image::channel_index(std::string_view name) const {
  for (std::size_t i = 0; i < channels.size(); ++i)
    if (channels[i] == name) return static_cast<int>(i);
  return -1;
}

std::string_view renderer_channel_alias(std::string_view name) {
  // Single-channel AOVs have one file channel (rayscan/image/aov.hpp): depth -> Z, index -> id, cost.
  if (const std::optional<Aov> a = parse_aov(name); a && aov_channels(*a).size() == 1) return aov_channels(*a)[0];
  return name;
}

int find_channel(const std::vector<std::string>& names, std::string_view name) {
  for (const std::string_view n : {name, renderer_channel_alias(name)})
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == n) return static_cast<int>(i);
  return -1;
}

Image make_image(int width, int height, std::vector<std::string> channels, float value) {
  if (width < 0 || height < 0) throw std::invalid_argument("make_image: negative size");
  if (channels.empty()) throw std::invalid_argument("make_image: no channels");
  Image img;
  img.width = width;
  img.height = height;
  img.channels = std::move(channels);
  for (std::size_t c = 0; c < img.channels.size(); ++c)
    if (img.channels[c] == "A" || img.channels[c] == "Alpha") img.alpha_channel = static_cast<int>(c);
  img.pixels.assign(img.npixels() * img.channels.size(), value);
  return img;
}

Image select_channels(const Image& img, const std::vector<int>& indices) {
  Image out;
  out.width = img.width;
  out.height = img.height;
  out.x0 = img.x0;
  out.y0 = img.y0;
  out.source = img.source;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const int c = indices[k];
    if (c < 0 || c >= img.nchannels())
      throw std::out_of_range("select_channels: channel index " + std::to_string(c) +
                              " outside 0.." + std::to_string(img.nchannels() - 1));
    out.channels.push_back(img.channels[static_cast<std::size_t>(c)]);
    if (c == img.alpha_channel) out.alpha_channel = static_cast<int>(k);
  }
  const std::size_t n = img.npixels(), src_nc = img.channels.size(), nc = indices.size();
  out.pixels.resize(n * nc);
  for (std::size_t p = 0; p < n; ++p)
    for (std::size_t k = 0; k < nc; ++k)
      out.pixels[p * nc + k] = img.pixels[p * src_nc + static_cast<std::size_t>(indices[k])];
  return out;
}

}  // namespace rayscan
