// Point spacing and the "auto" sphere radius: the one definition behind the renderer's scene
// "radius": "auto", `rayscan visibility --radius auto` and the benchmarks.
#pragma once

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/point_query.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string>

namespace rayscan {

/// Sample size of the median nearest-neighbour spacing (the functions below): points i * N / n,
/// i < n = min(N, kSpacingSamples), of N in original order.
inline constexpr std::size_t kSpacingSamples = 20000;

/// Median distance from a point to its nearest other point (kNN with k = 8, skipping duplicates
/// at distance 0), over an evenly spaced sample of at most `max_samples` points (deterministic,
/// parallel over TBB). World units; 0 for fewer than 2 distinct points. `index` must be built over
/// `positions`.
[[nodiscard]] double median_nn_spacing(const AnyIndex& index, std::span<const Vec3> positions,
                                       std::size_t max_samples = kSpacingSamples);

/// The same over any index satisfying SpatialIndex (e.g. io::MappedIndex, an index file): the
/// median over up to `max_samples` evenly spaced positions of the distance to the nearest point
/// at a non-zero distance (world units); 0 when fewer than two distinct points. With `batch` > 0
/// the samples are queried `batch` at a time (each batch in parallel) and `after_batch()` is
/// called after each, e.g. to drop the pages a mapped index's queries touched; the result is the
/// same.
template <class I>
[[nodiscard]] double median_nn_spacing_of(const I& index, std::span<const Vec3> positions,
                                          std::size_t max_samples = kSpacingSamples, std::size_t batch = 0,
                                          const std::function<void()>& after_batch = {}) {
  if (positions.size() < 2 || max_samples == 0) return 0.0;
  const std::size_t n = std::min(max_samples, positions.size());
  std::vector<double> d(n, 0.0);
  const std::size_t step = batch == 0 ? n : batch;
  for (std::size_t b0 = 0; b0 < n; b0 += step) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(b0, std::min(n, b0 + step), 32), [&](const auto& r) {
    std::vector<Neighbor> nb;
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const std::size_t p = i * positions.size() / n;
      // Nearest point at a non-zero distance (duplicates are common in scans).
      knn_query(index, positions[p], 8, kInf, nb);
      double best = 0.0;
      for (const Neighbor& x : nb)
        if (x.distance > 0.0) {
          best = x.distance;
          break;
        }
      d[i] = best;
    }
  });
    if (after_batch) after_batch();
  }
  std::erase(d, 0.0);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

/// median_nn_spacing_of(index, positions, max_samples) for an index whose points are not held in
/// original order (an index file, io::MappedIndex, whose positions are in storage order): the
/// same samples, original indices i * N / n, are located by one pass over index.ids() (parallel,
/// no per-point allocation), so the result is the same as over the original-order positions.
/// Without stored ids (IdView::identity: the original order is the slot order) the samples are
/// read at slots i * N / n directly, without the pass.
/// The pass goes in blocks of 4 Mi slots; `scanned(end)` (optional) is called after the slots
/// [0, end) are done, e.g. to drop the pages of a mapped ids section behind the pass (without
/// ids, after every 1,024 samples read by slot). `batch`
/// and `after_batch` are median_nn_spacing_of's.
template <class I>
[[nodiscard]] double median_nn_spacing_by_id(const I& index, std::size_t max_samples = kSpacingSamples,
                                             const std::function<void(std::size_t)>& scanned = {},
                                             std::size_t batch = 0, const std::function<void()>& after_batch = {}) {
  const auto pos = index.positions();
  const IdView ids = index.ids();
  const std::size_t N = pos.size();
  if (N < 2 || max_samples == 0) return 0.0;
  const std::size_t n = std::min(max_samples, N);
  std::vector<Vec3> samples(n);
  if (ids.is_identity()) {  // an index file without ids: original index == slot, no pass needed
    for (std::size_t i = 0; i < n; ++i) {
      samples[i] = pos[i * N / n];
      if (scanned && i % 1024 == 1023) scanned(i * N / n + 1);
    }
    if (scanned) scanned(N);
    return median_nn_spacing_of(index, std::span<const Vec3>(samples), n, batch, after_batch);
  }
  // Sample i is original index p(i) = floor(i N / n); p is strictly increasing (N >= n), so an id
  // is a sample iff p(ceil(id n / N)) == id.
  for (std::size_t c0 = 0; c0 < N; c0 += std::size_t{1} << 22) {
    const std::size_t c1 = std::min(N, c0 + (std::size_t{1} << 22));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(c0, c1, 1 << 16), [&](const auto& r) {
    for (std::size_t s = r.begin(); s != r.end(); ++s) {
      const std::uint64_t id = ids[s];
      const std::uint64_t i = (id * n + N - 1) / N;
      if (i < n && i * N / n == id) samples[i] = pos[s];
    }
  });
    if (scanned) scanned(c1);
  }
  return median_nn_spacing_of(index, std::span<const Vec3>(samples), n, batch, after_batch);
}

/// The auto radius factor when none is given (scene "auto_radius_factor", the jobs'
/// radius_factor): radius = the median spacing, so a sphere reaches its nearest neighbour and the
/// sampled surface has no gaps.
inline constexpr double kDefaultAutoRadiusFactor = 1.0;

/// The largest auto radius factor accepted: at 100 x the spacing a sphere already covers some
/// 30,000 neighbours of a surface sample, so a larger factor is a mistake, not a model.
inline constexpr double kMaxAutoRadiusFactor = 100.0;

/// The one check of an auto radius factor (scene "auto_radius_factor", `--radius-factor`, the
/// jobs' radius_factor, choose_radius): "" for a finite number in (0, kMaxAutoRadiusFactor],
/// otherwise what was expected, "expected a number in (0, 100]", for the caller to put after the
/// field's or option's name.
[[nodiscard]] std::string auto_radius_factor_problem(double factor);

/// The one check of a given sphere radius (`--radius`, the jobs' radius, choose_radius): "" for a
/// finite number > 0, otherwise what was expected, "expected a finite number > 0 (world units) or
/// auto" ("auto": the radius chosen from the spacing, a front end's word for nullopt), for the
/// caller to put after the field's or option's name.
[[nodiscard]] std::string sphere_radius_problem(double radius);

/// The sphere radius a job used and how it was chosen.
struct RadiusChoice {
  double radius = 0.0;     ///< world units, > 0
  bool automatic = false;  ///< true: radius = factor x spacing
  double spacing = 0.0;    ///< median_nn_spacing (only when automatic)
  double factor = kDefaultAutoRadiusFactor;  ///< the auto factor (only when automatic)
};

/// The radius of every point sphere (paper section 5.3): `radius` when given (one that
/// sphere_radius_problem accepts), otherwise ("auto") factor x median_nn_spacing(index, positions).
/// Throws std::invalid_argument "needs at least two distinct points" when auto finds no spacing,
/// for a radius sphere_radius_problem refuses, or (auto) for a factor auto_radius_factor_problem
/// refuses.
[[nodiscard]] RadiusChoice choose_radius(const AnyIndex& index, std::span<const Vec3> positions,
                                         std::optional<double> radius, double factor = kDefaultAutoRadiusFactor);

/// The same rule with the spacing supplied by the caller (called only when `radius` is unset),
/// e.g. median_nn_spacing_of over an index file. Same errors.
[[nodiscard]] RadiusChoice choose_radius(std::optional<double> radius, double factor,
                                         const std::function<double()>& spacing);

}  // namespace rayscan
