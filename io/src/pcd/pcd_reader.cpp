// PCD reader: the Point Cloud Library's "The PCD (Point Cloud Data) file format" (PCD v0.7, also
// reading v0.6 headers, which lack VIEWPOINT): header entries VERSION FIELDS SIZE TYPE COUNT
// WIDTH HEIGHT VIEWPOINT POINTS DATA (in this order, DATA last); DATA ascii (one point per
// line), binary (array of structs, little-endian) and binary_compressed (PCL's
// pcl::PCDWriter::writeBinaryCompressed: uint32 compressed size, uint32 uncompressed size, LZF
// stream of the struct-of-arrays layout). Packed colour: "rgb" (F 4) / "rgba" (U 4) hold
// 0x00RRGGBB / 0xAARRGGBB. Points with a non-finite x, y or z (invalid pixels of organized
// clouds) are dropped and counted in FileInfo::dropped_nonfinite. VIEWPOINT is reported in
// FileInfo, not applied (positions stay in the file's frame).
#include "readers.hpp"

extern "C" {
#include <lzf.h>
}

#include <algorithm>
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

}  // namespace

PointCloud read_pcd(const Input& in, const ReadOptions& opt, FileInfo& info) {
  const auto* d = reinterpret_cast<const char*>(in.bytes.data());
  const std::string& nm = in.name;
  info.format = "PCD";
  std::uint64_t pos = 0, line = 0;
  std::vector<PcdField> fields;
  bool have_fields = false, have_size = false, have_type = false, have_points = false;
  bool have_width = false, have_height = false;
  std::uint64_t width = 0, height = 1, points = 0;
  std::string data;
  auto parse_u64 = [&](const std::string& s, const char* what) {
    std::uint64_t v = 0;
    auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || p != s.data() + s.size())
      fail_line(nm, line, std::string(what) + " '" + s + "' is not a non-negative integer");
    return v;
  };
  while (data.empty()) {
    if (pos >= in.size()) fail_line(nm, line, "file ends before the DATA header line");
    std::uint64_t e = pos;
    while (e < in.size() && d[e] != '\n') ++e;
    std::string l(d + pos, e - pos);
    pos = e < in.size() ? e + 1 : e;
    ++line;
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
    const std::string key = w[0];
    const std::size_t nv = w.size() - 1;
    auto need_fields = [&]() {
      if (!have_fields) fail_line(nm, line, key + " before FIELDS (expected FIELDS first)");
      if (nv != fields.size())
        fail_line(nm, line, key + " has " + std::to_string(nv) + " entries for " +
                                std::to_string(fields.size()) + " FIELDS");
    };
    if (key == "VERSION") {
      info.version = nv > 0 ? w[1] : "";
      if (!info.version.empty() && info.version[0] == '.') info.version = "0" + info.version;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      if (nv == 0) fail_line(nm, line, "FIELDS lists no field");
      fields.assign(nv, PcdField{});
      for (std::size_t k = 0; k < nv; ++k) fields[k].name = w[k + 1];
      have_fields = true;
    } else if (key == "SIZE") {
      need_fields();
      for (std::size_t k = 0; k < nv; ++k) {
        const std::uint64_t s = parse_u64(w[k + 1], "SIZE");
        if (s != 1 && s != 2 && s != 4 && s != 8)
          fail_line(nm, line, "SIZE " + w[k + 1] + " of field '" + fields[k].name + "' (expected 1, 2, 4 or 8)");
        fields[k].size = static_cast<int>(s);
      }
      have_size = true;
    } else if (key == "TYPE") {
      need_fields();
      for (std::size_t k = 0; k < nv; ++k) {
        if (w[k + 1].size() != 1 || std::string("IUF").find(w[k + 1][0]) == std::string::npos)
          fail_line(nm, line, "TYPE '" + w[k + 1] + "' of field '" + fields[k].name + "' (expected I, U or F)");
        fields[k].type = w[k + 1][0];
      }
      have_type = true;
    } else if (key == "COUNT") {
      need_fields();
      for (std::size_t k = 0; k < nv; ++k) {
        fields[k].count = parse_u64(w[k + 1], "COUNT");
        if (fields[k].count == 0 || fields[k].count > 1000000)
          fail_line(nm, line, "COUNT " + w[k + 1] + " of field '" + fields[k].name + "' (expected 1..1000000)");
      }
    } else if (key == "WIDTH") {
      if (nv != 1) fail_line(nm, line, "WIDTH expects one value");
      width = parse_u64(w[1], "WIDTH");
      have_width = true;
    } else if (key == "HEIGHT") {
      if (nv != 1) fail_line(nm, line, "HEIGHT expects one value");
      height = parse_u64(w[1], "HEIGHT");
      have_height = true;
    } else if (key == "VIEWPOINT") {
      if (nv != 7) fail_line(nm, line, "VIEWPOINT expects 7 values tx ty tz qw qx qy qz");
      std::array<double, 7> vp{};
      for (int k = 0; k < 7; ++k) {
        const std::string& s = w[static_cast<std::size_t>(k) + 1];
        auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), vp[static_cast<std::size_t>(k)]);
        if (ec != std::errc() || p != s.data() + s.size())
          fail_line(nm, line, "VIEWPOINT value '" + s + "' is not a number");
      }
      info.viewpoint = vp;
    } else if (key == "POINTS") {
      if (nv != 1) fail_line(nm, line, "POINTS expects one value");
      points = parse_u64(w[1], "POINTS");
      have_points = true;
    } else if (key == "DATA") {
      if (!have_fields) fail_line(nm, line, "DATA before FIELDS (expected FIELDS, SIZE, TYPE before DATA)");
      if (nv != 1) fail_line(nm, line, "DATA expects ascii, binary or binary_compressed");
      data = w[1];
      if (data != "ascii" && data != "binary" && data != "binary_compressed")
        fail_line(nm, line, "DATA '" + data + "' (expected ascii, binary or binary_compressed)");
    } else {
      fail_line(nm, line, "unknown header entry '" + key + "'");
    }
  }
  if (data != "ascii" && (!have_size || !have_type))
    fail_line(nm, line, "binary DATA needs SIZE and TYPE lines in the header");
  if (!have_width && !have_points) fail_line(nm, line, "header has neither WIDTH nor POINTS");
  if (!have_width) width = points, height = 1;
  if (!have_height) height = 1;
  if (height != 0 && width > UINT64_MAX / height) fail_line(nm, line, "WIDTH * HEIGHT overflows");
  if (!have_points) points = width * height;
  if (points != width * height)
    fail_line(nm, line, "POINTS " + std::to_string(points) + " differs from WIDTH * HEIGHT = " +
                            std::to_string(width * height));
  info.encoding = data;
  info.width = width;
  info.height = height;
  info.header_point_count = points;
  std::uint64_t point_size = 0;
  for (PcdField& f : fields) {
    if (f.type == 'F' && f.size != 4 && f.size != 8)
      fail_line(nm, line, "field '" + f.name + "' TYPE F with SIZE " + std::to_string(f.size) + " (expected 4 or 8)");
    f.offset = point_size;
    point_size += static_cast<std::uint64_t>(f.size) * f.count;
    std::string desc = f.name;  // "x:F4", "fpfh:F4x33"
    desc += ':';
    desc += f.type;
    desc += std::to_string(f.size);
    if (f.count > 1) desc += 'x' + std::to_string(f.count);
    info.fields.push_back(desc);
  }

  std::uint64_t values_per_point = 0;
  for (const PcdField& f : fields) values_per_point += f.count;
  if (values_per_point > 65536)
    fail_line(nm, line, "FIELDS/COUNT declare " + std::to_string(values_per_point) +
                            " values per point (at most 65536 supported)");
  // Roles.
  const std::size_t nf = fields.size();
  std::vector<PcdRole> roles(nf, PcdRole::skip);
  int have = 0;
  bool has_n = false, has_packed = false, has_ch = false;
  std::vector<std::string> scalar_names;
  std::vector<std::pair<std::size_t, std::uint64_t>> scalar_src;  // field, element
  for (std::size_t k = 0; k < nf; ++k) {
    const std::string n = lower(fields[k].name);
    PcdRole r = PcdRole::scalar;
    if (n == "_") r = PcdRole::skip;
    else if (n == "x") r = PcdRole::x;
    else if (n == "y") r = PcdRole::y;
    else if (n == "z") r = PcdRole::z;
    else if (n == "normal_x" || n == "nx") r = PcdRole::nx;
    else if (n == "normal_y" || n == "ny") r = PcdRole::ny;
    else if (n == "normal_z" || n == "nz") r = PcdRole::nz;
    else if ((n == "rgb" || n == "rgba") && fields[k].size == 4 && fields[k].count == 1) r = PcdRole::packed;
    else if (n == "red" || n == "r") r = PcdRole::r;
    else if (n == "green" || n == "g") r = PcdRole::g;
    else if (n == "blue" || n == "b") r = PcdRole::b;
    if ((r >= PcdRole::x && r <= PcdRole::z) || (r >= PcdRole::r && r <= PcdRole::b) || (r >= PcdRole::nx && r <= PcdRole::nz))
      if (fields[k].count != 1) r = PcdRole::scalar;
    if (r == PcdRole::x) have |= 1;
    if (r == PcdRole::y) have |= 2;
    if (r == PcdRole::z) have |= 4;
    has_n |= r == PcdRole::nx;
    has_packed |= r == PcdRole::packed;
    has_ch |= r == PcdRole::r;
    if (r == PcdRole::scalar) {
      const bool core = n == "intensity" || n == "classification" || n == "gpstime" || n == "gps_time";
      if (!opt.scalars && !core) r = PcdRole::skip;
      else if (fields[k].count > 3) {
        info.notes.push_back("field '" + fields[k].name + "' has COUNT " + std::to_string(fields[k].count) +
                             " (a descriptor, not a per-point scalar): skipped");
        r = PcdRole::skip;
      } else {
        for (std::uint64_t j = 0; j < fields[k].count; ++j) {
          scalar_names.push_back(fields[k].count == 1 ? fields[k].name : fields[k].name + "_" + std::to_string(j));
          scalar_src.emplace_back(k, j);
        }
      }
    }
    roles[k] = r;
  }
  if (have != 7) fail_line(nm, line, "FIELDS lacks x, y or z");

  const std::uint64_t body = pos;
  const std::uint64_t remaining = in.size() - body;
  std::vector<std::uint8_t> decompressed;
  const std::uint8_t* base = in.bytes.data() + body;
  bool soa = false;
  if (data == "binary") {
    if (point_size > 0 && points > remaining / point_size)
      fail_at(nm, body, "header announces " + std::to_string(points) + " points of " +
                            std::to_string(point_size) + " bytes but only " + std::to_string(remaining) +
                            " bytes of data follow");
  } else if (data == "binary_compressed") {
    in.need(body, 8, "binary_compressed sizes (2 x uint32)");
    const std::uint32_t csize = load_le<std::uint32_t>(base);
    const std::uint32_t usize = load_le<std::uint32_t>(base + 4);
    if (csize > remaining - 8)
      fail_at(nm, body, "compressed size " + std::to_string(csize) + " exceeds the " +
                            std::to_string(remaining - 8) + " bytes that follow");
    if (point_size > 0 && points > UINT32_MAX / point_size)
      fail_at(nm, body + 4, "header announces " + std::to_string(points) + " points of " +
                                std::to_string(point_size) + " bytes: more than binary_compressed can hold");
    if (usize != points * point_size)
      fail_at(nm, body + 4, "uncompressed size " + std::to_string(usize) + " differs from POINTS * point size = " +
                                std::to_string(points * point_size));
    // LZF cannot expand more than ~88x (3 bytes encode at most a 264-byte back reference).
    if (usize > 90ull * csize + 1024)
      fail_at(nm, body + 4, "uncompressed size " + std::to_string(usize) + " impossible for " +
                                std::to_string(csize) + " bytes of LZF data");
    decompressed.resize(usize);
    if (usize > 0) {
      const unsigned got = lzf_decompress(base + 8, csize, decompressed.data(), usize);
      if (got != usize)
        fail_at(nm, body + 8, "LZF data decompresses to " + std::to_string(got) + " bytes, expected " +
                                  std::to_string(usize));
    }
    base = decompressed.data();
    soa = true;
  }

  PointCloud pc;
  const std::uint64_t cap = data == "ascii" ? std::min<std::uint64_t>(points, remaining / 2) : points;
  pc.positions.reserve(static_cast<std::size_t>(cap));
  if (has_n) pc.normals.reserve(static_cast<std::size_t>(cap));
  for (const std::string& s : scalar_names) {
    pc.scalars.push_back({s, {}});
    pc.scalars.back().values.reserve(static_cast<std::size_t>(cap));
  }
  std::vector<std::uint32_t> packed;
  std::vector<float> ch;
  bool ch_float = false;
  for (std::size_t k = 0; k < nf; ++k)
    if (roles[k] >= PcdRole::r && roles[k] <= PcdRole::b) ch_float |= fields[k].type == 'F';
  std::vector<double> vals;  // per point: one value per (field, element)
  std::vector<std::uint64_t> first(nf + 1, 0);
  for (std::size_t k = 0; k < nf; ++k) first[k + 1] = first[k] + fields[k].count;
  vals.resize(first[nf]);
  std::vector<std::uint32_t> packed_bits(nf, 0);

  auto emit = [&]() -> bool {
    double x = 0, y = 0, z = 0, n3[3] = {0, 0, 0}, c3[3] = {0, 0, 0};
    std::uint32_t pk = 0;
    for (std::size_t k = 0; k < nf; ++k) {
      const double a = vals[first[k]];
      switch (roles[k]) {
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
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      ++info.dropped_nonfinite;
      return false;
    }
    pc.positions.emplace_back(x, y, z);
    if (has_n) pc.normals.emplace_back(to_f32(n3[0]), to_f32(n3[1]), to_f32(n3[2]));
    if (has_packed) packed.push_back(pk);
    if (has_ch) ch.insert(ch.end(), {to_f32(c3[0]), to_f32(c3[1]), to_f32(c3[2])});
    for (std::size_t s = 0; s < scalar_src.size(); ++s)
      pc.scalars[s].values.push_back(vals[first[scalar_src[s].first] + scalar_src[s].second]);
    return true;
  };

  if (data == "ascii") {
    std::uint64_t p = body, newlines = 0;
    std::uint64_t done = 0;
    while (done < points) {
      // One point per line; blank lines are skipped.
      while (p < in.size() && (d[p] == '\n' || d[p] == '\r' || d[p] == ' ' || d[p] == '\t')) {
        if (d[p] == '\n') ++newlines;
        ++p;
      }
      const std::uint64_t ln = line + 1 + newlines;  // the line this point is on
      if (p >= in.size())
        fail_line(nm, ln, "file ends after " + std::to_string(done) + " of " + std::to_string(points) + " points");
      for (std::size_t k = 0; k < nf; ++k) {
        for (std::uint64_t j = 0; j < fields[k].count; ++j) {
          while (p < in.size() && (d[p] == ' ' || d[p] == '\t')) ++p;
          const std::uint64_t b = p;
          while (p < in.size() && d[p] != ' ' && d[p] != '\t' && d[p] != '\n' && d[p] != '\r') ++p;
          if (b == p)
            fail_line(nm, ln, "expected a value for field '" + fields[k].name + "', found end of line");
          const char* tb = d + b;
          const char* te = d + p;
          if (*tb == '+') ++tb;
          double v = 0;
          auto [q, ec] = std::from_chars(tb, te, v);
          if (ec == std::errc::result_out_of_range && q == te) {
            // Underflow (denormal packed colours) reads as 0; overflow (1e400) is an error, as
            // in the other readers, never a silent 0.
            if (std::isinf(std::strtod(std::string(tb, te).c_str(), nullptr)))
              fail_line(nm, ln, "field '" + fields[k].name + "': value '" +
                                    std::string(d + b, std::min<std::uint64_t>(p - b, 40)) +
                                    "' is out of the range of a double");
            v = 0;
          } else if (ec != std::errc() || q != te)
            fail_line(nm, ln, "field '" + fields[k].name + "': expected a number, got '" +
                                  std::string(d + b, std::min<std::uint64_t>(p - b, 40)) + "'");
          vals[first[k] + j] = v;
          if (roles[k] == PcdRole::packed) {
            // PCL writes packed colour in ascii as the uint32 value; older writers as the float.
            const std::string_view tok(d + b, p - b);
            if (tok.find_first_of(".eEnN") == std::string_view::npos && v >= 0 && v <= 4294967295.0) {
              packed_bits[k] = static_cast<std::uint32_t>(v);
            } else {
              const float f = to_f32(v);
              std::memcpy(&packed_bits[k], &f, 4);
            }
          }
        }
      }
      while (p < in.size() && d[p] != '\n') {
        if (d[p] != ' ' && d[p] != '\t' && d[p] != '\r')
          fail_line(nm, ln, "more values than the " + std::to_string(first[nf]) + " that FIELDS/COUNT declare");
        ++p;
      }
      emit();
      ++done;
    }
  } else {
    for (std::uint64_t i = 0; i < points; ++i) {
      for (std::size_t k = 0; k < nf; ++k) {
        const PcdField& f = fields[k];
        if (roles[k] == PcdRole::skip) continue;
        const std::uint8_t* fp = soa ? base + points * f.offset + i * f.size * f.count
                                     : base + i * point_size + f.offset;
        const std::uint64_t ne = roles[k] == PcdRole::scalar ? f.count : 1;
        for (std::uint64_t j = 0; j < ne; ++j) vals[first[k] + j] = load_field(fp + j * f.size, f);
        if (roles[k] == PcdRole::packed) packed_bits[k] = load_le<std::uint32_t>(fp);
      }
      emit();
      if (!soa && (i + 1) % 65536 == 0) in.done(body + (i + 1) * point_size);
    }
  }
  if (info.dropped_nonfinite > 0)
    info.notes.push_back(std::to_string(info.dropped_nonfinite) +
                         " points with a non-finite x, y or z (invalid pixels) dropped");
  const std::size_t n = pc.positions.size();
  if (has_packed) {
    pc.rgb.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t v = packed[i];
      pc.rgb[i] = Rgb16{static_cast<std::uint16_t>(((v >> 16) & 0xFF) * 257),
                        static_cast<std::uint16_t>(((v >> 8) & 0xFF) * 257),
                        static_cast<std::uint16_t>((v & 0xFF) * 257)};
    }
  } else if (has_ch) {
    float mx = 0;
    for (float c : ch) mx = std::max(mx, c);
    std::string note;
    const double s = colour_scale(mx, ch_float, note);
    if (!note.empty()) info.notes.push_back(note);
    pc.rgb.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      auto q = [&](float c) { return to_u16(c * s); };
      pc.rgb[i] = Rgb16{q(ch[3 * i]), q(ch[3 * i + 1]), q(ch[3 * i + 2])};
    }
  }
  return pc;
}

}  // namespace rayscan::io::detail
