#include "rayscan/analysis/geotiff.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/io/crs.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <system_error>

namespace rayscan::analysis {

namespace {

// Collects GDAL's error messages instead of letting it print them, for the duration of a scope,
// and keeps the first failure with the errno of the moment GDAL reported it: GDAL's file layer
// reports a failed system call at once ("_tiffWriteProc:No space left on device", from
// VSIStrerror(errno)), while the messages that follow from it ("TIFFRewriteDirectory:Error
// fetching directory count", the last one) no longer carry the cause and may name the file.
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandlerEx(&QuietGdal::handle, this);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;
  static std::string last() {
    const char* m = CPLGetLastErrorMsg();
    return m && *m ? m : "GDAL reported a failure without a message";
  }
  /// Forgets the failures so far, before a step whose own failures are checked (the close).
  void reset() {
    first_.reset();
    CPLErrorReset();
  }
  /// Whether GDAL reported a failure since construction or reset().
  [[nodiscard]] bool failed() const { return first_ || CPLGetLastErrorType() >= CE_Failure; }
  /// The error of the step `what` of writing `temp` (an AtomicFile's temporary: output_error names
  /// its output), "<output>: <what>: <cause>": the cause is the system's (strerror, the errno as
  /// code) when GDAL's first failure reported one, as a full disk's; else GDAL's message, with
  /// `temp` in it named as the output.
  [[nodiscard]] OutputFileError error(const std::filesystem::path& temp, const std::string& what) const {
    if (first_ && first_->err != 0 && first_->message.find(std::strerror(first_->err)) != std::string::npos)
      return output_error(temp, what, first_->err);
    std::string cause = first_ ? first_->message : last();
    const std::string t = temp.string(), out = output_of(temp).string();
    for (std::size_t at = cause.find(t); !t.empty() && at != std::string::npos; at = cause.find(t, at + out.size()))
      cause.replace(at, t.size(), out);
    return output_error(temp, what + ": " + cause, 0);
  }

 private:
  struct Failure {
    std::string message;
    int err;  // errno when GDAL reported it
  };
  static void CPL_STDCALL handle(CPLErr type, CPLErrorNum, const char* message) {
    const int err = errno;  // first: the failed call's, before anything here changes it
    auto* self = static_cast<QuietGdal*>(CPLGetErrorHandlerUserData());
    if (type < CE_Failure || self == nullptr || self->first_) return;
    try {
      self->first_ = Failure{message != nullptr ? message : "", err};
    } catch (...) {  // called from C: nothing may escape (the failure still counts, by GDAL's last error)
    }
  }
  std::optional<Failure> first_;
};

}  // namespace

std::string geotiff_band_unit(const GeoTiffOptions& options) {
  std::optional<io::LengthUnit> unit;
  if (options.unit_is_crs_height)
    unit = io::crs_vertical_unit(options.crs_wkt);
  else if (options.unit_is_crs_length)
    unit = io::crs_horizontal_unit(options.crs_wkt);
  else
    return options.unit;
  return unit ? unit->name : "";
}

std::string crs_length_unit(const std::string& crs_wkt) {
  const std::optional<io::LengthUnit> unit = io::crs_horizontal_unit(crs_wkt);
  return unit ? unit->name : "world units";
}

std::string crs_height_unit(const std::string& crs_wkt) {
  const std::optional<io::LengthUnit> unit = io::crs_vertical_unit(crs_wkt);
  return unit ? unit->name : "world units";
}

void write_geotiff(const std::filesystem::path& path, const Raster& raster, const GeoTiffOptions& options) {
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  const GridSpec& g = raster.grid;
  if (g.cols == 0 || g.rows == 0 || raster.values.size() != std::size_t(g.cols) * g.rows)
    throw std::invalid_argument(path.string() + ": raster size does not match its grid");
  if (g.cols > 0x7fffffffu || g.rows > 0x7fffffffu)
    throw std::invalid_argument(path.string() + ": raster too large for GDAL (int dimensions)");

  QuietGdal quiet;
  OGRSpatialReference srs;
  const bool has_crs = !options.crs_wkt.empty();
  if (has_crs) {
    if (srs.importFromWkt(options.crs_wkt.c_str()) != OGRERR_NONE)
      throw std::invalid_argument("crs: GDAL cannot parse the cloud's WKT (" + QuietGdal::last() + ")");
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }

  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!drv) throw std::runtime_error(path.string() + ": GDAL has no GTiff driver");
  AtomicFile file(path);  // removes the temporary unless committed
  const std::string tmp = file.temp().string();
  CPLStringList co;
  co.SetNameValue("COMPRESS", "DEFLATE");
  co.SetNameValue("PREDICTOR", "3");
  co.SetNameValue("TILED", "YES");
  co.SetNameValue("BLOCKXSIZE", "256");
  co.SetNameValue("BLOCKYSIZE", "256");
  co.SetNameValue("BIGTIFF", "IF_SAFER");
  auto fail = [&](const std::string& what) { throw quiet.error(file.temp(), what); };
  GDALDataset* ds = drv->Create(tmp.c_str(), int(g.cols), int(g.rows), 1, GDT_Float32, co.List());
  if (!ds) fail("cannot create GeoTIFF");
  bool ok = true;
  std::array<double, 6> gt = g.geotransform();
  ok = ok && ds->SetGeoTransform(gt.data()) == CE_None;
  if (has_crs) ok = ok && ds->SetSpatialRef(&srs) == CE_None;
  ds->SetMetadataItem("AREA_OR_POINT", "Area");
  for (const auto& [k, v] : options.metadata) ds->SetMetadataItem(k.c_str(), v.c_str());
  GDALRasterBand* band = ds->GetRasterBand(1);
  ok = ok && band->SetNoDataValue(options.nodata) == CE_None;
  band->SetDescription(raster.name.c_str());
  const std::string unit = geotiff_band_unit(options);
  if (!unit.empty()) ok = ok && band->SetUnitType(unit.c_str()) == CE_None;
  std::vector<float> data(raster.values);
  const float nd = static_cast<float>(options.nodata);
  for (float& v : data)
    if (std::isnan(v)) v = nd;
  ok = ok && band->RasterIO(GF_Write, 0, 0, int(g.cols), int(g.rows), data.data(), int(g.cols), int(g.rows),
                            GDT_Float32, 0, 0) == CE_None;
  if (!ok) {
    GDALClose(ds);
    fail("writing GeoTIFF failed");
  }
  quiet.reset();
  GDALClose(ds);  // flushes and writes the directory
  if (quiet.failed()) fail("closing GeoTIFF failed");
  // GDAL keeps statistics (gdalinfo -stats, QGIS) in path.aux.xml and external overviews
  // (gdaladdo -ro) in path.ovr; describing the old raster, they would be shown for the new one, so
  // they go as GDAL's Create removes them. Before the rename: a failure or a crash in between
  // leaves the old raster without them, which GDAL recomputes, never the new one with them.
  for (const char* sidecar : {".aux.xml", ".ovr"}) {
    const std::filesystem::path stale = path.string() + sidecar;
    std::error_code ec;
    if (!std::filesystem::remove(stale, ec) && ec && ec != std::errc::no_such_file_or_directory)
      throw output_error(path, "cannot remove the old raster's " + stale.filename().string(), ec.value());
  }
  file.commit();
}

const std::vector<std::string>& geotiff_extensions() {
  static const std::vector<std::string> exts{".tif", ".tiff"};
  return exts;
}

}  // namespace rayscan::analysis
