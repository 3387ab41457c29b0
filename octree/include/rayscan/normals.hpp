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

}  // namespace rayscan
