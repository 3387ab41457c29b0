#include "rayscan/analysis/dsm_viewshed.hpp"

#include "rayscan/base/threads.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

namespace rayscan::analysis {

namespace {

// Whether the target at the centre of cell (qt, rt), height zt, is seen from the eye at grid
// coordinates (fq, fr) (cell centres at integers), height ze: R3 over the crossings of the
// major axis' centre lines strictly between the two.
bool seen(const Raster& dsm, double fq, double fr, double ze, std::int64_t qt, std::int64_t rt, double zt) {
  const GridSpec& g = dsm.grid;
  const double dq = double(qt) - fq, dr = double(rt) - fr;
  auto z = [&](std::int64_t q, std::int64_t r) { return dsm.values[std::size_t(r) * g.cols + std::size_t(q)]; };
  // Heights compare with a relative slack so that a surface exactly on the line does not hide.
  const double slack = 1e-9 * (1.0 + std::abs(ze) + std::abs(zt));
  auto hides = [&](double t, double surface) { return std::isfinite(surface) && surface > ze + t * (zt - ze) + slack; };
  // Interpolation between two centres, a missing one (NaN) standing for the other.
  auto lerp = [](float a, float b, double f) {
    if (!std::isfinite(a)) return double(b);
    if (!std::isfinite(b)) return double(a);
    return double(a) + f * (double(b) - double(a));
  };
  if (std::abs(dq) >= std::abs(dr)) {
    if (dq == 0.0) return true;  // the eye's own cell centre
    const std::int64_t step = dq > 0 ? 1 : -1;
    // Columns strictly between the eye and the target.
    std::int64_t q = dq > 0 ? std::int64_t(std::floor(fq)) + 1 : std::int64_t(std::ceil(fq)) - 1;
    for (; q != qt; q += step) {
      if (q < 0 || q >= std::int64_t(g.cols)) continue;
      const double t = (double(q) - fq) / dq;
      if (t <= 0.0) continue;
      const double r = fr + t * dr;
      std::int64_t r0 = std::int64_t(std::floor(r));
      const double f = r - double(r0);
      std::int64_t r1 = r0 + 1;
      if (r0 < 0) r0 = 0;
      if (r1 >= std::int64_t(g.rows)) r1 = std::int64_t(g.rows) - 1;
      if (r0 >= std::int64_t(g.rows) || r1 < 0) continue;
      if (hides(t, lerp(z(q, r0), z(q, r1), f))) return false;
    }
  } else {
    const std::int64_t step = dr > 0 ? 1 : -1;
    std::int64_t r = dr > 0 ? std::int64_t(std::floor(fr)) + 1 : std::int64_t(std::ceil(fr)) - 1;
    for (; r != rt; r += step) {
      if (r < 0 || r >= std::int64_t(g.rows)) continue;
      const double t = (double(r) - fr) / dr;
      if (t <= 0.0) continue;
      const double q = fq + t * dq;
      std::int64_t q0 = std::int64_t(std::floor(q));
      const double f = q - double(q0);
      std::int64_t q1 = q0 + 1;
      if (q0 < 0) q0 = 0;
      if (q1 >= std::int64_t(g.cols)) q1 = std::int64_t(g.cols) - 1;
      if (q0 >= std::int64_t(g.cols) || q1 < 0) continue;
      if (hides(t, lerp(z(q0, r), z(q1, r), f))) return false;
    }
  }
  return true;
}

}  // namespace

Raster dsm_viewshed(const Raster& dsm, std::span<const Vec3> eyes, double target_height, unsigned threads) {
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
  tbb::task_arena arena(static_cast<int>(resolve_threads(threads)));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, g.rows), [&](const auto& range) {
      for (std::uint32_t r = range.begin(); r != range.end(); ++r)
        for (std::uint32_t q = 0; q < g.cols; ++q) {
          const float zs = dsm.values[std::size_t(r) * g.cols + q];
          if (!std::isfinite(zs)) continue;
          bool any = false;
          for (const Vec3& e : eyes) {
            const double fq = (e.x - g.x0) / g.cell - 0.5, fr = (g.y_top - e.y) / g.cell - 0.5;
            if (seen(dsm, fq, fr, e.z, q, r, double(zs) + target_height)) {
              any = true;
              break;
            }
          }
          out.values[std::size_t(r) * g.cols + q] = any ? 1.0f : 0.0f;
        }
    });
  });
  return out;
}

}  // namespace rayscan::analysis
