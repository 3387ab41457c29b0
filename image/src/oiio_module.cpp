// librayscan_oiio.so: rayscan_image's OpenImageIO calls (https://openimageio.readthedocs.io,
// "ImageInput", "ImageOutput", ImageBufAlgo::resize and ::render_text), loaded on first use
// (oiio_module.hpp says why). Only OpenImageIO and POSIX calls: no rayscan function.
#include "oiio_module.hpp"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/half.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <unistd.h>

namespace rayscan::oiio_module {

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

OIIO::TypeDesc to_oiio(SampleType t) {
  switch (t) {
    case SampleType::uint8: return OIIO::TypeDesc::UINT8;
    case SampleType::int8: return OIIO::TypeDesc::INT8;
    case SampleType::uint16: return OIIO::TypeDesc::UINT16;
    case SampleType::int16: return OIIO::TypeDesc::INT16;
    case SampleType::uint32: return OIIO::TypeDesc::UINT32;
    case SampleType::int32: return OIIO::TypeDesc::INT32;
    case SampleType::half: return OIIO::TypeDesc::HALF;
    case SampleType::float32: return OIIO::TypeDesc::FLOAT;
    case SampleType::float64: return OIIO::TypeDesc::DOUBLE;
    case SampleType::other: break;
  }
  return OIIO::TypeDesc::UNKNOWN;
}

SampleType from_oiio(OIIO::TypeDesc t) {
  switch (t.basetype) {
    case OIIO::TypeDesc::UINT8: return SampleType::uint8;
    case OIIO::TypeDesc::INT8: return SampleType::int8;
    case OIIO::TypeDesc::UINT16: return SampleType::uint16;
    case OIIO::TypeDesc::INT16: return SampleType::int16;
    case OIIO::TypeDesc::UINT32: return SampleType::uint32;
    case OIIO::TypeDesc::INT32: return SampleType::int32;
    case OIIO::TypeDesc::HALF: return SampleType::half;
    case OIIO::TypeDesc::FLOAT: return SampleType::float32;
    case OIIO::TypeDesc::DOUBLE: return SampleType::float64;
    default: return SampleType::other;
  }
}

/// Redirects file descriptor 2 to a temporary file while alive (libpng, called inside
/// OpenImageIO, prints its warnings and errors straight to stderr); text() returns what was
/// printed, so that it becomes part of rayscan's error (made one line by rayscan_image) instead
/// of extra lines.
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
  ~StderrCapture() {
    restore();
    if (tmp_ != nullptr) std::fclose(tmp_);
  }
  /// Restores stderr and returns the captured text, at most about 4 KiB ("" when nothing was
  /// printed).
  std::string text() {
    restore();
    std::string out;
    if (tmp_ == nullptr) return out;
    std::rewind(tmp_);
    char buf[512];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, tmp_)) > 0 && out.size() < 4096) out.append(buf, n);
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

class OiioReader final : public ImageReader {
 public:
  explicit OiioReader(std::unique_ptr<OIIO::ImageInput> in) : in_(std::move(in)) {
    const OIIO::ImageSpec& s = in_->spec();
    h_.width = s.width;
    h_.height = s.height;
    h_.depth = s.depth;
    h_.x0 = s.x;
    h_.y0 = s.y;
    h_.alpha_channel = s.alpha_channel;
    h_.sample_bytes = s.format.size();
    for (int c = 0; c < s.nchannels; ++c) {
      h_.channel_names.emplace_back(s.channel_name(c));
      h_.channel_types.push_back(from_oiio(s.channelformat(c)));
    }
  }
  ~OiioReader() override { in_->close(); }
  const ImageHeader& header() const override { return h_; }
  std::string read(int c0, int c1, SampleType type, void* out) override {
    StderrCapture capture;
    const bool ok = in_->read_image(0, 0, c0, c1, to_oiio(type), out);
    const std::string printed = capture.text();
    // A successful read can still carry the decoder's error: libjpeg takes data that ends
    // before the end-of-image marker as a warning ("Premature end of JPEG file") and makes up
    // the missing blocks, which OpenImageIO's JPEG reader records as an error without failing.
    if (ok && !in_->has_error()) return {};
    std::string why = in_->geterror();
    if (why.empty()) why = printed.empty() ? "cannot decode the pixels" : printed;
    return why;
  }

 private:
  std::unique_ptr<OIIO::ImageInput> in_;
  ImageHeader h_;
};

std::unique_ptr<ImageReader> open(const std::string& path, std::string& why) {
  // The samples as stored: without this hint OpenImageIO multiplies the colour of a PNG or of a
  // TIFF marked unassociated (ExtraSamples = 2) by its alpha ("oiio:UnassociatedAlpha",
  // OpenImageIO's PNG and TIFF readers). Files stored associated (EXR, TIFF ExtraSamples = 1)
  // are read as stored either way.
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  StderrCapture capture;
  auto in = OIIO::ImageInput::open(path, &config);
  const std::string printed = capture.text();
  if (!in) {
    why = OIIO::geterror();
    if (why.empty()) why = printed;
    if (why.empty()) why = "cannot open image";
    return nullptr;
  }
  return std::make_unique<OiioReader>(std::move(in));
}

/// encode's TIFF path: OpenImageIO 2.4's TIFF writer, given an IOProxy, points the file's first
/// directory at the EXIF directory it writes at close, and no reader opens the result; to a file
/// it writes a valid TIFF. So the TIFF is written straight to `file`, the caller's temporary
/// beside the output (same file system, renamed by the caller). Failed strip writes are reported
/// by libtiff; the directory written at close is not (TIFFOutput::close cannot fail: TIFFClose
/// returns no status), so the file's header is read back and checked against the image.
void encode_to_file(OIIO::ImageOutput& out, const std::string& name, const std::string& file,
                    const OIIO::ImageSpec& spec, OIIO::TypeDesc type, const void* pixels) {
  if (!out.open(file, spec)) throw std::runtime_error(name + ": cannot encode the image (" + out.geterror() + ")");
  if (!(out.write_image(type, pixels) && out.close())) throw std::runtime_error(name + ": encoding failed (" + out.geterror() + ")");
  auto in = OIIO::ImageInput::open(file);
  const bool whole = in && in->spec().width == spec.width && in->spec().height == spec.height &&
                     in->spec().nchannels == spec.nchannels;
  const std::string why = in ? std::string("the written header does not match the image") : OIIO::geterror();
  if (in) in->close();
  if (!whole) throw std::runtime_error(name + ": encoding failed (" + why + "; is the disk full?)");
}

bool encode(const Image& img, const std::string& name, const std::string& file, const std::vector<PixelFormat>& formats,
            const ImageWriteOptions& o, bool zip, std::vector<unsigned char>& bytes) {
  const std::size_t n = img.npixels(), nf = img.channels.size(), ni = img.id_channels.size();
  // The plugin is chosen from the final name; the data goes to the temporary sibling.
  auto out = OIIO::ImageOutput::create(name);
  if (!out) throw std::runtime_error(name + ": cannot create image writer (" + OIIO::geterror() + ")");
  std::vector<OIIO::TypeDesc> types;
  for (std::size_t c = 0; c < nf; ++c) types.push_back(to_oiio(formats[c]));
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
  for (const MatrixAttribute& a : o.matrices) spec.attribute(a.name, OIIO::TypeMatrix44, a.m.data());
  // No wall-clock time in the file: OpenImageIO stamps "DateTime" with
  // the current time unless it is set, so it is set to a fixed value; `cmp` then confirms that
  // two renders of one scene and seed are identical.
  spec.attribute("DateTime", "");
  if (o.jpeg_quality > 0) spec.attribute("Compression", "jpeg:" + std::to_string(o.jpeg_quality));
  if (zip) spec.attribute("compression", "zip");
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
  bytes.clear();
  if (std::strcmp(out->format_name(), "tiff") == 0) {
    encode_to_file(*out, name, file, spec, mixed ? OIIO::TypeDesc::UNKNOWN : types[0], buf.data());
    return true;
  }
  OIIO::Filesystem::IOVecOutput memory(bytes);
  if (!out->set_ioproxy(&memory)) throw std::runtime_error(name + ": the image writer cannot encode into memory");
  if (!out->open(name, spec)) throw std::runtime_error(name + ": cannot encode the image (" + out->geterror() + ")");
  const bool ok = out->write_image(mixed ? OIIO::TypeDesc::UNKNOWN : types[0], buf.data()) && out->close();
  if (!ok) throw std::runtime_error(name + ": encoding failed (" + out->geterror() + ")");
  return false;
}

OIIO::ImageSpec spec_of(const Image& img) {
  OIIO::ImageSpec spec(img.width, img.height, img.nchannels(), OIIO::TypeDesc::FLOAT);
  spec.channelnames = img.channels;
  spec.alpha_channel = img.alpha_channel;
  return spec;
}

Image resize(const Image& img, int width, int height, const std::string& filter) {
  // ImageBuf wraps (does not copy) the caller's buffer; resize only reads it.
  OIIO::ImageBuf src(spec_of(img), const_cast<float*>(img.pixels.data()));
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

bool render_text(Image& img, int x, int y, const std::string& text, int size, const float* color, int align) {
  OIIO::ImageBuf buf(spec_of(img), img.pixels.data());  // draws into the caller's pixels
  const auto ax = align == 1 ? OIIO::ImageBufAlgo::TextAlignX::Center
                  : align == 2 ? OIIO::ImageBufAlgo::TextAlignX::Right
                               : OIIO::ImageBufAlgo::TextAlignX::Left;
  return OIIO::ImageBufAlgo::render_text(buf, x, y, text, size, "DejaVuSans",
                                         OIIO::cspan<float>(color, std::size_t(img.nchannels())), ax);
}

constexpr Api kApi{&open, &encode, &resize, &render_text};

}  // namespace

}  // namespace rayscan::oiio_module

extern "C" __attribute__((visibility("default"))) const rayscan::oiio_module::Api* rayscan_oiio_module_v3() {
  return &rayscan::oiio_module::kApi;
}
