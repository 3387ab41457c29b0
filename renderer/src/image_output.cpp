#include "rayscan/render/image_output.hpp"

#include "rayscan/image/aov.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/version.hpp"

#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

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

/// Sets row `r` of the column-vector matrix `a` (acting on (x, y, z, 1)) to (v, t).
void set_row(glm::dmat4& a, int r, const Vec3& v, double t) {
  a[0][r] = v.x;
  a[1][r] = v.y;
  a[2][r] = v.z;
  a[3][r] = t;
}

/// The column-vector matrix `a` as an m44f attribute: Imath's row-vector matrix is a's transpose,
/// whose row-major layout is glm's column-major storage, a[column][row].
MatrixAttribute to_attribute(const char* name, const glm::dmat4& a) {
  MatrixAttribute m{name, {}};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m.m[std::size_t(4 * c + r)] = static_cast<float>(a[c][r]);
  return m;
}

}  // namespace

std::vector<MatrixAttribute> exr_camera_matrices(const Camera& camera) {
  if (camera.projection() == Projection::equirectangular ||
      camera.description().model == CameraModel::orthographic_grid)
    return {};
  const bool ortho = camera.projection() == Projection::orthographic;
  const bool distorted = camera.distortion().any();
  // A distorted camera's pose is its undistorted twin's (the same K, R, t): the lens bends the
  // rays, not the frame.
  const Camera pin = distorted ? Camera::pinhole(camera.description().pinhole, camera.width(), camera.height())
                               : camera;
  const Vec3 fwd = pin.forward();
  // Every point is X = base + B (a, b, s) for the pixel (u, v): perspective, base = the centre,
  // B = [m(1,0) - m(0,0), m(0,1) - m(0,0), m(0,0)] with m(u, v) the ray through the lens centre
  // (lens sample (0, 0)) scaled to unit depth along fwd, and (a, b, s) = s (u, v, 1), s the depth;
  // orthographic, base = the origin of pixel (0, 0)'s ray, B = [its steps, fwd], (a, b, s) =
  // (u, v, s). So B^-1 (X - base) is the homogeneous pixel.
  Vec3 base, col[3];
  if (ortho) {
    base = pin.generate_ray(0, 0).origin();
    col[0] = pin.generate_ray(1, 0).origin() - base;
    col[1] = pin.generate_ray(0, 1).origin() - base;
    col[2] = fwd;
  } else {
    const auto m = [&](double u, double v) {
      const Vec3 d = pin.generate_ray(u, v, 0.0, 0.0).direction();
      return d / glm::dot(d, fwd);
    };
    base = pin.center();
    col[2] = m(0, 0);
    col[0] = m(1, 0) - col[2];
    col[1] = m(0, 1) - col[2];
  }
  // OpenEXR's camera space: x right, y up (the pixel rows run down), z forward; right is the
  // direction of the pixel columns, which is perpendicular to fwd (K's last row is (0, 0, 1)).
  const Vec3 right = glm::normalize(col[0]);
  const Vec3 up = -glm::cross(fwd, right);
  const Vec3 c = pin.center();
  glm::dmat4 to_camera(1.0);
  set_row(to_camera, 0, right, -glm::dot(right, c));
  set_row(to_camera, 1, up, -glm::dot(up, c));
  set_row(to_camera, 2, fwd, -glm::dot(fwd, c));
  std::vector<MatrixAttribute> out{to_attribute("worldtocamera", to_camera)};
  if (distorted) return out;
  const glm::dmat3 to_pixel = glm::inverse(glm::dmat3(col[0], col[1], col[2]));
  Vec3 p[3];  // rows of to_pixel: (a, b, s) = (p0, p1, p2) . (X - base)
  for (int r = 0; r < 3; ++r) p[r] = Vec3(to_pixel[0][r], to_pixel[1][r], to_pixel[2][r]);
  const double w = camera.width(), h = camera.height();
  glm::dmat4 to_ndc(0.0);
  if (ortho) {  // x = (u + 0.5) / w, y = (v + 0.5) / h, z = s (camera z: base lies on the image plane)
    set_row(to_ndc, 0, p[0] / w, (0.5 - glm::dot(p[0], base)) / w);
    set_row(to_ndc, 1, p[1] / h, (0.5 - glm::dot(p[1], base)) / h);
    set_row(to_ndc, 2, p[2], -glm::dot(p[2], base));
    set_row(to_ndc, 3, Vec3(0.0), 1.0);
  } else {  // homogeneous: (s (u + 0.5) / w, s (v + 0.5) / h, 1, s)
    const Vec3 x = (p[0] + 0.5 * p[2]) / w, y = (p[1] + 0.5 * p[2]) / h;
    set_row(to_ndc, 0, x, -glm::dot(x, base));
    set_row(to_ndc, 1, y, -glm::dot(y, base));
    set_row(to_ndc, 2, Vec3(0.0), 1.0);
    set_row(to_ndc, 3, p[2], -glm::dot(p[2], base));
  }
  out.push_back(to_attribute("worldtoNDC", to_ndc));
  return out;
}

std::vector<std::filesystem::path> write_image(const Framebuffer& fb, const OutputDesc& out,
                                               const ImageMetadata& metadata, const Camera* camera) {
  if (out.image.empty()) throw std::runtime_error("no output image file given");
  if (fb.width == 0 || fb.height == 0 || fb.beauty.size() != std::size_t(fb.width) * fb.height)
    throw std::invalid_argument("write_image: empty or inconsistent framebuffer");
  if (camera && (camera->width() != fb.width || camera->height() != fb.height))
    throw std::invalid_argument("write_image: the camera's size differs from the framebuffer's");
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
  if (camera) opt.matrices = exr_camera_matrices(*camera);
  ImageWriteOptions aov_opt = opt;  // the AOV file carries the same record, not the beauty's encoding
  const std::string ext = lower_extension(out.image);
  opt.metadata.emplace_back("rayscan:exposure", shortest_text(out.exposure));
  opt.metadata.emplace_back("rayscan:transfer", ext == ".exr" ? "linear" : "sRGB");
  const float scale = static_cast<float>(std::exp2(out.exposure));
  const std::size_t n = fb.beauty.size();
  std::vector<Color> px(n);
  for (std::size_t i = 0; i < n; ++i) px[i] = fb.beauty[i] * scale;
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
  opt.matrices.clear();  // no standard place in PNG, TIFF or JPEG; rayscan:camera describes the view
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
