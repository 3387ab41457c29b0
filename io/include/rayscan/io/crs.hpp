// EPSG codes of a CRS given as WKT: what `rayscan info` reports beside the CRS's name for any
// file whose CRS is text (a LAS WKT VLR, a PLY comment, an index file's crs section); a CRS from
// the user's text; whether the writers may store a WKT; the units of its lengths and heights.
#pragma once

#include <optional>
#include <string>

namespace rayscan::io {

/// EPSG codes of a CRS; 0 where there is none.
struct EpsgCodes {
  int horizontal = 0;  ///< the projected or geographic CRS (of a compound CRS: its horizontal part)
  int vertical = 0;    ///< the vertical CRS of a compound (or vertical) CRS
};

/// The EPSG codes of the CRS in `wkt` (WKT1 or WKT2, read with GDAL's OGRSpatialReference, never
/// as a file name or URL): the horizontal one as the LAS reader identifies a WKT VLR's (the
/// PROJCS / GEOGCS authority, else PROJ's identification of the definition), the vertical one
/// from the vertical part's EPSG authority. {0, 0} for text GDAL cannot read; never throws.
[[nodiscard]] EpsgCodes epsg_codes_from_wkt(const std::string& wkt);

/// The CRS that `user_input` names, as WKT: WKT that GDAL reads is returned as given; an EPSG (or
/// other authority) code ("EPSG:2992"), PROJJSON or a PROJ string as WKT1, or WKT2 where WKT1
/// cannot express it. GDAL reads it with SET_FROM_USER_INPUT_LIMITATIONS: a file name or URL is
/// never opened. What the writers store and the LAS reader identifies by EPSG code. "" for text
/// GDAL cannot read. Throws std::invalid_argument, its message the reason without the argument's
/// name ("text after the WKT's closing bracket (character 689): 'GARBAGE'; expected nothing after it"), for a control
/// character (NUL included) anywhere, text after a WKT's closing bracket, and a CRS with a unit
/// whose size is not positive.
[[nodiscard]] std::string crs_wkt_from_user_input(const std::string& user_input);

/// A unit of length of a CRS, as GDAL reads it from the CRS's WKT.
struct LengthUnit {
  std::string name;     ///< GDAL's name: "metre", "foot", "US survey foot"; "unknown" for one known by its size alone
  double metres = 0.0;  ///< the unit's size in metres: positive and finite
};

/// The unit of x and y in the CRS of `wkt` (WKT1 or WKT2, read as epsg_codes_from_wkt reads it):
/// the linear unit of a projected CRS (of a compound CRS: its projected part's), of a local
/// (engineering) or of a geocentric one. nullopt where x and y are no lengths (a geographic CRS:
/// degrees) or the CRS has none (a vertical CRS alone), for "" or text GDAL cannot read, and for a
/// unit whose size is no positive finite number. The one rule for the unit of a distance or a cell
/// size; never throws.
[[nodiscard]] std::optional<LengthUnit> crs_horizontal_unit(const std::string& wkt);

/// The unit of z, the heights, in the CRS of `wkt`: the vertical CRS's unit where there is one (a
/// compound CRS such as EPSG:2992+5703, x and y in feet and heights in metres, or a vertical CRS
/// alone), else the ellipsoidal height's of a 3D geographic CRS, else crs_horizontal_unit (a
/// projected CRS without a vertical part: z is taken in the one unit the CRS names).
/// nullopt for a 2D geographic CRS, "" or text GDAL cannot read, and a unit whose size is no
/// positive finite number. The one rule for the unit of an elevation (a DSM's band, a site's
/// height above the datum); never throws.
[[nodiscard]] std::optional<LengthUnit> crs_vertical_unit(const std::string& wkt);

/// Whether GDAL reads `wkt` as a CRS (OSRImportFromWkt, never as a file name or URL): the check
/// the writers make before they store a CRS. Never throws.
[[nodiscard]] bool crs_wkt_readable(const std::string& wkt);

/// The first 40 characters of the CRS text `wkt` ("..." after them when there are more), on one
/// line: how a message quotes a CRS that GDAL cannot read. Never throws but std::bad_alloc.
[[nodiscard]] std::string crs_excerpt(const std::string& wkt);

/// "<name>: the CRS is WKT that GDAL cannot read ('<crs_excerpt>')": how a message names the file
/// `name` whose CRS `wkt` GDAL cannot read (require_readable_crs, a writer that drops it).
[[nodiscard]] std::string unreadable_crs(const std::string& name, const std::string& wkt);

/// Throws std::invalid_argument "<unreadable_crs>; expected a CRS GDAL reads, or none" unless
/// `wkt` is empty or GDAL reads it (crs_wkt_readable): the one rule of every writer that stores a
/// CRS (LAS, LAZ, PLY, COPC, GeoTIFF), since GDAL, PDAL and QGIS reject a file whose WKT they
/// cannot parse. `name` is the file to blame: the output a point writer was given, or the input
/// whose CRS an output that needs one would carry.
void require_readable_crs(const std::string& name, const std::string& wkt);

}  // namespace rayscan::io
