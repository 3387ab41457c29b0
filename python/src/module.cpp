// The `rayscan._rayscan` extension module: the C++ library on NumPy arrays. The public
// Python API (docstrings, result classes) is the package python/rayscan/__init__.py.
#include "arrays.hpp"
#include "bindings.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/version.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/site/index_file.hpp"
#ifdef RAYSCAN_PYTHON_JOBS
#include "rayscan/analysis/observer.hpp"
#include "rayscan/render/scene.hpp"
#endif

namespace py = pybind11;

PYBIND11_MODULE(_rayscan, m) {
  m.doc() = "rayscan C++ core (use the `rayscan` package)";
  m.attr("__version__") = rayscan::version();  // the project version of CMakeLists.txt
  // Library errors keep their one-line messages: bad arguments raise ValueError (pybind11 maps
  // std::invalid_argument and std::length_error), unreadable or malformed files raise OSError. A
  // file that cannot be opened raises the OSError subclass open() raises for its errno
  // (FileNotFoundError, IsADirectoryError, PermissionError, ...) with errno and filename, the
  // one-line message its note; one refused by rule (a FIFO, a size cap) a plain OSError.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const rayscan::InputFileError& e) {  // missing, unreadable, not a regular file
      if (e.error_number() != 0)
        rayscan::python::set_os_error(e.error_number(), e.path().string(), e.what());
      else
        PyErr_SetString(PyExc_OSError, e.what());
    } catch (const rayscan::io::FormatError& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    } catch (const rayscan::io::IndexError& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    }
  });
  rayscan::python::bind_io(m);
  rayscan::python::bind_index(m);
#ifdef RAYSCAN_PYTHON_JOBS
  rayscan::python::bind_jobs(m);
  // Scene and observer files: malformed content is a ValueError like a bad option.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const rayscan::render::SceneError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const rayscan::analysis::ObserverError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
#endif
}
