// The overview camera and command-line scene resolution (rayscan/jobs/quick_look.hpp).
#include "rayscan/jobs/quick_look.hpp"

#include "rayscan/base/file_names.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/render/scene_json.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/position_view.hpp"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

namespace rayscan::jobs {

using namespace rayscan::render;  // the renderer library's types, which this job speaks in
using namespace rayscan::io;

namespace {

using nlohmann::json;

}  // namespace

namespace {

/// The overview's view frame about `up`: forward f (towards the target), right r, camera up u.
struct ViewFrame {
  Vec3 f, r, u;
};

ViewFrame overview_frame(const Vec3& up, const std::optional<Vec3>& facing) {
  // "North": +y projected on the plane normal to up (+x when up is +-y); or the given facing,
  // looked along straight (bearing 0).
  const Vec3 ref = facing ? *facing : Vec3(0.0, 1.0, 0.0);
  Vec3 north = ref - glm::dot(ref, up) * up;
  if (glm::length(north) < 1e-6) north = Vec3(1.0, 0.0, 0.0) - up.x * up;
  north = glm::normalize(north);
  const Vec3 east = glm::cross(north, up);
  const double deg = std::numbers::pi / 180.0;
  const double az = facing ? 0.0 : kOverviewBearingDeg * deg, el = kOverviewPitchDeg * deg;
  ViewFrame v;
  v.f = std::cos(el) * (std::sin(az) * east + std::cos(az) * north) - std::sin(el) * up;
  v.r = glm::normalize(glm::cross(v.f, up));
  v.u = glm::cross(v.r, v.f);
  return v;
}

/// The smallest D at which every point projects inside the image when the eye is c - D f: point p
/// projects inside when |x| <= z th and |y| <= z tv with x = (p - c).r, y = (p - c).u,
/// z = (p - c).f + D.
double fit_distance(std::span<const Vec3> points, const Vec3& c, const ViewFrame& v, double th, double tv) {
  double D = 0.0;
  for (const Vec3& p : points) {
    const Vec3 d = p - c;
    const double z0 = glm::dot(d, v.f);
    D = std::max({D, std::abs(glm::dot(d, v.r)) / th - z0, std::abs(glm::dot(d, v.u)) / tv - z0});
  }
  return D;
}

/// The fmix64 finaliser of MurmurHash3: a bijective 64-bit mix, so that a point's sample key is
/// uniform whatever its coordinates' bit patterns.
constexpr std::uint64_t fmix64(std::uint64_t v) {
  v ^= v >> 33;
  v *= 0xff51afd7ed558ccdULL;
  v ^= v >> 33;
  v *= 0xc4ceb9fe1a85ec53ULL;
  return v ^ (v >> 33);
}

/// A point's sample key: a hash of its coordinates' bits, then the bits themselves (distinct
/// positions never tie). A function of the position alone, so the sample does not depend on the
/// order the points are stored in (a file's order, an index file's Morton order).
struct SampleKey {
  std::uint64_t hash = 0, x = 0, y = 0, z = 0;
  SampleKey() = default;
  explicit SampleKey(const Vec3& p)
      : x(std::bit_cast<std::uint64_t>(p.x)), y(std::bit_cast<std::uint64_t>(p.y)),
        z(std::bit_cast<std::uint64_t>(p.z)) {
    hash = fmix64(fmix64(fmix64(x) ^ y) ^ z);
  }
  auto operator<=>(const SampleKey&) const = default;
};

/// The kOverviewSample smallest of the SampleKeys added to it, in bounded memory: the candidates
/// are cut back to the smallest kOverviewSample whenever they reach twice that, and a key whose
/// hash exceeds the last cut's largest is not kept at all.
struct SmallestKeys {
  std::vector<SampleKey> kept;
  std::uint64_t cut = ~std::uint64_t{0};

  void add(const SampleKey& key) {
    if (key.hash > cut) return;
    if (kept.capacity() == 0) kept.reserve(2 * kOverviewSample);
    kept.push_back(key);
    if (kept.size() == 2 * kOverviewSample) keep_smallest();
  }
  void keep_smallest() {
    if (kept.size() <= kOverviewSample) return;
    const auto kth = kept.begin() + std::ptrdiff_t(kOverviewSample - 1);
    std::nth_element(kept.begin(), kth, kept.end());
    kept.resize(kOverviewSample);
    cut = kth->hash;  // the kOverviewSample-th smallest key
  }
};

/// The kOverviewSample points of `positions` (a span or a PositionView) with the smallest
/// SampleKey, in key order (all of them when there are fewer): a uniform random sample that is
/// the same for the same points in any order, duplicates included. One parallel pass; the
/// selection is exact, so the result does not depend on how the pass is split either.
template <class Positions>
std::vector<Vec3> order_free_sample(const Positions& positions) {
  tbb::enumerable_thread_specific<SmallestKeys> part;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, positions.size(), 1 << 16), [&](const auto& r) {
    SmallestKeys& mine = part.local();
    for (std::size_t i = r.begin(); i != r.end(); ++i) mine.add(SampleKey(positions[i]));
  });
  SmallestKeys all;
  for (const SmallestKeys& p : part)
    for (const SampleKey& key : p.kept) all.add(key);
  all.keep_smallest();
  std::sort(all.kept.begin(), all.kept.end());
  std::vector<Vec3> out;
  out.reserve(all.kept.size());
  for (const SampleKey& key : all.kept)
    out.emplace_back(std::bit_cast<double>(key.x), std::bit_cast<double>(key.y), std::bit_cast<double>(key.z));
  return out;
}

/// `v` normalised to a fixed point of glm::normalize: the scene parser normalises "up", so the
/// quick look's up axis must come back unchanged from --print-scene's JSON (the same image).
/// normalize(normalize(v)) may differ from normalize(v) in the last bit; a few rounds settle it.
Vec3 stable_unit(Vec3 v) {
  v = glm::normalize(v);
  for (int round = 0; round < 8; ++round) {
    const Vec3 w = glm::normalize(v);
    if (w == v) break;
    v = w;
  }
  return v;
}

}  // namespace

LookAtParams overview_view(std::span<const Vec3> points, const UpAxis& axis, std::uint32_t width,
                           std::uint32_t height) {
  const Vec3& up_axis = axis.up;
  if (width == 0 || height == 0) throw std::invalid_argument("overview camera: image size must be at least 1x1");
  if (points.empty()) throw std::invalid_argument("overview camera: no points to frame");
  const double up_len = glm::length(up_axis);
  if (!(up_len > 0.0) || !std::isfinite(up_len)) throw std::invalid_argument("overview camera: the up axis is zero or not finite");
  const AABB box = bounds_of(points);
  if (!std::isfinite(box.lo.x + box.lo.y + box.lo.z + box.hi.x + box.hi.y + box.hi.z))
    throw std::invalid_argument("overview camera: the points are not finite");
  const Vec3 up = up_axis / up_len;
  std::vector<Vec3> cube;
  if (box.max_extent() == 0.0) {  // one position: frame a 1-unit cube around it
    for (int k = 0; k < 8; ++k)
      cube.push_back(box.lo + Vec3((k & 1) ? 0.5 : -0.5, (k & 2) ? 0.5 : -0.5, (k & 4) ? 0.5 : -0.5));
    points = cube;
  }
  std::optional<Vec3> facing;
  if (axis.facing && glm::length(*axis.facing - glm::dot(*axis.facing, up) * up) > 1e-6) facing = axis.facing;
  const ViewFrame v = overview_frame(up, facing);
  const double tv = std::tan(0.5 * kOverviewVfovDeg * std::numbers::pi / 180.0);
  const double th = tv * double(width) / double(height);
  // Centre the projection: move the target across the view by the middle of the points'
  // projected extent, seen from the fitted distance (a few rounds: each move changes the fit).
  Vec3 c = box.center();
  for (int round = 0; round < 4; ++round) {
    const double D = fit_distance(points, c, v, th, tv);
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const Vec3& p : points) {
      const Vec3 d = p - c;
      const double z = glm::dot(d, v.f) + D;
      if (!(z > 0.0)) continue;
      const double x = glm::dot(d, v.r) / z, y = glm::dot(d, v.u) / z;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    if (!(x0 <= x1)) break;
    c += D * (0.5 * (x0 + x1) * v.r + 0.5 * (y0 + y1) * v.u);
  }
  // 2% margin. Every point then lies in front of the eye (z >= |x| / th >= 0).
  const double D = 1.02 * fit_distance(points, c, v, th, tv) + 1e-9 * box.max_extent();
  LookAtParams p;
  p.position = c - D * v.f;
  p.look_at = c;
  p.up = up;
  p.vfov_deg = kOverviewVfovDeg;
  return p;
}

LookAtParams overview_view(const AABB& bounds, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0) throw std::invalid_argument("overview camera: image size must be at least 1x1");
  const Vec3 lo = bounds.lo, hi = bounds.hi;
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) || !std::isfinite(lo.x + lo.y + lo.z + hi.x + hi.y + hi.z))
    throw std::invalid_argument("overview camera: the cloud's bounding box is empty or not finite");
  const Vec3 c = 0.5 * (lo + hi);
  Vec3 half = 0.5 * (hi - lo);
  if (glm::length(half) == 0.0) half = Vec3(0.5);
  const ViewFrame v = overview_frame(Vec3(0.0, 0.0, 1.0), std::nullopt);
  const double tv = std::tan(0.5 * kOverviewVfovDeg * std::numbers::pi / 180.0);
  const double th = tv * double(width) / double(height);
  std::array<Vec3, 8> corners;
  for (int k = 0; k < 8; ++k)
    corners[k] = c + Vec3((k & 1) ? half.x : -half.x, (k & 2) ? half.y : -half.y, (k & 4) ? half.z : -half.z);
  // 2% margin. Every corner then lies in front of the eye (z >= |x| / th >= 0), so the eye is
  // outside the box.
  const double D = 1.02 * fit_distance(corners, c, v, th, tv);
  LookAtParams p;
  p.position = c - D * v.f;
  p.look_at = c;
  p.up = Vec3(0.0, 0.0, 1.0);
  p.vfov_deg = kOverviewVfovDeg;
  return p;
}

UpAxis estimate_up_axis(std::span<const Vec3> sample, bool georeferenced, const std::optional<Vec3>& sensor) {
  if (georeferenced) return {Vec3(0.0, 0.0, 1.0), "+z (georeferenced: the CRS's vertical)", std::nullopt};
  Vec3 centroid(0.0);
  for (const Vec3& p : sample) centroid += p;
  if (!sample.empty()) centroid /= double(sample.size());
  std::optional<Vec3> facing;  // from the scanner towards the points: the scan's own view
  if (sensor && !sample.empty()) facing = centroid - *sensor;
  // A depth camera's cloud (PCD with its scanner position) is in the camera's optical frame: x
  // right, y down, z forward (ROS REP 103), and the camera is held about level: up is -y, refined
  // to the dominant plane's normal when that lies within 20 degrees (a tilted camera). The points
  // must lie ahead of it, within 45 degrees of its optical axis (+z): the identity VIEWPOINT is
  // also what every PCD writer puts in a georeferenced cloud's header (PDAL, PCL), whose points,
  // hundreds of kilometres east and north of the origin, are no camera's view.
  const bool optical = facing && facing->z > std::max(std::abs(facing->x), std::abs(facing->y));
  const auto optical_up = [&](const std::optional<Vec3>& plane_normal) -> UpAxis {
    constexpr double kCos20 = 0.93969262078590838;
    const Vec3 down(0.0, 1.0, 0.0);
    if (plane_normal && std::abs(glm::dot(*plane_normal, down)) >= kCos20) {
      const Vec3 up = stable_unit(glm::dot(*plane_normal, down) > 0.0 ? -*plane_normal : *plane_normal);
      char buf[160];
      std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f): -y of the depth camera's optical frame (y down), "
                    "refined to the dominant plane's normal", up.x, up.y, up.z);
      return {up, buf, facing};
    }
    return {-down, "-y (the depth camera's optical frame: y down, z forward)", facing};
  };
  constexpr std::size_t kMinPoints = 64, kNormals = 4096, kCandidates = 256, kNeighbours = 16;
  constexpr double kCosTol = 0.98480775301220802;  // cos(10 degrees)
  if (sample.size() < kMinPoints)
    return optical ? optical_up(std::nullopt) : UpAxis{Vec3(0.0, 0.0, 1.0), "+z (too few points to estimate it)", facing};
  // PCA normals (detail::surfel_normal, the surfels' own estimate) of up to kNormals sample points
  // from their kNeighbours nearest in the sample; an undetermined one (collinear neighbours)
  // comes back as the zero "up" passed in and is left out. Their sign does not matter here.
  const AnyIndex index = make_index(sample, IndexOptions{});
  SurfelOptions so;
  so.k_normal = kNeighbours;
  const std::size_t step = std::max<std::size_t>(1, sample.size() / kNormals);
  std::vector<Vec3> normals, at;
  visit_index(
      [&](const auto& idx) {
        for (std::size_t i = 0; i < sample.size(); i += step) {
          const std::vector<Neighbor> nb = knn(idx, sample[i], kNeighbours);
          if (nb.size() < 3) continue;
          const Vec3 n(rayscan::detail::surfel_normal(sample[i], nb, sample, so, Vec3(0.0), true, glm::vec3(0.0f)));
          if (glm::length(n) == 0.0) continue;
          normals.push_back(glm::normalize(n));
          at.push_back(sample[i]);
        }
      },
      index);
  if (normals.size() < kMinPoints)
    return optical ? optical_up(std::nullopt)
                   : UpAxis{Vec3(0.0, 0.0, 1.0), "+z (no surface orientation could be estimated)", facing};
  // The orientation (an axis: n and -n alike) shared by the most normals.
  std::size_t best_votes = 0;
  Vec3 axis(0.0, 0.0, 1.0);
  const std::size_t cstep = std::max<std::size_t>(1, normals.size() / kCandidates);
  for (std::size_t c = 0; c < normals.size(); c += cstep) {
    std::size_t votes = 0;
    for (const Vec3& n : normals) votes += std::abs(glm::dot(n, normals[c])) >= kCosTol;
    if (votes > best_votes) best_votes = votes, axis = normals[c];
  }
  const double share = double(best_votes) / double(normals.size());
  if (optical) return optical_up(share >= 0.2 ? std::optional<Vec3>(axis) : std::nullopt);
  if (share < 0.2) return {Vec3(0.0, 0.0, 1.0), "+z (no dominant plane among the points)", facing};
  // Refine: the mean of the agreeing normals, each turned to the candidate's side.
  Vec3 mean(0.0);
  std::vector<double> offsets;
  for (const Vec3& n : normals)
    if (std::abs(glm::dot(n, axis)) >= kCosTol) mean += glm::dot(n, axis) >= 0.0 ? n : -n;
  axis = stable_unit(mean);
  for (std::size_t i = 0; i < normals.size(); ++i)
    if (std::abs(glm::dot(normals[i], axis)) >= kCosTol) offsets.push_back(glm::dot(at[i], axis));
  // The most populated plane of that orientation: the mode of the offsets n . p in bins of 2% of
  // their range (the floor or the ground, with the scanner and the scene above it).
  const auto [lo_it, hi_it] = std::minmax_element(offsets.begin(), offsets.end());
  const double lo = *lo_it, span = std::max(*hi_it - lo, 1e-12);
  constexpr int kBins = 50;
  const auto bin_of = [&](double o) { return std::min(kBins - 1, int((o - lo) / span * kBins)); };
  std::array<std::size_t, kBins> bins{};
  for (double o : offsets) ++bins[bin_of(o)];
  const int mode = int(std::max_element(bins.begin(), bins.end()) - bins.begin());
  double plane = 0.0;  // the mean offset in the fullest bin: the plane itself, not its bin's centre
  for (double o : offsets)
    if (bin_of(o) == mode) plane += o;
  plane /= double(bins[mode]);
  // The scanner or the centroid tells up from down only when it lies off that plane by more than
  // the plane's thickness: 3 x the median distance of the points of that orientation from it (a
  // scan's noise), and at least 0.1% of the sample's size (rounding on a flat cloud).
  std::vector<double> dist(offsets.size());
  for (std::size_t i = 0; i < offsets.size(); ++i) dist[i] = std::abs(offsets[i] - plane);
  const auto mid = dist.begin() + std::ptrdiff_t(dist.size() / 2);
  std::nth_element(dist.begin(), mid, dist.end());
  const AABB box = bounds_of(sample);
  const double thickness = std::max(3.0 * *mid, 1e-3 * glm::length(box.hi - box.lo));
  // A VIEWPOINT at the origin is a scanner position only for a camera's view (optical): PCD
  // writers put the identity in every header, and a georeferenced cloud's origin lies anywhere.
  const bool scanner = sensor && (optical || *sensor != Vec3(0.0));
  const double above = glm::dot(scanner ? *sensor : centroid, axis) - plane;
  std::string sign;
  if (std::abs(above) > thickness) {
    if (above < 0.0) axis = -axis;
    sign = scanner ? "towards the scanner position (PCD VIEWPOINT)" : "towards the points' centroid";
  } else {
    // The points lie in that plane (a flat cloud): nothing in them tells up from down, so the
    // convention of scanners and meshes decides: +z up, else +y, else +x, i.e. the normal's
    // largest component positive (ties: z, then y, then x).
    int k = 2;
    for (const int c : {1, 0})
      if (std::abs(axis[c]) > std::abs(axis[k])) k = c;
    if (axis[k] < 0.0) axis = -axis;
    sign = std::string("its largest component (") + "xyz"[k] +
           ") positive: the points lie in that plane, with nothing to tell up from down";
  }
  const Vec3 shown = axis + Vec3(0.0);  // -0.0 printed as 0.000
  char buf[300];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f) estimated: the normal of the dominant plane (%.0f%% of the "
                "sampled normals), %s", shown.x, shown.y, shown.z, 100.0 * share, sign.c_str());
  return {axis, buf, facing};
}

namespace {

/// Whether `points` holds at least 2 distinct positions; stops at the first that differs from the
/// first point, so a scan answers at once.
bool has_distinct(const PositionView& points) {
  for (std::size_t i = 1; i < points.size(); ++i)
    if (points[i] != points[0]) return true;
  return false;
}

}  // namespace

CloudSummary summarize_cloud(std::span<const Vec3> positions, bool has_rgb, bool georeferenced,
                             const std::optional<Vec3>& sensor) {
  if (positions.empty()) throw std::invalid_argument("the point cloud has no points");
  CloudSummary s;
  s.bounds = bounds_of(positions);
  s.has_rgb = has_rgb;
  s.sample = order_free_sample(positions);
  s.up = estimate_up_axis(s.sample, georeferenced, sensor);
  s.points = positions.size();
  s.distinct = has_distinct(positions);
  return s;
}

std::optional<CloudSummary> summary_in_place(const std::filesystem::path& path) {
  if (io::is_index_file(path)) {
    io::IndexOpenOptions o;
    // The header's checks only: the positions are read once for the sample below, and the render
    // opens the file again with the full checks.
    o.verify = io::IndexOpenOptions::Verify::metadata_only;
    const io::MappedIndex m = io::MappedIndex::open(path, o);
    // The sample read in place: one pass over the stored positions, the same sample as of the
    // source cloud's points (order_free_sample does not depend on their Morton order).
    CloudSummary s;
    s.bounds = m.bounds();
    s.has_rgb = !m.rgb().empty();
    s.sample = order_free_sample(m.positions());
    s.up = estimate_up_axis(s.sample, !m.crs_wkt().empty(), std::nullopt);
    s.points = m.positions().size();
    s.distinct = has_distinct(m.positions());
    return s;
  }
  return std::nullopt;
}

bool is_cloud_input(const std::filesystem::path& input) {
  if (io::is_index_file(input)) return true;
  try {
    (void)io::format_from_extension(input);
    return true;
  } catch (const io::FormatError&) {
    return false;
  }
}

std::filesystem::path quick_look_image_name(const std::filesystem::path& cloud) {
  std::string stem = cloud.stem().string();
  if (lower_extension(stem) == ".copc") stem = std::filesystem::path(stem).stem().string();
  return stem + ".png";
}

CloudSummary summarize_cloud_file(const std::filesystem::path& file, std::optional<PointCloud>& points) {
  if (std::optional<CloudSummary> s = summary_in_place(file)) return *s;
  io::FileInfo info;
  double read_seconds = 0.0;
  if (!points) {
    const auto t0 = std::chrono::steady_clock::now();
    points = io::read_point_cloud(file, io::ReadOptions{.scalars = false}, &info);
    read_seconds = seconds_since(t0);
  }
  if (points->empty()) throw std::invalid_argument(file.string() + ": the point cloud has no points");
  std::optional<Vec3> sensor;  // a PCD VIEWPOINT's translation: where the scanner stood
  if (info.viewpoint) sensor = Vec3((*info.viewpoint)[0], (*info.viewpoint)[1], (*info.viewpoint)[2]);
  CloudSummary s = summarize_cloud(points->positions, !points->rgb.empty(), !points->crs_wkt.empty(), sensor);
  s.read_seconds = read_seconds;
  return s;
}

namespace {

/// The quick look's scene of a cloud (`cloud` "" for points in memory: no "cloud" key): its "up"
/// (the elevation ramp's and the sky's axis) is the up axis the overview camera stands on.
json quick_look_json(const std::string& cloud, const CloudSummary& summary) {
  const Vec3 up = summary.up.up + Vec3(0.0);  // -0.0 printed as 0.0
  json j = {{"radius", "auto"},
            {"primitive", "surfel"},
            {"material", {{"color", summary.has_rgb ? "rgb" : "elevation"}}},
            {"up", {up.x, up.y, up.z}}};
  if (!cloud.empty()) j["cloud"] = cloud;
  return j;
}

/// Refuses a quick look of the points `summary` describes (of the cloud `name`) when they have
/// fewer than 2 distinct positions: its surfels, or its spheres' "auto" radius, are sized from
/// their spacing. One line naming the cloud, rather than the generated scene's keys, which the
/// user never wrote.
void require_quick_look_points(const CloudSummary& summary, const std::string& name) {
  if (summary.distinct) return;
  throw std::invalid_argument(name + ": a quick look needs at least 2 distinct points, to size them from their spacing; " +
                              (summary.points == 1 ? std::string("the cloud has 1 point")
                                                   : "the cloud's " + std::to_string(summary.points) +
                                                         " points all lie at one position") +
                              " (a scene file with a numeric \"radius\" renders it)");
}

/// The common part of the resolve_* calls: scene JSON `j` parsed as if read from `as_file`
/// (errors naming `name`, "" = the file), the overview camera when it has none (from
/// `summary_of`, asked with the scene's cloud), the overrides applied.
ResolvedScene resolve_json(json j, const std::filesystem::path& as_file, const SceneParseOptions& parse,
                           const SceneOverrides& ov,
                           const std::function<const CloudSummary&(const std::filesystem::path&)>& summary_of) {
  ResolvedScene res;
  // A camera from the command line replaces the scene's, which is then not read at all.
  if (!ov.camera_file.empty() || !ov.colmap_dir.empty()) j.erase("camera");
  // Parsed once (one parser for scene files and quick looks); a scene may lack a camera here.
  res.scene = parse_scene_json(j, as_file, parse);
  SceneOverrides rest = ov;
  if (!res.scene.camera && ov.camera_file.empty() && ov.colmap_dir.empty()) {
    // The overview camera, at the size the flags ask for (fit_image_size keeps its 3:2 aspect).
    const ImageSize size = fit_image_size({kOverviewWidth, kOverviewHeight}, ov.width, ov.height);
    const CloudSummary& s = summary_of(res.scene.cloud);
    const LookAtParams p = s.sample.empty() ? overview_view(s.bounds, size.width, size.height)
                                            : overview_view(s.sample, s.up, size.width, size.height);
    res.up = s.sample.empty() ? UpAxis{} : s.up;
    res.scene.camera = Camera::look_at(p, size.width, size.height);
    res.overview = true;
    rest.width.reset();
    rest.height.reset();
  }
  res.scene.apply(rest);
  return res;
}

/// `cloud` asked at most once (the input's, or the scene's cloud's summary).
std::function<const CloudSummary&(const std::filesystem::path&)> summary_once(
    std::optional<CloudSummary>& summary, const std::function<CloudSummary(const std::filesystem::path&)>& cloud) {
  return [&summary, &cloud](const std::filesystem::path& f) -> const CloudSummary& {
    if (!summary) summary = cloud(f);
    return *summary;
  };
}

}  // namespace

ResolvedScene resolve_scene(const std::filesystem::path& input, const SceneOverrides& ov,
                            const std::function<CloudSummary(const std::filesystem::path&)>& cloud, bool cloud_given) {
  namespace fs = std::filesystem;
  // A point cloud by its extension (io::format_from_extension); anything else is read as a scene,
  // so its errors (not JSON, a device, missing) are the scene file's.
  const bool is_scene = !is_cloud_input(input);
  std::optional<CloudSummary> summary;
  const auto summary_of = summary_once(summary, cloud);
  const fs::path base = fs::absolute(input);
  json j;
  if (is_scene) {
    j = io::parse_json_file(input);
    if (!j.is_object()) io::json_fail(input.string(), "", "expected a JSON object (a scene)");
  } else {
    const CloudSummary& s = summary_of(base);
    require_quick_look_points(s, input.string());
    j = quick_look_json(base.lexically_normal().string(), s);
  }
  const fs::path as_file = is_scene ? base : base.parent_path() / (base.filename().string() + ".scene.json");
  ResolvedScene res = resolve_json(std::move(j), as_file,
                                   {.camera_required = false, .cloud_required = !cloud_given, .name = ""}, ov,
                                   summary_of);
  if (!is_scene) res.scene.file = fs::path();
  res.json = res.scene.to_json();
  return res;
}

ResolvedScene resolve_scene_text(const std::string& text, const std::string& name, const SceneOverrides& ov,
                                 const std::function<CloudSummary(const std::filesystem::path&)>& cloud,
                                 bool cloud_given) {
  const json j = io::parse_json_text(text, name);
  if (!j.is_object()) io::json_fail(name, "", "expected a JSON object (a scene)");
  std::optional<CloudSummary> summary;
  // Relative names resolve against the working directory, as those of a scene file there.
  ResolvedScene res = resolve_json(j, std::filesystem::absolute("scene.json"),
                                   {.camera_required = false, .cloud_required = !cloud_given, .name = name}, ov,
                                   summary_once(summary, cloud));
  res.scene.file = name;
  res.json = res.scene.to_json();
  return res;
}

ResolvedScene resolve_quick_look(const CloudSummary& summary, const SceneOverrides& ov, std::string_view source_label) {
  require_quick_look_points(summary, std::string(source_label));
  ResolvedScene res =
      resolve_json(quick_look_json("", summary), std::filesystem::path(),
                   {.camera_required = false, .cloud_required = false, .name = "(quick look)"}, ov,
                   [&](const std::filesystem::path&) -> const CloudSummary& { return summary; });
  res.scene.file = std::filesystem::path();
  res.json = res.scene.to_json();
  return res;
}

}  // namespace rayscan::jobs
