// NumPy <-> C++ conversions shared by every binding: validated (N, 3) float64 row views of Python
// arrays, vectors moved into NumPy arrays without a copy, and the CSR (offsets + flat arrays)
// layout of batch query results.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rayscan::python {

namespace py = pybind11;

static_assert(sizeof(Vec3) == 3 * sizeof(double), "glm::dvec3 must be three packed doubles");

/// Rows of an (N, 3) array as Vec3, borrowed from a float64 C-contiguous NumPy array.
/// `keep` owns the memory (the caller's array itself when it already was float64 C-contiguous:
/// zero-copy; otherwise a converted copy).
struct Vec3Rows {
  py::array keep;
  std::span<const Vec3> rows;
};

/// View `obj` (anything numpy.asarray accepts) as (N, 3) float64 rows. Integer and floating
/// dtypes are accepted (converted to float64 when needed). Another type raises TypeError
/// "<name>: expected an (N, 3) array of real numbers, got dtype <U3" (None, a str, an array of
/// str, bool, complex or objects); a str or os.PathLike adds that a point file is read by
/// rayscan.read or opened by rayscan.open. Another shape, or a ragged sequence (NumPy's own
/// message), raises ValueError. With `allow_single`, a shape (3,) array is accepted as one row.
/// Values are not checked for finiteness here (the callee names the bad row).
Vec3Rows as_vec3_rows(py::handle obj, const std::string& name, bool allow_single = false);

/// Move `v` into a new NumPy array of the given shape (no copy: the array owns the vector).
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<T>(std::move(v));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owned->data(), owner);
}

/// Move `v` into a new one-dimensional NumPy array.
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& v) {
  const auto n = static_cast<py::ssize_t>(v.size());
  return to_numpy(std::move(v), {n});
}

/// A NumPy view (no copy) of `n` rows of `cols` values of type T at `data`, kept alive by `base`.
/// cols == 0 gives a one-dimensional array.
template <class T>
py::array view_rows(const T* data, std::size_t n, std::size_t cols, py::handle base) {
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(n)};
  if (cols) shape.push_back(static_cast<py::ssize_t>(cols));
  return py::array_t<T>(shape, data, base);
}

/// Check that a Python int `k` (None = no limit; or anything with __index__, not a bool) is a
/// valid result count; returns kAllPoints for None, and for any k at or above it. Raises
/// TypeError "k must be None or an integer >= 0, got float" for another type, ValueError "..., got
/// -1" for a negative k.
std::size_t parse_k(const py::object& k);

/// The flag argument `name`: True or False (a Python bool or a NumPy bool). Raises TypeError
/// "<name> must be True or False, got str" for anything else (also 0, 1 and None, which pybind11's
/// bool conversion would take, and 'no', which it would refuse with its "incompatible function
/// arguments" listing).
bool bool_arg(py::handle v, const char* name);

/// The integer argument `name`: a Python int or anything with __index__ (NumPy integers), not a
/// bool, within [lo, hi]. `expected` says what is allowed ("an integer in [1, 2^32 - 1]").
/// Raises TypeError "<name> must be <expected>, got float" for another type and ValueError
/// "<name> must be <expected>, got <value>" outside the range (any size: 2**70 too), instead of
/// pybind11's conversion errors.
long long int_arg(py::handle v, const char* name, long long lo, long long hi, const std::string& expected);

/// As int_arg for an unsigned 64-bit argument (a seed): [0, 2^64 - 1].
std::uint64_t uint64_arg(py::handle v, const char* name);

/// As int_arg with None allowed (returns nullopt).
template <class T>
std::optional<T> opt_int_arg(py::handle v, const char* name, long long lo, long long hi, const std::string& expected) {
  if (v.is_none()) return std::nullopt;
  return static_cast<T>(int_arg(v, name, lo, hi, expected));
}

/// The real-number argument `name`: a Python int or float, or anything with __float__ (NumPy
/// scalars), not a bool or str. Raises TypeError "<name> must be <expected>, got str" instead of
/// pybind11's "incompatible function arguments". Values are not range-checked here (the job names
/// an out-of-range one).
double float_arg(py::handle v, const char* name, const std::string& expected);

/// As float_arg with None allowed (returns nullopt).
std::optional<double> opt_float_arg(py::handle v, const char* name, const std::string& expected);

/// The text argument `name`: a str. Raises TypeError "<name> must be <expected>, got datetime".
std::string str_arg(py::handle v, const char* name, const std::string& expected);

/// Check a `threads` argument: 0 (every core) or a positive count up to 4096; returns it. Raises
/// ValueError "threads must be 0 (all cores) or a positive count up to 4096, got -1" (TypeError
/// for a non-integer).
unsigned parse_threads(py::handle threads);

/// Python's name of v's type ("float", "str", "NoneType").
std::string type_name(py::handle v);

/// The `cache` keyword of Site, visibility and solar: a byte size as `--cache` takes it ("2G",
/// "512M"; parse_byte_size), the decoded-node budget of a COPC file queried in place. Raises
/// ValueError "cache: size '...': expected ...", TypeError for another type than str.
std::size_t cache_arg(py::handle cache_obj);

/// True for a str or an os.PathLike (what path_arg accepts, or refuses with a ValueError).
bool is_path_like(py::handle v);

/// A file name argument: a str or an os.PathLike giving one. Raises TypeError "<name> must be a
/// file name (str or os.PathLike), got bytes" and ValueError "<name> '<repr>' contains a NUL
/// byte; expected a file name" (no file can have such a name; the OS call would fail without
/// saying why).
std::string path_arg(py::handle v, const char* name);

/// An input file name argument: path_arg, then the file opened as the library's input policy
/// opens it (rayscan/base/input_file.hpp: an existing, readable regular file) and closed again.
/// A file that cannot be opened raises, here, the OSError subclass of its errno (os_error:
/// FileNotFoundError, IsADirectoryError, ...; a plain OSError for a refusal by rule, a FIFO),
/// with the message "<path>: cannot open file: No such file or directory" (module.cpp), where the
/// job behind a scene, camera, observer, image or weather file would report it inside a content
/// error (ValueError) or a RuntimeError.
std::string input_path_arg(py::handle v, const char* name);

/// The OSError subclass Python's open() raises for `err` (FileNotFoundError for ENOENT,
/// IsADirectoryError, PermissionError, OSError with errno ENOSPC for a full disk, ...) with errno,
/// strerror and filename `path` set, as open() sets them; `detail`, the library's one-line
/// message, when not empty, is added as a note (PEP 678, Python 3.11+), which a traceback prints.
py::object os_error(int err, const std::string& path, const std::string& detail = {});

/// Sets the exception os_error(err, path, detail) as the Python error (an exception translator's
/// way to raise it).
void set_os_error(int err, const std::string& path, const std::string& detail = {});

/// A list of names: one str, or an iterable of str (list, tuple). Raises TypeError "<name> must be
/// a str or a list of str, got a list holding int (item 0)".
std::vector<std::string> names_arg(py::handle v, const char* name);

}  // namespace rayscan::python
