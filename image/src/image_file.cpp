// The one reader and writer of rayscan::Image: the input policy, size caps, temporary file and
// channel look-up here, the OpenImageIO calls in the module loaded on first use (oiio_module.hpp:
// https://openimageio.readthedocs.io, "ImageInput"/"ImageOutput", ImageBufAlgo::resize).
#include "rayscan/image/image_file.hpp"

#include "oiio_module.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/octree/spatial_index.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan {

namespace oiio_module {

namespace {

/// Where librayscan_oiio.so is looked for (see api()).
std::vector<std::string> module_candidates() {
  // An explicit RAYSCAN_OIIO_MODULE is the only candidate: no silent fall-back to another build.
  if (const char* env = std::getenv("RAYSCAN_OIIO_MODULE"); env != nullptr && *env != '\0') return {env};
  std::vector<std::string> paths;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec)
    paths.push_back((exe.parent_path().parent_path() / RAYSCAN_OIIO_MODULE_LIBDIR / "rayscan" /
                     RAYSCAN_OIIO_MODULE_NAME).string());
  paths.emplace_back(RAYSCAN_OIIO_MODULE_INSTALLED);
  paths.emplace_back(RAYSCAN_OIIO_MODULE_BUILT);
  return paths;
}

const Api* load() {
  const std::vector<std::string> candidates = module_candidates();
  std::string tried;
  for (const std::string& path : candidates) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) continue;
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);  // never closed
    const char* err = handle == nullptr ? ::dlerror() : nullptr;
    std::string why = err != nullptr ? err : "not loadable";
    if (handle != nullptr) {
      if (auto entry = reinterpret_cast<EntryPoint>(::dlsym(handle, kEntryPoint))) return entry();
      why = std::string("no entry point ") + kEntryPoint + " (a module of another rayscan version)";
    }
    tried += (tried.empty() ? "" : "; ") + path + ": " + why;
  }
  if (tried.empty()) {
    for (const std::string& path : candidates) tried += (tried.empty() ? "" : ", ") + path;
    tried = "not found (looked for " + tried + ")";
  }
  throw std::runtime_error("image files need rayscan's OpenImageIO module " RAYSCAN_OIIO_MODULE_NAME ": " + tried);
}

}  // namespace

const Api& api() {
  static std::mutex m;
  static const Api* table = nullptr;
  std::lock_guard lock(m);
  if (table == nullptr) table = load();  // a failed load throws and is tried again next time
  return *table;
}

}  // namespace oiio_module

namespace {

/// Cap on one decoded image: 2^28 samples (1 GiB as float; e.g. 8192 x 8192 RGBA).
constexpr double kMaxImageSamples = double(1u << 28);
/// Largest plausible ratio of decoded bytes to file bytes (deflate, used by PNG and the EXR ZIP
/// codecs, expands at most ~1032:1; RFC 1951 section 3.2.5 with 258-byte matches), plus a
/// constant for headers. A header claiming more than this is lying about its size.
constexpr double kMaxExpansion = 1100.0;

/// OpenImageIO's reason for a failure as one line: its lines (libpng and the plugins give
/// several) trimmed and joined with "; ", leaving out empty lines and a line that another one
/// already contains ("Read error: hit end of file" beside "PNG read error: IDAT: Read error: hit
/// end of file"), and without the path the JPEG and EXR readers quote (" (\"<path>\")",
/// " \"<path>\""): the caller's message starts with it.
std::string one_line(const std::string& path, const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find_first_of("\r\n", start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    for (const std::string& quoted : {" (\"" + path + "\")", " (" + path + ")", " \"" + path + "\""})
      if (const std::size_t at = line.find(quoted); at != std::string::npos) line.erase(at, quoted.size());
    const std::size_t b = line.find_first_not_of(" \t"), e = line.find_last_not_of(" \t");
    if (b != std::string::npos) lines.push_back(line.substr(b, e - b + 1));
    start = end + 1;
  }
  std::string out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    bool contained = false;
    for (std::size_t j = 0; j < lines.size() && !contained; ++j)
      contained = j != i && lines[j].find(lines[i]) != std::string::npos && (lines[j] != lines[i] || j < i);
    if (!contained) out += (out.empty() ? "" : "; ") + lines[i];
  }
  return out.empty() ? std::string("no reason given by OpenImageIO") : out;
}

/// The error of pixels that cannot be decoded, one line: "<path>[ context]: cannot decode the
/// pixels (<reason>): the file is truncated or corrupt".
std::runtime_error decode_error(const std::string& path, const std::string& context, const std::string& why) {
  return std::runtime_error(path + context + ": cannot decode the pixels (" + one_line(path, why) +
                            "): the file is truncated or corrupt");
}

/// Opens `path` through the input policy and the module, and checks its header against the caps.
std::unique_ptr<oiio_module::ImageReader> open_input(const std::string& path) {
  std::uint64_t file_size = 0;
  try {
    const InputFile f(path);  // the input policy: regular files only, never a blocking open
    file_size = f.size();
  } catch (const InputFileError& e) {
    throw std::runtime_error(e.what());
  }
  // Said here because OpenImageIO's plugins word it as a wrong format ("Not a PNG file").
  if (file_size == 0) {
    const std::string ext = lower_extension(path);
    throw std::runtime_error(path + ": file is empty (0 bytes), expected " +
                             (ext.empty() ? std::string("an image") : "a " + ext + " image"));
  }
  std::string why;
  auto in = oiio_module::api().open(path, why);
  if (!in) throw std::runtime_error(path + ": " + one_line(path, why));
  const oiio_module::ImageHeader& s = in->header();
  const int nchannels = static_cast<int>(s.channel_names.size());
  if (s.depth > 1) throw std::runtime_error(path + ": volumetric images (depth > 1) are not supported");
  if (s.width <= 0 || s.height <= 0 || nchannels <= 0)
    throw std::runtime_error(path + ": empty image (" + std::to_string(s.width) + "x" +
                             std::to_string(s.height) + ", " + std::to_string(nchannels) + " channels)");
  // Checked against a fixed cap and against the file's size before any pixel buffer is
  // allocated (a 249-byte PNG claiming 10000x10000 must not allocate 1.5 GB).
  const double samples = double(s.width) * double(s.height) * double(nchannels);
  const std::string dims =
      std::to_string(s.width) + "x" + std::to_string(s.height) + "x" + std::to_string(nchannels);
  if (samples > kMaxImageSamples)
    throw std::runtime_error(path + ": image too large (" + dims + " samples exceeds the 2^28 limit)");
  const double decoded = samples * double(s.sample_bytes);
  if (decoded > kMaxExpansion * double(file_size) + 65536.0)
    throw std::runtime_error(path + ": header claims " + dims + " samples (" +
                             std::to_string(static_cast<std::uint64_t>(decoded)) +
                             " bytes) but the file has only " + std::to_string(file_size) +
                             " bytes (more than any compression allows)");
  return in;
}

}  // namespace

void load_image_io() { (void)oiio_module::api(); }

Image read_image(const std::string& path) {
  auto in = open_input(path);
  const oiio_module::ImageHeader& s = in->header();
  Image img;
  img.width = s.width;
  img.height = s.height;
  img.x0 = s.x0;
  img.y0 = s.y0;
  img.channels = s.channel_names;
  img.alpha_channel = s.alpha_channel;
  img.source = path;
  img.pixels.resize(img.npixels() * img.channels.size());
  const std::string why = in->read(0, img.nchannels(), oiio_module::SampleType::float32, img.pixels.data());
  if (!why.empty()) throw decode_error(path, "", why);
  return img;
}

Image resize_image(const Image& img, int width, int height, const std::string& filter) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("resize_image: target size must be positive");
  return oiio_module::api().resize(img, width, height, filter);
}

bool render_text(Image& img, int x, int y, const std::string& text, int size, std::span<const float> color,
                 TextAlign align) {
  if (img.nchannels() == 0 || color.size() != img.channels.size() || img.pixels.size() != img.npixels() * color.size())
    throw std::invalid_argument("render_text: one colour value per float channel of a complete image");
  return oiio_module::api().render_text(img, x, y, text, size, color.data(), static_cast<int>(align));
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
  std::vector<PixelFormat> formats(nf, PixelFormat::float32);
  for (std::size_t c = 0; c < nf && !o.formats.empty(); ++c) formats[c] = o.formats[o.formats.size() == 1 ? 0 : c];
  const oiio_module::Api& oiio = oiio_module::api();  // loaded before the temporary file exists
  AtomicFile file(path);
  std::vector<unsigned char> bytes;
  if (!oiio.encode(img, name, file.temp().string(), formats, o, lower_extension(path) == ".exr", bytes))
    file.write_all(bytes);
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
  const oiio_module::ImageHeader& s = in->header();
  const int nchannels = static_cast<int>(s.channel_names.size());
  int c = -1;
  if (channel.empty()) {
    if (nchannels != 1)
      throw std::runtime_error(path + ": expected a single point-index channel, found " + std::to_string(nchannels));
    c = 0;
  } else {
    c = find_channel(s.channel_names, channel);
    if (c < 0) {
      if (nchannels == 1) {
        c = 0;  // a separate index file with one channel under another name
      } else {
        std::string names;
        for (const std::string& nm : s.channel_names) names += (names.empty() ? "" : ",") + nm;
        throw std::runtime_error(path + ": no point-index channel '" + channel + "' (channels: " + names + ")");
      }
    }
  }
  width = s.width;
  height = s.height;
  const std::size_t n = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
  using oiio_module::SampleType;
  const SampleType t = s.channel_types[static_cast<std::size_t>(c)];
  std::vector<std::uint8_t> miss(n, 0);
  auto read_as = [&](SampleType type, auto* buf) {
    const std::string why = in->read(c, c + 1, type, buf);
    if (!why.empty()) throw decode_error(path, ": channel '" + s.channel_names[std::size_t(c)] + "'", why);
  };
  if (t == SampleType::uint32 || t == SampleType::uint16 || t == SampleType::uint8) {
    std::vector<std::uint32_t> v(n);
    read_as(SampleType::uint32, v.data());  // same-width or widening: values preserved
    // OIIO widens unsigned integers by scaling to the full range, so an all-ones uint8/uint16
    // sample also arrives as 0xFFFFFFFF.
    for (std::size_t i = 0; i < n; ++i) miss[i] = v[i] == kNoPoint;
  } else if (t == SampleType::int32 || t == SampleType::int16 || t == SampleType::int8) {
    std::vector<std::int32_t> v(n);
    read_as(SampleType::int32, v.data());
    for (std::size_t i = 0; i < n; ++i) miss[i] = v[i] < 0;
  } else {
    std::vector<double> v(n);
    read_as(SampleType::float64, v.data());
    for (std::size_t i = 0; i < n; ++i) miss[i] = !(v[i] >= 0.0);  // negative or NaN
  }
  return miss;
}

}  // namespace rayscan
