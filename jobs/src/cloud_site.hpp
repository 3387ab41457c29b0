// What the point analyses (visibility, solar) share before their own work: the cloud read (or an
// index file mapped, or a COPC file's hierarchy opened), its index built, the sphere radius chosen, the surfels estimated, the output
// folders checked, and the cloud with its result fields written on the source's integer grid.
// Private to rayscan::jobs.
#pragma once

#include "rayscan/base/job.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/io/file_info.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_cloud.hpp"
#include "rayscan/octree/spacing.hpp"
#include "rayscan/site/site.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rayscan::jobs::detail {

/// A cloud opened for point analyses: its points (in original order) and the site over them.
/// Not movable: the site refers to `cloud` (Site::over).
struct CloudSite {
  PointCloud cloud;          ///< the points; for an index file, MappedIndex::to_point_cloud()
  io::FileInfo info;         ///< what the reader found (empty for memory and index files)
  std::string source;        ///< the file name, or the label of points in memory (open_cloud_site)
  std::optional<Site> site;  ///< the index over `cloud` (or the mapped index file, or the COPC
                             ///< file's own hierarchy: SiteStorage::copc)
  RadiusChoice radius;       ///< the sphere radius chosen

  CloudSite() = default;
  CloudSite(const CloudSite&) = delete;
  CloudSite& operator=(const CloudSite&) = delete;
};

/// How open_cloud_site opens a COPC file (a LAS/LAZ file with the COPC info VLR).
struct CopcOpen {
  /// Query the file's own hierarchy in place (io::CopcIndex, no tree built; the points are still
  /// read whole, in file order, as the output cloud) or, when false, read it whole and build
  /// `index` over it like any other point file (SiteOptions::copc_in_place).
  bool in_place = true;
  std::size_t cache_bytes = io::kCopcDefaultCacheBytes;  ///< decoded-node cache budget, bytes (in place)
};

/// The lengths of a point analysis's line of sight (VisibilityJobOptions, SolarJobOptions), each
/// nullopt when not given.
struct SightLengths {
  std::optional<double> radius;         ///< sphere radius: finite, > 0 (nullopt = auto)
  double radius_factor = kDefaultAutoRadiusFactor;  ///< auto_radius_factor_problem's range, given radius or not
  std::optional<double> tolerance;      ///< finite, >= 0
  std::optional<double> target_height;  ///< finite, >= 0
  std::optional<double> max_distance;   ///< >= 0, infinity = unlimited
};

/// Refuses a length of `s` out of its range before any point is read (the values alone decide):
/// OptionError naming the field with the value given, "tolerance: expected a finite number >= 0
/// (world units), got -1"; radius's ends "or auto" (its value nullopt, the CLI's word).
void check_sight_lengths(const SightLengths& s);

/// Fills `cs`: reads `file` (or copies `memory` when non-null, named `memory_label` in messages
/// and as `cs.source`: the options' source_label), or maps an index file in place
/// (read ahead: every point will be queried), or opens a COPC file's hierarchy in place (`copc`)
/// and reads its points whole as the output cloud; builds the index of type `index` (not for an
/// index file or a COPC file in place); chooses the sphere radius (choose_radius; on a COPC file
/// in place the same samples and value as read whole). Logs one line per stage through `ctl`.
/// Throws OptionError naming `index`, `radius` or `radius_factor`, io::FormatError for the file
/// (a COPC file whose records disagree with its header's point count included),
/// std::invalid_argument for a cloud without points.
void open_cloud_site(CloudSite& cs, const std::filesystem::path& file, const PointCloud* memory,
                     std::string_view memory_label, const IndexOptions& index, std::optional<double> radius, double radius_factor,
                     const JobControl& ctl, const CopcOpen& copc = {});

/// One log line on a COPC index after its queries: node decodes (re-decodes included) of the
/// hierarchy's nodes and the decoded bytes' peak against the `--cache` budget, with the remedy
/// when the peak passed it (the nodes the queries in flight hold cannot be evicted, so a budget
/// below what they reach together is exceeded by about that much).
std::string copc_cache_report(const io::CopcIndex& c);

/// After the queries of a run on a COPC file in place: sets `decodes` (node decodes, re-decodes
/// included) and `peak` (CopcIndex::peak_resident_bytes) and logs copc_cache_report; nothing
/// for any other storage.
void copc_cache_stats(const CloudSite& cs, const JobControl& ctl, std::uint64_t& decodes, std::size_t& peak);

/// A job's progress bar of a surfel estimate over `points` points (Progress on stderr when
/// ctl.progress: "points (surfels)", points/s): callback() is the SurfelOptions::progress that
/// advances it to the most points the estimate has reported done (reports come from worker
/// threads, not in order), empty without ctl.progress. The bar is cleared when this ends. Not
/// movable (the callback refers to it).
class SurfelBar {
 public:
  SurfelBar(std::size_t points, const JobControl& ctl);
  SurfelBar(const SurfelBar&) = delete;
  SurfelBar& operator=(const SurfelBar&) = delete;
  ~SurfelBar() { bar_.finish(); }
  [[nodiscard]] decltype(SurfelOptions::progress) callback();

 private:
  bool enabled_;
  Progress bar_;
  std::atomic<std::uint64_t> shown_{0};
};

/// The surfels (normals and disc radii) of every point of `cs`, file normals when the cloud has
/// them; no thickness measure (the analyses trace no bounce rays). Shows its progress (SurfelBar)
/// and logs one line. Throws
/// OptionError naming `primitive` when the estimate fails.
SurfelAttributes estimate_analysis_surfels(const CloudSite& cs, const SurfelOptions& options, const JobControl& ctl);

/// The CRS a cloud file names, from its header alone, before any point is read: an index file's
/// checked metadata, or the header a LAS/LAZ/COPC reader parses at open (as `rayscan info` does).
/// nullopt for the other formats, whose readers decode the whole file at open (io::PointReader):
/// their CRS comes with their points. Throws io::FormatError / io::IndexError for a bad header.
std::optional<std::string> header_crs(const std::filesystem::path& file);

/// Refuses, before any point is read, a CRS that a GeoTIFF output would carry and GDAL cannot
/// read: io::require_readable_crs (std::invalid_argument, one line, exit 2) naming the input,
/// `file`, or `memory_label` when `memory` is non-null, for the CRS of the points in memory or of
/// the file's header (header_crs). Nothing for a format whose CRS comes only with its points: the
/// job checks that once they are read. Throws io::FormatError / io::IndexError for a bad header.
void require_readable_header_crs(const std::filesystem::path& file, const PointCloud* memory,
                                 std::string_view memory_label);

/// Throws OptionError (one line, exit 2) with analysis::refuse_unprojected_crs's text when
/// `crs_wkt` is geographic or geocentric: x and y in degrees, or from the Earth's centre, are no
/// frame for `need` (what the job measures, plural: "sun directions"). Nothing for any other CRS,
/// or none ("").
void refuse_unprojected_crs(const std::string& crs_wkt, const std::string& need);

/// Throws OptionError naming `field` when `path` is a folder or its folder does not exist: outputs
/// are written to a temporary sibling and renamed, so a missing folder would fail only at the end
/// of a long run. An empty path is not an output.
void check_output_folder(const char* field, const std::filesystem::path& path);

/// The options of a top-down map: `raster` a GeoTIFF name (.tif) with a `cell` > 0, and
/// `raster_value` and `preview` only with a raster. Throws OptionError naming the fields.
void check_raster_options(const std::filesystem::path& raster, std::optional<double> cell,
                          const std::string& raster_value, const std::filesystem::path& preview);

/// The PNG preview of the map `raster`: `preview` when given, else the raster's name with .png
/// beside it (`maps/site.tif` -> `maps/site.png`); "" without a raster. The one rule for the
/// checks before a job's work and the write after it, so that both name the same file.
std::filesystem::path preview_path(const std::filesystem::path& raster, const std::filesystem::path& preview);

/// Sets (or adds) the scalar field `name` of `cloud`.
void set_scalar(PointCloud& cloud, const std::string& name, std::vector<double> values);

/// A description an output gives a result field instead of ResultFields' own: for a field whose
/// name one kind of run fills with another meaning (a day of shadows' sun_hours counts every
/// instant with the sun up, a period's only the hours of sunshine). A length's unit is still added.
struct FieldDescription {
  std::string_view name;
  std::string_view description;
};

/// The meaning, unit and no-data value of the per-point result fields of the point analyses
/// (visibility, solar) in one output of a cloud of CRS `crs_wkt` (WKT, "" for none), as their LAS
/// outputs describe them in the Extra Bytes VLR (at most 32 bytes, LAS 1.4 R15 table 24), their PLY
/// and PCD outputs in header comments and their reports and maps by unit: "global irradiation,
/// kWh/m2", "observer dist., foot". A length's unit is the CRS's, parsed once, at the first length
/// field asked for, so that one object describes every field of an output with one parse. Not
/// for concurrent use.
class ResultFields {
 public:
  /// `own`: descriptions replacing the table's (FieldDescription), copied.
  explicit ResultFields(std::string crs_wkt, std::span<const FieldDescription> own = {});

  /// The descriptor of result field `name`; none for another name (a field of the source cloud).
  [[nodiscard]] std::optional<io::ExtraBytesInfo> info(const std::string& name) const;

  /// The unit alone of result field `name`, the one its description ends with: "kWh/m2", "W/m2",
  /// "h", "observers", "pixels", "1" for a ratio or a flag, and for a length the CRS's linear unit
  /// ("metre", "foot", "US survey foot") or "world units" without a CRS
  /// (analysis::crs_length_unit); none for another name. For reports (`--json`) and the GeoTIFF
  /// maps' band units.
  [[nodiscard]] std::optional<std::string> unit(const std::string& name) const;

 private:
  const std::string& length_unit() const;

  std::string crs_wkt_;
  std::vector<std::pair<std::string, std::string>> own_;
  mutable std::optional<std::string> length_unit_;
};

/// True when an output of a point analysis uses its result field `name`, so that the job computes
/// it: every field with `all_fields` (the caller returns them all, as Python does) or `cloud_out`
/// (a cloud output writes them all); otherwise `raster_field`, the field the raster maps ("" for
/// no raster or none), and the fields a report prints, `report_fields`.
bool result_field_used(std::string_view name, bool all_fields, bool cloud_out, std::string_view raster_field,
                       std::span<const std::string_view> report_fields = {});

/// Writes `cloud` to `path` (format by extension); a LAS/LAZ output keeps the integer grid
/// (scale and offset), GPS time type and project GUID of a LAS/LAZ/COPC source described by
/// `info`, and LAS/LAZ, PLY and PCD outputs describe the analyses' result fields
/// (ResultFields, with the descriptions `own`: meaning, unit, no-data value; text has no place
/// for them).
void write_result_cloud(const std::filesystem::path& path, const PointCloud& cloud, const io::FileInfo& info,
                        std::span<const FieldDescription> own = {});

}  // namespace rayscan::jobs::detail
