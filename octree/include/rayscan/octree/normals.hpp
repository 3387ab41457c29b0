// Per-point surface attributes for surfel rendering: unit normals by principal component analysis
// over the k nearest neighbours (Hoppe et al. 1992, "Surface Reconstruction from Unorganized
// Points", section 3.2; the covariance's smallest eigenvector), oriented towards a viewpoint or
// along an up axis (Hoppe's consistent orientation simplified to a visibility cue, as PCL's
// flipNormalTowardsViewpoint), and a per-point radius from the local spacing (distance to the
// k-th neighbour; Pfister et al. 2000, "Surfels", section 5: the splat radius that closes holes).
#pragma once

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/point_query.hpp"

#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace rayscan {

/// How estimate_surfels() orients the sign-ambiguous PCA normal.
struct NormalOrientation {
  /// Flip each normal so that it points towards this position (a scanner station, a camera
  /// centre). When unset, normals point along `up`.
  std::optional<Vec3> viewpoint;
  Vec3 up{0.0, 0.0, 1.0};  ///< used without a viewpoint: dot(n, up) >= 0
};

/// Lateral reach of the thickness measurement, in disc radii (SurfelAttributes::thickness).
inline constexpr double kThicknessReach = 3.0;
/// Largest thickness measured, in disc radii: parallel surfaces farther apart than this along the
/// normal stay separate surfaces (a shelf above a table), nearer ones within the lateral reach are
/// one measured surface (the terraces of a depth-quantised scan: 6-9 r on the office1 Kinect wall).
inline constexpr double kThicknessHeight = 10.0;
/// Only points whose normal is within acos(0.9) = 26 degrees of the patch normal count towards the
/// thickness: parallel layers (terraces, noise), not a wall, a canopy or a riser across the layers.
inline constexpr double kThicknessParallel = 0.9;

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
  bool measure_thickness = true;  ///< false: leave SurfelAttributes::thickness zero (callers that
                                  ///< do not trace shadow or bounce rays, e.g. visibility)
  /// Progress of the estimate, the phase callback of the index build and translate: phase
  /// kSurfelPhase, `done` of `total` = the points (with measure_thickness each of the two passes
  /// counts half of every point). Called from worker threads, possibly at once (the callee
  /// synchronises) and not in order of `done`; the last call, from the calling thread once the
  /// estimate is complete, has done == total. Empty = no reports. Never changes the result.
  std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)> progress;
};

/// The phase name of estimate_surfels' progress (SurfelOptions::progress).
inline constexpr const char* kSurfelPhase = "surfels";

/// Per-point surfel attributes, indexed by original point index.
struct SurfelAttributes {
  std::vector<glm::vec3> normals;  ///< unit normals (float), world frame
  std::vector<float> radii;        ///< disc radius, world units (> 0)
  /// Measured thickness of the surface at each point, world units (>= 0; all zero when
  /// SurfelOptions::measure_thickness is false): the distance along the normal of its surface patch
  /// (kThicknessBlock consecutive storage slots) to the farthest parallel layer of points (normals
  /// within acos(kThicknessParallel)) within kThicknessReach x r of the patch's normal line and
  /// kThicknessHeight x r of its plane (r: the patch's largest radius; detail::measure_thickness).
  /// About zero on a flat, noise-free surface; the depth step near the edges of a depth-quantised
  /// scan's terraces (a Kinect's disparity steps: ~7 cm at 5 m, 7 x the spacing), the noise
  /// amplitude on a noisy one. It widens the self-intersection slab of shadow and bounce rays
  /// (same_surface).
  std::vector<float> thickness;
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
/// Throws std::runtime_error: the kNN of the point with id `id` found `found` < 2 neighbours
/// among `points` (the index's nodes do not reach its points).
[[noreturn]] void throw_knn_short(std::size_t id, std::size_t found, std::size_t points);
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

/// Storage slots per block of the thickness pass (measure_thickness): one surface patch.
inline constexpr std::size_t kThicknessBlock = 32;

/// SurfelAttributes::thickness of the points in storage slots [b, e) of `index` (one patch:
/// consecutive slots are spatial neighbours), with the normals and final radii of `a` set;
/// `positions` by original id. Patch frame: centroid c, mean normal m (each normal sign-aligned to
/// the first), spread rho = max |p_i - c|, R = max r_i. One box query gathers the union of the
/// points' measurement cylinders (radius Reach r_i, half-length Height r_i about each normal line;
/// the box of a cylinder has half-extent Height r |n_k| + Reach r sqrt(1 - n_k^2) on axis k); of
/// those, the points q within Reach R + rho of the patch's normal line, within Height R + rho of its
/// plane and with |n_q . m| >= kThicknessParallel are the patch's layers, with offsets h_q = (q - c)
/// . m in [h_lo, h_hi]. Each point gets max(h_hi - h_i, h_i - h_lo), h_i = (p_i - c) . m: the
/// distance along the patch normal to its farthest layer (the patch itself included, so >= 0). Cost
/// per patch: one box query and one pass over its points (no per-point query).
template <SpatialIndex I>
void measure_thickness(const I& index, std::span<const Vec3> positions, SurfelAttributes& a, std::size_t b,
                       std::size_t e, std::vector<PointIndex>& gathered) {
  const auto pos = index.positions();
  const IdView ids = index.ids();
  const Vec3 n0(a.normals[ids[b]]);
  Vec3 c(0.0), m(0.0);
  AABB box;
  double R = 0.0;
  for (std::size_t s = b; s != e; ++s) {
    const Vec3 n(a.normals[ids[s]]);
    const double r = a.radii[ids[s]];
    const double H = kThicknessHeight * r, L = kThicknessReach * r;
    const auto half = [&](double nk) { return H * std::abs(nk) + L * std::sqrt(std::max(0.0, 1.0 - nk * nk)); };
    const Vec3 ext = Vec3(half(n.x), half(n.y), half(n.z)) * (1.0 + 1e-9);
    box.expand(pos[s] - ext);
    box.expand(pos[s] + ext);
    c += pos[s] - pos[b];  // relative to the first point: no cancellation at UTM magnitudes
    m += glm::dot(n, n0) < 0.0 ? -n : n;
    R = std::max(R, r);
  }
  c = pos[b] + c / double(e - b);
  const double ml = glm::length(m);
  m = ml > 0.0 ? m / ml : n0;
  double rho = 0.0;
  for (std::size_t s = b; s != e; ++s) rho = std::max(rho, glm::length(pos[s] - c));
  const double lat = kThicknessReach * R + rho, hl = kThicknessHeight * R + rho;
  box_query(index, box, gathered);
  double h_lo = 0.0, h_hi = 0.0;
  for (const PointIndex q : gathered) {
    const Vec3 v = positions[q] - c;
    const double h = glm::dot(v, m);
    if (std::abs(h) > hl || glm::dot(v, v) - h * h > lat * lat) continue;
    if (std::abs(glm::dot(Vec3(a.normals[q]), m)) < kThicknessParallel) continue;
    h_lo = std::min(h_lo, h);
    h_hi = std::max(h_hi, h);
  }
  for (std::size_t s = b; s != e; ++s) {
    const double h = glm::dot(pos[s] - c, m);
    a.thickness[ids[s]] = float(std::max({0.0, h_hi - h, h - h_lo}));
  }
}

/// SurfelOptions::progress over the passes of an estimate of `points` points: add() counts the
/// points a block finished (thread-safe), finish() reports done == total from the calling thread.
struct SurfelProgressCount {
  const SurfelOptions& o;
  std::uint64_t points;
  std::uint64_t passes;             ///< 2 with the thickness pass, else 1
  std::atomic<std::uint64_t> units{0};  ///< points x passes done

  SurfelProgressCount(const SurfelOptions& opt, std::uint64_t n)
      : o(opt), points(n), passes(opt.measure_thickness ? 2 : 1) {
    if (o.progress) o.progress(kSurfelPhase, 0, points);
  }
  void add(std::uint64_t finished) {
    if (o.progress) o.progress(kSurfelPhase, (units.fetch_add(finished) + finished) / passes, points);
  }
  void finish() const {
    if (o.progress) o.progress(kSurfelPhase, points, points);
  }
};

/// The per-point step of estimate_surfels_over, whatever order the points are visited in: the
/// attribute arrays (n points, by original id, initialised to +z normals and zero radii), the
/// neighbour count k and the up axis, and estimate(), which fills point `id` at position `p`
/// from its k nearest neighbours in `index`. Thread-safe across distinct ids. Throws as
/// throw_knn_short when the index returns fewer than 2 neighbours.
struct SurfelEstimator {
  SurfelAttributes out;
  const SurfelOptions& o;
  std::span<const Vec3> positions;   ///< original order (PCA neighbourhoods read them by id)
  std::span<const glm::vec3> file_normals;
  std::size_t n, k;
  Vec3 up;
  bool pca;  ///< normals by PCA (no file normals)

  SurfelEstimator(std::size_t points, std::span<const Vec3> pos, const SurfelOptions& opt,
                  std::span<const glm::vec3> normals)
      : o(opt), positions(pos), file_normals(normals), n(points), up(surfel_up(opt)), pca(normals.empty()) {
    out.normals.assign(n, glm::vec3(0.0f, 0.0f, 1.0f));
    out.radii.assign(n, 0.0f);
    out.thickness.assign(n, 0.0f);
    k = std::max<std::size_t>(pca ? o.k_normal : 0, o.k_radius + 1);
  }

  template <SpatialIndex I>
  void estimate(const I& index, const Vec3& p, PointIndex id, std::vector<Neighbor>& nb) {
    knn_query(index, p, k, kInf, nb);
    // k >= 2 and the index holds n >= 2 points, so fewer than 2 neighbours means an index whose
    // nodes do not reach its points (a corrupted file opened without its node checks).
    if (nb.size() < 2) throw_knn_short(id, nb.size(), n);
    // Radius: the k_radius-th neighbour other than the point (nb[0] is the point or a duplicate).
    const std::size_t rk = std::min<std::size_t>(o.k_radius, nb.size() - 1);
    out.radii[id] = float(nb[rk].distance * o.radius_factor);
    out.normals[id] = surfel_normal(p, nb, positions, o, up, pca, pca ? glm::vec3() : file_normals[id]);
  }
};
}  // namespace detail

template <SpatialIndex I>
SurfelAttributes estimate_surfels_over(const I& index, std::span<const Vec3> positions, const SurfelOptions& o,
                                       std::span<const glm::vec3> file_normals) {
  detail::check_surfel_arguments(index.positions().size(), positions, o, file_normals);
  const std::size_t n = positions.size();
  detail::SurfelEstimator est(n, positions, o, file_normals);
  SurfelAttributes& out = est.out;
  const auto pos = index.positions();
  const IdView ids = index.ids();
  detail::SurfelProgressCount progress(o, n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
    std::vector<Neighbor> nb;
    for (std::size_t s = range.begin(); s != range.end(); ++s) est.estimate(index, pos[s], ids[s], nb);
    progress.add(range.size());
  });
  detail::finish_surfel_radii(out, o);
  // Thickness with the final radii (a second pass: the clamp needs every radius).
  if (o.measure_thickness) {
    const std::size_t blocks = (n + detail::kThicknessBlock - 1) / detail::kThicknessBlock;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 16), [&](const auto& range) {
      std::vector<PointIndex> gathered;
      for (std::size_t k = range.begin(); k != range.end(); ++k)
        detail::measure_thickness(index, positions, out, k * detail::kThicknessBlock,
                                  std::min(n, (k + 1) * detail::kThicknessBlock), gathered);
      progress.add(std::min(n, range.end() * detail::kThicknessBlock) - range.begin() * detail::kThicknessBlock);
    });
  }
  progress.finish();
  return std::move(out);
}

}  // namespace rayscan
