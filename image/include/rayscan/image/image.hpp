// The one in-memory image type of rayscan: named float channels, interleaved, plus an optional
// plane of uint32 channels for values a float cannot hold exactly (the point-index AOV "id").
// Written and read by rayscan/image/image_file.hpp; the renderer's output and every analysis
// image (compare, heat maps, raster previews) use it. Callers never see OpenImageIO types.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan {

/// A 2-D image, row-major with the top row first (OpenImageIO's convention).
///  - `channels`: float channels, interleaved: sample (x, y, c) is
///    pixels[(y * width + x) * channels.size() + c]. Integer file formats read as float are
///    normalised to [0, 1] (OpenImageIO's float conversion); float formats (EXR, float TIFF) keep
///    their values.
///  - `id_channels`: uint32 channels (e.g. the renderer's point index "id", kNoPoint for a miss),
///    interleaved the same way in `ids`; written after the float channels, as uint32 samples.
///    Usually empty; read_image never fills it (it reads every file channel as float).
/// (x0, y0) is the pixel coordinate of pixels[0] (the file's data-window origin, 0 for
/// PNG/JPEG), used only when reporting pixel positions.
struct Image {
  int width = 0;
  int height = 0;
  int x0 = 0;
  int y0 = 0;
  std::vector<std::string> channels;     ///< float channel names, e.g. R, G, B, A, Y, Z
  int alpha_channel = -1;                ///< index of the alpha channel in `channels`, or -1
  std::vector<float> pixels;             ///< width * height * channels.size() samples
  std::vector<std::string> id_channels;  ///< uint32 channel names, e.g. id
  std::vector<std::uint32_t> ids;        ///< width * height * id_channels.size() samples
  std::string source;                    ///< file it came from (for error messages), may be empty

  [[nodiscard]] int nchannels() const { return static_cast<int>(channels.size()); }
  [[nodiscard]] std::size_t npixels() const {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
  /// Index of the float channel named `name` (exact, case-sensitive match), or -1.
  [[nodiscard]] int channel_index(std::string_view name) const;
  /// Float sample (x, y, c); no bounds check.
  [[nodiscard]] float at(int x, int y, int c) const {
    return pixels[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                   static_cast<std::size_t>(x)) * channels.size() + static_cast<std::size_t>(c)];
  }
};

/// The channel name `rayscan render` gives an AOV in an EXR (rayscan/image/aov.hpp, aov_channels):
/// "depth" -> "Z", "index" -> "id"; any other name is returned unchanged.
std::string_view renderer_channel_alias(std::string_view name);

/// Index into `names` of the channel `name` (exact, case-sensitive), or, when no channel has that
/// literal name, of its renderer alias (renderer_channel_alias: depth -> Z, index -> id); -1 when
/// neither exists. Lets `--channel depth` find the renderer's `Z` channel.
int find_channel(const std::vector<std::string>& names, std::string_view name);

/// Make an image of the given size and float channel names filled with `value` ("A" or "Alpha"
/// becomes the alpha channel). Throws std::invalid_argument for a negative size or no channels.
Image make_image(int width, int height, std::vector<std::string> channels, float value = 0.0f);

/// A new image holding the listed float channels of `img` (indices into img.channels, in that
/// order; the id plane is not copied). Throws std::out_of_range for an invalid index.
Image select_channels(const Image& img, const std::vector<int>& indices);

}  // namespace rayscan
