#include "rayscan/octree/spacing.hpp"

#include "rayscan/octree/point_query.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include "rayscan/base/number_text.hpp"
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan {

double median_nn_spacing(const AnyIndex& index, std::span<const Vec3> positions,
                         std::size_t max_samples) {
  return std::visit([&](const auto& idx) { return median_nn_spacing_of(idx, positions, max_samples); }, index);
}

std::string auto_radius_factor_problem(double factor) {
  if (std::isfinite(factor) && factor > 0.0 && factor <= kMaxAutoRadiusFactor) return "";
  return "expected a number in (0, " + shortest_text(kMaxAutoRadiusFactor) + "]";
}

std::string sphere_radius_problem(double radius) {
  if (std::isfinite(radius) && radius > 0.0) return "";
  return "expected a finite number > 0 (world units) or auto";
}

RadiusChoice choose_radius(const AnyIndex& index, std::span<const Vec3> positions,
                           std::optional<double> radius, double factor) {
  return choose_radius(radius, factor, [&] { return median_nn_spacing(index, positions); });
}

RadiusChoice choose_radius(std::optional<double> radius, double factor, const std::function<double()>& spacing) {
  RadiusChoice c;
  if (radius) {
    if (const std::string why = sphere_radius_problem(*radius); !why.empty())
      throw std::invalid_argument("radius: " + why + ", got " + shortest_text(*radius));
    c.radius = *radius;
    return c;
  }
  if (const std::string why = auto_radius_factor_problem(factor); !why.empty())
    throw std::invalid_argument("radius factor: " + why);
  c.automatic = true;
  c.factor = factor;
  c.spacing = spacing();
  if (!(c.spacing > 0.0))
    throw std::invalid_argument("\"auto\" needs at least two distinct points; give a number");
  c.radius = factor * c.spacing;
  return c;
}

}  // namespace rayscan
