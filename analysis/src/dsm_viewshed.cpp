#include "rayscan/analysis/dsm_viewshed.hpp"

#include "rayscan/base/progress.hpp"
#include "rayscan/base/threads.hpp"

#include <glm/geometric.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

namespace rayscan::analysis {

namespace {

// The R3 walk along one axis, the major one: the sight line from the eye at grid coordinates
// (fa, fb) (cell centres at integers; a along the major axis, b along the minor), height ze, to
// the target at the centre of cell (at, bt), height zt, with |at - fa| >= |bt - fb|, crosses the
// centre lines a = const strictly between the two; z(a, b) is the DSM there (na x nb cells).
template <class Z>
bool seen_along(double fa, double fb, double ze, std::int64_t at, std::int64_t bt, double zt, std::int64_t na,
                std::int64_t nb, Z&& z) {
  const double da = double(at) - fa, db = double(bt) - fb;
  if (da == 0.0) return true;  // the eye's own cell centre
  // Heights compare with a relative slack so that a surface exactly on the line does not hide.
  const double slack = 1e-9 * (1.0 + std::abs(ze) + std::abs(zt));
  // Interpolation between two centres, a missing one (NaN) standing for the other.
  auto lerp = [](float u, float v, double f) {
    if (!std::isfinite(u)) return double(v);
    if (!std::isfinite(v)) return double(u);
    return double(u) + f * (double(v) - double(u));
  };
  const std::int64_t step = da > 0 ? 1 : -1;
  for (std::int64_t a = da > 0 ? std::int64_t(std::floor(fa)) + 1 : std::int64_t(std::ceil(fa)) - 1; a != at; a += step) {
    if (a < 0 || a >= na) continue;
    const double t = (double(a) - fa) / da;  // > 0: a lies past the eye
    const double b = fb + t * db;
    std::int64_t b0 = std::int64_t(std::floor(b));
    const double f = b - double(b0);
    std::int64_t b1 = b0 + 1;
    if (b0 < 0) b0 = 0;
    if (b1 >= nb) b1 = nb - 1;
    if (b0 >= nb || b1 < 0) continue;
    const double surface = lerp(z(a, b0), z(a, b1), f);
    if (std::isfinite(surface) && surface > ze + t * (zt - ze) + slack) return false;
  }
  return true;
}

// Whether the target at the centre of cell (qt, rt), height zt, is seen from the eye at grid
// coordinates (fq, fr), height ze: R3 along columns when the line runs more east-west, else rows.
bool seen(const Raster& dsm, double fq, double fr, double ze, std::int64_t qt, std::int64_t rt, double zt) {
  const GridSpec& g = dsm.grid;
  const std::int64_t cols = g.cols, rows = g.rows;
  auto z = [&](std::int64_t q, std::int64_t r) { return dsm.values[std::size_t(r) * g.cols + std::size_t(q)]; };
  if (std::abs(double(qt) - fq) >= std::abs(double(rt) - fr))
    return seen_along(fq, fr, ze, qt, rt, zt, cols, rows, z);
  return seen_along(fr, fq, ze, rt, qt, zt, rows, cols, [&](std::int64_t r, std::int64_t q) { return z(q, r); });
}

}  // namespace

namespace {

// dsm_viewshed's work for the eyes `eyes`; admits(k, p): whether eye k's limits admit the cell's
// surface point p (world coordinates).
template <class Admits>
Raster viewshed_of(const Raster& dsm, std::span<const Vec3> eyes, double target_height, unsigned threads,
                   bool progress_bar, Admits&& admits) {
  const GridSpec& g = dsm.grid;
  if (dsm.values.size() != std::size_t(g.cols) * g.rows)
    throw std::invalid_argument("dsm viewshed: the DSM has " + std::to_string(dsm.values.size()) +
                                " values for " + std::to_string(g.cols) + " x " + std::to_string(g.rows) + " cells");
  if (!(target_height >= 0.0) || !std::isfinite(target_height))
    throw std::invalid_argument("dsm viewshed: target height must be a finite number >= 0");
  for (const Vec3& e : eyes)
    if (!std::isfinite(e.x) || !std::isfinite(e.y) || !std::isfinite(e.z))
      throw std::invalid_argument("dsm viewshed: an eye position is not finite");
  Raster out;
  out.grid = g;
  out.name = "viewshed on the DSM (exact line of sight to the cell centres, R3)";
  out.values.assign(dsm.values.size(), std::numeric_limits<float>::quiet_NaN());
  struct Eye {
    double q, r, z;  // grid coordinates (cell centres at integers) and height
  };
  std::vector<Eye> at;
  for (const Vec3& e : eyes) at.push_back({(e.x - g.x0) / g.cell - 0.5, (g.y_top - e.y) / g.cell - 0.5, e.z});
  // A grid of millions of cells takes minutes: the rows done, each counting its cells for the rate.
  Progress progress(g.rows, progress_bar, ProgressUnits{"rows", "cells/s", 1.0, 0});
  tbb::task_arena arena(static_cast<int>(resolve_threads(threads)));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, g.rows), [&](const auto& range) {
      for (std::uint32_t r = range.begin(); r != range.end(); ++r) {
        for (std::uint32_t q = 0; q < g.cols; ++q) {
          const float zs = dsm.values[std::size_t(r) * g.cols + q];
          if (!std::isfinite(zs)) continue;
          const Vec3 p(g.x0 + (q + 0.5) * g.cell, g.y_top - (r + 0.5) * g.cell, double(zs));
          bool any = false;
          for (std::size_t k = 0; k < at.size() && !any; ++k)
            any = admits(k, p) && seen(dsm, at[k].q, at[k].r, at[k].z, q, r, double(zs) + target_height);
          out.values[std::size_t(r) * g.cols + q] = any ? 1.0f : 0.0f;
        }
        progress.tile_done(g.cols);
      }
    });
  });
  progress.finish();
  return out;
}

}  // namespace

Raster dsm_viewshed(const Raster& dsm, std::span<const Vec3> eyes, double target_height, unsigned threads,
                    bool progress) {
  return viewshed_of(dsm, eyes, target_height, threads, progress, [](std::size_t, const Vec3&) { return true; });
}

Raster dsm_viewshed(const Raster& dsm, std::span<const Observer> observers, double max_distance,
                    double target_height, unsigned threads, bool progress) {
  if (!(max_distance >= 0.0)) throw std::invalid_argument("dsm viewshed: max distance must be >= 0");
  std::vector<Vec3> eyes;
  for (const Observer& o : observers) eyes.push_back(o.position);
  return viewshed_of(dsm, eyes, target_height, threads, progress, [&](std::size_t k, const Vec3& p) {
    const Vec3 v = p - observers[k].position;
    return within_view_limits(observers[k], max_distance, v, glm::length(v));
  });
}

}  // namespace rayscan::analysis
