// Per-point visibility over the paper's ray query (Teuscher et al., Algorithm 1, order sphere_hit):
// line of sight from observers, sky view factor, and the points a camera sees.
//
// Surface model: every point is a sphere of radius r (the renderer's model, paper section 5.3).
// All functions run on TBB over the points (or pixels) in the index's storage order (spatially
// coherent), each result depends only on its own point, so results are identical for any thread
// count.
#pragma once

#include "rayscan/analysis/observer.hpp"
#include "rayscan/site/site.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/camera/camera.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <type_traits>
#include <vector>

namespace rayscan::analysis {

/// A per-point result array that a job spread over processes gathers to the root (MPI): `size`
/// bytes for original point index i at data + i * size (a std::vector<T> of trivially copyable T
/// indexed by point, or one stretch of a larger array).
struct GatheredField {
  std::byte* data = nullptr;
  std::size_t size = 0;
  /// The elements of `values` (one per point) as a gathered field.
  template <class T>
  static GatheredField of(std::span<T> values) {
    static_assert(std::is_trivially_copyable_v<T>);
    return {reinterpret_cast<std::byte*>(values.data()), sizeof(T)};
  }
  /// The elements of `values` (one per point) as a gathered field.
  template <class T>
  static GatheredField of(std::vector<T>& values) {
    return of(std::span<T>(values));
  }
};

/// Parameters of the line-of-sight test.
struct VisibilityOptions {
  double radius = 1.0;        ///< sphere radius r of every point, world units (> 0)
  double tolerance = 2.0;     ///< along-ray tolerance tau, world units (>= 0); see is_visible()
  double target_height = 0.0; ///< the ray aims at P + (0, 0, h_t), world units (>= 0); see is_visible()
  double max_distance = kInf; ///< observers see no farther than this (each may override), world units
  unsigned threads = 0;       ///< worker threads; 0 = all cores (results are identical)
  bool progress = false;      ///< draw a progress bar on stderr (only if stderr is a terminal)
  /// Surfel mode: when set, every point is the oriented disc of these
  /// attributes (indexed like the positions; estimate_surfels) instead of a sphere of `radius`,
  /// and is_visible() uses the surfel (height-field) rule. Must outlive the call.
  const SurfelAttributes* surfels = nullptr;
  /// Spreads the point chunks over processes (rayscan::mpi, docs/mpi.md); nullptr = all here.
  /// With several processes, only the root's result is complete (per_observer, queries summed).
  WorkDistributor* distributor = nullptr;
  /// Checked before each chunk of points: once set, compute_visibility and trace_directions throw
  /// rayscan::Cancelled (base/job.hpp); nullptr = never. JobControl::cancel. Not owned.
  const std::atomic<bool>* cancel = nullptr;
};

/// Per-point results of compute_visibility(), indexed like the cloud's positions.
struct VisibilityResult {
  std::vector<std::uint32_t> count;       ///< number of observers that see the point
  std::vector<double> nearest;            ///< distance to the nearest observer that sees it; -1 if none
  std::vector<std::uint64_t> per_observer;  ///< number of points each observer sees
  std::uint64_t pairs = 0;     ///< observer-point pairs considered (points x observers)
  std::uint64_t queries = 0;   ///< ray queries issued (pairs inside range and angle limits)
  double seconds = 0.0;        ///< wall time of the parallel loop
  unsigned threads = 0;        ///< threads used
};

/// Line-of-sight rule. Point i at P, distance D = |P - O| from the eye O, is visible
/// from the observer when all of:
///  1. D <= max distance (the observer's own max_distance, else opts.max_distance);
///  2. the direction P - O lies inside the observer's azimuth/elevation limits (within_angle_limits);
///  3. D <= r or D' <= r (the eye is inside the point's sphere), or the first sphere hit of the ray
///     from O towards the aim point P' = P + (0, 0, h_t) at distance D' = |P' - O| -- ray_query
///     with k = 1, order sphere_hit, radius r, t in [0, D' - r] -- is (a) absent, (b) point i
///     itself, or (c) a point j whose centre projects onto the ray at t_j >= D' - tau (j lies at
///     most tau before the aim point along the ray: the same surface as P).
/// Spheres containing the eye have a negative entry parameter and are ignored (an eye inside a
/// tree crown is not blinded by the leaf it touches). Ties in entry parameter go to the lower point
/// index (the ray query's order).
///
/// Why h_t (the "target height" of GIS viewsheds, gdal_viewshed -tz, ArcGIS OFFSETB): a ray that
/// meets a sampled surface at a grazing elevation angle a passes within r of the surface's other
/// points for about r / tan(a) before P, so with h_t = 0 flat ground seen from eye height is
/// hidden by itself beyond a few metres unless tau >= r / tan(a). Aiming at the top of P's sphere
/// (h_t = r) keeps the ray above a flat, level neighbourhood (it stays more than r above the
/// neighbours' centres) while any real obstacle still blocks it. h_t = 0 is the plain rule.
///
/// Surfel rule (opts.surfels set): the discs are a height field, the surface
/// a first-return DSM records, solid below it. Rule 3 becomes: the segment from O to P' passes
/// below no disc j, where "below" means: c_j projects onto the segment's horizontal projection at
/// a parameter strictly between O and P', the segment's point there lies horizontally within r_j
/// of c_j, and the disc's height there exceeds the segment's by more than tau. A disc's height at
/// a horizontal offset is its plane's for discs within 45 degrees of level (limited to the disc's
/// own vertical extent), its top c_j.z + r_j sqrt(1 - n_z^2) for steeper ones (walls, leaves). The
/// discs of P's own surface that overlap P's disc (same_surface, centres within r_i + r_j)
/// and P itself are not obstacles. So, unlike the spheres, a crown or a roof edge hides what a
/// ray passes under, as it does in a DSM viewshed (gdal_viewshed, r.viewshed); use spheres for
/// the true 3-D answer (under trees, overhangs, through gaps). Found by one traversal of the index
/// pruned by the segment's horizontal projection (not the paper's ray query).
/// `site`'s points are `positions` in original order (for an index file, queried in place: by
/// ids(), slot order for a file built without ids, docs/index-format.md "Ids"); i <
/// positions.size(); `scratch` is caller-owned. A COPC file in place (positions: read_point_cloud()'s
/// file order, the order of its ids) answers in a CopcIndex::QueryScope of its own.
bool is_visible(const Site& site, std::span<const Vec3> positions, const Observer& observer,
                PointIndex i, const VisibilityOptions& opts, std::vector<RayHit>& scratch);

/// is_visible() for every point and observer. Observers must have a resolved z (place_observers).
/// Throws std::invalid_argument for radius <= 0, a negative or NaN tolerance or max distance, an
/// site whose size differs from positions (a COPC file: its header's point count) or surfel
/// attributes of another size. An index file is queried in place (no tree is built;
/// `positions`: its points in original order, MappedIndex::to_point_cloud()), and so is a COPC
/// file (`positions`: read_point_cloud()'s file order; each chunk of points runs in a
/// CopcIndex::QueryScope, so the decoded nodes stay within the cache budget plus what the chunks
/// in flight decode). Per-point results are by original index (ids(): the slot when the file has
/// no ids section, docs/index-format.md "Ids"; the file order on a COPC file). The same answers
/// on every storage of the same points.
VisibilityResult compute_visibility(const Site& site, std::span<const Vec3> positions,
                                    std::span<const Observer> observers, const VisibilityOptions& opts);

/// The open directions of every point: for each point i and world direction d_k (unit length, +z
/// up), whether something at infinity in that direction -- the sun of one sun-map sector, a patch
/// of sky -- is seen from P_i. Spheres: the ray from P_i + opts.target_height u_i along d_k
/// enters no sphere of radius opts.radius at t >= opts.tolerance (ray_query k = 1, sphere_hit;
/// spheres containing the start and those entered within the tolerance are the point's own
/// surface), u_i = n_i with `normals`, else +z (off a wall's surface, not up along it). Surfels
/// (opts.surfels set): the surfel rule of is_visible(), with the observer at P_i + L d_k, L beyond
/// the extent of `positions`, so that every obstacle of the site lies between. With `normals`
/// (unit, indexed like the positions; empty = none) and `cull`, direction k is traced for point i
/// only when dot(n_i, d_k) > 0 (a surface facing away receives nothing from it) and its bit stays
/// 0 otherwise. Calls `visit(i, mask)` once per point,
/// from worker threads (concurrently for different points); bit k % 64 of mask[k / 64] is set for
/// an open direction. opts.max_distance is not used. With opts.distributor over several processes
/// (MPI, docs/mpi.md) every process calls it with the same arguments; point chunks are handed out,
/// each process visits the points of its chunks, and the `gather` arrays (what `visit` wrote per
/// point) of the others' points travel to the root, whose arrays then hold every point's values
/// as one process would have written them.
/// Throws std::invalid_argument like compute_visibility and for normals of another count. Runs on
/// every storage as compute_visibility does (a COPC file in place: a QueryScope per point chunk).
void trace_directions(const Site& site, std::span<const Vec3> positions, std::span<const Vec3> dirs,
                      std::span<const Vec3> normals, const VisibilityOptions& opts,
                      const std::function<void(PointIndex, std::span<const std::uint64_t>)>& visit,
                      bool cull = true, std::span<const GatheredField> gather = {});

/// Turns each steep normal (|n_z| < 0.5: walls, façades, the sides of crowns) towards the side of
/// its surface that opens: a PCA normal's sign is arbitrary, and turning it up says nothing for a
/// wall. Two first-hit rays leave the point along +-n, 20 degrees up (ray_query k = 1, sphere_hit,
/// spheres of `radius`, from P +- radius n, those entered within 2 x radius ignored); the normal
/// keeps or takes the side whose ray meets nothing, or, when both meet something, the farther
/// hit (a building's inside ends at its opposite wall). Returns the number of normals turned.
/// `positions` in original order (a COPC file in place: file order, a QueryScope per block of
/// points). Throws std::invalid_argument for a radius that is not > 0 or normals of another count.
std::size_t orient_steep_normals(const Site& site, std::span<const Vec3> positions, std::span<Vec3> normals,
                                 double radius, unsigned threads = 0);

/// Hemisphere sampling of the sky view factor.
enum class SkyWeighting {
  uniform,  ///< equal solid angle: the fraction of the upper hemisphere that is open
  cosine    ///< cosine-weighted (Lambert): the fraction of diffuse sky irradiance on a horizontal
            ///< surface, the "sky view factor" of urban climatology and ambient occlusion
};

/// Parameters of the sky view estimate.
struct SkyViewOptions {
  std::uint32_t rays = 64;     ///< directions per point, N >= 1
  SkyWeighting weighting = SkyWeighting::uniform;
  double radius = 1.0;         ///< sphere radius r (> 0), world units
  double lift = 2.0;           ///< rays start this far above the point (+z), world units (>= 0);
                               ///< >= r keeps a point's own flat neighbourhood from closing its sky
  double max_distance = kInf;  ///< obstacles farther than this along a ray are ignored
  std::uint64_t seed = 0;      ///< varies the per-point rotation of the direction set
  unsigned threads = 0;        ///< worker threads; 0 = all cores (results are identical)
  bool progress = false;       ///< progress bar on stderr (only if stderr is a terminal)
  /// Spreads the point chunks over processes (rayscan::mpi); nullptr = all here. With several,
  /// only the root's values (and query count) are complete.
  WorkDistributor* distributor = nullptr;
  /// Checked before each chunk of points: once set, compute_sky_view throws rayscan::Cancelled
  /// (base/job.hpp); nullptr = never. JobControl::cancel. Not owned.
  const std::atomic<bool>* cancel = nullptr;
};

/// Direction k of the N-direction set (+z up, unit length): a spherical Fibonacci lattice
/// (Gonzalez 2010, "Measurement of areas on a sphere using Fibonacci and latitude-longitude
/// lattices"; Keinert et al. 2015) on the upper hemisphere. Uniform: z_k = 1 - (k + 0.5) / N
/// (equal-area bands, Archimedes' hat-box theorem); cosine: z_k = sqrt(1 - (k + 0.5) / N) (Malley's
/// method: the same lattice on the unit disk projected up); azimuth phi_k = 2 pi k / golden ratio
/// + rotation. Requires k < n.
Vec3 sky_direction(std::uint32_t k, std::uint32_t n, double rotation, SkyWeighting weighting);

/// The rotation (radians, [0, 2 pi)) of point i's direction set: a hash (SplitMix64) of (seed, i),
/// so neighbouring points use different directions yet every run gives the same answer.
double sky_rotation(std::uint64_t seed, std::uint64_t i);

/// Sky view of every point: the fraction of its N rays, origin P + (0, 0, lift) and directions
/// sky_direction(k, N, sky_rotation(seed, i)), with no sphere entry in [0, max_distance] (ray_query
/// k = 1, sphere_hit; spheres containing the origin are ignored). Values are multiples of 1/N in
/// [0, 1], by original index (an index file is queried in place). Throws std::invalid_argument
/// for rays == 0, radius <= 0, negative lift or max distance, or a site whose size differs from
/// positions. A COPC file is queried in place as in compute_visibility.
std::vector<double> compute_sky_view(const Site& site, std::span<const Vec3> positions,
                                     const SkyViewOptions& opts, std::uint64_t* queries = nullptr);

/// The point each pixel of `camera` sees: the first sphere hit (ray_query k = 1, sphere_hit,
/// t in [0, max_distance]) of the ray through the pixel centre and lens centre,
/// camera.generate_ray(x, y) -- the ray of the renderer's point-index AOV, so the result equals
/// `rayscan render --aov index` for the same radius. Row-major from the top-left pixel;
/// kNoPoint for a miss. With a `distributor` of several processes (MPI) the rows are handed out
/// by it and only the root's result is complete. An index file is queried in place, and so is a
/// COPC file (each image row in a CopcIndex::QueryScope: only the nodes the rays reach are
/// decoded; pixel values are file-order point indices). Throws std::invalid_argument for
/// radius <= 0, rayscan::Cancelled once `cancel` is set (checked before each image row; nullptr =
/// never).
std::vector<std::uint32_t> camera_first_hits(const Site& site, const Camera& camera,
                                             double radius, double max_distance = kInf,
                                             unsigned threads = 0, bool progress = false,
                                             WorkDistributor* distributor = nullptr,
                                             const std::atomic<bool>* cancel = nullptr);

/// Number of pixels whose first hit is each point (`npoints` entries) from camera_first_hits()'s
/// output. Throws std::out_of_range for an index >= npoints other than the miss value.
std::vector<std::uint32_t> count_pixel_hits(std::span<const std::uint32_t> pixel_hits, std::size_t npoints);

}  // namespace rayscan::analysis
