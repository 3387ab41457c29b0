// The render job (rayscan/jobs/render.hpp): what `rayscan render` and rayscan.render() run.
#include "rayscan/jobs/render.hpp"

#include "cloud_site.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/json_object.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/camera/camera_file.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/jobs/info.hpp"
#include "rayscan/jobs/memory_source.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/point_reader.hpp"
#include "rayscan/render/material.hpp"
#include "rayscan/render/surfel_setup.hpp"
#include "rayscan/base/work_distributor.hpp"
#include "rayscan/analysis/geotiff.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include <sys/resource.h>
#include <unistd.h>

namespace rayscan::jobs {

using namespace rayscan::render;  // the renderer library's types, which this job speaks in
using namespace rayscan::io;

namespace {

std::string num17(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// True in one process and on the root of several (the process that writes the image).
bool is_root(const JobControl& ctl) { return !ctl.distributor || ctl.distributor->is_root(); }

// The memory this process can allocate and how a message names it: the machine's physical memory
// (sysconf) or, when lower, the process's address-space limit (RLIMIT_AS, `ulimit -v`), which
// fails any allocation past it whatever the machine holds. bytes 0 when the system does not say.
struct MemoryLimit {
  std::uint64_t bytes = 0;
  bool address_space = false;  // the limit is RLIMIT_AS, not the physical memory
};
MemoryLimit memory_limit() {
  MemoryLimit m;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages > 0 && page > 0) m.bytes = std::uint64_t(pages) * std::uint64_t(page);
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY && (m.bytes == 0 || as.rlim_cur < m.bytes)) {
    m.bytes = std::uint64_t(as.rlim_cur);
    m.address_space = true;
  }
  return m;
}

// Bytes per pixel that a render of `aovs` holds at its peak: the framebuffer (beauty 12, depth 4,
// normal 12, position 12, index 4, albedo 12 + coverage 4, cost 4; render::Framebuffer) and, when the image is
// written to `image`, render::write_image's copies beside it: the exposure-scaled beauty (12) and
// the float image of the larger file it interleaves (4 per channel, the index as 4-byte ids; an
// .exr holds beauty and AOVs in one file, other formats beauty, then the AOVs apart). The points,
// the index and the image library's encoder buffers are not counted: a lower bound.
std::uint64_t render_bytes_per_pixel(std::span<const Aov> aovs, bool write, const std::filesystem::path& image) {
  std::uint64_t fb = 12, aov_channels = 0;  // float AOV channels, as write_image interleaves them
  bool index = false;
  for (Aov a : aovs) switch (a) {
      case Aov::depth: fb += 4, aov_channels += 1; break;
      case Aov::normal: fb += 12, aov_channels += 3; break;
      case Aov::position: fb += 12, aov_channels += 3; break;
      case Aov::index: fb += 4, index = true; break;
      case Aov::albedo: fb += 16, aov_channels += 3; break;
      case Aov::cost: fb += 4, aov_channels += 1; break;
    }
  if (!write) return fb;
  const std::uint64_t aov_image = 4 * aov_channels + (index ? 4 : 0);
  const std::uint64_t file_image = lower_extension(image) == ".exr" ? 12 + aov_image : std::max<std::uint64_t>(12, aov_image);
  return fb + 12 + file_image;
}

// Refuses, before anything is allocated, an image whose buffers (render_bytes_per_pixel) exceed
// the memory this process can allocate (check_image_memory). Throws OptionError "...; give a
// smaller " + `remedy`: by default the width or height; a job whose image size follows from
// another option (the ortho map's cell) names that one.
void check_render_memory(std::uint32_t width, std::uint32_t height, std::span<const Aov> aovs, bool write,
                         const std::filesystem::path& image,
                         std::vector<OptionError::Part> remedy = {option("width"), " or ", option("height")}) {
  check_image_memory(width, height, render_bytes_per_pixel(aovs, write, image), std::move(remedy), "",
                     aovs.empty() ? "" : " with AOVs");
}

// As above for `camera`'s image.
void check_render_memory(const Camera& camera, std::span<const Aov> aovs, bool write, const std::filesystem::path& image,
                         std::vector<OptionError::Part> remedy = {option("width"), " or ", option("height")}) {
  check_render_memory(camera.width(), camera.height(), aovs, write, image, std::move(remedy));
}

}  // namespace

void check_image_memory(std::uint32_t width, std::uint32_t height, std::uint64_t bytes_per_pixel,
                        std::vector<OptionError::Part> remedy, const std::string& lead, const std::string& detail) {
  const MemoryLimit have = memory_limit();
  if (have.bytes == 0) return;
  const double need = double(width) * double(height) * double(bytes_per_pixel);
  if (need <= double(have.bytes)) return;
  const double gib = double(std::uint64_t{1} << 30);
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%san image of %u x %u pixels%s needs about %.1f GiB of buffers, more than %s%.1f GiB%s; give a "
                "smaller ",
                lead.c_str(), unsigned(width), unsigned(height), detail.c_str(), need / gib,
                have.address_space ? "the " : "this machine's ", double(have.bytes) / gib,
                have.address_space ? " of address space this process may use (ulimit -v)" : " of memory");
  remedy.insert(remedy.begin(), std::string(buf));
  throw OptionError(std::move(remedy));
}

namespace {

// What the elevation colours mean, logged when the material colours by elevation (a quick look of
// a cloud without colours): the axis, the ramp and the heights at its ends (AlbedoRule::range),
// in the CRS's height unit as the DSM's band names it (analysis::crs_height_unit: a compound
// CRS's vertical unit, metre for EPSG:2992+5703 whose horizontal unit is foot), "world units"
// without a CRS, e.g. "colour: elevation along up (0, 0, 1), viridis, 408.73 (dark) .. 485.04
// (bright) metre, the 2nd and 98th percentiles of the points' heights". Along +z the heights are
// the points' z. Along any other axis (a quick look's estimated up without a CRS) p . up is no
// height to read against the points: for a cloud far from the origin a tilt of a fraction of a
// degree shifts it by thousands of units. The ends are then given as heights above the lowest
// point along that axis; a material's own range is given as written.
void log_elevation_ramp(const JobControl& ctl, const Scene& scene, const AlbedoRule& rule, const std::string& crs_wkt) {
  if (scene.material.mode != ColorMode::elevation) return;
  const std::string unit = analysis::crs_height_unit(crs_wkt);
  const Vec3 up = glm::normalize(scene.up) + Vec3(0.0);  // -0.0 printed as 0
  const char* ramp = ramp_names()[std::size_t(scene.material.ramp)].c_str();
  const std::array<double, 2> ends = rule.range();
  char buf[512];
  if (up == Vec3(0.0, 0.0, 1.0) || scene.material.range || !std::isfinite(rule.lowest()))
    std::snprintf(buf, sizeof buf, "colour: elevation along up (%.3g, %.3g, %.3g), %s, %.7g (dark) .. %.7g (bright) %s, %s",
                  up.x, up.y, up.z, ramp, ends[0], ends[1], unit.c_str(),
                  scene.material.range ? "the material's range" : "the 2nd and 98th percentiles of the points' heights");
  else
    std::snprintf(buf, sizeof buf,
                  "colour: height above the lowest point along up (%.3g, %.3g, %.3g), %s, %.7g (dark) .. %.7g (bright) %s, "
                  "the 2nd and 98th percentiles of the points' heights along that axis",
                  up.x, up.y, up.z, ramp, ends[0] - rule.lowest(), ends[1] - rule.lowest(), unit.c_str());
  ctl.info(buf);
}

// What every frame of a render job shares: the scene, the cloud or the mapped index file, the
// albedo, the index and the radius. Heap-allocated (spans into `owned`, `albedo`, `rule` must not
// move).
struct Prepared {
  Scene scene;
  std::optional<Site> site;           // the points and their index (in memory, index file or COPC)
  PointCloud owned;                   // the read cloud (or, for surfels over an index file, its points)
  const PointCloud* cloud = nullptr;  // points in original order; null when tracing straight from a file
  std::vector<Color> albedo;          // by original index (in-memory clouds, surfel mode)
  AlbedoRule rule;                    // the material's statistics; applied at shading time to a file traced in place
  AlbedoSource albedo_source;
  std::uint32_t albedo_samples = 1;   // RenderJobOptions::albedo_samples
  SurfelAttributes surfels;           // estimated here; left empty when RenderJobOptions::surfels are traced
  const SurfelAttributes* discs = &surfels;  // the discs traced: `surfels` or RenderJobOptions::surfels
  std::chrono::steady_clock::time_point started;  // job start (time to the first traced tile)
};

// The points' reach (RenderJobOptions::after_trace): no farther from its point is a primitive hit,
// the sphere radius or, for surfels, the largest disc radius. Set once prepare() chose the radius.
double primitive_reach(const Prepared& P, const RenderJobResult& r) {
  return P.scene.primitive == Primitive::surfel ? P.discs->max_radius : r.radius.radius;
}

// The COPC half of prepare(): albedo rule from one streamed pass of the statistics it needs (none
// for constant/classification/ranged modes; rgb stops at the first non-zero colour), the auto
// radius from a few nodes' samples (median_nn_spacing of the site), the exact bounds for camera_for_cloud by
// one streamed pass over the positions. Memory stays within the cache budget.

void prepare_copc(Prepared& P, const RenderJobOptions& o, RenderJobResult& r) {
  Scene& scene = P.scene;
  const std::string f = scene.file.empty() ? std::string("(scene)") : scene.file.string();
  const JobControl& ctl = o.control;
  io::CopcIndex& copc = *P.site->copc();
  char buf[512];
  r.crs_wkt = io::open_point_reader(scene.cloud, io::AttributeSet::none())->crs_wkt();
  if (o.crs_read) o.crs_read(r.crs_wkt);
  AABB bounds;  // first: bounds_read's checks come before the statistics and the radius
  if (o.bounds_read || o.camera_for_cloud) {
    copc.scan(0, [&](const io::CopcIndex::NodeBlock& k) {
      bounds.expand(bounds_of(k.positions));
      return true;
    });
    if (o.bounds_read) o.bounds_read(bounds);
  }
  auto t0 = std::chrono::steady_clock::now();
  const ColorMode mode = scene.material.mode;
  const unsigned attrs = mode == ColorMode::rgb              ? io::CopcIndex::kRgb
                         : mode == ColorMode::intensity      ? io::CopcIndex::kIntensity
                         : mode == ColorMode::classification ? io::CopcIndex::kClassification
                                                             : 0u;
  copc.set_attributes(attrs);
  AlbedoStream stream;
  stream.points = r.points;
  stream.rgb = copc.has_rgb();
  stream.intensity = stream.classification = true;  // PDRF 6-8 (COPC) always carry both
  stream.blocks = [&](const std::function<bool(const AlbedoAttributes&)>& each) {
    copc.scan(attrs, [&](const io::CopcIndex::NodeBlock& k) {
      return each(AlbedoAttributes{k.positions, k.rgb, k.intensity, k.classification});
    });
  };
  try {
    P.rule = AlbedoRule(stream, scene.material, scene.up);
  } catch (const std::invalid_argument& e) {
    throw SceneError(f + ": /material/color: " + e.what());
  }
  log_elevation_ramp(ctl, scene, P.rule, r.crs_wkt);
  const AlbedoAttributes slots{copc.positions(), copc.rgb(), copc.intensity(), copc.classification()};
  P.albedo_source = {{}, &P.rule, slots, copc.positions().size()};
  std::snprintf(buf, sizeof buf, "albedo at shading time from the decoded node attributes (statistics in %.2f s)",
                seconds_since(t0));
  ctl.info(buf);
  t0 = std::chrono::steady_clock::now();
  try {
    r.radius = choose_radius(scene.radius, scene.auto_radius_factor,
                             [&] { return median_nn_spacing(*P.site, {}); });  // kCopcSpacingSamples samples
  } catch (const std::invalid_argument& e) {
    throw SceneError(f + ": /radius: " + e.what());
  }
  if (r.radius.automatic) {
    std::snprintf(buf, sizeof buf,
                  "radius auto: median nearest-neighbour spacing %.6g (%zu samples from at most 64 nodes) x factor %.3g = "
                  "%.6g (%.2f s)",
                  r.radius.spacing, kCopcSpacingSamples, r.radius.factor, r.radius.radius, seconds_since(t0));
    ctl.info(buf);
  }
  if (o.camera_for_cloud) {
    scene.camera = o.camera_for_cloud(bounds, primitive_reach(P, r));
    check_render_memory(*scene.camera, scene.output.aovs, o.write && is_root(o.control), scene.output.image);
  }
  copc.trim_cache();
}

// Reads the cloud (or maps the index file), sets up the albedo, builds the index and chooses
// the radius; fills r.points, read/index seconds, radius, crs. (run_render's first half.)
//
// An index file (.rsi) in sphere mode is traced straight from the mapping: no copy of its points.
// The only passes over all points before tracing are whole-cloud statistics the image depends
// on: the 8-bit colour test of material "rgb" (stops at the first channel > 255), the percentile
// range of intensity/elevation without a "range", the original-order samples of the auto radius
// (one read of the 4-byte id section), and the exact bounds of an ortho map. Surfel mode still
// copies the points to original order (MappedIndex::to_point_cloud) for the disc estimate.
std::unique_ptr<Prepared> prepare(const RenderJobOptions& o, RenderJobResult& r) {
  auto P = std::make_unique<Prepared>();
  const double read_before = o.cloud && o.cloud_read_from_scene ? std::max(0.0, o.cloud_read_seconds) : 0.0;
  P->started = std::chrono::steady_clock::now() -
               std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(read_before));
  P->scene = o.scene;  // small: the camera may be replaced by camera_for_cloud
  P->albedo_samples = o.albedo_samples;
  Scene& scene = P->scene;
  const std::string f = scene.file.empty() ? std::string("(scene)") : scene.file.string();
  if (!scene.camera && !o.camera_for_cloud) throw SceneError(f + ": /camera: not set; give a camera in the scene or a camera file");
  if (o.site && (!o.cloud || o.site->size() != o.cloud->size()))
    throw std::invalid_argument("render: options.site needs options.cloud, the points it indexes");
  if (o.write && scene.output.image.empty())
    throw OptionError({f + ": /output/image: not set; give it in the scene or set the ", option("out"), " option"});
  if (o.write) {
    load_image_io();  // the image writer, before the render rather than after it
    const std::filesystem::path out[] = {scene.output.image}, in[] = {scene.cloud, scene.file};
    require_outputs(out, in);
  }
  // The image's size is known before the cloud is read unless the camera follows from its bounds.
  if (!o.camera_for_cloud) check_render_memory(*scene.camera, scene.output.aovs, o.write && is_root(o.control), scene.output.image);
  const JobControl& ctl = o.control;
  char buf[512];

  // Only positions, colour, intensity and classification are used: skip the other scalars.
  auto t0 = std::chrono::steady_clock::now();
  PointCloud& owned = P->owned;
  const bool surfel = scene.primitive == Primitive::surfel;
  const auto no_points = [&] { return SceneError(f + ": /cloud: the point cloud has no points"); };
  // A COPC file in sphere mode is traced in place (prepare_copc); surfels read it whole below.
  const bool in_place =
      !o.cloud && (io::is_index_file(scene.cloud) || (!surfel && io::is_copc_file(scene.cloud)));
  const io::MappedIndex* mapped = nullptr;
  if (in_place) {
    SiteOptions so;
    so.index_file.read_ahead = true;  // a render touches most of the file: read it ahead, nodes first
    so.copc_cache_bytes = o.cache_bytes;
    SiteOpenTimes times;
    P->site.emplace(Site::open(scene.cloud, so, &times));
    if (P->site->empty()) throw no_points();
    r.read_seconds = times.read_seconds;
    if (io::CopcIndex* copc = P->site->copc()) {
      r.points = copc->info().point_count;
      std::snprintf(buf, sizeof buf,
                    "COPC file %s: %zu points, %zu nodes, hierarchy read in %.2f s (nodes decoded as rays reach them)",
                    scene.cloud.string().c_str(), r.points, copc->node_count(), r.read_seconds);
      ctl.info(buf);
      prepare_copc(*P, o, r);
      return P;
    }
    mapped = P->site->index_file();
    if (surfel) owned = mapped->to_point_cloud();  // disc centres and estimate by original index
  } else if (!o.cloud) {
    owned = load_cloud(scene, io::ReadOptions{.scalars = false});
  } else if (o.cloud->empty()) {
    throw no_points();
  }
  if (o.cloud) P->cloud = o.cloud;
  else if (!mapped || surfel) P->cloud = &owned;
  const PointCloud* cloud = P->cloud;
  r.points = mapped ? mapped->positions().size() : cloud->size();
  if (!in_place) r.read_seconds = o.cloud ? read_before : seconds_since(t0);
  if (mapped)
    std::snprintf(buf, sizeof buf, "mapped index file %s: %zu points, %zu nodes, in %.2f s%s", scene.cloud.string().c_str(),
                  r.points, static_cast<std::size_t>(mapped->node_count()), r.read_seconds,
                  cloud ? " (points copied to original order for surfels)" : "");
  else
    std::snprintf(buf, sizeof buf, "read %zu points from %s in %.2f s", r.points, scene.cloud.string().c_str(),
                  r.read_seconds);
  if (!o.cloud || o.cloud_read_from_scene) ctl.info(buf);
  r.crs_wkt = mapped ? mapped->crs_wkt() : cloud->crs_wkt;
  if (o.crs_read) o.crs_read(r.crs_wkt);
  AABB bounds;  // once, for both hooks
  if (o.bounds_read || o.camera_for_cloud) {
    bounds = cloud ? bounds_of(cloud->positions) : mapped->bounds();  // an index file stores them: no pass
    if (o.bounds_read) o.bounds_read(bounds);
  }
  t0 = std::chrono::steady_clock::now();
  try {
    if (cloud) {
      P->rule = AlbedoRule(albedo_attributes(*cloud), cloud->size(), scene.material, scene.up);
      P->albedo = compute_albedo(*cloud, P->rule);
      P->albedo_source.by_index = P->albedo;
    } else {
      const AlbedoAttributes slots{mapped->positions(), mapped->rgb(), mapped->intensity(), mapped->classification()};
      P->rule = AlbedoRule(slots, r.points, scene.material, scene.up);
      P->albedo_source = {{}, &P->rule, slots, r.points};
    }
  } catch (const std::invalid_argument& e) {
    throw SceneError(f + ": /material/color: " + e.what());
  }
  log_elevation_ramp(ctl, scene, P->rule, r.crs_wkt);
  if (mapped && !cloud) {
    std::snprintf(buf, sizeof buf, "albedo at shading time from the stored attributes (statistics in %.2f s)",
                  seconds_since(t0));
    ctl.info(buf);
  }
  t0 = std::chrono::steady_clock::now();
  if (o.site) {
    P->site.emplace(*o.site);  // the caller's index over `cloud`: none built
  } else if (!mapped) {
    try {
      P->site.emplace(Site::over(*cloud, scene.index));
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /index: " + e.what());
    }
    r.index_seconds = seconds_since(t0);
    std::snprintf(buf, sizeof buf, "built %s index in %.2f s", scene.index.type.c_str(), r.index_seconds);
    ctl.info(buf);
  }
  const Site& site = *P->site;
  SurfelAttributes& surfels = P->surfels;
  if (surfel && o.surfels) {
    if (o.surfels->normals.size() != cloud->size() || o.surfels->radii.size() != cloud->size())
      throw std::invalid_argument("render: options.surfels has not one normal and radius a point of options.cloud");
    P->discs = o.surfels;
    r.radius.radius = o.surfels->median_radius;
    std::snprintf(buf, sizeof buf, "surfels: the caller's, median radius %.6g, max %.6g (none estimated)",
                  o.surfels->median_radius, o.surfels->max_radius);
    ctl.info(buf);
  } else if (surfel) {
    // Surfel normals and radii: kNN over the mapped or the built in-memory index (scene_surfels),
    // with the estimate's progress on stderr.
    t0 = std::chrono::steady_clock::now();
    try {
      detail::SurfelBar bar(cloud->size(), ctl);
      surfels = scene_surfels(scene, site, *cloud, bar.callback());
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /surfel: " + e.what());
    }
    r.radius.radius = surfels.median_radius;
    const std::string normals = cloud->normals.empty()
                                    ? "by PCA over " + std::to_string(scene.surfel.k_normal) + " neighbours"
                                    : std::string("from the file");
    std::snprintf(buf, sizeof buf,
                  "surfels: normals %s, radius %.3g x distance to neighbour %u: median %.6g, max %.6g "
                  "(clamped to %.3g x median), in %.2f s",
                  normals.c_str(), scene.surfel.radius_factor, scene.surfel.k_radius, surfels.median_radius,
                  surfels.max_radius, scene.surfel.max_radius_factor, seconds_since(t0));
    ctl.info(buf);
  } else {
    t0 = std::chrono::steady_clock::now();
    try {
      r.radius = choose_radius(scene.radius, scene.auto_radius_factor, [&] {
        return median_nn_spacing(site, cloud ? std::span<const Vec3>(cloud->positions) : std::span<const Vec3>{});
      });
    } catch (const std::invalid_argument& e) {
      throw SceneError(f + ": /radius: " + e.what());
    }
    if (r.radius.automatic) {
      std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x factor %.3g = %.6g (%.2f s)",
                    r.radius.spacing, r.radius.factor, r.radius.radius, seconds_since(t0));
      ctl.info(buf);
    }
  }
  if (o.camera_for_cloud) {  // once the reach is known: a map's rays start above it
    scene.camera = o.camera_for_cloud(bounds, primitive_reach(*P, r));
    check_render_memory(*scene.camera, scene.output.aovs, o.write && is_root(ctl), scene.output.image);
  }

  return P;
}

// Traces one camera's image over the prepared scene (run_render's second half).
RenderStats render_camera(const Prepared& P, const Camera& camera, const JobControl& ctl, double radius,
                          Framebuffer& image, bool distribute) {
  Scene scene = P.scene;
  scene.camera = camera;
  RenderSettings settings =
      make_settings(scene, P.cloud ? std::span<const Vec3>(P.cloud->positions) : std::span<const Vec3>{}, {}, radius);
  settings.integrator.albedo = P.albedo_source;
  settings.albedo_samples = P.albedo_samples;
  if (scene.primitive == Primitive::surfel) use_surfels(settings, *P.discs);
  const Camera& cam = settings.camera;
  const std::uint64_t tiles = std::uint64_t((cam.width() + 15) / 16) * ((cam.height() + 15) / 16);
  Progress progress(tiles, ctl.progress);
  RenderOptions ropt;
  ropt.threads = ctl.threads;
  ropt.progress = &progress;
  ropt.distributor = distribute ? ctl.distributor : nullptr;
  ropt.cancel = ctl.cancel;
  return render_image(*P.site, settings, image, ropt);
}

// The image header's record of a render (scenes/README.md, "Image metadata"): the scene file
// (none for a quick look), the cloud file as an absolute path (kMemorySource for points given in
// memory that are not scene.cloud's, RenderJobOptions::cloud_read_from_scene), the samples per
// pixel of the image's product (a map of albedo's: RenderJobOptions::albedo_map), the camera the
// image was traced through as camera-file JSON (none for a top-down map's grid, which the
// GeoTIFF's georeferencing describes) and the file it came from, if any.
ImageMetadata render_metadata(const RenderJobOptions& o, const Scene& scene, const RenderJobResult& r,
                              const Camera* camera, const std::filesystem::path& camera_file) {
  const auto absolute = [](const std::filesystem::path& p) {
    return std::filesystem::absolute(p).lexically_normal().string();
  };
  ImageMetadata m;
  if (!scene.file.empty()) m.emplace_back("rayscan:scene", scene.file.string());
  const bool file = !scene.cloud.empty() && (!o.cloud || o.cloud_read_from_scene);
  m.emplace_back("rayscan:cloud", file ? absolute(scene.cloud) : std::string(kMemorySource));
  m.emplace_back("rayscan:spp", std::to_string(o.albedo_map ? o.albedo_samples : scene.spp));
  m.emplace_back("rayscan:seed", std::to_string(scene.seed));
  m.emplace_back("rayscan:radius", num17(r.radius.radius));
  m.emplace_back("rayscan:primitive", scene.primitive == Primitive::surfel ? "surfel" : "sphere");
  // No render time in the file: two renders of the same scene and seed are identical
  // byte for byte (`cmp`); the time is in RenderJobResult::stats and the log.
  if (camera && camera->description().model != CameraModel::orthographic_grid)
    m.emplace_back("rayscan:camera", io::camera_to_json(*camera).dump());
  if (!camera_file.empty()) m.emplace_back("rayscan:camera_file", absolute(camera_file));
  return m;
}

// The stats line of a render. `albedo_rays` (0 = not a map of albedo) are an ortho map's rays per
// cell for its colour (RenderSettings::albedo_samples), the map's own count, stated first; the
// beauty's spp and the AOV ray follow, so that the primary rays add up: spp + 1 AOV ray, + the
// albedo rays when above 1 (one albedo ray is the AOV ray).
void log_stats(const JobControl& ctl, const RenderStats& st, const Camera& cam, std::uint32_t spp,
               std::uint32_t albedo_rays, const char* what) {
  std::string per_pixel = std::to_string(spp) + " spp";
  if (albedo_rays > 1) per_pixel = count_text(albedo_rays, "albedo ray") + " per px (and " + per_pixel + ", 1 AOV ray)";
  else if (albedo_rays == 1) per_pixel = "1 albedo ray per px (the AOV ray; and " + per_pixel + ")";
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s%.2f s, %u threads, %llux%llu px, %s, %llu primary rays, %llu ray queries, "
                "%.3g queries/s (%.3g per thread), %.3g nodes and %.3g points visited per query",
                what, st.seconds, st.threads, (unsigned long long)cam.width(), (unsigned long long)cam.height(),
                per_pixel.c_str(), (unsigned long long)st.primary_rays, (unsigned long long)st.queries,
                double(st.queries) / st.seconds,
                double(st.queries) / st.seconds / st.threads,
                st.queries ? double(st.nodes_visited) / double(st.queries) : 0.0,
                st.queries ? double(st.points_tested) / double(st.queries) : 0.0);
  ctl.info(buf);
}

}  // namespace

RenderJobResult run_render(const RenderJobOptions& o) {
  RenderJobResult r;
  const std::unique_ptr<Prepared> P = prepare(o, r);
  const Scene& scene = P->scene;
  const JobControl& ctl = o.control;
  const double prepared = seconds_since(P->started);
  r.stats = render_camera(*P, *scene.camera, ctl, r.radius.radius, r.image, true);
  if (const io::CopcIndex* copc = P->site->copc()) {
    r.copc_decodes = copc->decodes();
    r.copc_peak_cache_bytes = copc->peak_resident_bytes();
    ctl.info(detail::copc_cache_report(*copc));
  }
  r.first_tile_seconds = prepared + r.stats.first_tile_seconds;
  char buf[160];
  std::snprintf(buf, sizeof buf, "first tile traced %.2f s after the start (%.2f s to set up, %.2f s of tracing)",
                r.first_tile_seconds, prepared, r.stats.first_tile_seconds);
  ctl.info(buf);
  if (o.after_trace && is_root(ctl)) o.after_trace(*P->site, primitive_reach(*P, r), r.image);
  // A camera from camera_for_cloud (a map's grid) is not the scene's camera file's.
  r.metadata = render_metadata(o, scene, r, &*scene.camera,
                               o.camera_for_cloud ? std::filesystem::path() : scene.camera_file);
  if (o.write && !scene.output.image.empty() && is_root(ctl))
    r.written = write_image(r.image, scene.output, r.metadata, &*scene.camera);
  log_stats(ctl, r.stats, *scene.camera, scene.spp, o.albedo_map ? o.albedo_samples : 0, "");
  return r;
}

OrthoMapJobResult run_ortho_map(const OrthoMapJobOptions& o) {
  const double res = o.ortho_map;
  if (!(res > 0.0) || !std::isfinite(res))
    throw OptionError({option("ortho_map"), ": expected a finite number > 0 (world units per pixel), got " + num17(res)});
  if (o.render.camera_for_cloud)
    throw std::invalid_argument("ortho map: render.camera_for_cloud is set; the job sets it to the map's camera");
  if (o.render.bounds_read)
    throw std::invalid_argument("ortho map: render.bounds_read is set; the job sets it to check the map's grid");
  if (o.render.crs_read)
    throw std::invalid_argument("ortho map: render.crs_read is set; the job sets it to check the GeoTIFFs' CRS");
  RenderJobOptions job = o.render;
  // The map's camera looks straight down -z in the cloud's frame, so the sky gradient, the
  // elevation ramp and surfels oriented "up" run along +z whatever the scene's up: a quick look's
  // up axis, estimated for a cloud without a CRS, may point elsewhere, and its sky would then
  // light the map from below. (A sun keeps the direction the scene gave it.)
  job.scene.up = Vec3(0.0, 0.0, 1.0);
  // Surfels oriented towards "the camera" face +z, the side the map's parallel rays come from (its
  // camera is built once the discs' reach is known, after their estimate).
  job.scene.surfel_orient_camera = false;
  const std::filesystem::path image = job.scene.output.image;
  if (job.write) {
    if (!analysis::is_geotiff_name(image))
      throw OptionError({option("ortho_map"), ": ", option("out"),
                         " '" + image.string() + "': " + extensions_expected(analysis::geotiff_extensions()) + " (GeoTIFF)"});
    if (!o.dsm.empty() && !analysis::is_geotiff_name(o.dsm))
      throw OptionError({option("dsm"), " '" + o.dsm.string() + "': " + extensions_expected(analysis::geotiff_extensions())});
    // The map's files are written here (analysis::write_ortho_map), not by run_render: checked
    // before the render, as run_render checks its image.
    std::vector<std::filesystem::path> outs{image};
    if (!o.dsm.empty()) outs.push_back(o.dsm);
    const std::filesystem::path ins[] = {job.scene.cloud, job.scene.file};
    require_outputs(outs, ins);
    // The GeoTIFFs carry the cloud's CRS: one GDAL cannot read is refused naming the input, from
    // the header before any point is read where the format has one, else as soon as the points
    // are (crs_read), rather than by the writer after the render.
    const bool from_file = !job.scene.cloud.empty() && (!job.cloud || job.cloud_read_from_scene);
    const std::string source = from_file ? job.scene.cloud.string() : std::string(kMemorySource);
    if (job.cloud || from_file) detail::require_readable_header_crs(job.scene.cloud, job.cloud, source);
    job.crs_read = [source](const std::string& wkt) { io::require_readable_crs(source, wkt); };
  }
  job.write = false;
  const bool albedo = o.ortho_colour == analysis::OrthoColour::albedo;
  std::vector<Aov>& aovs = job.scene.output.aovs;
  for (const Aov a : {Aov::depth, Aov::albedo})
    if ((a == Aov::depth || albedo) && std::find(aovs.begin(), aovs.end(), a) == aovs.end()) aovs.push_back(a);
  const std::uint32_t albedo_samples = job.scene.spp;
  job.albedo_map = albedo;
  if (albedo) {
    // The depth AOV is traced by its own ray through each cell centre (the DSM's elevation), the
    // albedo by the scene's spp stratified rays per cell, averaged over those that hit: the
    // cell's mean colour, like a GIS rasterizer's mean of the cell's points, where one ray would
    // show whichever colour lies under the centre; the share that hit is the alpha band. The
    // beauty is not used, so it gets the least light transport the renderer allows.
    job.albedo_samples = albedo_samples;
    job.scene.spp = 1;
    job.scene.max_depth = 1;
  }
  OrthoMapJobResult r;
  r.ortho_colour = o.ortho_colour;
  AABB cloud_bounds;  // for the CRS's plausibility (crs_warnings)
  // The map's grid, its side limit and its memory follow from the bounds and the cell alone (not
  // from the reach): checked once, as soon as the cloud is read, before the index and the
  // primitives. run_render passes camera_for_cloud the same bounds it gave bounds_read, so the
  // camera below needs no second check.
  job.bounds_read = [&](const AABB& bounds) {
    analysis::GridSpec g;
    try {
      g = analysis::ortho_grid(bounds, res);
    } catch (const std::invalid_argument& e) {
      throw OptionError({option("ortho_map"), std::string(": ") + e.what()});
    }
    // The map's size follows from its cell: the width and height options do not apply to it.
    check_render_memory(g.cols, g.rows, job.scene.output.aovs, false, {}, {"map (a larger ", option("ortho_map"), " cell)"});
  };
  job.camera_for_cloud = [&](const AABB& bounds, double reach) {
    cloud_bounds = bounds;
    try {
      r.map = analysis::ortho_map(bounds, res, reach);
    } catch (const std::invalid_argument& e) {
      throw OptionError({option("ortho_map"), std::string(": ") + e.what()});
    }
    job.control.info("ortho map: " + std::to_string(r.map->grid.cols) + " x " + std::to_string(r.map->grid.rows) +
                     " cells, top-down, colour " + analysis::to_string(o.ortho_colour) +
                     (albedo ? " (mean of " + count_text(albedo_samples, "ray") + " per cell)" : std::string()));
    return r.map->camera;
  };
  // The DSM: the first surface down the cell-centre ray, within the heights of the points that can
  // reach the cell. A disc tilted at a roof or tree edge rises above its point by up to its radius
  // (a sphere's cap by its radius), which the viewshed and the solar maps would take for a wall
  // or a crown above any scanned point.
  job.after_trace = [&](const Site& site, double reach, const Framebuffer& image) {
    const auto t0 = std::chrono::steady_clock::now();
    r.dsm = analysis::dsm_from_depth(*r.map, image.depth);
    r.dsm_reach = reach;
    r.dsm_bounding = analysis::bound_dsm(site, *r.map, reach, r.dsm, job.control.threads);
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "dsm: %zu cells lowered to the highest and %zu raised to the lowest point within %.6g of the "
                  "cell centre (%.2f s)",
                  r.dsm_bounding.lowered, r.dsm_bounding.raised, reach, seconds_since(t0));
    job.control.info(buf);
  };
  r.render = run_render(job);
  job.control.check_cancel();  // set after the last tile: the map is not written either
  if (!albedo) {  // OrthoMapJobResult::coverage's shaded alpha
    const std::vector<float>& depth = r.render.image.depth;
    r.shaded_coverage.resize(depth.size());
    std::transform(depth.begin(), depth.end(), r.shaded_coverage.begin(),
                   [](float d) { return std::isfinite(d) ? 1.0f : 0.0f; });
  }
  if (!is_root(job.control)) return r;  // only the root's image is complete
  if (o.render.write)  // the files copy the cloud's CRS: `rayscan info`'s doubts about it too
    for (const std::string& w : crs_warnings(r.render.crs_wkt, cloud_bounds))
      job.control.info("warning: " + w + (o.dsm.empty() ? "; the GeoTIFF carries" : "; the GeoTIFFs carry") +
                       " it as it is");
  if (o.render.write)
    r.render.written = analysis::write_ortho_map(*r.map, o.ortho_colour, r.colour(), r.coverage(),
                                                 job.scene.output.exposure, r.render.crs_wkt, image, o.dsm, r.dsm,
                                                 r.render.metadata);
  return r;
}

std::vector<Camera> load_camera_list(const std::filesystem::path& file) {
  const std::string f = file.string();
  nlohmann::json j = io::parse_json_file(file);  // the input policy of every JSON input, its messages
  std::string base;
  if (j.is_object()) {
    if (j.size() != 1 || !j.contains("cameras"))
      throw SceneError(f + ": expected an array of cameras or {\"cameras\": [...]}");
    j = j["cameras"];
    base = "/cameras";
  }
  if (!j.is_array() || j.empty()) throw SceneError(f + ": " + (base.empty() ? "" : base + ": ") + "expected a non-empty array of cameras");
  if (j.size() > 1000000) throw SceneError(f + ": more than 1000000 cameras");
  std::vector<Camera> cams;
  cams.reserve(j.size());
  for (std::size_t k = 0; k < j.size(); ++k) {
    const std::string ptr = base + "/" + std::to_string(k);
    if (j[k].is_string()) {
      std::filesystem::path p = j[k].get<std::string>();
      if (p.is_relative()) p = file.parent_path() / p;
      cams.push_back(io::load_camera(p));
    } else if (j[k].is_object()) {
      cams.push_back(io::parse_camera(j[k], f, ptr));
    } else {
      throw SceneError(f + ": " + ptr + ": expected a camera object or a camera file name");
    }
  }
  return cams;
}

std::filesystem::path frame_file_name(const std::filesystem::path& image, std::size_t frame) {
  char num[32];
  std::snprintf(num, sizeof num, "_%04zu", frame);
  std::filesystem::path p = image;
  p.replace_filename(image.stem().string() + num + image.extension().string());
  return p;
}

RenderFramesResult run_render_frames(const RenderJobOptions& o, std::span<const Camera> cameras) {
  if (cameras.empty()) throw std::invalid_argument("render frames: the camera list is empty");
  if (o.write && o.scene.output.image.empty())
    throw OptionError({(o.scene.file.empty() ? std::string("(scene)") : o.scene.file.string()) +
                           ": /output/image: not set; give it in the scene or set the ",
                       option("out"), " option"});
  for (const Camera& c : cameras)
    check_render_memory(c, o.scene.output.aovs, o.write && is_root(o.control), o.scene.output.image);
  // Every frame's name is checked before the cloud is read: a directory or FIFO at a later
  // frame's name fails now, not after the frames before it were rendered and then discarded.
  if (o.write && is_root(o.control))
    for (std::size_t f = 0; f < cameras.size(); ++f) require_replaceable_output(frame_file_name(o.scene.output.image, f));
  RenderJobOptions first = o;
  if (!first.scene.camera) first.scene.camera = cameras.front();  // prepare() needs a camera
  RenderFramesResult fr;
  RenderJobResult& r = fr.job;
  const std::unique_ptr<Prepared> P = prepare(first, r);
  const Scene& scene = P->scene;
  const JobControl& ctl = o.control;
  WorkDistributor* dist = ctl.distributor;
  const int ranks = dist ? dist->size() : 1;
  const bool root = is_root(ctl);
  fr.frames = cameras.size();
  if (!o.write && root) fr.images.resize(cameras.size());
  std::mutex write_mutex;
  // The frames are one output, all or nothing (as solar's --day maps): each is written to its
  // temporary, and all are renamed once the last is written, so a failure at any frame leaves
  // the old files and none of this run's. A transaction gathers the files written on its thread:
  // the root's compute thread (whole frames over MPI) gets one of its own, committed with this
  // one; that thread ends with the stage, before they are committed or destroyed.
  OutputTransaction frames_tx;
  std::vector<std::unique_ptr<OutputTransaction>> thread_tx;
  const auto t0 = std::chrono::steady_clock::now();
  // Writes frame f (root only) and accumulates its statistics.
  auto finish_frame = [&](std::size_t f, const Framebuffer& fb, const RenderStats& st) {
    std::lock_guard lock(write_mutex);
    r.stats.queries += st.queries;
    r.stats.nodes_visited += st.nodes_visited;
    r.stats.points_tested += st.points_tested;
    r.stats.primary_rays += st.primary_rays;
    r.stats.threads = st.threads;
    if (!root) return;
    if (!o.write) {
      fr.images[f] = fb;
      return;
    }
    if (!OutputTransaction::current()) thread_tx.push_back(std::make_unique<OutputTransaction>());
    OutputDesc out = scene.output;
    out.image = frame_file_name(scene.output.image, f);
    ImageMetadata m = render_metadata(o, scene, r, &cameras[f], {});
    m.emplace_back("rayscan:frame", std::to_string(f));
    const auto w = write_image(fb, out, m, &cameras[f]);
    fr.job.written.insert(fr.job.written.end(), w.begin(), w.end());
  };
  if (cameras.size() > std::size_t(ranks) && ranks > 1) {
    // More frames than ranks: whole frames are the work items (one frame per request).
    JobControl quiet = ctl;
    quiet.progress = false;
    std::vector<Framebuffer> pending(cameras.size());  // a worker's frame until it is packed
    std::vector<RenderStats> stats(cameras.size());
    WorkStage stage;
    stage.items = cameras.size();
    stage.batch = 1;
    stage.compute = [&](std::uint64_t first_f, std::uint64_t count) {
      for (std::uint64_t f = first_f; f < first_f + count; ++f) {
        stats[f] = render_camera(*P, cameras[f], quiet, r.radius.radius, pending[f], false);
        if (root) {
          finish_frame(f, pending[f], stats[f]);
          pending[f] = Framebuffer{};
        }
      }
    };
    stage.pack = [&](std::uint64_t first_f, std::uint64_t count) {
      std::vector<std::byte> out;
      for (std::uint64_t f = first_f; f < first_f + count; ++f) {
        const std::uint64_t st[4] = {stats[f].queries, stats[f].nodes_visited, stats[f].points_tested,
                                     stats[f].primary_rays};
        append_bytes(out, std::span<const std::uint64_t>(st));
        const std::vector<std::byte> px = pack_tiles(pending[f], 1u << 30, 0, 1);  // one tile = the frame
        append_bytes(out, std::span<const std::byte>(px));
        pending[f] = Framebuffer{};
      }
      return out;
    };
    stage.unpack = [&](std::uint64_t first_f, std::uint64_t count, std::span<const std::byte> bytes) {
      std::size_t off = 0;
      for (std::uint64_t f = first_f; f < first_f + count; ++f) {
        std::uint64_t st[4];
        read_values(bytes, off, std::span<std::uint64_t>(st));
        Framebuffer fb = empty_framebuffer(cameras[f], scene.output.aovs);
        const std::size_t need = pack_tiles(fb, 1u << 30, 0, 1).size();
        if (bytes.size() - off < need) throw std::runtime_error("render frames: short frame message");
        unpack_tiles(fb, 1u << 30, 0, 1, bytes.subspan(off, need));
        off += need;
        RenderStats s;
        s.queries = st[0];
        s.nodes_visited = st[1];
        s.points_tested = st[2];
        s.primary_rays = st[3];
        s.threads = r.stats.threads;
        finish_frame(f, fb, s);
      }
    };
    dist->run(stage);
  } else {
    // As many ranks as frames or more (or one process): frame after frame, tiles distributed.
    for (std::size_t f = 0; f < cameras.size(); ++f) {
      Framebuffer fb;
      const RenderStats st = render_camera(*P, cameras[f], ctl, r.radius.radius, fb, true);
      finish_frame(f, fb, st);
      if (f + 1 == cameras.size()) r.image = std::move(fb);
    }
  }
  frames_tx.commit();
  for (const std::unique_ptr<OutputTransaction>& tx : thread_tx) tx->commit();
  r.stats.seconds = seconds_since(t0);
  r.metadata = render_metadata(o, scene, r, nullptr, {});
  char buf[256];
  std::snprintf(buf, sizeof buf, "%zu frames in %.2f s (%.3g frames/s), %llu ray queries", cameras.size(),
                r.stats.seconds, double(cameras.size()) / r.stats.seconds, (unsigned long long)r.stats.queries);
  ctl.info(buf);
  return fr;
}

}  // namespace rayscan::jobs
