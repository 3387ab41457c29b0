// Per-point surface attributes for surfel rendering: unit normals by principal component analysis
// over the k nearest neighbours (Hoppe et al. 1992, "Surface Reconstruction from Unorganized
// Points", section 3.2; the covariance's smallest eigenvector), oriented towards a viewpoint or
// along an up axis (Hoppe's consistent orientation simplified to a visibility cue, as PCL's
// flipNormalTowardsViewpoint), and a per-point radius from the local spacing (distance to the
// k-th neighbour; Pfister et al. 2000, "Surfels", section 5: the splat radius that closes holes).
#pragma once

#include "rayscan/any_index.hpp"
#include "rayscan/point_query.hpp"

#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include <optional>
#include <span>
#include <vector>

namespace rayscan {

/// How estimate_surfels() orients the sign-ambiguous PCA normal.
struct NormalOrientation {
  /// Flip each normal so that it points towards this position (a scanner station, a camera
  /// centre). When unset, normals point along `up`.
  std::optional<Vec3> viewpoint;
  Vec3 up{0.0, 0.0, 1.0};  ///< used without a viewpoint: dot(n, up) >= 0
};

/// Parameters of estimate_surfels().
struct SurfelOptions {
  unsigned k_normal = 10;         ///< neighbours (including the point) of the PCA, >= 3
  unsigned k_radius = 8;          ///< radius from the distance to this neighbour (excluding the point), >= 1
  double radius_factor = 0.6;     ///< radius = factor x distance to the k_radius-th neighbour, > 0.
                                  ///< 0.6 x the 8th neighbour closes a square grid (needs 0.71 s,
                                  ///< gives 0.85 s) and a 3:1 scan pattern (needs 1.58 s, gives 1.8 s)
  double max_radius_factor = 4.0; ///< radii are clamped to this factor x their median (isolated
                                  ///< points would otherwise give huge discs), > 0
  NormalOrientation orientation;  ///< sign of the normals
  bool compute_normals = true;    ///< false: keep `normals` given to estimate_surfels (file normals)
};

/// Per-point surfel attributes, indexed by original point index.
struct SurfelAttributes {
  std::vector<glm::vec3> normals;  ///< unit normals (float), world frame
  std::vector<float> radii;        ///< disc radius, world units (> 0)
  double max_radius = 0.0;         ///< max of radii (the ray query's candidate radius)
  double median_radius = 0.0;      ///< median of the radii before clamping, world units
};

/// Unit eigenvector of the smallest eigenvalue of the symmetric 3x3 matrix
/// [[a00 a01 a02][a01 a11 a12][a02 a12 a22]] (closed-form eigenvalues, Smith 1961 "Eigenvalues of a
/// symmetric 3x3 matrix", then the largest cross product of two rows of A - lambda I). Returns
/// nullopt when the eigenvector is not determined (a rank <= 1 or isotropic matrix).
std::optional<Vec3> smallest_eigenvector(double a00, double a01, double a02, double a11, double a12,
                                         double a22);

/// PCA normals and spacing radii for every point of `positions` (the cloud the index was built
/// over), computed in parallel (TBB) with the core's kNN (knn_query). If `file_normals` is non-empty
/// (PLY/PCD normals; size must equal positions) they are normalised and oriented instead of
/// estimated. Throws std::invalid_argument for sizes that differ, k_normal < 3, k_radius < 1,
/// a non-positive factor, or fewer than 2 points.
SurfelAttributes estimate_surfels(const AnyIndex& index, std::span<const Vec3> positions,
                                  const SurfelOptions& options = {},
                                  std::span<const glm::vec3> file_normals = {});

/// estimate_surfels over any SpatialIndex (e.g. the mapped index file, io::MappedIndex), with the
/// same results as the AnyIndex overload for the same points: the work runs over the index's slots
/// (storage order: consecutive slots are spatial neighbours, so the kNN stays in cache) and
/// writes by original id. `positions` are the points in original id order.
template <SpatialIndex I>
SurfelAttributes estimate_surfels_over(const I& index, std::span<const Vec3> positions,
                                       const SurfelOptions& options = {},
                                       std::span<const glm::vec3> file_normals = {});

namespace detail {
/// Argument checks of estimate_surfels (throws std::invalid_argument, see there).
void check_surfel_arguments(std::size_t index_points, std::span<const Vec3> positions, const SurfelOptions& o,
                            std::span<const glm::vec3> file_normals);
/// The unit up axis of `o.orientation` ((0, 0, 1) when it is zero), computed once per estimate.
Vec3 surfel_up(const SurfelOptions& o);
/// The normal of point `p` from its neighbours `nb` (ascending distance, original ids into
/// `positions`): PCA, or the file normal `file` when `estimate` is false; then oriented towards
/// `o.orientation.viewpoint`, or along `up` (surfel_up) without one. Unit length, world frame.
glm::vec3 surfel_normal(const Vec3& p, std::span<const Neighbor> nb, std::span<const Vec3> positions,
                        const SurfelOptions& o, const Vec3& up, bool estimate, const glm::vec3& file);
/// Median of the non-zero radii, zero radii set to it, clamp to max_radius_factor x median,
/// max_radius. Throws std::invalid_argument when every radius is zero.
void finish_surfel_radii(SurfelAttributes& a, const SurfelOptions& o);
}  // namespace detail

template <SpatialIndex I>
SurfelAttributes estimate_surfels_over(const I& index, std::span<const Vec3> positions, const SurfelOptions& o,
                                       std::span<const glm::vec3> file_normals) {
  detail::check_surfel_arguments(index.positions().size(), positions, o, file_normals);
  const std::size_t n = positions.size();
  SurfelAttributes out;
  out.normals.assign(n, glm::vec3(0.0f, 0.0f, 1.0f));
  out.radii.assign(n, 0.0f);
  const bool estimate = file_normals.empty();
  const std::size_t k = std::max<std::size_t>(estimate ? o.k_normal : 0, o.k_radius + 1);
  const Vec3 up = detail::surfel_up(o);
  const auto pos = index.positions();
  const auto ids = index.ids();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
    std::vector<Neighbor> nb;
    for (std::size_t s = range.begin(); s != range.end(); ++s) {
      const Vec3& p = pos[s];
      const PointIndex id = ids[s];
      knn_query(index, p, k, kInf, nb);
      // Radius: the k_radius-th neighbour other than the point (nb[0] is the point or a duplicate).
      const std::size_t rk = std::min<std::size_t>(o.k_radius, nb.size() - 1);
      out.radii[id] = float(nb[rk].distance * o.radius_factor);
      out.normals[id] = detail::surfel_normal(p, nb, positions, o, up, estimate, estimate ? glm::vec3() : file_normals[id]);
    }
  });
  detail::finish_surfel_radii(out, o);
  return out;
}

}  // namespace rayscan
