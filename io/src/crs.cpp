// CRS handling for LAS: GeoKeys (LAS 1.4 R15 section 2.5.2, GeoTIFF 1.0 section 2.4 "GeoKey
// directory" and 6.3 key codes) to EPSG codes, EPSG codes to WKT through GDAL/OSR (PROJ
// database), and back from a WKT to its EPSG codes (rayscan/io/crs.hpp). GDAL stays inside
// rayscan_io; the core library never sees it.
#include "readers.hpp"

#include "rayscan/io/crs.hpp"

#include <gdal/cpl_conv.h>
#include <gdal/cpl_error.h>
#include <gdal/ogr_srs_api.h>

#include <memory>
#include <mutex>

namespace rayscan::io::detail {

namespace {

constexpr std::uint16_t kGeographicType = 2048;  // GeographicTypeGeoKey
constexpr std::uint16_t kProjectedCSType = 3072;  // ProjectedCSTypeGeoKey
constexpr std::uint16_t kVerticalCSType = 4096;   // VerticalCSTypeGeoKey
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

std::string wkt_for(const std::string& user_input) {
  quiet_gdal();
  Srs srs(OSRNewSpatialReference(nullptr));
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  if (OSRSetFromUserInput(h, user_input.c_str()) != OGRERR_NONE) return "";
  return to_wkt(h);
}

}  // namespace

std::string crs_from_geokeys(const std::uint8_t* data, std::uint64_t len, FileInfo& info) {
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
  int projected = 0, geographic = 0, vertical = 0;
  for (std::uint16_t k = 0; k < nkeys; ++k) {
    const std::uint8_t* e = data + 8 + 8 * k;
    const std::uint16_t id = load_le<std::uint16_t>(e);
    const std::uint16_t loc = load_le<std::uint16_t>(e + 2);
    const std::uint16_t value = load_le<std::uint16_t>(e + 6);
    if (loc != 0) continue;  // value stored in another tag (doubles/ASCII): not an EPSG code
    if (id == kProjectedCSType) projected = value;
    if (id == kGeographicType) geographic = value;
    if (id == kVerticalCSType) vertical = value;
  }
  const int horizontal = (projected != 0 && projected != kUserDefined)
                             ? projected
                             : (geographic != 0 && geographic != kUserDefined ? geographic : 0);
  if (horizontal == 0) {
    if (projected == kUserDefined || geographic == kUserDefined)
      info.notes.push_back("GeoKeys describe a user-defined CRS (code 32767): no EPSG code");
    return "";
  }
  info.epsg = horizontal;
  if (vertical != 0 && vertical != kUserDefined) info.vertical_epsg = vertical;
  std::string wkt;
  if (info.vertical_epsg != 0)
    wkt = wkt_for("EPSG:" + std::to_string(horizontal) + "+" + std::to_string(info.vertical_epsg));
  if (wkt.empty()) wkt = wkt_for("EPSG:" + std::to_string(horizontal));
  if (wkt.empty())
    info.notes.push_back("EPSG:" + std::to_string(horizontal) + " unknown to the PROJ database: no WKT");
  return wkt;
}

int epsg_from_wkt(const std::string& wkt) {
  quiet_gdal();
  Srs srs(OSRNewSpatialReference(nullptr));
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  // ImportFromWkt, never SetFromUserInput: the text comes from the file and must not be taken
  // as a file name or URL.
  std::string copy = wkt;
  char* p = copy.data();
  if (OSRImportFromWkt(h, &p) != OGRERR_NONE) return 0;
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

}  // namespace rayscan::io::detail

namespace rayscan::io {

EpsgCodes epsg_codes_from_wkt(const std::string& wkt) {
  EpsgCodes codes;
  codes.horizontal = detail::epsg_from_wkt(wkt);
  detail::Srs srs(OSRNewSpatialReference(nullptr));
  auto* h = static_cast<OGRSpatialReferenceH>(srs.get());
  std::string copy = wkt;  // ImportFromWkt, as epsg_from_wkt: never a file name or URL
  char* p = copy.data();
  if (OSRImportFromWkt(h, &p) != OGRERR_NONE) return codes;
  const char* auth = OSRGetAuthorityName(h, "VERT_CS");
  const char* code = OSRGetAuthorityCode(h, "VERT_CS");
  if (auth != nullptr && code != nullptr && std::string(auth) == "EPSG") codes.vertical = std::atoi(code);
  return codes;
}

}  // namespace rayscan::io
