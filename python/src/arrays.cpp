#include "arrays.hpp"

#include "rayscan/octree/ray_query.hpp"

namespace rayscan::python {

Vec3Rows as_vec3_rows(py::handle obj, const std::string& name, bool allow_single) {
  py::module_ np = py::module_::import("numpy");
  py::array a = np.attr("asarray")(obj);  // ragged input raises ValueError in NumPy itself
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::value_error(name + ": expected an array of real numbers, got dtype " +
                          py::str(a.dtype()).cast<std::string>());
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

std::size_t parse_k(const py::object& k) {
  if (k.is_none()) return kAllPoints;
  const std::string bad = "k must be None or an integer >= 0, got " + py::repr(k).cast<std::string>();
  if (py::isinstance<py::bool_>(k)) throw py::value_error(bad);
  PyObject* i = PyNumber_Index(k.ptr());  // int, numpy integer, anything with __index__
  if (!i) {
    PyErr_Clear();
    throw py::value_error(bad);
  }
  const py::int_ v = py::reinterpret_steal<py::int_>(i);
  if (py::int_(0) > v) throw py::value_error(bad);
  if (v > py::int_(static_cast<unsigned long long>(kAllPoints) - 1)) return kAllPoints;
  return static_cast<std::size_t>(v.cast<unsigned long long>());
}

unsigned parse_threads(long long threads) {
  if (threads < 0 || threads > 4096)
    throw py::value_error("threads must be 0 (all cores) or a positive count, got " + std::to_string(threads));
  return static_cast<unsigned>(threads);
}

}  // namespace rayscan::python
