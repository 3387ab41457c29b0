#include "rayscan/camera/colmap.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/json_object.hpp"

#include <glm/gtc/quaternion.hpp>

#include <charconv>
#include <cmath>
#include <map>
#include <sstream>
#include <string_view>
#include <vector>

namespace rayscan::render {

namespace {

[[noreturn]] void fail(const std::filesystem::path& f, std::size_t line, const std::string& what) {
  throw io::JsonFileError(f.string() + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

// The model file as a stream, read under the input policy (a regular file, never a blocking
// open, 256 MiB cap); a missing one says which files the model needs.
std::istringstream open(const std::filesystem::path& f) {
  std::error_code ec;
  if (!std::filesystem::exists(f, ec)) fail(f, 0, "cannot open (a COLMAP text model needs cameras.txt and images.txt)");
  try {
    return std::istringstream(read_text_file(f));
  } catch (const InputFileError& e) {
    throw io::JsonFileError(e.what());
  }
}

// A whole token as a number of type T (no sign for an unsigned type, no trailing text).
template <class T>
bool parse_token(std::string_view t, T& v) {
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  return ec == std::errc() && end == t.data() + t.size();
}

struct ColmapCamera {
  std::string model;
  std::uint32_t width = 0, height = 0;
  std::vector<double> params;
};

}  // namespace

Camera load_colmap_camera(const std::filesystem::path& dir, const std::string& image_name) {
  // images.txt: two lines per image (the second, POINTS2D, may be empty); comments start with #.
  const std::filesystem::path images = dir / "images.txt";
  std::istringstream in = open(images);
  std::string line;
  std::size_t no = 0;
  bool header = true, found = false;
  double q[4], t[3];
  long cam_id = -1;
  while (std::getline(in, line)) {
    ++no;
    if (!line.empty() && line[0] == '#') continue;
    if (!header) {  // the POINTS2D line of the previous image
      header = true;
      continue;
    }
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;  // blank between images
    header = false;
    std::istringstream ls(line);
    long id;
    std::string name;
    if (!(ls >> id >> q[0] >> q[1] >> q[2] >> q[3] >> t[0] >> t[1] >> t[2] >> cam_id >> name))
      fail(images, no, "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    if (name == image_name) {
      found = true;
      break;
    }
  }
  if (!found) fail(images, 0, "no image named '" + image_name + "'");
  const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(qn > 0.0) || !std::isfinite(qn)) fail(images, no, "expected a non-zero quaternion QW QX QY QZ");

  const std::filesystem::path cameras = dir / "cameras.txt";
  std::istringstream cin_ = open(cameras);
  ColmapCamera cam;
  bool have = false;
  std::size_t cno = 0;
  while (std::getline(cin_, line)) {
    ++cno;
    if (line.empty() || line[0] == '#' || line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    long id;
    std::string width, height;
    if (!(ls >> id >> cam.model >> width >> height))
      fail(cameras, cno, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
    if (id != cam_id) continue;
    // Each field as a whole token: a stream would read "-8" as an unsigned 2^32 - 8 and stop at
    // "nan", leaving the parameters after it uncounted.
    const auto size = [&](const std::string& t, const char* name) {
      std::uint32_t v = 0;
      if (!parse_token(t, v) || v < 1 || v > kMaxImageSide)
        fail(cameras, cno, std::string(name) + " '" + one_line(t) + "': expected an integer in [1, 65536] (pixels)");
      return v;
    };
    cam.width = size(width, "WIDTH");
    cam.height = size(height, "HEIGHT");
    for (std::string t; ls >> t;) {
      double v = 0.0;
      if (!parse_token(t, v) || !std::isfinite(v))
        fail(cameras, cno, "model " + cam.model + ": parameter " + std::to_string(cam.params.size() + 1) + " '" +
                               one_line(t) + "': expected a finite number");
      cam.params.push_back(v);
    }
    have = true;
    break;
  }
  if (!have) fail(cameras, 0, "no camera with CAMERA_ID " + std::to_string(cam_id) + " (image '" + image_name + "')");
  const std::map<std::string, std::size_t> nparams{
      {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4}, {"SIMPLE_RADIAL", 4}, {"RADIAL", 5}, {"OPENCV", 8}};
  const auto it = nparams.find(cam.model);
  if (it == nparams.end())
    fail(cameras, cno, "model " + cam.model + ": expected SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL or OPENCV");
  if (cam.params.size() != it->second)
    fail(cameras, cno, "model " + cam.model + ": expected " + std::to_string(it->second) + " parameters, got " +
                           std::to_string(cam.params.size()));
  const auto& p = cam.params;
  double fx, fy, cx, cy;
  LensDistortion k;
  if (cam.model == "SIMPLE_PINHOLE" || cam.model == "SIMPLE_RADIAL" || cam.model == "RADIAL") {
    fx = fy = p[0];
    cx = p[1];
    cy = p[2];
    if (cam.model == "SIMPLE_RADIAL") k.k1 = p[3];
    if (cam.model == "RADIAL") { k.k1 = p[3]; k.k2 = p[4]; }
  } else {
    fx = p[0]; fy = p[1]; cx = p[2]; cy = p[3];
    if (cam.model == "OPENCV") { k.k1 = p[4]; k.k2 = p[5]; k.p1 = p[6]; k.p2 = p[7]; }
  }
  PinholeParams pp;
  pp.K = {{{fx, 0.0, cx - 0.5}, {0.0, fy, cy - 0.5}, {0.0, 0.0, 1.0}}};
  const glm::dquat quat(q[0] / qn, q[1] / qn, q[2] / qn, q[3] / qn);  // glm: (w, x, y, z)
  const glm::dmat3 R = glm::mat3_cast(quat);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) pp.R[r][c] = R[c][r];
  pp.t = Vec3(t[0], t[1], t[2]);
  try {
    return k.any() ? Camera::pinhole_distorted(pp, k, cam.width, cam.height)
                   : Camera::pinhole(pp, cam.width, cam.height);
  } catch (const std::invalid_argument& e) {
    fail(cameras, cno, e.what());
  }
}

}  // namespace rayscan::render
