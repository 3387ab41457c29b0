// The `rayscan._rayscan` extension module (issue 14): the C++ library on NumPy arrays. The public
// Python API (docstrings, result classes) is the package python/rayscan/__init__.py.
#include "bindings.hpp"

#include "rayscan/io/point_io.hpp"

namespace py = pybind11;

PYBIND11_MODULE(_rayscan, m) {
  m.doc() = "rayscan C++ core (use the `rayscan` package)";
  // Library errors keep their one-line messages: bad arguments raise ValueError (pybind11 maps
  // std::invalid_argument and std::length_error), unreadable or malformed files raise OSError.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const rayscan::io::FormatError& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    }
  });
  rayscan::python::bind_io(m);
  rayscan::python::bind_index(m);
}
