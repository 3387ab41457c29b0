// The interface between rayscan_image and its OpenImageIO module (librayscan_oiio.so, built from
// oiio_module.cpp). OpenImageIO pulls in about 260 shared libraries (OpenCV, GDCM, libheif, ...)
// whose loading and relocation took 0.43 s of every process start on the reference machine, so
// rayscan_image loads the module with dlopen on its first image operation instead of linking
// OpenImageIO: commands that never read or write an image (info, index, query, db, translate)
// start without it (bench/notes/: CI time). Private to image/: nothing here is
// installed as a header.
//
// The module holds only OpenImageIO calls: the input policy, the size caps, the temporary file
// and its rename, and the channel look-up stay in rayscan_image (one copy of each, in the
// program), so the module calls no rayscan function.
#pragma once

#include "rayscan/image/image.hpp"
#include "rayscan/image/image_file.hpp"

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace rayscan::oiio_module {

/// A file sample type as OpenImageIO reports it (TypeDesc basetype), or the type to read as.
enum class SampleType { uint8, int8, uint16, int16, uint32, int32, half, float32, float64, other };

/// The header of an opened image file (OpenImageIO ImageSpec): sizes in pixels, the data-window
/// origin, one name and file sample type per channel, the alpha channel (-1: none) and the byte
/// size of the file's main sample type.
struct ImageHeader {
  int width = 0, height = 0, depth = 1, x0 = 0, y0 = 0;
  std::vector<std::string> channel_names;
  std::vector<SampleType> channel_types;
  int alpha_channel = -1;
  std::size_t sample_bytes = 4;
};

/// An opened image file (OpenImageIO ImageInput), first subimage.
class ImageReader {
 public:
  virtual ~ImageReader() = default;
  [[nodiscard]] virtual const ImageHeader& header() const = 0;
  /// Reads channels [c0, c1) of every pixel, converted to `type` (OpenImageIO's conversion),
  /// into `out` (width * height * (c1 - c0) samples), the samples as stored (unassociated alpha
  /// is not multiplied in). Returns "" on success, else the reason: OpenImageIO's error, also
  /// one recorded by a read that did not fail (a truncated JPEG), or what libpng printed on
  /// stderr; possibly several lines.
  virtual std::string read(int c0, int c1, SampleType type, void* out) = 0;
};

/// The module's functions (one table, fetched once with dlsym).
struct Api {
  /// Opens `path` (already checked by the input policy) with OpenImageIO's hint to keep
  /// unassociated alpha as stored. Null with `why` set (possibly several lines) when OpenImageIO
  /// cannot open it.
  std::unique_ptr<ImageReader> (*open)(const std::string& path, std::string& why);
  /// Encodes `img` (already checked: buffers match its size; `formats` has one entry per float
  /// channel) with the writer OpenImageIO chooses from `name`'s extension. Returns false with the
  /// file in `bytes` (cleared first), encoded through an in-memory IOProxy: the caller writes it
  /// with checked writes (AtomicFile::write_all), because the PNG and JPEG plugins do not report a
  /// short fwrite (a full disk gave a truncated PNG and exit 0, and libjpeg's own exit). Returns
  /// true when the writer wrote `file` itself instead (TIFF: its IOProxy output is unreadable in
  /// OpenImageIO 2.4): `file` is the caller's temporary beside the output, already created, and
  /// the written header is read back as the check of the close. `zip`: ZIP compression (EXR).
  /// Throws std::runtime_error "<name>: <reason>".
  bool (*encode)(const Image& img, const std::string& name, const std::string& file,
                 const std::vector<PixelFormat>& formats, const ImageWriteOptions& options, bool zip,
                 std::vector<unsigned char>& bytes);
  /// ImageBufAlgo::resize of `img`'s float channels to width x height with `filter`. Throws
  /// std::runtime_error naming the filter.
  Image (*resize)(const Image& img, int width, int height, const std::string& filter);
  /// ImageBufAlgo::render_text into the float channels of `img` (at least 1): baseline-left (x, y)
  /// for align 0, centre 1, right 2; `size` in pixels, `color` one value per channel. False when
  /// no font was found.
  bool (*render_text)(Image& img, int x, int y, const std::string& text, int size, const float* color,
                      int align);
};

/// The module's entry point (extern "C", so dlsym finds it by this name); the version in the name
/// changes with Api, so a stale module is refused instead of called.
inline constexpr const char* kEntryPoint = "rayscan_oiio_module_v3";
using EntryPoint = const Api* (*)();

/// The loaded module's table (dlopen on the first call; thread-safe). When RAYSCAN_OIIO_MODULE is
/// set, the file it names and nothing else; otherwise librayscan_oiio.so in lib/rayscan/ beside
/// the program's bin/ (an installed tree, wherever it was moved), in the configured install
/// prefix, then in the build tree. Throws std::runtime_error naming the paths tried and dlerror()'s reason.
const Api& api();

}  // namespace rayscan::oiio_module
