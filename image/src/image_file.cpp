// Image files through OpenImageIO (https://openimageio.readthedocs.io, "ImageInput"/"ImageOutput"
// and ImageBufAlgo::resize): the one reader and writer of rayscan::Image.
#include "rayscan/image/image_file.hpp"

#include "rayscan/atomic_file.hpp"
#include "rayscan/file_names.hpp"
#include "rayscan/spatial_index.hpp"
#include "rayscan/input_file.hpp"

#include <OpenImageIO/half.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <unistd.h>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace rayscan {

namespace {

OIIO::TypeDesc to_oiio(PixelFormat f) {
  switch (f) {
    case PixelFormat::uint8: return OIIO::TypeDesc::UINT8;
    case PixelFormat::uint16: return OIIO::TypeDesc::UINT16;
    case PixelFormat::half: return OIIO::TypeDesc::HALF;
    case PixelFormat::float32: return OIIO::TypeDesc::FLOAT;
  }
  return OIIO::TypeDesc::FLOAT;
}

/// Redirects file descriptor 2 to a temporary file while alive (libpng, called inside
/// OpenImageIO, prints its warnings and errors straight to stderr); text() returns what was
/// printed, so that it becomes part of rayscan's one-line error instead of extra lines.
class StderrCapture {
 public:
  StderrCapture() {
    std::fflush(stderr);
    tmp_ = std::tmpfile();
    saved_ = ::dup(2);
    if (tmp_ != nullptr && saved_ >= 0) ::dup2(::fileno(tmp_), 2);
  }
  StderrCapture(const StderrCapture&) = delete;
  StderrCapture& operator=(const StderrCapture&) = delete;
  ~StderrCapture() { restore(); if (tmp_ != nullptr) std::fclose(tmp_); }
  /// Restores stderr and returns the captured text as one line ("" when nothing was printed).
  std::string text() {
    restore();
    std::string out;
    if (tmp_ == nullptr) return out;
    std::rewind(tmp_);
    char buf[512];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, tmp_)) > 0 && out.size() < 4096) out.append(buf, n);
    while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
    for (char& c : out)
      if (c == '\n') c = ';';
    return out;
  }

 private:
  void restore() {
    if (saved_ >= 0) {
      std::fflush(stderr);
      ::dup2(saved_, 2);
      ::close(saved_);
      saved_ = -1;
    }
  }
  std::FILE* tmp_ = nullptr;
  int saved_ = -1;
};

/// Cap on one decoded image: 2^28 samples (1 GiB as float; e.g. 8192 x 8192 RGBA).
constexpr double kMaxImageSamples = double(1u << 28);
/// Largest plausible ratio of decoded bytes to file bytes (deflate, used by PNG and the EXR ZIP
/// codecs, expands at most ~1032:1; RFC 1951 section 3.2.5 with 258-byte matches), plus a
/// constant for headers. A header claiming more than this is lying about its size.
constexpr double kMaxExpansion = 1100.0;

std::unique_ptr<OIIO::ImageInput> open_input(const std::string& path) {
  std::uint64_t file_size = 0;
  try {
    const InputFile f(path);  // the input policy: regular files only, never a blocking open
    file_size = f.size();
  } catch (const InputFileError& e) {
    throw std::runtime_error(e.what());
  }
  StderrCapture capture;
  auto in = OIIO::ImageInput::open(path);
  const std::string printed = capture.text();
  if (!in) {
    std::string why = OIIO::geterror();
    if (why.empty()) why = printed;
    if (why.empty()) why = "cannot open image";
    throw std::runtime_error(path + ": " + why);
  }
  const OIIO::ImageSpec& s = in->spec();
  if (s.depth > 1) throw std::runtime_error(path + ": volumetric images (depth > 1) are not supported");
  if (s.width <= 0 || s.height <= 0 || s.nchannels <= 0)
    throw std::runtime_error(path + ": empty image (" + std::to_string(s.width) + "x" +
                             std::to_string(s.height) + ", " + std::to_string(s.nchannels) +
                             " channels)");
  // Checked against a fixed cap and against the file's size before any pixel buffer is
  // allocated (issue 8: a 249-byte PNG claiming 10000x10000 must not allocate 1.5 GB).
  const double samples = double(s.width) * double(s.height) * double(s.nchannels);
  const std::string dims = std::to_string(s.width) + "x" + std::to_string(s.height) + "x" +
                           std::to_string(s.nchannels);
  if (samples > kMaxImageSamples)
    throw std::runtime_error(path + ": image too large (" + dims + " samples exceeds the 2^28 limit)");
  const double decoded = samples * double(s.format.size());
  if (decoded > kMaxExpansion * double(file_size) + 65536.0)
    throw std::runtime_error(path + ": header claims " + dims + " samples (" +
                             std::to_string(static_cast<std::uint64_t>(decoded)) +
                             " bytes) but the file has only " + std::to_string(file_size) +
                             " bytes (more than any compression allows)");
  return in;
}

OIIO::ImageSpec spec_of(const Image& img, OIIO::TypeDesc format) {
  OIIO::ImageSpec spec(img.width, img.height, img.nchannels(), format);
  spec.channelnames = img.channels;
  spec.alpha_channel = img.alpha_channel;
  return spec;
}

}  // namespace

Image read_image(const std::string& path) {
  auto in = open_input(path);
  const OIIO::ImageSpec& s = in->spec();
  Image img;
  img.width = s.width;
  img.height = s.height;
  img.x0 = s.x;
  img.y0 = s.y;
  img.channels = s.channelnames;
  img.alpha_channel = s.alpha_channel;
  img.source = path;
  img.pixels.resize(img.npixels() * static_cast<std::size_t>(s.nchannels));
  StderrCapture capture;
  const bool ok = in->read_image(0, 0, 0, s.nchannels, OIIO::TypeDesc::FLOAT, img.pixels.data());
  const std::string printed = capture.text();
  if (!ok) {
    std::string why = in->geterror();
    if (why.empty()) why = printed.empty() ? "cannot decode the pixels" : printed;
    throw std::runtime_error(path + ": " + why);
  }
  in->close();
  return img;
}

Image resize_image(const Image& img, int width, int height, const std::string& filter) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("resize_image: target size must be positive");
  OIIO::ImageSpec spec = spec_of(img, OIIO::TypeDesc::FLOAT);
  // ImageBuf wraps (does not copy) the caller's buffer; resize only reads it.
  OIIO::ImageBuf src(spec, const_cast<float*>(img.pixels.data()));
  OIIO::ROI roi(0, width, 0, height, 0, 1, 0, img.nchannels());
  OIIO::ImageBuf dst = OIIO::ImageBufAlgo::resize(src, filter, 0.0f, roi);
  if (dst.has_error() || !dst.initialized())
    throw std::runtime_error("resize with filter '" + filter + "': " + dst.geterror());
  Image out = img;
  out.width = width;
  out.height = height;
  out.x0 = out.y0 = 0;
  out.pixels.assign(out.npixels() * img.channels.size(), 0.0f);
  if (!dst.get_pixels(roi, OIIO::TypeDesc::FLOAT, out.pixels.data()))
    throw std::runtime_error("resize with filter '" + filter + "': " + dst.geterror());
  return out;
}

void write_image(const Image& img, const std::filesystem::path& path, const ImageWriteOptions& o) {
  const std::string name = path.string();
  const std::size_t n = img.npixels(), nf = img.channels.size(), ni = img.id_channels.size();
  if (img.width <= 0 || img.height <= 0 || nf + ni == 0 || img.pixels.size() != n * nf ||
      img.ids.size() != n * ni)
    throw std::invalid_argument(name + ": write_image: pixel buffer does not match the image size");
  if (o.formats.size() > 1 && o.formats.size() != nf)
    throw std::invalid_argument(name + ": write_image: " + std::to_string(o.formats.size()) +
                                " sample formats for " + std::to_string(nf) + " float channels");
  // The plugin is chosen from the final name; the data goes to a temporary sibling.
  auto out = OIIO::ImageOutput::create(name);
  if (!out) throw std::runtime_error(name + ": cannot create image writer (" + OIIO::geterror() + ")");
  std::vector<OIIO::TypeDesc> types;
  for (std::size_t c = 0; c < nf; ++c)
    types.push_back(o.formats.empty() ? OIIO::TypeDesc::FLOAT : to_oiio(o.formats[o.formats.size() == 1 ? 0 : c]));
  types.insert(types.end(), ni, OIIO::TypeDesc::UINT);
  OIIO::ImageSpec spec(img.width, img.height, static_cast<int>(nf + ni), types[0]);
  spec.channelnames = img.channels;
  spec.channelnames.insert(spec.channelnames.end(), img.id_channels.begin(), img.id_channels.end());
  bool mixed = false;
  std::size_t pixel_bytes = 0;
  for (const OIIO::TypeDesc& t : types) {
    mixed |= t != types[0];
    pixel_bytes += t.size();
  }
  if (mixed) spec.channelformats = types;
  spec.alpha_channel = img.alpha_channel;
  for (const auto& [k, v] : o.metadata) spec.attribute(k, v);
  // No wall-clock time in the file (issue 8, requirement 5): OpenImageIO stamps "DateTime" with
  // the current time unless it is set, so it is set to a fixed value; `cmp` then confirms that
  // two renders of one scene and seed are identical.
  spec.attribute("DateTime", "");
  if (o.jpeg_quality > 0) spec.attribute("Compression", "jpeg:" + std::to_string(o.jpeg_quality));
  if (lower_extension(path) == ".exr") spec.attribute("compression", "zip");
  if (o.png_compression >= 0) spec.attribute("png:compressionLevel", o.png_compression);

  // Pack the samples in their file types (one code path for every format, so the quantisation
  // does not depend on the OpenImageIO version).
  std::vector<unsigned char> buf(n * pixel_bytes);
  unsigned char* dst = buf.data();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t c = 0; c < nf; ++c) {
      const float v = img.pixels[i * nf + c];
      const OIIO::TypeDesc t = types[c];
      if (t == OIIO::TypeDesc::FLOAT) {
        std::memcpy(dst, &v, 4);
        dst += 4;
      } else if (t == OIIO::TypeDesc::HALF) {
        const half hv(v);
        std::memcpy(dst, &hv, 2);
        dst += 2;
      } else if (t == OIIO::TypeDesc::UINT8) {
        *dst++ = std::isnan(v) ? 0 : static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
      } else {  // UINT16
        const auto q = std::isnan(v) ? std::uint16_t{0}
                                     : static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 65535.0f));
        std::memcpy(dst, &q, 2);
        dst += 2;
      }
    }
    if (ni > 0) {
      std::memcpy(dst, &img.ids[i * ni], 4 * ni);
      dst += 4 * ni;
    }
  }

  AtomicFile file(path);
  if (!out->open(file.temp().string(), spec))
    throw std::runtime_error(name + ": cannot create output file (" + out->geterror() + ")");
  const bool ok = out->write_image(mixed ? OIIO::TypeDesc::UNKNOWN : types[0], buf.data()) && out->close();
  if (!ok) throw std::runtime_error(name + ": write failed (" + out->geterror() + ")");
  out.reset();
  file.commit();
}

void write_image(const Image& img, const std::string& path, PixelFormat format,
                 const std::string& description) {
  ImageWriteOptions o;
  o.formats = {format};
  if (!description.empty()) o.metadata.emplace_back("ImageDescription", description);
  o.png_compression = 3;
  write_image(img, std::filesystem::path(path), o);
}

std::vector<std::uint8_t> read_index_misses(const std::string& path, const std::string& channel,
                                            int& width, int& height) {
  auto in = open_input(path);
  const OIIO::ImageSpec& s = in->spec();
  int c = -1;
  if (channel.empty()) {
    if (s.nchannels != 1)
      throw std::runtime_error(path + ": expected a single point-index channel, found " +
                               std::to_string(s.nchannels));
    c = 0;
  } else {
    std::vector<std::string> names;
    for (int i = 0; i < s.nchannels; ++i) names.emplace_back(s.channel_name(i));
    c = find_channel(names, channel);
    if (c < 0) {
      if (s.nchannels == 1) {
        c = 0;  // a separate index file with one channel under another name
      } else {
        std::string names;
        for (int i = 0; i < s.nchannels; ++i) {
          if (i) names += ',';
          names += s.channel_name(i);
        }
        throw std::runtime_error(path + ": no point-index channel '" + channel + "' (channels: " +
                                 names + ")");
      }
    }
  }
  width = s.width;
  height = s.height;
  const std::size_t n = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
  const OIIO::TypeDesc t = s.channelformat(c);
  std::vector<std::uint8_t> miss(n, 0);
  auto read_as = [&](OIIO::TypeDesc type, auto* buf) {
    if (!in->read_image(0, 0, c, c + 1, type, buf))
      throw std::runtime_error(path + ": channel '" + std::string(s.channel_name(c)) + "': " + in->geterror());
  };
  if (t.basetype == OIIO::TypeDesc::UINT32 || t.basetype == OIIO::TypeDesc::UINT16 ||
      t.basetype == OIIO::TypeDesc::UINT8) {
    std::vector<std::uint32_t> v(n);
    read_as(OIIO::TypeDesc::UINT32, v.data());  // same-width or widening: values preserved
    // OIIO widens unsigned integers by scaling to the full range, so an all-ones uint8/uint16
    // sample also arrives as 0xFFFFFFFF.
    for (std::size_t i = 0; i < n; ++i) miss[i] = v[i] == kNoPoint;
  } else if (t.basetype == OIIO::TypeDesc::INT32 || t.basetype == OIIO::TypeDesc::INT16 ||
             t.basetype == OIIO::TypeDesc::INT8) {
    std::vector<std::int32_t> v(n);
    read_as(OIIO::TypeDesc::INT32, v.data());
    for (std::size_t i = 0; i < n; ++i) miss[i] = v[i] < 0;
  } else {
    std::vector<double> v(n);
    read_as(OIIO::TypeDesc::DOUBLE, v.data());
    for (std::size_t i = 0; i < n; ++i) miss[i] = !(v[i] >= 0.0);  // negative or NaN
  }
  in->close();
  return miss;
}

}  // namespace rayscan
