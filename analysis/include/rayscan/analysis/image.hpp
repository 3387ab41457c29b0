// A plain in-memory raster (float samples, named channels) and its file I/O through OpenImageIO.
// Used by `rayscan compare` and meant for any analysis output that is an image (heat maps,
// visibility previews). Callers never see OpenImageIO types.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan::analysis {

/// A 2-D image of `channels.size()` float channels, interleaved and row-major with the top row
/// first (OpenImageIO's convention): sample (x, y, c) is pixels[(y * width + x) * nchannels + c].
/// Integer file formats are normalised to [0, 1] (OpenImageIO's float conversion); float formats
/// (EXR, float TIFF) keep their values. (x0, y0) is the pixel coordinate of pixels[0] (the file's
/// data-window origin, 0 for PNG/JPEG), used only when reporting pixel positions.
struct Image {
  int width = 0;
  int height = 0;
  int x0 = 0;
  int y0 = 0;
  std::vector<std::string> channels;  ///< channel names, e.g. R, G, B, A, Y, Z, index
  int alpha_channel = -1;             ///< index of the alpha channel in `channels`, or -1
  std::vector<float> pixels;          ///< width * height * channels.size() samples
  std::string source;                 ///< file it came from (for error messages), may be empty

  [[nodiscard]] int nchannels() const { return static_cast<int>(channels.size()); }
  [[nodiscard]] std::size_t npixels() const {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
  /// Index of the channel named `name` (exact, case-sensitive match), or -1.
  [[nodiscard]] int channel_index(std::string_view name) const;
  /// Sample (x, y, c); no bounds check.
  [[nodiscard]] float at(int x, int y, int c) const {
    return pixels[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                   static_cast<std::size_t>(x)) * channels.size() + static_cast<std::size_t>(c)];
  }
};

/// The channel name `rayscan render` gives an AOV in an EXR (renderer/src/image_output.cpp):
/// "depth" -> "Z", "index" -> "id"; any other name is returned unchanged.
std::string_view renderer_channel_alias(std::string_view name);

/// Index into `names` of the channel `name` (exact, case-sensitive), or, when no channel has that
/// literal name, of its renderer alias (renderer_channel_alias: depth -> Z, index -> id); -1 when
/// neither exists. Lets `--channel depth` find the renderer's `Z` channel.
int find_channel(const std::vector<std::string>& names, std::string_view name);

/// Make an image of the given size and channel names filled with `value`.
/// Throws std::invalid_argument for a negative size or no channels.
Image make_image(int width, int height, std::vector<std::string> channels, float value = 0.0f);

/// Read the first subimage of any file OpenImageIO reads (PNG, JPEG, TIFF, OpenEXR, ...), all
/// channels converted to float. Throws std::runtime_error "<path>: <reason>" when the file cannot
/// be opened or decoded, or is volumetric (depth > 1), or would exceed 2^31 samples.
Image read_image(const std::string& path);

/// A new image holding the listed channels of `img` (indices into img.channels, in that order).
/// Throws std::out_of_range for an invalid index.
Image select_channels(const Image& img, const std::vector<int>& indices);

/// Resample `img` to width x height with OpenImageIO's ImageBufAlgo::resize using the named
/// filter (any OpenImageIO 2-D filter name: "lanczos3", "blackman-harris", "box", "triangle",
/// "gaussian", "mitchell", ...; its default width). The full image windows are mapped onto each
/// other. Throws std::runtime_error naming the filter when OpenImageIO rejects it.
Image resize_image(const Image& img, int width, int height, const std::string& filter);

/// Sample storage of a written file.
enum class PixelFormat { uint8, uint16, half, float32 };

/// Write `img` to `path` in the format its extension names (.png, .tif, .exr, .jpg, ...): data
/// goes to "<path>.tmp.<pid>" first and is renamed into place only when complete, so a failure
/// never leaves a half-written file. `description` (if not empty) is stored as the
/// ImageDescription attribute. Throws std::runtime_error "<path>: <reason>".
void write_image(const Image& img, const std::string& path, PixelFormat format,
                 const std::string& description = {});

/// Per-pixel "miss" flags (1 = miss) of a point-index AOV channel: the renderer's per-pixel index
/// of the point hit, with -1 where the primary ray hit nothing. The channel is read in its stored
/// type: a miss is any negative value or NaN for float/half/signed-integer channels, and the
/// all-ones value (0xFFFFFFFF, the bits of int32 -1) for unsigned channels. `channel` empty means
/// "the only channel" (the file must then have exactly one); otherwise the channel is looked up
/// with find_channel (so "index" finds the renderer's "id"), and a file with a single channel
/// under another name uses that channel. Returns a width*height vector, row
/// major, top row first, and sets `width`/`height`. Throws std::runtime_error naming the file and
/// channel when it is missing or unreadable.
std::vector<std::uint8_t> read_index_misses(const std::string& path, const std::string& channel,
                                            int& width, int& height);

}  // namespace rayscan::analysis
