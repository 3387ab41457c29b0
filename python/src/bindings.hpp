// The parts of the `rayscan._rayscan` extension module, one function per area.
#pragma once

#include <pybind11/pybind11.h>

namespace rayscan::python {

/// rayscan.read and the PointCloud class (bind_io.cpp).
void bind_io(pybind11::module_& m);
/// Octree, KdTree, BruteForce and their batch queries (bind_index.cpp).
void bind_index(pybind11::module_& m);
/// render, visibility, compare over the library's job calls (bind_jobs.cpp; built when the job
/// API of docs/library.md exists: RAYSCAN_PYTHON_JOBS).
void bind_jobs(pybind11::module_& m);

}  // namespace rayscan::python
