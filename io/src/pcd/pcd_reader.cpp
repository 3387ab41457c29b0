// PCD reader: the Point Cloud Library's "The PCD (Point Cloud Data) file format" (PCD v0.7, also
// reading v0.6 headers, which lack VIEWPOINT): header entries VERSION FIELDS SIZE TYPE COUNT
// WIDTH HEIGHT VIEWPOINT POINTS DATA (in this order, DATA last); DATA ascii (one point per
// line), binary (array of structs, little-endian) and binary_compressed (PCL's
// pcl::PCDWriter::writeBinaryCompressed: uint32 compressed size, uint32 uncompressed size, LZF
// stream of the struct-of-arrays layout). Packed colour: "rgb" (F 4) / "rgba" (U 4) hold
// 0x00RRGGBB / 0xAARRGGBB. Points with a non-finite x, y or z (invalid pixels of organized
// clouds) are dropped and counted in FileInfo::dropped_nonfinite; a finite one beyond
// +-kMaxCoordinate is refused, as the LAS reader refuses it. VIEWPOINT is reported in
// FileInfo, not applied (positions stay in the file's frame).
// read_pcd's steps make their checks in a fixed order (header lines, field layout, roles, data),
// which decides the error a file with several defects reports.
#include "readers.hpp"

#include "rayscan/io/field_names.hpp"

extern "C" {
#include <lzf.h>
}

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace rayscan::io::detail {

namespace {

struct PcdField {
  std::string name;
  int size = 4;
  char type = 'F';
  std::uint64_t count = 1;
  std::uint64_t offset = 0;  // byte offset inside one point (AoS)
};

double load_field(const std::uint8_t* p, const PcdField& f) {
  switch (f.type) {
    case 'F': return f.size == 8 ? load_le<double>(p) : load_le<float>(p);
    case 'U':
      switch (f.size) {
        case 1: return *p;
        case 2: return load_le<std::uint16_t>(p);
        case 4: return load_le<std::uint32_t>(p);
        default: return static_cast<double>(load_le<std::uint64_t>(p));
      }
    default:
      switch (f.size) {
        case 1: return static_cast<std::int8_t>(*p);
        case 2: return load_le<std::int16_t>(p);
        case 4: return load_le<std::int32_t>(p);
        default: return static_cast<double>(load_le<std::int64_t>(p));
      }
  }
}

enum class PcdRole { skip, x, y, z, nx, ny, nz, packed, r, g, b, scalar };

/// A validated PCD header (PCD spec, "The PCD file format", header entries). Filled by
/// parse_pcd_header(); point_size and values by layout_fields().
struct PcdHeader {
  std::vector<PcdField> fields;  ///< FIELDS with their SIZE, TYPE, COUNT, in file order
  std::uint64_t width = 0;       ///< WIDTH (points per row; POINTS when absent)
  std::uint64_t height = 1;      ///< HEIGHT (rows; 1 for unorganized clouds)
  std::uint64_t points = 0;      ///< POINTS, equal to WIDTH * HEIGHT
  std::string data;              ///< DATA: "ascii", "binary" or "binary_compressed"
  std::uint64_t line = 0;        ///< line number of the DATA line: errors about the header cite it
  std::uint64_t body = 0;        ///< byte offset of the data after the DATA line
  std::uint64_t point_size = 0;  ///< bytes per point: sum of SIZE * COUNT
  std::uint64_t values = 0;      ///< values per point: sum of COUNT (at most 65536)
};

/// Which header entries were seen (the spec's defaults apply to absent ones).
struct PcdSeen {
  bool fields = false, size = false, type = false, points = false, width = false, height = false;
};

/// `s` as a header integer; throws FormatError at `line` naming the entry `what` otherwise.
std::uint64_t parse_u64(const std::string& nm, std::uint64_t line, const std::string& s, const char* what) {
  std::uint64_t v = 0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || p != s.data() + s.size())
    fail_line(nm, line, std::string(what) + " '" + s + "' is not a non-negative integer");
  return v;
}

/// SIZE, TYPE and COUNT need FIELDS before them and one entry per field: throws FormatError
/// at `line` otherwise.
void need_fields(const std::string& nm, std::uint64_t line, const std::string& key, std::size_t nv,
                 const PcdSeen& seen, std::size_t nfields) {
  if (!seen.fields) fail_line(nm, line, key + " before FIELDS (expected FIELDS first)");
  if (nv != nfields)
    fail_line(nm, line, key + " has " + std::to_string(nv) + " entries for " + std::to_string(nfields) +
                            " FIELDS");
}

/// Applies one header line, split into words `w` (w[0] the entry's name), to `h` (line h.line).
/// VERSION and VIEWPOINT go to `info`. Throws FormatError on an unknown entry or a bad value.
void parse_header_entry(const std::string& nm, const std::vector<std::string>& w, PcdHeader& h, PcdSeen& seen,
                        FileInfo& info) {
  const std::uint64_t line = h.line;
  const std::string key = w[0];
  const std::size_t nv = w.size() - 1;
  std::vector<PcdField>& fields = h.fields;
  if (key == "VERSION") {
    info.version = nv > 0 ? w[1] : "";
    if (!info.version.empty() && info.version[0] == '.') info.version = "0" + info.version;
  } else if (key == "FIELDS" || key == "COLUMNS") {
    if (nv == 0) fail_line(nm, line, "FIELDS lists no field");
    fields.assign(nv, PcdField{});
    for (std::size_t k = 0; k < nv; ++k) fields[k].name = w[k + 1];
    seen.fields = true;
  } else if (key == "SIZE") {
    need_fields(nm, line, key, nv, seen, fields.size());
    for (std::size_t k = 0; k < nv; ++k) {
      const std::uint64_t s = parse_u64(nm, line, w[k + 1], "SIZE");
      if (s != 1 && s != 2 && s != 4 && s != 8)
        fail_line(nm, line, "SIZE " + w[k + 1] + " of field '" + fields[k].name + "' (expected 1, 2, 4 or 8)");
      fields[k].size = static_cast<int>(s);
    }
    seen.size = true;
  } else if (key == "TYPE") {
    need_fields(nm, line, key, nv, seen, fields.size());
    for (std::size_t k = 0; k < nv; ++k) {
      if (w[k + 1].size() != 1 || std::string("IUF").find(w[k + 1][0]) == std::string::npos)
        fail_line(nm, line, "TYPE '" + w[k + 1] + "' of field '" + fields[k].name + "' (expected I, U or F)");
      fields[k].type = w[k + 1][0];
    }
    seen.type = true;
  } else if (key == "COUNT") {
    need_fields(nm, line, key, nv, seen, fields.size());
    for (std::size_t k = 0; k < nv; ++k) {
      fields[k].count = parse_u64(nm, line, w[k + 1], "COUNT");
      if (fields[k].count == 0 || fields[k].count > 1000000)
        fail_line(nm, line, "COUNT " + w[k + 1] + " of field '" + fields[k].name + "' (expected 1..1000000)");
    }
  } else if (key == "WIDTH") {
    if (nv != 1) fail_line(nm, line, "WIDTH expects one value");
    h.width = parse_u64(nm, line, w[1], "WIDTH");
    seen.width = true;
  } else if (key == "HEIGHT") {
    if (nv != 1) fail_line(nm, line, "HEIGHT expects one value");
    h.height = parse_u64(nm, line, w[1], "HEIGHT");
    seen.height = true;
  } else if (key == "VIEWPOINT") {
    if (nv != 7) fail_line(nm, line, "VIEWPOINT expects 7 values tx ty tz qw qx qy qz");
    std::array<double, 7> vp{};
    for (int k = 0; k < 7; ++k) {
      const std::string& s = w[static_cast<std::size_t>(k) + 1];
      auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), vp[static_cast<std::size_t>(k)]);
      if (ec != std::errc() || p != s.data() + s.size())
        fail_line(nm, line, "VIEWPOINT value '" + s + "' is not a number");
      // A pose is a place and a rotation: "nan" or "inf" (which from_chars accepts) is none, and
      // would be written back into every PCD made from this cloud.
      if (!std::isfinite(vp[static_cast<std::size_t>(k)]))
        fail_line(nm, line, "VIEWPOINT value '" + s + "' is not a finite number");
    }
    info.viewpoint = vp;
  } else if (key == "POINTS") {
    if (nv != 1) fail_line(nm, line, "POINTS expects one value");
    h.points = parse_u64(nm, line, w[1], "POINTS");
    seen.points = true;
  } else if (key == "DATA") {
    if (!seen.fields) fail_line(nm, line, "DATA before FIELDS (expected FIELDS, SIZE, TYPE before DATA)");
    if (nv != 1) fail_line(nm, line, "DATA expects ascii, binary or binary_compressed");
    h.data = w[1];
    if (h.data != "ascii" && h.data != "binary" && h.data != "binary_compressed")
      fail_line(nm, line, "DATA '" + h.data + "' (expected ascii, binary or binary_compressed)");
  } else {
    fail_line(nm, line, "unknown header entry '" + key + "'");
  }
}

/// Reads the header lines up to and including DATA (PCD spec, "File format header"; '#' lines
/// are comments, kept in info.comments), applies the defaults (HEIGHT 1, WIDTH = POINTS) and
/// checks POINTS = WIDTH * HEIGHT. Fills info's encoding, width, height and header point count.
/// Throws FormatError "line N: ..." on the first defect.
PcdHeader parse_pcd_header(const Input& in, FileInfo& info) {
  const auto* d = reinterpret_cast<const char*>(in.bytes.data());
  const std::string& nm = in.name;
  PcdHeader h;
  PcdSeen seen;
  std::uint64_t pos = 0;
  while (h.data.empty()) {
    if (pos >= in.size()) fail_line(nm, h.line, "file ends before the DATA header line");
    std::uint64_t e = pos;
    while (e < in.size() && d[e] != '\n') ++e;
    std::string l(d + pos, e - pos);
    pos = e < in.size() ? e + 1 : e;
    ++h.line;
    if (!l.empty() && l.back() == '\r') l.pop_back();
    std::vector<std::string> w;
    for (std::size_t i = 0; i < l.size();) {
      while (i < l.size() && (l[i] == ' ' || l[i] == '\t')) ++i;
      std::size_t j = i;
      while (j < l.size() && l[j] != ' ' && l[j] != '\t') ++j;
      if (j > i) w.push_back(l.substr(i, j - i));
      i = j;
    }
    if (w.empty()) continue;
    if (w[0][0] == '#') {
      info.comments.push_back(l);
      continue;
    }
    parse_header_entry(nm, w, h, seen, info);
  }
  h.body = pos;
  const std::uint64_t line = h.line;
  if (h.data != "ascii" && (!seen.size || !seen.type))
    fail_line(nm, line, "binary DATA needs SIZE and TYPE lines in the header");
  if (!seen.width && !seen.points) fail_line(nm, line, "header has neither WIDTH nor POINTS");
  if (!seen.width) h.width = h.points, h.height = 1;
  if (!seen.height) h.height = 1;
  if (h.height != 0 && h.width > UINT64_MAX / h.height) fail_line(nm, line, "WIDTH * HEIGHT overflows");
  if (!seen.points) h.points = h.width * h.height;
  if (h.points != h.width * h.height)
    fail_line(nm, line, "POINTS " + std::to_string(h.points) + " differs from WIDTH * HEIGHT = " +
                            std::to_string(h.width * h.height));
  info.encoding = h.data;
  info.width = h.width;
  info.height = h.height;
  info.header_point_count = h.points;
  return h;
}

/// Byte offset of each field inside one point (array-of-structs order, PCD spec "DATA binary"),
/// h.point_size and h.values; lists the fields in info.fields as "x:F4", "fpfh:F4x33". Throws
/// FormatError for a TYPE F field not of SIZE 4 or 8, or more than 65536 values per point.
void layout_fields(const std::string& nm, PcdHeader& h, FileInfo& info) {
  h.point_size = 0;
  for (PcdField& f : h.fields) {
    if (f.type == 'F' && f.size != 4 && f.size != 8)
      fail_line(nm, h.line, "field '" + f.name + "' TYPE F with SIZE " + std::to_string(f.size) + " (expected 4 or 8)");
    f.offset = h.point_size;
    h.point_size += static_cast<std::uint64_t>(f.size) * f.count;
    std::string desc = f.name;
    desc += ':';
    desc += f.type;
    desc += std::to_string(f.size);
    if (f.count > 1) desc += 'x' + std::to_string(f.count);
    info.fields.push_back(desc);
  }
  h.values = 0;
  for (const PcdField& f : h.fields) h.values += f.count;
  if (h.values > 65536)
    fail_line(nm, h.line, "FIELDS/COUNT declare " + std::to_string(h.values) +
                              " values per point (at most 65536 supported)");
}

/// What each field becomes in the PointCloud, and the outputs that exist.
struct PcdRoles {
  std::vector<PcdRole> of;  ///< per field
  bool has_n = false;       ///< a normal_x field: normals are filled
  bool has_packed = false;  ///< packed "rgb"/"rgba" colour
  bool has_ch = false;      ///< separate colour channels (a red field)
  bool ch_float = false;    ///< some colour channel has TYPE F (colour_scale's 0..1 rule)
  std::vector<std::string> scalar_names;                          ///< PointCloud::scalars, in order
  std::vector<std::pair<std::size_t, std::uint64_t>> scalar_src;  ///< (field, element) of each scalar
};

/// Roles by field name (pcd_named_field, rayscan/io/field_names.hpp, which the PCD writer and
/// rayscan.write share to keep a scalar from reading back as one of these; case-insensitive; "_"
/// is PCL's padding; packed colour needs SIZE 4 and COUNT 1). Fields with COUNT > 1 are not
/// coordinates, normals or colours; scalars of COUNT > 3 (descriptors) are skipped with a note;
/// without opt.scalars only intensity, classification and GPS time are kept. Throws FormatError
/// when x, y or z is missing.
PcdRoles assign_roles(const std::string& nm, const PcdHeader& h, const ReadOptions& opt, FileInfo& info) {
  const std::vector<PcdField>& fields = h.fields;
  const std::size_t nf = fields.size();
  PcdRoles out;
  out.of.assign(nf, PcdRole::skip);
  int have = 0;
  for (std::size_t k = 0; k < nf; ++k) {
    PcdRole r = PcdRole::scalar;
    switch (pcd_named_field(fields[k].name)) {
      case NamedField::padding: r = PcdRole::skip; break;
      case NamedField::x: r = PcdRole::x; break;
      case NamedField::y: r = PcdRole::y; break;
      case NamedField::z: r = PcdRole::z; break;
      case NamedField::nx: r = PcdRole::nx; break;
      case NamedField::ny: r = PcdRole::ny; break;
      case NamedField::nz: r = PcdRole::nz; break;
      case NamedField::packed_rgb:
        if (fields[k].size == 4 && fields[k].count == 1) r = PcdRole::packed;
        break;
      case NamedField::red: r = PcdRole::r; break;
      case NamedField::green: r = PcdRole::g; break;
      case NamedField::blue: r = PcdRole::b; break;
      case NamedField::intensity:  // not a PCD name: promote_scalars fills intensity
      case NamedField::scalar: break;
    }
    if ((r >= PcdRole::x && r <= PcdRole::z) || (r >= PcdRole::r && r <= PcdRole::b) || (r >= PcdRole::nx && r <= PcdRole::nz))
      if (fields[k].count != 1) r = PcdRole::scalar;
    if (r == PcdRole::x) have |= 1;
    if (r == PcdRole::y) have |= 2;
    if (r == PcdRole::z) have |= 4;
    out.has_n |= r == PcdRole::nx;
    out.has_packed |= r == PcdRole::packed;
    out.has_ch |= r == PcdRole::r;
    if (r == PcdRole::scalar) {
      const bool core = dedicated_field_name(fields[k].name) != nullptr;
      if (!opt.scalars && !core) r = PcdRole::skip;
      else if (fields[k].count > 3) {
        info.notes.push_back("field '" + fields[k].name + "' has COUNT " + std::to_string(fields[k].count) +
                             " (a descriptor, not a per-point scalar): skipped");
        r = PcdRole::skip;
      } else {
        for (std::uint64_t j = 0; j < fields[k].count; ++j) {
          out.scalar_names.push_back(fields[k].count == 1 ? fields[k].name : fields[k].name + "_" + std::to_string(j));
          out.scalar_src.emplace_back(k, j);
        }
      }
    }
    out.of[k] = r;
  }
  if (have != 7) fail_line(nm, h.line, "FIELDS lacks x, y or z");
  for (std::size_t k = 0; k < nf; ++k)
    if (out.of[k] >= PcdRole::r && out.of[k] <= PcdRole::b) out.ch_float |= fields[k].type == 'F';
  return out;
}

/// The data section of a PCD file decoded into a PointCloud: one point's values are gathered in
/// `vals` (one per field element) and emitted, dropping points with a non-finite position.
struct PcdBody {
  const Input& in;
  FileInfo& info;
  const PcdHeader& h;
  const PcdRoles& roles;
  const char* d;                    ///< the file's bytes as characters (ascii data)
  std::uint64_t remaining;          ///< bytes from h.body to the end of the file
  const std::uint8_t* base;         ///< first byte of the binary points (file or decompressed)
  bool soa = false;                 ///< struct-of-arrays layout (binary_compressed)
  std::vector<std::uint8_t> decompressed;
  PointCloud pc;
  std::vector<std::uint32_t> packed;  ///< packed colour per emitted point
  std::vector<float> ch;              ///< r, g, b per emitted point (separate channels)
  std::vector<double> vals;           ///< the current point: one value per (field, element)
  std::vector<std::uint64_t> first;   ///< index in `vals` of each field's first element; [nf] = total
  std::vector<std::uint32_t> packed_bits;  ///< the current point's packed colour bits per field

  PcdBody(const Input& input, FileInfo& file_info, const PcdHeader& header, const PcdRoles& r)
      : in(input), info(file_info), h(header), roles(r), d(reinterpret_cast<const char*>(input.bytes.data())),
        remaining(input.size() - header.body), base(input.bytes.data() + header.body) {}

  /// DATA binary: the announced points must fit the bytes that follow (FormatError otherwise).
  void check_binary_size() const {
    if (h.point_size > 0 && h.points > remaining / h.point_size)
      fail_at(in.name, h.body, "header announces " + std::to_string(h.points) + " points of " +
                                   std::to_string(h.point_size) + " bytes but only " + std::to_string(remaining) +
                                   " bytes of data follow");
  }

  /// DATA binary_compressed (PCL's writeBinaryCompressed): uint32 compressed size, uint32
  /// uncompressed size (= POINTS * point size), then LZF data of the struct-of-arrays layout,
  /// decompressed into `decompressed`. Sizes are checked before any allocation; throws
  /// FormatError "byte N: ..." on a bad size or LZF stream.
  void load_compressed_body() {
    const std::string& nm = in.name;
    const std::uint64_t body = h.body;
    in.need(body, 8, "binary_compressed sizes (2 x uint32)");
    const std::uint32_t csize = load_le<std::uint32_t>(base);
    const std::uint32_t usize = load_le<std::uint32_t>(base + 4);
    if (csize > remaining - 8)
      fail_at(nm, body, "compressed size " + std::to_string(csize) + " exceeds the " +
                            std::to_string(remaining - 8) + " bytes that follow");
    if (h.point_size > 0 && h.points > UINT32_MAX / h.point_size)
      fail_at(nm, body + 4, "header announces " + std::to_string(h.points) + " points of " +
                                std::to_string(h.point_size) + " bytes: more than binary_compressed can hold");
    if (usize != h.points * h.point_size)
      fail_at(nm, body + 4, "uncompressed size " + std::to_string(usize) + " differs from POINTS * point size = " +
                                std::to_string(h.points * h.point_size));
    // LZF cannot expand more than ~88x (3 bytes encode at most a 264-byte back reference).
    if (usize > 90ull * csize + 1024)
      fail_at(nm, body + 4, "uncompressed size " + std::to_string(usize) + " impossible for " +
                                std::to_string(csize) + " bytes of LZF data");
    // (liblzf's loop reads a control byte before it tests the input's end: an empty stream would
    // be read one byte past the file.)
    if (usize > 0 && csize == 0)
      fail_at(nm, body, "compressed size 0 for " + std::to_string(usize) + " bytes of point data");
    decompressed.resize(usize);
    if (usize > 0) {
      errno = 0;
      const unsigned got = lzf_decompress(base + 8, csize, decompressed.data(), usize);
      // liblzf returns 0 on a bad stream and says why in errno: E2BIG, it decodes to more than the
      // stated size; EINVAL, a back reference or literal run past its bounds.
      if (got == 0 && (errno == E2BIG || errno == EINVAL))
        fail_at(nm, body + 8, std::string("LZF data is corrupt: ") +
                                  (errno == E2BIG ? "it decodes to more than the " + std::to_string(usize) + " bytes stated"
                                                  : "a back reference or literal run past its bounds"));
      if (got != usize)
        fail_at(nm, body + 8, "LZF data decompresses to " + std::to_string(got) + " bytes, expected " +
                                  std::to_string(usize));
    }
    base = decompressed.data();
    soa = true;
  }

  /// Reserves the outputs (for ascii only what the file can hold: a point takes >= 2 bytes)
  /// and sizes the per-point buffers.
  void reserve_outputs() {
    const std::size_t nf = h.fields.size();
    const std::uint64_t cap = h.data == "ascii" ? std::min<std::uint64_t>(h.points, remaining / 2) : h.points;
    pc.positions.reserve(static_cast<std::size_t>(cap));
    if (roles.has_n) pc.normals.reserve(static_cast<std::size_t>(cap));
    for (const std::string& s : roles.scalar_names) {
      pc.scalars.push_back({s, {}});
      pc.scalars.back().values.reserve(static_cast<std::size_t>(cap));
    }
    first.assign(nf + 1, 0);
    for (std::size_t k = 0; k < nf; ++k) first[k + 1] = first[k] + h.fields[k].count;
    vals.resize(first[nf]);
    packed_bits.assign(nf, 0);
  }

  /// Appends point `index` (file order) in `vals` / `packed_bits`; false (and counted in
  /// info.dropped_nonfinite) when x, y or z is not finite. A finite coordinate beyond
  /// +-kMaxCoordinate is refused as the LAS reader refuses it: `fail` (a FormatError thrower
  /// naming the point's line or byte) gets beyond_coordinate_bound's text.
  template <class Fail>
  bool emit(std::uint64_t index, Fail&& fail) {
    double x = 0, y = 0, z = 0, n3[3] = {0, 0, 0}, c3[3] = {0, 0, 0};
    std::uint32_t pk = 0;
    const std::size_t nf = h.fields.size();
    for (std::size_t k = 0; k < nf; ++k) {
      const double a = vals[first[k]];
      switch (roles.of[k]) {
        case PcdRole::x: x = a; break;
        case PcdRole::y: y = a; break;
        case PcdRole::z: z = a; break;
        case PcdRole::nx: n3[0] = a; break;
        case PcdRole::ny: n3[1] = a; break;
        case PcdRole::nz: n3[2] = a; break;
        case PcdRole::r: c3[0] = a; break;
        case PcdRole::g: c3[1] = a; break;
        case PcdRole::b: c3[2] = a; break;
        case PcdRole::packed: pk = packed_bits[k]; break;
        default: break;
      }
    }
    if (!within_coordinate_bound(x, y, z)) {  // one compare per axis; NaN and infinities too
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
        ++info.dropped_nonfinite;
        return false;
      }
      fail(beyond_coordinate_bound(index, x, y, z));
    }
    pc.positions.emplace_back(x, y, z);
    if (roles.has_n) pc.normals.emplace_back(to_f32(n3[0]), to_f32(n3[1]), to_f32(n3[2]));
    if (roles.has_packed) packed.push_back(pk);
    if (roles.has_ch) ch.insert(ch.end(), {to_f32(c3[0]), to_f32(c3[1]), to_f32(c3[2])});
    const auto& src = roles.scalar_src;
    for (std::size_t s = 0; s < src.size(); ++s)
      pc.scalars[s].values.push_back(vals[first[src[s].first] + src[s].second]);
    return true;
  }

  /// Reads the ascii value of element j of field k at byte p (advanced past it) on line `ln`
  /// into `vals`, and for a packed colour its bits. Throws FormatError on a missing value, a
  /// non-number or a value beyond the range of a double.
  void read_ascii_value(std::uint64_t& p, std::uint64_t ln, std::size_t k, std::uint64_t j) {
    const std::string& nm = in.name;
    const PcdField& f = h.fields[k];
    while (p < in.size() && (d[p] == ' ' || d[p] == '\t')) ++p;
    const std::uint64_t b = p;
    while (p < in.size() && d[p] != ' ' && d[p] != '\t' && d[p] != '\n' && d[p] != '\r') ++p;
    if (b == p) fail_line(nm, ln, "expected a value for field '" + f.name + "', found end of line");
    const char* tb = d + b;
    const char* te = d + p;
    if (*tb == '+') ++tb;
    double v = 0;
    auto [q, ec] = std::from_chars(tb, te, v);
    if (ec == std::errc::result_out_of_range && q == te) {
      // Underflow (denormal packed colours) reads as 0; overflow (1e400) is an error, as
      // in the other readers, never a silent 0.
      if (std::isinf(std::strtod(std::string(tb, te).c_str(), nullptr)))
        fail_line(nm, ln, "field '" + f.name + "': value '" + std::string(d + b, std::min<std::uint64_t>(p - b, 40)) +
                              "' is out of the range of a double");
      v = 0;
    } else if (ec != std::errc() || q != te)
      fail_line(nm, ln, "field '" + f.name + "': expected a number, got '" +
                            std::string(d + b, std::min<std::uint64_t>(p - b, 40)) + "'");
    vals[first[k] + j] = v;
    if (roles.of[k] == PcdRole::packed) {
      // PCL writes packed colour in ascii as the uint32 value; older writers as the float.
      const std::string_view tok(d + b, p - b);
      if (tok.find_first_of(".eEnN") == std::string_view::npos && v >= 0 && v <= 4294967295.0) {
        packed_bits[k] = static_cast<std::uint32_t>(v);
      } else {
        const float fv = to_f32(v);
        std::memcpy(&packed_bits[k], &fv, 4);
      }
    }
  }

  /// DATA ascii: one point per line, h.values whitespace-separated values (blank lines
  /// skipped). Throws FormatError "line N: ..." when the file ends early or a line holds too
  /// few or too many values.
  void read_ascii_points() {
    const std::string& nm = in.name;
    const std::size_t nf = h.fields.size();
    std::uint64_t p = h.body, newlines = 0;
    std::uint64_t done = 0;
    while (done < h.points) {
      // One point per line; blank lines are skipped.
      while (p < in.size() && (d[p] == '\n' || d[p] == '\r' || d[p] == ' ' || d[p] == '\t')) {
        if (d[p] == '\n') ++newlines;
        ++p;
      }
      const std::uint64_t ln = h.line + 1 + newlines;  // the line this point is on
      if (p >= in.size())
        fail_line(nm, ln, "file ends after " + std::to_string(done) + " of " + std::to_string(h.points) + " points");
      for (std::size_t k = 0; k < nf; ++k)
        for (std::uint64_t j = 0; j < h.fields[k].count; ++j) read_ascii_value(p, ln, k, j);
      while (p < in.size() && d[p] != '\n') {
        if (d[p] != ' ' && d[p] != '\t' && d[p] != '\r')
          fail_line(nm, ln, "more values than the " + std::to_string(first[nf]) + " that FIELDS/COUNT declare");
        ++p;
      }
      emit(done, [&](const std::string& what) { fail_line(nm, ln, what); });
      ++done;
    }
  }

  /// DATA binary (array of structs, point_size bytes per point) or the decompressed
  /// binary_compressed data (struct of arrays: each field's values for all points in turn).
  /// Sizes were checked before; skipped fields are not read.
  void read_binary_points() {
    const std::size_t nf = h.fields.size();
    const std::uint64_t points = h.points;
    for (std::uint64_t i = 0; i < points; ++i) {
      for (std::size_t k = 0; k < nf; ++k) {
        const PcdField& f = h.fields[k];
        const PcdRole role = roles.of[k];
        if (role == PcdRole::skip) continue;
        const std::uint8_t* fp = soa ? base + points * f.offset + i * f.size * f.count
                                     : base + i * h.point_size + f.offset;
        const std::uint64_t ne = role == PcdRole::scalar ? f.count : 1;
        for (std::uint64_t j = 0; j < ne; ++j) vals[first[k] + j] = load_field(fp + j * f.size, f);
        if (role == PcdRole::packed) packed_bits[k] = load_le<std::uint32_t>(fp);
      }
      // The point's record, or for binary_compressed (no record in the file) the LZF data.
      emit(i, [&](const std::string& what) { fail_at(in.name, soa ? h.body + 8 : h.body + i * h.point_size, what); });
      if (!soa && (i + 1) % 65536 == 0) in.done(h.body + (i + 1) * h.point_size);
    }
  }

  /// PointCloud::rgb from packed colour (0x??RRGGBB, 8 bit scaled by 257) or from separate
  /// channels (scaled by colour_scale(), its note added to info.notes). 8-bit colour (scaled by
  /// 257) is marked PointCloud::rgb_from_8bit_las: write_las stores it as those values, as PDAL's
  /// writers.las does, so LAS -> PCD -> LAS keeps the LAS file's own colour values.
  void finish_colour() {
    const std::size_t n = pc.positions.size();
    if (roles.has_packed) {
      pc.rgb_from_8bit_las = true;
      pc.rgb.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t v = packed[i];
        pc.rgb[i] = Rgb16{static_cast<std::uint16_t>(((v >> 16) & 0xFF) * 257),
                          static_cast<std::uint16_t>(((v >> 8) & 0xFF) * 257),
                          static_cast<std::uint16_t>((v & 0xFF) * 257)};
      }
    } else if (roles.has_ch) {
      float mx = 0;
      for (float c : ch) mx = std::max(mx, c);
      std::string note;
      const double s = colour_scale(mx, roles.ch_float, note);
      if (!note.empty()) info.notes.push_back(note);
      pc.rgb_from_8bit_las = s == 257.0;
      pc.rgb.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        auto q = [&](float c) { return to_u16(c * s); };
        pc.rgb[i] = Rgb16{q(ch[3 * i]), q(ch[3 * i + 1]), q(ch[3 * i + 2])};
      }
    }
  }
};

}  // namespace

PointCloud read_pcd(const Input& in, const ReadOptions& opt, FileInfo& info) {
  info.format = "PCD";
  PcdHeader h = parse_pcd_header(in, info);
  layout_fields(in.name, h, info);
  const PcdRoles roles = assign_roles(in.name, h, opt, info);
  PcdBody body(in, info, h, roles);
  if (h.data == "binary") body.check_binary_size();
  else if (h.data == "binary_compressed") body.load_compressed_body();
  body.reserve_outputs();
  if (h.data == "ascii") body.read_ascii_points();
  else body.read_binary_points();
  if (info.dropped_nonfinite > 0)
    info.notes.push_back(std::to_string(info.dropped_nonfinite) +
                         " points with a non-finite x, y or z (invalid pixels) dropped");
  body.finish_colour();
  return std::move(body.pc);
}

}  // namespace rayscan::io::detail
