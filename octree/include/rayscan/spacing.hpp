// Point spacing and the "auto" sphere radius: the one definition behind the renderer's scene
// "radius": "auto", `rayscan visibility --radius auto` and the benchmarks.
#pragma once

#include "rayscan/any_index.hpp"

#include <cstddef>
#include <optional>
#include <span>

namespace rayscan {

/// Median distance from a point to its nearest other point (kNN with k = 8, skipping duplicates
/// at distance 0), over an evenly spaced sample of at most `max_samples` points (deterministic,
/// parallel over TBB). World units; 0 for fewer than 2 distinct points. `index` must be built over
/// `positions`.
[[nodiscard]] double median_nn_spacing(const AnyIndex& index, std::span<const Vec3> positions,
                                       std::size_t max_samples = 20000);

/// The sphere radius a job used and how it was chosen.
struct RadiusChoice {
  double radius = 0.0;     ///< world units, > 0
  bool automatic = false;  ///< true: radius = factor x spacing
  double spacing = 0.0;    ///< median_nn_spacing (only when automatic)
  double factor = 1.0;     ///< the auto factor (only when automatic)
};

/// The radius of every point sphere (paper section 5.3): `radius` when given (must be finite and
/// > 0), otherwise ("auto") factor x median_nn_spacing(index, positions). Throws
/// std::invalid_argument "needs at least two distinct points" when auto finds no spacing, or for
/// a non-positive radius or factor.
[[nodiscard]] RadiusChoice choose_radius(const AnyIndex& index, std::span<const Vec3> positions,
                                         std::optional<double> radius, double factor = 1.0);

}  // namespace rayscan
