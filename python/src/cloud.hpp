// The object behind rayscan.PointCloud: a read cloud plus the file metadata Python sees. Shared by
// the io binding (which creates it) and the job bindings (which accept it as an in-memory cloud).
#pragma once

#include "rayscan/io/file_info.hpp"
#include "rayscan/octree/point_cloud.hpp"

#include <pybind11/pybind11.h>

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

namespace rayscan::python {

/// The attributes with a dedicated PointCloud field, in the order PyCloud::attributes lists them.
inline const std::vector<std::string>& standard_attributes() {
  static const std::vector<std::string> names{"xyz", "rgb", "intensity", "classification",
                                              "gps_time", "normals"};
  return names;
}

/// A cloud (read, or built from arrays) plus the file metadata the Python object exposes.
struct PyCloud {
  PointCloud cloud;
  io::FileInfo info;  ///< what the reader found (format "" for a cloud built from arrays)
  std::string path;   ///< the file read, "" for a cloud built from arrays

  [[nodiscard]] bool has(const std::string& name) const {
    if (name == "xyz") return true;
    if (name == "rgb") return !cloud.rgb.empty();
    if (name == "intensity") return !cloud.intensity.empty();
    if (name == "classification") return !cloud.classification.empty();
    if (name == "gps_time") return !cloud.gps_time.empty();
    if (name == "normals") return !cloud.normals.empty();
    return cloud.scalar(name) != nullptr;
  }
  [[nodiscard]] std::vector<std::string> attributes() const {
    std::vector<std::string> out;
    for (const std::string& n : standard_attributes())
      if (has(n)) out.push_back(n);
    for (const ScalarField& f : cloud.scalars) out.push_back(f.name);
    return out;
  }
  /// Drop every attribute not in `keep` (positions always stay).
  void keep_only(const std::vector<std::string>& keep) {
    auto wanted = [&](const std::string& n) { return std::find(keep.begin(), keep.end(), n) != keep.end(); };
    if (!wanted("rgb")) std::vector<Rgb16>().swap(cloud.rgb);
    if (!wanted("intensity")) std::vector<std::uint16_t>().swap(cloud.intensity);
    if (!wanted("classification")) std::vector<std::uint8_t>().swap(cloud.classification);
    if (!wanted("gps_time")) std::vector<double>().swap(cloud.gps_time);
    if (!wanted("normals")) std::vector<glm::vec3>().swap(cloud.normals);
    std::erase_if(cloud.scalars, [&](const ScalarField& f) { return !wanted(f.name); });
  }
};

/// A job's `cloud` argument: a file name, a rayscan.PointCloud (used in place, not copied) or an
/// (N, 3) array of positions (copied). Movable; `points` and `info` stay valid while it lives.
struct CloudArg {
  std::string path;                    ///< the file name, "" for points in memory
  const PointCloud* points = nullptr;  ///< the points in memory, nullptr for a file name
  const io::FileInfo* info = nullptr;  ///< a PointCloud's file metadata, nullptr otherwise
  pybind11::object keep;               ///< the PointCloud object `points` belongs to
  std::unique_ptr<PointCloud> owned;   ///< an array's points
};

/// Converts a job's `cloud` argument named `name`. Raises TypeError "<name> must be a file name
/// (str or os.PathLike), a rayscan.PointCloud or an (N, 3) array of coordinates, got int" (without
/// the file name when `allow_path` is false), ValueError for an array of another shape or dtype or
/// with a non-finite coordinate (naming the point).
CloudArg cloud_arg(pybind11::handle v, const char* name, bool allow_path = true);

}  // namespace rayscan::python
