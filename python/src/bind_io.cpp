// rayscan.PointCloud: read from a file (rayscan.read, NumPy views of the reader's arrays, no copy)
// or built from NumPy arrays (PointCloud(xyz, ...), PointCloud.from_structured), subsets (pc[mask],
// pc.take) and rayscan.write. Readers: rayscan::io::read_point_cloud (LAS 1.0-1.4, LAZ, PLY, PCD,
// XYZ/CSV/TXT, .f64; docs/formats.md); the writer: io::write_point_cloud (format by extension).
#include "arrays.hpp"
#include "bindings.hpp"
#include "cloud.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/interrupt.hpp"
#include "rayscan/io/crs.hpp"
#include "rayscan/io/field_names.hpp"
#include "rayscan/io/point_io.hpp"

#include <pybind11/eval.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <memory>
#include <optional>
#include <system_error>
#include <utility>

namespace rayscan::python {

using namespace pybind11::literals;

namespace {

static_assert(sizeof(Rgb16) == 3 * sizeof(std::uint16_t));
static_assert(sizeof(glm::vec3) == 3 * sizeof(float));

/// A view of attribute `name` of the cloud owned by `self` (None when absent).
py::object attribute(py::object self, const std::string& name) {
  const PyCloud& c = self.cast<const PyCloud&>();
  const std::size_t n = c.cloud.size();
  const PointCloud& pc = c.cloud;
  if (name == "xyz") return view_rows(reinterpret_cast<const double*>(pc.positions.data()), n, 3, self);
  if (!c.has(name)) return py::none();
  if (name == "rgb") return view_rows(reinterpret_cast<const std::uint16_t*>(pc.rgb.data()), n, 3, self);
  if (name == "intensity") return view_rows(pc.intensity.data(), n, 0, self);
  if (name == "classification") return view_rows(pc.classification.data(), n, 0, self);
  if (name == "gps_time") return view_rows(pc.gps_time.data(), n, 0, self);
  if (name == "normals") return view_rows(reinterpret_cast<const float*>(pc.normals.data()), n, 3, self);
  return view_rows(pc.scalar(name)->values.data(), n, 0, self);
}

/// A view of the scalar field `name` (None when absent). A file may hold a scalar field named like
/// an absent standard attribute (a PLY float "intensity" property is not the uint16 intensity),
/// which attribute() would not find.
py::object scalar_attribute(py::object self, const std::string& name) {
  const PyCloud& c = self.cast<const PyCloud&>();
  const ScalarField* f = c.cloud.scalar(name);
  return f ? view_rows(f->values.data(), c.cloud.size(), 0, self) : py::object(py::none());
}

/// True when the reader of `path` delivers intensity, classification or GPS time as a named field
/// first (PLY, PCD, text: docs/formats.md "Dedicated fields from named values"): the field moves
/// to its dedicated attribute only when its values fit, else stays a scalar of that name, and
/// either needs the scalars read. LAS and .f64 have no such fields (nor does a name no reader
/// takes, which read_point_cloud refuses).
bool named_core_fields(const std::string& path) {
  try {
    const io::Format f = io::format_from_extension(path);
    return f == io::Format::ply || f == io::Format::pcd || f == io::Format::text;
  } catch (const std::exception&) {
    return false;
  }
}

/// Raises os_error(err, path, detail).
[[noreturn]] void raise_os_error(int err, const std::string& path, const std::string& detail = {}) {
  set_os_error(err, path, detail);
  throw py::error_already_set();
}

PyCloud read(const std::string& path, const py::object& attributes) {
  std::optional<std::vector<std::string>> keep;
  if (!attributes.is_none()) keep = names_arg(attributes, "attributes");
  io::ReadOptions opts;
  if (keep) {
    const auto& std_names = standard_attributes();
    const bool named_core = named_core_fields(path);
    opts.scalars = std::any_of(keep->begin(), keep->end(), [&](const std::string& n) {
      const bool core = n == "intensity" || n == "classification" || n == "gps_time";
      return (core && named_core) || std::find(std_names.begin(), std_names.end(), n) == std_names.end();
    });
  }
  PyCloud c;
  c.path = path;
  try {
    py::gil_scoped_release nogil;
    c.cloud = io::read_point_cloud(path, opts, &c.info);
  } catch (const std::exception&) {
    // The reader reports a file it cannot open by its message alone (its FormatError), and may
    // refuse the name first (a directory's "unknown point cloud extension ''"): asked again
    // through the input policy, a file that cannot be opened raises the OSError subclass of its
    // errno (module.cpp: FileNotFoundError, IsADirectoryError, ...).
    const InputFile probe(path);
    throw;  // a file that opens (or a FIFO): the library's error and message
  }
  if (keep) {
    for (const std::string& n : *keep)
      if (!c.has(n) && !c.cloud.scalar(n)) {  // (a scalar "intensity" whose values do not fit uint16)
        std::string have;
        for (const std::string& a : c.attributes()) have += (have.empty() ? "" : ", ") + a;
        throw py::value_error(path + ": no attribute '" + n + "' (the file has: " + have + ")");
      }
    c.keep_only(*keep);
  }
  return c;
}

py::module_ numpy() { return py::module_::import("numpy"); }

std::string dtype_text(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// `obj` as an array of `n` rows of `cols` values (0: one-dimensional, shape (n,)) whose dtype kind
/// is one of `kinds` (NumPy's: b bool, i/u integers, f floating). Raises ValueError "<name>:
/// expected <what> of shape (N,) with N = 10 (as xyz), got ...".
py::array column(py::handle obj, const std::string& name, std::size_t n, std::size_t cols, const char* kinds,
                 const std::string& what) {
  py::array a = numpy().attr("asarray")(obj);
  const std::string want = cols ? "(N, " + std::to_string(cols) + ")" : "(N,)";
  const std::string expected = name + ": expected " + what + " of shape " + want + " with N = " + std::to_string(n) +
                               " (as xyz), got ";
  if (std::string(kinds).find(a.dtype().kind()) == std::string::npos)
    throw py::value_error(expected + "dtype " + dtype_text(a));
  const bool shape_ok = a.ndim() == (cols ? 2 : 1) && static_cast<std::size_t>(a.shape(0)) == n &&
                        (!cols || static_cast<std::size_t>(a.shape(1)) == cols);
  if (!shape_ok) throw py::value_error(expected + "shape " + shape_text(a));
  return a;
}

/// The values of `a` as T (C order, converted by NumPy).
template <class T>
std::vector<T> values_as(const py::array& a) {
  auto c = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!c) throw py::error_already_set();
  return std::vector<T>(c.data(), c.data() + c.size());
}

/// An integer column checked to lie in [0, hi]: ValueError "<name>: values must be in [0, hi], got -1".
template <class T>
std::vector<T> integers_in_range(const py::array& a, const std::string& name, long long hi) {
  if (a.size() > 0) {
    const py::int_ lo_v(a.attr("min")()), hi_v(a.attr("max")());
    for (const py::int_& v : {lo_v, hi_v})
      if (v < py::int_(0) || v > py::int_(hi))
        throw py::value_error(name + ": values must be in [0, " + std::to_string(hi) + "], got " +
                              py::repr(v).cast<std::string>());
  }
  return values_as<T>(a);
}

/// A scalar field's name: a non-empty str that is not a standard attribute. Raises ValueError.
void check_scalar_name(const std::string& name, const std::string& where) {
  const auto& std_names = standard_attributes();
  if (name.empty()) throw py::value_error(where + ": a scalar field needs a non-empty name");
  if (std::find(std_names.begin(), std_names.end(), name) != std_names.end())
    throw py::value_error(where + ": '" + name + "' is a PointCloud attribute, not a scalar field; give it as " +
                          "PointCloud(..., " + name + "=...)");
}

/// Sets the scalar field `name` (replacing one of that name).
void set_scalar(PointCloud& cloud, const std::string& name, std::vector<double> values) {
  const auto it = std::find_if(cloud.scalars.begin(), cloud.scalars.end(),
                               [&](const ScalarField& f) { return f.name == name; });
  if (it != cloud.scalars.end()) it->values = std::move(values);
  else cloud.scalars.push_back({name, std::move(values)});
}

PyCloud from_arrays(py::handle xyz, py::handle rgb, py::handle intensity, py::handle classification,
                    py::handle gps_time, py::handle normals, py::handle scalars, py::handle crs) {
  PyCloud c;
  PointCloud& pc = c.cloud;
  const Vec3Rows p = as_vec3_rows(xyz, "xyz");
  pc.positions.assign(p.rows.begin(), p.rows.end());
  const std::size_t n = pc.positions.size();
  if (!rgb.is_none()) {
    const std::string what = "colours of dtype uint8 (0..255) or uint16 (0..65535)";
    const py::array a = column(rgb, "rgb", n, 3, "u", what);
    if (a.itemsize() != 1 && a.itemsize() != 2)
      throw py::value_error("rgb: expected " + what + ", got dtype " + dtype_text(a));
    const std::vector<std::uint16_t> v = values_as<std::uint16_t>(a);
    const std::uint16_t scale = a.itemsize() == 1 ? 257 : 1;  // 8-bit colour to the 16-bit range (255 -> 65535)
    pc.rgb.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      pc.rgb[i] = {static_cast<std::uint16_t>(v[3 * i] * scale), static_cast<std::uint16_t>(v[3 * i + 1] * scale),
                   static_cast<std::uint16_t>(v[3 * i + 2] * scale)};
  }
  if (!intensity.is_none())
    pc.intensity = integers_in_range<std::uint16_t>(column(intensity, "intensity", n, 0, "iu", "integers"),
                                                    "intensity", 65535);
  if (!classification.is_none())
    pc.classification = integers_in_range<std::uint8_t>(
        column(classification, "classification", n, 0, "iu", "integers"), "classification", 255);
  if (!gps_time.is_none()) pc.gps_time = values_as<double>(column(gps_time, "gps_time", n, 0, "iuf", "real numbers"));
  if (!normals.is_none()) {
    const std::vector<float> v = values_as<float>(column(normals, "normals", n, 3, "iuf", "real numbers"));
    pc.normals.resize(n);
    for (std::size_t i = 0; i < n; ++i) pc.normals[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
  }
  if (!scalars.is_none()) {
    if (!py::isinstance<py::dict>(scalars))
      throw py::type_error("scalars must be a dict of name -> (N,) array, got " + type_name(scalars));
    for (auto [k, v] : scalars.cast<py::dict>()) {
      if (!py::isinstance<py::str>(k)) throw py::type_error("scalars: names must be str, got " + type_name(k));
      const std::string name = k.cast<std::string>();
      check_scalar_name(name, "scalars");
      const py::array values = column(v, "scalars['" + name + "']", n, 0, "biuf", "real numbers");
      pc.scalars.push_back({name, values_as<double>(values)});
    }
  }
  if (!crs.is_none()) {
    const std::string expected =
        "a CRS as GDAL reads it (\"EPSG:2992\", WKT, PROJJSON, a PROJ string; not a file name or URL) or None";
    if (!py::isinstance<py::str>(crs)) throw py::type_error("crs must be " + expected + ", got " + type_name(crs));
    const std::string text = crs.cast<std::string>();
    std::string refused;  // io's reason to refuse text GDAL reads
    {
      py::gil_scoped_release nogil;  // the PROJ database lookup
      try {
        pc.crs_wkt = io::crs_wkt_from_user_input(text);
      } catch (const std::invalid_argument& e) {
        refused = e.what();
      }
    }
    if (!refused.empty()) throw py::value_error("crs: " + refused);
    if (pc.crs_wkt.empty()) {
      const std::string shown = text.size() > 60 ? text.substr(0, 60) + "..." : text;
      throw py::value_error("crs: GDAL cannot read " + py::repr(py::str(shown)).cast<std::string>() +
                            " as a CRS; expected " + expected);
    }
  }
  pc.validate();  // non-finite positions: ValueError naming the point
  return c;
}

/// One attribute's field names in a structured array: PDAL's spelling and laspy's.
struct Spelling {
  const char* pdal;
  const char* laspy;
};

PyCloud from_structured(py::handle obj, py::handle crs) {
  py::module_ np = numpy();
  const py::array a = np.attr("asarray")(obj);
  const py::object names = a.dtype().attr("names");
  if (names.is_none() || a.ndim() != 1)
    throw py::value_error("from_structured: expected a one-dimensional NumPy structured array (fields X, Y, Z or "
                          "x, y, z, ...), got dtype " + dtype_text(a) + " of shape " + shape_text(a));
  std::vector<std::string> fields = names.cast<std::vector<std::string>>();
  std::vector<std::string> used;
  const auto has = [&](const char* f) { return std::find(fields.begin(), fields.end(), f) != fields.end(); };
  // The field naming one attribute, "" when absent; both spellings at once are ambiguous.
  const auto pick = [&](const Spelling& s) -> std::string {
    if (has(s.pdal) && has(s.laspy))
      throw py::value_error(std::string("from_structured: fields '") + s.pdal + "' and '" + s.laspy +
                            "' name the same attribute; keep one");
    const char* f = has(s.pdal) ? s.pdal : has(s.laspy) ? s.laspy : nullptr;
    if (!f) return {};
    used.emplace_back(f);
    return f;
  };
  // Three fields stacked as (N, 3) (None when all are absent).
  const auto triple = [&](const std::array<Spelling, 3>& s) -> py::object {
    std::array<std::string, 3> f{pick(s[0]), pick(s[1]), pick(s[2])};
    if (f[0].empty() && f[1].empty() && f[2].empty()) return py::none();
    for (const std::string& x : f)
      if (x.empty())
        throw py::value_error(std::string("from_structured: fields ") + s[0].pdal + ", " + s[1].pdal + ", " +
                              s[2].pdal + " (or " + s[0].laspy + ", " + s[1].laspy + ", " + s[2].laspy +
                              ") go together; the array has only some of them");
    return np.attr("column_stack")(py::make_tuple(a[py::str(f[0])], a[py::str(f[1])], a[py::str(f[2])]));
  };
  const auto single = [&](const Spelling& s) -> py::object {
    const std::string f = pick(s);
    return f.empty() ? py::object(py::none()) : py::object(a[py::str(f)]);
  };
  const py::object xyz = triple({Spelling{"X", "x"}, {"Y", "y"}, {"Z", "z"}});
  if (xyz.is_none()) throw py::value_error("from_structured: the array needs the fields X, Y, Z (or x, y, z)");
  const py::object rgb = triple({Spelling{"Red", "red"}, {"Green", "green"}, {"Blue", "blue"}});
  const py::object normals = triple({Spelling{"NormalX", "nx"}, {"NormalY", "ny"}, {"NormalZ", "nz"}});
  const py::object intensity = single({"Intensity", "intensity"});
  const py::object classification = single({"Classification", "classification"});
  const py::object gps_time = single({"GpsTime", "gps_time"});
  py::dict scalars;
  for (const std::string& f : fields) {
    if (std::find(used.begin(), used.end(), f) != used.end()) continue;
    const py::array col = a[py::str(f)];
    if (col.ndim() != 1 || std::string("biuf").find(col.dtype().kind()) == std::string::npos)
      throw py::value_error("from_structured: field '" + f + "' has dtype " +
                            py::str(a.dtype()[py::str(f)]).cast<std::string>() + "; expected numbers (one per point)");
    // PDAL's (or laspy's) names of the other LAS fields take the names write_las stores in the
    // standard fields: the readers' rule (io::las_standard_scalar_name).
    const char* las = io::las_standard_scalar_name(f);
    const std::string name = las != nullptr ? las : f;
    if (scalars.contains(name))
      throw py::value_error("from_structured: fields '" + f + "' and another both give the scalar field '" + name +
                            "'");
    scalars[py::str(name)] = col;
  }
  return from_arrays(xyz, rgb, intensity, classification, gps_time, normals, scalars, crs);
}

/// Indices as gather() walks them: one C-contiguous run of int64 (a slice with a step, or a
/// reversed one, is a strided view of NumPy's arange; forcecast makes it one run).
using IndexArray = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

/// The points `sel` (indices into c, each in [0, N)) of `c` as a new cloud, every attribute kept.
std::shared_ptr<PyCloud> gather(const PyCloud& c, const IndexArray& sel) {
  auto out = std::make_shared<PyCloud>();
  out->info = c.info;  // the source's format and LAS grid: rayscan.write keeps it
  out->path = c.path;
  const std::int64_t* idx = sel.data();
  const std::size_t k = static_cast<std::size_t>(sel.size());
  py::gil_scoped_release nogil;
  const PointCloud& src = c.cloud;
  PointCloud& dst = out->cloud;
  const auto take = [&](const auto& from, auto& to) {
    if (from.empty()) return;
    to.resize(k);
    for (std::size_t i = 0; i < k; ++i) to[i] = from[static_cast<std::size_t>(idx[i])];
  };
  take(src.positions, dst.positions);
  take(src.rgb, dst.rgb);
  take(src.intensity, dst.intensity);
  take(src.classification, dst.classification);
  take(src.gps_time, dst.gps_time);
  take(src.normals, dst.normals);
  for (const ScalarField& f : src.scalars) {
    dst.scalars.push_back({f.name, {}});
    take(f.values, dst.scalars.back().values);
  }
  dst.crs_wkt = src.crs_wkt;
  dst.rgb_from_8bit_las = src.rgb_from_8bit_las;
  dst.viewpoint = src.viewpoint;
  return out;
}

/// NumPy's selection `key` (a boolean mask, integer indices, a slice) of the point indices 0..N-1,
/// as int64 indices in [0, N), C-contiguous. NumPy raises IndexError for a mask of another length
/// or an index out of range. Unsigned indices are checked here first: NumPy casts uint64 indices
/// to intp, so 2**64 - 1 would select the last point as -1 does.
IndexArray selection(const PyCloud& c, py::handle key) {
  py::module_ np = numpy();
  const auto n = static_cast<std::int64_t>(c.cloud.size());
  if (py::isinstance<py::array>(key)) {
    const py::array k = py::reinterpret_borrow<py::array>(key);
    if (k.dtype().kind() == 'u' && k.size() > 0) {
      const py::int_ hi(k.attr("max")());
      if (hi >= py::int_(n))
        throw py::index_error("index " + py::repr(hi).cast<std::string>() + " is out of bounds for a cloud of " +
                              std::to_string(n) + " points");
    }
  }
  const py::object all = np.attr("arange")(n, "dtype"_a = "int64");
  const py::array sel = all[key];
  if (sel.ndim() != 1)
    throw py::type_error("PointCloud: a selection must give a one-dimensional array of points (a boolean mask of "
                         "length N, integer indices or a slice), got shape " + shape_text(sel));
  IndexArray out = IndexArray::ensure(sel);
  if (!out) throw py::error_already_set();
  return out;
}

std::shared_ptr<PyCloud> take(const PyCloud& c, py::handle indices) {
  const py::array a = numpy().attr("asarray")(indices);
  if (a.size() > 0 && a.dtype().kind() != 'i' && a.dtype().kind() != 'u')
    throw py::type_error("take: expected integer indices, got dtype " + dtype_text(a) +
                         (a.dtype().kind() == 'b' ? " (use pc[mask] for a boolean mask)" : ""));
  if (a.ndim() != 1)
    throw py::value_error("take: expected a one-dimensional array of indices, got shape " + shape_text(a));
  // An unsigned array goes to selection() as it is, which checks its range (astype would wrap
  // 2**64 - 1 to -1); an empty one of any dtype is cast, as NumPy indexes only with integers.
  return gather(c, selection(c, a.size() > 0 ? py::object(a) : a.attr("astype")("int64")));
}

}  // namespace

CloudArg cloud_arg(py::handle v, const char* name, bool allow_path) {
  CloudArg a;
  if (py::isinstance<PyCloud>(v)) {
    PyCloud& c = v.cast<PyCloud&>();
    a.keep = py::reinterpret_borrow<py::object>(v);
    a.points = &c.cloud;
    a.info = &c.info;
  } else if (allow_path && is_path_like(v)) {
    a.path = path_arg(v, name);
  } else if (py::isinstance<py::array>(v) || py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    const Vec3Rows rows = as_vec3_rows(v, name);
    a.owned = std::make_unique<PointCloud>();
    std::string bad;
    {
      // The copy and the finiteness scan need no Python (rows.keep holds the array).
      py::gil_scoped_release nogil;
      a.owned->positions.assign(rows.rows.begin(), rows.rows.end());
      try {
        a.owned->validate();
      } catch (const std::invalid_argument& e) {
        bad = e.what();
      }
    }
    if (!bad.empty()) throw py::value_error(std::string(name) + ": " + bad);
    a.points = a.owned.get();
  } else {
    throw py::type_error(std::string(name) + " must be " + (allow_path ? "a file name (str or os.PathLike), " : "") +
                         "a rayscan.PointCloud or an (N, 3) array of coordinates, got " + type_name(v));
  }
  return a;
}

namespace {

/// The format of a PLY, PCD or text output, whose reader takes a field spelt like another
/// attribute or a LAS field for that (docs/formats.md "Dedicated fields from named values");
/// nullopt for LAS, which keeps every extra-bytes name as it is, and for a bad extension (the
/// writer names it).
std::optional<io::Format> renaming_format(const std::string& path) {
  try {
    const io::Format f = io::format_from_extension(path);
    if (f == io::Format::ply || f == io::Format::pcd || f == io::Format::text) return f;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

/// Refuses a field of rayscan.write that `path`'s reader (of `format`) would give back under
/// another name, by the rules the readers and writers share (rayscan/io/field_names.hpp): another
/// spelling of intensity, classification or GPS time (any case, "gpstime"), which the reader
/// moves into that attribute; a LAS field's (PDAL's "ReturnNumber"), which it renames
/// (io::las_standard_scalar_name); and for PCD and text a position, normal or colour name ("nx",
/// "red"), which their readers take for that attribute (io::scalar_read_back_as; their writers
/// would add a suffix). Raises ValueError "write: field 'gpstime' would read back from out.ply
/// as the gps_time attribute; ...".
void check_name_reads_back(const std::string& name, const std::string& path, io::Format format) {
  if (const char* attribute = io::dedicated_field_name(name))
    throw py::value_error("write: field '" + name + "' would read back from " + path + " as the " + attribute +
                          " attribute; give it as PointCloud(..., " + attribute + "=...) or use another name");
  const char* las = io::las_standard_scalar_name(name);
  if (las != nullptr && name != las)
    throw py::value_error("write: field '" + name + "' would read back from " + path + " as '" + las +
                          "' (the LAS field's name); write it as " + las + "=...");
  if (const char* other = io::scalar_read_back_as(format, name))
    throw py::value_error("write: field '" + name + "' would read back from " + path + " as " + other +
                          "; use another name, or write PLY or LAS, which keep it");
}

/// rayscan.write. The writer takes one PointCloud, which owns its arrays, so `fields` cannot be
/// added to a PointCloud object's cloud as views: that cloud is copied (another Python thread may
/// read it meanwhile, so it is not borrowed and given back), with the GIL released, as the write
/// itself; `c.keep` holds the object for both. An array's cloud is already the call's own copy and
/// takes the fields in place. The fields are converted to float64 first, with the GIL (NumPy).
/// A failed system call (a missing folder, a full disk) raises raise_os_error's OSError subclass
/// for its errno, named by `path`, the library's message as its note; a refusal by rule (a FIFO
/// at the path) a plain OSError with the message. While it writes, a SIGTERM, SIGINT or SIGHUP
/// that would end the process anyway removes the temporary file first (InterruptCleanup).
void write(py::handle path, py::handle cloud, const py::dict& fields) {
  const std::string file = path_arg(path, "path");
  CloudArg c = cloud_arg(cloud, "cloud", /*allow_path=*/false);
  std::vector<ScalarField> extra;
  const std::optional<io::Format> renaming = renaming_format(file);
  for (auto [k, v] : fields) {
    const std::string name = py::str(k).cast<std::string>();
    check_scalar_name(name, "write");
    if (renaming) check_name_reads_back(name, file, *renaming);
    extra.push_back({name, values_as<double>(column(v, name, c.points->size(), 0, "biuf", "real numbers"))});
  }
  const io::LasWriteOptions las = c.info ? io::las_grid_of(*c.info) : io::LasWriteOptions{};
  std::string io_error;  // an I/O failure is an OSError, like an unreadable file
  int io_errno = 0;      // the errno of the failed call, 0 for a refusal by rule
  {
    py::gil_scoped_release nogil;
    const InterruptCleanup on_signal;
    const PointCloud* pc = c.points;
    PointCloud copy;  // a PointCloud object's cloud plus `fields`
    if (!extra.empty()) {
      PointCloud* target = c.owned.get();
      if (!target) {
        copy = *pc;
        target = &copy;
      }
      for (ScalarField& f : extra) set_scalar(*target, f.name, std::move(f.values));
      pc = target;
    }
    try {
      io::write_point_cloud(file, *pc, las);
    } catch (const std::invalid_argument&) {
      throw;  // a bad name or cloud: ValueError
    } catch (const OutputFileError& e) {
      io_error = e.what();
      io_errno = e.code().value();
    } catch (const std::system_error& e) {  // std::filesystem's
      io_error = e.what();
      if (e.code().category() == std::generic_category() || e.code().category() == std::system_category())
        io_errno = e.code().value();
    } catch (const std::runtime_error& e) {
      io_error = e.what();
    }
  }
  if (io_errno != 0) raise_os_error(io_errno, file, io_error);
  if (!io_error.empty()) {
    PyErr_SetString(PyExc_OSError, io_error.c_str());
    throw py::error_already_set();
  }
}

}  // namespace

/// Defines rayscan.ScalarFields in `m`: the read-only mapping PointCloud.scalars returns (a
/// collections.abc.Mapping: len, iteration, in, get, keys, items, == with a dict). Read-only
/// because a PointCloud's fields are fixed once made (a job may be reading the cloud in another
/// thread with the GIL released); assignment raises TypeError naming the calls that add a field.
/// The arrays themselves are views of the cloud, as every attribute is.
void define_scalar_fields(py::module_& m) {
  py::dict scope;
  scope["__name__"] = m.attr("__name__");
  py::exec(R"py(
import collections.abc

class ScalarFields(collections.abc.Mapping):
    """PointCloud.scalars: name -> (N,) float64 view of each scalar field, read-only. A new
    field is added by PointCloud(xyz, ..., scalars={name: values}) or written by
    rayscan.write(path, pc, name=values)."""

    __slots__ = ("_fields",)

    def __init__(self, fields):
        self._fields = fields

    def __getitem__(self, name):
        return self._fields[name]

    def __iter__(self):
        return iter(self._fields)

    def __len__(self):
        return len(self._fields)

    def __repr__(self):
        return "ScalarFields(" + repr(self._fields) + ")"

    def __setitem__(self, name, values):
        raise TypeError("PointCloud.scalars is read-only: give a new field as PointCloud(xyz, ..., "
                        "scalars={...}) or write it with rayscan.write(path, pc, " + str(name) + "=values)")

    def __delitem__(self, name):
        raise TypeError("PointCloud.scalars is read-only: keep fewer fields with rayscan.read(path, "
                        "attributes=[...])")
)py", scope);
  m.attr("ScalarFields") = scope["ScalarFields"];
}

void bind_io(py::module_& m) {
  define_scalar_fields(m);
  py::class_<PyCloud, std::shared_ptr<PyCloud>>(m, "PointCloud", R"doc(
A point cloud: read by rayscan.read() (arrays are NumPy views of the reader's memory, no copy,
kept alive by this object) or built from NumPy arrays (copied):

    PointCloud(xyz, rgb=None, intensity=None, classification=None, gps_time=None,
               normals=None, scalars=None, crs=None)

  xyz            (N, 3) float64  positions in the cloud's world frame and units (the CRS's)
  rgb            (N, 3) uint16   colour, 0..65535 per channel. Given as uint8 (0..255) it is
                                 scaled by 257 (255 -> 65535); as uint16 it is kept. 8-bit LAS
                                 sources are read scaled by 257 too.
  intensity      (N,)   uint16   return intensity as stored (LAS: raw 16-bit); integers 0..65535
  classification (N,)   uint8    ASPRS class code; integers 0..255
  gps_time       (N,)   float64  GPS time, seconds as in the file
  normals        (N, 3) float32  unit normals (PLY nx ny nz, PCD normal_*)
  scalars        dict name -> (N,) float64: every other per-point field (LAS extra bytes,
                 return_number, scan_angle in degrees, PLY/PCD properties); .scalars is a
                 read-only mapping of views
  crs            the CRS as GDAL reads it ("EPSG:2992", WKT, PROJJSON, a PROJ string), kept
                 as WKT (WKT as given); None when unknown. Text GDAL cannot read: ValueError
  epsg           EPSG code from LAS GeoKeys, or None

Absent attributes are None. Bad shapes, dtypes or values raise ValueError naming the argument,
a non-finite position ValueError naming the point, an argument of the wrong type TypeError.
pc[mask] (bool (N,)), pc[indices], pc[start:stop:step] and pc.take(indices) give a new cloud of
those points with every attribute, as NumPy indexes each array; pc["name"] gives one attribute.)doc")
      .def(py::init(
               [](py::handle xyz, py::handle rgb, py::handle intensity, py::handle classification, py::handle gps_time,
                  py::handle normals, py::handle scalars, py::handle crs) {
                 return std::make_shared<PyCloud>(
                     from_arrays(xyz, rgb, intensity, classification, gps_time, normals, scalars, crs));
               }),
           py::arg("xyz"), py::arg("rgb") = py::none(), py::arg("intensity") = py::none(),
           py::arg("classification") = py::none(), py::arg("gps_time") = py::none(), py::arg("normals") = py::none(),
           py::arg("scalars") = py::none(), py::arg("crs") = py::none())
      .def_static("from_structured",
                  [](py::handle a, py::handle crs) { return std::make_shared<PyCloud>(from_structured(a, crs)); },
                  py::arg("array"), py::arg("crs") = py::none(), R"doc(
A PointCloud from a NumPy structured array (one record per point), as PDAL
(pipeline.arrays[0]) or laspy-style code gives them. Fields, PDAL's name or laspy's:
X Y Z / x y z (required), Red Green Blue / red green blue (uint8 or uint16), Intensity /
intensity, Classification / classification, GpsTime / gps_time, NormalX NormalY NormalZ /
nx ny nz. Every other numeric field becomes a scalar field of its name; PDAL's LAS dimensions
ReturnNumber, NumberOfReturns, ScanDirectionFlag, EdgeOfFlightLine, ScanAngleRank (degrees),
UserData, PointSourceId, ScanChannel, Infrared (and laspy's scan_angle_rank) take rayscan's
names (return_number, ..., scan_angle, nir), which rayscan.write stores in the standard LAS
fields. crs: as PointCloud's ("EPSG:2992", WKT, ...; a PDAL array carries none: take it from the
pipeline's metadata, e.g. pipeline.metadata["metadata"]["readers.las"]["comp_spatialreference"]),
or None. Raises
ValueError for a missing X/Y/Z, both spellings of one field, or a non-numeric field.)doc")
      .def("__len__", [](const PyCloud& c) { return c.cloud.size(); })
      .def("__getitem__",
           [](py::object self, py::handle key) -> py::object {
             const PyCloud& c = self.cast<const PyCloud&>();
             if (py::isinstance<py::str>(key)) {
               const std::string name = key.cast<std::string>();
               py::object a = attribute(self, name);
               if (a.is_none()) a = scalar_attribute(self, name);
               if (a.is_none()) throw py::key_error(name);
               return a;
             }
             if (py::isinstance<py::int_>(key) || (!py::isinstance<py::array>(key) && py::hasattr(key, "__index__")))
               throw py::type_error("PointCloud[i]: one index is not a cloud; use pc.take([i]), pc[mask] or "
                                    "pc[start:stop]");
             return py::cast(gather(c, selection(c, key)));
           },
           py::arg("key"),
           "pc[\"name\"]: one attribute (KeyError when absent). pc[mask] (bool (N,)), pc[indices] (int), "
           "pc[start:stop:step]: a new PointCloud of those points (NumPy's indexing rules; IndexError out of range, "
           "unsigned indices too).")
      .def("take", &take, py::arg("indices"),
           "A new PointCloud of the points `indices` ((K,) integers in [-N, N), in that order, repeats "
           "allowed) with every attribute. Raises TypeError for non-integer indices, IndexError out of range.")
      .def("__contains__", [](const PyCloud& c, const std::string& name) { return c.has(name); })
      .def_property_readonly("xyz", [](py::object s) { return attribute(s, "xyz"); },
                             "(N, 3) float64 positions in the cloud's world frame and units (a view of the cloud's memory).")
      .def_property_readonly("rgb", [](py::object s) { return attribute(s, "rgb"); },
                             "(N, 3) uint16 colour, 0..65535 per channel, or None when the cloud has none.")
      .def_property_readonly("intensity", [](py::object s) { return attribute(s, "intensity"); },
                             "(N,) uint16 return intensity as stored, or None.")
      .def_property_readonly("classification", [](py::object s) { return attribute(s, "classification"); },
                             "(N,) uint8 ASPRS class code, or None.")
      .def_property_readonly("gps_time", [](py::object s) { return attribute(s, "gps_time"); },
                             "(N,) float64 GPS time in seconds as in the file, or None.")
      .def_property_readonly("normals", [](py::object s) { return attribute(s, "normals"); },
                             "(N, 3) float32 unit normals, or None.")
      .def_property_readonly("scalars",
                             [scalar_fields = py::object(m.attr("ScalarFields"))](py::object s) {
                               py::dict d;
                               for (const ScalarField& f : s.cast<const PyCloud&>().cloud.scalars)
                                 d[py::str(f.name)] = scalar_attribute(s, f.name);
                               return scalar_fields(d);
                             },
                             "Read-only mapping name -> (N,) float64 view of every other "
                             "per-point field (LAS extra bytes, return_number, scan_angle in degrees, PLY/PCD "
                             "properties); empty when none. Assigning to it raises TypeError: add a field with "
                             "PointCloud(..., scalars={...}) or rayscan.write(path, pc, name=values).")
      .def_property_readonly("attributes", &PyCloud::attributes,
                             "Names of the attributes present (xyz first, then rgb, ..., scalars).")
      .def_property_readonly("crs",
                             [](const PyCloud& c) -> py::object {
                               if (c.cloud.crs_wkt.empty()) return py::none();
                               return py::str(c.cloud.crs_wkt);
                             },
                             "The coordinate reference system as WKT (a crs given as \"EPSG:2992\" or PROJJSON "
                             "is converted), or None when unknown.")
      .def_property_readonly("epsg",
                             [](const PyCloud& c) -> py::object {
                               if (c.info.epsg == 0) return py::none();
                               return py::int_(c.info.epsg);
                             },
                             "EPSG code from the LAS GeoKeys (int), or None when the file names none.")
      .def_property_readonly("format",
                             [](const PyCloud& c) -> py::object {
                               if (c.info.format.empty()) return py::none();
                               return py::str(c.info.format);
                             },
                             "\"LAS\", \"LAZ\", \"PLY\", \"PCD\", \"text\" or \"f64\" for a cloud read from a "
                             "file (and its subsets), None for one built from arrays.")
      .def_property_readonly("point_format",
                             [](const PyCloud& c) -> py::object {
                               if (c.info.point_format < 0) return py::none();
                               return py::int_(c.info.point_format);
                             },
                             "LAS point data record format (0..10), None for other formats.")
      .def_property_readonly("path",
                             [](const PyCloud& c) -> py::object {
                               if (c.path.empty()) return py::none();
                               return py::str(c.path);
                             },
                             "The file the points were read from, None for a cloud built from arrays.")
      .def_property_readonly("bounds",
                             [](const PyCloud& c) {
                               const AABB b = c.cloud.bounds();
                               std::vector<double> v{b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z};
                               return to_numpy(std::move(v), {2, 3});
                             },
                             "(2, 3) float64 [lo, hi] recomputed from the points (inf/-inf if empty).")
      .def("__repr__", [](const PyCloud& c) {
        std::string a;
        for (const std::string& n : c.attributes()) a += (a.empty() ? "" : ", ") + n;
        return "<rayscan.PointCloud " + (c.path.empty() ? std::string("(arrays)") : c.path) + ": " +
               std::to_string(c.cloud.size()) + " points, " + (c.info.format.empty() ? "" : c.info.format + ", ") +
               "attributes: " + a + ">";
      });

  m.def("_read", [](py::handle path, const py::object& attributes) {
    return std::make_shared<PyCloud>(read(path_arg(path, "path"), attributes));
  }, py::arg("path"), py::arg("attributes") = py::none());
  m.def("_write", &write, py::arg("path"), py::arg("cloud"), py::arg("fields") = py::dict());
}

}  // namespace rayscan::python
