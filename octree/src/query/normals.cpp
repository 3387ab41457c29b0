#include "rayscan/octree/normals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace rayscan {

std::optional<Vec3> smallest_eigenvector(double a00, double a01, double a02, double a11, double a12,
                                         double a22) {
  // Smith (1961): eigenvalues of a symmetric 3x3 from the trace, the deviatoric norm and det.
  const double p1 = a01 * a01 + a02 * a02 + a12 * a12;
  const double q = (a00 + a11 + a22) / 3.0;
  const double b00 = a00 - q, b11 = a11 - q, b22 = a22 - q;
  const double p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1;
  if (!(p2 > 0.0) || !std::isfinite(p2)) return std::nullopt;  // A = q I: isotropic
  const double p = std::sqrt(p2 / 6.0);
  // det(B) / 2 with B = (A - q I) / p.
  const double detB = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) +
                       a02 * (a01 * a12 - b11 * a02)) / (p * p * p);
  const double r = std::clamp(0.5 * detB, -1.0, 1.0);
  const double phi = std::acos(r) / 3.0;
  const double lambda = q + 2.0 * p * std::cos(phi + 2.0 * std::numbers::pi / 3.0);  // smallest
  // Rows of A - lambda I span the orthogonal complement of the eigenvector; their largest cross
  // product is the best-conditioned estimate of it.
  const Vec3 r0(a00 - lambda, a01, a02), r1(a01, a11 - lambda, a12), r2(a02, a12, a22 - lambda);
  const Vec3 c01 = glm::cross(r0, r1), c02 = glm::cross(r0, r2), c12 = glm::cross(r1, r2);
  const double d01 = glm::dot(c01, c01), d02 = glm::dot(c02, c02), d12 = glm::dot(c12, c12);
  const Vec3& best = d01 >= d02 && d01 >= d12 ? c01 : (d02 >= d12 ? c02 : c12);
  const double dbest = std::max({d01, d02, d12});
  // Relative threshold: the cross product of two rows scales with p^2 (p^4 squared).
  if (!(dbest > 1e-20 * p2 * p2)) return std::nullopt;
  return best / std::sqrt(dbest);
}

namespace detail {

void check_surfel_arguments(std::size_t index_points, std::span<const Vec3> positions, const SurfelOptions& o,
                            std::span<const glm::vec3> file_normals) {
  const std::size_t n = positions.size();
  if (o.k_normal < 3) throw std::invalid_argument("surfels: k_normal must be >= 3");
  if (o.k_radius < 1) throw std::invalid_argument("surfels: k_radius must be >= 1");
  if (!(o.radius_factor > 0.0) || !(o.max_radius_factor > 0.0))
    throw std::invalid_argument("surfels: radius_factor and max_radius_factor must be > 0");
  if (!file_normals.empty() && file_normals.size() != n)
    throw std::invalid_argument("surfels: the file's normals and positions differ in size");
  if (n < 2) throw std::invalid_argument("surfels: need at least 2 points");
  if (index_points != n) throw std::invalid_argument("surfels: the index was built over another cloud");
}

void throw_knn_short(std::size_t id, std::size_t found, std::size_t points) {
  throw std::runtime_error("surfels: the kNN of point " + std::to_string(id) + " found " + std::to_string(found) +
                           " neighbours among " + std::to_string(points) +
                           " points (expected at least 2: the index is inconsistent; `rayscan info --verify` checks an index file)");
}

Vec3 surfel_up(const SurfelOptions& o) {
  return glm::length(o.orientation.up) > 0.0 ? glm::normalize(o.orientation.up) : Vec3(0, 0, 1);
}

glm::vec3 surfel_normal(const Vec3& p, std::span<const Neighbor> nb, std::span<const Vec3> positions,
                        const SurfelOptions& o, const Vec3& up, bool estimate, const glm::vec3& file) {
  Vec3 nrm = up;
  if (estimate) {
    // Covariance about the neighbourhood mean, in coordinates relative to p (no cancellation at
    // UTM magnitudes).
    const std::size_t m = std::min<std::size_t>(o.k_normal, nb.size());
    Vec3 mean(0.0);
    for (std::size_t j = 0; j < m; ++j) mean += positions[nb[j].index] - p;
    mean /= double(m);
    double c00 = 0, c01 = 0, c02 = 0, c11 = 0, c12 = 0, c22 = 0;
    for (std::size_t j = 0; j < m; ++j) {
      const Vec3 v = positions[nb[j].index] - p - mean;
      c00 += v.x * v.x; c01 += v.x * v.y; c02 += v.x * v.z;
      c11 += v.y * v.y; c12 += v.y * v.z; c22 += v.z * v.z;
    }
    const double tr = c00 + c11 + c22;
    if (tr > 0.0) {
      const double s_ = 1.0 / tr;  // scale-free eigen problem
      if (auto e = smallest_eigenvector(c00 * s_, c01 * s_, c02 * s_, c11 * s_, c12 * s_, c22 * s_)) nrm = *e;
    }
  } else {
    const double len = glm::length(glm::dvec3(file));
    if (len > 0.0 && std::isfinite(len)) nrm = glm::dvec3(file) / len;
  }
  const Vec3 toward = o.orientation.viewpoint ? *o.orientation.viewpoint - p : up;
  if (glm::dot(nrm, toward) < 0.0) nrm = -nrm;
  return glm::vec3(nrm);
}

void finish_surfel_radii(SurfelAttributes& out, const SurfelOptions& o) {
  // Clamp radii to a factor of their median so isolated points do not grow huge discs (which
  // would also widen every ray query's candidate cylinder). Zero radii (duplicates only) get the
  // median.
  std::vector<float> sorted = out.radii;
  std::erase(sorted, 0.0f);
  if (sorted.empty()) throw std::invalid_argument("surfels: every point coincides with its neighbours");
  std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2), sorted.end());
  out.median_radius = sorted[sorted.size() / 2];
  const float cap = float(out.median_radius * o.max_radius_factor);
  double mx = 0.0;
  for (float& r : out.radii) {
    if (!(r > 0.0f)) r = float(out.median_radius);
    r = std::min(r, cap);
    mx = std::max(mx, double(r));
  }
  out.max_radius = mx;
}

}  // namespace detail

SurfelAttributes estimate_surfels(const AnyIndex& index, std::span<const Vec3> positions,
                                  const SurfelOptions& o, std::span<const glm::vec3> file_normals) {
  return std::visit([&](const auto& idx) { return estimate_surfels_over(idx, positions, o, file_normals); }, index);
}

}  // namespace rayscan
