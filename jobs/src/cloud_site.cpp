#include "cloud_site.hpp"

#include "rayscan/analysis/geotiff.hpp"
#include "rayscan/analysis/site_location.hpp"
#include "rayscan/analysis/solar_irradiation.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/io/point_reader.hpp"
#include "rayscan/jobs/solar.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>

namespace rayscan::jobs::detail {

void check_sight_lengths(const SightLengths& s) {
  const auto refuse = [](const char* field, double v, const char* expected) {
    throw OptionError({option(field), std::string(": expected ") + expected + ", got " + shortest_text(v)});
  };
  if (s.radius)
    if (const std::string why = sphere_radius_problem(*s.radius); !why.empty())
      throw OptionError({option("radius"), ": " + why + ", got " + shortest_text(*s.radius)});
  // Refused also with a given radius (which it does not affect), as a scene's auto_radius_factor
  // is: one range wherever a factor is given.
  if (const std::string why = auto_radius_factor_problem(s.radius_factor); !why.empty())
    throw OptionError({option("radius_factor"), ": " + why});
  if (s.tolerance && !(*s.tolerance >= 0.0 && std::isfinite(*s.tolerance)))
    refuse("tolerance", *s.tolerance, "a finite number >= 0 (world units)");
  if (s.target_height && !(*s.target_height >= 0.0 && std::isfinite(*s.target_height)))
    refuse("target_height", *s.target_height, "a finite number >= 0 (world units)");
  if (s.max_distance && !(*s.max_distance >= 0.0))
    refuse("max_distance", *s.max_distance, "a number >= 0 (world units; infinity: unlimited)");
}

void open_cloud_site(CloudSite& cs, const std::filesystem::path& file, const PointCloud* memory,
                     std::string_view memory_label, const IndexOptions& index, std::optional<double> radius,
                     double radius_factor,
                     const JobControl& ctl, const CopcOpen& copc) {
  // The jobs check these first (check_options); again here, as this reads the file.
  check_sight_lengths({radius, radius_factor, {}, {}, {}});
  char buf[512];
  auto t0 = std::chrono::steady_clock::now();
  cs.source = memory ? std::string(memory_label) : file.string();
  const char* how = "read";
  // An index file (.rsi) is queried in place (no tree is built); its points are copied to the
  // sources' original order (tiles concatenated in build order) as the output cloud, so the
  // per-point fields line up with the sources.
  if (memory)
    cs.cloud = *memory;
  else if (io::is_index_file(file)) {
    SiteOptions so;
    so.index_file.read_ahead = true;  // every point is read and many queried: read the file ahead
    cs.site.emplace(Site::open(file, so));
    cs.cloud = cs.site->index_file()->to_point_cloud();
    how = "mapped";
  } else if (copc.in_place && io::is_copc_file(file)) {
    // A COPC file is queried on its own hierarchy (nodes decoded as the queries reach them, within
    // the cache); the per-point fields still need every point, in file order (the order of the
    // hierarchy's ids), so the points are read whole too, but no tree is built over them.
    SiteOptions so;
    so.copc_cache_bytes = copc.cache_bytes;
    cs.site.emplace(Site::open(file, so));
    cs.cloud = io::read_point_cloud(file, {}, &cs.info);
    const std::uint64_t header = cs.site->copc()->info().point_count;
    if (cs.cloud.size() != header)
      throw io::FormatError(cs.source + ": " + std::to_string(cs.cloud.size()) +
                            " point records, the header's COPC hierarchy counts " + std::to_string(header));
    how = "read (COPC hierarchy queried in place)";
  } else {
    cs.cloud = io::read_point_cloud(file, {}, &cs.info);
  }
  if (cs.cloud.empty()) throw std::invalid_argument(cs.source + ": the point cloud has no points");
  std::snprintf(buf, sizeof buf, "%s %zu points from %s in %.2f s", how, cs.cloud.size(), cs.source.c_str(),
                seconds_since(t0));
  ctl.info(buf);
  if (const io::CopcIndex* c = cs.site ? cs.site->copc() : nullptr) {
    std::snprintf(buf, sizeof buf, "COPC: %zu nodes, cache %.1f MB", c->node_count(),
                  double(c->cache_bytes()) / 1048576.0);
    ctl.info(buf);
  }
  t0 = std::chrono::steady_clock::now();
  if (!cs.site) {
    try {
      cs.site.emplace(Site::over(cs.cloud, index));
    } catch (const std::invalid_argument& e) {
      throw OptionError({option("index"), std::string(": ") + e.what()});
    }
    std::snprintf(buf, sizeof buf, "built %s index in %.2f s", index.type.c_str(), seconds_since(t0));
    ctl.info(buf);
  }
  t0 = std::chrono::steady_clock::now();
  try {
    cs.radius = choose_radius(radius, radius_factor, [&] { return median_nn_spacing(*cs.site, cs.cloud.positions); });
  } catch (const std::invalid_argument&) {
    throw OptionError({option("radius"), " auto needs at least two distinct points; give a number"});
  }
  if (cs.radius.automatic) {
    std::snprintf(buf, sizeof buf, "radius auto: median nearest-neighbour spacing %.6g x %.3g = %.6g (%.2f s)",
                  cs.radius.spacing, cs.radius.factor, cs.radius.radius, seconds_since(t0));
    ctl.info(buf);
  }
}

std::string copc_cache_report(const io::CopcIndex& c) {
  char buf[320];
  const double peak = double(c.peak_resident_bytes()) / 1048576.0, budget = double(c.cache_bytes()) / 1048576.0;
  std::snprintf(buf, sizeof buf, "COPC: %llu node decodes (of %zu nodes), cache peak %.1f MB of %.1f MB%s",
                static_cast<unsigned long long>(c.decodes()), c.node_count(), peak, budget,
                c.peak_resident_bytes() > c.cache_bytes()
                    ? " (the nodes the rays in flight hold together passed the budget: raise --cache or lower --threads)"
                    : "");
  return buf;
}

void copc_cache_stats(const CloudSite& cs, const JobControl& ctl, std::uint64_t& decodes, std::size_t& peak) {
  const io::CopcIndex* c = cs.site ? cs.site->copc() : nullptr;
  if (!c) return;
  decodes = c->decodes();
  peak = c->peak_resident_bytes();
  ctl.info(copc_cache_report(*c));
}

SurfelBar::SurfelBar(std::size_t points, const JobControl& ctl)
    : enabled_(ctl.progress),
      bar_(points, ctl.progress, ProgressUnits{std::string("points (") + kSurfelPhase + ")", "points/s", 1.0, 0}) {}

decltype(SurfelOptions::progress) SurfelBar::callback() {
  if (!enabled_) return {};
  return [this](const char*, std::uint64_t done, std::uint64_t) {
    std::uint64_t shown = shown_.load();
    while (done > shown && !shown_.compare_exchange_weak(shown, done)) {
    }
    if (done > shown) bar_.add(done - shown, done - shown);
  };
}

SurfelAttributes estimate_analysis_surfels(const CloudSite& cs, const SurfelOptions& options, const JobControl& ctl) {
  const auto t0 = std::chrono::steady_clock::now();
  SurfelOptions so = options;
  so.measure_thickness = false;  // no shadow or bounce rays leave a surfel here (same_surface with 0)
  SurfelAttributes surfels;
  try {
    SurfelBar bar(cs.cloud.size(), ctl);
    so.progress = bar.callback();
    surfels = estimate_surfels(*cs.site, cs.cloud.positions, so, cs.cloud.normals);
  } catch (const std::invalid_argument& e) {
    throw OptionError({option("primitive"), std::string(" surfel: ") + e.what()});
  }
  char buf[256];
  std::snprintf(buf, sizeof buf, "surfels: %s normals, median disc radius %.6g, max %.6g, in %.2f s",
                cs.cloud.normals.empty() ? "PCA" : "file", surfels.median_radius, surfels.max_radius,
                seconds_since(t0));
  ctl.info(buf);
  return surfels;
}

std::optional<std::string> header_crs(const std::filesystem::path& file) {
  if (io::is_index_file(file)) {
    io::IndexOpenOptions oo;
    oo.verify = io::IndexOpenOptions::Verify::metadata_only;  // the nodes are checked when the site opens
    return io::MappedIndex::open(file, oo).crs_wkt();
  }
  if (io::format_from_extension(file) != io::Format::las) return std::nullopt;
  io::ReadOptions ro;
  ro.stored_colour = true;  // no pass over the colours at open
  return io::open_point_reader(file, io::AttributeSet::none(), ro)->crs_wkt();
}

void require_readable_header_crs(const std::filesystem::path& file, const PointCloud* memory,
                                 std::string_view memory_label) {
  if (memory) io::require_readable_crs(std::string(memory_label), memory->crs_wkt);
  else if (const std::optional<std::string> wkt = header_crs(file)) io::require_readable_crs(file.string(), *wkt);
}

void refuse_unprojected_crs(const std::string& crs_wkt, const std::string& need) {
  try {
    analysis::refuse_unprojected_crs(crs_wkt, need);
  } catch (const std::invalid_argument& e) {  // the analysis library's wording, as an option error
    throw OptionError({e.what()});
  }
}

void check_output_folder(const char* field, const std::filesystem::path& path) {
  if (path.empty()) return;
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(fs::status(path, ec)))
    throw OptionError({option(field), " '" + path.string() + "': is a folder, expected a file name"});
  const fs::path dir = path.parent_path();
  if (dir.empty()) return;  // the current folder
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st))
    throw OptionError({option(field), " '" + path.string() + "': folder '" + dir.string() + "' does not exist"});
  if (!fs::is_directory(st))
    throw OptionError({option(field), " '" + path.string() + "': '" + dir.string() + "' is not a folder"});
}

void check_raster_options(const std::filesystem::path& raster, std::optional<double> cell,
                          const std::string& raster_value, const std::filesystem::path& preview) {
  if (!raster.empty()) {
    if (!has_extension(raster, analysis::geotiff_extensions()))
      throw OptionError({option("raster"), " '" + raster.string() + "': expected a file name ending in .tif (GeoTIFF)"});
    if (!cell) throw OptionError({option("raster"), " needs ", option("cell"), " SIZE (cell edge in the cloud's units)"});
    if (!(*cell > 0.0) || !std::isfinite(*cell)) throw OptionError({option("cell"), ": expected a number > 0"});
  } else if (cell || !raster_value.empty() || !preview.empty()) {
    throw OptionError({option("cell"), ", ", option("raster_value"), " and ", option("preview"), " need ",
                       option("raster"), " OUT.tif"});
  }
}

std::filesystem::path preview_path(const std::filesystem::path& raster, const std::filesystem::path& preview) {
  if (raster.empty()) return {};
  if (!preview.empty()) return preview;
  return std::filesystem::path(raster).replace_extension(".png");
}

void set_scalar(PointCloud& cloud, const std::string& name, std::vector<double> values) {
  for (ScalarField& f : cloud.scalars)
    if (f.name == name) {
      f.values = std::move(values);
      return;
    }
  cloud.scalars.push_back({name, std::move(values)});
}

namespace {

/// What ResultFields says of one field.
struct ResultField {
  io::ExtraBytesInfo info;
  const char* unit;  ///< nullptr for a length, whose unit is the cloud's (analysis::crs_length_unit)
};

/// The Extra Bytes descriptor's description field holds 32 bytes (LAS 1.4 R15 table 24); a longer
/// text would be cut by the writer.
constexpr std::size_t kDescriptionBytes = 32;

/// The one table of the analyses' result fields. Descriptions fit the Extra Bytes descriptor's 32
/// bytes and end with the unit where there is one; units are ASCII for every reader, written as
/// the GeoTIFF bands write theirs ("1" for a ratio or a flag). A length's description is its
/// meaning alone here, short enough for ", " and the unit of most CRSs ("US survey foot" too),
/// which ResultFields::info adds.
std::optional<ResultField> table_field(const std::string& name) {
  static const std::map<std::string, ResultField, std::less<>> kFields = {
      {"visible_count", {{"observers that see the point", {}}, "observers"}},
      {"visible_distance", {{"observer dist.", -1.0}, nullptr}},
      {"sky_view", {{"sky view factor, 0-1", {}}, "1"}},
      {"camera_hits", {{"camera pixels seeing the point", {}}, "pixels"}},
      {"in_shadow", {{"1 shadow (or night), 0 sun", {}}, "1"}},
      {"irradiance_global", {{"global irradiance, W/m2", {}}, "W/m2"}},
      {"irradiance_beam", {{"beam irradiance, W/m2", {}}, "W/m2"}},
      {"irradiance_diffuse", {{"diffuse irradiance, W/m2", {}}, "W/m2"}},
      {"solar_global", {{"global irradiation, kWh/m2", {}}, "kWh/m2"}},
      {"solar_beam", {{"beam irradiation, kWh/m2", {}}, "kWh/m2"}},
      {"solar_diffuse", {{"diffuse irradiation, kWh/m2", {}}, "kWh/m2"}},
      {"solar_reflected", {{"reflected irradiation, kWh/m2", {}}, "kWh/m2"}},
      {"sun_hours", {{"sun hours, " + analysis::sunshine_criterion() + ", h", {}}, "h"}},
      {"shadow_hours", {{"hours in shadow (sun up), h", {}}, "h"}},
  };
  if (const auto it = kFields.find(name); it != kFields.end()) return it->second;
  // solar_global_01 .. solar_global_12: the months of the period.
  const std::size_t month = kSolarMonthlyPrefix.size();
  if (name.size() == month + 2 && name.starts_with(kSolarMonthlyPrefix) &&
      std::isdigit(static_cast<unsigned char>(name[month])) && std::isdigit(static_cast<unsigned char>(name[month + 1])))
    return ResultField{{"global irrad. month " + name.substr(month) + ", kWh/m2", {}}, "kWh/m2"};
  return std::nullopt;
}

}  // namespace

ResultFields::ResultFields(std::string crs_wkt, std::span<const FieldDescription> own) : crs_wkt_(std::move(crs_wkt)) {
  for (const FieldDescription& d : own) own_.emplace_back(d.name, d.description);
}

const std::string& ResultFields::length_unit() const {
  if (!length_unit_) length_unit_ = analysis::crs_length_unit(crs_wkt_);
  return *length_unit_;
}

std::optional<io::ExtraBytesInfo> ResultFields::info(const std::string& name) const {
  std::optional<ResultField> f = table_field(name);
  if (!f) return std::nullopt;
  for (const auto& [field, description] : own_)
    if (field == name) f->info.description = description;
  if (f->unit != nullptr) return std::move(f->info);
  // A unit name too long for the descriptor (a rare CRS's, "British foot (Sears 1922)") is named
  // where there is room: the CRS, and the unit of --json and the GeoTIFF band.
  const std::string described = f->info.description + ", " + length_unit();
  f->info.description = described.size() <= kDescriptionBytes ? described : f->info.description + ", CRS linear unit";
  return std::move(f->info);
}

std::optional<std::string> ResultFields::unit(const std::string& name) const {
  const std::optional<ResultField> f = table_field(name);
  if (!f) return std::nullopt;
  return f->unit != nullptr ? std::string(f->unit) : length_unit();
}

bool result_field_used(std::string_view name, bool all_fields, bool cloud_out, std::string_view raster_field,
                       std::span<const std::string_view> report_fields) {
  if (all_fields || cloud_out || (!raster_field.empty() && raster_field == name)) return true;
  return std::find(report_fields.begin(), report_fields.end(), name) != report_fields.end();
}

void write_result_cloud(const std::filesystem::path& path, const PointCloud& cloud, const io::FileInfo& info,
                        std::span<const FieldDescription> own) {
  io::LasWriteOptions las = io::las_grid_of(info);
  const ResultFields fields(cloud.crs_wkt, own);
  for (const ScalarField& f : cloud.scalars)
    if (auto d = fields.info(f.name)) las.extra_bytes[f.name] = std::move(*d);
  io::write_point_cloud(path, cloud, las);
}

}  // namespace rayscan::jobs::detail
