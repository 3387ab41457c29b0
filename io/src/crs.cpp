// CRS handling for LAS: GeoKeys (LAS 1.4 R15 section 2.5.2, GeoTIFF 1.0 section 2.4 "GeoKey
// directory" and 6.3 key codes) to EPSG codes, EPSG codes to WKT through GDAL/OSR (PROJ
// database) with the unit keys applied as GDAL's GeoTIFF reader applies them (GeoTIFF 1.1, OGC
// 19-008r4, clause 7.5), and back from a WKT to its EPSG codes (rayscan/io/crs.hpp). GDAL and PROJ
// stay inside rayscan_io; the core library never sees them.
#include "readers.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/io/crs.hpp"

#include <gdal/cpl_conv.h>
#include <gdal/cpl_error.h>
#include <gdal/ogr_spatialref.h>
#include <gdal/ogr_srs_api.h>
#include <proj.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string_view>

namespace rayscan::io::detail {

namespace {

// GeoKey ids (GeoTIFF 1.0 section 6.2; GeoTIFF 1.1, OGC 19-008r4, clause 7 names them
// GeodeticCRSGeoKey, ProjectedCRSGeoKey and VerticalGeoKey).
constexpr std::uint16_t kGeographicType = 2048;    // GeographicTypeGeoKey
constexpr std::uint16_t kGeogAngularUnits = 2054;  // GeogAngularUnitsGeoKey
constexpr std::uint16_t kProjectedCSType = 3072;   // ProjectedCSTypeGeoKey
constexpr std::uint16_t kProjLinearUnits = 3076;   // ProjLinearUnitsGeoKey
constexpr std::uint16_t kProjLinearUnitSize = 3077;  // ProjLinearUnitSizeGeoKey (a double, metres)
constexpr std::uint16_t kVerticalCSType = 4096;    // VerticalCSTypeGeoKey
constexpr std::uint16_t kVerticalUnits = 4099;     // VerticalUnitsGeoKey
constexpr std::uint16_t kGeoDoubleParamsTag = 34736;
constexpr std::uint16_t kUserDefined = 32767;

struct SrsDeleter {
  void operator()(void* h) const { OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(h)); }
};
using Srs = std::unique_ptr<void, SrsDeleter>;

void quiet_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { CPLSetErrorHandler(CPLQuietErrorHandler); });
}

std::string to_wkt(OGRSpatialReferenceH h) {
  char* out = nullptr;
  const char* opts[] = {"FORMAT=WKT1", nullptr};
  std::string wkt;
  if (OSRExportToWktEx(h, &out, opts) == OGRERR_NONE && out != nullptr) wkt = out;
  CPLFree(out);
  return wkt;
}

/// The CRS `user_input` names, read by SetFromUserInput with GDAL's
/// SET_FROM_USER_INPUT_LIMITATIONS: EPSG and other authority codes, WKT, PROJJSON and PROJ strings,
/// never a file name or URL, which GDAL would otherwise open (a text from a user or a file must not
/// make the library read a local file or connect anywhere). Null when GDAL cannot read it.
Srs srs_from_user_input(const std::string& user_input) {
  quiet_gdal();
  Srs srs(OSRNewSpatialReference(nullptr));
  if (OGRSpatialReference::FromHandle(static_cast<OGRSpatialReferenceH>(srs.get()))
          ->SetFromUserInput(user_input.c_str(), OGRSpatialReference::SET_FROM_USER_INPUT_LIMITATIONS) != OGRERR_NONE)
    return nullptr;
  return srs;
}

/// The CRS of `wkt` as GDAL reads it (OSRImportFromWkt, which reads WKT1 and WKT2 and never takes
/// the text as a file name or URL, as SetFromUserInput would: the text comes from a file or a
/// user). Null when GDAL cannot read it.
Srs srs_from_wkt(const std::string& wkt) {
  quiet_gdal();
  Srs srs(OSRNewSpatialReference(nullptr));
  std::string copy = wkt;  // OSRImportFromWkt takes a char** and moves it past what it read
  char* p = copy.data();
  if (OSRImportFromWkt(static_cast<OGRSpatialReferenceH>(srs.get()), &p) != OGRERR_NONE) return nullptr;
  return srs;
}

/// WKT1 of `h`; with `wkt2_fallback`, WKT2_2019 where WKT1 cannot express the CRS.
std::string export_wkt(OGRSpatialReferenceH h, bool wkt2_fallback) {
  std::string wkt = to_wkt(h);
  if (wkt.empty() && wkt2_fallback) {
    char* out = nullptr;
    const char* opts[] = {"FORMAT=WKT2_2019", nullptr};
    if (OSRExportToWktEx(h, &out, opts) == OGRERR_NONE && out != nullptr) wkt = out;
    CPLFree(out);
  }
  return wkt;
}

/// WKT1 of `user_input` (srs_from_user_input). "" when GDAL cannot read it.
std::string wkt_for(const std::string& user_input) {
  const Srs srs = srs_from_user_input(user_input);
  return srs ? to_wkt(static_cast<OGRSpatialReferenceH>(srs.get())) : std::string();
}

/// The CRS of an EPSG code, or null when the PROJ database does not know it.
Srs srs_for_epsg(int code) { return srs_from_user_input("EPSG:" + std::to_string(code)); }

/// A unit as GDAL reports it: its name (null when GDAL gives none) and its size, unchecked.
struct ReportedUnit {
  const char* name = nullptr;
  double size = 0.0;
};

/// The unit of x and y of `h` (crs_horizontal_unit's rule), or nullopt where they are no lengths.
/// OSRGetLinearUnits gives a compound CRS's horizontal part's unit, but is asked only where x and y
/// are lengths: of a geographic CRS it gives "unknown", of a geographic compound one the vertical
/// unit.
std::optional<ReportedUnit> horizontal_unit(OGRSpatialReferenceH h) {
  if (!OSRIsProjected(h) && !OSRIsLocal(h) && !OSRIsGeocentric(h)) return std::nullopt;
  char* name = nullptr;
  const double size = OSRGetLinearUnits(h, &name);
  return ReportedUnit{name, size};
}

/// The unit of z of `h` (crs_vertical_unit's rule), or nullopt where there is none.
/// OSRGetLinearUnits gives a compound CRS's horizontal unit, never its vertical one.
std::optional<ReportedUnit> vertical_unit(OGRSpatialReferenceH h) {
  char* name = nullptr;
  // GDAL finds a compound CRS's vertical part in its WKT1 form; where it cannot write that (a part
  // WKT1 cannot express, a unit of size 0) it reports "unknown" of size 1, which is no unit read.
  if (OSRIsCompound(h) && OSRGetAttrValue(h, "VERT_CS", 0) == nullptr) return std::nullopt;
  if (OSRIsVertical(h)) {  // a vertical CRS, or a compound one with a vertical part
    const double size = OSRGetTargetLinearUnits(h, "VERT_CS", &name);
    return ReportedUnit{name, size};
  }
  if (OSRIsGeographic(h)) {
    if (OSRGetAxesCount(h) != 3) return std::nullopt;
    const double size = OSRGetLinearUnits(h, &name);  // of a 3D geographic CRS: the ellipsoidal height's
    return ReportedUnit{name, size};
  }
  return horizontal_unit(h);
}

/// `unit` as a LengthUnit, or nullopt when its size is no positive finite number.
std::optional<LengthUnit> length_unit(const std::optional<ReportedUnit>& unit) {
  if (!unit || !(std::isfinite(unit->size) && unit->size > 0.0)) return std::nullopt;
  return LengthUnit{unit->name != nullptr ? unit->name : "unknown", unit->size};
}

/// The first unit of `h` whose size is no positive finite number, in words ("linear unit 'foot'
/// of size 0"); "" when all are. GDAL reads UNIT["foot",0] without complaint, and every length or
/// angle in that CRS would then be 0 or infinite.
std::string bad_unit(OGRSpatialReferenceH h) {
  auto check = [](const char* kind, const std::optional<ReportedUnit>& unit) -> std::string {
    if (!unit || (std::isfinite(unit->size) && unit->size > 0.0)) return "";
    return std::string(kind) + " unit '" + (unit->name != nullptr ? unit->name : "unnamed") + "' of size " +
           shortest_text(unit->size);
  };
  std::string bad = check("linear", horizontal_unit(h));
  if (bad.empty() && (OSRIsGeographic(h) || OSRIsProjected(h))) {
    char* name = nullptr;
    const double size = OSRGetAngularUnits(h, &name);
    bad = check("angular", ReportedUnit{name, size});
  }
  if (bad.empty()) bad = check("vertical", vertical_unit(h));
  return bad;
}

/// The length of the WKT at the start of `text`: up to and with the bracket that closes its first
/// one ('[' or '(' and their closing ones, which WKT1 and WKT2 both allow; brackets in "quoted
/// text", where "" stands for a quote, do not count). npos when none closes it.
std::size_t wkt_length(std::string_view text) {
  int depth = 0;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"') {
      quoted = !quoted;  // "" inside quotes: out and in again
    } else if (!quoted && (c == '[' || c == '(')) {
      ++depth;
    } else if (!quoted && (c == ']' || c == ')') && depth > 0 && --depth == 0) {
      return i + 1;
    }
  }
  return std::string_view::npos;
}

/// A unit of measure: its name and size in the SI unit of its kind (metres, radians).
struct Unit {
  std::string name;
  double to_si = 0.0;
  std::string kind;  ///< PROJ's category: "linear", "angular", "scale", ...
};

/// The EPSG unit `code` from PROJ's database (the one GDAL's CRSs come from), or nullopt.
std::optional<Unit> epsg_unit(int code) {
  // A context of its own: PROJ's default context may not be used from several threads at once,
  // and its log would print an unknown code on stderr, which the caller reports as a note.
  PJ_CONTEXT* ctx = proj_context_create();
  proj_log_level(ctx, PJ_LOG_NONE);
  const char* name = nullptr;
  const char* kind = nullptr;
  double to_si = 0.0;
  std::optional<Unit> unit;
  if (proj_uom_get_info_from_database(ctx, "EPSG", std::to_string(code).c_str(), &name, &to_si, &kind) != 0 &&
      name != nullptr && kind != nullptr && std::isfinite(to_si) && to_si > 0.0)
    unit = Unit{name, to_si, kind};
  proj_context_destroy(ctx);
  return unit;
}

/// The sizes a linear unit may have, in metres: a micrometre to a thousand kilometres. Every EPSG
/// length unit lies within (the millimetre, 0.001 m, to the nautical mile, 1852 m; the US survey
/// foot is 0.3048006 m); a size beyond is a corrupt double, not a unit: 1e-305 m turns the false
/// easting into infinity (a WKT GDAL cannot read back), 1e300 m puts every coordinate beyond the
/// Earth. PROJ's database also files rates (millimetres per year, 3.2e-11 m/s) as lengths; these
/// fall outside too.
constexpr double kMinLinearUnit = 1e-6, kMaxLinearUnit = 1e6;

/// Whether `size` (metres) is within kMinLinearUnit .. kMaxLinearUnit; false for NaN.
bool plausible_linear_unit(double size) { return size >= kMinLinearUnit && size <= kMaxLinearUnit; }

/// Whether GDAL reads `wkt` back (OSRImportFromWkt): what a writer may store as the CRS.
bool wkt_readable(const std::string& wkt) { return srs_from_wkt(wkt) != nullptr; }

/// Whether two unit sizes are the same unit: equal but for the rounding of a WKT's 15 digits.
bool same_size(double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(a, b); }

/// The start of the note that GeoKey `key` replaces the unit of `h` with `unit`: "GeoKeys: <crs>
/// in <unit> (<key>), not its <h's unit>", to which the caller adds the consequence; nullopt where
/// `h` has that unit already (same_size). An angular `unit` is compared with h's angular unit
/// (OSRGetAngularUnits), any other with its linear one (OSRGetLinearUnits: a projected or vertical
/// CRS).
std::optional<std::string> unit_change(OGRSpatialReferenceH h, const Unit& unit, const std::string& crs,
                                       const char* key) {
  char* old_name = nullptr;
  const double old_size = unit.kind == "angular" ? OSRGetAngularUnits(h, &old_name) : OSRGetLinearUnits(h, &old_name);
  if (same_size(old_size, unit.to_si)) return std::nullopt;
  return "GeoKeys: " + crs + " in " + unit.name + " (" + key + "), not its " +
         (old_name != nullptr ? old_name : "unit");
}

/// The GeoKeys of a GeoKeyDirectoryTag: each key's {TIFFTagLocation, Count, Value_Offset}.
class GeoKeys {
 public:
  struct Entry {
    std::uint16_t location = 0, count = 0, value = 0;
  };

  void add(std::uint16_t id, Entry e) { entries_[id] = e; }

  /// A SHORT key's value (TIFFTagLocation 0), 0 when absent or stored in another tag (doubles,
  /// ASCII: no code).
  [[nodiscard]] int code(std::uint16_t id) const {
    const auto it = entries_.find(id);
    return it != entries_.end() && it->second.location == 0 ? it->second.value : 0;
  }

  /// A DOUBLE key's value: the GeoDoubleParamsTag entry at its Value_Offset (an index, not a byte
  /// offset), nullopt when the key, the tag or that entry is missing.
  [[nodiscard]] std::optional<double> real(std::uint16_t id, const GeoDoubles& doubles) const {
    const auto it = entries_.find(id);
    if (it == entries_.end() || it->second.location != kGeoDoubleParamsTag || it->second.count < 1 ||
        doubles.data == nullptr || it->second.value >= doubles.len / 8)
      return std::nullopt;
    return load_le<double>(doubles.data + 8ull * it->second.value);
  }

 private:
  std::map<std::uint16_t, Entry> entries_;
};

/// Applies ProjLinearUnitsGeoKey to `h`, the projected CRS of ProjectedCSTypeGeoKey `epsg`, as
/// GDAL's GeoTIFF reader does (GTIFGetOGISDefn): a unit that differs from the CRS's replaces it,
/// the parameters that are lengths (false easting and northing) converted to it
/// (OSRSetLinearUnitsAndUpdateParameters), and the CRS loses its EPSG code, being no longer the
/// registered one. GeoTIFF 1.1 (OGC 19-008r4) clause 7.5.1 "Requirements Class Units GeoKeys" and
/// 7.5.2 "Unit Size GeoKeys": the key holds an EPSG unit code, or 32767 with the unit's size in
/// metres in ProjLinearUnitSizeGeoKey. True when the unit changed.
bool apply_linear_unit(OGRSpatialReferenceH h, const GeoKeys& keys, const GeoDoubles& doubles, int epsg,
                       FileInfo& info) {
  const int code = keys.code(kProjLinearUnits);
  if (code == 0) return false;
  const std::string crs = "EPSG:" + std::to_string(epsg);
  std::optional<Unit> unit;
  if (code == kUserDefined) {
    const std::optional<double> size = keys.real(kProjLinearUnitSize, doubles);
    if (size && plausible_linear_unit(*size))
      unit = Unit{"unknown", *size, "linear"};  // GDAL's name for a unit known by its size alone
    else
      info.notes.push_back("GeoKeys: ProjLinearUnitsGeoKey is user-defined (32767) without a "
                           "ProjLinearUnitSizeGeoKey of 1e-06 to 1e+06 m" +
                           (size ? " (" + shortest_text(*size) + ")" : std::string()) + ": the unit of " + crs + " kept");
  } else {
    unit = epsg_unit(code);
    if (!unit || unit->kind != "linear" || !plausible_linear_unit(unit->to_si)) {
      info.notes.push_back("GeoKeys: ProjLinearUnitsGeoKey " + std::to_string(code) +
                           " is not an EPSG linear unit: the unit of " + crs + " kept");
      unit.reset();
    }
  }
  if (!unit) return false;
  const std::optional<std::string> change = unit_change(h, *unit, crs, "ProjLinearUnitsGeoKey");
  if (!change) return false;
  // The parameters converted must stay numbers GDAL writes and reads back (a false easting of
  // 1e308 m in a unit of 1e-6 m would not): tried on a copy first.
  const Srs trial(OSRClone(h));
  OSRSetLinearUnitsAndUpdateParameters(static_cast<OGRSpatialReferenceH>(trial.get()), unit->name.c_str(), unit->to_si);
  if (!wkt_readable(to_wkt(static_cast<OGRSpatialReferenceH>(trial.get())))) {
    info.notes.push_back("GeoKeys: " + crs + " in " + unit->name + " (ProjLinearUnitsGeoKey) has parameters that "
                         "are no finite numbers: the unit of " + crs + " kept");
    return false;
  }
  OSRSetLinearUnitsAndUpdateParameters(h, unit->name.c_str(), unit->to_si);
  if (code != kUserDefined) OSRSetAuthority(h, "PROJCS|UNIT", "EPSG", code);
  info.notes.push_back(*change + ", as GDAL reads them: a CRS without an EPSG code");
  return true;
}

/// Applies GeogAngularUnitsGeoKey to `h`, the geographic CRS of GeographicTypeGeoKey `epsg`, as
/// GDAL's GeoTIFF reader does: an EPSG angular unit that differs from the CRS's replaces it
/// (GeoTIFF 1.1 clause 7.5.1). A user-defined one (32767, GeogAngularUnitSizeGeoKey) is not read.
/// True when the unit changed.
bool apply_angular_unit(OGRSpatialReferenceH h, const GeoKeys& keys, int epsg, FileInfo& info) {
  const int code = keys.code(kGeogAngularUnits);
  if (code == 0) return false;
  const std::string crs = "EPSG:" + std::to_string(epsg);
  const std::optional<Unit> unit = code == kUserDefined ? std::nullopt : epsg_unit(code);
  if (!unit || unit->kind != "angular") {
    info.notes.push_back("GeoKeys: GeogAngularUnitsGeoKey " + std::to_string(code) +
                         " is not an EPSG angular unit: the unit of " + crs + " kept");
    return false;
  }
  const std::optional<std::string> change = unit_change(h, *unit, crs, "GeogAngularUnitsGeoKey");
  if (!change) return false;
  OSRSetAngularUnits(h, unit->name.c_str(), unit->to_si);
  info.notes.push_back(*change + ", as GDAL reads them");
  return true;
}

/// The kinds of CRS the GeoKeys name by EPSG code.
enum class CrsKind { projected, geographic, vertical };

/// The EPSG CRS `code` of GeoKey `key` (ProjectedCSTypeGeoKey, GeographicTypeGeoKey,
/// VerticalCSTypeGeoKey), which must be a CRS of `kind`: each key names one part of the CRS (GeoTIFF
/// 1.1, OGC 19-008r4, names them ProjectedCRSGeoKey, GeodeticCRSGeoKey and VerticalGeoKey), so a
/// compound CRS is none of them. Null, with a note that the key
/// is ignored, when the PROJ database does not know the code or it names another kind of CRS
/// (VerticalCSTypeGeoKey 4326, ProjectedCSTypeGeoKey 5703): the CRS is then read without that part.
Srs crs_of_kind(int code, CrsKind kind, const char* key, FileInfo& info) {
  const std::string what = std::string("GeoKeys: ") + key + " " + std::to_string(code);
  Srs srs = srs_for_epsg(code);
  if (!srs) {
    info.notes.push_back(what + " is unknown to the PROJ database: ignored");
    return nullptr;
  }
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  const bool compound = OSRIsCompound(h) != 0;
  const bool right = !compound && (kind == CrsKind::projected    ? OSRIsProjected(h) != 0
                                   : kind == CrsKind::geographic ? OSRIsGeographic(h) != 0
                                                                 : OSRIsVertical(h) != 0);
  if (right) return srs;
  const char* name = OSRGetName(h);
  const char* is = compound                ? "a compound CRS"
                   : OSRIsProjected(h)     ? "a projected CRS"
                   : OSRIsGeographic(h)    ? "a geographic CRS"
                   : OSRIsVertical(h)      ? "a vertical CRS"
                   : OSRIsGeocentric(h)    ? "a geocentric CRS"
                                           : "no CRS of these kinds";
  const char* expected = kind == CrsKind::projected ? "projected" : kind == CrsKind::geographic ? "geographic" : "vertical";
  info.notes.push_back(what + " (" + (name != nullptr ? name : "unnamed") + ") is " + is + ", not a " + expected +
                       " one: ignored");
  return nullptr;
}

/// A vertical CRS named `name` on datum `datum` whose heights are in `unit` (EPSG `code`).
Srs make_vertical(const char* name, const char* datum, const Unit& unit, int code) {
  Srs vert(OSRNewSpatialReference(nullptr));
  auto* v = static_cast<OGRSpatialReferenceH>(vert.get());
  OSRSetVertCS(v, name, datum, 2005);  // 2005: orthometric height (OGC 01-009 VD_ORTHOMETRIC), as GDAL
  OSRSetLinearUnits(v, unit.name.c_str(), unit.to_si);
  OSRSetAuthority(v, "VERT_CS|UNIT", "EPSG", code);
  return vert;
}

/// The vertical CRS of the GeoKeys, or null: VerticalCSTypeGeoKey's EPSG CRS (info.vertical_epsg),
/// its unit replaced by VerticalUnitsGeoKey's where they differ (it then loses its code:
/// info.vertical_epsg = 0); or, with VerticalUnitsGeoKey alone, an "unknown" vertical CRS in that
/// unit, as GDAL's GeoTIFF reader builds it when it reports compound CRSs
/// (GTIFF_REPORT_COMPD_CS=YES): the unit of the heights is known where their datum is not.
/// GeoTIFF 1.1 clause 7.5.1; clause 7.5.2 has no size key for a user-defined vertical unit, so
/// 32767 is not read. `custom`: set when the result is not the EPSG CRS.
Srs vertical_crs(const GeoKeys& keys, FileInfo& info, bool& custom) {
  Srs vert;
  if (info.vertical_epsg != 0) vert = srs_for_epsg(info.vertical_epsg);
  const int code = keys.code(kVerticalUnits);
  if (code == 0) return vert;
  const std::optional<Unit> unit = code == kUserDefined ? std::nullopt : epsg_unit(code);
  if (!unit || unit->kind != "linear" || !plausible_linear_unit(unit->to_si)) {
    info.notes.push_back("GeoKeys: VerticalUnitsGeoKey " + std::to_string(code) +
                         " is not an EPSG linear unit: ignored");
    return vert;
  }
  custom = true;
  if (!vert) return make_vertical("unknown", "unknown", *unit, code);
  auto* v = static_cast<OGRSpatialReferenceH>(vert.get());
  const std::optional<std::string> change =
      unit_change(v, *unit, "vertical EPSG:" + std::to_string(info.vertical_epsg), "VerticalUnitsGeoKey");
  if (!change) {
    custom = false;
    return vert;
  }
  // GDAL 3.6 keeps the registered unit here. The heights are in the unit the keys name: what a LAS
  // writer means by US survey feet beside NAVD88 (EPSG:5703, metres).
  const char* name = OSRGetAttrValue(v, "VERT_CS", 0);
  const char* datum = OSRGetAttrValue(v, "VERT_DATUM", 0);
  info.notes.push_back(*change + ": a vertical CRS without an EPSG code");
  info.vertical_epsg = 0;
  return make_vertical(name != nullptr ? name : "unknown", datum != nullptr ? datum : "unknown", *unit, code);
}

/// crs_from_geokeys before its last check.
std::string geokeys_wkt(const std::uint8_t* data, std::uint64_t len, FileInfo& info, GeoDoubles doubles) {
  // GeoKeyDirectoryTag: header {KeyDirectoryVersion, KeyRevision, MinorRevision, NumberOfKeys}
  // then NumberOfKeys entries {KeyID, TIFFTagLocation, Count, Value_Offset}, all uint16.
  if (len < 8) {
    info.notes.push_back("GeoKeyDirectoryTag VLR shorter than its 8-byte header: ignored");
    return "";
  }
  const std::uint16_t nkeys = load_le<std::uint16_t>(data + 6);
  if (8 + 8ull * nkeys > len) {
    info.notes.push_back("GeoKeyDirectoryTag announces " + std::to_string(nkeys) +
                         " keys but holds " + std::to_string((len - 8) / 8) + ": ignored");
    return "";
  }
  GeoKeys keys;
  for (std::uint16_t k = 0; k < nkeys; ++k) {
    const std::uint8_t* e = data + 8 + 8 * k;
    keys.add(load_le<std::uint16_t>(e),
             {load_le<std::uint16_t>(e + 2), load_le<std::uint16_t>(e + 4), load_le<std::uint16_t>(e + 6)});
  }
  const int projected = keys.code(kProjectedCSType), geographic = keys.code(kGeographicType),
            vertical = keys.code(kVerticalCSType);
  // ProjectedCSTypeGeoKey first, else GeographicTypeGeoKey; a code that names no CRS of its key's
  // kind is ignored (crs_of_kind), as if the key were absent.
  int horizontal = 0;
  Srs horiz;
  if (projected != 0 && projected != kUserDefined &&
      (horiz = crs_of_kind(projected, CrsKind::projected, "ProjectedCSTypeGeoKey", info)))
    horizontal = projected;
  if (!horiz && geographic != 0 && geographic != kUserDefined &&
      (horiz = crs_of_kind(geographic, CrsKind::geographic, "GeographicTypeGeoKey", info)))
    horizontal = geographic;
  if (!horiz) {
    if (projected == kUserDefined || geographic == kUserDefined)
      info.notes.push_back("GeoKeys describe a user-defined CRS (code 32767): no EPSG code");
    return "";
  }
  info.epsg = horizontal;
  if (vertical != 0 && vertical != kUserDefined && crs_of_kind(vertical, CrsKind::vertical, "VerticalCSTypeGeoKey", info))
    info.vertical_epsg = vertical;
  auto* h = static_cast<OGRSpatialReferenceH>(horiz.get());
  bool custom = false;
  if (OSRIsProjected(h)) {
    custom = apply_linear_unit(h, keys, doubles, horizontal, info);
    if (custom) info.epsg = 0;
  } else if (OSRIsGeographic(h)) {
    custom = apply_angular_unit(h, keys, horizontal, info);
  }
  bool custom_vertical = false;
  const Srs vert = vertical_crs(keys, info, custom_vertical);
  if (!custom && !custom_vertical) {
    // The registered CRSs as they are: the compound one as PROJ builds "EPSG:h+v".
    std::string wkt;
    if (vert) wkt = wkt_for("EPSG:" + std::to_string(horizontal) + "+" + std::to_string(info.vertical_epsg));
    return wkt.empty() ? to_wkt(h) : wkt;
  }
  if (!vert) return to_wkt(h);
  // The compound CRS, named as "EPSG:h+v" names it: the two parts' names joined by " + ".
  auto* v = static_cast<OGRSpatialReferenceH>(vert.get());
  const char* hname = OSRGetName(h);
  const char* vname = OSRGetName(v);
  const std::string name =
      std::string(hname != nullptr ? hname : "unknown") + " + " + (vname != nullptr ? vname : "unknown");
  const Srs compound(OSRNewSpatialReference(nullptr));
  auto* c = static_cast<OGRSpatialReferenceH>(compound.get());
  if (OSRSetCompoundCS(c, name.c_str(), h, v) != OGRERR_NONE) return to_wkt(h);
  return to_wkt(c);
}

}  // namespace

std::string crs_from_geokeys(const std::uint8_t* data, std::uint64_t len, FileInfo& info, GeoDoubles doubles) {
  std::string wkt = geokeys_wkt(data, len, info, doubles);
  // The writers store this WKT: it must be one GDAL reads back (the unit checks above keep the
  // parameters finite; this holds whatever combination of keys a file has).
  if (!wkt.empty() && !wkt_readable(wkt)) {
    info.notes.push_back("GeoKeys: the CRS they describe is not one GDAL can write and read back: no CRS");
    info.epsg = info.vertical_epsg = 0;
    wkt.clear();
  }
  return wkt;
}

int epsg_from_wkt(const std::string& wkt) {
  const Srs srs = srs_from_wkt(wkt);
  if (!srs) return 0;
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  const char* key = OSRIsProjected(h) ? "PROJCS" : (OSRIsGeographic(h) ? "GEOGCS" : nullptr);
  if (key == nullptr) return 0;
  const char* auth = OSRGetAuthorityName(h, key);
  const char* code = OSRGetAuthorityCode(h, key);
  if (auth == nullptr || code == nullptr) {
    if (OSRAutoIdentifyEPSG(h) != OGRERR_NONE) return 0;
    auth = OSRGetAuthorityName(h, key);
    code = OSRGetAuthorityCode(h, key);
  }
  if (auth == nullptr || code == nullptr || std::string(auth) != "EPSG") return 0;
  return std::atoi(code);
}

std::optional<double> geographic_unit_degrees(const std::string& wkt) {
  if (wkt.empty()) return std::nullopt;
  const Srs srs = srs_from_wkt(wkt);
  if (!srs) return std::nullopt;
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  if (!OSRIsGeographic(h)) return std::nullopt;
  const double radians = OSRGetAngularUnits(h, nullptr);
  if (!(std::isfinite(radians) && radians > 0.0)) return std::nullopt;
  return radians * 180.0 / std::numbers::pi;
}

}  // namespace rayscan::io::detail

namespace rayscan::io {

std::string crs_wkt_from_user_input(const std::string& user_input) {
  // A control character has no place in any of the forms taken, and GDAL stops at a NUL, so that
  // what follows it would be stored unread (into a PLY header line, a LAS VLR).
  for (std::size_t i = 0; i < user_input.size(); ++i) {
    const auto c = static_cast<unsigned char>(user_input[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7F) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02X", c);
      throw std::invalid_argument("control character " + std::string(hex) + " at character " + std::to_string(i) +
                                  " (expected a CRS as text)");
    }
  }
  // WKT that GDAL reads is kept as given: the source's own text (an ESRI-flavoured WKT1, a WKT2
  // with details WKT1 lacks) is what the writers store and `rayscan info` shows. GDAL reads the
  // WKT and ignores any text after it, which must then be none.
  detail::Srs srs = detail::srs_from_wkt(user_input);
  std::string wkt;
  if (srs) {
    const std::size_t end = detail::wkt_length(user_input);
    if (end == std::string::npos) throw std::invalid_argument("the WKT's first bracket is never closed");
    if (const std::size_t after = user_input.find_first_not_of(" \t\n\r", end); after != std::string::npos)
      throw std::invalid_argument("text after the WKT's closing bracket (character " + std::to_string(end - 1) +
                                  "): '" + user_input.substr(after, 20) + (user_input.size() - after > 20 ? "...'" : "'") +
                                  "; expected nothing after it");
    wkt = user_input;
  } else {
    srs = detail::srs_from_user_input(user_input);
    if (!srs) return "";
    wkt = detail::export_wkt(static_cast<OGRSpatialReferenceH>(srs.get()), /*wkt2_fallback=*/true);
  }
  if (const std::string bad = detail::bad_unit(static_cast<OGRSpatialReferenceH>(srs.get())); !bad.empty())
    throw std::invalid_argument("the CRS has a " + bad + " (expected a positive size)");
  return wkt;
}

bool crs_wkt_readable(const std::string& wkt) { return detail::wkt_readable(wkt); }

std::string crs_excerpt(const std::string& wkt) { return one_line(wkt.substr(0, 40) + (wkt.size() > 40 ? "..." : "")); }

std::string unreadable_crs(const std::string& name, const std::string& wkt) {
  return name + ": the CRS is WKT that GDAL cannot read ('" + crs_excerpt(wkt) + "')";
}

void require_readable_crs(const std::string& name, const std::string& wkt) {
  if (wkt.empty() || crs_wkt_readable(wkt)) return;
  throw std::invalid_argument(unreadable_crs(name, wkt) + "; expected a CRS GDAL reads, or none");
}

namespace {

// The length unit `axis` (detail::horizontal_unit or detail::vertical_unit) finds in `wkt`, or
// nullopt for an empty or unreadable WKT or no such unit.
std::optional<LengthUnit> unit_of(const std::string& wkt,
                                  std::optional<detail::ReportedUnit> (*axis)(OGRSpatialReferenceH)) {
  if (wkt.empty()) return std::nullopt;
  const detail::Srs srs = detail::srs_from_wkt(wkt);
  if (!srs) return std::nullopt;
  return detail::length_unit(axis(static_cast<OGRSpatialReferenceH>(srs.get())));
}

}  // namespace

std::optional<LengthUnit> crs_horizontal_unit(const std::string& wkt) { return unit_of(wkt, detail::horizontal_unit); }

std::optional<LengthUnit> crs_vertical_unit(const std::string& wkt) { return unit_of(wkt, detail::vertical_unit); }

EpsgCodes epsg_codes_from_wkt(const std::string& wkt) {
  EpsgCodes codes;
  codes.horizontal = detail::epsg_from_wkt(wkt);
  const detail::Srs srs = detail::srs_from_wkt(wkt);
  if (!srs) return codes;
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  const char* auth = OSRGetAuthorityName(h, "VERT_CS");
  const char* code = OSRGetAuthorityCode(h, "VERT_CS");
  if (auth != nullptr && code != nullptr && std::string(auth) == "EPSG") codes.vertical = std::atoi(code);
  return codes;
}

}  // namespace rayscan::io
