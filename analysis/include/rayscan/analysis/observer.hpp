// Observers of a visibility analysis (`rayscan visibility`): eye positions,
// optionally given as a height above the local ground, each with optional angle and range limits.
#pragma once

#include "rayscan/base/coordinate_bound.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/site/site.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <filesystem>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan::analysis {

/// A malformed observer list. what() is one line naming the file, the line or JSON pointer, and
/// what was expected: "obs.csv: line 3: column 'height': expected a number, got 'abc'".
/// An OptionError (std::invalid_argument), so that a hint naming an option ("a default height
/// (height)") reaches the command line as its flag.
struct ObserverError : OptionError {
  explicit ObserverError(const std::string& message) : OptionError({message}) {}
  explicit ObserverError(std::vector<Part> parts) : OptionError(std::move(parts)) {}
};

/// The largest magnitude of an observer's coordinates (x, y, z) and eye height, world units (the
/// bound of `visibility --height` too): the point readers' bound, kMaxCoordinate, so that an eye
/// may sit anywhere a point may, and a line of sight from an accepted eye never fails inside the
/// ray code.
inline constexpr double kMaxObserverCoordinate = kMaxCoordinate;

/// A closed range of angles in degrees.
///  - Azimuth (horizontal): compass bearing, clockwise from grid north (+Y) towards east (+X), the
///    GIS/ArcGIS viewshed convention (AZIMUTH1/AZIMUTH2). The range runs clockwise from `lo` to
///    `hi` and may wrap through north: {315, 45} is north +-45 degrees. lo, hi in [0, 360];
///    hi - lo (mod 360) = 0 with lo != hi, e.g. {0, 360}, is the full circle.
///  - Elevation (vertical): angle above the horizontal plane, -90 (straight down) .. +90 (straight
///    up), lo <= hi (ArcGIS VERT1/VERT2).
struct AngleRange {
  double lo = 0.0;
  double hi = 0.0;
};

/// One observer (eye). Coordinates are in the cloud's world frame and units.
struct Observer {
  std::string name;            ///< label for reports ("" = "observer <n>", 1-based)
  Vec3 position{0.0};          ///< eye; z is valid when has_z or after place_observers()
  bool has_z = false;          ///< z was given (absolute) rather than as a height
  std::optional<double> height;  ///< eye height above the local ground (world units), if given so
  double ground_z = std::numeric_limits<double>::quiet_NaN();  ///< local ground, set by place_observers
  std::optional<AngleRange> azimuth;    ///< horizontal limit (see AngleRange); unset = 360 degrees
  std::optional<AngleRange> elevation;  ///< vertical limit (see AngleRange); unset = -90..90
  std::optional<double> max_distance;   ///< this observer's range; unset = the run's maximum distance
  /// Where it was defined, for error messages: "<file>: /<i>" (JSON pointer), "<file>: line <n>"
  /// (CSV), "--observer '<text>'" (command line); empty when built in code.
  std::string source;
};

/// Read an observer list; the format is chosen by extension: .json, or .csv/.txt.
///
/// JSON: an array of observers or {"observers": [...]}; each observer is an object with
/// "position": [x, y, z] (absolute) or [x, y] plus "height": h (eye h above the local ground), and
/// optionally "name", "azimuth": [from, to], "elevation": [lo, hi] (degrees, see AngleRange) and
/// "max_distance". Unknown keys are errors (they are typos).
///
/// CSV: a header line naming the columns, then one observer per line. Columns (any order): x, y
/// (required), z, height, name, azimuth_from, azimuth_to, elevation_min, elevation_max,
/// max_distance. Empty cells are unset. Lines starting with '#' and blank lines are skipped.
///
/// Every observer needs z or height (or neither when `default_height` will be given to
/// place_observers); z and height together are an error. A key given twice in one JSON object is
/// an error (io::parse_json_text). Throws ObserverError (one line: file, line or JSON pointer,
/// expectation) for unreadable or malformed files, non-finite numbers, coordinates or heights
/// beyond +-kMaxObserverCoordinate, angles out of range or a negative max_distance.
std::vector<Observer> read_observers(const std::filesystem::path& path);

/// Parse one observer given as text, "x,y,z" (absolute) or "x,y" (height from place_observers'
/// default). `source` names it in messages and in Observer::source (default: "observer 'TEXT'").
/// Throws ObserverError naming it and the coordinate when one is not a finite number within
/// +-kMaxObserverCoordinate.
Observer parse_observer(std::string_view text, std::string source = {});

/// Checks one observer's values (coordinates and height finite and within
/// +-kMaxObserverCoordinate, angle ranges, max_distance >= 0, not both z and height). `where`
/// prefixes the message. Throws ObserverError.
void validate_observer(const Observer& o, const std::string& where);

/// How the local ground under an observer is found.
struct GroundOptions {
  /// Horizontal search radius around the observer's (x, y), world units (> 0).
  double radius = 5.0;
  /// Height used for observers that have neither z nor a height; unset = such observers are an
  /// error. Must be finite and within +-kMaxObserverCoordinate (place_observers throws
  /// ObserverError naming `height` otherwise).
  std::optional<double> default_height;
  /// When set (> 0), the ground is first searched within this smaller radius (the surface right
  /// under the eye: on a slope the lowest point within `radius` lies downhill, putting the eye too
  /// low), and within `radius` only when that holds no usable point. World units.
  std::optional<double> inner_radius;
};

/// The local ground at (x, y): the lowest z among the cloud's points within horizontal distance
/// `radius` of (x, y) (a vertical cylinder). When the cloud has classifications and the cylinder
/// holds points of ASPRS class 2 (ground; LAS 1.4 R15 table 17), only those count; points of class 7
/// (low noise) and 18 (high noise) never count. Returns NaN when the cylinder holds no usable point.
/// `cloud` holds the site's points in original order (for an index file: by ids(), slot order for
/// a file built without ids, docs/index-format.md "Ids"; for a COPC file in place: file order,
/// read_point_cloud(), its box query running in a CopcIndex::QueryScope).
double local_ground(const Site& site, const PointCloud& cloud, double x, double y, double radius);

/// Resolves every observer's eye z: observers with a height (or, lacking z and height, the default
/// height) get z = local_ground + height. Fills ground_z for those. Throws ObserverError naming the
/// observer when no ground point lies within the radius, or it has neither z nor a height and there
/// is no default; naming `height` when the default height is not finite or beyond
/// +-kMaxObserverCoordinate. `cloud` holds the site's points in original order (as for
/// local_ground).
void place_observers(std::vector<Observer>& observers, const Site& site, const PointCloud& cloud,
                     const GroundOptions& options);

/// True when `dir` (from the observer, need not be unit) lies inside the observer's azimuth and
/// elevation limits. A direction with no horizontal component (straight up or down) passes any
/// azimuth limit. Inclusive bounds.
bool within_angle_limits(const Observer& o, const Vec3& dir);

/// The observer's field of view as every line of sight applies it: a target at `v` from the eye
/// (world units; `length` = |v|, which the caller has) is in view when `length` <= max_distance
/// (the observer's own max_distance when set, else the run's; +inf = no limit) and `v` lies inside
/// its angle limits (within_angle_limits). NaN lengths are out of view.
bool within_view_limits(const Observer& o, double max_distance, const Vec3& v, double length);

/// The observer's label: its name, or "observer <number>" (1-based `number`).
std::string observer_label(const Observer& o, std::size_t number);

/// observer_label prefixed with the observer's source when known, for error messages:
/// "obs.json: /1: observer 2", "obs.csv: line 3: observer 2", or just "observer 2".
std::string observer_where(const Observer& o, std::size_t number);

}  // namespace rayscan::analysis
