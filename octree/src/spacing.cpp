#include "rayscan/spacing.hpp"

#include "rayscan/point_query.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace rayscan {

double median_nn_spacing(const AnyIndex& index, std::span<const Vec3> positions,
                         std::size_t max_samples) {
  if (positions.size() < 2 || max_samples == 0) return 0.0;
  const std::size_t n = std::min(max_samples, positions.size());
  std::vector<double> d(n, 0.0);
  std::visit(
      [&](const auto& idx) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& r) {
          std::vector<Neighbor> nb;
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const std::size_t p = i * positions.size() / n;
            // Nearest point at a non-zero distance (duplicates are common in scans).
            knn_query(idx, positions[p], 8, kInf, nb);
            double best = 0.0;
            for (const Neighbor& x : nb)
              if (x.distance > 0.0) { best = x.distance; break; }
            d[i] = best;
          }
        });
      },
      index);
  std::erase(d, 0.0);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

RadiusChoice choose_radius(const AnyIndex& index, std::span<const Vec3> positions,
                           std::optional<double> radius, double factor) {
  RadiusChoice c;
  if (radius) {
    if (!(*radius > 0.0) || !std::isfinite(*radius))
      throw std::invalid_argument("radius: expected a finite number > 0");
    c.radius = *radius;
    return c;
  }
  if (!(factor > 0.0) || !std::isfinite(factor))
    throw std::invalid_argument("radius factor: expected a finite number > 0");
  c.automatic = true;
  c.factor = factor;
  c.spacing = median_nn_spacing(index, positions);
  if (!(c.spacing > 0.0))
    throw std::invalid_argument("\"auto\" needs at least two distinct points; give a number");
  c.radius = factor * c.spacing;
  return c;
}

}  // namespace rayscan
