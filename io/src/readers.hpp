// Internal: the per-format readers behind read_point_cloud(). Each reads the whole Input and
// throws FormatError (see bytes.hpp) on malformed data.
#pragma once

#include "bytes.hpp"
#include "rayscan/io/point_reader.hpp"

#include <memory>
#include <optional>
#include <string>

namespace rayscan::io::detail {

/// Read-only memory map of a whole file (POSIX mmap). Empty files map to an empty span. Throws
/// FormatError when the file cannot be opened, is not a regular file or cannot be mapped.
class MappedFile {
 public:
  explicit MappedFile(const std::filesystem::path& path);
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();
  [[nodiscard]] std::span<const std::uint8_t> bytes() const { return {data_, size_}; }
  /// Drops the pages of [0, upto) from the resident set (they stay in the page cache) and asks
  /// for the next 256 MiB to be read ahead (MADV_WILLNEED). A call with a smaller `upto` than
  /// before starts a new pass.
  void release(std::uint64_t upto);
  /// Drops the pages holding bytes [begin, end) from the resident set (they stay in the page
  /// cache; a later read faults them in again): for a reader done with one part of the file
  /// while other threads may read the rest, since the mapping is read-only.
  void drop(std::uint64_t begin, std::uint64_t end) const;

 private:
  int fd_ = -1;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::uint64_t released_ = 0;
  std::uint64_t ahead_ = 0;  ///< [.., ahead_) was asked for (release's read ahead)
};

/// The bytes a chunked reader decodes: a mapped file (owned) or caller memory, as an Input.
struct Source {
  std::unique_ptr<MappedFile> map;  ///< null for caller memory
  Input in;
};

/// ASPRS LAS 1.0-1.4 (R15) chunked reader, also for LAZ and COPC (LASzip VLR present): LAZ
/// chunks are decoded on demand, only the layers the attributes need. See las_reader.cpp.
std::unique_ptr<PointReader> open_las(std::shared_ptr<Source> src, AttributeSet attrs,
                                      const ReadOptions& opt);
/// PLY 1.0 ascii / binary_little_endian / binary_big_endian. See ply_reader.cpp.
PointCloud read_ply(const Input& in, const ReadOptions& opt, FileInfo& info);
/// PCD 0.6/0.7 ascii / binary / binary_compressed. See pcd_reader.cpp.
PointCloud read_pcd(const Input& in, const ReadOptions& opt, FileInfo& info);
/// XYZ/CSV/TXT columns. See text_reader.cpp.
PointCloud read_text(const Input& in, const ReadOptions& opt, FileInfo& info);

/// The payload of a GeoDoubleParamsTag VLR ("LASF_Projection" 34736): little-endian doubles that
/// GeoKeys with TIFFTagLocation 34736 index. {nullptr, 0} when the file has none.
struct GeoDoubles {
  const std::uint8_t* data = nullptr;
  std::uint64_t len = 0;  ///< bytes; a trailing partial double is not read
};

/// CRS from the GeoKeys of a GeoKeyDirectoryTag VLR (LAS 1.4 R15 section 2.5.2; GeoTIFF 1.0
/// section 2.7): the EPSG projected, geographic and vertical CRSs of ProjectedCSTypeGeoKey,
/// GeographicTypeGeoKey and VerticalCSTypeGeoKey (PROJ database through GDAL/OSR), with the unit
/// keys applied as GDAL's GeoTIFF reader applies them: ProjLinearUnitsGeoKey (an EPSG unit, or
/// 32767 with ProjLinearUnitSizeGeoKey from `doubles`) and GeogAngularUnitsGeoKey replace the
/// CRS's unit where they differ; VerticalUnitsGeoKey that of the vertical CRS, or makes an unnamed
/// vertical CRS in that unit where there is none. Fills info.epsg / vertical_epsg (0 for a CRS
/// whose unit was replaced) and info.notes (a unit replaced, a key ignored); returns WKT1 when
/// GDAL/OSR can build it, else "". Never throws.
std::string crs_from_geokeys(const std::uint8_t* data, std::uint64_t len, FileInfo& info,
                             GeoDoubles doubles = {});
/// EPSG code identified from a WKT string (0 when OSR cannot identify it).
int epsg_from_wkt(const std::string& wkt);
/// The size in degrees of the angular unit of the latitude and longitude of `wkt` (read as
/// OSRImportFromWkt reads it, never as a file name or URL) when the CRS is geographic (of a
/// compound CRS: its horizontal part), e.g. 1 for degrees, 57.3 for radians; nullopt for no CRS,
/// text GDAL cannot read, a unit of no positive finite size, and a projected, geocentric or local
/// CRS, whose x and y are lengths. Never throws. See crs.cpp.
std::optional<double> geographic_unit_degrees(const std::string& wkt);

}  // namespace rayscan::io::detail
