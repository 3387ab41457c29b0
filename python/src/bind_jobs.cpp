// rayscan.render / ortho_map / visibility / solar / compare: the library's job calls (docs/library.md: one
// options struct in, one result out; jobs::run_render, run_visibility, run_solar, run_compare)
// with NumPy arrays out. A cloud is a file name, a rayscan.PointCloud (passed to the job in
// memory, not copied) or an (N, 3) array (cloud_arg). Each call converts its arguments with the
// GIL held, then runs the job without it on a worker thread while the calling thread watches for
// Ctrl-C (run_interruptible). rayscan.dask checks the
// options of visibility and solar at its call through the same conversions and the jobs' own
// checks (jobs::check_options).
#include "arrays.hpp"
#include "bindings.hpp"
#include "cloud.hpp"

#include "rayscan/analysis/ortho_map.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/job.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/jobs/compare.hpp"
#include "rayscan/jobs/quick_look.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/jobs/visibility.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/site/site.hpp"

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>
#include <thread>

namespace rayscan::python {

namespace {

static_assert(sizeof(glm::vec3) == 3 * sizeof(float));

/// Move a vector of U (U = N packed T) into a NumPy array of T with the given shape.
template <class T, class U>
py::array_t<T> own_as(std::vector<U>&& v, std::vector<py::ssize_t> shape) {
  static_assert(sizeof(U) % sizeof(T) == 0);
  auto* owned = new std::vector<U>(std::move(v));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<U>*>(p); });
  return py::array_t<T>(shape, reinterpret_cast<const T*>(owned->data()), owner);
}

/// Point indices (uint32 with kNoPoint for a miss) as int64 with -1 for a miss, like
/// RayQueryResult.first().
py::array_t<std::int64_t> point_ids(const std::vector<std::uint32_t>& v, std::vector<py::ssize_t> shape) {
  std::vector<std::int64_t> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = v[i] == kNoPoint ? -1 : static_cast<std::int64_t>(v[i]);
  return to_numpy(std::move(out), std::move(shape));
}

/// Runs `f` (with the GIL held: `f` releases it for the job). The point, image and EPW readers
/// report a file they cannot open, read or decode as a std::runtime_error "<file>: ..." (the point
/// readers' FormatError included), by its message alone; one naming a file of `files` ("" = none)
/// is asked again through the input policy, so that a file that cannot be opened raises the
/// OSError subclass of its errno (FileNotFoundError, IsADirectoryError, ...; module.cpp), and
/// raises OSError otherwise (a malformed file), as the point readers' errors do. Anything else
/// passes unchanged.
template <class F>
void run_reading_files(F&& f, std::initializer_list<std::string> files) {
  try {
    f();
  } catch (const InputFileError&) {
    throw;  // module.cpp's translation
  } catch (const std::runtime_error& e) {
    const std::string_view what = e.what();
    for (const std::string& file : files)
      if (!file.empty() && what.size() > file.size() && what.substr(0, file.size()) == file &&
          what.substr(file.size(), 2) == ": ") {
        const InputFile probe(file);  // InputFileError when it cannot be opened
        PyErr_SetString(PyExc_OSError, e.what());
        throw py::error_already_set();
      }
    throw;
  }
}

/// How often the calling thread looks for a signal while a job runs: Ctrl-C is answered within
/// this and the job's check interval (a render tile, a chunk of points), without a measurable
/// cost to the job.
constexpr std::chrono::milliseconds kSignalPoll{50};

/// Runs the job `f` (the one whose options hold `ctl`) on a worker thread and waits for it on the
/// calling thread, which holds the GIL: the wait releases it in steps of kSignalPoll, and between
/// steps PyErr_CheckSignals runs the Python handlers of the signals that came (the main thread
/// only; elsewhere the job runs to its end). When one raises (KeyboardInterrupt at Ctrl-C),
/// ctl.cancel is set, the job stops at its next check by throwing rayscan::Cancelled, and once the
/// worker has ended the handler's exception is raised, with the note "<job> interrupted before its
/// end" (PEP 678, Python 3.11+) when the job did stop early; the job's result is dropped. A job
/// that ends with an error raises it here as if run on this thread. `f` must not touch Python
/// objects. The batch queries look for signals between chunks instead (bind_index.cpp): they run
/// on the calling thread already.
template <class F>
void run_interruptible(JobControl& ctl, const char* job, F&& f) {
  std::atomic<bool> stop{false};
  ctl.cancel = &stop;
  std::mutex m;
  std::condition_variable cv;
  bool done = false;
  std::exception_ptr error;
  std::thread worker([&] {
    try {
      f();
    } catch (...) {
      error = std::current_exception();
    }
    std::lock_guard lock(m);
    done = true;
    cv.notify_one();
  });
  // Joined on every way out, an exception of this thread's included (a joinable std::thread's
  // destructor ends the process); the job is stopped first so that the join is short.
  struct Join {
    std::thread& t;
    std::atomic<bool>& stop;
    ~Join() {
      stop = true;
      py::gil_scoped_release nogil;
      t.join();
    }
  } join{worker, stop};
  std::optional<py::error_already_set> interrupted;
  for (;;) {
    bool finished;
    {
      py::gil_scoped_release nogil;
      std::unique_lock lock(m);
      finished = cv.wait_for(lock, kSignalPoll, [&] { return done; });
    }
    if (finished) break;
    if (PyErr_CheckSignals() != 0) {
      interrupted.emplace();  // takes the handler's exception
      break;
    }
  }
  if (interrupted) {
    stop = true;
    {
      py::gil_scoped_release nogil;
      std::unique_lock lock(m);
      cv.wait(lock, [&] { return done; });
    }
    bool cancelled = false;
    try {
      if (error) std::rethrow_exception(error);
    } catch (const Cancelled&) {
      cancelled = true;
    } catch (...) {
      // The job's own error, come before it saw the flag: the signal's exception wins.
    }
    if (cancelled && py::hasattr(interrupted->value(), "add_note"))
      interrupted->value().attr("add_note")(std::string(job) + " interrupted before its end");
    throw std::move(*interrupted);
  }
  if (error) std::rethrow_exception(error);
}

// The command line's bounds, defined once: rayscan::kMaxImageSide (camera.hpp), render::kMaxSpp
// (scene.hpp).
using render::kMaxSpp;

/// An image side (width, height) in pixels: None or an integer in [1, 65536], the command
/// line's range, checked here so that a side out of it is named as given rather than by the
/// aspect-ratio rule that derives a missing one.
std::optional<std::uint32_t> side_arg(py::handle v, const char* name) {
  return opt_int_arg<std::uint32_t>(v, name, 1, kMaxImageSide, "None or an integer in [1, 65536]");
}

/// The keyword of rayscan.<job> (`job`: "render", "ortho_map", "visibility", "solar") that sets
/// the job option `field`, for an OptionError's message: the fields these calls take under another
/// name, else the field itself (the keywords are the options' field names).
std::string keyword_for(std::string_view job, std::string_view field) {
  struct Spelling {
    std::string_view job, field, keyword;
  };
  static constexpr Spelling kSpellings[] = {
      {"render", "camera_file", "camera"},
      {"ortho_map", "ortho_map", "res"},
      {"visibility", "observers_file", "observers"},
      {"visibility", "camera_file", "camera"},
  };
  for (const Spelling& s : kSpellings)
    if (s.job == job && s.field == field) return std::string(s.keyword);
  return std::string(field);
}

/// Whether rayscan.<job> lacks the job option `field`, which only the command line gives:
/// solar's day of shadows, whose frames are files.
bool call_lacks(std::string_view job, std::string_view field) {
  return job == "solar" && (field == "day" || field == "every");
}

/// The text `text` that follows option `name` in a job's message with the library's word for the
/// option's automatic value written as the call's: a radius given nullopt is "auto" on the
/// command line and None here ("radius: expected a finite number > 0 (world units) or None",
/// "radius None (auto) needs at least two distinct points; give a number").
std::string call_words(const OptionName& name, std::string text) {
  static constexpr std::string_view kAuto = " or auto", kNone = " or None";
  static constexpr std::string_view kAutoFirst = " auto ", kNoneFirst = " None (auto) ";
  if (name.field == "radius") {
    if (const std::size_t at = text.find(kAuto); at != std::string::npos) text.replace(at, kAuto.size(), kNone);
    if (text.starts_with(kAutoFirst)) text.replace(0, kAutoFirst.size(), kNoneFirst);
  }
  return text;
}

/// The message of OptionError `e` of rayscan.<job>, each option written as its keyword
/// (keyword_for). An option the call lacks (call_lacks) is left out with the text part on each side
/// of it, which the job writes as that option's own clause (", or a day of shadows (", day, ")").
/// Of two options that the call takes as one keyword, joined by " or " alone (observers_file or
/// observers), the keyword is named once.
std::string keyword_message(std::string_view job, const OptionError& e) {
  const std::vector<OptionError::Part>& parts = e.parts();
  std::vector<OptionError::Part> kept;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (const auto* text = std::get_if<std::string>(&parts[i]); text && i > 0)
      if (const auto* before = std::get_if<OptionName>(&parts[i - 1])) {
        kept.push_back(call_words(*before, *text));
        continue;
      }
    const auto* name = std::get_if<OptionName>(&parts[i]);
    if (name && call_lacks(job, name->field)) {
      if (!kept.empty() && std::holds_alternative<std::string>(kept.back())) kept.pop_back();
      if (i + 1 < parts.size() && std::holds_alternative<std::string>(parts[i + 1])) ++i;
      continue;
    }
    if (name && kept.size() >= 2) {
      const auto* between = std::get_if<std::string>(&kept.back());
      const auto* before = std::get_if<OptionName>(&kept[kept.size() - 2]);
      if (between && *between == " or " && before &&
          keyword_for(job, before->field) == keyword_for(job, name->field)) {
        kept.pop_back();
        continue;
      }
    }
    kept.push_back(parts[i]);
  }
  return OptionError(std::move(kept)).spelled([&](std::string_view field) { return keyword_for(job, field); });
}

/// Runs the job `f` (GIL released or not, as the caller holds it) and rethrows an OptionError it
/// throws (a bad option or combination, an observer error) as std::invalid_argument, i.e.
/// ValueError, with the message in rayscan.<job>'s terms (keyword_message); `edit` may then
/// rewrite that message. Other exceptions pass unchanged.
template <class F, class Edit = std::string (*)(std::string)>
void run_naming_keywords(std::string_view job, F&& f, Edit edit = [](std::string m) { return m; }) {
  try {
    f();
  } catch (const OptionError& e) {
    throw std::invalid_argument(edit(keyword_message(job, e)));
  }
}

/// Refuses a PointCloud given to a job when a coordinate is not finite: ValueError "<name>:
/// PointCloud: point I has a non-finite coordinate", I the caller's row, as for an array
/// (cloud_arg). The jobs would refuse it later but name the point by its place in what they
/// build first (the quick look's sample, in hash order, for a cloud without a CRS) and blame their
/// own steps ("overview camera", the index). Call without the GIL.
void require_finite_points(const CloudArg& a, const std::string& name) {
  if (!a.points || a.owned) return;  // a file, or an array's copy that cloud_arg checked
  try {
    a.points->validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(name + ": " + e.what());
  }
}

/// The points of a render: a PointCloud or an array in memory (`arg`), a cloud file (`arg` with a
/// path, or the scene's cloud), which is read once for the overview camera and then rendered from
/// memory, as `rayscan render` does.
struct RenderPoints {
  std::optional<CloudArg> arg;     // the points given (as `scene` or cloud=); none: the scene's
  std::optional<PointCloud> read;  // a cloud file read for the overview camera
  double read_seconds = 0.0;       // the seconds that read took (CloudSummary::read_seconds)

  /// The summary resolve_scene asks for (called without the GIL): of the points in memory (with
  /// a CRS georeferenced, a PCD VIEWPOINT as the scanner position), else of the file.
  jobs::CloudSummary summary(const std::filesystem::path& scene_cloud) {
    if (arg && arg->points) {
      std::optional<Vec3> sensor;
      if (const io::FileInfo* i = arg->info; i && i->viewpoint)
        sensor = Vec3((*i->viewpoint)[0], (*i->viewpoint)[1], (*i->viewpoint)[2]);
      const PointCloud& c = *arg->points;
      return jobs::summarize_cloud(c.positions, !c.rgb.empty(), !c.crs_wkt.empty(), sensor);
    }
    jobs::CloudSummary s = jobs::summarize_cloud_file(arg ? std::filesystem::path(arg->path) : scene_cloud, read);
    read_seconds = s.read_seconds;
    return s;
  }
  /// Gives the job the points: in memory, or the file given as cloud= in place of the scene's.
  /// A file read here is the scene's cloud read by the caller, as `rayscan render` hands it on:
  /// the job then counts the read's seconds as its own (read_seconds, first_tile_seconds).
  void attach(jobs::RenderJobOptions& o) const {
    if (arg && !arg->points) o.scene.cloud = std::filesystem::absolute(arg->path);
    o.cloud = arg && arg->points ? arg->points : read ? &*read : nullptr;
    if (read && o.cloud == &*read) {
      o.cloud_read_from_scene = true;
      o.cloud_read_seconds = read_seconds;
    }
  }
};

/// The overrides every render call takes (SceneOverrides; aovs are the caller's).
render::SceneOverrides render_overrides(py::handle width, py::handle height, py::handle spp, py::handle seed,
                                        py::handle camera) {
  render::SceneOverrides ov;
  if (!camera.is_none()) ov.camera_file = input_path_arg(camera, "camera");
  ov.width = side_arg(width, "width");
  ov.height = side_arg(height, "height");
  ov.spp = opt_int_arg<std::uint32_t>(spp, "spp", 1, kMaxSpp, "None or an integer in [1, 1048576]");
  if (!seed.is_none()) ov.seed = uint64_arg(seed, "seed");
  return ov;
}

/// `scene` is a scene file or a point cloud file (its quick look, as `rayscan render CLOUD`), a
/// PointCloud or an (N, 3) array (the quick look of those points); with a non-empty `scene_json`
/// (a scene dict as JSON text) it is not used. `cloud` replaces the scene's points.
py::dict render(py::handle scene, const std::string& scene_json, py::handle cloud, py::handle width,
                py::handle height, py::handle spp, py::handle seed, py::handle aovs, py::handle camera,
                py::handle threads) {
  jobs::RenderJobOptions o;
  o.write = false;
  o.control.threads = parse_threads(threads);
  render::SceneOverrides ov = render_overrides(width, height, spp, seed, camera);
  ov.aovs = names_arg(aovs, "aovs");
  const bool from_text = !scene_json.empty();
  const bool quick_look_in_memory = !from_text && !is_path_like(scene);
  RenderPoints points;
  std::string scene_file;
  if (quick_look_in_memory) {
    if (!py::isinstance<PyCloud>(scene) && !py::isinstance<py::array>(scene) && !py::isinstance<py::list>(scene) &&
        !py::isinstance<py::tuple>(scene))
      throw py::type_error("scene must be a scene or point cloud file name (str or os.PathLike), a scene dict, a "
                           "rayscan.PointCloud or an (N, 3) array of coordinates, got " + type_name(scene));
    if (!cloud.is_none()) throw py::type_error("render: the points are `scene` already; do not give cloud= too");
    points.arg.emplace(cloud_arg(scene, "scene", false));
  } else {
    if (!from_text) scene_file = input_path_arg(scene, "scene");
    if (!cloud.is_none()) points.arg.emplace(cloud_arg(cloud, "cloud"));
  }
  const auto summary = [&](const std::filesystem::path& f) { return points.summary(f); };
  const bool given = points.arg.has_value();
  jobs::RenderJobResult r;
  const char* points_name = quick_look_in_memory ? "scene" : "cloud";
  const std::string cloud_file = given ? points.arg->path : std::string();
  run_reading_files(
      [&] {
        run_interruptible(o.control, "render", [&] {
          if (points.arg) require_finite_points(*points.arg, points_name);
          // Points in memory are named by the keyword that gave them ("scene: a quick look needs
          // ..."), as by the jobs' source_label below.
          run_naming_keywords("render", [&] {
            const jobs::ResolvedScene rs =
                quick_look_in_memory ? jobs::resolve_quick_look(summary({}), ov, points_name)
                : from_text          ? jobs::resolve_scene_text(scene_json, "scene dict", ov, summary, given)
                                     : jobs::resolve_scene(scene_file, ov, summary, given);
            o.scene = rs.scene;
            points.attach(o);
            r = jobs::run_render(o);
          });
        });
      },
      {cloud_file});
  render::Framebuffer& fb = r.image;
  const auto h = static_cast<py::ssize_t>(fb.height), w = static_cast<py::ssize_t>(fb.width);
  py::dict out;
  out["beauty"] = own_as<float>(std::move(fb.beauty), {h, w, 3});
  if (!fb.depth.empty()) out["depth"] = own_as<float>(std::move(fb.depth), {h, w});
  if (!fb.normal.empty()) out["normal"] = own_as<float>(std::move(fb.normal), {h, w, 3});
  if (!fb.position.empty()) {
    out["position"] = own_as<float>(std::move(fb.position), {h, w, 3});
    out["position_origin"] = to_numpy(std::vector<double>{fb.position_origin.x, fb.position_origin.y,
                                                          fb.position_origin.z});
  }
  if (!fb.index.empty()) out["index"] = point_ids(fb.index, {h, w});
  if (!fb.albedo.empty()) out["albedo"] = own_as<float>(std::move(fb.albedo), {h, w, 3});
  if (!fb.cost.empty()) out["cost"] = own_as<float>(std::move(fb.cost), {h, w});
  out["radius"] = r.radius.radius;
  out["points"] = r.points;
  py::dict stats;
  stats["seconds"] = r.stats.seconds;
  stats["primary_rays"] = r.stats.primary_rays;
  stats["queries"] = r.stats.queries;
  stats["nodes_visited"] = r.stats.nodes_visited;
  stats["points_tested"] = r.stats.points_tested;
  stats["threads"] = r.stats.threads;
  stats["index_seconds"] = r.index_seconds;
  stats["read_seconds"] = r.read_seconds;
  stats["first_tile_seconds"] = r.first_tile_seconds;
  out["stats"] = stats;
  return out;
}

/// rayscan.ortho_map: `rayscan render CLOUD --ortho-map RES --ortho-colour COLOUR` without files
/// (jobs::run_ortho_map, write off): the quick look's scene (material, surfels) seen by the map's
/// top-down camera over the cloud's exact bounds, with the files' bands as arrays (the coverage
/// is the orthophoto's alpha, OrthoMapJobResult::coverage). `colour` is "albedo" or "shaded"
/// (analysis::OrthoColour); anything else raises ValueError (TypeError for a non-string).
py::dict ortho_map(py::handle cloud, py::handle res_arg, py::handle spp, py::handle seed, py::handle threads,
                   py::handle colour) {
  jobs::OrthoMapJobOptions o;
  o.render.write = false;
  o.render.control.threads = parse_threads(threads);
  if (!py::isinstance<py::str>(colour))
    throw py::type_error("colour must be \"albedo\" or \"shaded\", got " + type_name(colour));
  const std::string colour_name = colour.cast<std::string>();
  const std::optional<analysis::OrthoColour> kind = analysis::parse_ortho_colour(colour_name);
  if (!kind) throw py::value_error("colour '" + colour_name + "': expected albedo or shaded");
  o.ortho_colour = *kind;
  const double res = float_arg(res_arg, "res", "a number > 0 (world units per pixel)");
  if (!(res > 0.0) || !std::isfinite(res))
    throw py::value_error("res: expected a finite number > 0 (world units per pixel), got " + std::to_string(res));
  o.ortho_map = res;
  const render::SceneOverrides ov = render_overrides(py::none(), py::none(), spp, seed, py::none());
  RenderPoints points;
  points.arg.emplace(cloud_arg(cloud, "cloud"));
  const std::string path = points.arg->path;
  if (!path.empty() && !jobs::is_cloud_input(path))
    throw py::value_error("cloud '" + path + "': expected a point cloud file (LAS, LAZ, COPC, PLY, PCD, text, .rsi)");
  const auto summary = [&](const std::filesystem::path& f) { return points.summary(f); };
  jobs::OrthoMapJobResult r;
  run_reading_files(
      [&] {
        run_interruptible(o.render.control, "ortho_map", [&] {
          require_finite_points(*points.arg, "cloud");
          run_naming_keywords("ortho_map", [&] {
            o.render.scene = path.empty() ? jobs::resolve_quick_look(summary({}), ov, "cloud").scene
                                          : jobs::resolve_scene(path, ov, summary).scene;
            points.attach(o.render);
            r = jobs::run_ortho_map(o);
          });
        });
      },
      {path});
  const analysis::GridSpec& g = r.map->grid;
  const auto h = static_cast<py::ssize_t>(g.rows), w = static_cast<py::ssize_t>(g.cols);
  py::dict out;
  std::vector<render::Color>& colour_of =
      *kind == analysis::OrthoColour::albedo ? r.render.image.albedo : r.render.image.beauty;
  out["image"] = own_as<float>(std::move(colour_of), {h, w, 3});
  const std::span<const float> coverage = r.coverage();  // the orthophoto GeoTIFF's alpha band
  out["coverage"] = to_numpy(std::vector<float>(coverage.begin(), coverage.end()), {h, w});
  out["dsm"] = to_numpy(std::move(r.dsm.values), {h, w});
  const std::array<double, 6> gt = g.geotransform();
  out["geotransform"] = py::make_tuple(gt[0], gt[1], gt[2], gt[3], gt[4], gt[5]);
  out["crs"] = r.render.crs_wkt.empty() ? py::object(py::none()) : py::object(py::str(r.render.crs_wkt));
  out["radius"] = r.render.radius.radius;
  return out;
}

/// An (H, W) or (H, W, C) array as an rayscan::Image: channels Y (C = 1), R G B (3), R G B A (4),
/// else c0, c1, ...; float32 samples. Raises TypeError for an object that is no array of numbers
/// (None, a dict) and for a scalar (3.5, True: no image at all), ValueError for an array of
/// another shape or dtype.
rayscan::Image to_image(py::handle obj, const std::string& name) {
  py::module_ np = py::module_::import("numpy");
  py::array a = np.attr("asarray")(obj);
  const char kind = a.dtype().kind();
  // NumPy's wrapping of a non-numeric object, or of one number (a 0-d array given as such is an
  // array of the wrong shape).
  if (kind == 'O' || kind == 'S' || kind == 'V' || (a.ndim() == 0 && !py::isinstance<py::array>(obj)))
    throw py::type_error(name + " must be an image file name (str or os.PathLike) or an (H, W) or (H, W, C) "
                                "array of numbers, got " + type_name(obj));
  if ((kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b') || (a.ndim() != 2 && a.ndim() != 3))
    throw py::value_error(name + ": expected a file name or an (H, W) or (H, W, C) array of numbers");
  auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f) throw py::error_already_set();
  rayscan::Image img;
  img.height = static_cast<int>(f.shape(0));
  img.width = static_cast<int>(f.shape(1));
  const int c = a.ndim() == 3 ? static_cast<int>(f.shape(2)) : 1;
  if (img.width == 0 || img.height == 0 || c == 0) throw py::value_error(name + ": the image is empty");
  if (c == 1) img.channels = {"Y"};
  else if (c == 3) img.channels = {"R", "G", "B"};
  else if (c == 4) {
    img.channels = {"R", "G", "B", "A"};
    img.alpha_channel = 3;
  } else {
    // std::string first: GCC 12 at -O3 warns (-Wrestrict, a false positive) on "c" + std::string here.
    for (int i = 0; i < c; ++i) img.channels.push_back(std::string(1, 'c') + std::to_string(i));
  }
  img.pixels.assign(f.data(), f.data() + f.size());
  img.source = name;
  return img;
}

py::dict compare(const py::object& a, const py::object& b, py::handle channels,
                 py::handle mask, py::handle alpha, py::handle resize, py::handle fail,
                 py::handle fail_percent, py::handle fail_psnr,
                 py::handle fail_ssim, py::handle warn) {
  jobs::CompareJobOptions o;
  std::optional<rayscan::Image> ia, ib;
  if (is_path_like(a))
    o.reference_file = input_path_arg(a, "reference");
  else
    o.reference = &ia.emplace(to_image(a, "reference"));
  if (is_path_like(b))
    o.image_file = input_path_arg(b, "image");
  else
    o.image = &ib.emplace(to_image(b, "image"));
  o.channels = names_arg(channels, "channels");
  o.mask = bool_arg(mask, "mask");
  o.alpha = bool_arg(alpha, "alpha");
  o.resize = bool_arg(resize, "resize");
  o.fail.threshold = opt_float_arg(fail, "fail", "None or a number (absolute error per sample)");
  o.fail.percent = opt_float_arg(fail_percent, "fail_percent", "None or a number (percent of samples)");
  o.fail.min_psnr = opt_float_arg(fail_psnr, "fail_psnr", "None or a number (dB)");
  o.fail.min_ssim = opt_float_arg(fail_ssim, "fail_ssim", "None or a number (SSIM, at most 1)");
  o.warn.threshold = opt_float_arg(warn, "warn", "None or a number (absolute error per sample)");
  jobs::CompareJobResult r;
  run_reading_files([&] { run_interruptible(o.control, "compare", [&] { r = jobs::run_compare(o); }); },
                    {o.reference_file, o.image_file});
  const analysis::CompareMetrics& m = r.metrics;
  py::dict d;
  d["width"] = m.width;
  d["height"] = m.height;
  d["channels"] = m.channels;
  d["pixels_compared"] = m.pixels_compared;
  d["pixels_ignored"] = m.pixels_ignored;
  d["mae"] = m.mae;
  d["rmse"] = m.rmse;
  d["psnr"] = m.psnr;
  d["peak"] = m.peak;
  d["max_error"] = m.max_error;
  d["max_pixel"] = py::make_tuple(m.max_x, m.max_y, m.max_c);
  d["ssim"] = m.ssim;
  d["ssim_signal"] = m.ssim_signal;
  // As the CLI's --json ssim.undefined, ssim.windows and ssim.window_positions (the "ssim_" prefix
  // as ssim_signal's): why SSIM is NaN (None when it is defined), and the windows averaged of the
  // positions inside the image, the others holding a masked pixel or a NaN/Inf sample.
  d["ssim_undefined"] = m.ssim_undefined.empty() ? py::object(py::none()) : py::object(py::str(m.ssim_undefined));
  d["ssim_windows"] = m.ssim_windows;
  d["ssim_window_positions"] = m.ssim_positions;
  d["flip"] = m.flip;  // mean LDR-FLIP (analysis/flip.hpp), NaN when not computed
  // None where the level has no pixel test (CompareJobResult's limits), as the CLI's text says
  // "off" and its JSON null: a count over a threshold nothing judges would read as a finding.
  const auto level = [&d](const analysis::Limits& l, const char* threshold_key, double threshold,
                          const char* percent_key, double percent) {
    d[threshold_key] = l.pixel_test ? py::object(py::float_(threshold)) : py::object(py::none());
    d[percent_key] = l.pixel_test ? py::object(py::float_(percent)) : py::object(py::none());
  };
  level(r.fail_limits, "fail_threshold", m.fail_threshold, "percent_over_fail", m.percent_over_fail());
  level(r.warn_limits, "warn_threshold", m.warn_threshold, "percent_over_warn", m.percent_over_warn());
  d["nonfinite_mismatches"] = m.nonfinite_mismatches;
  py::dict per;
  for (const analysis::ChannelStats& c : m.per_channel) {
    py::dict s;
    s["mae"] = c.mae;
    s["rmse"] = c.rmse;
    s["max_error"] = c.max_error;
    per[py::str(c.name)] = s;
  }
  d["per_channel"] = per;
  d["verdict"] = std::string(analysis::to_string(r.judgement.verdict));
  d["reasons"] = r.judgement.reasons;
  return d;
}

/// What a sphere radius argument is, for its TypeError.
constexpr const char* kRadiusExpected = "None (auto) or a number > 0 (world units)";

/// rayscan.visibility's options from its arguments but the cloud, each converted and refused
/// (TypeError, ValueError naming its keyword) as the call does. Observer rows are named
/// "observers[i]" (0-based, as the caller indexes them).
jobs::VisibilityJobOptions visibility_options(const py::object& observers, py::handle radius, py::handle height,
                                              py::handle max_distance, py::handle tolerance, py::handle target_height,
                                              py::handle sky_rays, py::handle camera, py::handle distance,
                                              py::handle threads, py::handle cache, py::handle ground_radius) {
  jobs::VisibilityJobOptions o;
  o.cache_bytes = cache_arg(cache);
  if (!observers.is_none()) {
    if (is_path_like(observers)) {
      o.observers_file = input_path_arg(observers, "observers");
    } else {
      py::module_ np = py::module_::import("numpy");
      py::array a = np.attr("asarray")(observers);
      const bool xy = a.ndim() == 2 && a.shape(1) == 2;
      if (xy) a = np.attr("hstack")(py::make_tuple(a, np.attr("zeros")(py::make_tuple(a.shape(0), 1))));
      const Vec3Rows rows = as_vec3_rows(a, "observers", true);
      for (std::size_t i = 0; i < rows.rows.size(); ++i) {
        analysis::Observer ob;
        ob.position = rows.rows[i];
        ob.has_z = !xy;
        ob.source = "observers[" + std::to_string(i) + "]";
        o.observers.push_back(ob);
      }
    }
  }
  o.radius = opt_float_arg(radius, "radius", kRadiusExpected);
  o.height = opt_float_arg(height, "height", "None or a number (eye height above the local ground, world units)");
  o.max_distance = opt_float_arg(max_distance, "max_distance", "None or a number >= 0 (world units)");
  o.tolerance = opt_float_arg(tolerance, "tolerance", "None or a number >= 0 (world units)");
  o.target_height = opt_float_arg(target_height, "target_height", "None or a number >= 0 (world units)");
  o.ground_radius = opt_float_arg(ground_radius, "ground_radius", "None (5 x radius) or a number > 0 (world units)");
  o.sky_rays = static_cast<std::uint32_t>(int_arg(sky_rays, "sky_rays", 0, 0xFFFFFFFFll, "an integer in [0, 2^32 - 1]"));
  if (!camera.is_none()) o.camera_file = input_path_arg(camera, "camera");
  o.distance = bool_arg(distance, "distance");
  o.control.threads = parse_threads(threads);
  return o;
}

/// The message `m` of a visibility job over `observers`, its "observers[i]: observer i+1: ..."
/// (the row, then the job's label of the observer) written "observers[i]: ...": one number, the
/// caller's.
std::string one_row_number(const std::vector<analysis::Observer>& observers, std::string m) {
  for (std::size_t k = 0; k < observers.size(); ++k) {
    const std::string where = analysis::observer_where(observers[k], k + 1);
    if (m.compare(0, where.size(), where) == 0) return observers[k].source + m.substr(where.size());
  }
  return m;
}

/// rayscan.visibility: visibility_options over the cloud given.
py::dict visibility(const py::object& cloud, const py::object& observers, py::handle radius,
                    py::handle height, py::handle max_distance, py::handle tolerance, py::handle target_height,
                    py::handle sky_rays, py::handle camera, py::handle distance, py::handle threads,
                    py::handle cache, py::handle ground_radius) {
  const CloudArg c = cloud_arg(cloud, "cloud");
  jobs::VisibilityJobOptions o = visibility_options(observers, radius, height, max_distance, tolerance, target_height,
                                                    sky_rays, camera, distance, threads, cache, ground_radius);
  o.cloud = c.points;
  o.cloud_file = c.path;
  o.source_label = "cloud";  // points in memory named by their keyword ("cloud: the point cloud has no points")
  jobs::VisibilityJobResult r;
  run_reading_files(
      [&] {
        run_interruptible(o.control, "visibility", [&] {
          require_finite_points(c, "cloud");
          run_naming_keywords("visibility", [&] { r = jobs::run_visibility(o); },
                              [&](std::string m) { return one_row_number(o.observers, std::move(m)); });
        });
      },
      {c.path});
  py::dict d;
  for (ScalarField& f : r.cloud.scalars)
    if (f.name == "visible_count" || f.name == "visible_distance" || f.name == "sky_view" ||
        f.name == "camera_hits")
      d[py::str(f.name)] = to_numpy(std::move(f.values));
  d["radius"] = r.radius.radius;
  d["tolerance"] = r.tolerance;
  d["target_height"] = r.target_height;
  std::vector<double> obs;
  for (const analysis::Observer& ob : r.observers) obs.insert(obs.end(), {ob.position.x, ob.position.y, ob.position.z});
  d["observers"] = to_numpy(std::move(obs), {static_cast<py::ssize_t>(r.observers.size()), 3});
  d["per_observer"] = to_numpy(std::vector<std::uint64_t>(r.line_of_sight.per_observer));
  return d;
}

/// An optional ISO 8601 time argument of solar: None (not given) or a str.
std::string time_arg(py::handle v, const char* name) {
  if (v.is_none()) return {};
  return str_arg(v, name, "None or ISO 8601 text (\"2024-06-21T12:00\"; a datetime's isoformat())");
}

/// rayscan.solar's options from its arguments but the cloud, each converted and refused as the
/// call does; the weather file is opened (OSError when it cannot be) only with `open_weather`.
jobs::SolarJobOptions solar_options(py::handle start, py::handle end, py::handle step, py::handle at,
                                    py::handle latitude, py::handle longitude, py::handle linke, py::handle albedo,
                                    const py::object& weather, py::handle sector, py::handle sky_rays,
                                    py::handle primitive, py::handle radius, py::handle threads, py::handle cache,
                                    bool open_weather) {
  jobs::SolarJobOptions o;
  o.cache_bytes = cache_arg(cache);
  o.start = time_arg(start, "start");
  o.end = time_arg(end, "end");
  o.step = str_arg(step, "step", "a duration as text (\"15min\", \"1h\")");
  o.at = time_arg(at, "at");
  o.latitude = opt_float_arg(latitude, "latitude", "None or a number (degrees north)");
  o.longitude = opt_float_arg(longitude, "longitude", "None or a number (degrees east)");
  const std::string linke_expected = "a number or a list of 12 numbers (Linke turbidity)";
  if (py::isinstance<py::str>(linke) || py::isinstance<py::bytes>(linke) || !py::hasattr(linke, "__iter__")) {
    o.linke = {float_arg(linke, "linke", linke_expected)};
  } else {
    o.linke.clear();
    for (py::handle v : linke) o.linke.push_back(float_arg(v, "linke", linke_expected));
  }
  o.albedo = float_arg(albedo, "albedo", "a number in [0, 1]");
  if (!weather.is_none()) o.weather = open_weather ? input_path_arg(weather, "weather") : path_arg(weather, "weather");
  o.sector = float_arg(sector, "sector", "a number of degrees (0 = one shadow ray per step)");
  o.sky_rays = static_cast<std::uint32_t>(int_arg(sky_rays, "sky_rays", 0, 4096, "an integer in [0, 4096]"));
  o.primitive = str_arg(primitive, "primitive", "\"sphere\" or \"surfel\"");
  o.radius = opt_float_arg(radius, "radius", kRadiusExpected);
  o.control.threads = parse_threads(threads);
  return o;
}

/// rayscan.solar: solar_options over the cloud given.
py::dict solar(const py::object& cloud, py::handle start, py::handle end, py::handle step, py::handle at,
               py::handle latitude, py::handle longitude, py::handle linke, py::handle albedo,
               const py::object& weather, py::handle sector, py::handle sky_rays, py::handle primitive,
               py::handle radius, py::handle threads, py::handle cache) {
  const CloudArg c = cloud_arg(cloud, "cloud");
  jobs::SolarJobOptions o = solar_options(start, end, step, at, latitude, longitude, linke, albedo, weather, sector,
                                          sky_rays, primitive, radius, threads, cache, true);
  o.cloud = c.points;
  o.cloud_file = c.path;
  o.source_label = "cloud";  // as visibility's
  jobs::SolarJobResult r;
  run_naming_keywords("solar", [&] {
    run_reading_files(
        [&] {
          run_interruptible(o.control, "solar", [&] {
            require_finite_points(c, "cloud");
            r = jobs::run_solar(o);
          });
        },
        {o.weather.string(), c.path});
  });
  py::dict d;
  // The result fields only: a cloud file's own scalar fields are in r.cloud too.
  const auto listed = [](const auto& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  for (ScalarField& f : r.cloud.scalars)
    if (f.name.starts_with(jobs::kSolarMonthlyPrefix) || listed(jobs::kSolarPeriodFields, f.name) ||
        listed(jobs::kSolarInstantFields, f.name))
      d[py::str(f.name)] = to_numpy(std::move(f.values));
  d["latitude"] = r.location.latitude_deg;
  d["longitude"] = r.location.longitude_deg;
  d["steps"] = r.steps;
  d["sectors"] = r.sectors;
  d["radius"] = r.radius.radius;
  if (r.sun) {
    d["sun_azimuth"] = r.sun->azimuth_deg;
    d["sun_elevation"] = r.sun->elevation_deg;
  }
  return d;
}

/// rayscan.dask.visibility's check at the call, before any task runs: rayscan.visibility's
/// arguments but the cloud, refused as rayscan.visibility refuses them before it reads a file
/// (jobs::check_options, in rayscan.visibility's words); what needs the points is the tasks'.
void check_visibility(const py::object& observers, py::handle radius, py::handle height, py::handle max_distance,
                      py::handle tolerance, py::handle target_height, py::handle sky_rays, py::handle camera,
                      py::handle distance, py::handle threads, py::handle cache, py::handle ground_radius) {
  jobs::VisibilityJobOptions o = visibility_options(observers, radius, height, max_distance, tolerance, target_height,
                                                    sky_rays, camera, distance, threads, cache, ground_radius);
  run_naming_keywords("visibility", [&] { jobs::check_options(o); },
                      [&](std::string m) { return one_row_number(o.observers, std::move(m)); });
}

/// rayscan.dask.solar's check at the call: rayscan.solar's arguments but the cloud, refused as
/// rayscan.solar refuses them before it reads a file (jobs::check_options); the weather file is
/// the tasks' to open, as the cloud is (a client need not see the workers' files).
void check_solar(py::handle start, py::handle end, py::handle step, py::handle at, py::handle latitude,
                 py::handle longitude, py::handle linke, py::handle albedo, const py::object& weather,
                 py::handle sector, py::handle sky_rays, py::handle primitive, py::handle radius, py::handle threads,
                 py::handle cache) {
  jobs::SolarJobOptions o = solar_options(start, end, step, at, latitude, longitude, linke, albedo, weather, sector,
                                          sky_rays, primitive, radius, threads, cache, false);
  run_naming_keywords("solar", [&] { jobs::check_options(o); });
}

/// The names of `names` as a Python tuple of str.
template <std::size_t N>
py::tuple name_tuple(const std::array<std::string_view, N>& names) {
  py::tuple t(N);
  for (std::size_t i = 0; i < N; ++i) t[i] = py::str(names[i].data(), names[i].size());
  return t;
}

/// True when rayscan.open(path) would query the file in place without reading it whole: an index
/// file or a COPC file, as Site::opens_in_place decides for Site::open (the COPC test reads the
/// header's bytes, whatever the name), with rayscan.open's options. False for a file that
/// cannot be read (rayscan.open raises for it).
bool opens_in_place(py::handle path) {
  const std::filesystem::path p = path_arg(path, "path");
  py::gil_scoped_release nogil;
  return Site::opens_in_place(p, SiteOptions{});
}

}  // namespace

void bind_jobs(py::module_& m) {
  // A job stopped by its cancel flag (run_interruptible raises the signal's own exception
  // instead; this covers a Cancelled that reaches Python otherwise).
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled&) {
      PyErr_SetNone(PyExc_KeyboardInterrupt);
    }
  });
  m.def("_render", &render, py::arg("scene"), py::arg("scene_json") = "", py::arg("cloud") = py::none(),
        py::arg("width") = py::none(),
        py::arg("height") = py::none(), py::arg("spp") = py::none(), py::arg("seed") = py::none(),
        py::arg("aovs") = py::tuple(), py::arg("camera") = py::none(), py::arg("threads") = 0);
  m.def("_ortho_map", &ortho_map, py::arg("cloud"), py::arg("res"), py::arg("spp") = py::none(),
        py::arg("seed") = py::none(), py::arg("threads") = 0, py::arg("colour") = "albedo");
  m.def("_compare", &compare, py::arg("reference"), py::arg("image"),
        py::arg("channels") = py::tuple(), py::arg("mask") = false, py::arg("alpha") = false,
        py::arg("resize") = false, py::arg("fail") = py::none(), py::arg("fail_percent") = py::none(),
        py::arg("fail_psnr") = py::none(), py::arg("fail_ssim") = py::none(), py::arg("warn") = py::none());
  m.def("_visibility", &visibility, py::arg("cloud"), py::arg("observers") = py::none(),
        py::arg("radius") = py::none(), py::arg("height") = py::none(), py::arg("max_distance") = py::none(),
        py::arg("tolerance") = py::none(), py::arg("target_height") = py::none(), py::arg("sky_rays") = 0,
        py::arg("camera") = py::none(), py::arg("distance") = false, py::arg("threads") = 0,
        py::arg("cache") = "2G", py::arg("ground_radius") = py::none());
  m.def("_solar", &solar, py::arg("cloud"), py::arg("start") = py::none(), py::arg("end") = py::none(),
        py::arg("step") = "1h", py::arg("at") = py::none(), py::arg("latitude") = py::none(),
        py::arg("longitude") = py::none(), py::arg("linke") = 3.0, py::arg("albedo") = 0.2, py::arg("weather") = py::none(),
        py::arg("sector") = 1.0, py::arg("sky_rays") = 64, py::arg("primitive") = "sphere",
        py::arg("radius") = py::none(), py::arg("threads") = 0, py::arg("cache") = "2G");
  // solar()'s result fields, defined once in the library (rayscan.SOLAR_PERIOD_FIELDS, ...).
  m.attr("SOLAR_PERIOD_FIELDS") = name_tuple(jobs::kSolarPeriodFields);
  m.attr("SOLAR_INSTANT_FIELDS") = name_tuple(jobs::kSolarInstantFields);
  m.def("_opens_in_place", &opens_in_place, py::arg("path"));
  // rayscan.dask's checks at the call of the options of visibility and solar.
  m.def("_check_visibility", &check_visibility, py::arg("observers") = py::none(), py::arg("radius") = py::none(),
        py::arg("height") = py::none(), py::arg("max_distance") = py::none(), py::arg("tolerance") = py::none(),
        py::arg("target_height") = py::none(), py::arg("sky_rays") = 0, py::arg("camera") = py::none(),
        py::arg("distance") = false, py::arg("threads") = 0, py::arg("cache") = "2G",
        py::arg("ground_radius") = py::none());
  m.def("_check_solar", &check_solar, py::arg("start") = py::none(), py::arg("end") = py::none(),
        py::arg("step") = "1h", py::arg("at") = py::none(), py::arg("latitude") = py::none(),
        py::arg("longitude") = py::none(), py::arg("linke") = 3.0, py::arg("albedo") = 0.2,
        py::arg("weather") = py::none(), py::arg("sector") = 1.0, py::arg("sky_rays") = 64,
        py::arg("primitive") = "sphere", py::arg("radius") = py::none(), py::arg("threads") = 0,
        py::arg("cache") = "2G");
}

}  // namespace rayscan::python
