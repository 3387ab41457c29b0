// Image files through OpenImageIO (https://openimageio.readthedocs.io, "ImageInput",
// "ImageOutput", ImageBufAlgo::resize and ::render_text): the one reader and the one writer of
// rayscan::Image, used by the renderer (render output and AOV files) and by analysis (compare,
// heat maps, raster previews, visibility index files). OpenImageIO lives in a module
// (librayscan_oiio.so) loaded by the first call of any function here, so that programs start
// without its ~260 libraries; each function also throws std::runtime_error when the module cannot
// be loaded (the message names the paths tried).
#pragma once

#include "rayscan/image/image.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace rayscan {

/// Loads the OpenImageIO module now, which the first image call below otherwise does: for jobs
/// that end by writing an image (a render, a preview), so that a missing or broken module stops
/// them before hours of work, not after. Throws std::runtime_error naming the paths tried.
void load_image_io();

/// Sample storage of a written float channel.
enum class PixelFormat { uint8, uint16, half, float32 };

/// Key/value metadata stored in the image header (PNG tEXt, TIFF/EXR string attributes), e.g.
/// {"rayscan:scene", "scenes/x.json"}, {"ImageDescription", "..."}, {"oiio:ColorSpace", "sRGB"}.
using ImageMetadata = std::vector<std::pair<std::string, std::string>>;

/// A 4 x 4 float matrix header attribute (OpenImageIO type "matrix", TypeMatrix44), stored as
/// OpenEXR's m44f: `m` row-major, m[4 * row + col], in Imath's row-vector convention (a point p
/// maps to p * M, the translation in the last row). OpenImageIO's EXR writer names "worldtocamera"
/// and "worldtoNDC" as the standard attributes worldToCamera and worldToNDC (ImfStandardAttributes.h).
struct MatrixAttribute {
  std::string name;
  std::array<float, 16> m{};
};

/// How write_image stores an Image.
struct ImageWriteOptions {
  /// File sample type of each float channel (one entry per channel), or one entry for all of
  /// them; empty means float32. uint8/uint16 samples are round(clamp(v, 0, 1) * 255 or 65535)
  /// (NaN -> 0), half is IEEE 754 binary16 (round to nearest). Id channels are always uint32.
  std::vector<PixelFormat> formats;
  ImageMetadata metadata;       ///< header attributes, in this order
  std::vector<MatrixAttribute> matrices;  ///< matrix header attributes, after `metadata`
  int jpeg_quality = 0;         ///< JPEG quality 1..100; 0 = OpenImageIO's default
  int png_compression = -1;     ///< PNG zlib level 0..9; -1 = OpenImageIO's default
};

/// Write `img` to `path` in the format its extension names (.png, .tif, .tiff, .exr, .jpg, ...):
/// float channels first, then the id channels. EXR uses ZIP compression; "DateTime" is stored
/// empty so that equal images give byte-identical files. Data goes to a temporary
/// sibling (rayscan::AtomicFile) renamed into place only when complete (or at the commit of an
/// enclosing OutputTransaction), so a failure never leaves a half-written file.
/// Throws std::invalid_argument "<path>: ..." for buffers that do not match the size or a
/// format list of the wrong length, std::runtime_error "<path>: <reason>" when OpenImageIO
/// cannot create or write the file, and the AtomicFile errors for refused output paths.
void write_image(const Image& img, const std::filesystem::path& path, const ImageWriteOptions& options);

/// write_image with every float channel stored as `format`, `description` (if not empty) as the
/// ImageDescription attribute and PNG zlib level 3 (a 3840x2160 heat map writes several times
/// faster than at OpenImageIO's 6 for a few percent more bytes).
void write_image(const Image& img, const std::string& path, PixelFormat format,
                 const std::string& description = {});

/// Read the first subimage of any file OpenImageIO reads (PNG, JPEG, TIFF, OpenEXR, ...), all
/// channels converted to float (id_channels stays empty; integer samples scaled to [0, 1]). The
/// samples are the stored ones: colour with unassociated alpha (PNG, TIFF ExtraSamples = 2) is
/// not multiplied by the alpha, and associated files (EXR) keep their premultiplied colour;
/// alpha_channel says which channel is alpha. The path must be a regular file
/// (rayscan::InputFile). Throws std::runtime_error "<path>: <reason>", one line, when the file is
/// empty, cannot be opened or decoded (also when the decoder reports an error on a read it
/// completed, e.g. JPEG data that ends before its end-of-image marker), is volumetric
/// (depth > 1), would exceed 2^28 samples, or its header claims more samples than its size
/// allows under any compression.
Image read_image(const std::string& path);

/// Resample `img` (float channels) to width x height with OpenImageIO's ImageBufAlgo::resize
/// using the named filter (any OpenImageIO 2-D filter name: "lanczos3", "blackman-harris", "box",
/// "triangle", "gaussian", "mitchell", ...; its default width). The full image windows are mapped
/// onto each other. Throws std::runtime_error naming the filter when OpenImageIO rejects it.
Image resize_image(const Image& img, int width, int height, const std::string& filter);

/// Horizontal alignment of render_text's string at its x.
enum class TextAlign { left = 0, center = 1, right = 2 };

/// Draws `text` into `img`'s float channels with OpenImageIO's ImageBufAlgo::render_text
/// (FreeType, the DejaVu Sans font): baseline at pixel row y, aligned at pixel column x, `size`
/// pixels high, `color` one value per float channel. Returns false (and draws nothing) when no
/// font is found. Throws std::invalid_argument when `color` does not have one value per channel
/// or the pixel buffer does not match the image size.
bool render_text(Image& img, int x, int y, const std::string& text, int size, std::span<const float> color,
                 TextAlign align = TextAlign::left);

/// Per-pixel "miss" flags (1 = miss) of a point-index AOV channel: the renderer's per-pixel index
/// of the point hit, with -1 where the primary ray hit nothing. The channel is read in its stored
/// type: a miss is any negative value or NaN for float/half/signed-integer channels, and the
/// all-ones value (kNoPoint, the bits of int32 -1) for unsigned channels. `channel` empty means
/// "the only channel" (the file must then have exactly one); otherwise the channel is looked up
/// with find_channel (so "index" finds the renderer's "id"), and a file with a single channel
/// under another name uses that channel. Same input checks as read_image. Returns a
/// width*height vector, row major, top row first, and sets `width`/`height`. Throws
/// std::runtime_error naming the file and channel when it is missing or unreadable.
std::vector<std::uint8_t> read_index_misses(const std::string& path, const std::string& channel,
                                            int& width, int& height);

}  // namespace rayscan
