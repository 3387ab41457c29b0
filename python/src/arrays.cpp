#include "arrays.hpp"

#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/octree/ray_query.hpp"

#include <cstring>

namespace rayscan::python {

Vec3Rows as_vec3_rows(py::handle obj, const std::string& name, bool allow_single) {
  py::module_ np = py::module_::import("numpy");
  py::array a = np.attr("asarray")(obj);  // ragged input raises ValueError in NumPy itself
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    // A scalar (None, a str) is named by its type, an array by its dtype; a file name is the
    // likely slip where points are expected, so the message says what takes one.
    const std::string got = a.ndim() == 0 && !py::isinstance<py::array>(obj)
                                ? type_name(obj)
                                : "dtype " + py::str(a.dtype()).cast<std::string>();
    const std::string hint =
        is_path_like(obj) ? " (a point file is read by rayscan.read(path) or opened for queries by rayscan.open(path))"
                          : "";
    throw py::type_error(name + ": expected an (N, 3)" + std::string(allow_single ? " or (3,)" : "") +
                         " array of real numbers, got " + got + hint);
  }
  const bool single = allow_single && a.ndim() == 1 && a.shape(0) == 3;
  if (!single && (a.ndim() != 2 || a.shape(1) != 3)) {
    std::string shape = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) shape += (i ? ", " : "") + std::to_string(a.shape(i));
    shape += a.ndim() == 1 ? ",)" : ")";
    throw py::value_error(name + ": expected shape (N, 3)" + std::string(allow_single ? " or (3,)" : "") +
                          ", got " + shape);
  }
  // No copy when the input already is float64 and C-contiguous (the zero-copy path).
  auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!c) throw py::error_already_set();
  const std::size_t n = single ? 1 : static_cast<std::size_t>(c.shape(0));
  Vec3Rows out{c, {}};
  out.rows = std::span<const Vec3>(reinterpret_cast<const Vec3*>(c.data()), n);
  return out;
}

std::string type_name(py::handle v) { return py::str(py::type::handle_of(v).attr("__name__")).cast<std::string>(); }

bool is_path_like(py::handle v) { return py::isinstance<py::str>(v) || py::hasattr(v, "__fspath__"); }

namespace {

/// v as a Python int (operator.index), or TypeError naming the argument.
py::int_ index_of(py::handle v, const char* name, const std::string& expected) {
  PyObject* i = py::isinstance<py::bool_>(v) ? nullptr : PyNumber_Index(v.ptr());
  if (!i) {
    PyErr_Clear();
    throw py::type_error(std::string(name) + " must be " + expected + ", got " + type_name(v));
  }
  return py::reinterpret_steal<py::int_>(i);
}

}  // namespace

std::size_t parse_k(const py::object& k) {
  if (k.is_none()) return kAllPoints;
  const std::string expected = "None or an integer >= 0";
  const py::int_ v = index_of(k, "k", expected);
  if (py::int_(0) > v) throw py::value_error("k must be " + expected + ", got " + py::repr(v).cast<std::string>());
  if (v > py::int_(static_cast<unsigned long long>(kAllPoints) - 1)) return kAllPoints;
  return static_cast<std::size_t>(v.cast<unsigned long long>());
}

bool bool_arg(py::handle v, const char* name) {
  if (PyBool_Check(v.ptr())) return v.ptr() == Py_True;
  if (py::isinstance(v, py::module_::import("numpy").attr("bool_"))) return PyObject_IsTrue(v.ptr()) == 1;
  throw py::type_error(std::string(name) + " must be True or False, got " + type_name(v));
}

long long int_arg(py::handle v, const char* name, long long lo, long long hi, const std::string& expected) {
  const py::int_ i = index_of(v, name, expected);
  if (i < py::int_(lo) || i > py::int_(hi))
    throw py::value_error(std::string(name) + " must be " + expected + ", got " + py::repr(i).cast<std::string>());
  return i.cast<long long>();
}

std::uint64_t uint64_arg(py::handle v, const char* name) {
  const std::string expected = "an integer in [0, 2^64 - 1]";
  const py::int_ i = index_of(v, name, expected);
  if (i < py::int_(0) || i > py::int_(~std::uint64_t{0}))
    throw py::value_error(std::string(name) + " must be " + expected + ", got " + py::repr(i).cast<std::string>());
  return i.cast<std::uint64_t>();
}

double float_arg(py::handle v, const char* name, const std::string& expected) {
  const bool number = !py::isinstance<py::bool_>(v) && !py::isinstance<py::str>(v) && !py::isinstance<py::bytes>(v) &&
                      (py::hasattr(v, "__float__") || py::hasattr(v, "__index__"));
  if (!number) throw py::type_error(std::string(name) + " must be " + expected + ", got " + type_name(v));
  const double d = PyFloat_AsDouble(v.ptr());
  if (d == -1.0 && PyErr_Occurred()) throw py::error_already_set();  // __float__ raised, an int too large
  return d;
}

std::optional<double> opt_float_arg(py::handle v, const char* name, const std::string& expected) {
  if (v.is_none()) return std::nullopt;
  return float_arg(v, name, expected);
}

std::string str_arg(py::handle v, const char* name, const std::string& expected) {
  if (!py::isinstance<py::str>(v)) throw py::type_error(std::string(name) + " must be " + expected + ", got " + type_name(v));
  return v.cast<std::string>();
}

unsigned parse_threads(py::handle threads) {
  return static_cast<unsigned>(
      int_arg(threads, "threads", 0, 4096, "0 (all cores) or a positive count up to 4096"));
}

std::string path_arg(py::handle v, const char* name) {
  py::object s = py::reinterpret_borrow<py::object>(v);
  if (!py::isinstance<py::str>(s) && py::hasattr(s, "__fspath__")) s = s.attr("__fspath__")();
  if (!py::isinstance<py::str>(s))
    throw py::type_error(std::string(name) + " must be a file name (str or os.PathLike), got " + type_name(s));
  const std::string path = s.cast<std::string>();
  if (path.find('\0') != std::string::npos)
    throw py::value_error(std::string(name) + " " + py::repr(s).cast<std::string>() +
                          " contains a NUL byte; expected a file name");
  return path;
}

std::string input_path_arg(py::handle v, const char* name) {
  std::string path = path_arg(v, name);
  const InputFile probe(path);  // InputFileError (OSError, module.cpp) when it cannot be opened
  return path;
}

py::object os_error(int err, const std::string& path, const std::string& detail) {
  // OSError(errno, strerror, filename) constructs the subclass for errno.
  py::object e = py::reinterpret_borrow<py::object>(PyExc_OSError)(err, std::strerror(err), path);
  if (!detail.empty() && py::hasattr(e, "add_note")) e.attr("add_note")(detail);
  return e;
}

void set_os_error(int err, const std::string& path, const std::string& detail) {
  const py::object e = os_error(err, path, detail);
  PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(e.ptr())), e.ptr());
}

std::vector<std::string> names_arg(py::handle v, const char* name) {
  if (py::isinstance<py::str>(v)) return {v.cast<std::string>()};
  const std::string expected = std::string(name) + " must be a str or a list of str, got ";
  if (py::isinstance<py::bytes>(v) || !py::hasattr(v, "__iter__")) throw py::type_error(expected + type_name(v));
  std::vector<std::string> out;
  for (py::handle item : v) {
    if (!py::isinstance<py::str>(item))
      throw py::type_error(expected + "a " + type_name(v) + " holding " + type_name(item) + " (item " +
                           std::to_string(out.size()) + ")");
    out.push_back(item.cast<std::string>());
  }
  return out;
}

std::size_t cache_arg(py::handle cache_obj) {
  const std::string cache = str_arg(cache_obj, "cache", "a byte size as text (\"2G\", \"512M\")");
  try {
    return static_cast<std::size_t>(parse_byte_size(cache));
  } catch (const std::invalid_argument& e) {
    throw py::value_error(std::string("cache: ") + e.what());
  }
}

}  // namespace rayscan::python
