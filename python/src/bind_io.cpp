// rayscan.read(path, attributes=...) -> PointCloud with NumPy views (no copy) of the reader's
// arrays. Readers: rayscan::io::read_point_cloud (LAS 1.0-1.4, PLY, PCD, XYZ/CSV/TXT, .f64;
// docs/formats.md).
#include "arrays.hpp"
#include "bindings.hpp"
#include "cloud.hpp"

#include "rayscan/io/point_io.hpp"

#include <pybind11/stl.h>

#include <algorithm>
#include <memory>
#include <optional>

namespace rayscan::python {

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

PyCloud read(const std::string& path, const py::object& attributes) {
  std::optional<std::vector<std::string>> keep;
  if (!attributes.is_none()) keep = names_arg(attributes, "attributes");
  io::ReadOptions opts;
  if (keep) {
    const auto& std_names = standard_attributes();
    opts.scalars = std::any_of(keep->begin(), keep->end(), [&](const std::string& n) {
      return std::find(std_names.begin(), std_names.end(), n) == std_names.end();
    });
  }
  PyCloud c;
  c.path = path;
  {
    py::gil_scoped_release nogil;
    c.cloud = io::read_point_cloud(path, opts, &c.info);
  }
  if (keep) {
    for (const std::string& n : *keep)
      if (!c.has(n)) {
        std::string have;
        for (const std::string& a : c.attributes()) have += (have.empty() ? "" : ", ") + a;
        throw py::value_error(path + ": no attribute '" + n + "' (the file has: " + have + ")");
      }
    c.keep_only(*keep);
  }
  return c;
}

}  // namespace

void bind_io(py::module_& m) {
  py::class_<PyCloud, std::shared_ptr<PyCloud>>(m, "PointCloud", R"doc(
A point cloud read by rayscan.read(). Arrays are NumPy views of the reader's memory (no copy),
kept alive by this object; absent attributes are None.

  xyz            (N, 3) float64  positions in the file's world frame and units (the CRS's)
  rgb            (N, 3) uint16   colour, 0..65535 per channel (8-bit sources scaled by 257)
  intensity      (N,)   uint16   return intensity as stored (LAS: raw 16-bit)
  classification (N,)   uint8    ASPRS class code
  gps_time       (N,)   float64  GPS time, seconds as in the file
  normals        (N, 3) float32  unit normals (PLY nx ny nz, PCD normal_*)
  scalars        dict name -> (N,) float64: every other per-point field (LAS extra bytes,
                 return_number, scan_angle in degrees, PLY/PCD properties)
  crs            WKT string, or None when the file has no usable CRS
  epsg           EPSG code from LAS GeoKeys, or None)doc")
      .def("__len__", [](const PyCloud& c) { return c.cloud.size(); })
      .def("__getitem__",
           [](py::object self, const std::string& name) {
             py::object a = attribute(self, name);
             if (a.is_none()) throw py::key_error(name);
             return a;
           })
      .def("__contains__", [](const PyCloud& c, const std::string& name) { return c.has(name); })
      .def_property_readonly("xyz", [](py::object s) { return attribute(s, "xyz"); })
      .def_property_readonly("rgb", [](py::object s) { return attribute(s, "rgb"); })
      .def_property_readonly("intensity", [](py::object s) { return attribute(s, "intensity"); })
      .def_property_readonly("classification", [](py::object s) { return attribute(s, "classification"); })
      .def_property_readonly("gps_time", [](py::object s) { return attribute(s, "gps_time"); })
      .def_property_readonly("normals", [](py::object s) { return attribute(s, "normals"); })
      .def_property_readonly("scalars",
                             [](py::object s) {
                               py::dict d;
                               for (const ScalarField& f : s.cast<const PyCloud&>().cloud.scalars)
                                 d[py::str(f.name)] = attribute(s, f.name);
                               return d;
                             })
      .def_property_readonly("attributes", &PyCloud::attributes,
                             "Names of the attributes present (xyz first, then rgb, ..., scalars).")
      .def_property_readonly("crs",
                             [](const PyCloud& c) -> py::object {
                               if (c.cloud.crs_wkt.empty()) return py::none();
                               return py::str(c.cloud.crs_wkt);
                             })
      .def_property_readonly("epsg",
                             [](const PyCloud& c) -> py::object {
                               if (c.info.epsg == 0) return py::none();
                               return py::int_(c.info.epsg);
                             })
      .def_property_readonly("format", [](const PyCloud& c) { return c.info.format; },
                             "\"LAS\", \"PLY\", \"PCD\", \"text\" or \"f64\".")
      .def_property_readonly("point_format",
                             [](const PyCloud& c) -> py::object {
                               if (c.info.point_format < 0) return py::none();
                               return py::int_(c.info.point_format);
                             },
                             "LAS point data record format (0..10), None for other formats.")
      .def_property_readonly("path", [](const PyCloud& c) { return c.path; })
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
        return "<rayscan.PointCloud " + c.path + ": " + std::to_string(c.cloud.size()) + " points, " +
               c.info.format + ", attributes: " + a + ">";
      });

  m.def("_read", [](py::handle path, const py::object& attributes) {
    return std::make_shared<PyCloud>(read(path_arg(path, "path"), attributes));
  }, py::arg("path"), py::arg("attributes") = py::none());
}

}  // namespace rayscan::python
