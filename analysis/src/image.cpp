// Image I/O through OpenImageIO (https://openimageio.readthedocs.io, "ImageInput"/"ImageOutput"
// and ImageBufAlgo::resize).
#include "rayscan/analysis/image.hpp"

#include "rayscan/aov.hpp"

#include "rayscan/atomic_file.hpp"
#include "rayscan/spatial_index.hpp"
#include "rayscan/input_file.hpp"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdio>
#include <unistd.h>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace rayscan::analysis {

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

int Image::channel_index(std::string_view name) const {
  for (std::size_t i = 0; i < channels.size(); ++i)
    if (channels[i] == name) return static_cast<int>(i);
  return -1;
}

std::string_view renderer_channel_alias(std::string_view name) {
  // Single-channel AOVs have one file channel (rayscan/aov.hpp): depth -> Z, index -> id, cost.
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

void write_image(const Image& img, const std::string& path, PixelFormat format,
                 const std::string& description) {
  if (img.pixels.size() != img.npixels() * img.channels.size() || img.channels.empty())
    throw std::invalid_argument(path + ": write_image: pixel buffer does not match the image size");
  // The plugin is chosen from the final name; the data goes to a temporary sibling.
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw std::runtime_error(path + ": " + OIIO::geterror());
  OIIO::ImageSpec spec = spec_of(img, to_oiio(format));
  if (!description.empty()) spec.attribute("ImageDescription", description);
  // zlib level 3 instead of OpenImageIO's 6: a 3840x2160 heat map writes several times faster
  // for a few percent more bytes.
  spec.attribute("png:compressionLevel", 3);
  AtomicFile file(path);
  const std::string tmp = file.temp().string();
  auto fail = [&](const std::string& why) { throw std::runtime_error(path + ": " + why); };
  if (!out->open(tmp, spec)) fail(out->geterror());
  if (!out->write_image(OIIO::TypeDesc::FLOAT, img.pixels.data())) {
    const std::string why = out->geterror();
    out->close();
    fail(why);
  }
  if (!out->close()) fail(out->geterror());
  file.commit();
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

}  // namespace rayscan::analysis
