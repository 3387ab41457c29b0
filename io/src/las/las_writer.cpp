// LAS 1.4 writer (ASPRS LAS Specification 1.4 R15): public header block (section 2.4, 375 bytes),
// OGC WKT VLR (2.5.1, record 2112), Extra Bytes VLR (2.5.6, record 4 of "LASF_Spec"), point data
// record formats 6, 7 and 8 (2.6, tables 13-15), an EVLR (2.7) only for WKT longer than a VLR
// can hold.
#include "rayscan/io/point_io.hpp"

#include "atomic_writer.hpp"
#include "field_names.hpp"
#include "bytes.hpp"
#include "las/las_grid.hpp"
#include "las/las_header.hpp"
#include "readers.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/file_names.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/version.hpp"
#include "rayscan/io/translate.hpp"

#include <algorithm>
#include <array>
#include <optional>
#include <chrono>
#include <cmath>
#include <limits>

namespace rayscan::io {

namespace {

struct Standard {
  const std::vector<double>* ret = nullptr;
  const std::vector<double>* nret = nullptr;
  const std::vector<double>* angle = nullptr;
  const std::vector<double>* udata = nullptr;
  const std::vector<double>* psid = nullptr;
  const std::vector<double>* nir = nullptr;
  const std::vector<double>* cflags = nullptr;
  const std::vector<double>* channel = nullptr;
  const std::vector<double>* scan_dir = nullptr;
  const std::vector<double>* edge = nullptr;
};

/// One float64 Extra Bytes field of the output: a ScalarField, or one axis of the normals.
struct ExtraOut {
  std::string name;                           ///< name in the descriptor (<= 32 bytes, unique)
  const ExtraBytesInfo* info = nullptr;         ///< its description and no-data value, when given
  const std::vector<double>* values = nullptr;  ///< the scalar's values, or null for a normal axis
  int normal_axis = -1;                       ///< 0, 1, 2: PointCloud::normals' x, y or z
};

/// The Extra Bytes descriptor names (LAS 1.4 R15 table 24: 32 bytes, NUL-padded) for `names`, in
/// order, each one distinct so that readers keep every field apart: a name of at most 32 bytes
/// not used by an earlier field is kept; a longer name, or a repeated one, ends in "~1", "~2", ...
/// (the smallest number giving a name no other field has) after as much of the name as fits,
/// cut at a UTF-8 character boundary.
std::vector<std::string> unique_extra_names(const std::vector<std::string>& names) {
  std::vector<std::string> out;
  out.reserve(names.size());
  auto used = [&](const std::string& c) {
    if (std::find(out.begin(), out.end(), c) != out.end()) return true;
    // a later field that keeps its own name must not be pre-empted
    for (const std::string& n : names)
      if (n == c) return true;
    return false;
  };
  for (const std::string& name : names) {
    if (name.size() <= 32 && std::find(out.begin(), out.end(), name) == out.end()) {
      out.push_back(name);
      continue;
    }
    for (std::size_t k = 1;; ++k) {
      std::string suffix = "~";  // built by appending (GCC 12 -Wrestrict false positive on "~" + s)
      suffix += std::to_string(k);
      std::size_t cut = std::min(name.size(), 32 - suffix.size());
      while (cut > 0 && cut < name.size() && (static_cast<unsigned char>(name[cut]) & 0xC0) == 0x80) --cut;
      const std::string cand = name.substr(0, cut) + suffix;
      if (!used(cand)) {
        out.push_back(cand);
        break;
      }
    }
  }
  return out;
}

/// 10^e as the double nearest the decimal (1e-7, not 1e-8 x 10): the scales the writer picks.
double decimal_step(int e) {
  double p = 1.0;
  for (int i = 0; i < std::abs(e); ++i) p *= 10.0;  // exact up to 1e22
  return e < 0 ? 1.0 / p : p;
}

/// The exponent e of the finest default scale 10^e of LAS axis k (0 X, 1 Y, 2 Z) for a cloud
/// whose CRS's angular unit is `unit_degrees` when geographic (geographic_unit_degrees): -3 (a millimetre in metres, a thousandth of any other length unit); for the latitude
/// and longitude of a geographic CRS, the largest power of ten of its angular unit within 1e-7
/// degrees (about 1 cm on the ground; what LAStools and PDAL users write lat/lon LAS with): -7 in
/// degrees, -9 in radians, since a thousandth of a degree is about 100 m and would merge points.
int finest_scale_exponent(int k, const std::optional<double>& unit_degrees) {
  if (k == 2 || !unit_degrees) return -3;  // a geographic CRS's height is a length
  // + 1e-9: a degree that comes back from GDAL's radians a last place above 1 still gives -7.
  // Clamped: a unit GDAL reads may be as small or large as a double allows.
  return static_cast<int>(std::clamp(std::floor(std::log10(1e-7 / *unit_degrees) + 1e-9), -20.0, 20.0));
}

template <class T>
T clamp_to(double v) {
  if (!std::isfinite(v)) return T{0};
  const double lo = static_cast<double>(std::numeric_limits<T>::lowest());
  const double hi = static_cast<double>(std::numeric_limits<T>::max());
  return static_cast<T>(std::llround(std::clamp(v, lo, hi)));
}

}  // namespace

namespace {
void write_las_records(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& options,
                       bool direct = false);
}  // namespace

void write_las(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& options) {
  if (lower_extension(path) != ".laz") {
    write_las_records(path, cloud, options);
    return;
  }
  // LAZ: the LAS bytes go to a hidden sibling file (written directly: inside an OutputTransaction
  // an AtomicFile's rename would be deferred), then translate_las compresses them (layered
  // encoder for PDRF 6-8) into `path` through its own AtomicFile; the sibling is always removed,
  // by a signal too, and its write errors name `path` (IntermediateFile).
  std::string plain_name = ".";  // built by appending (GCC 12 -Wrestrict false positive on "." + s)
  plain_name += path.filename().string();
  plain_name += ".las.tmp.";
  plain_name += std::to_string(::getpid());
  const IntermediateFile intermediate(path.parent_path() / plain_name, path);
  const std::filesystem::path& plain = intermediate.path();
  try {
    write_las_records(plain, cloud, options, true);
  } catch (const std::invalid_argument& e) {  // name the file the caller asked for
    throw std::invalid_argument(temporary_named_as(e.what(), plain, path));
  }
  TranslateOptions t;
  t.compression = LasCompression::laz;
  translate_las(plain, path, t);
}

namespace {

/// One LAS 1.4 write of a PointCloud (PDRF 6, 7 or 8; LAS 1.4 R15 section 2.6). The layout is
/// planned from the cloud before the output file is created (split_fields, choose_scale_offset,
/// first_pass, plan_vlrs), so that a cloud LAS cannot hold leaves no file behind; then the
/// header, VLRs, point records and the WKT EVLR are written in file order.
struct LasRecordWriter {
  const std::filesystem::path& path;
  const PointCloud& cloud;
  const LasWriteOptions& options;
  const std::size_t n;          ///< points
  const std::string& wkt;       ///< the cloud's CRS as WKT ("" for none)
  Standard st;                  ///< standard fields the reader carries as named scalars
  std::vector<ExtraOut> extra;  ///< normals, then the other scalars: Extra Bytes (double each)
  bool rgb = false;             ///< the cloud has colour: PDRF 7 (8 with NIR)
  int pdrf = 6;
  int base_len = 30;            ///< bytes of the PDRF's own fields (30, 36 or 38)
  int rec_len = 30;             ///< base_len + 8 bytes per extra scalar
  Vec3 scale{0.001}, offset{0.0};
  std::array<std::uint64_t, 15> by_return{};  ///< points by return number 1..15
  Vec3 qlo{0.0}, qhi{0.0};      ///< bounds of the quantised coordinates
  bool wkt_evlr = false;        ///< WKT too long for a VLR (record length is 16 bit): an EVLR
  std::uint32_t n_vlr = 0;
  std::uint64_t vlr_bytes = 0;
  std::uint64_t point_offset = 375;  ///< header (375 bytes) + VLRs
  std::uint64_t evlr_start = 0;      ///< offset of the WKT EVLR (0: none)

  LasRecordWriter(const std::filesystem::path& p, const PointCloud& c, const LasWriteOptions& o)
      : path(p), cloud(c), options(o), n(c.size()), wkt(c.crs_wkt) {}

  /// Sorts the scalars into standard fields and extra bytes and picks the PDRF: 8 with NIR
  /// (and colour), 7 with colour, else 6 (tables 13-15). Normals become the extra bytes NormalX,
  /// NormalY, NormalZ (PDAL's dimension names, which the LAS reader maps back to normals), first.
  /// Names are made unique within 32 bytes (unique_extra_names). Throws std::invalid_argument
  /// when the extra bytes make a record longer than 65535 bytes.
  void split_fields() {
    if (!cloud.normals.empty())
      for (int a = 0; a < 3; ++a) extra.push_back({detail::kLasNormalNames[a], nullptr, nullptr, a});
    for (const ScalarField& f : cloud.scalars) {
      if (f.name == "return_number") st.ret = &f.values;
      else if (f.name == "number_of_returns") st.nret = &f.values;
      else if (f.name == "scan_angle") st.angle = &f.values;
      else if (f.name == "user_data") st.udata = &f.values;
      else if (f.name == "point_source_id") st.psid = &f.values;
      else if (f.name == "classification_flags") st.cflags = &f.values;
      else if (f.name == "scanner_channel") st.channel = &f.values;
      else if (f.name == "scan_direction_flag") st.scan_dir = &f.values;
      else if (f.name == "edge_of_flight_line") st.edge = &f.values;
      else if (f.name == "nir" && !cloud.rgb.empty()) st.nir = &f.values;
      else {
        const auto it = options.extra_bytes.find(f.name);
        extra.push_back({f.name, it == options.extra_bytes.end() ? nullptr : &it->second, &f.values, -1});
      }
    }
    {
      std::vector<std::string> names;
      for (const ExtraOut& e : extra) names.push_back(e.name);
      names = unique_extra_names(names);
      for (std::size_t k = 0; k < extra.size(); ++k) extra[k].name = std::move(names[k]);
    }
    rgb = !cloud.rgb.empty();
    pdrf = st.nir != nullptr ? 8 : (rgb ? 7 : 6);
    base_len = pdrf == 8 ? 38 : (pdrf == 7 ? 36 : 30);
    if (extra.size() > (65535 - 38) / 8)
      throw std::invalid_argument(path.string() + ": " + std::to_string(extra.size()) +
                                  " scalar fields do not fit a LAS point record");
    rec_len = base_len + 8 * static_cast<int>(extra.size());
  }

  /// Scale and offset per axis (header section 2.4). An invalid option scale is chosen: the
  /// coarsest decimal grid (1, 0.1, ... down to the finest default: 0.001 units, or for the
  /// latitude and longitude of a geographic CRS 1e-7 degrees; finest_scale_exponent) on which
  /// every coordinate of the axis reads back bit for bit (X * scale + offset == v, the reader's
  /// arithmetic) with the option offset, or without one offset 0 or the default below: a cloud
  /// that came from LAS on such a grid (through PLY or PCD) is written back exactly. Failing that,
  /// the coarsest on which every coordinate lies to within the rounding of decimal text
  /// (detail::OnGrid::decimal): a cloud that came from LAS through text, which prints the grid's
  /// decimals (write_text), gets its integers back. Otherwise the finest default, coarsened tenfold
  /// until the bounds fit 32-bit integers (2e9 units); without an option offset, the box's low
  /// corner rounded down to 1000 scale units.
  void choose_scale_offset() {
    const AABB box = cloud.bounds();
    scale = options.scale;
    offset = options.offset;
    const std::optional<double> unit_degrees = detail::geographic_unit_degrees(wkt);
    bool auto_scale[3];
    int finest[3];  // exponent of each axis' finest default scale
    for (int k = 0; k < 3; ++k) {
      auto_scale[k] = !(scale[k] > 0.0) || !std::isfinite(scale[k]);
      finest[k] = finest_scale_exponent(k, unit_degrees);
      if (auto_scale[k]) scale[k] = decimal_step(finest[k]);
    }
    // Rounded towards zero instead where rounding down would leave the coordinate bound (a low
    // corner near -1e9 on a scale such as 7), which the readers hold a LAS offset to.
    // A unit below 1 that is 1 / n (n whole: 1e-4 degrees at 1e-7) divides by n, so that the
    // offset is the double nearest its decimal (-122.4567, not -122.45679999999999, which would
    // cost a text copy of the file 17 decimals).
    auto default_offset = [&](int k, double s) {
      if (box.empty()) return 0.0;
      const double unit = 1000.0 * s;
      const double n = std::round(1.0 / unit);
      const bool reciprocal = unit < 1.0 && std::abs(n * unit - 1.0) < 1e-12;
      const double units = reciprocal ? box.lo[k] * n : box.lo[k] / unit;  // the low corner in units
      const auto offset_of = [&](double whole_units) { return reciprocal ? whole_units / n : whole_units * unit; };
      const double down = offset_of(std::floor(units));
      return std::abs(down) <= kMaxCoordinate ? down : offset_of(std::trunc(units));
    };
    if (!options.has_offset)
      for (int k = 0; k < 3; ++k) offset[k] = default_offset(k, scale[k]);
    // Whether every coordinate of axis k lies on the grid (s, off) as closely as `how` asks,
    // within the 32-bit range.
    auto reads_back = [&](int k, double s, double off, detail::OnGrid how) {
      if (std::max(std::abs(box.hi[k] - off), std::abs(box.lo[k] - off)) / s > 2.0e9) return false;
      for (std::size_t i = 0; i < n; ++i)
        if (!detail::on_las_grid(cloud.positions[i][k], s, off, how)) return false;
      return true;
    };
    // The offset on which axis k reads back at scale s: the option offset, else 0 or the default.
    auto grid_offset = [&](int k, double s, detail::OnGrid how) -> std::optional<double> {
      if (options.has_offset)
        return reads_back(k, s, offset[k], how) ? std::optional<double>(offset[k]) : std::nullopt;
      for (const double off : {0.0, default_offset(k, s)})
        if (reads_back(k, s, off, how)) return off;
      return std::nullopt;
    };
    for (int k = 0; k < 3; ++k) {
      if (!auto_scale[k] || box.empty()) continue;
      // Exact first on every grid, so that a cloud with an exact grid keeps its bits even where a
      // coarser grid would match to the last place.
      for (const detail::OnGrid how : {detail::OnGrid::exact, detail::OnGrid::decimal}) {
        for (int e = std::max(0, finest[k]); e >= finest[k]; --e)
          if (const std::optional<double> off = grid_offset(k, decimal_step(e), how)) {
            scale[k] = decimal_step(e), offset[k] = *off, auto_scale[k] = false;
            break;
          }
        if (!auto_scale[k]) break;
      }
    }
    for (int k = 0; k < 3; ++k)
      for (int e = finest[k]; auto_scale[k] && !box.empty() &&
                              std::max(std::abs(box.hi[k] - offset[k]), std::abs(box.lo[k] - offset[k])) / scale[k] > 2.0e9;)
        scale[k] = decimal_step(++e);
    // The readers refuse a header offset beyond the bound (parse_las_header): not written.
    for (int k = 0; k < 3; ++k)
      if (!(std::abs(offset[k]) <= kMaxCoordinate))
        throw std::invalid_argument(path.string() + ": offset " + "XYZ"[k] + " is " + shortest_text(offset[k]) +
                                    " (" + coordinate_bound_expected() + ")");
  }

  /// Coordinate v of axis k (0 X, 1 Y, 2 Z) of point i as the record's 32-bit integer.
  /// Throws std::invalid_argument when it does not fit.
  [[nodiscard]] std::int32_t quantise(double v, int k, std::size_t i) const {
    const double q = std::round((v - offset[k]) / scale[k]);
    if (!(q >= -2147483648.0 && q <= 2147483647.0))
      throw std::invalid_argument(path.string() + ": point " + std::to_string(i) + " coordinate " + "XYZ"[k] +
                                  " = " + shortest_text(v) + ": (" + "XYZ"[k] + " - offset) / scale = " +
                                  shortest_text((v - offset[k]) / scale[k]) +
                                  " does not fit a 32-bit LAS integer (scale " + shortest_text(scale[k]) +
                                  ", offset " + shortest_text(offset[k]) + ")");
    return static_cast<std::int32_t>(q);
  }

  /// The header's bounds (of the quantised coordinates, as readers will see them) and points
  /// by return; checks that every coordinate quantises, and reads back within +-kMaxCoordinate
  /// (a coordinate inside the bound may round to the grid beyond it): std::invalid_argument
  /// "<path>: point N: X coordinate is V (stored integer I x scale S + offset O, from P; expected
  /// within +-1e+09, the coordinate bound in world units)" otherwise.
  void first_pass() {
    qlo = Vec3(std::numeric_limits<double>::infinity());
    qhi = Vec3(-std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        const std::int32_t q = quantise(cloud.positions[i][k], k, i);
        const double v = las_coordinate(q, scale[k], offset[k]);  // the readers' expression
        if (!(std::abs(v) <= kMaxCoordinate))
          throw std::invalid_argument(path.string() + ": " +
                                      detail::beyond_coordinate_bound(
                                          i, k, v,
                                          detail::las_coordinate_source(q, scale[k], offset[k]) + ", from " +
                                              shortest_text(cloud.positions[i][k])));
        qlo[k] = std::min(qlo[k], v);
        qhi[k] = std::max(qhi[k], v);
      }
      const int r = st.ret != nullptr ? std::clamp(static_cast<int>((*st.ret)[i]), 0, 15) : 1;
      if (r >= 1) ++by_return[static_cast<std::size_t>(r - 1)];
    }
    if (n == 0) qlo = qhi = Vec3(0.0);
  }

  /// VLR count and bytes (54-byte VLR headers, section 2.5): the OGC WKT VLR (2.5.1) unless the
  /// WKT needs an EVLR, the Extra Bytes VLR (2.5.6); hence the offset to point data and of the
  /// EVLR. Throws std::invalid_argument when the point data offset exceeds 32 bits.
  void plan_vlrs() {
    wkt_evlr = wkt.size() + 1 > 65535;
    if (!wkt.empty() && !wkt_evlr) ++n_vlr, vlr_bytes += 54 + wkt.size() + 1;
    if (192 * extra.size() > 65535)  // (the Extra Bytes VLR's record length is 16 bit)
      throw std::invalid_argument(path.string() + ": " + std::to_string(extra.size()) +
                                  " extra fields; the Extra Bytes VLR of LAS 1.4 holds at most 341");
    if (!extra.empty()) ++n_vlr, vlr_bytes += 54 + 192 * extra.size();
    point_offset = 375 + vlr_bytes;
    if (point_offset > std::numeric_limits<std::uint32_t>::max())
      throw std::invalid_argument(path.string() + ": VLRs too large for a LAS header");
    evlr_start = wkt_evlr ? point_offset + static_cast<std::uint64_t>(rec_len) * n : 0;
  }

  /// Public header block (section 2.4, table 3; 375 bytes): version 1.4, WKT global encoding bit
  /// (required for PDRF 6-10) and the options' GPS time type bit and project GUID, creation
  /// day/year of today, legacy point counts 0.
  void write_header(detail::AtomicWriter& w) const {
    w.write("LASF", 4);
    w.put<std::uint16_t>(0);                         // file source id
    // Global encoding (table 4): bit 4 WKT CRS (required for PDRF 6-10), bit 0 the GPS time
    // type of the source, so that derived files' GPS times keep their meaning.
    w.put<std::uint16_t>(static_cast<std::uint16_t>((1u << 4) | (options.adjusted_standard_gps_time ? 1u : 0u)));
    w.write(options.project_guid.data(), 16);        // project GUID (the source's, else zeros)
    w.put<std::uint8_t>(1);
    w.put<std::uint8_t>(4);
    w.put_fixed(options.system_id, 32);
    w.put_fixed(software_name(), 32);
    {
      const auto now = std::chrono::system_clock::now();
      const std::chrono::year_month_day ymd{std::chrono::floor<std::chrono::days>(now)};
      const auto jan1 = std::chrono::sys_days{ymd.year() / std::chrono::January / 1};
      const auto doy = (std::chrono::floor<std::chrono::days>(now) - jan1).count() + 1;
      w.put<std::uint16_t>(static_cast<std::uint16_t>(doy));
      w.put<std::uint16_t>(static_cast<std::uint16_t>(static_cast<int>(ymd.year())));
    }
    w.put<std::uint16_t>(375);
    w.put<std::uint32_t>(static_cast<std::uint32_t>(point_offset));
    w.put<std::uint32_t>(n_vlr);
    w.put<std::uint8_t>(static_cast<std::uint8_t>(pdrf));
    w.put<std::uint16_t>(static_cast<std::uint16_t>(rec_len));
    w.put<std::uint32_t>(0);  // legacy point count: 0 for PDRF 6-10
    for (int k = 0; k < 5; ++k) w.put<std::uint32_t>(0);
    for (int k = 0; k < 3; ++k) w.put<double>(scale[k]);
    for (int k = 0; k < 3; ++k) w.put<double>(offset[k]);
    for (int k = 0; k < 3; ++k) {
      w.put<double>(qhi[k]);
      w.put<double>(qlo[k]);
    }
    w.put<std::uint64_t>(0);  // start of waveform data packet record
    w.put<std::uint64_t>(evlr_start);
    w.put<std::uint32_t>(wkt_evlr ? 1 : 0);
    w.put<std::uint64_t>(n);
    for (std::uint64_t c : by_return) w.put<std::uint64_t>(c);
  }

  /// The VLRs plan_vlrs() counted: OGC WKT (2.5.1, record 2112, NUL-terminated) and Extra Bytes
  /// (2.5.6, record 4 of "LASF_Spec"; one 192-byte descriptor per extra scalar, type 10 double).
  void write_vlrs(detail::AtomicWriter& w) const {
    auto vlr_header = [&](const char* user, std::uint16_t id, std::uint64_t len, const char* desc) {
      std::vector<std::uint8_t> h;
      detail::append_vlr_header(h, user, id, len, desc, false);
      w.write(h.data(), h.size());
    };
    if (!wkt.empty() && !wkt_evlr) {
      vlr_header("LASF_Projection", 2112, wkt.size() + 1, "OGC WKT");
      w.write(wkt.c_str(), wkt.size() + 1);
    }
    if (!extra.empty()) {
      vlr_header("LASF_Spec", 4, 192 * extra.size(), "Extra Bytes Record");
      for (const ExtraOut& f : extra) {
        std::uint8_t e[192] = {};
        e[2] = 10;  // data type: double
        e[3] = 0;   // options (bit 0: no_data given; no min/max/scale/offset)
        std::memcpy(e + 4, f.name.data(), std::min<std::size_t>(32, f.name.size()));
        if (f.info != nullptr && f.info->no_data) {
          e[3] |= 1u;
          const double nd = *f.info->no_data;
          std::memcpy(e + 40, &nd, 8);  // no_data (table 24: the field's own type, double here)
        }
        const std::string desc = f.info != nullptr && !f.info->description.empty() ? f.info->description
                                 : f.normal_axis >= 0                           ? "rayscan point normal"
                                                                                : "rayscan per-point scalar";
        std::memcpy(e + 160, desc.data(), std::min<std::size_t>(32, desc.size()));
        w.write(e, 192);
      }
    }
  }

  /// Point record i (section 2.6, tables 13-15) into r[0, rec_len): standard fields clamped to
  /// their types, colour back to 8 bit when the reader scaled it up, then the extra bytes.
  void pack_record(std::size_t i, std::uint8_t* r) const {
    std::memset(r, 0, static_cast<std::size_t>(rec_len));
    for (int k = 0; k < 3; ++k) {
      const std::int32_t q = quantise(cloud.positions[i][k], k, i);
      std::memcpy(r + 4 * k, &q, 4);
    }
    const std::uint16_t inten = cloud.intensity.empty() ? 0 : cloud.intensity[i];
    std::memcpy(r + 12, &inten, 2);
    const int ret = st.ret ? std::clamp(static_cast<int>((*st.ret)[i]), 0, 15) : 1;
    const int nret = st.nret ? std::clamp(static_cast<int>((*st.nret)[i]), 0, 15) : 1;
    r[14] = static_cast<std::uint8_t>(ret | (nret << 4));
    // Classification flags, scanner channel, scan direction, edge of flight line (table 13).
    auto bits = [&](const std::vector<double>* v, int mask) { return v ? (clamp_to<int>((*v)[i]) & mask) : 0; };
    r[15] = static_cast<std::uint8_t>(bits(st.cflags, 15) | (bits(st.channel, 3) << 4) |
                                      (bits(st.scan_dir, 1) << 6) | (bits(st.edge, 1) << 7));
    r[16] = cloud.classification.empty() ? 0 : cloud.classification[i];
    r[17] = st.udata ? clamp_to<std::uint8_t>((*st.udata)[i]) : 0;
    const std::int16_t angle = st.angle ? clamp_to<std::int16_t>((*st.angle)[i] / 0.006) : 0;
    std::memcpy(r + 18, &angle, 2);
    const std::uint16_t psid = st.psid ? clamp_to<std::uint16_t>((*st.psid)[i]) : 0;
    std::memcpy(r + 20, &psid, 2);
    const double t = cloud.gps_time.empty() ? 0.0 : cloud.gps_time[i];
    std::memcpy(r + 22, &t, 8);
    if (rgb) {
      Rgb16 c = cloud.rgb[i];
      if (cloud.rgb_from_8bit_las)  // back to the source's 8-bit values (the reader scaled by 257)
        c = Rgb16{static_cast<std::uint16_t>(c.r / 257), static_cast<std::uint16_t>(c.g / 257),
                  static_cast<std::uint16_t>(c.b / 257)};
      std::memcpy(r + 30, &c.r, 2);
      std::memcpy(r + 32, &c.g, 2);
      std::memcpy(r + 34, &c.b, 2);
    }
    if (st.nir) {
      const std::uint16_t v = clamp_to<std::uint16_t>((*st.nir)[i]);
      std::memcpy(r + 36, &v, 2);
    }
    for (std::size_t k = 0; k < extra.size(); ++k) {
      const ExtraOut& e = extra[k];
      const double v = e.values != nullptr ? (*e.values)[i] : static_cast<double>(cloud.normals[i][e.normal_axis]);
      std::memcpy(r + base_len + 8 * k, &v, 8);
    }
  }

  /// The OGC WKT EVLR (section 2.7: 60-byte header with a 64-bit length) after the points, for
  /// WKT longer than a VLR can hold.
  void write_wkt_evlr(detail::AtomicWriter& w) const {
    std::vector<std::uint8_t> h;
    detail::append_vlr_header(h, "LASF_Projection", 2112, wkt.size() + 1, "OGC WKT", true);
    w.write(h.data(), h.size());
    w.write(wkt.c_str(), wkt.size() + 1);
  }
};

/// The LAS writer proper; `direct` writes `path` without a temporary (see AtomicWriter).
void write_las_records(const std::filesystem::path& path, const PointCloud& cloud, const LasWriteOptions& options,
                       bool direct) {
  detail::validate_for_writing(path, cloud);
  LasRecordWriter lw(path, cloud, options);
  lw.split_fields();
  lw.choose_scale_offset();
  lw.first_pass();
  lw.plan_vlrs();
  detail::AtomicWriter w(path, direct);
  lw.write_header(w);
  lw.write_vlrs(w);
  std::vector<std::uint8_t> rec(static_cast<std::size_t>(lw.rec_len));
  for (std::size_t i = 0; i < lw.n; ++i) {
    lw.pack_record(i, rec.data());
    w.write(rec.data(), rec.size());
  }
  if (lw.wkt_evlr) lw.write_wkt_evlr(w);
  w.commit();
}

}  // namespace

}  // namespace rayscan::io
